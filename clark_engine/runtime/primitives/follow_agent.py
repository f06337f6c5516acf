"""follow_agent: go to another agent's reported position plus an offset.

Runtime semantics (the declaration is :mod:`clark_engine.mission.primitives.follow_agent`).
The thesis's cooperative test (5.2.1) relayed Slash A's GPS position, made a
waypoint of it and put Slash B in guided mode; this primitive does the same and
keeps moving the waypoint as the target moves.

- The target's position is its latest Agent Status in the fleet table
  (``ctx.peer_status_by_id``, read by the id the compiled config gives, which peeks
  and leaves the new-data flag to others). The
  goal is that position moved by ``offset`` north/east (``offset_position``) and
  ``offset.up_m`` above the target's altitude.
- ``start``: SetMode(guided), as for :mod:`.waypoint`, and a Goto to the goal at
  once when a status is already known.
- Re-targeting: until the first Goto, every tick looks for a status (no status
  yet: RUNNING, no command). After it, a Goto to the latest goal is sent every
  ``1 / retarget_hz`` seconds of the runtime clock, on a fixed schedule counted
  from the first Goto (no drift; a late tick does not cause a burst). A stale
  status is still followed: the target's last known position is the best guess,
  and ``lost:<agent>`` is the machine's business.
- ``update``: DONE (unless ``continuous``) once the vehicle is within
  ``tolerance_m`` of the goal computed from the latest status, 3-D for air
  vehicles and ground distance for rovers, as for waypoint. No vehicle state or
  no status: never done.
- Mode changes are not fought: SetMode is sent at start, and again only while
  the autopilot has refused it and nobody changed the mode since
  (:class:`~._shared.ModeRequest`); guided targets sent while the pilot flies
  another mode are ignored by the autopilot, and the current Goto is re-sent
  when the vehicle enters guided mode again.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from typing import Any

from clark_engine.link.messages import AgentStatus
from clark_engine.runtime.context import PrimitiveContext, Status, offset_position
from clark_engine.runtime.primitives._shared import (
    GuidedLeg,
    Schedule,
    Target,
    distance_m,
)
from clark_engine.runtime.primitives.base import Primitive


class FollowAgent(Primitive):
    """Guided navigation to a moving agent.

    Attributes:
        target_name: The agent followed.
        target_id: Its id: the fleet table is read by id (loading proved it is a peer's).
        offset_north_m: Metres north of the target.
        offset_east_m: Metres east of the target.
        offset_up_m: Metres above the target.
        retarget_period_s: Time between Gotos once the target is known.
        tolerance_m: Distance that counts as arrived.
        continuous: Never finish; keep following.
    """

    name = "follow_agent"

    def __init__(self, params: Mapping[str, Any]) -> None:
        super().__init__(params)
        target = params["target"]
        self.target_name = str(target["name"])
        self.target_id = int(target["id"])
        offset = params.get("offset") or {}
        self.offset_north_m = float(offset.get("north_m", 0.0))
        self.offset_east_m = float(offset.get("east_m", 0.0))
        self.offset_up_m = float(offset.get("up_m", 0.0))
        self.retarget_period_s = 1.0 / float(params.get("retarget_hz", 1.0))
        self.lead_s = float(params.get("lead_s", 2.5))
        self.tolerance_m = float(params.get("tolerance_m", 5.0))
        self.continuous = bool(params.get("continuous", False))
        self._leg = GuidedLeg(None)
        self._three_d = True
        self._schedule = Schedule(self.retarget_period_s)

    def goal(self, status: AgentStatus) -> Target:
        """Where to be for a given status of the target: its position plus the offset."""
        lat_deg, lon_deg = offset_position(
            status.lat_deg, status.lon_deg, self.offset_north_m, self.offset_east_m
        )
        return Target(lat_deg, lon_deg, status.alt_m + self.offset_up_m)

    @staticmethod
    def velocity(status: AgentStatus) -> tuple[float, float]:
        """The target's reported velocity north and east, m/s."""
        heading = math.radians(status.heading_deg)
        speed = max(status.ground_speed_m_s, 0.0)
        return speed * math.cos(heading), speed * math.sin(heading)

    def aim(self, status: AgentStatus) -> Target:
        """The guided target: the goal moved ``lead_s`` ahead along the target's velocity."""
        goal = self.goal(status)
        north, east = self.velocity(status)
        lat_deg, lon_deg = offset_position(
            goal.lat_deg, goal.lon_deg, north * self.lead_s, east * self.lead_s
        )
        return Target(lat_deg, lon_deg, goal.alt_m)

    def start(self, ctx: PrimitiveContext) -> None:
        """Enter guided mode; send the goal at once when the target's status is known."""
        self._three_d = ctx.config.is_aircraft
        self._schedule = Schedule(self.retarget_period_s)
        self._leg.begin(ctx)
        if not self._leg.failed:
            self._retarget(ctx, ctx.peer_status_by_id(self.target_id))

    def update(self, ctx: PrimitiveContext) -> Status:
        """DONE at the goal unless continuous; otherwise re-target when due."""
        if self._leg.failed:
            return Status.FAILED
        status = ctx.peer_status_by_id(self.target_id)
        if status is not None and not self.continuous:
            remaining_m = distance_m(ctx, self.goal(status), three_d=self._three_d)
            if remaining_m is not None and remaining_m <= self.tolerance_m:
                return Status.DONE
        self._retarget(ctx, status)
        self._leg.track(ctx)
        return Status.RUNNING

    def _retarget(self, ctx: PrimitiveContext, status: AgentStatus | None) -> None:
        if status is None:
            return
        if not self._schedule.started:  # the first Goto: as soon as the target is known
            self._schedule.begin(ctx.now_s)
        elif not self._schedule.due(ctx.now_s):
            return
        self._leg.go(ctx, self.aim(status), self.velocity(status))
