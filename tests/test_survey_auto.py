"""survey's ``fly_as: auto``: the lines uploaded to the autopilot and flown in AUTO.

The behaviour's commands and its DONE on a virtual clock (as tests/test_survey.py's
guided runtime), the adapter's encoding of the upload against a scripted autopilot, the
envelope guard refusing a mission with a waypoint outside, the validator's findings,
and a dry run of the example. The same example on ArduPilot SITL, compared with the
simulated autopilot: tests/test_dry_run_sitl.py.
"""

from __future__ import annotations

import json
import logging
import subprocess
import sys
from pathlib import Path
from typing import Any

import pytest
from pymavlink.dialects.v20 import ardupilotmega as mavlink2

from clark_engine.behaviors.base import Status
from clark_engine.behaviors.survey import SurveyBehavior
from clark_engine.io.autopilot import AutopilotAdapter, AutopilotSettings
from clark_engine.link.fleet import FleetTable
from clark_engine.mission.compiler import agent_config
from clark_engine.mission.validate import validate_path
from clark_engine.runtime.commands import (
    Goto,
    MissionItem,
    PayloadCommand,
    SetMode,
    UploadMission,
)
from clark_engine.runtime.config import AgentConfig, config_from_dict
from clark_engine.runtime.context import Outbox, PrimitiveContext, offset_position
from clark_engine.runtime.envelope_guard import EnvelopeGuard
from clark_engine.runtime.events import MissionProgress, MissionUploadResult, VehicleState
from clark_engine.runtime.logbook import Logbook
from clark_engine.runtime.runtime import AgentRuntime

ROOT = Path(__file__).resolve().parents[1]
EXAMPLE = ROOT / "missions" / "survey_auto.yaml"
GPS_MS = 1_400_000_000_000


def _compiled(path: Path = EXAMPLE, agent: str = "f450") -> AgentConfig:
    result = validate_path(path)
    assert result.mission is not None, [str(f) for f in result.findings]
    data = json.loads(json.dumps(agent_config(result.mission, result.mission.agents[agent])))
    return config_from_dict(data)


def _survey_params(config: AgentConfig) -> dict[str, Any]:
    assert config.machine is not None
    params: dict[str, Any] = next(
        s.params for s in config.machine.walk() if s.primitive == "survey"
    )
    return params


def _at(config: AgentConfig, north_m: float, east_m: float, mode: str = "AUTO") -> VehicleState:
    lat, lon = offset_position(config.origin_lat_deg, config.origin_lon_deg, north_m, east_m)
    return VehicleState(GPS_MS, lat, lon, 20.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, mode, 0, True)


class _Clock:
    """The survey on a virtual clock, one update per tick, commands per call."""

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

    def _begin(self, state: VehicleState) -> list[Any]:
        self.ctx.outbox = Outbox()
        self.ctx.now_s = self.tick / self.ctx.config.loop_hz
        self.tick += 1
        self.ctx.vehicle = state
        return self.ctx.outbox.commands

    def start(self, state: VehicleState) -> list[Any]:
        commands = self._begin(state)
        self.survey.start(self.ctx)
        return list(commands)

    def step(self, state: VehicleState) -> tuple[Status, list[Any]]:
        commands = self._begin(state)
        return self.survey.update(self.ctx), list(commands)

    def hear(self, event: MissionUploadResult | MissionProgress) -> list[Any]:
        self.ctx.outbox = Outbox()
        self.survey.on_mission(self.ctx, event)
        return list(self.ctx.outbox.commands)


# ------------------------------------------------------------------ the behaviour


def test_uploads_the_lines_sets_auto_once_accepted_photographs_and_is_done_at_the_end() -> None:
    config = _compiled()
    params = _survey_params(config)
    assert params["fly_as"] == "auto"
    survey = SurveyBehavior(params)
    clock = _Clock(config, survey)
    lines = params["lines"]
    commands = clock.start(_at(config, 0, 0, "GUIDED"))
    # One upload: the speed, then each line's start and end; no Goto, no mode yet.
    (upload,) = [c for c in commands if isinstance(c, UploadMission)]
    assert not [c for c in commands if isinstance(c, (Goto, SetMode))]
    ends = [line[end] for line in lines for end in ("start", "end")]
    assert upload.items == (
        MissionItem("speed", speed_m_s=5.0),
        *(MissionItem("waypoint", e["lat"], e["lon"], e["alt_m"]) for e in ends),
    )
    status, commands = clock.step(_at(config, 0, 0, "GUIDED"))
    assert status is Status.RUNNING and commands == []
    # Accepted: AUTO is asked for.
    commands = clock.hear(MissionUploadResult(upload.upload_id, True, "ACCEPTED"))
    assert commands == [SetMode("AUTO", 3)]
    clock.hear(MissionProgress(1, 5))  # MISSION_CURRENT: the first line's start is flown
    status, commands = clock.step(_at(config, 10, 10, "AUTO"))
    assert status is Status.RUNNING and commands == []  # no picture on the way to it
    captures: list[PayloadCommand] = []
    for index, line in enumerate(lines):
        a, b = line["start"], line["end"]
        clock.hear(MissionProgress(1 + 2 * index, reached=True))  # its start reached
        sign = 1.0 if b["north_m"] > a["north_m"] else -1.0
        for metre in range(0, 59):  # along the line a metre a tick, 1 m short of its end
            status, commands = clock.step(_at(config, a["north_m"] + sign * metre, a["east_m"]))
            assert status is Status.RUNNING
            captures.extend(c for c in commands if isinstance(c, PayloadCommand))
        assert len(captures) == 5 * index + 4, index  # 0, 15, 30, 45 m; 60 m still due
        # The autopilot says its end is reached: the last mark is taken.
        clock.hear(MissionProgress(2 + 2 * index, reached=True))
        status, commands = clock.step(_at(config, b["north_m"] - sign * 1.0, b["east_m"]))
        captures.extend(c for c in commands if isinstance(c, PayloadCommand))
        assert len(captures) == 5 * (index + 1), index
    assert status is Status.DONE
    assert survey.requested == 10


def test_not_done_until_the_vehicle_is_at_the_last_end() -> None:
    config = _compiled()
    params = _survey_params(config)
    survey = SurveyBehavior(params)
    clock = _Clock(config, survey)
    (upload,) = [c for c in clock.start(_at(config, 0, 0)) if isinstance(c, UploadMission)]
    clock.hear(MissionUploadResult(upload.upload_id, True, "ACCEPTED"))
    clock.hear(MissionProgress(4, reached=True))  # the last waypoint (items: speed + 4)
    last = params["lines"][-1]["end"]
    status, _ = clock.step(_at(config, last["north_m"] + 10, last["east_m"]))
    assert status is Status.RUNNING  # reported reached, but 10 m away: not yet
    status, _ = clock.step(_at(config, last["north_m"] + 1, last["east_m"]))
    assert status is Status.DONE


def test_a_refused_upload_fails_the_survey_and_another_upload_is_not_ours() -> None:
    config = _compiled()
    survey = SurveyBehavior(_survey_params(config))
    clock = _Clock(config, survey)
    (upload,) = [c for c in clock.start(_at(config, 0, 0)) if isinstance(c, UploadMission)]
    assert clock.hear(MissionUploadResult(upload.upload_id + 7, False, "NO_SPACE")) == []
    assert clock.step(_at(config, 0, 0))[0] is Status.RUNNING
    clock.hear(MissionUploadResult(upload.upload_id, False, "NO_SPACE", "Only 5 items"))
    assert clock.step(_at(config, 0, 0))[0] is Status.FAILED


def test_an_upload_that_never_got_an_outcome_is_sent_again() -> None:
    """The runtime drops vehicle commands while the autopilot is lost: no answer comes."""
    config = _compiled()
    survey = SurveyBehavior(_survey_params(config))
    clock = _Clock(config, survey)
    (first,) = [c for c in clock.start(_at(config, 0, 0)) if isinstance(c, UploadMission)]
    sent = [clock.step(_at(config, 0, 0))[1] for _ in range(100)]  # 10 s
    again = [c for commands in sent for c in commands if isinstance(c, UploadMission)]
    assert len(again) == 1 and again[0].items == first.items
    assert again[0].upload_id != first.upload_id
    # An answer to the first is no longer the survey's.
    assert clock.hear(MissionUploadResult(first.upload_id, True, "ACCEPTED")) == []
    assert clock.hear(MissionUploadResult(again[0].upload_id, True, "ACCEPTED")) == [
        SetMode("AUTO", 3)
    ]


def test_a_pilot_who_takes_the_mode_is_never_fought() -> None:
    config = _compiled()
    survey = SurveyBehavior(_survey_params(config))
    clock = _Clock(config, survey)
    (upload,) = [
        c for c in clock.start(_at(config, 0, 0, "GUIDED")) if isinstance(c, UploadMission)
    ]
    assert clock.hear(MissionUploadResult(upload.upload_id, True, "ACCEPTED")) == [
        SetMode("AUTO", 3)
    ]
    # Refused for a while: asked again each second, as waypoint's guided mode is.
    asked = [clock.step(_at(config, 0, 0, "GUIDED"))[1] for _ in range(11)]
    assert sum(c == [SetMode("AUTO", 3)] for c in asked) == 1
    clock.step(_at(config, 0, 0, "AUTO"))
    # The pilot switches to LOITER: the survey goes on, never asking for AUTO again.
    for _ in range(30):
        status, commands = clock.step(_at(config, 5, 5, "LOITER"))
        assert status is Status.RUNNING
        assert not [c for c in commands if isinstance(c, SetMode)]


def test_guided_is_the_default_and_is_not_written_into_the_config() -> None:
    config = _compiled(ROOT / "missions" / "survey_field.yaml")
    params = _survey_params(config)
    assert "fly_as" not in params
    assert SurveyBehavior(params).fly_as == "guided"


# ------------------------------------------------------------- the adapter's upload

_AUTOPILOT = mavlink2.MAVLink(None, srcSystem=1, srcComponent=1)


def _frames(*messages: Any) -> bytes:
    return b"".join(m.pack(_AUTOPILOT) for m in messages)


def _sent(data: bytes) -> list[Any]:
    parser = mavlink2.MAVLink(None)
    return list(parser.parse_buffer(data) or [])


def _adapter(firmware: str = "arducopter") -> AutopilotAdapter:
    adapter = AutopilotAdapter(
        AutopilotSettings(modes={"GUIDED": 4, "AUTO": 3}, firmware=firmware, origin_alt_amsl_m=90)
    )
    adapter.start(0.0)
    # Home 5 m above the origin: heights above the origin go out 5 m lower, above home.
    adapter.receive(
        _frames(
            mavlink2.MAVLink_home_position_message(
                306372000, -964787000, 95000, 0, 0, 0, [1, 0, 0, 0], 0, 0, 0
            )
        ),
        0.1,
    )
    return adapter


def test_the_upload_encodes_home_the_speed_and_each_waypoint_above_home() -> None:
    adapter = _adapter()
    items = (
        MissionItem("speed", speed_m_s=5.0),
        MissionItem("waypoint", 30.6373799, -96.4785171, 20.0),
        MissionItem("waypoint", 30.6379195, -96.4785171, 20.0),
    )
    (count,) = [
        m
        for m in _sent(adapter.command(UploadMission(7, items, "test"), 1.0))
        if m.get_type() == "MISSION_COUNT"
    ]
    assert (count.count, count.mission_type) == (4, mavlink2.MAV_MISSION_TYPE_MISSION)
    sent = []
    for seq in range(4):
        answer = adapter.receive(
            _frames(mavlink2.MAVLink_mission_request_int_message(255, 191, seq, 0)), 1.1 + seq
        )
        assert answer == []
        (item,) = _sent(adapter.flush())
        sent.append(item)
    assert [i.seq for i in sent] == [0, 1, 2, 3]
    home, speed, first, second = sent
    assert (home.command, home.x, home.y, home.z) == (16, 306372000, -964787000, 95.0)
    assert (speed.command, speed.frame, speed.param1, speed.param2, speed.param3) == (
        mavlink2.MAV_CMD_DO_CHANGE_SPEED,
        mavlink2.MAV_FRAME_MISSION,
        1.0,  # ground speed (ArduPlane: 0, airspeed)
        5.0,
        -1.0,
    )
    for item, lat in ((first, 306373799), (second, 306379195)):
        assert item.command == mavlink2.MAV_CMD_NAV_WAYPOINT
        assert item.frame == mavlink2.MAV_FRAME_GLOBAL_RELATIVE_ALT_INT
        assert (item.x, item.y, item.z) == (lat, -964785171, 15.0)
        assert item.autocontinue == 1 and item.mission_type == 0
    events = adapter.receive(_frames(mavlink2.MAVLink_mission_ack_message(255, 191, 0, 0)), 5.0)
    assert events == [MissionUploadResult(7, True, "ACCEPTED")]
    (current,) = _sent(adapter.flush())
    assert current.get_type() == "MISSION_SET_CURRENT" and current.seq == 1
    # Progress, counted in the command's items (ArduPilot's seq less its home); before
    # ArduPilot shows the first item current, its current item may be an old mission's.
    events = adapter.receive(
        _frames(
            mavlink2.MAVLink_mission_current_message(3, 3, 2, 0),
            mavlink2.MAVLink_mission_current_message(1, 3, 3, 1),
            mavlink2.MAVLink_mission_current_message(1, 3, 3, 1),  # unchanged: once
            mavlink2.MAVLink_mission_item_reached_message(2),
        ),
        6.0,
    )
    assert events == [MissionProgress(0, 3), MissionProgress(1, 3, reached=True)]


def test_a_refused_upload_names_ardupilots_result() -> None:
    adapter = _adapter()
    adapter.command(UploadMission(3, (MissionItem("waypoint", 30.6, -96.4, 20.0),)), 1.0)
    events = adapter.receive(
        _frames(
            mavlink2.MAVLink_statustext_message(4, b"Only 1 items are supported"),
            mavlink2.MAVLink_mission_ack_message(255, 191, mavlink2.MAV_MISSION_NO_SPACE, 0),
        ),
        1.5,
    )
    (result,) = [e for e in events if isinstance(e, MissionUploadResult)]
    assert (result.upload_id, result.accepted, result.result) == (3, False, "NO_SPACE")
    assert "Only 1 items are supported" in result.reason


def test_an_upload_waits_for_a_safety_set_up_and_one_upload_at_a_time() -> None:
    from clark_engine.runtime.commands import SetUpAutopilotSafety, UploadFence

    adapter = _adapter()
    adapter.command(SetUpAutopilotSafety((), (UploadFence(),)), 1.0)
    data = adapter.command(UploadMission(1, (MissionItem("waypoint", 30.6, -96.4, 20.0),)), 1.0)
    assert not [m for m in _sent(data) if m.get_type() == "MISSION_COUNT"]
    # The fence list (cleared: no zones) is accepted: the set-up is over, the mission goes.
    adapter.receive(_frames(mavlink2.MAVLink_mission_ack_message(255, 191, 0, 1)), 1.2)
    data = adapter.command(UploadMission(2, (MissionItem("waypoint", 30.6, -96.4, 20.0),)), 1.3)
    data += adapter.poll(1.3)
    counts = [m for m in _sent(data) if m.get_type() == "MISSION_COUNT"]
    assert [(c.count, c.mission_type) for c in counts] == [(2, 0)]  # only the first
    events = adapter.receive(_frames(mavlink2.MAVLink_mission_ack_message(255, 191, 0, 0)), 2.0)
    assert MissionUploadResult(1, True, "ACCEPTED") in events
    counts = [m for m in _sent(adapter.poll(2.1)) if m.get_type() == "MISSION_COUNT"]
    assert [c.count for c in counts] == [2]  # the second, after the first


def _upload(upload_id: int) -> UploadMission:
    return UploadMission(upload_id, (MissionItem("waypoint", 30.6, -96.4, 20.0),))


def test_waiting_uploads_are_bounded_and_none_outlives_a_silent_autopilot() -> None:
    from clark_engine.runtime.commands import SetUpAutopilotSafety, UploadFence

    adapter = _adapter()
    adapter.receive(_frames(mavlink2.MAVLink_heartbeat_message(2, 3, 0, 4, 4, 3)), 0.2)
    adapter.command(SetUpAutopilotSafety((), (UploadFence(),)), 1.0)  # the fence first
    for upload_id in range(1, 7):  # six wait: the two oldest are superseded
        adapter.command(_upload(upload_id), 1.0 + upload_id / 10)
    refused = [e for e in adapter.receive(b"", 1.7) if isinstance(e, MissionUploadResult)]
    assert refused == [MissionUploadResult(i, False, "SUPERSEDED") for i in (1, 2)]
    # The autopilot falls silent (no heartbeat for its 3 s timeout): the uploads waiting
    # are dropped, never sent when the link returns.
    adapter.poll(3.5)
    lost = [e for e in adapter.receive(b"", 3.6) if isinstance(e, MissionUploadResult)]
    assert lost == [MissionUploadResult(i, False, "AUTOPILOT_LOST") for i in (3, 4, 5, 6)]
    adapter.receive(
        _frames(
            mavlink2.MAVLink_heartbeat_message(2, 3, 0, 4, 4, 3),
            mavlink2.MAVLink_mission_ack_message(255, 191, 0, 1),  # the fence taken
        ),
        4.0,
    )
    counts = [m for m in _sent(adapter.poll(4.1)) if m.get_type() == "MISSION_COUNT"]
    assert counts == []


def test_progress_past_the_end_of_the_uploaded_mission_is_not_reported() -> None:
    adapter = _adapter()
    adapter.command(_upload(5), 1.0)
    adapter.receive(_frames(mavlink2.MAVLink_mission_ack_message(255, 191, 0, 0)), 1.5)
    events = adapter.receive(
        _frames(
            mavlink2.MAVLink_mission_item_reached_message(7),  # not an item of ours
            mavlink2.MAVLink_mission_item_reached_message(1),
        ),
        2.0,
    )
    assert [e for e in events if isinstance(e, MissionProgress)] == [
        MissionProgress(0, 1, reached=True)
    ]


# ------------------------------------------------------------------ the envelope


def _runtime(config: AgentConfig) -> AgentRuntime:
    return AgentRuntime(config, logbook=Logbook.in_memory(config), gps_epoch_ms=0)


def test_the_guard_passes_a_mission_inside_and_refuses_one_with_a_waypoint_outside(
    caplog: pytest.LogCaptureFixture,
) -> None:
    config = _compiled()
    assert config.envelope is not None
    guard = EnvelopeGuard(config, config.envelope, logging.getLogger("test.mission"))
    here = _at(config, 0, 0)
    inside = UploadMission(
        1,
        (
            MissionItem("speed", speed_m_s=5.0),
            MissionItem("waypoint", here.lat_deg, here.lon_deg, 20.0),
        ),
    )
    assert guard.check(inside, here, (), 1.0) is inside
    far_lat, far_lon = offset_position(config.origin_lat_deg, config.origin_lon_deg, 5000, 0)
    outside = UploadMission(
        2,
        (*inside.items, MissionItem("waypoint", far_lat, far_lon, 20.0)),
        "survey: 1 line",
    )
    high = UploadMission(3, (MissionItem("waypoint", here.lat_deg, here.lon_deg, 500.0),))
    with caplog.at_level(logging.WARNING, logger="test.mission"):
        assert guard.check(outside, here, (), 2.0) is None
        assert guard.check(high, here, (), 3.0) is None
    text = caplog.text
    assert "UploadMission refused (fence)" in text
    assert "item 2 (north 5000.0 m, east 0.0 m) is" in text and "outside the geofence" in text
    assert "the whole mission not sent" in text
    assert "UploadMission refused (ceiling)" in text
    counts = guard.counts
    assert (counts.checked, counts.refused) == (3, 2)
    assert counts.refused_by == {"fence": 1, "ceiling": 1}


def test_a_refused_upload_never_leaves_the_runtime_and_fails_the_survey() -> None:
    """The runtime's guard drops the upload whole and tells the behaviour (ENVELOPE)."""
    config = _compiled()
    survey = SurveyBehavior(_survey_params(config))
    runtime = _runtime(config)
    far_lat, far_lon = offset_position(config.origin_lat_deg, config.origin_lon_deg, 5000, 0)
    heard: list[Any] = []

    class _Machine:
        def deliver_mission(self, _ctx: PrimitiveContext, event: Any) -> None:
            heard.append(event)
            survey.on_mission(_ctx, event)

    runtime.machine = _Machine()  # type: ignore[assignment]
    runtime.context.vehicle = _at(config, 0, 0)
    ctx = runtime.context
    survey.start(ctx)
    (upload,) = ctx.outbox.commands
    assert isinstance(upload, UploadMission)
    bad = UploadMission(
        upload.upload_id, (*upload.items, MissionItem("waypoint", far_lat, far_lon, 20.0))
    )
    runtime._commands = [bad]
    assert runtime._drain() == []
    assert heard == [MissionUploadResult(upload.upload_id, False, "ENVELOPE", heard[0].reason)]
    assert survey.update(ctx) is Status.FAILED


# ------------------------------------------------------------------ the checks


def _write(tmp_path: Path, text: str) -> Path:
    path = tmp_path / "mission.yaml"
    path.write_text(text.replace("../schemas/", str(ROOT / "schemas") + "/"), encoding="utf-8")
    return path


def test_the_example_is_valid_and_a_copter_needs_no_radius(tmp_path: Path) -> None:
    text = EXAMPLE.read_text(encoding="utf-8").replace(
        "tolerance_m: 2\n            fly_as", "tolerance_m: 0.5\n            fly_as"
    )
    assert "tolerance_m: 0.5" in text
    findings = [f for f in validate_path(_write(tmp_path, text)).findings if f.is_error]
    assert findings == []  # ArduCopter settles on its last waypoint


def test_a_rover_whose_tolerance_is_under_its_waypoint_radius_is_told(tmp_path: Path) -> None:
    text = """clark: 1
mission: {id: 1, name: demo, loop_hz: 10, origin: {lat: 30.6372, lon: -96.4787, alt_amsl_m: 90}}
agents:
  slash:
    id: 2
    profile: traxxas_slash
    hardware: {payloads: {camera: {profile: raspberry_pi_camera}}}
    telemetry: {heartbeat: 1}
    behavior:
      use: survey
      with:
        area: [[20, 10], [80, 10], [80, 40], [20, 40]]
        altitude_m: 1
        line_spacing_m: 15
        tolerance_m: 1
        fly_as: auto
"""
    findings = [f for f in validate_path(_write(tmp_path, text)).findings if f.is_error]
    assert [f.code for f in findings] == ["E-SURVEY-AUTO-RADIUS"]
    assert "at least 3 m" in findings[0].message
    ok = text.replace("tolerance_m: 1\n", "tolerance_m: 3\n")
    assert not [f for f in validate_path(_write(tmp_path, ok)).findings if f.is_error]
    guided = text.replace("        fly_as: auto\n", "")
    assert not [f for f in validate_path(_write(tmp_path, guided)).findings if f.is_error]


def test_an_autopilot_without_auto_is_told_at_the_use(tmp_path: Path) -> None:
    profiles = tmp_path / "my_profiles"
    profiles.mkdir()
    copter = (ROOT / "hardware_profiles" / "autopilots" / "pixhawk_arducopter.yaml").read_text(
        encoding="utf-8"
    )
    copter = copter.replace("profile: pixhawk_arducopter", "profile: my_arducopter").replace(
        "  AUTO: 3\n", ""
    )
    (profiles / "my_arducopter.yaml").write_text(copter, encoding="utf-8")
    text = (
        EXAMPLE.read_text(encoding="utf-8")
        .replace(
            '    hardware:\n      radio: {address: "0013A20040A1B202"}',
            "    hardware:\n      autopilot: my_arducopter\n"
            '      radio: {address: "0013A20040A1B202"}',
        )
        .replace("agents:\n", "include: {hardware_profiles: [my_profiles]}\nagents:\n", 1)
    )
    findings = [f for f in validate_path(_write(tmp_path, text)).findings if f.is_error]
    assert [f.code for f in findings] == ["E-SURVEY-AUTO"], [str(f) for f in findings]
    assert "names no AUTO mode" in findings[0].message
    assert findings[0].location.dotted_path.endswith("with.fly_as")


# ------------------------------------------------------------------ the dry run


def test_the_example_flies_its_mission_in_the_dry_run(tmp_path: Path) -> None:
    run = subprocess.run(
        [
            sys.executable,
            "-m",
            "clark_engine",
            "dry-run",
            str(EXAMPLE),
            "-q",
            "--report",
            str(tmp_path / "report"),
        ],
        cwd=ROOT,
        capture_output=True,
        text=True,
        timeout=300,
        check=False,
    )
    assert run.returncode == 0, run.stdout + run.stderr
    assert "**FAIL**" not in run.stdout  # photos at every mark, the lines' ends reached
    mission_log = (tmp_path / "report" / "logs" / "f450.mission.log").read_text(encoding="utf-8")
    interface_log = (tmp_path / "report" / "logs" / "f450.interface.log").read_text(
        encoding="utf-8"
    )
    assert "the autopilot accepted the mission survey: 2 line(s), 4 waypoints" in interface_log
    assert "survey: the autopilot took the mission; flying it in AUTO" in mission_log
    assert "the autopilot reached waypoint 4 of 4" in mission_log
    assert "10 photos" in run.stdout
    # The report draws the path flown, its waypoints and the pictures where they were taken.
    assert (tmp_path / "report" / "tracks.png").stat().st_size > 0
