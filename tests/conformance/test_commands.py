"""Commands on the ground, every vehicle ready and disarmed: DO_CHANGE_SPEED's acceptance
per mode, and DO_SET_SERVO on outputs with and without a function.

Observed as modesweep.py observes modes (result, mode and armed state after, texts);
SPEED_TABLE and SERVO_TABLE are what ArduPilot SITL did (``python modesweep.py
test_commands KIND``). What a speed change does in flight is in test_guided.py.
"""

from __future__ import annotations

from harness import Peer
from modesweep import Step, Sweep, command_texts, fast_heartbeats, set_mode
from pymavlink.dialects.v20 import ardupilotmega as mavlink2

SPEED_REQUESTS: dict[str, tuple[tuple[str, int, float], ...]] = {
    "rover": (
        ("MANUAL", 1, 2.0),
        ("HOLD", 1, 2.0),
        ("GUIDED", 1, 2.0),  # no target yet
        ("GUIDED", 2, 2.0),
        ("GUIDED", 1, 0.0),
    ),
    "copter": (
        ("STABILIZE", 1, 3.0),
        ("LOITER", 1, 3.0),
        ("GUIDED", 1, 3.0),
        ("GUIDED", 0, 3.0),
        ("GUIDED", 1, 0.0),
        ("GUIDED", 1, -1.0),
        ("GUIDED", 3, 1.0),
    ),
    "plane": (
        ("MANUAL", 0, 15.0),
        ("LOITER", 0, 15.0),
        ("TAKEOFF", 0, 15.0),
        ("GUIDED", 0, 15.0),
        ("GUIDED", 0, 40.0),
        ("GUIDED", 0, 5.0),
        ("GUIDED", 0, 0.0),
        ("GUIDED", 1, 30.0),
        ("GUIDED", 1, 0.0),
    ),
}
"""(mode, speed type, m/s) sent as MAV_CMD_DO_CHANGE_SPEED on the ground, disarmed."""

SERVO_REQUESTS = (1, 9, 16, 17)
"""Outputs DO_SET_SERVO is tried on: 1 has a function on every vehicle, 9-16 have none."""
SERVO_PWM_US = 1234


def observe_commands(peer: Peer) -> dict[str, Sweep]:
    """DO_CHANGE_SPEED per mode, then DO_SET_SERVO per output, on a ready vehicle."""
    peer.wait_ready()
    manual = str(peer.spec.autopilot["manual_mode"])
    fast_heartbeats(peer, True)
    try:
        speeds: Sweep = {}
        for mode, speed_type, speed in SPEED_REQUESTS[peer.kind]:
            set_mode(peer, mode)
            mark = peer.mark()
            ack = peer.command_long(mavlink2.MAV_CMD_DO_CHANGE_SPEED, speed_type, speed, -1)
            peer.run_for(0.2)
            hb = peer.heartbeat()
            speeds[f"{mode} type {speed_type} {speed:g} m/s"] = Step(
                ack.result,
                peer.mode_name(hb.custom_mode),
                bool(hb.base_mode & mavlink2.MAV_MODE_FLAG_SAFETY_ARMED),
                command_texts(peer.texts_since(mark)),
            )
        set_mode(peer, manual)
        servos = servo_sweep(peer)
    finally:
        fast_heartbeats(peer, False)
    return {"change_speed": speeds, "set_servo": servos}


def servo_sweep(peer: Peer) -> Sweep:
    """DO_SET_SERVO on each of SERVO_REQUESTS; the Step's mode is the output's pulse after."""
    peer.message_interval("SERVO_OUTPUT_RAW", 100_000)
    observed: Sweep = {}
    try:
        for servo in SERVO_REQUESTS:
            mark = peer.mark()
            ack = peer.command_long(mavlink2.MAV_CMD_DO_SET_SERVO, servo, SERVO_PWM_US)
            peer.run_for(0.3)
            raw = peer.wait_for("SERVO_OUTPUT_RAW", 1.0)
            pulse = getattr(raw, f"servo{servo}_raw", None) if servo <= 16 else None
            observed[f"servo {servo}"] = Step(
                ack.result,
                f"{pulse == SERVO_PWM_US}",
                peer.is_armed(),
                command_texts(peer.texts_since(mark)),
            )
    finally:
        peer.message_interval("SERVO_OUTPUT_RAW", 0)
    return observed


_CHANNEL_IN_USE = "6:ServoRelayEvent: Channel {} is already in use"
_SERVOS = {
    "servo 1": Step(4, "False", False, (_CHANNEL_IN_USE.format(1),)),
    "servo 9": Step(0, "True", False, ()),
    "servo 16": Step(0, "True", False, ()),
    "servo 17": Step(4, "False", False, (_CHANNEL_IN_USE.format(17),)),
}

TABLE: dict[str, dict[str, Sweep]] = {
    "rover": {
        "change_speed": {
            "MANUAL type 1 2 m/s": Step(4, "MANUAL", False, ()),
            "HOLD type 1 2 m/s": Step(4, "HOLD", False, ()),
            "GUIDED type 1 2 m/s": Step(4, "GUIDED", False, ()),
            "GUIDED type 2 2 m/s": Step(2, "GUIDED", False, ()),
            "GUIDED type 1 0 m/s": Step(4, "GUIDED", False, ()),
        },
        "set_servo": _SERVOS,
    },
    "copter": {
        "change_speed": {
            "STABILIZE type 1 3 m/s": Step(4, "STABILIZE", False, ()),
            "LOITER type 1 3 m/s": Step(4, "LOITER", False, ()),
            "GUIDED type 1 3 m/s": Step(0, "GUIDED", False, ()),
            "GUIDED type 0 3 m/s": Step(0, "GUIDED", False, ()),
            "GUIDED type 1 0 m/s": Step(2, "GUIDED", False, ()),
            "GUIDED type 1 -1 m/s": Step(2, "GUIDED", False, ()),
            "GUIDED type 3 1 m/s": Step(0, "GUIDED", False, ()),
        },
        "set_servo": _SERVOS,
    },
    "plane": {
        "change_speed": {
            "MANUAL type 0 15 m/s": Step(4, "MANUAL", False, ()),
            "LOITER type 0 15 m/s": Step(4, "LOITER", False, ()),
            "TAKEOFF type 0 15 m/s": Step(4, "TAKEOFF", False, ()),
            "GUIDED type 0 15 m/s": Step(0, "GUIDED", False, ("6:Set airspeed 15 m/s",)),
            "GUIDED type 0 40 m/s": Step(4, "GUIDED", False, ()),
            "GUIDED type 0 5 m/s": Step(4, "GUIDED", False, ()),
            "GUIDED type 0 0 m/s": Step(4, "GUIDED", False, ()),
            "GUIDED type 1 30 m/s": Step(0, "GUIDED", False, ("6:Set groundspeed 30",)),
            "GUIDED type 1 0 m/s": Step(0, "GUIDED", False, ("6:Set groundspeed 0",)),
        },
        "set_servo": _SERVOS,
    },
}
"""What ArduPilot SITL did (4.7.0-dev, SITL's default parameters). The airspeeds asked of
the plane are inside (15) or outside (5, 40) both SITL's limits (AIRSPEED_MIN 10,
AIRSPEED_MAX 30) and the simulated Super Cub's (13, 30)."""


def test_speed_changes_and_servos_on_the_ground(peer: Peer) -> None:
    observed = observe_commands(peer)
    problems = [
        f"{phase} {key}: {observed[phase].get(key)} where ArduPilot gave {want}"
        for phase, expected in TABLE[peer.kind].items()
        for key, want in expected.items()
        if observed[phase].get(key) != want
    ]
    assert not problems, "\n".join(problems)
