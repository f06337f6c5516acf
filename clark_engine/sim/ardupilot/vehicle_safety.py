"""What ArduPilot's own safety code asks of the vehicle it runs on.

ArduPilot's geofence reaction (``Copter::fence_check``, ``Rover::fence_check``,
``Plane::fence_check``) and its ground-station failsafe (``failsafe_gcs_on_event``
and the like) are vehicle code: they read the mode, the arming and landed state
and parameters, speak STATUSTEXTs, change modes for a reason and disarm. The
simulated autopilot (:class:`~clark_engine.sim.ardupilot.autopilot.SimAutopilot`) offers
exactly that to :mod:`clark_engine.sim.ardupilot.fence` and
:mod:`clark_engine.sim.ardupilot.gcs_failsafe` through :class:`ApVehicle`, so that those
modules hold ArduPilot's rules and words and the autopilot only carries them out
(in ArduPilot's order: a text said before a mode change is said before it).
"""

from __future__ import annotations

from typing import Literal, Protocol

ModeReason = Literal["gcs", "fence", "gcs_failsafe", "takeoff_failsafe", "autopilot"]
"""Why a mode was entered (ArduPilot's ModeReason, as far as the simulation tells them
apart): a ground station or the engine, the fence's action, the GCS failsafe's action,
ArduPlane's deferred failsafe after its takeoff climb, the autopilot's own logic."""


class ApVehicle(Protocol):
    """The autopilot's side: state to read and actions to take, ArduPilot's way."""

    @property
    def firmware(self) -> str:
        """``ardurover``, ``arducopter`` or ``arduplane``."""

    @property
    def mode(self) -> str:
        """The current mode's name (the profile's)."""

    @property
    def mode_reason(self) -> ModeReason:
        """Why the current mode was entered."""

    @property
    def armed(self) -> bool:
        """Whether the motors are armed."""

    @property
    def landed(self) -> bool:
        """On the ground (ArduCopter's ``land_complete``; a rover always is)."""

    @property
    def landing(self) -> bool:
        """Descending to land (ArduCopter's ``is_landing``: LAND, an RTL's or AUTO's landing)."""

    @property
    def initial_climb(self) -> bool:
        """ArduPlane in the initial climb of its TAKEOFF mode (flight stage TAKEOFF)."""

    @property
    def throttle_zero(self) -> bool:
        """The pilot's throttle at zero."""

    def param(self, name: str) -> float:
        """A parameter's value (it must exist in the firmware's table)."""

    def text(self, severity: int, text: str) -> None:
        """Send a STATUSTEXT."""

    def try_mode(self, mode: str, reason: ModeReason) -> bool:
        """Enter ``mode`` as ArduPilot's ``set_mode`` does (with its refusals); True on success.

        Entering the mode the vehicle is already in succeeds without a word.
        """

    def disarm(self) -> None:
        """Disarm (as ArduPilot's failsafes and fence do: wherever the vehicle is)."""

    def clear_overrides(self) -> None:
        """Drop every RC override (``RC_Channels::clear_overrides``)."""

    def spell(self, mode: str) -> str:
        """A mode's name as the firmware's texts spell it."""
