"""The simulated ArduPilot's boot and readiness: its timeline, home and its EKF's heights.

:class:`Readiness` answers how far the autopilot is in its boot
(:class:`~clark_engine.sim.ardupilot.firmware.BootTimes`, counted from ``boot_s``: a GPS
fix, an EKF origin, an absolute position), schedules the boot STATUSTEXTs, sets home where
the vehicle is (at the barometer's height where the firmware has no better), gives the
heights GLOBAL_POSITION_INT reports (above sea level, or the barometer's, and above home),
and runs ArduRover's EKF check, whose failsafe refuses modes that need a position.

Apart from :class:`~clark_engine.sim.ardupilot.autopilot.SimAutopilot` because readiness is
one concept, read by arming, modes, the fence and every message: a helper object the
autopilot owns (``SimAutopilot.readiness``). Home and the EKF failsafe stay on the
autopilot, which the rest of it reads at every step; this reads and sets them through it.
"""

from __future__ import annotations

import math
from typing import TYPE_CHECKING, Final

from pymavlink.dialects.v20 import ardupilotmega as mavlink2

from clark_engine.sim.ardupilot.telemetry import (
    M_PER_DEG_LAT,
)

if TYPE_CHECKING:
    from clark_engine.sim.ardupilot.autopilot import SimAutopilot

_INFO: Final = mavlink2.MAV_SEVERITY_INFO
_CRITICAL: Final = mavlink2.MAV_SEVERITY_CRITICAL

_BOOT_TEXTS: Final[tuple[tuple[str, float, int, str], ...]] = (
    ("streams_s", 0.0, _INFO, "ArduPilot Ready"),
    ("streams_s", 0.0, _INFO, "AHRS: DCM active"),
    ("gps_fix_s", -0.3, _INFO, "GPS 1: detected u-blox"),
    ("origin_s", 0.0, _INFO, "EKF3 IMU0 origin set"),
    ("origin_s", 0.0, _INFO, "EKF3 IMU1 origin set"),
    ("position_s", 0.0, _INFO, "EKF3 IMU0 is using GPS"),
    ("position_s", 0.0, _INFO, "EKF3 IMU1 is using GPS"),
    ("position_s", 0.0, _INFO, "AHRS: EKF3 active"),
)
"""STATUSTEXTs ArduPilot prints as it boots: (step of BootTimes, offset s, severity, text)."""
EKF_CHECK_PERIOD_S: Final = 0.1
"""ArduRover checks its EKF at 10 Hz (Rover::ekf_check)."""
EKF_CHECK_ITERATIONS: Final = 10
"""EKF_CHECK_ITERATIONS_MAX: a second of failed checks turns ArduRover's EKF failsafe on,
and as many good ones turn it off."""


class Readiness:
    """The boot and readiness of one simulated autopilot (owned by it, acting through it).

    Args:
        ap: The autopilot it belongs to.
    """

    def __init__(self, ap: SimAutopilot) -> None:
        self._ap = ap

    def boot_armed(self) -> float | None:
        """When an autopilot built armed was armed (a vehicle the pilot flies already)."""
        return self._ap.boot_s if self._ap.model.armed else None

    def boot_text_schedule(self) -> list[tuple[float, int, str]]:
        """The boot STATUSTEXTs still to say, as (time, severity, text), in time order."""
        texts = [
            (self._ap.boot_s + getattr(self._ap.boot_times, step) + offset, severity, text)
            for step, offset, severity, text in _BOOT_TEXTS
        ]
        # An autopilot that booted before the run said these before anyone listened.
        return sorted((t for t in texts if t[0] >= 0.0), key=lambda t: t[0])

    def age_s(self, now_s: float) -> float:
        """Seconds since it powered on."""
        return now_s - self._ap.boot_s

    def gps_fix(self, now_s: float) -> bool:
        """Its GPS has a fix now."""
        return self.age_s(now_s) >= self._ap.boot_times.gps_fix_s

    def origin_set(self, now_s: float) -> bool:
        """Its EKF has an origin now."""
        return self.age_s(now_s) >= self._ap.boot_times.origin_s

    def position_ok(self, now_s: float) -> bool:
        """Its EKF has an absolute position now."""
        return self.age_s(now_s) >= self._ap.boot_times.position_s

    def rover_ekf_check(self, now_s: float) -> None:
        """ArduRover's EKF check (Rover::ekf_check, 10 Hz): its failsafe refuses modes.

        Armed without an EKF position (a rover armed in MANUAL before its EKF uses the
        GPS), a count rises by one per check; at 10 the EKF failsafe is on. Once the
        position is good the count falls by one per check, and at 0 the failsafe ends
        with CRITICAL "EKF failsafe cleared". While it is on, every mode that needs a
        position is refused ("Flight mode change failed"). Measured on SITL: position
        good at 41.57 s, GUIDED refused at 42.08 s, "EKF failsafe cleared" at 42.57 s.
        The rover cannot be in a mode that needs a position when it starts (it was
        refused them), so the failsafe's own switch to HOLD is not simulated.
        """
        self._ap._next_ekf_check_s = max(self._ap._next_ekf_check_s + EKF_CHECK_PERIOD_S, now_s)
        if not self.origin_set(now_s):
            return  # no origin yet: ArduRover does not look
        if not self._ap.model.armed:
            self._ap._ekf_fail_count = 0
            self._ekf_failsafe_off()
            return
        if not self.position_ok(now_s):
            self._ap._ekf_fail_count = min(self._ap._ekf_fail_count + 1, EKF_CHECK_ITERATIONS)
            if self._ap._ekf_fail_count >= EKF_CHECK_ITERATIONS:
                self._ap._ekf_failsafe = True
        elif self._ap._ekf_fail_count > 0:
            self._ap._ekf_fail_count -= 1
            if self._ap._ekf_fail_count == 0:
                self._ekf_failsafe_off()

    def _ekf_failsafe_off(self) -> None:
        if self._ap._ekf_failsafe:
            self._ap._ekf_failsafe = False
            self._ap._text(_CRITICAL, "EKF failsafe cleared")

    def distance_from_home_m(self) -> float:
        """Horizontal distance from the vehicle to home (m); home must be set."""
        assert self._ap._home is not None
        truth = self._ap.model.truth()
        north_m = (truth.lat_deg - self._ap._home[0]) * M_PER_DEG_LAT
        east_m = (
            (truth.lon_deg - self._ap._home[1])
            * M_PER_DEG_LAT
            * math.cos(math.radians(self._ap._home[0]))
        )
        return math.hypot(north_m, east_m)

    def home_here(self, now_s: float) -> None:
        """Home where the vehicle is now (ArduPilot's own re-setting of home).

        Until its EKF takes over from DCM, ArduRover's position has no altitude above
        sea level: the home it sets then is at its barometer's height (about 0 m; SITL:
        0.19 m), so a rover on the ground reads 90 m above such a home (measured).
        ArduCopter and ArduPlane set home with the GPS's altitude.
        """
        truth = self._ap.model.truth()
        alt_m = self._ap.origin_alt_amsl_m + truth.up_m
        if self._ap.fw.baro_alt_until == "position":
            alt_m = self.fused_alt_m(now_s, truth.up_m)
        self._ap.set_home(truth.lat_deg, truth.lon_deg, alt_m, now_s)

    def _baro_only(self, now_s: float) -> bool:
        """The firmware's position still has no height above sea level (its barometer's)."""
        until = self._ap.fw.baro_alt_until
        if until == "position":
            return not self.position_ok(now_s)
        if until == "home":
            return self._ap._home is None
        return False

    def fused_alt_m(self, now_s: float, up_m: float) -> float:
        """GLOBAL_POSITION_INT.alt's height (m) for a height above the origin.

        Above sea level, or the barometer's height (relative to where it booted, on the
        ground: about the height above the origin) while the firmware has no better.
        """
        if self._baro_only(now_s) or not self.gps_fix(now_s):
            return up_m
        return self._ap.origin_alt_amsl_m + up_m

    def alt_above_home_m(self, now_s: float, up_m: float) -> float:
        """GLOBAL_POSITION_INT.relative_alt's height (m): the barometer's before home."""
        if self._ap._home is None:
            return up_m
        return self.fused_alt_m(now_s, up_m) - self._ap._home[2]
