"""orbit: its checks at the `use:`, its guided targets on a virtual clock, its turn counting.

Issue 20 item 8. The checks are run through ``validate_path`` on the example mission with
one line changed; the runtime through the same virtual-clock harness as the other
behaviours (tests/test_runtime_primitives.py), from the example compiled in-process.
"""

from __future__ import annotations

import json
import math
from pathlib import Path
from typing import Any

import pytest

from clark_engine.behaviors import behaviors, make_behavior
from clark_engine.behaviors.orbit import OrbitBehavior, circle_points, wrap_rad
from clark_engine.link.messages import AgentStatus, AgentType, Heartbeat
from clark_engine.link.packet import Packet
from clark_engine.mission.compiler import agent_config
from clark_engine.mission.validate import validate_path
from clark_engine.runtime.commands import Goto
from clark_engine.runtime.config import AgentConfig, config_from_dict
from clark_engine.runtime.context import EARTH_RADIUS_M, Status, offset_position
from tests.test_runtime_primitives import (
    GPS_MS,
    Run,
    at,
    compiled,
    fleet_for,
    local,
    params_of,
    set_mode,
    states_of,
)

ROOT = Path(__file__).resolve().parent.parent
EXAMPLE = "orbit_overwatch.yaml"
ORBIT_LINE = "with: {agent: slash, alt_m: 15, radius_m: 15, speed_m_s: 4, direction: cw, turns: 2}"

# ------------------------------------------------------------------ checks


def findings(tmp_path: Path, with_line: str | None = None, **replace: str) -> list[tuple[str, str]]:
    """(code, message) of every finding of the example with its orbit's `with:` replaced."""
    text = (ROOT / "missions" / EXAMPLE).read_text()
    assert ORBIT_LINE in text
    if with_line is not None:
        text = text.replace(ORBIT_LINE, with_line)
    for old, new in replace.items():
        assert old in text
        text = text.replace(old, new)
    path = tmp_path / "mission.yaml"
    path.write_text(text)
    result = validate_path(path)
    return [(f.code, f.message) for f in result.findings if f.code != "W-NO-KEY"]


def codes(found: list[tuple[str, str]]) -> list[str]:
    return [code for code, _ in found]


def test_the_example_is_valid(tmp_path: Path) -> None:
    assert findings(tmp_path) == []


@pytest.mark.parametrize(
    ("with_line", "code", "says"),
    [
        ("with: {radius_m: 15}", "E-ORBIT-CENTER", "neither is given"),
        (
            "with: {agent: slash, center: [0, 0, 15], alt_m: 15, radius_m: 15}",
            "E-ORBIT-CENTER",
            "not both",
        ),
        ("with: {center: [0, 0, 15], alt_m: 15, radius_m: 15}", "E-ORBIT-CENTER", "up_m"),
        ("with: {agent: slash, radius_m: 15}", "E-ORBIT-CENTER", "give alt_m"),
        ("with: {agent: f450, alt_m: 15, radius_m: 15}", "E-ORBIT-SELF", "cannot orbit itself"),
        ("with: {agent: mcs, alt_m: 15, radius_m: 15}", "E-ORBIT-STATUS", "is a station"),
        ("with: {agent: slsh, alt_m: 15, radius_m: 15}", "E-AGENT-UNKNOWN", "'slash'"),
        ("with: {agent: slash, alt_m: 500, radius_m: 15}", "E-ALTITUDE-CEILING", "ceiling"),
        ("with: {agent: slash, alt_m: 3, radius_m: 3}", "E-ORBIT-SEPARATION", "radius_m 4 m or"),
        ("with: {agent: slash, alt_m: 15, radius_m: 15, retarget_hz: 20}", "E-RATE", "loop_hz"),
        ("with: {agent: slash, alt_m: 15, radius_m: 15, speed_m_s: 90}", "E-SPEED-RANGE", "90"),
    ],
)
def test_checks_refuse_a_bad_orbit_at_its_use(
    tmp_path: Path, with_line: str, code: str, says: str
) -> None:
    found = findings(tmp_path, with_line)
    assert code in codes(found), found
    assert any(says in message for c, message in found if c == code), found


def test_the_centre_agent_must_report_its_position_to_the_orbiter(tmp_path: Path) -> None:
    # Without agent_status the copter never learns where to circle: an error at the agent.
    silent = findings(
        tmp_path,
        **{
            "telemetry: {heartbeat: 1, agent_status: 2, behavior_state: 1": "telemetry: "
            "{heartbeat: 1, behavior_state: 1"
        },
    )
    assert "E-ORBIT-STATUS" in codes(silent)
    # Slower than the retarget rate: a warning that names both rates.
    slow = findings(tmp_path, f"{ORBIT_LINE[:-1]}, retarget_hz: 5}}")
    assert [m for c, m in slow if c == "W-ORBIT-RATE"] == [
        "'f450' moves its target round 'slash' at 5 Hz but 'slash' reports its position at "
        "only 2 Hz; raise its agent_status rate or lower retarget_hz"
    ]


def test_the_schema_bounds_the_radius(tmp_path: Path) -> None:
    for radius in ("0", "0.5", "2500"):
        found = findings(tmp_path, ORBIT_LINE.replace("radius_m: 15", f"radius_m: {radius}"))
        assert found and all(c.startswith("E-") for c in codes(found)), (radius, found)


def test_a_station_cannot_orbit(tmp_path: Path) -> None:
    station = findings(
        tmp_path,
        **{
            "telemetry: {heartbeat: 1}\n": "telemetry: {heartbeat: 1}\n    behavior: {use: "
            "orbit, with: {center: [0, 0], radius_m: 10}}\n"
        },
    )
    assert "E-ROLE" in codes(station)


PLANE = ROOT / "tests" / "dryrun" / "plane_orbit_point.yaml"
PLANE_LINE = "with: {center: [0, 300, 60], radius_m: 120, direction: ccw, turns: 1}"


@pytest.mark.parametrize(
    ("radius", "speed", "least"),
    [("40", "", 52), ("51", "", 52), ("90", ", speed_m_s: 25", 96)],
)
def test_a_plane_cannot_circle_tighter_than_it_turns(
    tmp_path: Path, radius: str, speed: str, least: int
) -> None:
    # the Super Cub: at 18 m/s cruise and 30 deg/s 34.4 m turns, at 25 m/s and 45 deg bank
    # 63.7 m: 1.5 times that at least
    text = PLANE.read_text()
    assert PLANE_LINE in text
    path = tmp_path / "plane.yaml"
    path.write_text(text.replace(PLANE_LINE, PLANE_LINE.replace("120", radius)[:-1] + speed + "}"))
    found = [(f.code, f.message) for f in validate_path(path).findings]
    assert [c for c, _ in found] == ["E-ORBIT-RADIUS"], found
    assert f"give radius_m {least} m or more" in found[0][1]
    assert validate_path(PLANE).findings == []


def test_a_plane_is_sent_the_centre_with_its_loiter_radius_and_direction() -> None:
    config = compiled_from(PLANE, "cub")
    (state,) = states_of(config, "orbit")
    run = Run(config, make_behavior(state))
    lat, lon = state.params["center"]["lat"], state.params["center"]["lon"]
    me = at(config, 0, 0, alt_m=60.0)
    start = run.start(me)
    assert start == [set_mode(config, "GUIDED"), Goto(lat, lon, 60.0, None, None, None, 120, True)]
    # a fixed point is sent once: ArduPlane circles it by itself
    assert all(run.step(me) == (Status.RUNNING, []) for _ in range(30))
    orbit = run.primitive
    assert isinstance(orbit, OrbitBehavior)
    # counting starts within tolerance_m of a circle up to 15 % wide (ArduPlane's 126.7 m)
    # (138 m and tolerance_m 5: 143 m)
    for inside_m in (145, 114, 10):  # too wide, too tight, over the centre: not counted
        run.step(at(config, 0, 300 - inside_m, alt_m=60.0))
        assert orbit.swept_deg == 0 and orbit._last_bearing is None
    run.step(at(config, 0, 300 - 141, alt_m=60.0))
    assert orbit._last_bearing is not None


def test_orbit_raises_done_only_with_turns() -> None:
    orbit = behaviors()["orbit"]
    assert orbit.events({"turns": 2}) == frozenset({"done"})
    assert orbit.events({}) == frozenset()
    assert orbit.traits.guided and orbit.traits.flies


def test_the_plan_is_the_circle_the_way_it_is_flown() -> None:
    cw = circle_points([10, 20, 15], 10.0, "cw", 4)
    assert [(round(p["north_m"], 6), round(p["east_m"], 6), p["up_m"]) for p in cw] == [
        (20, 20, 15),
        (10, 30, 15),
        (0, 20, 15),
        (10, 10, 15),
    ]
    ccw = circle_points({"north_m": 10, "east_m": 20, "up_m": 15}, 10.0, "ccw", 4)
    assert [round(p["east_m"], 6) for p in ccw] == [20, 10, 20, 30]
    plan = behaviors()["orbit"].plan({"center": [0, 0, 15], "radius_m": 10, "direction": "cw"})
    assert plan.loop and len(plan.points) == 12 and {p for _, p in plan.points} == {"center"}
    assert behaviors()["orbit"].plan({"agent": "slash", "radius_m": 10}).points == ()


# ------------------------------------------------------------------ runtime


def compiled_from(path: Path, agent: str) -> AgentConfig:
    """A mission outside missions/ compiled in-process, read back as the runtime reads it."""
    resolved = validate_path(path).mission
    assert resolved is not None
    return config_from_dict(json.loads(json.dumps(agent_config(resolved, resolved.agents[agent]))))


COPTER = (EXAMPLE, "f450")


def report(config: AgentConfig, fleet: Any, north_m: float, east_m: float, now_s: float) -> None:
    """The rover's Agent Status, as the copter's fleet table receives it."""
    peer = config.peer("slash")
    assert peer is not None
    lat, lon = local(config, north_m, east_m)
    gps_ms = GPS_MS + round(now_s * 1000)
    status = AgentStatus(peer.id, gps_ms, lat, lon, 0.0, 0.0, 0.0, 0.0, 15)
    beat = Heartbeat(peer.id, gps_ms, config.mission_id, AgentType.VEHICLE)
    fleet.receive(
        Packet(config.mission_id, peer.id, 0, 1, False, (beat, status), 60), now_s, gps_ms
    )


def relative(config: AgentConfig, goto: Goto, north_m: float, east_m: float) -> tuple[float, float]:
    """(distance m, bearing deg) of a Goto from a point metres from the origin."""
    lat, lon = local(config, north_m, east_m)
    n = math.radians(goto.lat_deg - lat) * EARTH_RADIUS_M
    e = math.radians(goto.lon_deg - lon) * EARTH_RADIUS_M * math.cos(math.radians(lat))
    return math.hypot(n, e), math.degrees(math.atan2(e, n)) % 360


def point_orbit(config: AgentConfig, **changes: Any) -> OrbitBehavior:
    """The example's orbit made to circle a point 15 m up at (north 100, east 0)."""
    params = params_of(config, "orbit", agent=None, alt_m=None, **changes)
    lat, lon = local(config, 100, 0)
    params["center"] = {
        "north_m": 100,
        "east_m": 0,
        "up_m": 15,
        "lat": lat,
        "lon": lon,
        "alt_m": 15,
    }
    return OrbitBehavior(params)


def on_circle(config: AgentConfig, bearing_deg: float, radius_m: float = 15.0) -> Any:
    b = math.radians(bearing_deg)
    return at(config, 100 + radius_m * math.cos(b), radius_m * math.sin(b), alt_m=15.0)


@pytest.mark.parametrize(("direction", "sign"), [("cw", 1), ("ccw", -1)])
def test_the_lead_point_is_ahead_on_the_tangent_the_way_it_flies(direction: str, sign: int) -> None:
    config = compiled(*COPTER)
    run = Run(config, point_orbit(config, direction=direction))
    start = run.start(on_circle(config, 90))  # due east of the centre
    assert start[0] == set_mode(config, "GUIDED")
    (goto,) = start[1:]
    assert isinstance(goto, Goto) and goto.speed_m_s == 4 and goto.alt_m == 15
    distance, bearing = relative(config, goto, 100, 0)
    # lead_deg 45 round the circle, on the tangent at the vehicle's bearing: r / cos 45
    assert distance == pytest.approx(15 / math.cos(math.radians(45)), abs=1e-3)
    assert bearing == pytest.approx((90 + sign * 45) % 360, abs=1e-3)


@pytest.mark.parametrize(("out_m", "aimed_m"), [(2.0, 11.0), (-1.5, 18.0), (9.0, 7.5), (-9, 22.5)])
def test_the_lead_point_corrects_twice_the_distance_off_the_circle(
    out_m: float, aimed_m: float
) -> None:
    # the autopilot's lag carries the vehicle outwards: aim inside by twice its error,
    # within half and one and a half radii
    config = compiled(*COPTER)
    run = Run(config, point_orbit(config))
    (goto,) = run.start(on_circle(config, 180, radius_m=15 + out_m))[1:]
    assert isinstance(goto, Goto)
    distance, bearing = relative(config, goto, 100, 0)
    assert distance == pytest.approx(aimed_m / math.cos(math.radians(45)), abs=1e-3)
    assert bearing == pytest.approx(225, abs=1e-3)


def test_targets_stream_at_the_retarget_rate() -> None:
    config = compiled(*COPTER)
    assert config.loop_hz == 10 and params_of(config, "orbit")["retarget_hz"] == 2
    run = Run(config, point_orbit(config))
    run.start(on_circle(config, 0))
    ticks = []
    for tick in range(1, 21):
        status, commands = run.step(on_circle(config, tick * 3.0))
        assert status is Status.RUNNING
        if any(isinstance(c, Goto) for c in commands):
            ticks.append(tick)
            (goto,) = commands
            assert isinstance(goto, Goto)
            _, bearing = relative(config, goto, 100, 0)
            assert bearing == pytest.approx(tick * 3.0 + 45, abs=1e-3)
    assert ticks == [5, 10, 15, 20]  # every 0.5 s from the first Goto


def fly(
    orbit: OrbitBehavior, config: AgentConfig, bearings: list[float], **kw: Any
) -> list[Status]:
    run = Run(config, orbit)
    run.start(on_circle(config, bearings[0], **kw))
    return [run.step(on_circle(config, b, **kw))[0] for b in bearings[1:]]


def test_done_after_the_turns_counted_by_the_angle_swept() -> None:
    config = compiled(*COPTER)
    orbit = point_orbit(config, turns=2)
    # 7 degrees a tick clockwise; counting starts at the first update, at 7 degrees, so
    # 720 degrees are swept at the update at 728 (the 104th): DONE there, not before
    statuses = fly(orbit, config, [7.0 * i for i in range(0, 105)])
    assert statuses == [Status.RUNNING] * 103 + [Status.DONE]
    assert orbit.swept_deg == pytest.approx(721, abs=1e-3)


def test_the_wrong_way_round_counts_against_the_turns() -> None:
    config = compiled(*COPTER)
    orbit = point_orbit(config, turns=1)
    # from -10 (the first update) back to -180, then forward a full turn to +180
    back = [-10.0 * i for i in range(0, 19)]
    forward = [-180 + 10.0 * i for i in range(1, 37)]
    statuses = fly(orbit, config, back + forward)
    assert Status.DONE not in statuses
    assert orbit.swept_deg == pytest.approx(-170 + 360, abs=1e-3)
    # counter-clockwise, bearings falling: the same count the other way
    ccw = point_orbit(config, turns=1, direction="ccw")
    statuses = fly(ccw, config, [-7.0 * i for i in range(0, 54)])
    assert statuses == [Status.RUNNING] * 52 + [Status.DONE]


def test_turns_are_counted_only_once_on_the_circle() -> None:
    config = compiled(*COPTER)
    orbit = point_orbit(config, turns=1)
    # a full turn 40 m out (outside tolerance_m 5) counts nothing
    statuses = fly(orbit, config, [10.0 * i for i in range(0, 40)], radius_m=40.0)
    assert Status.DONE not in statuses and orbit.swept_deg == 0


def test_without_turns_it_circles_until_a_transition() -> None:
    config = compiled(*COPTER)
    orbit = point_orbit(config, turns=None)
    assert Status.DONE not in fly(orbit, config, [10.0 * i for i in range(0, 120)])
    assert orbit.swept_deg == pytest.approx(1180)


def test_round_an_agent_it_waits_for_its_status_then_circles_where_it_reports() -> None:
    config = compiled(*COPTER)
    fleet = fleet_for(config)
    run = Run(config, OrbitBehavior(params_of(config, "orbit")), fleet)
    me = at(config, 0, -20, alt_m=15.0)
    assert run.start(me) == [set_mode(config, "GUIDED")]  # no status yet: no target
    assert run.step(me) == (Status.RUNNING, [])
    report(config, fleet, 30, 0, now_s=0.2)
    status, commands = run.step(me)
    (goto,) = commands
    assert status is Status.RUNNING and isinstance(goto, Goto) and goto.alt_m == 15
    distance, _ = relative(config, goto, 30, 0)
    # 36 m from the rover, far outside the circle: aimed at half the radius (the clamp)
    assert distance == pytest.approx(7.5 / math.cos(math.radians(45)), abs=1e-3)


def test_wrap_is_the_short_way_round() -> None:
    assert math.degrees(wrap_rad(math.radians(350))) == pytest.approx(-10)
    assert math.degrees(wrap_rad(math.radians(-190))) == pytest.approx(170)
    assert wrap_rad(-math.pi) == math.pi
    assert offset_position(0.0, 0.0, 0.0, 0.0) == (0.0, 0.0)


def test_every_compiled_orbit_state_builds_its_runtime() -> None:
    (state,) = states_of(compiled(*COPTER), "orbit")
    assert state.params["agent"] == {"name": "slash", "id": 2}
