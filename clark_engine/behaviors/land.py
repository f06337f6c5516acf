"""land: land where the vehicle is, in the autopilot's land mode.

The autopilot descends on the spot, detects the touchdown and disarms
(ArduCopter's LAND); ``done`` is raised once the vehicle is on the ground. The
mode comes from the autopilot profile's ``land_mode``. Multirotors only: a
rover never flies, and ArduPlane lands only through a landing sequence in an
AUTO mission, which the engine does not fly, so a fixed-wing aircraft returns
with ``return_home`` and its pilot lands it.
"""

from __future__ import annotations

from collections.abc import Iterator
from typing import TYPE_CHECKING

from clark_engine.behaviors.base import Status
from clark_engine.behaviors.declaration import (
    Behavior,
    Params,
    Traits,
    UseContext,
    raises_done,
)
from clark_engine.behaviors.flight import ProfileModeBehavior, is_airborne
from clark_engine.behaviors.shared import check_airframe, check_mode_role
from clark_engine.mission.findings import Finding

if TYPE_CHECKING:
    from clark_engine.runtime.context import PrimitiveContext


class LandParams(Params):
    """land takes no parameters."""

    DESCRIPTION = "land takes no parameters."


def _check(ctx: UseContext) -> Iterator[Finding]:
    refused = list(
        check_airframe(
            ctx,
            "land",
            {
                "rover": "a rover never leaves the ground; stop it with hold",
                "fixed_wing": "ArduPlane lands through a landing sequence in an AUTO mission, "
                "which the engine does not fly; use return_home and let the pilot land",
            },
        )
    )
    yield from refused
    if not refused:
        yield from check_mode_role(ctx, "land", "land_mode", "LAND", "lands on the spot")


class LandBehavior(ProfileModeBehavior):
    """What land commands in flight, tick by tick (its section of docs/runtime.md).

    Land where the vehicle is, in the autopilot's land mode; done on the ground.
    Multirotors only (the mission layer refuses it on a rover and on ArduPlane, which lands
    only through a landing sequence in an AUTO mission).

    - `start`: `SetMode(land mode)` (the profile's `land_mode`: LAND for ArduCopter), always.
      ArduCopter descends, detects the touchdown and disarms.
    - `update`: DONE once the vehicle is on the ground: its landed state says so, or, without
      one, it is disarmed or at most 2 m above the origin. `SetMode` is asked again only while it
      is refused ([Modes and arming](#modes-and-arming)), so a pilot who takes over is not
      fought.
    - FAILED when the profile names no land mode (the mission layer refuses that:
      [E-MODE-MISSING](check-codes.md#e-mode-missing)).
    """

    name = "land"
    params_type = LandParams
    mode_key = "land_mode"

    def update(self, ctx: PrimitiveContext) -> Status:
        """DONE on the ground."""
        if not self.keep_mode(ctx):
            return Status.FAILED
        if ctx.vehicle is None or is_airborne(ctx):
            return Status.RUNNING
        return Status.DONE


BEHAVIOR = Behavior(
    name="land",
    summary=(
        "Land where the vehicle is in the autopilot's land mode; done once it is on the ground."
    ),
    parameters=LandParams,
    runtime=LandBehavior,
    events=raises_done,
    traits=Traits(lands=True, floor_exempt=True, stays_put=True),
    check=_check,
)
