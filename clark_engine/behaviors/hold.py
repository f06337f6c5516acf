"""hold: keep the vehicle where it is, in the autopilot's hold mode.

The mode comes from the profile (LOITER for planes and copters, HOLD for
rovers). Never finishes by itself: a transition moves the machine on.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

from clark_engine.behaviors.base import Status
from clark_engine.behaviors.declaration import Behavior, Params, Traits, raises_nothing
from clark_engine.behaviors.flight import ProfileModeBehavior

if TYPE_CHECKING:
    from clark_engine.runtime.context import PrimitiveContext


class HoldParams(Params):
    """hold takes no parameters."""

    DESCRIPTION = "hold takes no parameters."


class HoldBehavior(ProfileModeBehavior):
    """What hold commands in flight, tick by tick (its section of docs/runtime.md).

    Keep the vehicle where it is; never finishes. `start` sends `SetMode(hold mode)` (the
    profile's `hold_mode`: LOITER for planes and copters, HOLD for rovers), always; `update`
    is RUNNING and asks for the mode again only while it is refused
    ([Modes and arming](#modes-and-arming)): once the vehicle has reported the hold mode, or
    the pilot or the station chose another, `SetMode` is not repeated, so a pilot who takes
    over is not fought. FAILED only when the profile names no hold mode.
    """

    name = "hold"
    params_type = HoldParams
    mode_key = "hold_mode"

    def update(self, ctx: PrimitiveContext) -> Status:
        """RUNNING until a transition moves on."""
        return Status.RUNNING if self.keep_mode(ctx) else Status.FAILED


BEHAVIOR = Behavior(
    name="hold",
    summary="Hold position in the autopilot's hold mode until a transition moves on.",
    parameters=HoldParams,
    runtime=HoldBehavior,
    events=raises_nothing,
    traits=Traits(flies_if_aircraft=True, stays_put=True),
)
