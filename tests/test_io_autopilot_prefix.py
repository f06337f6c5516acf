"""The adapter never takes a position an autopilot reports before it knows where it is.

ArduPlane dead-reckons before its GPS fix: from its power-on, its GLOBAL_POSITION_INT
starts at 0, 0 and then drifts away from it (SITL, measured: about 35 m north of
(0, 0) within 6 s, at up to 26 m/s and more between reports, velocities 0), with
GPS_RAW_INT saying "no fix" (0, then 1) and EKF_STATUS_REPORT "uninitialised" (0x400).
A vehicle state built from that would put the aircraft in the Gulf of Guinea. The
adapter takes a position only with a 3-D fix (GPS_RAW_INT) or an EKF absolute
position (EKF_STATUS_REPORT).
"""

from __future__ import annotations

import math
from typing import Any

from pymavlink.dialects.v20 import ardupilotmega as mavlink2
from test_io_autopilot import HOME, PLANE_MODES, START_UNIX_US, FakeModel

from clark_engine.io.autopilot import AutopilotAdapter
from clark_engine.io.autopilot_settings import AutopilotSettings
from clark_engine.runtime.events import VehicleState
from clark_engine.sim.ardupilot.autopilot import SimAutopilot

#: (time_boot_ms, lat, lon) of ArduPlane SITL's GLOBAL_POSITION_INT before its GPS fix
#: (4.7.0-dev, boot at 30.6372, -96.4787; GPS_RAW_INT fix_type 0 throughout).
SITL_PRE_FIX = (
    (3660, 1047, -45),
    (3870, 1730, -77),
    (4070, 2197, -100),
    (4460, 2777, -127),
    (5060, 2990, -136),
    (9060, 3191, -145),
)
#: Its first position with the fix (GPS_RAW_INT fix_type 6 at 9.26 s).
SITL_FIXED = (9460, 306371999, -964786999)


def frames() -> Any:
    return mavlink2.MAVLink(None, 1, 1)  # the autopilot's system and component


def heartbeat_and_attitude(mav: Any, boot_ms: int) -> bytes:
    beat = mav.heartbeat_encode(1, 3, 1, PLANE_MODES["MANUAL"], 3)
    attitude = mav.attitude_encode(boot_ms, 0.0, 0.0, -0.04, 0.0, 0.0, 0.0)
    return bytes(beat.pack(mav)) + bytes(attitude.pack(mav))


def position(mav: Any, boot_ms: int, lat: int, lon: int, alt_mm: int = -120) -> bytes:
    msg = mav.global_position_int_encode(boot_ms, lat, lon, alt_mm, alt_mm, 0, 0, 0, 35749)
    return bytes(msg.pack(mav))


def gps_raw(mav: Any, fix_type: int, lat: int = 0, lon: int = 0) -> bytes:
    fixed = fix_type >= 3
    msg = mav.gps_raw_int_encode(
        0,
        fix_type,
        lat,
        lon,
        90090 if fixed else 0,
        121 if fixed else 65535,
        200 if fixed else 65535,
        0,
        0,
        10 if fixed else 0,
    )
    return bytes(msg.pack(mav))


def ekf(mav: Any, flags: int) -> bytes:
    return bytes(mav.ekf_status_report_encode(flags, 0, 0, 0, 0, 0).pack(mav))


def states(events: list[Any]) -> list[VehicleState]:
    return [e for e in events if isinstance(e, VehicleState)]


def test_sitl_planes_dead_reckoned_positions_before_its_fix_are_not_taken() -> None:
    mav = frames()
    link = AutopilotAdapter(AutopilotSettings(modes=PLANE_MODES, firmware="arduplane"))
    link.start(0.0)
    taken: list[VehicleState] = []
    for boot_ms, lat, lon in SITL_PRE_FIX:
        t = boot_ms / 1000.0
        data = heartbeat_and_attitude(mav, boot_ms) + gps_raw(mav, 0) + ekf(mav, 0x400)
        data += position(mav, boot_ms, lat, lon)
        taken += states(link.receive(data, t))
    assert taken == [], f"took a position before the GPS fix: {taken[0]}"
    assert link.state is None
    # With the fix, the next position is taken.
    boot_ms, lat, lon = SITL_FIXED
    data = gps_raw(mav, 6, lat, lon) + heartbeat_and_attitude(mav, boot_ms)
    data += position(mav, boot_ms, lat, lon, alt_mm=90090)
    fixed = states(link.receive(data, boot_ms / 1000.0))
    assert len(fixed) == 1
    assert (fixed[0].lat_deg, fixed[0].lon_deg) == (lat / 1e7, lon / 1e7)


def test_a_position_is_taken_with_an_ekf_position_during_a_gps_outage() -> None:
    """Losing the fix in flight does not blind the engine while the EKF still has a position."""
    mav = frames()
    link = AutopilotAdapter(AutopilotSettings(modes=PLANE_MODES, firmware="arduplane"))
    link.start(0.0)
    data = gps_raw(mav, 1) + ekf(mav, 0x33F) + heartbeat_and_attitude(mav, 100_000)
    data += position(mav, 100_000, 306372000, -964787000, alt_mm=140_000)
    assert len(states(link.receive(data, 100.0))) == 1
    # Neither a fix nor an EKF position: not taken.
    data = ekf(mav, 0xA7) + heartbeat_and_attitude(mav, 101_000)
    data += position(mav, 101_000, 306373000, -964787000, alt_mm=140_000)
    assert states(link.receive(data, 101.0)) == []


def test_the_simulated_arduplane_dead_reckons_before_its_fix_and_the_adapter_ignores_it() -> None:
    """The simulated ArduPlane sends SITL's kind of early positions; none becomes a state."""
    sim = SimAutopilot(
        FakeModel(PLANE_MODES),
        firmware="arduplane",
        system_id=1,
        origin_lat_deg=HOME[0],
        origin_lon_deg=HOME[1],
        start_time_unix_us=START_UNIX_US,
        boot_s=0.0,
    )
    link = AutopilotAdapter(AutopilotSettings(modes=PLANE_MODES, firmware="arduplane"))
    sim.receive(link.start(0.0), 0.0)
    parser = mavlink2.MAVLink(None)
    early: list[tuple[float, int, int]] = []
    taken: list[VehicleState] = []
    for i in range(400):  # 20 s
        t = i * 0.05
        data = sim.advance(t)
        for msg in parser.parse_buffer(data) or []:
            if msg.get_type() == "GLOBAL_POSITION_INT" and abs(msg.lat) < 10_000_000:
                early.append((t, msg.lat, msg.lon))
        taken += states(link.receive(data, t))
        sim.receive(link.poll(t), t)
    moved_m = [math.hypot(lat, lon) * 1e-7 * 111_195 for _, lat, lon in early]
    assert early, "no position before the fix"
    assert max(moved_m) > 20.0, "the early positions do not drift away from (0, 0)"
    assert taken, "no position after the fix"
    home_lat, home_lon = HOME[0], HOME[1]
    assert all(abs(s.lat_deg - home_lat) < 0.01 and abs(s.lon_deg - home_lon) < 0.01 for s in taken)
