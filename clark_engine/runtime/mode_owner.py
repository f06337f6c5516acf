"""Whose mode the vehicle is in: the engine's, or someone else's.

:class:`ModeOwner` says whether the mode the vehicle reports is one the engine put it
in, so that a breach never fights a pilot (or a station) who took the vehicle. A module
of its own because it is no part of the envelope's geometry: it follows the modes asked
and reported, and the runtime asks it before a breach's action sends a mode.
"""

from __future__ import annotations


class ModeOwner:
    """Whether the vehicle is in a mode the engine put it in.

    The engine asks for modes (its behaviour's states, its failsafe); the pilot's
    switch, the station's Mode Change Request and the autopilot's own failsafes
    change them too. The vehicle is the engine's while the mode it reports is the
    last one the engine asked for: from the report that shows the engine's mode
    granted until a report of any other. While a request is pending the vehicle
    stays with whoever put it in the mode it still reports.
    """

    def __init__(self) -> None:
        self.asked: str | None = None
        """The mode the engine last asked for."""
        self.reported: str | None = None
        """The mode the vehicle last reported."""
        self.engine_holds = False
        """True while the reported mode is one the engine put the vehicle in."""

    def engine_asked(self, mode: str) -> None:
        """The engine asked for ``mode`` (a behaviour's SetMode, a failsafe's)."""
        self.asked = mode
        if self.reported == mode:
            self.engine_holds = True

    def mode_reported(self, mode: str) -> None:
        """The vehicle reported ``mode`` (a VehicleState, an autopilot heartbeat)."""
        if mode == self.reported:
            return
        self.reported = mode
        self.engine_holds = mode == self.asked
