"""waypoint_tour: visit positions in order, optionally looping; done at the last unless loop.

Runtime semantics (the declaration is :mod:`clark_engine.mission.primitives.waypoint_tour`):

- ``start``: SetMode(guided), then Goto(waypoint 0), as for :mod:`.waypoint`
  (thesis 5.2.1: Slash A drove an eight-waypoint mission).
- ``update``: while no vehicle state has arrived, RUNNING. When the vehicle is
  within ``tolerance_m`` of the current waypoint (3-D for air vehicles, ground
  distance for rovers, as for waypoint), the tour moves to the next one and sends
  its Goto in the same tick. After the last waypoint it is DONE, or with
  ``loop`` it starts again at waypoint 0. At most one waypoint is passed per
  tick, so a vehicle that is already near the next one moves on at the next
  tick. A Goto is sent only when the target changes: a looping tour of a single
  point (or two equal points in a row) does not repeat its Goto every tick.
- Mode changes are not fought, and the current Goto is re-sent when the vehicle
  enters guided mode again, exactly as for waypoint.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

from clark_engine.runtime.context import PrimitiveContext, Status
from clark_engine.runtime.primitives._shared import GuidedLeg, Target, distance_m
from clark_engine.runtime.primitives.base import Primitive


class WaypointTour(Primitive):
    """Guided navigation through a list of points.

    Attributes:
        waypoints: The points, in order.
        loop: Start again at the first point after the last.
        tolerance_m: Distance that counts as arrived at each point.
        speed_m_s: Requested ground speed, None for the autopilot's own.
        index: The waypoint being flown to.
    """

    name = "waypoint_tour"

    def __init__(self, params: Mapping[str, Any]) -> None:
        super().__init__(params)
        self.waypoints = tuple(Target.from_point(p) for p in params["waypoints"])
        self.loop = bool(params.get("loop", False))
        self.tolerance_m = float(params.get("tolerance_m", 5.0))
        speed = params.get("speed_m_s")
        self.speed_m_s = float(speed) if speed is not None else None
        self.index = 0
        self._leg = GuidedLeg(self.speed_m_s)
        self._three_d = True

    def start(self, ctx: PrimitiveContext) -> None:
        """Enter guided mode and send the first waypoint."""
        self._three_d = ctx.config.is_aircraft
        self.index = 0
        self._leg.begin(ctx)
        if not self._leg.failed:
            self._leg.go(ctx, self.waypoints[0])

    def update(self, ctx: PrimitiveContext) -> Status:
        """Move on to the next waypoint on arrival; DONE after the last unless looping."""
        if self._leg.failed:
            return Status.FAILED
        current = self.waypoints[self.index]
        remaining_m = distance_m(ctx, current, three_d=self._three_d)
        if remaining_m is not None and remaining_m <= self.tolerance_m:
            following = self.index + 1
            if following == len(self.waypoints):
                if not self.loop:
                    return Status.DONE
                following = 0
            self.index = following
            if self.waypoints[following] != current:
                self._leg.go(ctx, self.waypoints[following])
        self._leg.track(ctx)
        return Status.RUNNING
