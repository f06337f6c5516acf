"""Arming before the vehicle is ready is refused, and the autopilot says why."""

from __future__ import annotations

import pytest
from harness import Peer, backends
from pymavlink.dialects.v20 import ardupilotmega as mavlink2

# Seconds after connecting: past ArduPilot's start-up (streams run from about 3 s), well
# before any firmware is ready to arm (23 s at the earliest, test_readiness.py).
ARM_AT_S = 5.0


@backends("fresh_peer")
def test_arming_before_ready_is_refused_with_reasons(fresh_peer: Peer) -> None:
    peer = fresh_peer
    peer.run_for(ARM_AT_S - peer.now_s)
    mark = peer.mark()
    ack = peer.command_long(mavlink2.MAV_CMD_COMPONENT_ARM_DISARM, 1)
    assert ack.result == mavlink2.MAV_RESULT_FAILED
    peer.run_for(1.0)
    # Checks run for an arm command report as "Arm: <reason>"; ArduPilot's periodic
    # checks (every 30 s while they fail) as "PreArm: <reason>".
    reasons = [s for s in peer.texts_since(mark) if s.text.startswith(("Arm: ", "PreArm: "))]
    assert reasons, f"no reason given: {peer.texts_since(mark)}"
    assert all(s.severity == mavlink2.MAV_SEVERITY_CRITICAL for s in reasons), reasons
    hb = peer.wait_for("HEARTBEAT", 2.0)
    assert not hb.base_mode & mavlink2.MAV_MODE_FLAG_SAFETY_ARMED


def test_arm_with_a_bad_value_is_unsupported(peer: Peer) -> None:
    ack = peer.command_long(mavlink2.MAV_CMD_COMPONENT_ARM_DISARM, 2)
    assert ack.result == mavlink2.MAV_RESULT_UNSUPPORTED


ARMED_TEXT = {"rover": "Throttle armed", "copter": "Arming motors", "plane": "Throttle armed"}
DISARMED_TEXT = {
    "rover": "Throttle disarmed",
    "copter": "Disarming motors",
    "plane": "Throttle disarmed",
}
COPTER_DISARM_DELAY_S = 10.0
"""ArduCopter's DISARM_DELAY: armed on the ground without taking off, it disarms after it."""


def test_arm_and_disarm_say_so_and_repeats_are_accepted_silently(peer: Peer) -> None:
    peer.wait_ready()
    mark = peer.mark()
    assert peer.arm().result == mavlink2.MAV_RESULT_ACCEPTED
    peer.run_for(0.2)
    again = peer.mark()
    assert peer.arm().result == mavlink2.MAV_RESULT_ACCEPTED
    peer.run_for(0.2)
    assert peer.texts_since(again) == []
    assert peer.disarm().result == mavlink2.MAV_RESULT_ACCEPTED
    peer.run_for(0.2)
    again = peer.mark()
    assert peer.disarm().result == mavlink2.MAV_RESULT_ACCEPTED
    peer.run_for(0.2)
    assert peer.texts_since(again) == []
    texts = [(s.severity, s.text) for s in peer.texts_since(mark)]
    info = mavlink2.MAV_SEVERITY_INFO
    assert texts == [(info, ARMED_TEXT[peer.kind]), (info, DISARMED_TEXT[peer.kind])]


def test_only_arducopter_disarms_by_itself_on_the_ground(peer: Peer) -> None:
    # ArduCopter: DISARM_DELAY (10 s) after arming without taking off, in any mode.
    # ArduRover and ArduPlane stay armed (SITL: 180 s and 40 s measured).
    peer.wait_ready()
    if peer.kind == "copter":
        assert peer.param_get("DISARM_DELAY").param_value == COPTER_DISARM_DELAY_S
    mark = peer.mark()
    armed = peer.arm()
    assert armed.result == mavlink2.MAV_RESULT_ACCEPTED
    armed_s = peer.time_of(armed)
    try:
        peer.run_for(COPTER_DISARM_DELAY_S + 3.0)
        disarms = [s for s in peer.texts_since(mark) if s.text == DISARMED_TEXT[peer.kind]]
        if peer.kind == "copter":
            assert len(disarms) == 1, disarms
            assert disarms[0].time_s - armed_s == pytest.approx(COPTER_DISARM_DELAY_S, abs=0.3)
            assert not peer.is_armed()
        else:
            assert disarms == []
            assert peer.is_armed()
    finally:
        peer.disarm()
