"""The autopilot adapter's AutopilotHealth: from SYS_STATUS and GPS_RAW_INT, at their rates.

Through real pymavlink bytes: from the simulated autopilot (which sends what ArduPilot
SITL sends for the battery and the satellites, docs/clarklink.md), and from hand-made
frames for MAVLink's "not measured" values and for hostile ones.
"""

from __future__ import annotations

from typing import Any

import pytest
from pymavlink.dialects.v20 import ardupilotmega as mavlink2
from test_io_autopilot import HOME, PLANE_MODES, START_UNIX_US, FakeModel

from clark_engine.io.autopilot import AutopilotAdapter
from clark_engine.io.autopilot_settings import AutopilotSettings
from clark_engine.runtime.events import AutopilotHealth
from clark_engine.sim.ardupilot.autopilot import SimAutopilot

PREARM = 0x10000000  # MAV_SYS_STATUS_PREARM_CHECK


def adapter() -> AutopilotAdapter:
    return AutopilotAdapter(AutopilotSettings(modes=PLANE_MODES, firmware="arduplane"))


def frames() -> Any:
    return mavlink2.MAVLink(None, 1, 1)  # the autopilot's system and component


def sys_status(millivolts: int, remaining: int, prearm: bool | None = True) -> bytes:
    mav = frames()
    present = PREARM if prearm is not None else 0
    health = PREARM if prearm else 0
    msg = mav.sys_status_encode(
        present, present, health, 0, millivolts, -1, remaining, 0, 0, 0, 0, 0, 0
    )
    return bytes(msg.pack(mav))


def gps_raw(fix_type: int, satellites: int) -> bytes:
    mav = frames()
    msg = mav.gps_raw_int_encode(0, fix_type, 0, 0, 0, 65535, 65535, 0, 0, satellites)
    return bytes(msg.pack(mav))


def healths(events: list[Any]) -> list[AutopilotHealth]:
    return [e for e in events if isinstance(e, AutopilotHealth)]


def test_from_the_simulated_autopilot_booting_to_ready() -> None:
    """A fresh ArduPlane: the battery at once, the GPS after its fix, pre-arm at the end."""
    sim = SimAutopilot(
        FakeModel(PLANE_MODES),
        firmware="arduplane",
        system_id=1,
        origin_lat_deg=HOME[0],
        origin_lon_deg=HOME[1],
        start_time_unix_us=START_UNIX_US,
        boot_s=0.0,
    )
    link = adapter()
    sim.receive(link.start(0.0), 0.0)
    seen: list[AutopilotHealth] = []
    counts = {"SYS_STATUS": 0, "GPS_RAW_INT": 0}
    parser = mavlink2.MAVLink(None)
    for i in range(1200):  # 60 s
        t = i * 0.05
        data = sim.advance(t)
        for msg in parser.parse_buffer(data) or []:
            counts[msg.get_type()] = counts.get(msg.get_type(), 0) + 1
        seen += healths(link.receive(data, t))
        sim.receive(link.poll(t), t)
    # one per SYS_STATUS and per GPS_RAW_INT: their stream rates, not one per change
    assert len(seen) == counts["SYS_STATUS"] + counts["GPS_RAW_INT"]
    assert 100 <= len(seen) <= 200  # 1 Hz + 2 Hz once streaming
    distinct = list(dict.fromkeys(seen))
    assert distinct[-1] == AutopilotHealth(
        battery_v=12.6, battery_pct=100, gps_fix_type=3, satellites=10, prearm_ok=True
    )
    assert any(h.gps_fix_type < 3 and h.prearm_ok is False for h in distinct)  # before the fix
    assert link.health == distinct[-1]


@pytest.mark.parametrize(
    ("data", "expected"),
    [
        # MAVLink's "not measured": voltage UINT16_MAX, remaining -1, satellites 255
        (sys_status(65535, -1, prearm=None), AutopilotHealth()),
        (gps_raw(0, 255), AutopilotHealth(gps_fix_type=0, satellites=None)),
        # ArduPilot SITL as measured: 12.6 V, full, RTK fixed with 10 satellites
        (sys_status(12600, 100) + gps_raw(6, 10), AutopilotHealth(12.6, 100, 6, 10, True)),
        # a flat battery and no satellite are figures, not unknowns
        (sys_status(0, 0, prearm=False), AutopilotHealth(0.0, 0, prearm_ok=False)),
        # hostile or garbled: out of MAVLink's own ranges, never passed on
        (sys_status(12600, 120) + gps_raw(200, 254), AutopilotHealth(12.6, None, 0, 254, True)),
    ],
)
def test_mavlink_figures_become_known_or_none(data: bytes, expected: AutopilotHealth) -> None:
    got = healths(adapter().receive(data, 1.0))
    assert got and got[-1] == expected


def test_health_from_another_system_is_ignored() -> None:
    mav = mavlink2.MAVLink(None, 2, 1)
    msg = mav.sys_status_encode(0, 0, 0, 0, 1000, -1, 3, 0, 0, 0, 0, 0, 0)
    assert healths(adapter().receive(bytes(msg.pack(mav)), 1.0)) == []
