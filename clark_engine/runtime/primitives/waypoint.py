"""waypoint: go to one position in guided mode; done within ``tolerance_m`` of it.

Runtime semantics (the declaration is :mod:`clark_engine.mission.primitives.waypoint`):

- ``start``: SetMode(the autopilot's guided mode), then Goto(the point's lat, lon,
  alt_m, ``speed_m_s``), as the thesis's framework put Slash B in "Guided Mode"
  and gave it one waypoint (thesis 5.2.1). SetMode is sent even when the vehicle
  already reports guided: the report may be stale, and a change to the current
  mode is a no-op for ArduPilot (see :class:`GuidedLeg`).
- ``update``: DONE once the vehicle is within ``tolerance_m`` of the point,
  RUNNING until then and while no vehicle state has arrived. Air vehicles measure
  the straight-line (3-D) distance, altitude difference included, so a copter
  climbing to 60 m has not "reached" the point while it passes underneath at
  20 m; rovers measure ground distance only, since their altitude is the
  terrain's, not a command.
- Mode changes by the pilot or the station are not fought: SetMode is sent again
  only while the autopilot has refused it and nobody changed the mode since
  (:class:`~._shared.ModeRequest`). When the vehicle is seen entering guided mode
  again (from another mode), the Goto is re-sent, because ArduPilot resets its
  guided target to the current position on entering GUIDED.
- FAILED only when the autopilot profile names no guided mode (impossible for a
  compiled config; a hand-edited one is logged and fails the state).
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

from clark_engine.runtime.context import PrimitiveContext, Status
from clark_engine.runtime.primitives._shared import GuidedLeg, Target, distance_m
from clark_engine.runtime.primitives.base import Primitive


class Waypoint(Primitive):
    """Guided navigation to one point.

    Attributes:
        target: The point (``to``).
        tolerance_m: Distance that counts as arrived.
        speed_m_s: Requested ground speed, None for the autopilot's own.
    """

    name = "waypoint"

    def __init__(self, params: Mapping[str, Any]) -> None:
        super().__init__(params)
        self.target = Target.from_point(params["to"])
        self.tolerance_m = float(params.get("tolerance_m", 5.0))
        speed = params.get("speed_m_s")
        self.speed_m_s = float(speed) if speed is not None else None
        self._leg = GuidedLeg(self.speed_m_s)
        self._three_d = True

    def start(self, ctx: PrimitiveContext) -> None:
        """Enter guided mode and send the point."""
        self._three_d = ctx.config.is_aircraft
        self._leg.begin(ctx)
        if not self._leg.failed:
            self._leg.go(ctx, self.target)

    def update(self, ctx: PrimitiveContext) -> Status:
        """DONE within tolerance; otherwise keep the target alive across mode changes."""
        if self._leg.failed:
            return Status.FAILED
        remaining_m = distance_m(ctx, self.target, three_d=self._three_d)
        if remaining_m is not None and remaining_m <= self.tolerance_m:
            return Status.DONE
        self._leg.track(ctx)
        return Status.RUNNING
