"""takeoff: lift off and climb to ``alt_m`` above home; done within ``tolerance_m`` of it.

Runtime semantics (the declaration is :mod:`clark_engine.mission.primitives.takeoff`).

A multirotor: ArduCopter takes off only in its guided mode, armed, on the ground,
on MAV_CMD_NAV_TAKEOFF; it ignores position targets until then, and disarms by
itself 10 s after arming if it has not taken off. So:

- ``start``: SetMode(guided), always and again while refused (as for
  :mod:`.waypoint`), and Arm when the
  engine arms this vehicle (``launch.armed_by: engine``) and it is disarmed
  (:class:`~._shared.EngineArming`; with ``armed_by: pilot`` the state waits for
  the pilot to arm).
- ``update``: once the vehicle reports guided and armed and is still on the
  ground, Takeoff(``alt_m``); sent again every :data:`TAKEOFF_RETRY_S` while it
  stays on the ground in guided and armed (a refusal's reason is in the mission
  log).

A fixed wing: ArduPlane takes off in its TAKEOFF mode, armed, climbing to its
TKOFF_ALT, and loiters there (ahead of where it took off) until told otherwise:

- ``start``: Takeoff(``alt_m``), which the adapter carries out as TKOFF_ALT and the
  TAKEOFF mode; then Arm when the engine arms it. Arming in TAKEOFF launches it.
- ``update``: while it is still on the ground, Takeoff again every
  :data:`TAKEOFF_RETRY_S`.

Both: DONE once the vehicle flies at ``alt_m - tolerance_m`` or higher. FAILED when
the vehicle, armed in this state, is disarmed again before it flies (the pilot
disarmed it, or ArduCopter's auto-disarm); the engine does not arm it again. Also
FAILED when a multirotor's profile names no guided mode.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any, Final

from clark_engine.runtime.commands import Takeoff as TakeoffCommand
from clark_engine.runtime.context import PrimitiveContext, Status
from clark_engine.runtime.launch import is_airborne
from clark_engine.runtime.log_events import LogEvent
from clark_engine.runtime.primitives._shared import (
    TIME_EPSILON_S,
    EngineArming,
    ModeRequest,
    reported_mode,
)
from clark_engine.runtime.primitives.base import Primitive

TAKEOFF_RETRY_S: Final = 5.0
"""Time between two Takeoff commands while the vehicle stays on the ground. ArduCopter
starts climbing 3.25 s after a takeoff sent just after arming (its motors spool up),
and its landed state (EXTENDED_SYS_STATE) comes once a second: asked again sooner, a
copter already climbing refuses the repeat (measured on SITL)."""


class Takeoff(Primitive):
    """Guided takeoff to an altitude.

    Attributes:
        alt_m: Altitude above home to climb to.
        tolerance_m: How far below ``alt_m`` counts as there.
    """

    name = "takeoff"

    def __init__(self, params: Mapping[str, Any]) -> None:
        super().__init__(params)
        self.alt_m = float(params["alt_m"])
        self.tolerance_m = float(params.get("tolerance_m", 1.0))
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
            ctx.log.error(
                "%s: the autopilot profile names no guided_mode",
                ctx.config.agent,
                extra=LogEvent.BEHAVIOR_ERROR.extra,
            )
            return
        self._mode.begin(ctx, mode)
        self._arming.begin(ctx)

    def _take_off(self, ctx: PrimitiveContext) -> None:
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
        flying = is_airborne(ctx.autopilot, vehicle)
        if flying and vehicle.alt_m >= self.alt_m - self.tolerance_m:
            return Status.DONE
        self._arming.update(ctx)
        if not vehicle.armed:
            if self._arming.was_armed and not flying:
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
