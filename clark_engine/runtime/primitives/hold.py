"""hold: keep the vehicle where it is in the autopilot's hold mode; never finishes.

Runtime semantics (the declaration is :mod:`clark_engine.mission.primitives.hold`):
``start`` sends SetMode(the profile's hold_mode: LOITER for planes and copters,
HOLD for rovers), always, even when the vehicle already reports it, because a
stale report must never leave the vehicle in the mode a previous state asked for
(a change to the current mode is a no-op for ArduPilot). ``update`` is RUNNING
until a transition leaves the state; SetMode is repeated only while the
autopilot has refused it and nobody changed the mode since
(:class:`~._shared.ModeRequest`), so a pilot who takes over is not fought.
FAILED only when the profile names no hold mode (impossible for a compiled
config).
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

from clark_engine.runtime.context import PrimitiveContext, Status
from clark_engine.runtime.primitives._shared import ModeRequest
from clark_engine.runtime.primitives.base import Primitive


class Hold(Primitive):
    """Hold position in the autopilot's hold mode."""

    name = "hold"

    _failed = False

    def __init__(self, params: Mapping[str, Any]) -> None:
        super().__init__(params)
        self._mode = ModeRequest()

    def start(self, ctx: PrimitiveContext) -> None:
        """Switch to the hold mode."""
        mode = ctx.config.hold_mode
        self._failed = mode is None
        if mode is None:
            ctx.log.error("%s: the autopilot profile names no hold_mode", ctx.config.agent)
            return
        self._mode.begin(ctx, mode)

    def update(self, ctx: PrimitiveContext) -> Status:
        """RUNNING until a transition moves on."""
        self._mode.update(ctx)
        return Status.FAILED if self._failed else Status.RUNNING
