"""SYS_STATUS's sensor bits (present, enabled, healthy) as ArduPilot sets them.

Ground stations read these bits: MAVProxy says "fence breach" when the geofence's health
bit goes from set to clear, and QGroundControl and Mission Planner colour their sensor
panels from them. ArduPilot builds them in ``GCS::update_sensor_status_flags`` (the
sensors, the AHRS, the logger, the fence, the pre-arm checks) and each firmware's
``update_vehicle_sensor_status_flags`` (the controllers its current mode uses, terrain,
proximity, propulsion). The bits here were measured on the SITL builds of
``../shared/ardupilot-sitl`` over boot, with the fence on and off, armed and disarmed
(``tools/sitl_measurements/q6_sys_status.py``); what depends on the mode follows the
firmwares' source.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from typing import Final

from pymavlink.dialects.v20 import ardupilotmega as mavlink2


def _bit(name: str) -> int:
    return int(getattr(mavlink2, f"MAV_SYS_STATUS_{name}"))


GYRO: Final = _bit("SENSOR_3D_GYRO")
ACCEL: Final = _bit("SENSOR_3D_ACCEL")
MAG: Final = _bit("SENSOR_3D_MAG")
BARO: Final = _bit("SENSOR_ABSOLUTE_PRESSURE")
AIRSPEED: Final = _bit("SENSOR_DIFFERENTIAL_PRESSURE")
GPS: Final = _bit("SENSOR_GPS")
LASER: Final = _bit("SENSOR_LASER_POSITION")
RATE: Final = _bit("SENSOR_ANGULAR_RATE_CONTROL")
ATTITUDE: Final = _bit("SENSOR_ATTITUDE_STABILIZATION")
YAW: Final = _bit("SENSOR_YAW_POSITION")
Z_CONTROL: Final = _bit("SENSOR_Z_ALTITUDE_CONTROL")
XY_CONTROL: Final = _bit("SENSOR_XY_POSITION_CONTROL")
MOTORS: Final = _bit("SENSOR_MOTOR_OUTPUTS")
RC: Final = _bit("SENSOR_RC_RECEIVER")
GEOFENCE: Final = _bit("GEOFENCE")
AHRS: Final = _bit("AHRS")
TERRAIN: Final = _bit("TERRAIN")
LOGGING: Final = _bit("LOGGING")
BATTERY: Final = _bit("SENSOR_BATTERY")
PROXIMITY: Final = _bit("SENSOR_PROXIMITY")
PREARM: Final = _bit("PREARM_CHECK")
PROPULSION: Final = _bit("SENSOR_PROPULSION")

_SENSORS: Final = GYRO | ACCEL | MAG | BARO | MOTORS | RC | BATTERY
"""Present, enabled and healthy from power-on on every firmware (SITL's sensors)."""

LOG_PERSIST_S: Final = 15.0
"""The logger keeps logging (LOGGING enabled) this long after a disarm or a refused
arming (AP_Logger's HAL_LOGGER_ARM_PERSIST); LOG_DISARMED is 0, so not before."""

AIRSPEED_HEALTHY_S: Final = 3.5
"""ArduPlane's airspeed sensor turns healthy about 3.5 s after power-on (measured 3.46 s;
present and enabled from the first SYS_STATUS)."""


@dataclass(frozen=True, slots=True)
class VehicleBits:
    """The bits one firmware adds to the common ones, whatever the mode."""

    present: int
    enabled: int
    health: int
    ahrs_healthy_with_position: bool
    """AHRS healthy only once the EKF uses the GPS (ArduRover, measured 41.85 s), not as
    soon as it is enabled at the EKF origin (ArduCopter, ArduPlane)."""


VEHICLE_BITS: Final[Mapping[str, VehicleBits]] = {
    # GCS_Rover: the controllers; proximity "not connected" reads healthy (LASER_POSITION).
    "ardurover": VehicleBits(RATE | ATTITUDE | YAW | XY_CONTROL, 0, LASER, True),
    # GCS_Copter: rate, attitude and yaw control always on; terrain, propulsion, proximity.
    "arducopter": VehicleBits(
        RATE | ATTITUDE | YAW | Z_CONTROL | XY_CONTROL | TERRAIN | PROPULSION,
        RATE | ATTITUDE | YAW | TERRAIN | PROPULSION,
        RATE | ATTITUDE | YAW | TERRAIN | PROPULSION | PROXIMITY,
        False,
    ),
    # GCS_Plane: the airspeed sensor; terrain present and enabled but without data.
    "arduplane": VehicleBits(
        AIRSPEED | RATE | ATTITUDE | YAW | Z_CONTROL | XY_CONTROL | TERRAIN,
        AIRSPEED | TERRAIN,
        0,
        False,
    ),
}

_ROVER_UNSTABILISED: Final = frozenset({"MANUAL", "HOLD", "ACRO"})
_ROVER_AUTOPILOT: Final = frozenset(
    {"AUTO", "GUIDED", "RTL", "SMART_RTL", "LOITER", "FOLLOW", "CIRCLE", "DOCK"}
)
_COPTER_POSITION: Final = frozenset(
    {
        "AUTO",
        "AVOID_ADSB",
        "GUIDED",
        "LOITER",
        "RTL",
        "CIRCLE",
        "LAND",
        "POSHOLD",
        "BRAKE",
        "THROW",
        "SMART_RTL",
    }
)
_COPTER_ALTITUDE: Final = frozenset({"ALT_HOLD", "GUIDED_NOGPS", "SPORT", "AUTOTUNE", "FLOWHOLD"})
_PLANE_RATE: Final = frozenset({"ACRO", "QACRO"})
_PLANE_STABILISED: Final = frozenset(
    {
        "STABILIZE",
        "FBWA",
        "FBWB",
        "AUTOTUNE",
        "QSTABILIZE",
        "QHOVER",
        "QLAND",
        "QLOITER",
        "QAUTOTUNE",
        "CRUISE",
        "TRAINING",
    }
)
_PLANE_NAVIGATING: Final = frozenset(
    {
        "AUTO",
        "RTL",
        "LOITER",
        "AVOID_ADSB",
        "GUIDED",
        "CIRCLE",
        "TAKEOFF",
        "AUTOLAND",
        "QRTL",
        "LOITERALTQLAND",
        "THERMAL",
    }
)


def mode_bits(firmware: str, mode: str) -> int:
    """The controller bits ``mode`` turns on (enabled and healthy at once), per firmware."""
    if firmware == "ardurover":
        bits = 0 if mode in _ROVER_UNSTABILISED else RATE | ATTITUDE
        return bits | (YAW | XY_CONTROL if mode in _ROVER_AUTOPILOT else 0)
    if firmware == "arducopter":
        if mode in _COPTER_POSITION:
            return Z_CONTROL | XY_CONTROL
        return Z_CONTROL if mode in _COPTER_ALTITUDE else 0
    if mode in _PLANE_RATE:
        return RATE
    if mode in _PLANE_STABILISED:
        return RATE | ATTITUDE
    if mode in _PLANE_NAVIGATING:
        return RATE | ATTITUDE | YAW | Z_CONTROL | XY_CONTROL
    return 0


@dataclass(frozen=True, slots=True)
class Inputs:
    """What the bits depend on at one instant."""

    since_boot_s: float
    mode: str
    gps_fixed: bool
    ekf_origin: bool
    ekf_position: bool
    prearm_ok: bool
    """The pre-arm checks pass now (or the vehicle is armed: ArduPilot reports it healthy)."""
    logging: bool
    """Armed, or within LOG_PERSIST_S of a disarm or a refused arming."""
    fence: tuple[bool, bool, bool]
    """The geofence's (present, enabled, healthy) (AC_Fence::sys_status_*)."""


def sensor_bits(firmware: str, now: Inputs) -> tuple[int, int, int]:
    """SYS_STATUS's (present, enabled, health) for ``firmware`` in the state ``now``."""
    vehicle = VEHICLE_BITS[firmware]
    present = _SENSORS | AHRS | LOGGING | PREARM | vehicle.present
    enabled = _SENSORS | PREARM | vehicle.enabled
    health = _SENSORS | LOGGING | vehicle.health
    if firmware == "arduplane" and now.since_boot_s >= AIRSPEED_HEALTHY_S:
        health |= AIRSPEED
    if now.gps_fixed:
        present |= GPS
        enabled |= GPS
        health |= GPS
    if now.ekf_origin:
        enabled |= AHRS
        if now.ekf_position or not vehicle.ahrs_healthy_with_position:
            health |= AHRS
    if now.prearm_ok:
        health |= PREARM
    if now.logging:
        enabled |= LOGGING
    controllers = mode_bits(firmware, now.mode)
    enabled |= controllers
    health |= controllers
    fence_present, fence_enabled, fence_healthy = now.fence
    present |= GEOFENCE if fence_present else 0
    enabled |= GEOFENCE if fence_enabled else 0
    health |= GEOFENCE if fence_healthy else 0
    return present, enabled, health
