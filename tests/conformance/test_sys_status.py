"""SYS_STATUS's sensor bits over boot, and what MAVProxy makes of them.

Measured on each SITL build with tools/sitl_measurements/q6_sys_status.py: the present,
enabled and health bit fields from the first SYS_STATUS to ready, with the fence on and
off, armed and disarmed. MAVProxy reads them: its fence module says "fence breach" when
the geofence's health bit goes from set to clear (it starts out healthy), and its arm
module says "Arming checks disabled" on arming unless ARMING_CHECK (or, on newer
firmware, ARMING_SKIPCHK) from its parameter download says every check is on.
"""

from __future__ import annotations

from typing import Any

from harness import Peer
from pymavlink.dialects.v20 import ardupilotmega as mavlink2
from test_params import download_list

GPS = mavlink2.MAV_SYS_STATUS_SENSOR_GPS
AHRS = mavlink2.MAV_SYS_STATUS_AHRS
PREARM = mavlink2.MAV_SYS_STATUS_PREARM_CHECK
GEOFENCE = mavlink2.MAV_SYS_STATUS_GEOFENCE
LOGGING = mavlink2.MAV_SYS_STATUS_LOGGING
AIRSPEED = mavlink2.MAV_SYS_STATUS_SENSOR_DIFFERENTIAL_PRESSURE

READY: dict[str, tuple[int, int, int]] = {
    "rover": (0x1331DC2F, 0x1221802F, 0x1331812F),
    "copter": (0x5371FC2F, 0x52619C2F, 0x57719C2F),
    "plane": (0x1361FC3F, 0x1261803F, 0x1331803F),
}
"""(present, enabled, health) once ready to arm, disarmed in the manual mode, fence off
(measured). ArduPlane's default fence is a polygon, none uploaded: not present."""

BOOTING: dict[str, int] = {kind: GPS | AHRS | PREARM for kind in READY}
"""The bits that come as the vehicle boots: the GPS at its fix, the AHRS at the EKF's
origin (healthy then, ArduRover's once the EKF uses the GPS), the pre-arm checks when
they pass; and ArduPlane's airspeed sensor healthy at 3.5 s."""
BOOTING["plane"] |= AIRSPEED


def bits(msg: Any) -> tuple[int, int, int]:
    """SYS_STATUS's (present, enabled, health)."""
    return (
        int(msg.onboard_control_sensors_present),
        int(msg.onboard_control_sensors_enabled),
        int(msg.onboard_control_sensors_health),
    )


class MavproxyChecks:
    """MAVProxy's fence and arm modules' reading of a vehicle, as their source does it.

    ``mavproxy_fence.FenceModule.handle_sys_status`` (present, enabled and healthy start
    False, False, True; a change of each is said) and ``mavproxy_arm.ArmModule``
    (on each arming, "Arming checks disabled" unless ``all_checks_enabled``).
    """

    def __init__(self, params: dict[str, float]) -> None:
        self.params = params
        self.present, self.enabled, self.healthy = False, False, True
        self.was_armed = False
        self.said: list[str] = []

    def all_checks_enabled(self) -> bool:
        """mavproxy_arm.all_checks_enabled: ARMING_CHECK 1 or every bit, else SKIPCHK 0."""
        check = self.params.get("ARMING_CHECK")
        if check is not None:
            mask = int(check)
            full = 0b1111111111111111111111110
            return mask == 1 or mask & full == full
        skip = self.params.get("ARMING_SKIPCHK")
        return skip is not None and int(skip) == 0

    def take(self, msg: Any) -> None:
        """One message from the vehicle."""
        kind = msg.get_type()
        if kind == "SYS_STATUS":
            present, enabled, health = (bool(b & GEOFENCE) for b in bits(msg))
            for was, now, on, off in (
                (self.present, present, "fence present", "fence removed"),
                (self.enabled, enabled, "fence enabled", "fence disabled"),
                (self.healthy, health, "fence OK", "fence breach"),
            ):
                if was != now:
                    self.said.append(on if now else off)
            self.present, self.enabled, self.healthy = present, enabled, health
        elif kind == "HEARTBEAT" and msg.type != mavlink2.MAV_TYPE_GCS:
            armed = bool(msg.base_mode & mavlink2.MAV_MODE_FLAG_SAFETY_ARMED)
            if armed != self.was_armed:
                self.was_armed = armed
                if armed and not self.all_checks_enabled():
                    self.said.append("Arming checks disabled")


def test_sensor_bits_over_boot_and_what_mavproxy_says(fresh_peer: Peer) -> None:
    peer = fresh_peer
    kind = peer.kind
    peer.message_interval("SYS_STATUS", 200_000)
    # MAVProxy downloads every parameter on connecting.
    params = {str(m.param_id): float(m.param_value) for m in download_list(peer).values()}
    mavproxy = MavproxyChecks(params)
    statuses = [m for _, m in peer.history if m.get_type() == "SYS_STATUS"]
    peer.wait_ready()
    peer.run_for(3.0)
    ready = peer.wait_for("SYS_STATUS", 2.0, since=peer.mark())
    assert tuple(hex(b) for b in bits(ready)) == tuple(hex(b) for b in READY[kind])
    # Before ready, only the booting bits differ (and stay off at first).
    first = bits(statuses[0]) if statuses else bits(ready)
    for now, then in zip(first, READY[kind], strict=True):
        assert hex(now & ~BOOTING[kind]) == hex(then & ~BOOTING[kind])
    history_start = 0

    def phase(seconds: float) -> tuple[int, int, int]:
        nonlocal history_start
        peer.run_for(seconds)
        latest = None
        for _, msg in peer.history[history_start:]:
            mavproxy.take(msg)
            if msg.get_type() == "SYS_STATUS":
                latest = msg
        history_start = len(peer.history)
        assert latest is not None
        return bits(latest)

    phase(0.5)
    try:
        peer.param_set("FENCE_ENABLE", 1, mavlink2.MAV_PARAM_TYPE_INT8)
        present, enabled, health = phase(2.0)
        if kind == "plane":  # a polygon fence with no polygon: absent, and arming refused
            assert not present & GEOFENCE and not enabled & GEOFENCE
            assert not health & PREARM
        else:
            assert present & enabled & health & GEOFENCE
    finally:
        peer.param_set("FENCE_ENABLE", 0, mavlink2.MAV_PARAM_TYPE_INT8)
    assert phase(2.0) == READY[kind]
    assert peer.arm().result == mavlink2.MAV_RESULT_ACCEPTED
    present, enabled, health = phase(2.0)
    assert enabled == READY[kind][1] | LOGGING  # the logger runs while armed
    assert peer.disarm(force=True).result == mavlink2.MAV_RESULT_ACCEPTED
    present, enabled, health = phase(3.0)
    assert enabled & LOGGING, "the logger stops 15 s after the disarm, not at once"
    fenced = ["fence present", "fence enabled", "fence disabled"]
    assert mavproxy.said == ([] if kind == "plane" else fenced)
