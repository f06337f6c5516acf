"""The simulated ArduPilot as its fence and ground-station failsafe see it.

:class:`SafetyHooks` is the autopilot's side of
:class:`~clark_engine.sim.ardupilot.vehicle_safety.ApVehicle`: the firmware, mode and why
it was entered, armed, landed, landing, the initial climb, the throttle at zero, parameters,
texts, and the actions a fence or failsafe takes (a mode tried for a reason, a forced
disarm, the RC overrides cleared), each at the time of the step being run.

Apart from :class:`~clark_engine.sim.ardupilot.autopilot.SimAutopilot` because it is a view
of it, the one :mod:`~clark_engine.sim.ardupilot.fence` and
:mod:`~clark_engine.sim.ardupilot.gcs_failsafe` are handed: they see these names and nothing
else of the autopilot.
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Final

from pymavlink.dialects.v20 import ardupilotmega as mavlink2

from clark_engine.sim.ardupilot.vehicle_safety import ModeReason

if TYPE_CHECKING:
    from clark_engine.sim.ardupilot.autopilot import SimAutopilot

_ACCEPTED: Final = int(mavlink2.MAV_RESULT_ACCEPTED)


class SafetyHooks:
    """The autopilot as ArduPilot's fence and failsafes see it (:class:`ApVehicle`).

    Args:
        autopilot: The autopilot it shows them.
    """

    def __init__(self, autopilot: SimAutopilot) -> None:
        self._ap = autopilot
        self.now_s = 0.0
        """The time of the advance or message being handled."""

    @property
    def firmware(self) -> str:
        """``ardurover``, ``arducopter`` or ``arduplane``."""
        return self._ap.firmware

    @property
    def mode(self) -> str:
        """The current mode's name (the profile's)."""
        return self._ap.model.mode

    @property
    def mode_reason(self) -> ModeReason:
        """Why the current mode was entered."""
        return self._ap._mode_reason

    @property
    def armed(self) -> bool:
        """Whether the motors are armed."""
        return self._ap.model.armed

    @property
    def landed(self) -> bool:
        """On the ground (ArduCopter's ``land_complete``; a rover always is)."""
        return not self._ap.model.airborne

    @property
    def landing(self) -> bool:
        """Descending to land (ArduCopter's ``is_landing``: LAND, an RTL's or AUTO's landing)."""
        ap, model = self._ap, self._ap.model
        if model.mode == "LAND":
            return True
        if model.mode == "AUTO" and ap._auto_landing:
            return True
        return model.mode in ("RTL", "SMART_RTL") and model.landed_state == "landing"

    @property
    def initial_climb(self) -> bool:
        """ArduPlane in the initial climb of its TAKEOFF mode (flight stage TAKEOFF)."""
        model = self._ap.model
        return model.mode == "TAKEOFF" and model.landed_state == "taking_off"

    @property
    def throttle_zero(self) -> bool:
        """The pilot's throttle at zero."""
        return self._ap.arming.throttle_at_zero()

    def param(self, name: str) -> float:
        """A parameter's value (it must exist in the firmware's table)."""
        return self._ap._params[name].value

    def text(self, severity: int, text: str) -> None:
        """Send a STATUSTEXT."""
        self._ap._text(severity, text)

    def try_mode(self, mode: str, reason: ModeReason) -> bool:
        """Enter ``mode`` as ArduPilot's ``set_mode`` does (with its refusals); True on success."""
        ap = self._ap
        if mode not in ap.modes:
            return False  # the profile has no such mode: nothing to try
        if mode == ap.model.mode:
            return True
        return (
            ap.mode_changes.enter(mode, self.now_s, reason) == _ACCEPTED and ap.model.mode == mode
        )

    def disarm(self) -> None:
        """Disarm (as ArduPilot's failsafes and fence do: wherever the vehicle is)."""
        self._ap.arming.disarm(self.now_s, force=True)

    def clear_overrides(self) -> None:
        """Drop every RC override (``RC_Channels::clear_overrides``)."""
        self._ap.rc_overrides.clear()

    def spell(self, mode: str) -> str:
        """A mode's name as the firmware's texts spell it."""
        return self._ap.fw.spell(mode)
