"""What the simulated ArduPilot says about itself: every message it streams or answers with.

:class:`Telemetry` builds each message ArduPilot sends from the vehicle's state and the
autopilot's (HEARTBEAT, SYS_STATUS, GPS_RAW_INT, GLOBAL_POSITION_INT, ATTITUDE, VFR_HUD,
SYSTEM_TIME, RC_CHANNELS, SERVO_OUTPUT_RAW, EKF_STATUS_REPORT, EXTENDED_SYS_STATE,
MISSION_CURRENT, BATTERY_STATUS, NAV_CONTROLLER_OUTPUT, FENCE_STATUS,
POSITION_TARGET_GLOBAL_INT, HOME_POSITION, AUTOPILOT_VERSION), filled as each firmware
fills it while it boots and flies (the altitudes before the fix, ArduPlane's dead reckoning,
the land detector's lag, the battery's draw); :data:`STREAM_GROUPS` is what it streams, in
emission order, and which MAV1_* rate sets each.

Apart from :class:`~clark_engine.sim.ardupilot.autopilot.SimAutopilot` because it is one
concept, the autopilot's reports, which reads the autopilot and never changes what it does:
a helper object the autopilot owns (``SimAutopilot.telemetry``), which reads its state
through it. When a message is due, which rates apply and what commands do stay in the
autopilot.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Iterable, Mapping
from typing import TYPE_CHECKING, Any, Final

from pymavlink.dialects.v20 import ardupilotmega as mavlink2

from clark_engine.mission.geo import EARTH_RADIUS_M
from clark_engine.sim.ardupilot import sys_status as ap_sys_status

if TYPE_CHECKING:
    from clark_engine.sim.ardupilot.autopilot import SimAutopilot

FIRMWARE_TYPES: Final[Mapping[str, int]] = {
    "arduplane": mavlink2.MAV_TYPE_FIXED_WING,
    "arducopter": mavlink2.MAV_TYPE_QUADROTOR,
    "ardurover": mavlink2.MAV_TYPE_GROUND_ROVER,
}
"""HEARTBEAT vehicle type per firmware."""
FIRMWARE_VERSION: Final = (4, 7, 0)
"""The ArduPilot version the simulation claims in AUTOPILOT_VERSION: the SITL build its
facts were measured on (4.7.0-dev), whose parameter names it has (MAV_SYSID,
MAV_GCS_SYSID, MAV1_*; 4.5's SYSID_THISMAV, SYSID_MYGCS and SR0_* are unknown to it)."""
FIRMWARE_VERSION_TYPE: Final = int(mavlink2.FIRMWARE_VERSION_TYPE_DEV)
"""A development build, as SITL's master build reports itself."""
CAPABILITIES: Final[Mapping[str, int]] = {
    "ardurover": 0xF1EF,
    "arducopter": 0xFBEF,
    "arduplane": 0xF36F,
}
"""AUTOPILOT_VERSION capabilities, exactly as the SITL builds report them."""
M_PER_DEG_LAT: Final = math.radians(1.0) * EARTH_RADIUS_M
"""Metres per degree of latitude, on the sphere the vehicle models use."""
INITIALISING_S: Final = 1.0
"""How long a firmware with an INITIALISING mode reports it after power-on."""
LANDED_REPORT_DELAY_S: Final = 1.6
"""ArduCopter's land detector: on the ground this long after touchdown (measured 1.6 s)."""
BATTERY_VOLTAGE_MV: Final = 12600
"""The battery's voltage (SITL's SIM_BATT_VOLTAGE; it does not sag in SITL either)."""
FULL_THROTTLE_CURRENT_A: Final[Mapping[str, float]] = {
    "arducopter": 56.0,
    "arduplane": 23.0,
    "ardurover": 10.0,
}
"""Battery current at full throttle, so a hovering copter draws ~28 A and a cruising
plane ~11 A, as SITL's do."""
UINT16_MAX: Final = 65535
STREAM_GROUPS: Final[Mapping[str, str | None]] = {
    "HEARTBEAT": None,
    "SYS_STATUS": "MAV1_EXT_STAT",
    "GPS_RAW_INT": "MAV1_EXT_STAT",
    "MISSION_CURRENT": "MAV1_EXT_STAT",
    "NAV_CONTROLLER_OUTPUT": "MAV1_EXT_STAT",
    "FENCE_STATUS": "MAV1_EXT_STAT",
    "POSITION_TARGET_GLOBAL_INT": "MAV1_EXT_STAT",
    "EXTENDED_SYS_STATE": "MAV1_EXT_STAT",
    "GLOBAL_POSITION_INT": "MAV1_POSITION",
    "ATTITUDE": "MAV1_EXTRA1",
    "VFR_HUD": "MAV1_EXTRA2",
    "SYSTEM_TIME": "MAV1_EXTRA3",
    "EKF_STATUS_REPORT": "MAV1_EXTRA3",
    "BATTERY_STATUS": "MAV1_EXTRA3",
    "RC_CHANNELS": "MAV1_RC_CHAN",
    "SERVO_OUTPUT_RAW": "MAV1_RC_CHAN",
}
"""Streamed messages, in emission order, and the MAV1_* parameter (Hz) that sets each
one's default rate (None: HEARTBEAT, always 1 Hz by default), as ArduPilot groups them."""
_AUTO_MODES: Final = frozenset({"AUTO", "RTL", "SMART_RTL", "LAND", "LOITER", "TAKEOFF"})
"""Modes that fly themselves (HEARTBEAT's GUIDED_ENABLED flag)."""
_LANDED: Final[Mapping[str, int]] = {
    "on_ground": mavlink2.MAV_LANDED_STATE_ON_GROUND,
    "in_air": mavlink2.MAV_LANDED_STATE_IN_AIR,
    "taking_off": mavlink2.MAV_LANDED_STATE_TAKEOFF,
    "landing": mavlink2.MAV_LANDED_STATE_LANDING,
}
_EKF_UNINITIALISED: Final = 0x400
_EKF_ATTITUDE_ONLY: Final = 0xA7  # attitude, velocities, vertical position, constant position
_EKF_POSITION: Final = 0x33F  # ... and absolute and relative horizontal position
_EKF_UNINITIALISED_S: Final = 3.6
"""EKF_STATUS_REPORT says uninitialised until this long after power-on (measured 3.6-4 s)."""
PLANE_PRE_FIX_DRIFT_START: Final = 0.37
"""ArduPlane's dead reckoning before its GPS fix starts at this share of the time to the
fix (SITL: 3.5 s of 9.3 s, once "Airspeed 1 calibrated"): its DCM integrates the airspeed
sensor's reading along the heading from 0, 0, so GLOBAL_POSITION_INT drifts away from
(0, 0) while GPS_RAW_INT says no fix. Measured (4.7.0-dev, on the ground): 11.6 m after
0.2 s, 24.4 m after 0.6 s, 33.2 m after 1.6 s, 35.7 m at the fix (at up to 58 m/s between
reports, 3-26 m/s averaged over a second), velocities 0. The shape below reproduces it."""
PLANE_PRE_FIX_DRIFT_M: Final = 33.3
"""The fast part of that drift, m: it covers 1 - exp(-t / tau) of it."""
PLANE_PRE_FIX_DRIFT_TAU_S: Final = 0.47
"""Its time constant, s (fitted: 0.46-0.48 over the first 0.6 s)."""
PLANE_PRE_FIX_CREEP_M_S: Final = 0.55
"""The slow drift that follows, until the fix, m/s (2.3 m over the last 4 s)."""
GPS_DETECTED_BEFORE_FIX_S: Final = 0.3
"""GPS_RAW_INT says NO_GPS (0) until the receiver is detected ("GPS 1: detected u-blox"),
this long before its fix, then NO_FIX (1) until the fix (SITL, every firmware)."""


def _clamp(value: float, low: int, high: int) -> int:
    rounded = round(value)  # (comparisons, not min and max: several per streamed message)
    return low if rounded < low else high if rounded > high else rounded


class Telemetry:
    """The message builders of one simulated autopilot (owned by it, reading its state).

    Each ``_msg_<name>(now_s)`` builds message ``<name>`` as the autopilot would send it
    now (None: nothing to send); :meth:`builders` hands them to the autopilot by name. It
    keeps only what the reports themselves need between calls: messages re-encoded in
    place, the last RC inputs reported, the previous attitude (body rates), the battery's
    draw, the boot time's cache.

    Args:
        ap: The autopilot it reports on.
    """

    def __init__(self, ap: SimAutopilot) -> None:
        self._ap = ap
        self._boot_ms_at_s = math.nan  # _boot_ms' last time (never equal to a time) and value
        self._boot_ms_value = 0
        # The RC inputs RC_CHANNELS last reported, and that message, to send again.
        self._rc_key: tuple[int, ...] | None = None
        self._rc_message: Any = None
        # Messages sent again and again with new values (see _msg_global_position_int).
        self._position_message = ap._mav.global_position_int_encode(0, 0, 0, 0, 0, 0, 0, 0, 0)
        self._attitude_message = ap._mav.attitude_encode(0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0)
        self._hud_message = ap._mav.vfr_hud_encode(0.0, 0.0, 0, 0, 0.0, 0.0)
        # ATTITUDE body rates from successive attitudes: (time, roll, pitch, yaw) in rad.
        self._attitude_before: tuple[float, float, float, float] | None = None
        self._battery_mah = 0.0
        self._battery_s: float | None = None

    def builders(self, names: Iterable[str]) -> dict[str, Callable[[float], Any]]:
        """Message name -> the method that builds it (``HEARTBEAT``: ``_msg_heartbeat``)."""
        return {name: getattr(self, f"_msg_{name.lower()}") for name in names}

    def _boot_ms(self, now_s: float) -> int:
        # Kept for the next call at the same time: up to four messages of one advance()
        # carry it.
        if now_s != self._boot_ms_at_s:
            self._boot_ms_at_s = now_s
            self._boot_ms_value = max(0, round((now_s - self._ap.boot_s) * 1000)) & 0xFFFFFFFF
        return self._boot_ms_value

    def _unix_us(self, now_s: float) -> int:
        """The GPS's Unix time: 0 before its fix, then the wall clock or the simulated one."""
        if not self._ap.readiness.gps_fix(now_s):
            return 0
        if self._ap._unix_clock_us is not None:
            return self._ap._unix_clock_us()
        if self._ap.start_time_unix_us is None:
            return 0
        return self._ap.start_time_unix_us + round(now_s * 1e6)

    def _landed_state(self, now_s: float) -> int:
        """MAV_LANDED_STATE, with ArduCopter's land detector lag after a touchdown."""
        state = self._ap.model.landed_state
        if state == "taking_off" and now_s < self._ap._takeoff_starts_s:
            state = "on_ground"  # ArduPlane: rolling, but its takeoff not yet started
        if (
            state == "on_ground"
            and self._ap._touchdown_s is not None
            and now_s - self._ap._touchdown_s < LANDED_REPORT_DELAY_S
            and self._ap.model.armed
        ):
            # Until the land detector says landed: LANDING in a mode that lands, IN_AIR in
            # any other (a copter sunk to the ground in LOITER, measured on SITL).
            state = "landing" if self._ap.arming.landing_mode() else "in_air"
        return _LANDED[state]

    def _msg_heartbeat(self, now_s: float) -> Any:
        self._ap._heartbeat_sent = True
        model = self._ap.model
        armed = model.armed
        booting = self._ap.readiness.age_s(now_s) < INITIALISING_S
        custom_mode = (
            self._ap.fw.initialising_mode
            if booting and self._ap.fw.initialising_mode is not None
            else self._ap.modes.get(model.mode, 0)
        )
        base_mode = mavlink2.MAV_MODE_FLAG_CUSTOM_MODE_ENABLED
        auto = model.mode == self._ap.guided_mode or model.mode in _AUTO_MODES
        if self._ap.firmware == "ardurover":
            # Measured: MANUAL 0x41, HOLD 0x01, GUIDED/RTL/AUTO 0x09.
            if auto:
                base_mode |= mavlink2.MAV_MODE_FLAG_GUIDED_ENABLED
            elif model.mode != "HOLD":
                base_mode |= mavlink2.MAV_MODE_FLAG_MANUAL_INPUT_ENABLED
        else:
            base_mode |= (
                mavlink2.MAV_MODE_FLAG_MANUAL_INPUT_ENABLED
                | mavlink2.MAV_MODE_FLAG_STABILIZE_ENABLED
            )
            if auto:
                base_mode |= mavlink2.MAV_MODE_FLAG_GUIDED_ENABLED
        if armed:
            base_mode |= mavlink2.MAV_MODE_FLAG_SAFETY_ARMED
        if self._ap.readiness.age_s(now_s) < self._ap.boot_times.streams_s:
            status = mavlink2.MAV_STATE_BOOT
        elif self._ap.firmware == "ardurover":
            hold = model.mode == "HOLD"
            status = mavlink2.MAV_STATE_STANDBY if hold else mavlink2.MAV_STATE_ACTIVE
        elif model.airborne:
            status = mavlink2.MAV_STATE_ACTIVE
        else:
            status = mavlink2.MAV_STATE_STANDBY
        return self._ap._mav.heartbeat_encode(
            FIRMWARE_TYPES[self._ap.firmware],
            mavlink2.MAV_AUTOPILOT_ARDUPILOTMEGA,
            base_mode,
            custom_mode,
            status,
        )

    def _msg_sys_status(self, now_s: float) -> Any:
        """SYS_STATUS, its sensor bits as ArduPilot sets them (``ap_sys_status``)."""
        # The geofence: present with any fence configured that exists, enabled with a
        # fence on and an action, healthy unless breached (AC_Fence::sys_status_*).
        self._ap.fence_checks.zones()
        now = ap_sys_status.Inputs(
            since_boot_s=now_s - self._ap.boot_s,
            mode=self._ap.model.mode,
            gps_fixed=self._ap.readiness.gps_fix(now_s),
            ekf_origin=self._ap.readiness.origin_set(now_s),
            ekf_position=self._ap.readiness.position_ok(now_s),
            prearm_ok=self._ap.model.armed or self._ap.arming.prearm_healthy(now_s),
            logging=self._ap.model.armed or now_s < self._ap._logging_until_s,
            fence=self._ap.fence.sys_status(),
        )
        present, enabled, health = ap_sys_status.sensor_bits(self._ap.firmware, now)
        current_ca, remaining = self._battery(now_s)
        return self._ap._mav.sys_status_encode(
            present, enabled, health, 0, BATTERY_VOLTAGE_MV, current_ca, remaining, 0, 0, 0, 0, 0, 0
        )

    def _battery(self, now_s: float) -> tuple[int, int]:
        """Current (cA) and remaining charge (%), drawn at the throttle the model reports."""
        throttle = max(0.0, min(1.0, abs(self._ap._truth().throttle_pct) / 100.0))
        current_a = (
            FULL_THROTTLE_CURRENT_A[self._ap.firmware] * throttle if self._ap.model.armed else 0.0
        )
        if self._battery_s is not None and now_s > self._battery_s:
            self._battery_mah += current_a * (now_s - self._battery_s) / 3.6
        self._battery_s = now_s
        capacity = max(self._ap._params["BATT_CAPACITY"].value, 1.0)
        remaining = max(0, round(100.0 * (1.0 - self._battery_mah / capacity)))
        return round(current_a * 100), remaining

    def _position(self, now_s: float, raw: bool = False) -> tuple[float, float, float]:
        """Latitude, longitude and height above the origin as the autopilot reports them.

        Before the GPS has a fix ArduPilot reports 0, 0 (ArduPlane: its dead reckoning
        from there, :meth:`_dead_reckoned_m`), and a height from its barometer (taken
        here as the height with the receiver's vertical error: a little noise around
        the truth). A model with a GPS is read through it: ``raw`` the receiver's fix
        (``gps_fix``: seeded noise at the receiver's rate, GPS_RAW_INT), otherwise its
        estimate (``position_estimate``: that noise smoothed as ArduPilot's EKF smooths
        it, GLOBAL_POSITION_INT); a model without one reports the truth.
        """
        fix = getattr(self._ap.model, "gps_fix" if raw else "position_estimate", None)
        if fix is not None:
            lat, lon, alt = fix()
        else:
            t = self._ap._truth()
            lat, lon, alt = t.lat_deg, t.lon_deg, t.up_m
        if not self._ap.readiness.gps_fix(now_s):
            north_m, east_m = self._dead_reckoned_m(now_s)
            return north_m / M_PER_DEG_LAT, east_m / M_PER_DEG_LAT, float(alt)
        return float(lat), float(lon), float(alt)

    def _dead_reckoned_m(self, now_s: float) -> tuple[float, float]:
        """North and east of (0, 0), m, where ArduPlane's DCM puts itself before a fix.

        ArduPlane integrates its airspeed sensor from 0, 0 along its heading (SITL:
        :data:`PLANE_PRE_FIX_DRIFT_START`); the other firmwares stay at 0, 0. An engine
        must not take these for the vehicle's position (GPS_RAW_INT says no fix).
        """
        if self._ap.firmware != "arduplane":
            return 0.0, 0.0
        fix_s = self._ap.boot_times.gps_fix_s
        since_s = self._ap.readiness.age_s(now_s) - PLANE_PRE_FIX_DRIFT_START * fix_s
        if since_s <= 0.0:
            return 0.0, 0.0
        drift_m = PLANE_PRE_FIX_DRIFT_M * -math.expm1(-since_s / PLANE_PRE_FIX_DRIFT_TAU_S)
        drift_m += PLANE_PRE_FIX_CREEP_M_S * since_s
        yaw = math.radians(self._ap._truth().yaw_deg)
        return drift_m * math.cos(yaw), drift_m * math.sin(yaw)

    def _msg_gps_raw_int(self, now_s: float) -> Any:
        t = self._ap._truth()
        lat, lon, up = self._position(now_s, raw=True)
        fixed = self._ap.readiness.gps_fix(now_s)
        if not fixed:
            lat = lon = 0.0  # the receiver's own report: nothing (the DCM's is not its)
        unix_us = self._unix_us(now_s)
        return self._ap._mav.gps_raw_int_encode(
            unix_us if unix_us else round((now_s - self._ap.boot_s) * 1e6),
            mavlink2.GPS_FIX_TYPE_3D_FIX
            if fixed
            else mavlink2.GPS_FIX_TYPE_NO_FIX
            if self._ap.readiness.age_s(now_s)
            >= self._ap.boot_times.gps_fix_s - GPS_DETECTED_BEFORE_FIX_S
            else mavlink2.GPS_FIX_TYPE_NO_GPS,
            round(lat * 1e7),
            round(lon * 1e7),
            round((self._ap.origin_alt_amsl_m + up) * 1000) if fixed else 0,
            121 if fixed else UINT16_MAX,  # HDOP 1.21
            200 if fixed else UINT16_MAX,  # VDOP 2.00
            _clamp(t.ground_speed_m_s * 100, 0, UINT16_MAX - 1) if fixed else 0,
            round((t.heading_deg % 360.0) * 100) % 36000 if fixed else 0,
            10 if fixed else 0,
        )

    def _msg_global_position_int(self, now_s: float) -> Any:
        """The fused position (see :meth:`Readiness.fused_alt_m` for its altitudes).

        Before the GPS fix ArduCopter sends its never-filled location (all zero); the
        others 0, 0 and their barometer's height in both altitudes.
        """
        t = self._ap._truth()
        lat, lon, up = self._position(now_s)
        msg = self._position_message
        msg.time_boot_ms = self._boot_ms(now_s)
        msg.lat = round(lat * 1e7)
        msg.lon = round(lon * 1e7)
        if self._ap.fw.zero_before_fix and not self._ap.readiness.gps_fix(now_s):
            msg.alt = msg.relative_alt = 0
        else:
            msg.alt = round(self._ap.readiness.fused_alt_m(now_s, up) * 1000)
            msg.relative_alt = round(self._ap.readiness.alt_above_home_m(now_s, up) * 1000)
        msg.vx = _clamp(t.velocity_north_m_s * 100, -32768, 32767)
        msg.vy = _clamp(t.velocity_east_m_s * 100, -32768, 32767)
        msg.vz = _clamp(-t.climb_rate_m_s * 100, -32768, 32767)
        msg.hdg = round((t.yaw_deg % 360.0) * 100) % 36000
        return msg

    def _msg_attitude(self, now_s: float) -> Any:
        t = self._ap._truth()
        msg = self._attitude_message
        roll, pitch = math.radians(t.roll_deg), math.radians(t.pitch_deg)
        yaw = math.radians(math.remainder(t.yaw_deg, 360.0))
        # Body rates from the change since the last ATTITUDE (Euler rates: close enough
        # to body rates at the modest angles these models fly).
        rates = (0.0, 0.0, 0.0)
        before = self._attitude_before
        if before is not None and now_s > before[0]:
            dt_s = now_s - before[0]
            rates = (
                (roll - before[1]) / dt_s,
                (pitch - before[2]) / dt_s,
                math.remainder(yaw - before[3], math.tau) / dt_s,
            )
        self._attitude_before = (now_s, roll, pitch, yaw)
        msg.time_boot_ms = self._boot_ms(now_s)
        msg.roll, msg.pitch, msg.yaw = roll, pitch, yaw
        msg.rollspeed, msg.pitchspeed, msg.yawspeed = rates
        return msg

    def _msg_vfr_hud(self, now_s: float) -> Any:
        t = self._ap._truth()
        msg = self._hud_message
        msg.airspeed = t.airspeed_m_s
        msg.groundspeed = t.ground_speed_m_s
        msg.heading = int(t.yaw_deg % 360.0)
        msg.throttle = _clamp(t.throttle_pct, 0, 100)
        msg.alt = self._ap.readiness.fused_alt_m(now_s, t.up_m)
        msg.climb = t.climb_rate_m_s
        return msg

    def _msg_system_time(self, now_s: float) -> Any:
        return self._ap._mav.system_time_encode(self._unix_us(now_s), self._boot_ms(now_s))

    def _msg_rc_channels(self, now_s: float) -> Any:
        # The inputs change only when a stick or an override moves: the message is built
        # anew then, and otherwise sent again with only its time updated (21 fields).
        inputs = tuple(self._ap.model.rc_inputs())
        if inputs != self._rc_key or self._rc_message is None:
            used = list(inputs)[:18]
            values = [_clamp(v, 0, UINT16_MAX) if v else UINT16_MAX for v in used]
            values += [UINT16_MAX] * (18 - len(values))
            self._rc_key = inputs
            self._rc_message = self._ap._mav.rc_channels_encode(0, len(used), *values, 255)
        self._rc_message.time_boot_ms = self._boot_ms(now_s)
        return self._rc_message

    def _msg_servo_output_raw(self, now_s: float) -> Any:
        outputs = [_clamp(v, 0, UINT16_MAX) for v in list(self._ap.model.servo_outputs())[:16]]
        outputs += [0] * (16 - len(outputs))
        time_us = max(0, round((now_s - self._ap.boot_s) * 1e6)) & 0xFFFFFFFF
        return self._ap._mav.servo_output_raw_encode(time_us, 0, *outputs)

    def _msg_ekf_status_report(self, now_s: float) -> Any:
        age = self._ap.readiness.age_s(now_s)
        if age < _EKF_UNINITIALISED_S:
            flags = _EKF_UNINITIALISED
        elif age < self._ap.boot_times.attitude_s:
            flags = 0
        elif age < self._ap.boot_times.position_s:
            flags = _EKF_ATTITUDE_ONLY
        else:
            flags = _EKF_POSITION
        return self._ap._mav.ekf_status_report_encode(flags, 0.02, 0.01, 0.01, 0.03, 0.0, 0.0)

    def _msg_extended_sys_state(self, now_s: float) -> Any:
        if self._ap.firmware == "ardurover":  # no landed state (measured: 0, 0)
            return self._ap._mav.extended_sys_state_encode(
                mavlink2.MAV_VTOL_STATE_UNDEFINED, mavlink2.MAV_LANDED_STATE_UNDEFINED
            )
        vtol = (
            mavlink2.MAV_VTOL_STATE_MC
            if self._ap.firmware == "arducopter"
            else mavlink2.MAV_VTOL_STATE_UNDEFINED
        )
        return self._ap._mav.extended_sys_state_encode(vtol, self._landed_state(now_s))

    def _msg_mission_current(self, now_s: float) -> Any:
        seq, total, state, mode = self._ap.missions.mission_current(self._ap.model.mode == "AUTO")
        return self._ap._mav.mission_current_encode(seq, total, state, mode)

    def _msg_battery_status(self, now_s: float) -> Any:
        current_ca, remaining = self._battery(now_s)
        return self._ap._mav.battery_status_encode(
            0,
            mavlink2.MAV_BATTERY_FUNCTION_UNKNOWN,
            mavlink2.MAV_BATTERY_TYPE_UNKNOWN,
            32767,
            [BATTERY_VOLTAGE_MV] + [UINT16_MAX] * 9,
            current_ca,
            round(self._battery_mah),
            -1,
            remaining,
        )

    def _waypoint_target(self) -> tuple[float, float, float] | None:
        """The point the current mode flies to (lat, lon, height above origin), if any."""
        mode = self._ap.model.mode
        if mode == self._ap.guided_mode:
            return self._ap._target
        if mode in ("RTL", "SMART_RTL") and self._ap._home is not None:
            return (
                self._ap._home[0],
                self._ap._home[1],
                self._ap._home[2] - self._ap.origin_alt_amsl_m,
            )
        return None

    def _msg_nav_controller_output(self, now_s: float) -> Any:
        t = self._ap._truth()
        target = self._waypoint_target()
        bearing_deg, distance_m, alt_error_m = 0.0, 0.0, 0.0
        if target is not None:
            north = (target[0] - t.lat_deg) * M_PER_DEG_LAT
            east = (target[1] - t.lon_deg) * M_PER_DEG_LAT * math.cos(math.radians(t.lat_deg))
            bearing_deg = math.degrees(math.atan2(east, north)) % 360.0
            distance_m = math.hypot(north, east)
            alt_error_m = target[2] - t.up_m
        nav_roll_deg, nav_pitch_deg = self._ap.model.nav_attitude_deg()
        return self._ap._mav.nav_controller_output_encode(
            nav_roll_deg,
            nav_pitch_deg,
            round(t.heading_deg) % 360,
            round(bearing_deg) % 360,
            min(round(distance_m), UINT16_MAX),
            alt_error_m,
            0.0,
            0.0,
        )

    def _msg_fence_status(self, now_s: float) -> Any:
        """FENCE_STATUS while a fence is enabled (and at once on a new breach).

        The mitigation is ArduRover's and ArduCopter's avoidance (velocity limited while
        it holds the rover short of the fence, else none); ArduPlane reports unknown.
        """
        status = self._ap.fence.status()
        if status is None:
            return None
        breached, count, kind, at_s = status
        if self._ap.firmware == "arduplane":
            mitigation = mavlink2.FENCE_MITIGATE_UNKNOWN
        elif self._ap._avoid_cut and self._ap.model.target_reached:
            mitigation = mavlink2.FENCE_MITIGATE_VEL_LIMIT
        else:
            mitigation = mavlink2.FENCE_MITIGATE_NONE
        time_ms = max(0, round((at_s - self._ap.boot_s) * 1000)) if count else 0
        return self._ap._mav.fence_status_encode(breached, count, kind, time_ms, mitigation)

    def _msg_position_target_global_int(self, now_s: float) -> Any:
        target = self._waypoint_target()
        if target is None:
            return None  # ArduPilot sends it only while the mode flies to a target
        return self._ap._mav.position_target_global_int_encode(
            self._boot_ms(now_s),
            mavlink2.MAV_FRAME_GLOBAL,
            0xFDF8,
            round(target[0] * 1e7),
            round(target[1] * 1e7),
            self._ap.origin_alt_amsl_m + target[2],
            0.0,
            0.0,
            0.0,
            0.0,
            0.0,
            0.0,
            0.0,
            0.0,
        )

    def _msg_home_position(self, now_s: float) -> Any:
        if self._ap._home is None:
            return None  # ArduPilot acknowledges the request and sends nothing
        self._ap._home_sent_s = now_s
        lat, lon, alt = self._ap._home
        truth = self._ap._truth()
        north = (truth.lat_deg - lat) * M_PER_DEG_LAT
        east = (truth.lon_deg - lon) * M_PER_DEG_LAT * math.cos(math.radians(lat))
        return self._ap._mav.home_position_encode(
            round(lat * 1e7),
            round(lon * 1e7),
            round(alt * 1000),
            -north,
            -east,
            0.0,
            [math.nan] * 4,
            0.0,
            0.0,
            0.0,
            round((now_s - self._ap.boot_s) * 1e6),
        )

    def _msg_autopilot_version(self, now_s: float) -> Any:
        major, minor, patch = FIRMWARE_VERSION
        version = (major << 24) | (minor << 16) | (patch << 8) | FIRMWARE_VERSION_TYPE
        zeros8 = [0] * 8
        uid = int.from_bytes(b"CLARK", "big") << 16 | self._ap._sysid << 8 | self._ap._compid
        return self._ap._mav.autopilot_version_encode(
            CAPABILITIES[self._ap.firmware], version, 0, 0, 0, zeros8, zeros8, zeros8, 0, 0, uid
        )
