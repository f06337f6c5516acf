"""Arming before the vehicle is ready is refused, and the autopilot says why."""

from __future__ import annotations

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
