"""return_home: go back to home in the autopilot's return-to-launch mode.

Home is where the autopilot says it is (where it got its first fix or was
armed), not the mission origin. The mode comes from the autopilot profile's
``rtl_mode``; ``done`` is raised once the vehicle is within ``tolerance_m`` of
home, ground distance. What the autopilot does there is its own: ArduRover stops,
ArduCopter goes on to land (a following state that changes the mode stops the
landing), ArduPlane circles home, so a fixed-wing aircraft needs a
``tolerance_m`` as wide as that circle.
"""

from __future__ import annotations

from collections.abc import Iterator, Mapping
from typing import TYPE_CHECKING, Any

from clark_engine.behaviors.base import Status
from clark_engine.behaviors.declaration import (
    Behavior,
    Params,
    Traits,
    UseContext,
    param,
    raises_done,
)
from clark_engine.behaviors.flight import ProfileModeBehavior
from clark_engine.behaviors.shared import check_mode_role, check_orbit_tolerance
from clark_engine.mission.findings import Finding
from clark_engine.mission.schema_source.common import number

if TYPE_CHECKING:
    from clark_engine.runtime.context import PrimitiveContext


class ReturnHomeParams(Params):
    """Parameters of return_home."""

    DESCRIPTION = "Parameters of return_home."

    tolerance_m: float = param(
        number(
            "Ground distance from home at which the vehicle counts as home.",
            unit="m",
            exclusive_minimum=0,
            maximum=1000,
            default=5,
        )
    )


def _check(ctx: UseContext) -> Iterator[Finding]:
    yield from check_mode_role(ctx, "return_home", "rtl_mode", "RTL", "returns to launch")
    yield from check_orbit_tolerance(ctx, circled="home in RTL", reached="home")


class ReturnHomeBehavior(ProfileModeBehavior):
    """What return_home commands in flight, tick by tick (its section of docs/runtime.md).

    Go home in the autopilot's return-to-launch mode; done within `tolerance_m` (default
    5 m) of home.

    - `start`: `SetMode(rtl mode)` (the profile's `rtl_mode`), always, and again while
      refused ([Modes and arming](#modes-and-arming)). ArduRover drives home and stops;
      ArduCopter climbs to RTL_ALT, flies home, lands and disarms; ArduPlane flies home and
      circles it.
    - `update`: DONE once the vehicle is within `tolerance_m` of home, ground distance. Home
      is where the autopilot says (HOME_POSITION, in its `AutopilotStatus`: where it got its
      first fix or was armed), not the mission origin. Before the autopilot has reported
      home, and without a vehicle state, RUNNING. ArduCopter goes on to land after this is
      done; a following state that changes the mode stops the landing.
    - FAILED when the profile names no RTL mode.

    Attributes:
        tolerance_m: Ground distance from home that counts as home.
    """

    name = "return_home"
    params_type = ReturnHomeParams
    params: ReturnHomeParams
    mode_key = "rtl_mode"

    def __init__(self, params: ReturnHomeParams | Mapping[str, Any]) -> None:
        super().__init__(params)
        self.tolerance_m = float(self.params.tolerance_m)

    def update(self, ctx: PrimitiveContext) -> Status:
        """DONE within tolerance of home."""
        if not self.keep_mode(ctx):
            return Status.FAILED
        home = ctx.autopilot.home if ctx.autopilot is not None else None
        if home is None:
            return Status.RUNNING
        distance = ctx.distance_to_m(home[0], home[1])
        if distance is not None and distance <= self.tolerance_m:
            return Status.DONE
        return Status.RUNNING


BEHAVIOR = Behavior(
    name="return_home",
    summary=(
        "Return to home in the autopilot's RTL mode; done within tolerance_m of home "
        "(ArduCopter goes on to land there)."
    ),
    parameters=ReturnHomeParams,
    runtime=ReturnHomeBehavior,
    events=raises_done,
    traits=Traits(lands=True, floor_exempt=True, home_when_done=True),
    check=_check,
)
