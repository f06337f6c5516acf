"""Connecting: what a ground station learns about the autopilot in its first seconds."""

from __future__ import annotations

from harness import Peer
from pymavlink.dialects.v20 import ardupilotmega as mavlink2

VEHICLE_TYPES = {
    "rover": mavlink2.MAV_TYPE_GROUND_ROVER,
    "copter": mavlink2.MAV_TYPE_QUADROTOR,
    "plane": mavlink2.MAV_TYPE_FIXED_WING,
}

# AUTOPILOT_VERSION.capabilities of the SITL builds (ArduPilot 4.7.0-dev, 2025-07-21).
ARDUPILOT_CAPABILITIES = {"rover": 0xF1EF, "copter": 0xFBEF, "plane": 0xF36F}

# What the engine relies on (MAVLink 2, COMMAND_INT, position targets, integer missions).
NEEDED_CAPABILITIES = (
    mavlink2.MAV_PROTOCOL_CAPABILITY_MAVLINK2
    | mavlink2.MAV_PROTOCOL_CAPABILITY_COMMAND_INT
    | mavlink2.MAV_PROTOCOL_CAPABILITY_MISSION_INT
    | mavlink2.MAV_PROTOCOL_CAPABILITY_SET_POSITION_TARGET_GLOBAL_INT
    | mavlink2.MAV_PROTOCOL_CAPABILITY_PARAM_FLOAT
)


def capability_names(mask: int) -> list[str]:
    entries = mavlink2.enums["MAV_PROTOCOL_CAPABILITY"]
    return [e.name for bit, e in entries.items() if bit & mask and bit & (bit - 1) == 0]


def test_heartbeat_names_the_vehicle_type_and_ardupilot(peer: Peer) -> None:
    hb = peer.wait_for("HEARTBEAT", 2.0)
    assert hb.type == VEHICLE_TYPES[peer.kind]
    assert hb.autopilot == mavlink2.MAV_AUTOPILOT_ARDUPILOTMEGA
    assert hb.base_mode & mavlink2.MAV_MODE_FLAG_CUSTOM_MODE_ENABLED
    assert hb.mavlink_version == 3


def test_heartbeat_comes_at_1_hz(peer: Peer) -> None:
    # From 5 s: while ArduPilot starts (about 3 s) its heartbeats come irregularly.
    peer.run_for(max(0.0, 5.0 - peer.now_s))
    peer.wait_for("HEARTBEAT", 2.0)
    start_s = peer.now_s
    beats = [m for m in peer.run_for(5.0) if m.get_type() == "HEARTBEAT"]
    assert 4 <= len(beats) <= 6, f"{len(beats)} heartbeats from t={start_s:.1f} s in 5 s"


def test_boots_disarmed_in_the_manual_mode(peer: Peer) -> None:
    manual = peer.spec.modes[str(peer.spec.autopilot["manual_mode"])]
    initialising = peer.spec.modes.get("INITIALISING")

    def booted(msg: object) -> bool:
        """custom_mode past INITIALISING"""
        return getattr(msg, "custom_mode", None) != initialising

    hb = peer.wait_for("HEARTBEAT", 5.0, where=booted, since=0)
    assert not hb.base_mode & mavlink2.MAV_MODE_FLAG_SAFETY_ARMED, "armed at boot"
    assert hb.custom_mode == manual


def test_autopilot_version_on_request_message(peer: Peer) -> None:
    mark = peer.mark()
    ack = peer.command_long(
        mavlink2.MAV_CMD_REQUEST_MESSAGE, mavlink2.MAVLINK_MSG_ID_AUTOPILOT_VERSION
    )
    assert ack.result == mavlink2.MAV_RESULT_ACCEPTED
    version = peer.wait_for("AUTOPILOT_VERSION", 1.0, since=mark)
    assert version.flight_sw_version >> 24 == 4, hex(version.flight_sw_version)
    missing = NEEDED_CAPABILITIES & ~version.capabilities
    assert not missing, f"capabilities lack {capability_names(missing)}"


def test_autopilot_version_claims_nothing_ardupilot_lacks(peer: Peer) -> None:
    mark = peer.mark()
    peer.command_long(mavlink2.MAV_CMD_REQUEST_MESSAGE, mavlink2.MAVLINK_MSG_ID_AUTOPILOT_VERSION)
    version = peer.wait_for("AUTOPILOT_VERSION", 1.0, since=mark)
    extra = version.capabilities & ~ARDUPILOT_CAPABILITIES[peer.kind]
    assert not extra, f"claims {capability_names(extra)}"


def test_request_message_for_an_unknown_message_fails(peer: Peer) -> None:
    ack = peer.command_long(mavlink2.MAV_CMD_REQUEST_MESSAGE, 60000)
    assert ack.result == mavlink2.MAV_RESULT_FAILED
