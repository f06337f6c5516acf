"""The simulated ArduPilot's arming: pre-arm checks, ARM/DISARM, and the disarms it makes.

:class:`Arming` answers MAV_CMD_COMPONENT_ARM_DISARM as ArduPilot does: every failing check
refused with its CRITICAL ``Arm: ...`` text (the boot phase, the fence, the GCS failsafe,
the throttle off zero, a position the mode needs, a mode that is not armable, an internal
error until a reboot), forced arming past them, no disarming in the air unless forced; what
arming and disarming do (texts, home, the fence's auto-enable, ArduPlane's launch in
TAKEOFF); the pre-arm state SYS_STATUS and the ``PreArm:`` reports show; and ArduCopter's
disarms by itself (after touching down in a landing mode, and DISARM_DELAY after an idle
arm).

Apart from :class:`~clark_engine.sim.ardupilot.autopilot.SimAutopilot` because arming is one
concept, ArduPilot's AP_Arming: a helper object the autopilot owns
(``SimAutopilot.arming``). What the rest of the autopilot also reads (when it armed, on the
ground since, the internal error) stays on the autopilot, which this reads and sets through
it.
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Final

from pymavlink.dialects.v20 import ardupilotmega as mavlink2

from clark_engine.sim.ardupilot import sys_status as ap_sys_status
from clark_engine.sim.ardupilot.firmware import FORCE_MAGIC
from clark_engine.sim.ardupilot.telemetry import (
    LANDED_REPORT_DELAY_S,
)

if TYPE_CHECKING:
    from clark_engine.sim.ardupilot.autopilot import SimAutopilot

_INFO: Final = mavlink2.MAV_SEVERITY_INFO
_CRITICAL: Final = mavlink2.MAV_SEVERITY_CRITICAL
_ACCEPTED: Final = int(mavlink2.MAV_RESULT_ACCEPTED)
_FAILED: Final = int(mavlink2.MAV_RESULT_FAILED)
_UNSUPPORTED: Final = int(mavlink2.MAV_RESULT_UNSUPPORTED)

INTERNAL_ERROR_TEXT: Final = "Arm: Internal errors 0x100000 l:{line} flow_of_ctrl"
"""The arming refusal after an internal error (AP_InternalError's flow_of_control, raised
at a line of ArduPilot's source: ArduRover's AR_WPNav 239, ArduCopter's SmartRTL 130)."""
THROTTLE_DEAD_ZONE_US: Final = 30
"""RC3_DZ: a throttle this close to zero counts as zero for arming (measured: SITL armed
at its 1000 us minimum and refused 1200 us; the rover armed at its 1500 us trim)."""
PLANE_LAUNCH_S: Final = 0.2
"""ArduPlane, armed in TAKEOFF: "Triggered AUTO" this long after arming (measured)."""
PLANE_TAKEOFF_STARTS_S: Final = 1.2
"""ArduPlane, armed in TAKEOFF: "Takeoff to ..." and landed_state TAKEOFF this long after
arming (measured 1.2 s; the ground roll has begun)."""
LAND_DISARM_DELAY_S: Final = 2.05
"""ArduCopter disarms this long after touching down in LAND or RTL (measured)."""


class Arming:
    """The arming and disarming of one simulated autopilot (owned by it, acting through it).

    Args:
        ap: The autopilot it belongs to.
    """

    def __init__(self, ap: SimAutopilot) -> None:
        self._ap = ap

    def refusals(self, now_s: float, mode: str) -> list[str]:
        """Why arming in ``mode`` is refused now ("Arm: ..." texts); empty when it is not.

        As ArduPilot, every failing check says so: the boot phase's sensor check, a
        position the mode needs, and the mode itself.
        """
        age, boot, fw = self._ap.readiness.age_s(now_s), self._ap.boot_times, self._ap.fw
        reasons: list[str] = []
        if self._ap._internal_error is not None:
            return [INTERNAL_ERROR_TEXT.format(line=self._ap._internal_error)]
        if age < boot.attitude_s:
            reasons.append("Arm: EKF attitude is bad")
        elif age < boot.gps_fix_s:
            reasons.append("Arm: GPS 1: Bad fix")
        elif self._ap._home is None:
            reasons.append("Arm: AHRS: waiting for home")
        elif age < boot.prearm_s:
            reasons.append("Arm: Gyros inconsistent")
        self._ap.fence_checks.zones()
        fence_problem = self._ap.fence.pre_arm_failure(self._ap.fence_checks.position(now_s), now_s)
        if fence_problem is not None:
            reasons.append(f"Arm: {fence_problem}")
        if self._ap.firmware == "arducopter" and self._ap.gcs_failsafe.active:
            reasons.append("Arm: GCS failsafe on")
        if not self.throttle_at_zero():
            reasons.append(
                "Arm: Throttle too high"
                if mode in fw.throttle_too_high_modes
                else "Arm: Throttle (RC3) is not neutral"
            )
        if mode in fw.arm_needs_position and not self._ap.readiness.position_ok(now_s):
            reasons.append(fw.no_position_text)
        if mode == "AUTO" and fw.name == "arducopter" and not self._ap.auto.has_items():
            reasons.append("Arm: Mode requires mission")
        elif mode in fw.not_armable:
            reasons.append(fw.not_armable_text.format(mode=fw.spell(mode)))
        return reasons

    def throttle_at_zero(self) -> bool:
        """The throttle input is within its dead zone of zero (RC3_DZ, 30 us in SITL).

        ArduPilot constrains a pulse to RC3_MIN..RC3_MAX before reading it, so on a
        throttle whose zero is its minimum (copter, plane) anything below the minimum
        is zero too: an RC override of 1000 us arms where the minimum is 1100 us, as
        ArduCopter SITL arms with it. A rover's zero is its trim (a centred throttle).
        """
        if self._ap._throttle is None:
            return True
        rc, zero_us = self._ap._throttle
        inputs = self._ap.model.rc_inputs()
        if not 1 <= rc <= len(inputs):
            return True
        pwm_us = inputs[rc - 1]
        if self._ap.firmware != "ardurover" and pwm_us < zero_us:
            return True
        return abs(pwm_us - zero_us) <= THROTTLE_DEAD_ZONE_US

    def prearm_healthy(self, now_s: float) -> bool:
        """Arming in the current mode would pass its checks now."""
        return not self.refusals(now_s, self._ap.model.mode)

    def command(self, p1: float, p2: float, now_s: float) -> int:
        """MAV_CMD_COMPONENT_ARM_DISARM (p1 1 arms, 0 disarms; p2 forces); MAV_RESULT."""
        if p1 not in (0.0, 1.0):
            return _UNSUPPORTED
        force = p2 in FORCE_MAGIC
        model = self._ap.model
        if p1 == 0.0:
            if not model.armed:
                return _ACCEPTED
            if model.airborne and not force:
                return _FAILED  # ArduPilot: no disarming in the air, and no text
            self.disarm(now_s, force=force)
            return _ACCEPTED
        if model.armed:
            return _ACCEPTED
        if not force:
            refusals = self.refusals(now_s, model.mode)
            if refusals:
                for reason in refusals:
                    self._ap._text(_CRITICAL, reason)
                self._ap._logging_until_s = now_s + ap_sys_status.LOG_PERSIST_S
                return _FAILED
        if not model.arm(True):
            return _FAILED
        self._ap._armed_s = now_s
        self._ap._ground_since_s = None if model.airborne else now_s
        self._ap._smart_rtl_entered = False  # arming starts a new SmartRTL path
        self._ap._fence_quiet = False
        self._ap.fence.auto_enable_on_arming()
        self._ap._text(_INFO, self._ap.fw.armed_text)
        for severity, text in self._ap.fw.arm_texts.get(model.mode, ()):
            self._ap._text(severity, text)
        if self._ap.fw.home_at == "arming" and not self._ap._home_locked:
            self._ap.readiness.home_here(now_s)
        if self._ap.firmware == "arduplane" and (
            model.mode == "TAKEOFF"
            or (model.mode == "AUTO" and self._ap.auto.current_nav_is(mavlink2.MAV_CMD_NAV_TAKEOFF))
        ):
            self._plane_launch(now_s)
        return _ACCEPTED

    def _plane_launch(self, now_s: float) -> None:
        """ArduPlane's texts as an armed TAKEOFF (or AUTO takeoff) launches, at SITL's times.

        The takeoff proper (landed_state TAKEOFF) starts with "Takeoff to ..." 1.2 s
        after arming; "Autoland direction" is the heading it takes off along.
        """
        self._ap._text(_INFO, "Armed AUTO, xaccel = -0.0 m/s/s, waiting 0.2 sec")
        self._ap._say_at(now_s + PLANE_LAUNCH_S, _INFO, "Triggered AUTO. GPS speed = 0.0")
        heading = self._ap.model.truth().heading_deg
        alt, dist = self._ap._params["TKOFF_ALT"].value, self._ap._params["TKOFF_DIST"].value
        started_s = now_s + PLANE_TAKEOFF_STARTS_S
        self._ap._say_at(
            started_s, _INFO, f"Takeoff to {alt:.0f}m for {dist:.1f}m heading {heading:.1f} deg"
        )
        self._ap._say_at(started_s, _INFO, f"Autoland direction= {int(heading) % 360}")
        self._ap._takeoff_starts_s = started_s

    def disarm(self, now_s: float, *, force: bool = False) -> None:
        """Disarm (forced: even in the air), with what ArduPilot does at disarming."""
        if self._ap.model.arm(False, force=force):
            self._ap._armed_s = None
            self._ap._logging_until_s = now_s + ap_sys_status.LOG_PERSIST_S
            self._ap._ground_since_s = None
            self._ap._text(_INFO, self._ap.fw.disarmed_text)
            self._ap._fence_quiet = False
            self._ap.fence.auto_disable_on_disarming()
            if self._ap.firmware == "arducopter" and self._ap.model.mode == "AUTO":
                # ArduCopter resets its mission at disarming, and AUTO starts it over:
                # "Mission: 1 Takeoff" again, waiting for the next arming and start.
                self._ap._auto_go = False
                self._ap._auto_seq = None
                if self._ap.auto.has_items():
                    self._ap.missions.start()
            if self._ap.fw.home_at == "disarming" and not self._ap._home_locked:
                self._ap.readiness.home_here(now_s)

    def landing_and_disarm(self, now_s: float) -> None:
        """Touchdowns, and ArduCopter's disarms after one or after an idle arm."""
        model = self._ap.model
        flying = model.airborne
        if self._ap._was_flying and not flying:
            self._ap._touchdown_s = now_s
            if model.armed:
                self._ap._ground_since_s = now_s
        self._ap._was_flying = flying
        delay_s = self._ap.fw.auto_disarm_s
        if delay_s is None or not model.armed or flying or self._ap._ground_since_s is None:
            return
        landed_in = (
            self._ap._touchdown_s is not None and self._ap._touchdown_s >= self._ap._ground_since_s
        )
        landing_mode = self.landing_mode()
        if landed_in and landing_mode:
            if now_s - self._ap._ground_since_s >= LAND_DISARM_DELAY_S:
                self.disarm(now_s)
            return
        # The idle disarm (Copter::auto_disarm_check): DISARM_DELAY after the land
        # detector says landed (LANDED_REPORT_DELAY_S after a touchdown), counted only
        # while the throttle stick is at zero: a pilot holding it up keeps it armed.
        if "DISARM_DELAY" in self._ap._params:
            delay_s = self._ap._params["DISARM_DELAY"].value  # 0 turns the idle disarm off
        if not self.throttle_at_zero():
            self._ap._throttle_up_s = now_s
            return
        since_s = self._ap._ground_since_s + (LANDED_REPORT_DELAY_S if landed_in else 0.0)
        if self._ap._throttle_up_s is not None and self._ap._throttle_up_s > since_s:
            since_s = self._ap._throttle_up_s
        if delay_s > 0 and now_s - since_s >= delay_s:
            self.disarm(now_s)

    def landing_mode(self) -> bool:
        """The mode lands the copter (LAND, RTL's descent, AUTO's land item)."""
        mode = self._ap.model.mode
        return mode in ("LAND", "RTL", "SMART_RTL") or (mode == "AUTO" and self._ap._auto_landing)
