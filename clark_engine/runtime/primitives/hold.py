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

from clark_engine.runtime.context import PrimitiveContext, Status
from clark_engine.runtime.primitives._shared import ProfileModePrimitive


class Hold(ProfileModePrimitive):
    """Hold position in the autopilot's hold mode."""

    name = "hold"
    mode_key = "hold_mode"

    def update(self, ctx: PrimitiveContext) -> Status:
        """RUNNING until a transition moves on."""
        return Status.RUNNING if self.keep_mode(ctx) else Status.FAILED
