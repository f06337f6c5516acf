"""waypoint_tour: visit a list of positions in order, optionally looping.

Each waypoint is sent in turn as a guided target once the previous one is
within tolerance. Without ``loop`` the tour raises ``done`` at the last one;
with it, the tour runs until a transition leaves the state.
"""

from __future__ import annotations

from collections.abc import Iterator, Mapping
from typing import TYPE_CHECKING, Any

from clark_engine.behaviors.base import BehaviorRuntime, Point, Status, points_from_config
from clark_engine.behaviors.declaration import (
    Behavior,
    CompileContext,
    Params,
    Plan,
    Traits,
    UseContext,
    param,
)
from clark_engine.behaviors.flight import GuidedLeg, Target, distance_m
from clark_engine.behaviors.shared import (
    POINT_SCHEMA,
    RESOLVED_POINT_SCHEMA,
    SPEED_SCHEMA,
    TOLERANCE_SCHEMA,
    check_orbit_tolerance,
    check_points,
    check_speed,
    check_tour_legs,
)
from clark_engine.mission.findings import Finding
from clark_engine.mission.schema_source.common import array, boolean

if TYPE_CHECKING:
    from clark_engine.runtime.context import PrimitiveContext

_WAYPOINTS = array("The positions to visit, in order.", POINT_SCHEMA, min_items=1)


class WaypointTourParams(Params):
    """Parameters of waypoint_tour."""

    DESCRIPTION = "Parameters of waypoint_tour."
    REQUIRED = ("waypoints",)

    waypoints: tuple[Point, ...] = param(
        _WAYPOINTS,
        compiled=lambda: {**_WAYPOINTS, "items": RESOLVED_POINT_SCHEMA},
        convert=points_from_config,
    )
    loop: bool = param(boolean("Start again at the first waypoint after the last.", default=False))
    tolerance_m: float = param(TOLERANCE_SCHEMA)
    speed_m_s: float | None = param(SPEED_SCHEMA)


def _events(params: Mapping[str, Any]) -> frozenset[str]:
    return frozenset() if params.get("loop") else frozenset({"done"})


def _check(ctx: UseContext) -> Iterator[Finding]:
    yield from check_points(ctx, list(ctx.params["waypoints"]), "waypoints", indexed=True)
    yield from check_tour_legs(ctx)
    yield from check_speed(ctx)
    yield from check_orbit_tolerance(ctx)


def _compile(params: dict[str, Any], ctx: CompileContext) -> dict[str, Any]:
    params["waypoints"] = [ctx.point(p) for p in params["waypoints"]]
    return params


def _plan(params: Mapping[str, Any]) -> Plan:
    return Plan(
        points=[(p, f"waypoints[{i}]") for i, p in enumerate(params["waypoints"])],
        loop=bool(params.get("loop")),
    )


class WaypointTourBehavior(BehaviorRuntime):
    """What waypoint_tour commands in flight, tick by tick (its section of docs/runtime.md).

    Visit positions in order, optionally looping; done at the last unless `loop`.

    - `start`: as for waypoint, with `Goto(waypoint 0)`.
    - `update`: when the vehicle is within `tolerance_m` of the current waypoint (3-D for air
      vehicles, ground distance for rovers), the tour moves to the next one and sends its
      `Goto` in the same tick; after the last it is DONE, or with `loop` starts again at
      waypoint 0. At most one waypoint is passed per tick. A `Goto` is sent only when the
      target changes, or again as for waypoint (entering guided, armed, flying).
    - Modes and arming are handled as for waypoint.

    Attributes:
        waypoints: The points, in order.
        loop: Start again at the first point after the last.
        tolerance_m: Distance that counts as arrived at each point.
        speed_m_s: Requested ground speed, None for the autopilot's own.
        index: The waypoint being flown to.
    """

    name = "waypoint_tour"
    params_type = WaypointTourParams
    params: WaypointTourParams

    def __init__(self, params: WaypointTourParams | Mapping[str, Any]) -> None:
        super().__init__(params)
        self.waypoints = tuple(Target.from_point(p) for p in self.params.waypoints)
        self.loop = bool(self.params.loop)
        self.tolerance_m = float(self.params.tolerance_m)
        speed = self.params.speed_m_s
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


BEHAVIOR = Behavior(
    name="waypoint_tour",
    summary="Visit waypoints in order (optionally forever); done at the last one unless loop.",
    parameters=WaypointTourParams,
    runtime=WaypointTourBehavior,
    events=_events,
    traits=Traits(guided=True, flies=True),
    check=_check,
    compile=_compile,
    plan=_plan,
)
