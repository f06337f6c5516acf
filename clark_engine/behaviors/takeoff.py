"""takeoff: leave the ground and climb to ``alt_m`` above the mission origin.

A real aircraft starts on the ground, and ArduPilot flies it nowhere until it has
taken off: ArduCopter ignores guided targets until then. ArduCopter takes off in
its guided mode, armed, on MAV_CMD_NAV_TAKEOFF; ArduPlane takes off in its own
TAKEOFF mode. The state waits for the vehicle to be armed (by the pilot, or by
the engine with ``launch.armed_by: engine``) and raises ``done`` once it flies
within ``tolerance_m`` below ``alt_m``. ``alt_m`` is above the mission origin, like
every altitude of a mission (the engine tells ArduPilot the height above home it
wants), and must stay under the vehicle's ceiling. Aircraft only;
a vehicle the pilot hands over in flight (``launch.airborne``) needs none.
"""

from __future__ import annotations

from collections.abc import Iterator, Mapping
from typing import TYPE_CHECKING, Any, Final

from clark_engine.behaviors.base import BehaviorRuntime, Status
from clark_engine.behaviors.declaration import (
    Behavior,
    Params,
    Plan,
    Traits,
    UseContext,
    param,
    raises_done,
)
from clark_engine.behaviors.flight import (
    TIME_EPSILON_S,
    EngineArming,
    ModeRequest,
    is_airborne,
    reported_mode,
)
from clark_engine.behaviors.shared import (
    check_airframe,
    check_ceiling,
    check_height_margin,
)
from clark_engine.mission.findings import Finding
from clark_engine.mission.schema_source.common import altitude_m, distance_m

if TYPE_CHECKING:
    from clark_engine.runtime.context import PrimitiveContext


class TakeoffParams(Params):
    """Parameters of takeoff."""

    DESCRIPTION = "Parameters of takeoff."
    REQUIRED = ("alt_m",)

    alt_m: float = param(
        altitude_m(
            "Altitude above the mission origin to climb to; at most the vehicle's "
            "envelope ceiling.",
            exclusive_minimum=0,
        )
    )
    tolerance_m: float = param(
        distance_m("How far below alt_m counts as there.", maximum=1000, default=1)
    )


def _check(ctx: UseContext) -> Iterator[Finding]:
    yield from check_airframe(
        ctx,
        "takeoff",
        {"rover": "a rover never leaves the ground; drive it with waypoint or waypoint_tour"},
    )
    alt_m = float(ctx.params["alt_m"])
    where = ctx.locate("alt_m")
    yield from check_ceiling(ctx, alt_m, where, "the takeoff altitude")
    # A climb passes through the floor: only the ceiling's margin applies to a takeoff.
    yield from check_height_margin(
        ctx.agent, alt_m, where, "the takeoff altitude", ctx.use_location, guided=False
    )


TAKEOFF_RETRY_S: Final = 5.0
"""Time between two Takeoff commands while the vehicle stays on the ground. ArduCopter
starts climbing 3.25 s after a takeoff sent just after arming (its motors spool up),
and its landed state (EXTENDED_SYS_STATE) comes once a second: asked again sooner, a
copter already climbing refuses the repeat (measured on SITL)."""


class TakeoffBehavior(BehaviorRuntime):
    """What takeoff commands in flight, tick by tick (its section of docs/runtime.md).

    Lift off and climb to `alt_m` above the mission origin; done within `tolerance_m`
    (default 1 m) below it. Aircraft only (the mission layer refuses it on a rover).

    A multirotor: ArduCopter takes off only in its guided mode, armed, on the ground, on
    MAV_CMD_NAV_TAKEOFF; it ignores position targets until then, and disarms by itself 10 s
    after arming if it has not taken off.

    - `start`: `SetMode(guided)` (asked again while refused), and `Arm` when the engine arms
      this vehicle and it is disarmed; with `armed_by: pilot` the state waits for the pilot
      to arm it.
    - `update`: once the vehicle reports guided and armed and is still on the ground,
      `Takeoff(alt_m)`; sent again every 2 s while it stays on the ground in guided and armed
      (a refusal's reason is in the mission log).

    A fixed wing: ArduPlane takes off in its TAKEOFF mode, armed, climbing to its TKOFF_ALT,
    and loiters there (ahead of where it took off) until told otherwise.

    - `start`: `Takeoff(alt_m)`, which the adapter carries out as TKOFF_ALT and the TAKEOFF
      mode; then `Arm` when the engine arms it. Arming in TAKEOFF launches it.
    - `update`: while it is armed and still on the ground, `Takeoff` again every 2 s.

    Both: DONE once the vehicle flies (its landed state, or, without one, armed and more than
    2 m above the origin) at `alt_m - tolerance_m` or higher. FAILED when the vehicle, armed in
    this state, is disarmed again before it flies (the pilot disarmed it, or ArduCopter's
    auto-disarm); the engine does not arm it again. Also FAILED when a multirotor's profile
    names no guided mode.

    Attributes:
        alt_m: Altitude above home to climb to.
        tolerance_m: How far below ``alt_m`` counts as there.
    """

    name = "takeoff"
    params_type = TakeoffParams
    params: TakeoffParams

    def __init__(self, params: TakeoffParams | Mapping[str, Any]) -> None:
        super().__init__(params)
        self.alt_m = float(self.params.alt_m)
        self.tolerance_m = float(self.params.tolerance_m)
        self._arming = EngineArming()
        self._sent_s: float | None = None
        self._failed = False
        self._plane = False
        self._mode = ModeRequest()

    def start(self, ctx: PrimitiveContext) -> None:
        """Copter: enter guided mode; plane: TAKEOFF. Arm when the engine arms this vehicle."""
        self._sent_s = None
        self._plane = ctx.config.airframe_class == "fixed_wing"
        if self._plane:
            self._take_off(ctx)
            self._arming.begin(ctx)
            return
        mode = ctx.config.guided_mode
        self._failed = mode is None
        if mode is None:
            from clark_engine.runtime.log_events import LogEvent

            ctx.log.error(
                "%s: the autopilot profile names no guided_mode",
                ctx.config.agent,
                extra=LogEvent.BEHAVIOR_ERROR.extra,
            )
            return
        self._mode.begin(ctx, mode)
        self._arming.begin(ctx)

    def _take_off(self, ctx: PrimitiveContext) -> None:
        from clark_engine.runtime.commands import Takeoff as TakeoffCommand

        self._sent_s = ctx.now_s
        ctx.command(TakeoffCommand(self.alt_m))

    def update(self, ctx: PrimitiveContext) -> Status:
        """DONE at altitude; Takeoff when armed on the ground in guided."""
        if self._failed:
            return Status.FAILED
        if not self._plane:
            self._mode.update(ctx)
        vehicle = ctx.vehicle
        if vehicle is None:
            return Status.RUNNING
        flying = is_airborne(ctx)
        if flying and vehicle.alt_m >= self.alt_m - self.tolerance_m:
            return Status.DONE
        self._arming.update(ctx)
        if not vehicle.armed:
            if self._arming.was_armed and not flying:
                from clark_engine.runtime.log_events import LogEvent

                ctx.log.error(
                    "%s: disarmed before taking off; the engine does not arm it again",
                    ctx.config.agent,
                    extra=LogEvent.BEHAVIOR_ERROR.extra,
                )
                self._failed = True
                return Status.FAILED
            return Status.RUNNING
        due = self._sent_s is None or (ctx.now_s - self._sent_s + TIME_EPSILON_S >= TAKEOFF_RETRY_S)
        if not flying and due and (self._plane or reported_mode(ctx) == ctx.config.guided_mode):
            self._take_off(ctx)
        return Status.RUNNING


BEHAVIOR = Behavior(
    name="takeoff",
    summary=(
        "Take off and climb to alt_m above the origin (ArduCopter: guided takeoff; ArduPlane: "
        "its TAKEOFF mode); done within tolerance_m of it."
    ),
    parameters=TakeoffParams,
    runtime=TakeoffBehavior,
    events=raises_done,
    traits=Traits(takes_off=True, floor_exempt=True, flies=True, stays_put=True),
    check=_check,
    plan=lambda params: Plan(climb_to_m=float(params["alt_m"])),
)
