"""waypoint: go to one position and finish there.

Guided navigation: the runtime sends the target to the autopilot (guided mode)
and raises ``done`` once the vehicle is within ``tolerance_m`` of it.
"""

from __future__ import annotations

from collections.abc import Iterator, Mapping
from typing import TYPE_CHECKING, Any

from clark_engine.behaviors.base import BehaviorRuntime, Point, Status
from clark_engine.behaviors.declaration import (
    Behavior,
    CompileContext,
    Params,
    Plan,
    Traits,
    UseContext,
    param,
    raises_done,
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
)
from clark_engine.mission.findings import Finding

if TYPE_CHECKING:
    from clark_engine.runtime.context import PrimitiveContext


class WaypointParams(Params):
    """Parameters of waypoint."""

    DESCRIPTION = "Parameters of waypoint."
    REQUIRED = ("to",)

    to: Point = param(
        POINT_SCHEMA, compiled=lambda: RESOLVED_POINT_SCHEMA, convert=Point.from_config
    )
    tolerance_m: float = param(TOLERANCE_SCHEMA)
    speed_m_s: float | None = param(SPEED_SCHEMA)


def _check(ctx: UseContext) -> Iterator[Finding]:
    yield from check_points(ctx, [ctx.params["to"]], "to", indexed=False)
    yield from check_speed(ctx)
    yield from check_orbit_tolerance(ctx)


def _compile(params: dict[str, Any], ctx: CompileContext) -> dict[str, Any]:
    params["to"] = ctx.point(params["to"])
    return params


def _plan(params: Mapping[str, Any]) -> Plan:
    return Plan(points=[(params["to"], "to")], kind="target")


class WaypointBehavior(BehaviorRuntime):
    """What waypoint commands in flight, tick by tick (its section of docs/runtime.md).

    Go to one position in guided mode; done within `tolerance_m` of it.

    - `start`: `SetMode(guided mode)` (asked again while refused, as
      [above](#modes-and-arming)), `Arm` when the engine arms this vehicle and it is
      disarmed, then `Goto(lat, lon, alt_m, speed_m_s)`. Without `speed_m_s` the Goto
      carries no speed and the autopilot flies its own (ArduRover's WP_SPEED, ArduCopter's
      WPNAV_SPEED, ArduPlane's AIRSPEED_CRUISE: see
      [hardware-profiles.md](hardware-profiles.md#speeds-cruise_speed_m_s-and-the-autopilots-parameters)).
    - `update`: DONE once the vehicle is within `tolerance_m` of the point; RUNNING until then
      and while no vehicle state has arrived. Air vehicles measure the straight-line (3-D)
      distance, altitude included; rovers the ground distance only.
    - The `Goto` is sent again when the vehicle is seen *entering* guided mode (from another
      mode), *armed* after being disarmed, or *flying* after being on the ground (aircraft):
      ArduPilot resets its guided target to where the vehicle is on entering GUIDED, and
      ArduCopter ignores targets while on the ground, so a vehicle switched back to guided by
      the station, armed late by its pilot or lifted off by a takeoff would otherwise sit
      still.
    - Mode changes by the pilot or the station are not fought: once the vehicle has reported
      guided, or another mode was chosen, `SetMode` is never sent again.
    - FAILED only when the autopilot profile names no guided mode.

    Attributes:
        target: The point (``to``).
        tolerance_m: Distance that counts as arrived.
        speed_m_s: Requested ground speed, None for the autopilot's own.
    """

    name = "waypoint"
    params_type = WaypointParams
    params: WaypointParams

    def __init__(self, params: WaypointParams | Mapping[str, Any]) -> None:
        super().__init__(params)
        self.target = Target.from_point(self.params.to)
        self.tolerance_m = float(self.params.tolerance_m)
        speed = self.params.speed_m_s
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


BEHAVIOR = Behavior(
    name="waypoint",
    summary="Go to one position in guided mode; done within tolerance_m of it.",
    parameters=WaypointParams,
    runtime=WaypointBehavior,
    events=raises_done,
    traits=Traits(guided=True, flies=True),
    check=_check,
    compile=_compile,
    plan=_plan,
)
