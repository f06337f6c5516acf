"""hold: keep the vehicle where it is in the autopilot's hold mode; never finishes.

Runtime semantics (the declaration is :mod:`clark_engine.mission.primitives.hold`):
``start`` sends SetMode(the profile's hold_mode: LOITER for planes and copters,
HOLD for rovers), always, even when the vehicle already reports it, because a
stale report must never leave the vehicle in the mode a previous state asked for
(a change to the current mode is a no-op for ArduPilot). ``update`` is RUNNING
until a transition leaves the state; SetMode is not repeated, so a pilot who
takes over is not fought. FAILED only when the profile names no hold mode
(impossible for a compiled config).
"""

from __future__ import annotations

from clark_engine.runtime.context import PrimitiveContext, Status
from clark_engine.runtime.primitives._shared import mode_command
from clark_engine.runtime.primitives.base import Primitive


class Hold(Primitive):
    """Hold position in the autopilot's hold mode."""

    name = "hold"

    _failed = False

    def start(self, ctx: PrimitiveContext) -> None:
        """Switch to the hold mode."""
        mode = ctx.config.hold_mode
        self._failed = mode is None
        if mode is None:
            ctx.log.error("%s: the autopilot profile names no hold_mode", ctx.config.agent)
            return
        ctx.command(mode_command(ctx, mode))

    def update(self, ctx: PrimitiveContext) -> Status:
        """RUNNING until a transition moves on."""
        return Status.FAILED if self._failed else Status.RUNNING
