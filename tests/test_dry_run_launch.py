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

from clark_engine.sim.dryrun import run_dry_run
from clark_engine.sim.engine import DryRun
from clark_engine.sim.pilot import SimPilot
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
