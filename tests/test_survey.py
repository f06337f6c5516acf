"""survey: the lawnmower's geometry, its checks, its compiled plan and its runtime.

Quick tests (no dry run: the example's dry run is one of tests/test_dry_run.py's
examples). The runtime runs on a virtual clock as tests/test_runtime_primitives.py's do.
"""

from __future__ import annotations

import json
import math
from pathlib import Path
from typing import Any

import pytest

from clark_engine.behaviors import behaviors
from clark_engine.behaviors.base import Status
from clark_engine.behaviors.lawnmower import (
    lawnmower,
    longest_edge_heading_deg,
    photo_marks,
    polygon_area_m2,
    self_crossing,
)
from clark_engine.behaviors.survey import SurveyBehavior, SurveyParams
from clark_engine.behaviors.survey_plan import footprint_m
from clark_engine.link.fleet import FleetTable
from clark_engine.link.messages import PictureData
from clark_engine.mission.compiler import agent_config
from clark_engine.mission.validate import validate_path
from clark_engine.runtime.commands import Goto, PayloadCommand, SetMode
from clark_engine.runtime.config import AgentConfig, config_from_dict
from clark_engine.runtime.context import Outbox, PrimitiveContext, offset_position
from clark_engine.runtime.events import PayloadEvent, VehicleState

ROOT = Path(__file__).resolve().parents[1]
EXAMPLE = ROOT / "missions" / "survey_field.yaml"
AREA = "area: [[20, 10], [100, 10], [100, 55], [20, 55]]"

# ----------------------------------------------------------------------- geometry


def test_lines_run_down_the_middle_of_equal_strips_and_alternate() -> None:
    square = [(0.0, 0.0), (100.0, 0.0), (100.0, 60.0), (0.0, 60.0)]
    lines = lawnmower(square, 20.0, 0.0)
    assert [(line.start, line.end) for line in lines] == [
        ((0.0, 10.0), (100.0, 10.0)),
        ((100.0, 30.0), (0.0, 30.0)),
        ((0.0, 50.0), (100.0, 50.0)),
    ]
    # A width that is not a whole number of spacings: the lines are centred, no wider apart.
    lines = lawnmower(square, 25.0, 0.0)
    assert [round(line.start[1], 6) for line in lines] == [5.0, 30.0, 55.0]


def test_lines_are_clipped_to_the_polygon() -> None:
    triangle = [(0.0, 0.0), (100.0, 0.0), (0.0, 100.0)]
    lines = lawnmower(triangle, 25.0, 0.0)
    assert len(lines) == 4
    for line in lines:
        east = line.start[1]
        assert line.start[1] == pytest.approx(line.end[1])
        north_ends = sorted((line.start[0], line.end[0]))
        assert north_ends == pytest.approx([0.0, 100.0 - east])  # the hypotenuse n + e = 100
        assert line.photo_to_m - line.photo_from_m == pytest.approx(100.0 - east)


def test_run_out_extends_each_line_past_the_area_and_photos_stay_inside() -> None:
    square = [(0.0, 0.0), (100.0, 0.0), (100.0, 40.0), (0.0, 40.0)]
    first, second = lawnmower(square, 20.0, 0.0, run_out_m=30.0)
    assert (first.start, first.end) == ((-30.0, 10.0), (130.0, 10.0))
    assert (second.start, second.end) == ((130.0, 30.0), (-30.0, 30.0))
    assert (first.photo_from_m, first.photo_to_m) == (30.0, 130.0)


def test_heading_defaults_along_the_longest_edge_and_turns_the_lines() -> None:
    h = math.radians(30.0)
    along, across = (math.cos(h), math.sin(h)), (-math.sin(h), math.cos(h))

    def at(a: float, c: float) -> tuple[float, float]:
        return (a * along[0] + c * across[0], a * along[1] + c * across[1])

    rotated = [at(0, 0), at(200, 0), at(200, 50), at(0, 50)]
    assert longest_edge_heading_deg(rotated) == pytest.approx(30.0)
    lines = lawnmower(rotated, 25.0, 30.0)
    assert len(lines) == 2
    for line in lines:
        dn, de = line.end[0] - line.start[0], line.end[1] - line.start[1]
        assert math.degrees(math.atan2(de, dn)) % 180.0 == pytest.approx(30.0)
        assert math.hypot(dn, de) == pytest.approx(200.0)


def test_polygon_tests() -> None:
    bow_tie = [(0.0, 0.0), (10.0, 10.0), (10.0, 0.0), (0.0, 10.0)]
    assert self_crossing(bow_tie) == (0, 2)
    assert self_crossing([(0.0, 0.0), (10.0, 0.0), (10.0, 10.0), (0.0, 10.0)]) is None
    assert polygon_area_m2([(0.0, 0.0), (0.0, 10.0), (10.0, 10.0), (10.0, 0.0)]) == 100.0
    assert polygon_area_m2([(0.0, 0.0), (5.0, 5.0), (10.0, 10.0)]) == 0.0


def test_photo_marks_are_even_at_most_the_distance_apart_with_both_ends() -> None:
    assert photo_marks(0.0, 80.0, 11.417) == [10.0 * i for i in range(9)]
    assert photo_marks(30.0, 130.0, 50.0) == [30.0, 80.0, 130.0]
    assert photo_marks(5.0, 5.0, 10.0) == [5.0, 5.0]  # a line that only grazes the area


def test_footprint_from_the_cameras_optics() -> None:
    camera = {"sensor_width_mm": 3.76, "sensor_height_mm": 2.74, "focal_length_mm": 3.6}
    across, along = footprint_m(camera, 25.0) or (0.0, 0.0)
    assert (across, along) == pytest.approx((26.111, 19.028), abs=1e-3)
    assert footprint_m({"sensor_width_mm": 3.76}, 25.0) is None


# -------------------------------------------------------------------- the example


def _write(tmp_path: Path, text: str) -> Path:
    path = tmp_path / "mission.yaml"
    path.write_text(text, encoding="utf-8")
    return path


def _codes(path: Path) -> list[str]:
    return [f.code for f in validate_path(path).findings if f.is_error]


def _compiled(path: Path, agent: str = "f450") -> AgentConfig:
    result = validate_path(path)
    assert result.mission is not None, [str(f) for f in result.errors]
    data = json.loads(json.dumps(agent_config(result.mission, result.mission.agents[agent])))
    return config_from_dict(data)


def _survey_params(config: AgentConfig) -> dict[str, Any]:
    assert config.machine is not None
    return next(s.params for s in config.machine.walk() if s.primitive == "survey")


def test_the_example_compiles_its_spacing_and_photo_marks_from_the_footprint() -> None:
    params = _survey_params(_compiled(EXAMPLE))
    # 25 m up: 26.11 m across and 19.03 m along; 30 % side and 40 % forward overlap.
    assert params["line_spacing_m"] == pytest.approx(26.111 * 0.7, abs=1e-3)
    assert params["photo_every_m"] == pytest.approx(19.028 * 0.6, abs=1e-3)
    assert params["heading_deg"] == 0.0  # the 80 m edges run north
    assert params["run_out_m"] == 0.0
    lines = params["lines"]
    assert len(lines) == 3  # 45 m wide / 18.28 m
    assert [round(line["start"]["east_m"], 2) for line in lines] == [14.22, 32.5, 50.78]
    assert [line["start"]["north_m"] for line in lines] == [20.0, 100.0, 20.0]
    assert all(line["start"]["up_m"] == 25.0 for line in lines)
    assert "lines" not in SurveyParams.schema()["properties"]  # the compiler's alone
    assert behaviors()["survey"].plan(params).points[-1][0] == lines[-1]["end"]


def test_an_area_in_lat_lon_compiles_to_the_same_lines(tmp_path: Path) -> None:
    text = EXAMPLE.read_text(encoding="utf-8")
    result = validate_path(EXAMPLE)
    assert result.mission is not None
    origin = result.mission.origin
    corners = [(20, 10), (100, 10), (100, 55), (20, 55)]
    globals_ = [offset_position(origin.lat_deg, origin.lon_deg, n, e) for n, e in corners]
    lat_lon = ", ".join(f"{{lat: {lat:.9f}, lon: {lon:.9f}}}" for lat, lon in globals_)
    path = _write(tmp_path, text.replace(AREA, f"area: [{lat_lon}]"))
    local = _survey_params(_compiled(EXAMPLE))["lines"]
    global_ = _survey_params(_compiled(path))["lines"]
    for a, b in zip(local, global_, strict=True):
        for end in ("start", "end"):
            assert a[end]["north_m"] == pytest.approx(b[end]["north_m"], abs=0.01)
            assert a[end]["east_m"] == pytest.approx(b[end]["east_m"], abs=0.01)


def test_an_aeroplane_runs_out_past_the_area_by_its_tolerance(tmp_path: Path) -> None:
    text = (ROOT / "missions" / "anaconda_survey.yaml").read_text(encoding="utf-8")
    state = """\
        survey:
          use: survey
          with:
            area: [[0, 0], [400, 0], [400, 300], [0, 300]]
            altitude_m: 60
            line_spacing_m: 100
            photo_every_m: 40
            tolerance_m: 75
          transitions: {done: doublet}
"""
    start = text.index("        survey:\n")
    end = text.index("        doublet:\n")
    path = _write(tmp_path, text[:start] + state + text[end:])
    assert _codes(path) == []
    params = _survey_params(_compiled(path, "anaconda"))
    assert params["run_out_m"] == 75
    first = params["lines"][0]
    assert (first["start"]["north_m"], first["end"]["north_m"]) == (-75.0, 475.0)
    assert (first["photo_from_m"], first["photo_to_m"]) == (75.0, 475.0)


@pytest.mark.parametrize(
    ("change", "code"),
    [
        (("area: [[20, 10], [100, 10], [100, 55], [20, 55]]", AREA), None),
        (("area: [[20, 10], [100, 55], [100, 10], [20, 55]]", AREA), "E-SURVEY-AREA"),
        (("area: [[20, 10], [60, 10], [100, 10]]", AREA), "E-SURVEY-AREA"),
        (
            ("line_spacing_m: 20\n            side_overlap: 0.3", "side_overlap: 0.3"),
            "E-SURVEY-SPACING",
        ),
        (
            ("photo_every_m: 10\n            forward_overlap: 0.4", "forward_overlap: 0.4"),
            "E-SURVEY-SPACING",
        ),
        (("line_spacing_m: 0.2", "side_overlap: 0.3"), "E-SURVEY-LINES"),
        (
            ("            payload: cam\n            to: [mcs]", "            to: [mcs]"),
            "E-PAYLOAD-MISSING",
        ),
        (("speed_m_s: 9", "speed_m_s: 4.5"), "E-PHOTO-INTERVAL"),
        (("altitude_m: 300", "altitude_m: 25"), "E-ALTITUDE-CEILING"),
        (("area: [[2000, 10], [2080, 10], [2080, 55], [2000, 55]]", AREA), "E-GEOFENCE-POINT"),
        (("{profile: raspberry_pi_camera}", None), "E-CAMERA-FOOTPRINT"),
    ],
    ids=[
        "valid",
        "crosses-itself",
        "no-area",
        "spacing-and-overlap",
        "every-and-overlap",
        "too-many-lines",
        "no-such-camera",
        "photos-too-often",
        "over-the-ceiling",
        "outside-the-fence",
        "camera-without-optics",
    ],
)
def test_checks(tmp_path: Path, change: tuple[str, str | None], code: str | None) -> None:
    text = EXAMPLE.read_text(encoding="utf-8")
    new, old = change
    if old is None:  # the camera without its optics
        start = text.index("{profile: raspberry_pi_camera,")
        text = text[:start] + new + text[text.index("\n", start) :]
    else:
        assert old in text
        text = text.replace(old, new, 1)
    codes = _codes(_write(tmp_path, text))
    if code is None:
        assert codes == []
    else:
        assert code in codes, codes


def test_a_station_cannot_survey(tmp_path: Path) -> None:
    text = EXAMPLE.read_text(encoding="utf-8").replace(
        "    telemetry: {heartbeat: 1}\n\n  f450:",
        "    telemetry: {heartbeat: 1}\n    behavior: {use: survey, with: {"
        + AREA
        + ", altitude_m: 25, line_spacing_m: 20}}\n\n  f450:",
        1,
    )
    codes = _codes(_write(tmp_path, text))
    assert codes and all(c.startswith("E-") for c in codes)
    messages = [f.message for f in validate_path(tmp_path / "mission.yaml").findings]
    assert any("survey" in m for m in messages)


def test_a_rover_cannot_space_lines_from_a_footprint(tmp_path: Path) -> None:
    text = EXAMPLE.read_text(encoding="utf-8").replace(
        "profile: dji_f450", "profile: traxxas_slash"
    )
    text = text.replace(
        "        climb: {use: takeoff, with: {alt_m: 25}, transitions: {done: field}}\n", ""
    )
    text = text.replace("transitions: {activate: climb}", "transitions: {activate: field}")
    findings = [f for f in validate_path(_write(tmp_path, text)).findings if f.is_error]
    spacing = [f for f in findings if f.code == "E-SURVEY-SPACING"]
    assert len(spacing) == 2, [str(f) for f in findings]
    assert "is a rover" in spacing[0].message and "give line_spacing_m" in spacing[0].message


def test_the_camera_without_optics_says_what_to_add(tmp_path: Path) -> None:
    text = EXAMPLE.read_text(encoding="utf-8")
    start = text.index("{profile: raspberry_pi_camera,")
    text = text[:start] + "raspberry_pi_camera" + text[text.index("\n", start) :]
    findings = [f for f in validate_path(_write(tmp_path, text)).findings if f.is_error]
    assert [f.code for f in findings] == ["E-CAMERA-FOOTPRINT"]
    message = findings[0].message
    assert "sensor_width_mm, sensor_height_mm, focal_length_mm" in message
    assert "line_spacing_m" in message


# ------------------------------------------------------------------------ runtime

GPS_MS = 1_400_000_000_000


def _at(config: AgentConfig, north_m: float, east_m: float, alt_m: float = 25.0) -> VehicleState:
    lat, lon = offset_position(config.origin_lat_deg, config.origin_lon_deg, north_m, east_m)
    return VehicleState(
        gps_time_ms=GPS_MS,
        lat_deg=lat,
        lon_deg=lon,
        alt_m=alt_m,
        ground_speed_m_s=0.0,
        climb_rate_m_s=0.0,
        heading_deg=0.0,
        roll_deg=0.0,
        pitch_deg=0.0,
        yaw_deg=0.0,
        mode="GUIDED",
        custom_mode=0,
        armed=True,
    )


class _Clock:
    """One behaviour on a virtual clock: one update per tick at the config's loop rate."""

    def __init__(self, config: AgentConfig, survey: SurveyBehavior) -> None:
        fleet = FleetTable(
            config.agent_id,
            config.mission_id,
            config.heartbeat_timeout_s,
            {peer.id: peer.name for peer in config.peers},
        )
        self.ctx = PrimitiveContext(config=config, fleet=fleet)
        self.survey = survey
        self.tick = 0

    def _begin(self) -> list[Any]:
        self.ctx.outbox = Outbox()
        self.ctx.now_s = self.tick / self.ctx.config.loop_hz
        self.tick += 1
        return self.ctx.outbox.commands

    def start(self, state: VehicleState) -> list[Any]:
        commands = self._begin()
        self.ctx.vehicle = state
        self.survey.start(self.ctx)
        return list(commands)

    def step(self, state: VehicleState) -> tuple[Status, list[Any]]:
        commands = self._begin()
        self.ctx.vehicle = state
        return self.survey.update(self.ctx), list(commands)


def test_flies_the_lines_in_order_photographs_by_distance_and_is_done_at_the_end() -> None:
    config = _compiled(EXAMPLE)
    params = _survey_params(config)
    survey = SurveyBehavior(params)
    clock = _Clock(config, survey)
    lines = params["lines"]
    first = lines[0]["start"]
    commands = clock.start(_at(config, 0, 0))
    assert isinstance(commands[0], SetMode) and commands[0].mode == "GUIDED"
    assert Goto(first["lat"], first["lon"], first["alt_m"], 4.5) in commands
    # On the way to the first line: no pictures.
    status, commands = clock.step(_at(config, 10, 10))
    assert status is Status.RUNNING and commands == []
    captures: list[PayloadCommand] = []
    for index, line in enumerate(lines):
        a, b = line["start"], line["end"]
        # Arrive at the line's start: the Goto to its end goes out.
        status, commands = clock.step(_at(config, a["north_m"], a["east_m"]))
        end = Goto(b["lat"], b["lon"], b["alt_m"], 4.5)
        assert end in commands, index
        # Fly it a metre a tick (to 3 m short of its end): a capture at each 10 m mark.
        sign = 1.0 if b["north_m"] > a["north_m"] else -1.0
        for metre in range(0, 78):
            status, commands = clock.step(_at(config, a["north_m"] + sign * metre, a["east_m"]))
            assert status is Status.RUNNING
            captures.extend(c for c in commands if isinstance(c, PayloadCommand))
        # Arrive at its end (within tolerance_m 2): the last mark, then the next line.
        status, commands = clock.step(_at(config, b["north_m"] - sign * 1.0, b["east_m"]))
        captures.extend(c for c in commands if isinstance(c, PayloadCommand))
        if index + 1 == len(lines):
            assert status is Status.DONE
        else:
            following = lines[index + 1]["start"]
            assert Goto(following["lat"], following["lon"], following["alt_m"], 4.5) in commands
        assert len(captures) == 9 * (index + 1), index
    assert all(c.payload == "camera" and c.action == "capture" for c in captures)
    assert survey.requested == 27


def test_a_confirmed_capture_sends_picture_data_to_the_station() -> None:
    config = _compiled(EXAMPLE)
    params = _survey_params(config)
    survey = SurveyBehavior(params)
    clock = _Clock(config, survey)
    a = params["lines"][0]["start"]
    clock.start(_at(config, 0, 0))
    clock.step(_at(config, a["north_m"], a["east_m"]))
    _status, commands = clock.step(_at(config, a["north_m"], a["east_m"]))
    (request,) = [c for c in commands if isinstance(c, PayloadCommand)]
    clock.ctx.outbox = Outbox()
    survey.on_payload(clock.ctx, PayloadEvent("camera", "captured", request.request_id, "IMG_0001"))
    (message,) = clock.ctx.outbox.messages
    picture, to = message
    assert isinstance(picture, PictureData) and picture.image_index == 1
    assert to == ("mcs",)
    assert survey.captured == 1


def test_a_late_tick_sends_one_request_not_a_burst() -> None:
    config = _compiled(EXAMPLE)
    params = _survey_params(config)
    survey = SurveyBehavior(params)
    clock = _Clock(config, survey)
    a = params["lines"][0]["start"]
    clock.start(_at(config, 0, 0))
    clock.step(_at(config, a["north_m"], a["east_m"]))
    _status, commands = clock.step(_at(config, a["north_m"] + 45, a["east_m"]))
    assert len([c for c in commands if isinstance(c, PayloadCommand)]) == 1
    _status, commands = clock.step(_at(config, a["north_m"] + 46, a["east_m"]))
    assert not [c for c in commands if isinstance(c, PayloadCommand)]
    _status, commands = clock.step(_at(config, a["north_m"] + 50, a["east_m"]))
    assert len([c for c in commands if isinstance(c, PayloadCommand)]) == 1


def test_the_station_draws_the_compiled_lines_as_a_survey() -> None:
    from clark_engine.station.view_hello import plan_of

    config = _compiled(EXAMPLE)
    (item,) = [i for i in plan_of(config) if i["primitive"] == "survey"]
    lines = _survey_params(config)["lines"]
    assert item["kind"] == "tour" and item["survey"] is True  # it takes its own pictures
    assert len(item["points"]) == 2 * len(lines)
    last = item["points"][-1]
    assert last["north_m"] == pytest.approx(lines[-1]["end"]["north_m"], abs=0.01)
    assert last["east_m"] == pytest.approx(lines[-1]["end"]["east_m"], abs=0.01)
    assert last["up_m"] == 25.0


def test_a_compiled_config_without_its_lines_is_refused_at_load() -> None:
    from clark_engine.runtime.config import ConfigError

    result = validate_path(EXAMPLE)
    assert result.mission is not None
    data = json.loads(json.dumps(agent_config(result.mission, result.mission.agents["f450"])))

    def drop_lines(value: Any) -> int:
        if isinstance(value, dict):
            dropped = int(value.pop("lines", None) is not None)
            return dropped + sum(drop_lines(v) for v in value.values())
        if isinstance(value, list):
            return sum(drop_lines(v) for v in value)
        return 0

    assert drop_lines(data) == 1
    broken = data
    with pytest.raises(ConfigError, match="lines"):
        config_from_dict(broken)


def test_the_link_budget_counts_pictures_spaced_by_the_cameras_footprint() -> None:
    """survey_field spaces its pictures by forward_overlap, not photo_every_m: the budget
    still counts a Picture Data each spacing, at the compiled spacing the runtime flies."""
    from clark_engine.validation import mission_flows

    validation = validate_path(ROOT / "missions" / "survey_field.yaml")
    assert validation.ok and validation.mission is not None
    mission = validation.mission
    state = next(s for s in mission.agents["f450"].behavior.walk() if s.primitive == "survey")
    assert "photo_every_m" not in state.params and state.params["forward_overlap"] == 0.4
    compiled = agent_config(mission, mission.agents["f450"])
    (survey,) = [s for s in _states(compiled["machine"]) if s.get("primitive") == "survey"]
    interval_s = survey["params"]["photo_every_m"] / state.params["speed_m_s"]
    (flow,) = [f for f in mission_flows(mission) if f.message == "picture_data"]
    assert flow.sender == "f450" and flow.destinations == ("mcs",)
    assert flow.every_ticks == max(1, round(interval_s * mission.loop_hz))


def _states(node: dict[str, Any]) -> list[dict[str, Any]]:
    return [node, *(s for child in node.get("states", []) for s in _states(child))]
