"""ArduRover's EKF failsafe: a rover armed before its EKF has a position.

Measured on SITL: armed in MANUAL once the pre-arm checks pass (24 s), before the EKF
uses the GPS (about 42 s), the rover's EKF check (Rover::ekf_check, 10 Hz) counts a
second of failures and turns its EKF failsafe on, silently since MANUAL needs no
position. The position comes good at 41.57 s; GUIDED is still refused at 42.08 s with
"Flight mode change failed"; the count runs back down and CRITICAL "EKF failsafe
cleared" comes at 42.57 s, after which GUIDED is entered. A simulation that accepts
GUIDED as soon as the position is good is kinder than ArduPilot by a second: a
behaviour that asks once, at the first good position, fails on the real rover.
"""

from __future__ import annotations

from typing import Any

from harness import Peer, backends
from pymavlink.dialects.v20 import ardupilotmega as mavlink2

CLEARED_AFTER_S = 1.0
"""From a good EKF position to "EKF failsafe cleared" (ten checks at 10 Hz; 1.0 s measured)."""
EKF_REPORT_INTERVAL_US = 50_000
"""EKF_STATUS_REPORT at 20 Hz: the good position is seen within 0.05 s of coming."""


def positioned(msg: Any) -> bool:
    """the EKF has an absolute horizontal position"""
    return bool(msg.flags & mavlink2.EKF_POS_HORIZ_ABS)


def prearm_ok(msg: Any) -> bool:
    """the pre-arm checks pass"""
    return bool(msg.onboard_control_sensors_health & mavlink2.MAV_SYS_STATUS_PREARM_CHECK)


@backends("fresh_peer", kinds=("rover",))
def test_a_rover_armed_before_its_position_refuses_guided_until_the_failsafe_clears(
    fresh_peer: Peer,
) -> None:
    peer = fresh_peer
    assert peer.message_interval("EKF_STATUS_REPORT", EKF_REPORT_INTERVAL_US).result == (
        mavlink2.MAV_RESULT_ACCEPTED
    )
    peer.wait_for("SYS_STATUS", 60.0, where=prearm_ok)
    first = peer.wait_for("EKF_STATUS_REPORT", 2.0)
    assert not positioned(first), f"positioned already at t={peer.now_s:.1f} s"
    assert peer.arm().result == mavlink2.MAV_RESULT_ACCEPTED  # in MANUAL, throttle at trim

    good = peer.wait_for("EKF_STATUS_REPORT", 60.0, where=positioned)
    good_s = peer.time_of(good)
    mark = peer.mark()
    ack = peer.set_mode("GUIDED")
    assert ack.result == mavlink2.MAV_RESULT_FAILED, (
        f"GUIDED accepted {peer.now_s - good_s:.2f} s after the EKF's position came good"
    )
    peer.wait_for(
        "STATUSTEXT", 0.5, where=lambda m: m.text == "Flight mode change failed", since=mark
    )

    cleared = peer.wait_for(
        "STATUSTEXT", 3.0, where=lambda m: m.text == "EKF failsafe cleared", since=mark
    )
    assert cleared.severity == mavlink2.MAV_SEVERITY_CRITICAL
    assert abs(peer.time_of(cleared) - good_s - CLEARED_AFTER_S) <= 0.3
    assert peer.set_mode("GUIDED").result == mavlink2.MAV_RESULT_ACCEPTED
    peer.disarm(force=True)
