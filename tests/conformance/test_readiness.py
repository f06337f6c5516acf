"""Readiness: a fresh vehicle is not ready at once; what says when it becomes ready.

Measured on the SITL builds (vehicle seconds after the ground station connected;
ArduPilot's lockstep clock makes them the same run after run): the GPS gets its
3D fix at 10 s on every firmware, the pre-arm checks pass (SYS_STATUS health bit
PREARM_CHECK) at 24 s (rover), 42 s (copter) and 23 s (plane), and the EKF has
an absolute horizontal position at 42, 42 and 21 s. A simulation is as strict as
ArduPilot when each comes on within half to one and a half times those.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

from harness import Peer
from pymavlink.dialects.v20 import ardupilotmega as mavlink2

PREARM_CHECK = mavlink2.MAV_SYS_STATUS_PREARM_CHECK  # 0x10000000
POS_HORIZ_ABS = mavlink2.EKF_POS_HORIZ_ABS

MEASURED_S = {
    "rover": {"gps": 10.05, "prearm": 24.05, "ekf": 42.05},
    "copter": {"gps": 10.04, "prearm": 42.04, "ekf": 42.04},
    "plane": {"gps": 10.06, "prearm": 23.06, "ekf": 21.06},
}
WAIT_S = 90.0


def comes_on(peer: Peer, kind: str, condition: Callable[[Any], bool], what: str) -> float:
    """When ``condition`` first held on a message of ``kind`` (off on the first such message)."""
    first = peer.wait_for(kind, WAIT_S, since=0)
    assert not condition(first), f"{what} at the first {kind} (t={peer.time_of(first):.1f} s)"
    on = peer.wait_for(kind, WAIT_S, where=condition, since=0, describe=what)
    return peer.time_of(on)


def assert_near(peer: Peer, signal: str, at_s: float) -> None:
    measured = MEASURED_S[peer.kind][signal]
    assert 0.5 * measured <= at_s <= 1.5 * measured, (
        f"{signal} came on at t={at_s:.1f} s; ArduPilot's at {measured:g} s"
    )


def test_gps_fix_comes_after_boot(peer: Peer) -> None:
    def fixed(msg: Any) -> bool:
        return bool(msg.fix_type >= mavlink2.GPS_FIX_TYPE_3D_FIX)

    assert_near(peer, "gps", comes_on(peer, "GPS_RAW_INT", fixed, "a 3D GPS fix"))


def test_prearm_check_passes_when_ready(peer: Peer) -> None:
    def present(msg: Any) -> bool:
        return bool(msg.onboard_control_sensors_present & PREARM_CHECK)

    def healthy(msg: Any) -> bool:
        return bool(msg.onboard_control_sensors_health & PREARM_CHECK)

    assert present(peer.wait_for("SYS_STATUS", WAIT_S, since=0)), "PREARM_CHECK not present"
    assert_near(peer, "prearm", comes_on(peer, "SYS_STATUS", healthy, "pre-arm checks passing"))


def test_ekf_gets_an_absolute_horizontal_position(peer: Peer) -> None:
    assert peer.subscribed["EKF_STATUS_REPORT"] == mavlink2.MAV_RESULT_ACCEPTED

    def absolute(msg: Any) -> bool:
        return bool(msg.flags & POS_HORIZ_ABS)

    at_s = comes_on(peer, "EKF_STATUS_REPORT", absolute, "EKF absolute horizontal position")
    assert_near(peer, "ekf", at_s)
