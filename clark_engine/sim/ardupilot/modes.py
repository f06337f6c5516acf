"""The simulated ArduPilot's mode changes, made or refused as ArduPilot's set_mode does.

:class:`ModeChanges` changes mode by number (MAV_CMD_DO_SET_MODE, SET_MODE: an unknown
number is "No such mode N") and by name (commands, AUTO's end, the fence and failsafes),
with every firmware's refusals and texts (the firmware's facts, measured mode by mode), the
fence's recovery, ArduCopter's LAND on the ground disarming it, ArduPlane's AUTO without a
mission turning to RTL, and the internal errors two refusals leave behind.

Apart from :class:`~clark_engine.sim.ardupilot.autopilot.SimAutopilot` because a mode change
is one concept: a helper object the autopilot owns (``SimAutopilot.mode_changes``); the mode
itself is the vehicle model's, and what a change resets (the guided target, the reason of
the mode) stays on the autopilot, set through it.
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Final

from pymavlink.dialects.v20 import ardupilotmega as mavlink2

from clark_engine.sim.ardupilot.vehicle_safety import ModeReason

if TYPE_CHECKING:
    from clark_engine.sim.ardupilot.autopilot import SimAutopilot

_INFO: Final = mavlink2.MAV_SEVERITY_INFO
_NOTICE: Final = mavlink2.MAV_SEVERITY_NOTICE
_WARNING: Final = mavlink2.MAV_SEVERITY_WARNING
_CRITICAL: Final = mavlink2.MAV_SEVERITY_CRITICAL
_ACCEPTED: Final = int(mavlink2.MAV_RESULT_ACCEPTED)
_DENIED: Final = int(mavlink2.MAV_RESULT_DENIED)
_FAILED: Final = int(mavlink2.MAV_RESULT_FAILED)


class ModeChanges:
    """The mode changes of one simulated autopilot (owned by it, acting through it).

    Args:
        ap: The autopilot it belongs to.
    """

    def __init__(self, ap: SimAutopilot) -> None:
        self._ap = ap

    def set_mode(self, base_mode: int, custom_mode: int, now_s: float) -> int:
        """A mode change by number (DO_SET_MODE, SET_MODE); returns MAV_RESULT."""
        # Like ArduPilot: only custom modes; a number the build lacks is FAILED with a
        # warning.
        if not base_mode & mavlink2.MAV_MODE_FLAG_CUSTOM_MODE_ENABLED:
            return _DENIED
        name = self._ap._mode_names.get(custom_mode)
        if name is None or name in self._ap.fw.absent_modes:
            self._ap._text(_WARNING, f"No such mode {custom_mode}")
            return _FAILED
        return self.enter(name, now_s)

    def enter(self, name: str, now_s: float, reason: ModeReason = "gcs") -> int:
        """Change mode as ArduPilot's set_mode does, for ``reason``; returns MAV_RESULT.

        After a change during a fence breach, the fence ignores new breaches for ten
        seconds ("Manual recovery started"; ArduCopter only with a FENCE_ACTION).
        """
        model, fw = self._ap.model, self._ap.fw
        if name == model.mode:
            return _ACCEPTED
        left = model.mode
        refusal = self.refusal(name, now_s)
        if refusal is not None or not model.set_mode(name):
            for severity, text in refusal or [(_WARNING, fw.mode_refused_text)]:
                self._ap._text(severity, text.format(mode=fw.spell(name)))
            return _FAILED
        self._ap._target = None  # ArduPilot forgets the guided target on changing mode
        self._ap._velocity_target = None
        self._ap._guided_wp_active = False
        self._ap._avoid_cut = False
        self._ap._last_mode = name
        self._ap._mode_reason = reason
        self._ap.gcs_failsafe.mode_changed()
        if fw.name != "arducopter" or self._ap.fence.action != 0:
            self._ap.fence.manual_recovery_start(now_s)
        for severity, text in fw.enter_texts.get(name, ()):
            self._ap._text(severity, text)
        self._ap._rtl_arrival_due = fw.name == "ardurover" and name in ("RTL", "SMART_RTL")
        if fw.name == "arducopter" and name == "SMART_RTL" and not model.armed:
            # Measured: entering it disarmed a second time without arming in between is an
            # internal error (the mode is entered; arming is refused until a reboot).
            if self._ap._smart_rtl_entered:
                self._ap._internal_error = 130
                self._ap._text(_CRITICAL, "Internal Errors 0x100000")
            self._ap._smart_rtl_entered = True
        if fw.name == "arducopter" and name == "LAND" and model.armed and not model.airborne:
            self._ap.arming.disarm(now_s)  # LAND on the ground: landed at once
        if left == "AUTO":
            self._ap.auto.left()
        if name == "AUTO":
            if fw.name == "arduplane" and not self._ap.auto.has_items():
                self._ap.missions.start()  # empty: complete at once
                self._ap._text(_INFO, "Mission complete, changing mode to RTL")
                model.set_mode("RTL")
                self._ap._last_mode = "RTL"
            else:
                self._ap.auto.entered()
        return _ACCEPTED

    def refusal(self, name: str, now_s: float) -> list[tuple[int, str]] | None:
        """ArduPilot's refusal of entering ``name`` now, as (severity, text)s; None: allowed.

        In ArduPilot's order: a mode that needs a position the EKF lacks while armed
        (Mode::enter, before the mode's own init), a mode whose init always fails here,
        then each firmware's own conditions.
        """
        fw, model = self._ap.fw, self._ap.model
        refused = [(_WARNING, fw.mode_refused_text)]
        if fw.name == "arduplane" and self.in_fence_recovery() and not name.startswith("Q"):
            return [(_NOTICE, "Mode change to {mode} denied, in fence recovery")]
        if (
            model.armed
            and name in fw.set_needs_position_armed
            and (not self._ap.readiness.position_ok(now_s) or self._ap._ekf_failsafe)
        ):
            return [(_WARNING, fw.position_refused_text)]
        if fw.name == "arducopter" and self.in_fence_recovery() and model.airborne:
            return [(_WARNING, "Mode change to {mode} failed: in fence recovery")]
        if name in fw.refused_modes:
            return list(fw.refused_modes[name])
        if model.armed and not model.airborne and name in fw.refused_armed_on_ground:
            return list(fw.refused_armed_on_ground[name])
        if fw.name == "ardurover":
            if name == "AUTO" and not self._ap.auto.has_items():
                return [(_NOTICE, "No Mission. Can't set AUTO."), *refused]
            if (
                not model.armed
                and name in fw.set_needs_origin
                and not self._ap.readiness.origin_set(now_s)
            ):
                if name == "RTL" and self._ap._home is not None:
                    # Home without an EKF origin: AR_WPNav fails an internal check, and
                    # ArduRover refuses to arm from then on until it reboots (measured).
                    self._ap._internal_error = 239
                    return [*refused, (_CRITICAL, "Internal Errors 0x100000")]
                return refused
        elif fw.name == "arducopter":
            if name in fw.set_needs_origin and not self._ap.readiness.position_ok(now_s):
                return refused
            if name == "AUTO" and model.armed and not model.airborne:
                first = self._ap.auto.first_nav()
                if first is None:
                    return refused  # nothing to fly
                if first.command != mavlink2.MAV_CMD_NAV_TAKEOFF:
                    return [(_CRITICAL, "Auto: Missing Takeoff Cmd"), *refused]
        elif fw.name == "arduplane" and name == "AUTOLAND" and not model.airborne:
            return [(_WARNING, "Must already be flying!"), *refused]
        return None

    def in_fence_recovery(self) -> bool:
        """Whether a mode change is refused now, as in a fence's recovery.

        FENCE_OPTIONS bit 0 (ArduPlane's default), armed, breached, and in the mode the
        fence chose (ArduCopter and ArduPlane).
        """
        fence = self._ap.fence
        return (
            self._ap.model.armed
            and fence.enabled
            and fence.option(1)
            and bool(fence.breaches)
            and self._ap._mode_reason == "fence"
        )
