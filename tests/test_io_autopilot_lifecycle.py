"""The autopilot adapter's side of the vehicle lifecycle, against frames ArduPilot sends.

An "autopilot" here is a pymavlink encoder with ArduPilot's ids writing the frames
the real firmware sends (as measured on SITL: readiness messages, STATUSTEXT before
a refusal's COMMAND_ACK, lat/lon 0 before the GPS fix); the adapter under test gets
their bytes, and what it sends back is parsed by a strict pymavlink parser.
"""

from __future__ import annotations

import math
from typing import Any

import pytest
from pymavlink.dialects.v20 import ardupilotmega as mavlink2

from clark_engine.io.autopilot import AutopilotAdapter
from clark_engine.io.autopilot_flight import SPEED_RETRY_S
from clark_engine.io.autopilot_requests import ACK_TIMEOUT_S, REASON_WAIT_S
from clark_engine.io.autopilot_settings import AutopilotSettings
from clark_engine.runtime.commands import Arm, Goto, Takeoff
from clark_engine.runtime.events import (
    AutopilotStatus,
    AutopilotText,
    CommandRefused,
    LandedState,
    VehicleState,
)
from clark_engine.untrusted import printable

MODES = {"MANUAL": 0, "HOLD": 4, "GUIDED": 15, "TAKEOFF": 13}


class Autopilot:
    """ArduPilot's side of the link: encodes frames from system 1, component 1."""

    def __init__(self, adapter: AutopilotAdapter) -> None:
        self.adapter = adapter
        self.out = bytearray()
        self.mav = mavlink2.MAVLink(self, srcSystem=1, srcComponent=1)
        self.parser = mavlink2.MAVLink(None, 255, 191)
        self.now_s = 0.0

    def write(self, data: bytes) -> None:
        self.out += data

    def say(self, *messages: Any) -> list[Any]:
        """Send frames to the adapter; the events it returns."""
        for message in messages:
            self.mav.send(message)
        data, self.out = bytes(self.out), bytearray()
        return self.adapter.receive(data, self.now_s)

    def heard(self, data: bytes) -> list[Any]:
        """What the adapter sent, parsed strictly, but heartbeats and connection set-up."""
        return [
            m
            for m in self.parser.parse_buffer(data) or []
            if m.get_type() != "HEARTBEAT"
            and not (
                m.get_type() == "COMMAND_LONG"
                and m.command
                in (
                    mavlink2.MAV_CMD_SET_MESSAGE_INTERVAL,
                    mavlink2.MAV_CMD_REQUEST_MESSAGE,
                    mavlink2.MAV_CMD_REQUEST_AUTOPILOT_CAPABILITIES,
                )
            )
        ]

    def heartbeat(self, mode: str = "GUIDED", armed: bool = False) -> Any:
        base = mavlink2.MAV_MODE_FLAG_CUSTOM_MODE_ENABLED
        if armed:
            base |= mavlink2.MAV_MODE_FLAG_SAFETY_ARMED
        return self.mav.heartbeat_encode(
            mavlink2.MAV_TYPE_GROUND_ROVER,
            mavlink2.MAV_AUTOPILOT_ARDUPILOTMEGA,
            base,
            MODES[mode],
            mavlink2.MAV_STATE_ACTIVE,
        )

    def ack(self, command: int, result: int) -> Any:
        return self.mav.command_ack_encode(command, result, 0, 0, 255, 191)


def bench(
    firmware: str = "ardurover", origin_alt_amsl_m: float = 0.0
) -> tuple[AutopilotAdapter, Autopilot]:
    adapter = AutopilotAdapter(
        AutopilotSettings(modes=MODES, firmware=firmware, origin_alt_amsl_m=origin_alt_amsl_m)
    )
    autopilot = Autopilot(adapter)
    adapter.start(0.0)
    return adapter, autopilot


def of(events: list[Any], kind: type) -> list[Any]:
    return [e for e in events if isinstance(e, kind)]


def test_readiness_follows_what_ardupilot_reports_and_is_sent_on_change() -> None:
    adapter, ap = bench()
    assert not adapter.status.ready
    no_fix = ap.mav.gps_raw_int_encode(0, 0, 0, 0, 0, 65535, 65535, 0, 0, 0)
    assert of(ap.say(no_fix), AutopilotStatus) == []  # nothing changed: nothing sent
    assert adapter.status.waiting_for == ("a 3-D GPS fix", "an EKF position", "a home position")
    fix = ap.mav.gps_raw_int_encode(0, 3, 306372000, -964787000, 90000, 121, 200, 0, 0, 10)
    attitude_only = ap.mav.ekf_status_report_encode(0xA7, 0, 0, 0, 0, 0)
    prearm = mavlink2.MAV_SYS_STATUS_PREARM_CHECK
    not_yet = ap.mav.sys_status_encode(prearm, prearm, 0, 0, 12600, 0, 100, 0, 0, 0, 0, 0, 0)
    events = ap.say(fix, attitude_only, not_yet)
    assert of(events, AutopilotStatus)[-1].waiting_for == (
        "an EKF position",
        "the pre-arm checks",
        "a home position",
    )
    home = ap.mav.home_position_encode(
        306372000, -964787000, 90000, 0, 0, 0, [math.nan] * 4, 0, 0, 0
    )
    position = ap.mav.ekf_status_report_encode(0x33F, 0, 0, 0, 0, 0)
    passed = ap.mav.sys_status_encode(prearm, prearm, prearm, 0, 12600, 0, 100, 0, 0, 0, 0, 0, 0)
    landed = ap.mav.extended_sys_state_encode(0, mavlink2.MAV_LANDED_STATE_ON_GROUND)
    last = of(ap.say(home, position, passed, landed), AutopilotStatus)[-1]
    assert last.ready
    assert last.home == (30.6372, -96.4787, 90.0)
    assert last.landed is LandedState.ON_GROUND
    assert adapter.status == last


def test_constant_position_mode_is_no_position() -> None:
    adapter, ap = bench()
    ap.say(ap.mav.ekf_status_report_encode(0x10 | 0x80, 0, 0, 0, 0, 0))
    assert adapter.status.position_ok is False


def test_an_autopilot_without_the_prearm_bit_is_not_held_back_by_it() -> None:
    adapter, ap = bench()
    ap.say(ap.mav.sys_status_encode(0, 0, 0, 0, 12600, 0, 100, 0, 0, 0, 0, 0, 0))
    assert adapter.status.prearm_ok is None
    assert "the pre-arm checks" not in adapter.status.waiting_for


def test_no_vehicle_state_before_the_first_fix() -> None:
    _adapter, ap = bench()
    ap.say(ap.heartbeat(), ap.mav.attitude_encode(0, 0, 0, 0, 0, 0, 0))
    nowhere = ap.mav.global_position_int_encode(3000, 0, 0, 150, 305, 0, 0, 0, 0)
    assert of(ap.say(nowhere), VehicleState) == []
    # ArduPlane's dead reckoning from 0, 0 before its fix is no position either.
    drifting = ap.mav.global_position_int_encode(4000, 1047, -45, 150, 305, 0, 0, 0, 0)
    no_fix = ap.mav.gps_raw_int_encode(0, 1, 0, 0, 0, 65535, 65535, 0, 0, 0)
    assert of(ap.say(no_fix, drifting), VehicleState) == []
    fix = ap.mav.gps_raw_int_encode(0, 6, 306372000, -964787000, 90000, 121, 200, 0, 0, 10)
    here = ap.mav.global_position_int_encode(10000, 306372000, -964787000, 90000, 0, 0, 0, 0, 0)
    (state,) = of(ap.say(fix, here), VehicleState)
    assert (state.lat_deg, state.lon_deg) == (30.6372, -96.4787)


def test_statustext_becomes_an_event_and_an_escaped_log_line(caplog: Any) -> None:
    _adapter, ap = bench()
    hostile = "PreArm: x\n[CRIT] forged\x1b[2J"
    (text,) = of(ap.say(ap.mav.statustext_encode(2, hostile.encode())), AutopilotText)
    assert text == AutopilotText(2, hostile)
    lines = [r.getMessage() for r in caplog.records]
    assert any(printable(hostile) in line for line in lines)
    assert not any("\n" in line or "\x1b" in line for line in lines)


def test_printable_escapes_what_could_forge_a_line_and_bounds_the_length() -> None:
    assert printable("ok: PreArm") == "ok: PreArm"
    assert printable("a\nb\\c\x00") == "a\\x0ab\\\\c\\x00"
    assert printable("\u202e\U0001f600") == "\\u202e\U0001f600"
    cut = printable("x" * 500, limit=20)
    assert len(cut) == 20 and cut.endswith("...")


def test_a_refused_arm_carries_ardupilots_reason() -> None:
    adapter, ap = bench()
    ap.heard(adapter.command(Arm(), 1.0))
    ap.now_s = 1.1
    # ArduPilot sends the reason, then the COMMAND_ACK (measured order).
    events = ap.say(
        ap.mav.statustext_encode(2, b"Arm: Need Position Estimate"),
        ap.ack(mavlink2.MAV_CMD_COMPONENT_ARM_DISARM, mavlink2.MAV_RESULT_FAILED),
    )
    assert of(events, CommandRefused) == []  # waits a moment for a late reason
    later = adapter.receive(adapter.poll(1.1 + REASON_WAIT_S) and b"", 1.1 + REASON_WAIT_S)
    (refusal,) = of(later, CommandRefused)
    assert refusal.request == "arm"
    assert refusal.result == "FAILED"
    assert refusal.reason == "Arm: Need Position Estimate"


def test_a_reason_that_comes_after_the_ack_is_kept_too() -> None:
    adapter, ap = bench()
    adapter.command(Arm(), 1.0)
    ap.now_s = 1.1
    ap.say(ap.ack(mavlink2.MAV_CMD_COMPONENT_ARM_DISARM, mavlink2.MAV_RESULT_FAILED))
    ap.now_s = 1.3
    ap.say(ap.mav.statustext_encode(2, b"Arm: Mode not armable"))
    ap.now_s = 1.1 + REASON_WAIT_S
    (refusal,) = of(ap.say(), CommandRefused)
    assert refusal.reason == "Arm: Mode not armable"


def test_speed_goes_after_the_target_and_is_retried_until_accepted() -> None:
    adapter, ap = bench()
    ap.say(ap.heartbeat("GUIDED", armed=True))
    sent = ap.heard(adapter.command(Goto(30.6375, -96.4787, 0.0, 2.0), 1.0))
    assert [m.get_type() for m in sent] == ["SET_POSITION_TARGET_GLOBAL_INT", "COMMAND_LONG"]
    assert (sent[1].command, sent[1].param2) == (mavlink2.MAV_CMD_DO_CHANGE_SPEED, 2.0)
    # ArduRover refuses it (no target yet in its eyes): sent again, not dropped.
    ap.now_s = 1.2
    ap.say(ap.ack(mavlink2.MAV_CMD_DO_CHANGE_SPEED, mavlink2.MAV_RESULT_FAILED))
    assert ap.heard(adapter.poll(1.2 + SPEED_RETRY_S / 2)) == []
    (again,) = ap.heard(adapter.poll(1.2 + SPEED_RETRY_S))
    assert (again.command, again.param2) == (mavlink2.MAV_CMD_DO_CHANGE_SPEED, 2.0)
    ap.now_s = 2.4
    ap.say(ap.ack(mavlink2.MAV_CMD_DO_CHANGE_SPEED, mavlink2.MAV_RESULT_ACCEPTED))
    # Accepted: the next target carries the same speed, so nothing more is sent...
    sent = ap.heard(adapter.command(Goto(30.6376, -96.4787, 0.0, 2.0), 3.0))
    assert [m.get_type() for m in sent] == ["SET_POSITION_TARGET_GLOBAL_INT"]
    # ...until a mode change, after which ArduPilot flies its default speed again.
    ap.say(ap.heartbeat("HOLD", armed=True), ap.heartbeat("GUIDED", armed=True))
    sent = ap.heard(adapter.command(Goto(30.6377, -96.4787, 0.0, 2.0), 4.0))
    assert [m.get_type() for m in sent] == ["SET_POSITION_TARGET_GLOBAL_INT", "COMMAND_LONG"]


def test_an_unanswered_speed_is_sent_again() -> None:
    adapter, ap = bench()
    ap.say(ap.heartbeat("GUIDED", armed=True))
    adapter.command(Goto(30.6375, -96.4787, 0.0, 2.0), 1.0)
    changes = 0
    t = 1.0
    while t < 1.0 + 3 * ACK_TIMEOUT_S * 2 + SPEED_RETRY_S:
        t += 0.1
        ap.now_s = t
        ap.say(ap.heartbeat("GUIDED", armed=True))  # the autopilot is heard, never answers
        changes += sum(
            m.get_type() == "COMMAND_LONG" and m.command == mavlink2.MAV_CMD_DO_CHANGE_SPEED
            for m in ap.heard(adapter.poll(t))
        )
    assert changes >= 3  # the retries, then a new attempt after giving up: never dropped


def test_copter_takeoff_is_nav_takeoff() -> None:
    adapter, ap = bench("arducopter")
    (sent,) = ap.heard(adapter.command(Takeoff(10.0), 1.0))
    assert (sent.command, sent.param7) == (mavlink2.MAV_CMD_NAV_TAKEOFF, 10.0)


def test_takeoff_heights_above_the_origin_go_out_above_home() -> None:
    """NAV_TAKEOFF and TKOFF_ALT are above home: home 5 m above a 90 m origin takes 5 off."""
    for firmware in ("arducopter", "arduplane"):
        adapter, ap = bench(firmware, origin_alt_amsl_m=90.0)
        home = ap.mav.home_position_encode(
            306372000, -964787000, 95000, 0, 0, 0, [math.nan] * 4, 0, 0, 0
        )
        ap.say(ap.heartbeat(), home)
        sent = ap.heard(adapter.command(Takeoff(30.0), 1.0))[0]
        if firmware == "arducopter":
            assert (sent.command, sent.param7) == (mavlink2.MAV_CMD_NAV_TAKEOFF, 25.0)
        else:
            assert (sent.param_id, sent.param_value) == ("TKOFF_ALT", 25)


def test_altitudes_are_above_the_origin_from_the_amsl_altitude() -> None:
    """relative_alt is not used: ArduRover's reads +90 m on a 90 m field (home at 0 m)."""
    _adapter, ap = bench("ardurover", origin_alt_amsl_m=90.0)
    attitude = ap.mav.attitude_encode(0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0)
    position = ap.mav.global_position_int_encode(
        1000, 306372000, -964787000, 90_400, 90_210, 0, 0, 0, 0
    )
    ekf = ap.mav.ekf_status_report_encode(0x33F, 0, 0, 0, 0, 0)  # a position: it is taken
    (state,) = of(ap.say(ap.heartbeat(), attitude, ekf, position), VehicleState)
    assert state.alt_m == pytest.approx(0.4)


def test_a_barometer_height_before_the_ekf_takes_over_gives_way_to_the_gps() -> None:
    """ArduRover reads about 0 m in alt for some 30 s after its fix (measured on SITL)."""
    _adapter, ap = bench("ardurover", origin_alt_amsl_m=90.0)
    attitude = ap.mav.attitude_encode(0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0)
    fix = ap.mav.gps_raw_int_encode(0, 6, 306372000, -964787000, 90_000, 121, 200, 0, 0, 10)
    baro = ap.mav.global_position_int_encode(1000, 306372000, -964787000, 160, 0, 0, 0, 0, 0)
    (state,) = of(ap.say(ap.heartbeat(), attitude, fix, baro), VehicleState)
    assert state.alt_m == pytest.approx(0.0)  # the GPS's 90 m, not the barometer's 0.16 m
    ekf = ap.mav.global_position_int_encode(2000, 306372000, -964787000, 91_500, 0, 0, 0, 0, 0)
    (state,) = of(ap.say(ekf), VehicleState)
    assert state.alt_m == pytest.approx(1.5)  # the fused height once it agrees


def test_plane_takeoff_is_tkoff_alt_then_the_takeoff_mode() -> None:
    adapter, ap = bench("arduplane")
    param, mode = ap.heard(adapter.command(Takeoff(40.0), 1.0))
    assert (param.get_type(), param.param_id, param.param_value) == ("PARAM_SET", "TKOFF_ALT", 40)
    assert (mode.command, mode.param2) == (mavlink2.MAV_CMD_DO_SET_MODE, MODES["TAKEOFF"])
