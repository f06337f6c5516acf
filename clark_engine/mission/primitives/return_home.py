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

from collections.abc import Iterator

from clark_engine.mission.findings import Finding
from clark_engine.mission.primitives._shared import check_mode_role, check_orbit_tolerance
from clark_engine.mission.primitives.base import PrimitiveSpec, UseContext, raises_done
from clark_engine.mission.schema_source.common import number, obj


def _check(ctx: UseContext) -> Iterator[Finding]:
    yield from check_mode_role(ctx, "return_home", "rtl_mode", "RTL", "returns to launch")
    yield from check_orbit_tolerance(ctx, circled="home in RTL", reached="home")


SPEC = PrimitiveSpec(
    name="return_home",
    summary=(
        "Return to home in the autopilot's RTL mode; done within tolerance_m of home "
        "(ArduCopter goes on to land there)."
    ),
    params=obj(
        "Parameters of return_home.",
        {
            "tolerance_m": number(
                "Ground distance from home at which the vehicle counts as home.",
                unit="m",
                exclusive_minimum=0,
                maximum=1000,
                default=5,
            ),
        },
    ),
    events=raises_done,
    check=_check,
)
