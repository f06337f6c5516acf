"""The launch that cannot fly (issue 17 item 7): the simulated pilot arms at the ready light.

A pilot arms when the autopilot shows itself ready: pre-arm checks passed, the EKF's
absolute position, and home. Arming on a streamed GPS position alone armed an
ArduCopter about 18 s before it was ready, and ArduCopter disarmed it again before the
engine could start the behaviour.
"""

from __future__ import annotations

import io
from pathlib import Path

from pymavlink.dialects.v20 import ardupilotmega as mavlink2

from clark_engine.dryrun.command import run_dry_run
from clark_engine.dryrun.engine import DryRun
from clark_engine.dryrun.pilot import SimPilot
from clark_engine.expectations.from_logs import check_folder
from clark_engine.validation import validate_file

HERE = Path(__file__).resolve().parent
COPTER = HERE / "dryrun" / "copter_pilot_takeoff.yaml"


class _Autopilot:
    """What the pilot talks to: records what it sends (a backend's two methods)."""

    def __init__(self) -> None:
        self.sent: list[bytes] = []

    def send(self, data: bytes, t_s: float) -> None:
        self.sent.append(data)

    def set_pilot(self, pwm_us: dict[int, int]) -> None:
        pass


class _Wire:
    """pymavlink's encoder writing into a list, as the autopilot (system 1)."""

    def __init__(self) -> None:
        self.buffer = bytearray()
        self.mav = mavlink2.MAVLink(self, srcSystem=1, srcComponent=1)

    def write(self, data: bytes) -> None:
        self.buffer += data

    def take(self) -> bytes:
        data, self.buffer = bytes(self.buffer), bytearray()
        return data


def _arm_commands(sent: list[bytes]) -> int:
    parser = mavlink2.MAVLink(None)
    count = 0
    for data in sent:
        for msg in parser.parse_buffer(data) or []:
            if msg.get_type() == "COMMAND_LONG" and msg.command == 400 and msg.param1 == 1:
                count += 1
    return count


def test_the_pilot_waits_for_the_ready_light_not_a_position() -> None:
    autopilot, wire = _Autopilot(), _Wire()
    pilot = SimPilot(autopilot, system_id=1, arms=True)  # type: ignore[arg-type]
    prearm = mavlink2.MAV_SYS_STATUS_PREARM_CHECK
    wire.mav.sys_status_send(prearm, prearm, prearm, 0, 12000, -1, -1, 0, 0, 0, 0, 0, 0)
    wire.mav.global_position_int_send(1000, 306372000, -964787000, 90000, 0, 0, 0, 0, 0)
    pilot.hear(wire.take(), 24.0)
    assert not pilot.sees_ready and _arm_commands(autopilot.sent) == 0, (
        "pre-arm checks and a GPS position are not ready: the EKF has no position yet"
    )
    const = mavlink2.EKF_POS_HORIZ_ABS | mavlink2.EKF_CONST_POS_MODE
    wire.mav.ekf_status_report_send(const, 0, 0, 0, 0, 0)
    pilot.hear(wire.take(), 30.0)
    assert not pilot.sees_ready, "an EKF in constant-position mode has no position source"
    wire.mav.ekf_status_report_send(mavlink2.EKF_POS_HORIZ_ABS, 0, 0, 0, 0, 0)
    pilot.hear(wire.take(), 40.0)
    assert not pilot.sees_ready and _arm_commands(autopilot.sent) == 0, "no home yet"
    wire.mav.home_position_send(306372000, -964787000, 90000, 0, 0, 0, [1, 0, 0, 0], 0, 0, 0)
    pilot.hear(wire.take(), 42.0)
    assert pilot.sees_ready
    assert _arm_commands(autopilot.sent) == 1


def test_a_copter_its_pilot_arms_takes_off() -> None:
    out, err = io.StringIO(), io.StringIO()
    outcome = run_dry_run(
        COPTER, seed=None, until_s=None, report=None, speed=None, out=out, err=err
    )
    assert outcome.exit_code == 0, out.getvalue() + err.getvalue()
    result = outcome.result
    assert result is not None
    entered = result.recording.entered_by("f450", "hover", 85.0)
    assert entered is not None
    track = result.recording.tracks["f450"]
    highest_m = max(up for _, _, _, up in track.samples())
    assert highest_m > 8.0, "it flew up (takeoff is done 1 m under its 10 m)"


def test_the_pilot_arms_once_the_autopilot_is_ready() -> None:
    validation = validate_file(COPTER, str(COPTER))
    assert validation.mission is not None
    run = DryRun(validation.mission, COPTER, seed=1, until_s=50.0)
    run.run()
    pilot = run.agents["f450"].pilot
    autopilot = run.agents["f450"].autopilot
    assert pilot is not None and autopilot is not None and pilot.armed_at_s is not None
    boot = autopilot.boot_times
    ready_s = max(boot.position_s, boot.prearm_s)
    assert pilot.armed_at_s >= ready_s, (pilot.armed_at_s, ready_s)


# -- when a state is never reached, the report says why ----------------------------------


def _variant(tmp_path: Path, old: str, new: str) -> Path:
    text = COPTER.read_text(encoding="utf-8")
    assert old in text
    path = tmp_path / "m.yaml"
    path.write_text(text.replace(old, new), encoding="utf-8")
    return path


def test_not_reached_while_waiting_for_readiness_says_what_it_waits_for(tmp_path: Path) -> None:
    # The run ends at 35 s: ArduCopter's EKF has no position before about 42 s.
    mission = _variant(
        tmp_path,
        "- {name: takes off, by_s: 85,",
        "- {name: takes off, by_s: 30,",
    )
    out, err = io.StringIO(), io.StringIO()
    outcome = run_dry_run(
        mission, seed=None, until_s=35.0, report=None, speed=None, out=out, err=err
    )
    (result,) = outcome.results
    assert result.verdict == "FAIL"
    assert result.observed == (
        "not reached (last: no state): the behaviour never started, waiting for an EKF "
        "position, the pilot to arm it"
    )
    # clark analyze --checks reads the same from the mission log.
    report = tmp_path / "report"
    run_dry_run(
        mission, seed=None, until_s=35.0, report=report, speed=None,
        out=io.StringIO(), err=io.StringIO(),
    )  # fmt: skip
    validated = validate_file(mission, str(mission)).mission
    assert validated is not None
    (from_logs,) = check_folder(report / "logs", validated).results
    assert from_logs.observed == result.observed


def test_not_reached_after_the_autopilot_disarmed_it(tmp_path: Path) -> None:
    # Its first state waits longer than the run: ArduCopter disarms the idle copter 10 s
    # after its pilot armed it.
    mission = _variant(
        tmp_path,
        "initial: climb\n",
        "initial: idle\n",
    )
    mission.write_text(
        mission.read_text(encoding="utf-8").replace(
            "      states:\n",
            "      states:\n"
            "        idle: {use: wait, timeout_s: 200, transitions: {timeout: climb}}\n",
        ),
        encoding="utf-8",
    )
    outcome = run_dry_run(
        mission, seed=None, until_s=None, report=None, speed=None,
        out=io.StringIO(), err=io.StringIO(),
    )  # fmt: skip
    (result,) = outcome.results
    assert outcome.result is not None
    pilot_armed = [e for e in outcome.result.recording.flight["f450"] if e.armed]
    disarmed = [e for e in outcome.result.recording.flight["f450"] if not e.armed][-1]
    assert pilot_armed and disarmed.time_s - pilot_armed[0].time_s >= 10.0
    assert result.verdict == "FAIL"
    assert result.observed == (
        f"not reached (last: idle): disarmed by the autopilot at {disarmed.time_s:.1f} s"
    )


def test_why_a_state_was_not_reached_from_the_recording() -> None:
    from clark_engine.expectations.evaluate import why_not_entered
    from clark_engine.expectations.recording import FlightEntry, Recording, StateEntry

    rec = Recording(end_s=100.0)
    rec.states["a"] = [StateEntry(40.0, "start", ("go",), ("go",))]
    rec.safety["a"] = [(50.0, "failsafe hold"), (60.0, "autopilot_lost")]
    rec.killed["a"] = 70.0
    assert why_not_entered(rec, "a", 100.0) == (
        "its mission computer was killed at 70.0 s (fault); the behaviour was stopped by a "
        "failsafe (hold) at 50.0 s; its autopilot was lost at 60.0 s"
    )
    assert why_not_entered(rec, "a", 45.0) == ""  # nothing had happened yet
    rec.waiting["b"] = ("a 3-D GPS fix", "the pilot to arm it")
    rec.flight["b"] = [FlightEntry(0.0, False, "MANUAL"), FlightEntry(24.0, True, "MANUAL"),
                       FlightEntry(34.0, False, "MANUAL")]  # fmt: skip
    assert why_not_entered(rec, "b", 100.0) == (
        "the behaviour never started, waiting for a 3-D GPS fix, the pilot to arm it; armed "
        "at 24.0 s and disarmed by the autopilot at 34.0 s, before the behaviour started"
    )
