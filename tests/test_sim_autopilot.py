"""The simulated ArduPilot on its own: what a ground station sees on the wire.

Frames are parsed by a fresh, strict pymavlink parser (a bad checksum raises),
times are virtual, and the last tests let pymavlink's own ``mavutil`` connect
over UDP loopback as an independent ground station.
"""

from __future__ import annotations

import itertools
import math
import struct
from collections.abc import Iterator, Mapping
from pathlib import Path
from typing import Any

import pytest
import yaml
from fake_vehicle import FakeModelHooks, RcServoBook
from pymavlink.dialects.v20 import ardupilotmega as mavlink2

from clark_engine.io.transports import UdpTransport
from clark_engine.sim.ardupilot.autopilot import SimAutopilot
from clark_engine.sim.ardupilot.telemetry import STREAM_GROUPS
from clark_engine.sim.ardupilot.vehicle_model import Truth, VehicleModel

ROOT = Path(__file__).resolve().parent.parent
HOME = (30.6319, -96.4826, 90.0)
START_UNIX_US = 1_700_000_000_123_456


def modes_of(name: str) -> dict[str, int]:
    with (ROOT / "hardware_profiles" / "autopilots" / f"{name}.yaml").open(encoding="utf-8") as f:
        modes: dict[str, int] = yaml.safe_load(f)["modes"]
    return modes


PLANE_MODES = modes_of("pixhawk_arduplane")
COPTER_MODES = modes_of("pixhawk_arducopter")
ROVER_MODES = modes_of("pixhawk_ardurover")


class FakeModel(FakeModelHooks, RcServoBook, VehicleModel):
    """Stands still at home, remembering every call; enough to watch the autopilot layer."""

    def __init__(self, modes: Mapping[str, int], mode: str = "MANUAL") -> None:
        self.modes = dict(modes)
        self.mode = mode
        self.armed = False
        self.up_m = 0.0
        self.lat_deg = HOME[0]
        self.gotos: list[tuple[float, float, float, float | None]] = []
        FakeModelHooks.__init__(self)
        RcServoBook.__init__(self, pilot={1: 1500, 3: 1100}, servo_count=14)

    def step(self, dt_s: float) -> None:
        pass

    def truth(self) -> Truth:
        return Truth(
            north_m=0.0,
            east_m=0.0,
            up_m=self.up_m,
            lat_deg=self.lat_deg,
            lon_deg=HOME[1],
            velocity_north_m_s=1.0,
            velocity_east_m_s=-2.0,
            climb_rate_m_s=0.5,
            roll_deg=10.0,
            pitch_deg=5.0,
            yaw_deg=271.5,
            ground_speed_m_s=math.hypot(1.0, -2.0),
            heading_deg=296.5,
            airspeed_m_s=2.5,
            throttle_pct=42.0,
        )

    def set_mode(self, mode: str) -> bool:
        if mode not in self.modes:
            return False
        self.mode = mode
        return True

    def goto(self, lat_deg: float, lon_deg: float, alt_m: float, speed_m_s: float | None) -> bool:
        self.gotos.append((lat_deg, lon_deg, alt_m, speed_m_s))
        return True


class Gcs:
    """A ground station's two halves: an encoder with its ids, a strict parser."""

    def __init__(self, system_id: int = 255, component_id: int = 190) -> None:
        self.mav = mavlink2.MAVLink(None, system_id, component_id)
        self.parser = mavlink2.MAVLink(None)  # not robust: a bad frame raises

    def frame(self, msg: Any) -> bytes:
        data: bytes = msg.pack(self.mav)
        self.mav.seq = (self.mav.seq + 1) % 256
        return data

    def command(self, command: int, *params: float, target: int = 1) -> bytes:
        p = (*params, *(0.0,) * (7 - len(params)))
        return self.frame(self.mav.command_long_encode(target, 1, command, 0, *p))

    def parse(self, data: bytes) -> list[Any]:
        messages: list[Any] = self.parser.parse_buffer(data) or []
        assert not [m for m in messages if m.get_type() == "BAD_DATA"]
        return messages


def make_sim(firmware: str = "arduplane", **kwargs: Any) -> tuple[SimAutopilot, FakeModel]:
    """A simulated autopilot powered on 100 s before time 0 (ready) unless ``boot_s`` says."""
    modes = {"arduplane": PLANE_MODES, "ardurover": ROVER_MODES}.get(firmware, COPTER_MODES)
    model = FakeModel(modes)
    kwargs.setdefault("boot_s", -100.0)
    sim = SimAutopilot(
        model,
        firmware=firmware,
        origin_lat_deg=HOME[0],
        origin_lon_deg=HOME[1],
        origin_alt_amsl_m=HOME[2],
        start_time_unix_us=START_UNIX_US,
        **kwargs,
    )
    return sim, model


def run(
    sim: SimAutopilot, gcs: Gcs, start_s: float, end_s: float, step_s: float = 0.01
) -> list[tuple[float, Any]]:
    """Advance from start (exclusive) to end (inclusive); returns (time, message) pairs."""
    out: list[tuple[float, Any]] = []
    for i in range(1, round((end_s - start_s) / step_s) + 1):
        now = round(start_s + i * step_s, 9)
        out += [(now, m) for m in gcs.parse(sim.advance(now))]
    return out


def ask(sim: SimAutopilot, gcs: Gcs, data: bytes, now_s: float = 1.0) -> list[Any]:
    """Send bytes, collect the answers (what the next advance emits that is not streamed).

    The first advance is made before the bytes arrive, so that what the autopilot says
    by itself at start (its home) is not taken for an answer.
    """
    sim.advance(now_s)
    sim.receive(data, now_s)
    unasked = {*STREAM_GROUPS, "HOME_POSITION"}
    return [m for m in gcs.parse(sim.advance(now_s)) if m.get_type() not in unasked]


def ack_of(messages: list[Any]) -> tuple[int, int]:
    (ack,) = [m for m in messages if m.get_type() == "COMMAND_ACK"]
    return int(ack.command), int(ack.result)


# -- frames ---------------------------------------------------------------------------------


def test_every_frame_is_valid_mavlink2_in_sequence() -> None:
    sim, _model = make_sim()
    data = b"".join(sim.advance(i * 0.05) for i in range(100))
    gcs = Gcs()
    messages = gcs.parse(data)
    assert len(messages) > 60  # five seconds of ArduPlane's default 1 Hz streams
    assert gcs.parser.total_receive_errors == 0
    seqs = []
    for msg in messages:
        header = msg.get_header()
        assert msg.get_msgbuf()[0] == 0xFD  # MAVLink 2
        assert (header.srcSystem, header.srcComponent) == (1, 1)
        seqs.append(header.seq)
    assert seqs == [i % 256 for i in range(len(seqs))]


def test_golden_frames() -> None:
    sim, _model = make_sim()
    frames = {m.get_type(): bytes(m.get_msgbuf()) for m in Gcs().parse(sim.advance(0.0))}
    # HEARTBEAT (sequence 1, after the HOME_POSITION it has since boot): custom_mode 0
    # (MANUAL), type 1 (fixed wing), autopilot 3 (ArduPilot), base_mode 81 (custom mode,
    # stabilize and manual input enabled, as ArduPlane's), status 3 (standby), version 3.
    assert frames["HEARTBEAT"].hex() == "fd0900000101010000000000000001035103038f10"
    # SYSTEM_TIME (sequence 10): 1700000000123456 us of Unix time, boot time 100 s.
    assert frames["SYSTEM_TIME"].hex() == "fd0b00000a010102000040222018240a0600a086014b62"


def test_stream_contents() -> None:
    sim, model = make_sim()  # home at the model, on the ground, from boot
    model.up_m = 12.345
    model.armed = True
    messages = {m.get_type(): m for m in Gcs().parse(sim.advance(2.5))}
    position = messages["GLOBAL_POSITION_INT"]
    assert (position.time_boot_ms, position.lat, position.lon) == (102500, 306319000, -964826000)
    assert (position.alt, position.relative_alt) == (102345, 12345)
    assert (position.vx, position.vy, position.vz, position.hdg) == (100, -200, -50, 27150)
    attitude = messages["ATTITUDE"]
    assert math.degrees(attitude.roll) == pytest.approx(10.0, abs=1e-5)
    assert math.degrees(attitude.yaw) == pytest.approx(-88.5, abs=1e-5)  # -180..180 as ArduPilot
    hud = messages["VFR_HUD"]
    assert (hud.heading, hud.throttle, hud.airspeed) == (271, 42, 2.5)
    assert hud.alt == pytest.approx(102.345)
    assert messages["SYSTEM_TIME"].time_unix_usec == START_UNIX_US + 2_500_000
    gps = messages["GPS_RAW_INT"]
    assert (gps.fix_type, gps.cog, gps.vel) == (3, 29650, 224)
    rc = messages["RC_CHANNELS"]
    assert (rc.chancount, rc.chan1_raw, rc.chan2_raw, rc.chan3_raw) == (16, 1500, 65535, 1100)
    servo = messages["SERVO_OUTPUT_RAW"]
    assert (servo.servo1_raw, servo.servo14_raw, servo.servo15_raw) == (1500, 1500, 0)
    beat = messages["HEARTBEAT"]
    assert beat.base_mode == 81 | mavlink2.MAV_MODE_FLAG_SAFETY_ARMED  # ArduPlane in MANUAL
    assert beat.system_status == mavlink2.MAV_STATE_ACTIVE  # flying
    status = messages["SYS_STATUS"]
    assert (status.voltage_battery, status.battery_remaining) == (12600, 100)  # as SITL's
    assert status.current_battery == round(23.0 * 0.42 * 100)  # 42 % throttle of 23 A
    assert status.onboard_control_sensors_health & mavlink2.MAV_SYS_STATUS_PREARM_CHECK
    assert messages["EKF_STATUS_REPORT"].flags == 0x33F  # an absolute position
    assert messages["EXTENDED_SYS_STATE"].landed_state == mavlink2.MAV_LANDED_STATE_IN_AIR


@pytest.mark.parametrize(
    ("firmware", "mav_type"),
    [
        ("arduplane", mavlink2.MAV_TYPE_FIXED_WING),
        ("arducopter", mavlink2.MAV_TYPE_QUADROTOR),
        ("ardurover", mavlink2.MAV_TYPE_GROUND_ROVER),
    ],
)
def test_heartbeat_type_per_firmware(firmware: str, mav_type: int) -> None:
    sim, _ = make_sim(firmware)
    (beat,) = [m for m in Gcs().parse(sim.advance(0.0)) if m.get_type() == "HEARTBEAT"]
    assert (beat.type, beat.autopilot) == (mav_type, mavlink2.MAV_AUTOPILOT_ARDUPILOTMEGA)


def count(pairs: list[tuple[float, Any]], name: str) -> int:
    return sum(1 for _t, m in pairs if m.get_type() == name)


def test_default_streams() -> None:
    sim, _ = make_sim()
    gcs = Gcs()
    pairs = [(0.0, m) for m in gcs.parse(sim.advance(0.0))] + run(sim, gcs, 0.0, 1.99)
    # ArduPlane streams everything at 1 Hz until asked otherwise (measured).
    for name in ("HEARTBEAT", "SYSTEM_TIME", "GLOBAL_POSITION_INT", "ATTITUDE", "VFR_HUD"):
        assert count(pairs, name) == 2, name
    for name in ("SYS_STATUS", "GPS_RAW_INT", "RC_CHANNELS", "SERVO_OUTPUT_RAW"):
        assert count(pairs, name) == 2, name
    # ArduCopter streams nothing but its heartbeat (measured).
    copter, _ = make_sim("arducopter")
    pairs = [(0.0, m) for m in gcs.parse(copter.advance(0.0))] + run(copter, gcs, 0.0, 1.99)
    assert {m.get_type() for _t, m in pairs} <= {"HEARTBEAT", "HOME_POSITION"}


def test_message_intervals_are_honoured_on_a_virtual_clock() -> None:
    sim, _ = make_sim()
    gcs = Gcs()
    position = mavlink2.MAVLINK_MSG_ID_GLOBAL_POSITION_INT
    sim.advance(0.0)
    answers = ask(sim, gcs, gcs.command(511, position, 50_000), now_s=0.0)
    assert ack_of(answers) == (511, mavlink2.MAV_RESULT_ACCEPTED)
    pairs = run(sim, gcs, 0.0, 2.0)
    times = [m.time_boot_ms for _t, m in pairs if m.get_type() == "GLOBAL_POSITION_INT"]
    assert len(times) == 40
    assert {b - a for a, b in itertools.pairwise(times)} == {50}
    ask(sim, gcs, gcs.command(511, position, -1), now_s=2.0)  # stop it
    assert count(run(sim, gcs, 2.0, 4.0), "GLOBAL_POSITION_INT") == 0
    ask(sim, gcs, gcs.command(511, position, 0), now_s=4.0)  # back to the default, 1 Hz
    assert count(run(sim, gcs, 4.0, 6.0), "GLOBAL_POSITION_INT") == 2
    answers = ask(sim, gcs, gcs.command(510, position), now_s=6.0)
    interval = [m for m in answers if m.get_type() == "MESSAGE_INTERVAL"]
    assert (interval[0].message_id, interval[0].interval_us) == (position, 1_000_000)
    # Faster than 40 Hz is DENIED, as ArduPilot does (measured), and changes nothing.
    assert ack_of(ask(sim, gcs, gcs.command(511, position, 20_000), now_s=6.0)) == (511, 2)


def test_request_data_stream_sets_a_group() -> None:
    sim, _ = make_sim()
    gcs = Gcs()
    sim.advance(0.0)
    extra1 = mavlink2.MAV_DATA_STREAM_EXTRA1
    sim.receive(gcs.frame(gcs.mav.request_data_stream_encode(1, 1, extra1, 10, 1)), 0.0)
    assert count(run(sim, gcs, 0.0, 1.0), "ATTITUDE") == 10
    assert sim.param("MAV1_EXTRA1") == 10
    sim.receive(gcs.frame(gcs.mav.request_data_stream_encode(1, 1, 0, 0, 0)), 1.0)  # all off
    pairs = run(sim, gcs, 1.0, 3.0)
    assert {m.get_type() for _t, m in pairs} == {"HEARTBEAT"}


@pytest.mark.parametrize(
    ("params", "result"),
    [
        ((176, 1, 15), mavlink2.MAV_RESULT_ACCEPTED),  # DO_SET_MODE GUIDED
        ((176, 1, 99), mavlink2.MAV_RESULT_FAILED),  # no such mode number
        ((176, 0, 15), mavlink2.MAV_RESULT_DENIED),  # not a custom mode
        ((400, 1), mavlink2.MAV_RESULT_ACCEPTED),  # arm
        ((400, 2), mavlink2.MAV_RESULT_UNSUPPORTED),
        ((183, 9, 1700), mavlink2.MAV_RESULT_ACCEPTED),  # DO_SET_SERVO
        ((183, 17, 1700), mavlink2.MAV_RESULT_FAILED),
        ((178, 0, 12, -1), mavlink2.MAV_RESULT_FAILED),  # ArduPlane: speed only in guided/auto
        ((511, 33, 100_000), mavlink2.MAV_RESULT_ACCEPTED),
        ((511, 9999, 100_000), mavlink2.MAV_RESULT_DENIED),  # nothing to stream
        ((512, 242), mavlink2.MAV_RESULT_ACCEPTED),  # REQUEST_MESSAGE HOME_POSITION
        ((512, 148), mavlink2.MAV_RESULT_ACCEPTED),  # AUTOPILOT_VERSION
        ((512, 12345), mavlink2.MAV_RESULT_FAILED),
        ((520, 1), mavlink2.MAV_RESULT_ACCEPTED),
        ((410,), mavlink2.MAV_RESULT_ACCEPTED),
        ((192,), mavlink2.MAV_RESULT_UNSUPPORTED),  # DO_REPOSITION only as COMMAND_INT
        ((31000,), mavlink2.MAV_RESULT_UNSUPPORTED),  # an unknown command
    ],
)
def test_command_ack_results(params: tuple[int, ...], result: int) -> None:
    sim, _ = make_sim()
    gcs = Gcs()
    assert ack_of(ask(sim, gcs, gcs.command(*params))) == (params[0], result)


def test_commands_act_on_the_model() -> None:
    sim, model = make_sim()
    gcs = Gcs()
    ask(sim, gcs, gcs.command(176, 1, PLANE_MODES["LOITER"]))
    assert model.mode == "LOITER"
    ask(sim, gcs, gcs.command(400, 1))
    assert model.armed
    ask(sim, gcs, gcs.command(183, 9, 1700))
    assert model.servos[8] == 1700
    ask(sim, gcs, gcs.command(176, 1, PLANE_MODES["GUIDED"]))
    assert ack_of(ask(sim, gcs, gcs.command(178, 0, 18.0, -1))) == (178, 0)
    assert model.speeds == [18.0]
    answers = ask(sim, gcs, gcs.frame(gcs.mav.set_mode_encode(1, 1, PLANE_MODES["RTL"])))
    assert not [m for m in answers if m.get_type() == "COMMAND_ACK"]  # ArduPilot 4.7: no ack
    assert model.mode == "RTL"


def test_acks_answer_whoever_asked() -> None:
    sim, model = make_sim()
    engine, station = Gcs(255, 191), Gcs(254, 190)
    for gcs in (engine, station):
        sim.receive(gcs.frame(gcs.mav.heartbeat_encode(6, 8, 0, 0, 4)), 0.5)
    sim.receive(engine.command(400, 1), 1.0)
    sim.receive(station.command(176, 1, 12), 1.0)
    acks = [m for m in Gcs().parse(sim.advance(1.0)) if m.get_type() == "COMMAND_ACK"]
    assert [(a.command, a.target_system, a.target_component) for a in acks] == [
        (400, 255, 191),
        (176, 254, 190),
    ]
    assert set(sim.gcs_peers) == {(255, 191), (254, 190)}
    assert (model.armed, model.mode) == (True, "LOITER")


def test_commands_for_another_vehicle_are_ignored() -> None:
    sim, model = make_sim()
    gcs = Gcs()
    assert ask(sim, gcs, gcs.command(176, 1, 15, target=2)) == []
    assert model.mode == "MANUAL"


def test_requested_messages_follow_their_ack() -> None:
    sim, _ = make_sim()
    gcs = Gcs()
    answers = ask(sim, gcs, gcs.command(512, mavlink2.MAVLINK_MSG_ID_AUTOPILOT_VERSION))
    assert [m.get_type() for m in answers] == ["COMMAND_ACK", "AUTOPILOT_VERSION"]
    version = answers[1]
    assert version.flight_sw_version == (4 << 24) | (7 << 16) | (0 << 8) | 0  # 4.7.0-dev, as SITL
    assert version.capabilities == 0xF36F  # exactly ArduPlane SITL's
    sim.receive(gcs.command(512, mavlink2.MAVLINK_MSG_ID_HOME_POSITION), 1.0)
    replies = gcs.parse(sim.advance(1.0))
    assert [m.get_type() for m in replies][:2] == ["COMMAND_ACK", "HOME_POSITION"]
    home = replies[1]
    assert (home.latitude, home.longitude, home.altitude) == (306319000, -964826000, 90000)


def test_position_targets() -> None:
    sim, model = make_sim("arducopter")
    gcs = Gcs(255, 191)
    frame = mavlink2.MAV_FRAME_GLOBAL_RELATIVE_ALT_INT
    target = gcs.mav.set_position_target_global_int_encode(
        0, 1, 1, frame, 0x0DF8, 306320000, -964820000, 20.0, 0, 0, 0, 0, 0, 0, 0, 0
    )
    ask(sim, gcs, gcs.frame(target))
    assert model.gotos == []  # not in GUIDED: dropped, as ArduCopter does
    ask(sim, gcs, gcs.command(176, 1, COPTER_MODES["GUIDED"]))
    model.up_m = 5.0  # flying: speed changes apply once it flies to targets
    ask(sim, gcs, gcs.frame(target))
    assert model.gotos == [(30.632, -96.482, 20.0, None)]
    amsl = gcs.mav.set_position_target_global_int_encode(
        0, 1, 1, mavlink2.MAV_FRAME_GLOBAL_INT, 0x0DF8, 306320000, -964820000, 100.0, *[0] * 8
    )
    ask(sim, gcs, gcs.frame(amsl))
    assert model.gotos[-1][2] == pytest.approx(10.0)  # 100 m AMSL is 10 m above home
    ask(sim, gcs, gcs.command(178, 1, 6.0, -1))  # the leg's speed, kept for later targets
    assert model.speeds == [6.0]


def test_arduplane_takes_only_altitude_from_position_targets() -> None:
    sim, model = make_sim("arduplane")
    gcs = Gcs()
    ask(sim, gcs, gcs.command(176, 1, PLANE_MODES["GUIDED"]))
    target = gcs.mav.set_position_target_global_int_encode(
        0, 1, 1, 6, 0x0DF8, 306400000, -964900000, 55.0, 0, 0, 0, 0, 0, 0, 0, 0
    )
    ask(sim, gcs, gcs.frame(target))
    assert model.gotos == [(HOME[0], HOME[1], 55.0, None)]


def test_do_reposition() -> None:
    sim, model = make_sim("arduplane")
    gcs = Gcs()

    def reposition(flags: int) -> bytes:
        return gcs.frame(
            gcs.mav.command_int_encode(
                1, 1, 6, 192, 0, 0, -1, flags, 0, math.nan, 306330000, -964830000, 40.0
            )
        )

    assert ack_of(ask(sim, gcs, reposition(0))) == (192, mavlink2.MAV_RESULT_FAILED)
    assert ack_of(ask(sim, gcs, reposition(1))) == (192, mavlink2.MAV_RESULT_ACCEPTED)
    assert model.mode == "GUIDED"
    assert model.gotos == [(30.633, -96.483, 40.0, None)]


def test_guided_mission_item_as_mavproxy_sends_it() -> None:
    """MAVProxy's ``guided LAT LON ALT``: MISSION_ITEM_INT with current = 2, in GUIDED only."""
    sim, model = make_sim("arducopter")
    gcs = Gcs()

    def item(current: int, alt_m: float, mission_type: int = 0, integer: bool = True) -> bytes:
        encode = gcs.mav.mission_item_int_encode if integer else gcs.mav.mission_item_encode
        x, y = (306330000, -964830000) if integer else (30.633, -96.483)
        frame = mavlink2.MAV_FRAME_GLOBAL_RELATIVE_ALT_INT
        return gcs.frame(
            encode(1, 1, 0, frame, 16, current, 0, 0, 0, 0, 0, x, y, alt_m, mission_type)
        )

    def answer(data: bytes) -> int:
        (ack,) = [m for m in ask(sim, gcs, data) if m.get_type() == "MISSION_ACK"]
        assert (ack.target_system, ack.target_component) == (255, 190)
        return int(ack.type)

    assert answer(item(2, 30.0)) == mavlink2.MAV_MISSION_ERROR  # not in GUIDED
    assert model.gotos == []
    model.set_mode("GUIDED")
    assert answer(item(2, 30.0)) == mavlink2.MAV_MISSION_ACCEPTED
    assert model.gotos == [(30.633, -96.483, 30.0, None)]
    assert answer(item(3, 45.0)) == mavlink2.MAV_MISSION_ACCEPTED  # altitude change
    assert model.gotos[-1] == (30.633, -96.483, 45.0, None)
    assert answer(item(2, 20.0, integer=False)) == mavlink2.MAV_MISSION_ACCEPTED
    assert model.gotos[-1] == pytest.approx((30.633, -96.483, 20.0, None))
    assert answer(item(0, 20.0)) == mavlink2.MAV_MISSION_ERROR  # no upload in progress
    # A fence item with current 2 is the fence's, outside an upload: an error, no target.
    assert answer(item(2, 20.0, mission_type=1)) == mavlink2.MAV_MISSION_ERROR
    assert len(model.gotos) == 3


def test_rc_override_semantics() -> None:
    sim, model = make_sim()
    gcs, stranger = Gcs(255, 191), Gcs(250, 190)
    ignore = 65535

    def override(sender: Gcs, first8: list[int], rest: list[int]) -> bytes:
        return sender.frame(sender.mav.rc_channels_override_encode(1, 1, *first8, *rest))

    sim.receive(override(stranger, [1900] * 8, [0] * 10), 1.0)
    assert model.overrides == {}  # only MAV_GCS_SYSID (255) may override
    sim.receive(override(gcs, [1600, ignore, *[ignore] * 6], [1200, 0, *[0] * 8]), 1.0)
    assert model.overrides == {1: 1600, 9: 1200}
    assert model.rc_inputs()[0] == 1600
    sim.receive(override(gcs, [0, *[ignore] * 7], [ignore, *[0] * 9]), 1.5)  # release 1 only
    assert model.overrides == {9: 1200}
    sim.receive(override(gcs, [ignore] * 8, [65534, *[0] * 9]), 1.6)  # 9-18 release at 65534
    assert model.overrides == {}
    sim.receive(override(gcs, [1700, *[ignore] * 7], [0] * 10), 2.0)
    sim.advance(4.9)
    assert model.overrides == {1: 1700}
    sim.advance(5.01)  # RC_OVERRIDE_TIME 3 s after the last refresh
    assert model.overrides == {}
    assert model.override_calls[-1] == {1: 0}


def test_rc_override_never_times_out_with_minus_one() -> None:
    sim, model = make_sim(params={"RC_OVERRIDE_TIME": -1})
    gcs = Gcs()
    sim.receive(gcs.frame(gcs.mav.rc_channels_override_encode(1, 1, 1600, *[65535] * 7)), 0.0)
    sim.advance(100.0)
    assert model.overrides == {1: 1600}


def download(sim: SimAutopilot, gcs: Gcs, now_s: float = 1.0) -> list[Any]:
    """PARAM_REQUEST_LIST at ``now_s``; every PARAM_VALUE of the paced answer, in order."""
    values = ask(sim, gcs, gcs.frame(gcs.mav.param_request_list_encode(1, 1)), now_s)
    values += [m for _, m in run(sim, gcs, now_s, now_s + 3.0) if m.get_type() == "PARAM_VALUE"]
    return values


def test_parameters() -> None:
    sim, _ = make_sim()
    gcs = Gcs()
    values = download(sim, gcs)
    names = [v.param_id for v in values]
    assert (names[0], names[-1], len(names)) == ("FORMAT_VERSION", "MAV3_OPTIONS", 1406)
    assert {"MAV_SYSID", "MAV_GCS_SYSID", "RC_OVERRIDE_TIME", "MAV1_POSITION", "WP_RADIUS"} <= set(
        names
    )
    assert not {"SYSID_THISMAV", "SYSID_MYGCS", "SR0_POSITION"} & set(names)  # 4.5's names
    assert [v.param_index for v in values] == list(range(len(values)))
    assert {v.param_count for v in values} == {len(values)}
    (read,) = ask(sim, gcs, gcs.frame(gcs.mav.param_request_read_encode(1, 1, b"WP_RADIUS", -1)))
    assert (read.param_id, read.param_value, read.param_type) == ("WP_RADIUS", 90.0, 4)
    (by_index,) = ask(sim, gcs, gcs.frame(gcs.mav.param_request_read_encode(1, 1, b"", 0)))
    assert by_index.param_id == "FORMAT_VERSION"
    (echo,) = ask(sim, gcs, gcs.frame(gcs.mav.param_set_encode(1, 1, b"MAV1_POSITION", 10.2, 9)))
    assert echo.param_value == 10.0  # an integer parameter truncates
    assert sim.param("MAV1_POSITION") == 10.0
    assert count(run(sim, gcs, 1.0, 2.0), "GLOBAL_POSITION_INT") == 10  # the new default rate
    unknown = gcs.frame(gcs.mav.param_set_encode(1, 1, b"NO_SUCH_PARAM", 1.0, 9))
    assert ask(sim, gcs, unknown) == []  # ArduPilot ignores it without a word
    with pytest.raises(ValueError, match="no parameter"):
        make_sim(params={"NO_SUCH_PARAM": 1})


def test_param_set_reaches_the_model_at_once() -> None:
    sim, model = make_sim("arduplane")
    gcs = Gcs()
    ask(sim, gcs, gcs.frame(gcs.mav.param_set_encode(1, 1, b"WP_RADIUS", 35.0, 9)))
    assert model.params["WP_RADIUS"] == 35.0  # the model is configured from the new table


@pytest.mark.parametrize(
    ("name", "sent", "sent_type", "stored", "stored_type"),
    [
        # Measured on SITL (docs/sitl-measurements.md, section 5): integers get 0.01 away from zero,
        # are clamped to their C type and truncated; the echo carries the stored type.
        ("FENCE_ACTION", 2.7, 9, 2.0, 2),
        ("FENCE_ACTION", -2.7, 9, -2.0, 2),
        ("FENCE_ACTION", 2.995, 9, 3.0, 2),  # 2.995 + 0.01 truncates to 3
        ("FENCE_ACTION", 300.0, 2, 127.0, 2),  # int8
        ("FENCE_TYPE", 255.0, 2, 127.0, 2),
        ("FENCE_OPTIONS", 70000.0, 9, 32767.0, 4),  # int16
        ("FENCE_RADIUS", 5.0, 2, 5.0, 9),  # below @Range 30: kept (no range is enforced)
        ("FENCE_RADIUS", 1e6, 9, 1e6, 9),
        ("FENCE_ALT_MAX", -5.0, 9, -5.0, 9),
        ("FENCE_MARGIN", 0.1, 9, 0.10000000149011612, 9),  # a C float
    ],
)
def test_param_set_stores_as_ardupilot(
    name: str, sent: float, sent_type: int, stored: float, stored_type: int
) -> None:
    sim, _ = make_sim()
    gcs = Gcs()
    answers = ask(
        sim, gcs, gcs.frame(gcs.mav.param_set_encode(1, 1, name.encode(), sent, sent_type))
    )
    assert [(m.param_id, m.param_value, m.param_type, m.param_index) for m in answers] == [
        (name, pytest.approx(stored), stored_type, 65535)
    ]
    assert sim.param(name) == stored


@pytest.mark.parametrize("value", [math.nan, math.inf, -math.inf])
def test_param_set_of_nan_or_infinity_is_not_answered(value: float) -> None:
    sim, _ = make_sim()
    gcs = Gcs()
    assert ask(sim, gcs, gcs.frame(gcs.mav.param_set_encode(1, 1, b"FENCE_RADIUS", value, 9))) == []
    assert sim.param("FENCE_RADIUS") == 300.0


@pytest.mark.parametrize("name", ["SYSID_MYGCS", "SYSID_THISMAV", "SR0_POSITION"])
def test_names_of_ardupilot_4_5_are_unknown(name: str) -> None:
    sim, _ = make_sim()
    gcs = Gcs()
    assert ask(sim, gcs, gcs.frame(gcs.mav.param_set_encode(1, 1, name.encode(), 7.0, 4))) == []
    assert (
        ask(sim, gcs, gcs.frame(gcs.mav.param_request_read_encode(1, 1, name.encode(), -1))) == []
    )


def test_frame_limited_parameters_answer_by_name_but_are_not_listed() -> None:
    # ArduRover's FENCE_ALT_MAX belongs to other frames (AP_GROUPINFO_FRAME): absent from
    # the list and its count, read and set by name (measured).
    sim, _ = make_sim(firmware="ardurover")
    gcs = Gcs()
    listed = download(sim, gcs)
    names = {m.param_id for m in listed}
    assert "FENCE_ALT_MAX" not in names and "FENCE_RADIUS" in names
    (read,) = ask(
        sim, gcs, gcs.frame(gcs.mav.param_request_read_encode(1, 1, b"FENCE_ALT_MAX", -1))
    )
    assert (read.param_value, read.param_type, read.param_count) == (100.0, 9, len(listed))
    (echo,) = ask(sim, gcs, gcs.frame(gcs.mav.param_set_encode(1, 1, b"FENCE_ALT_MAX", -5.0, 9)))
    assert echo.param_value == -5.0


def test_mav_options_bit_0_takes_mavlink_only_from_the_gcs() -> None:
    sim, _ = make_sim(params={"MAV_OPTIONS": 1})
    gcs, stranger = Gcs(255, 190), Gcs(245, 190)
    read = b"FENCE_RADIUS"
    assert (
        ask(sim, stranger, stranger.frame(stranger.mav.param_request_read_encode(1, 1, read, -1)))
        == []
    )
    assert len(ask(sim, gcs, gcs.frame(gcs.mav.param_request_read_encode(1, 1, read, -1)))) == 1


def test_empty_mission_and_an_upload_the_mission_protocol_answers() -> None:
    # The mission protocol itself is clark_engine.sim.ardupilot.mission_protocol's (and its tests);
    # here: the autopilot hands it the messages and its home. Home is set (an autopilot
    # booted before the run), so an empty mission counts 1 item, home, as ArduPilot's.
    sim, _ = make_sim()
    gcs = Gcs(255, 190)
    (answer,) = ask(sim, gcs, gcs.frame(gcs.mav.mission_request_list_encode(1, 1, 0)))
    assert answer.get_type() == "MISSION_COUNT"
    assert (answer.count, answer.target_system, answer.target_component) == (1, 255, 190)
    (request,) = ask(sim, gcs, gcs.frame(gcs.mav.mission_count_encode(1, 1, 2, 0)))
    assert (request.get_type(), request.seq) == ("MISSION_REQUEST", 0)


def test_mavftp_is_refused() -> None:
    sim, _ = make_sim()
    gcs = Gcs()
    request = struct.pack("<HBBBBBBI", 41, 0, 4, 9, 0, 0, 0, 0) + b"@PARAM/param.pck"
    payload = list(request) + [0] * (251 - len(request))
    (nak,) = ask(sim, gcs, gcs.frame(gcs.mav.file_transfer_protocol_encode(0, 1, 1, payload)))
    assert nak.get_type() == "FILE_TRANSFER_PROTOCOL"
    assert (nak.target_system, nak.target_component) == (255, 190)
    seq, session, opcode, size, req_opcode = struct.unpack_from("<HBBBB", bytes(nak.payload))
    assert (seq, session, opcode, size, req_opcode) == (42, 0, 129, 1, 4)
    assert nak.payload[12] == 7  # UnknownCommand: ground stations fall back


def test_timesync() -> None:
    sim, _ = make_sim()
    gcs = Gcs()
    (answer,) = ask(sim, gcs, gcs.frame(gcs.mav.timesync_encode(0, 123456789)), now_s=2.0)
    assert (answer.tc1, answer.ts1) == (102_000_000_000, 123456789)  # its boot clock, in ns


def test_garbage_is_counted_and_skipped() -> None:
    sim, model = make_sim()
    gcs = Gcs()
    sim.receive(b"\x00\x01garbage" + gcs.command(176, 1, 12), 1.0)
    assert sim.bad_frames == 1
    assert model.mode == "LOITER"


def test_output_depends_only_on_inputs_and_times() -> None:
    outputs = []
    for _ in range(2):
        sim, _ = make_sim()
        gcs = Gcs()
        data = b""
        for i in range(200):
            now = i * 0.02
            if i % 50 == 7:
                sim.receive(gcs.command(176, 1, 12 if i % 100 else 11), now)
            data += sim.advance(now)
        outputs.append(data)
    assert outputs[0] == outputs[1]


def test_from_profile() -> None:
    with (ROOT / "hardware_profiles" / "autopilots" / "pixhawk_ardurover.yaml").open() as f:
        rover = yaml.safe_load(f)
    rover["mavlink"] = {"system_id": 7, "component_id": 1}
    model = FakeModel(rover["modes"])
    sim = SimAutopilot.from_profile(model, rover, origin_lat_deg=HOME[0], origin_lon_deg=HOME[1])
    assert (sim.sysid, sim.firmware, sim.guided_mode) == (7, "ardurover", "GUIDED")
    with pytest.raises(ValueError, match="unknown firmware"):
        SimAutopilot(model, firmware="px4", origin_lat_deg=0.0, origin_lon_deg=0.0)


# -- an independent ground station: pymavlink's mavutil over UDP loopback -------------------


@pytest.fixture
def mavutil(monkeypatch: pytest.MonkeyPatch) -> Iterator[Any]:
    """pymavlink's mavutil, with its process-wide dialect and environment restored after.

    mavutil keeps its dialect in module globals and switches protocol versions by
    writing MAVLINK20 into os.environ; the monkeypatches undo both.
    """
    monkeypatch.setenv("MAVLINK20", "1")
    monkeypatch.setenv("MAVLINK_DIALECT", "ardupilotmega")
    from pymavlink import mavutil as module

    monkeypatch.setattr(module, "mavlink", module.mavlink)
    monkeypatch.setattr(module, "current_dialect", module.current_dialect)
    yield module


@pytest.mark.parametrize("role", ["udpin", "udpout"])
def test_mavutil_ground_station_flies_the_sim(mavutil: Any, role: str) -> None:
    sim, model = make_sim()
    if role == "udpin":
        # The station listens (as QGroundControl on 14550); the vehicle sends to it.
        gcs = mavutil.mavlink_connection(
            "udpin:127.0.0.1:0", dialect="ardupilotmega", source_system=254, source_component=190
        )
        vehicle = UdpTransport(bind=("127.0.0.1", 0), remote=gcs.port.getsockname()[:2])
    else:
        # The vehicle listens (as SITL); the station sends first.
        vehicle = UdpTransport(bind=("127.0.0.1", 0))
        host, port = vehicle.address
        gcs = mavutil.mavlink_connection(
            f"udpout:{host}:{port}",
            dialect="ardupilotmega",
            source_system=254,
            source_component=190,
        )
        gcs.mav.heartbeat_send(mavlink2.MAV_TYPE_GCS, mavlink2.MAV_AUTOPILOT_INVALID, 0, 0, 0)
    try:
        seen: dict[str, Any] = {}
        now = 0.0

        def pump(until: Any, steps: int = 300) -> bool:
            nonlocal now
            for _ in range(steps):
                now = round(now + 0.05, 6)
                sim.receive(vehicle.receive(), now)
                vehicle.send(sim.advance(now))
                while (msg := gcs.recv_match(blocking=True, timeout=0.002)) is not None:
                    seen[msg.get_type()] = msg
                if until():
                    return True
            return False

        assert pump(lambda: {"HEARTBEAT", "GLOBAL_POSITION_INT"} <= seen.keys())
        gcs.mav.heartbeat_send(mavlink2.MAV_TYPE_GCS, mavlink2.MAV_AUTOPILOT_INVALID, 0, 0, 0)
        assert pump(lambda: (254, 190) in sim.gcs_peers)
        assert gcs.target_system == 1
        assert seen["GLOBAL_POSITION_INT"].lat == 306319000
        assert gcs.flightmode == "MANUAL"
        gcs.set_mode("GUIDED")  # mavutil maps the name through the heartbeat's vehicle type
        assert pump(lambda: model.mode == "GUIDED" and "COMMAND_ACK" in seen)
        assert (seen["COMMAND_ACK"].command, seen["COMMAND_ACK"].result) == (176, 0)
        assert seen["COMMAND_ACK"].target_system == 254
        gcs.mav.command_long_send(1, 1, 176, 0, 1, PLANE_MODES["LOITER"], 0, 0, 0, 0, 0)
        assert pump(lambda: model.mode == "LOITER")
        assert pump(lambda: gcs.flightmode == "LOITER")
    finally:
        gcs.close()
        vehicle.close()


def test_a_disarmed_rover_moved_half_a_metre_moves_its_home() -> None:
    # ArduRover's one-second loop (Rover::update_home): while disarmed, home follows the
    # rover once it is DISTANCE_HOME_MINCHANGE (0.5 m) away, and HOME_POSITION says so;
    # a rover that moved less keeps its home and sends nothing.
    sim, model = make_sim("ardurover")
    gcs = Gcs()
    run(sim, gcs, 0.0, 2.0)  # the first home, sent at the start

    def homes_after_moving_north(metres: float, start_s: float) -> list[Any]:
        model.lat_deg = HOME[0] + metres / 111_320.0
        answers = run(sim, gcs, start_s, start_s + 2.0)
        return [m for _t, m in answers if m.get_type() == "HOME_POSITION"]

    assert homes_after_moving_north(0.3, 2.0) == []
    (home,) = homes_after_moving_north(0.7, 4.0)
    assert home.latitude == pytest.approx((HOME[0] + 0.7 / 111_320.0) * 1e7, abs=1)
