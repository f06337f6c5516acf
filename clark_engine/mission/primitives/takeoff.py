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

from collections.abc import Iterator

from clark_engine.mission.findings import Finding
from clark_engine.mission.primitives._shared import (
    check_airframe,
    check_ceiling,
    check_height_margin,
)
from clark_engine.mission.primitives.base import PrimitiveSpec, UseContext, raises_done
from clark_engine.mission.schema_source.common import altitude_m, distance_m, obj


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


SPEC = PrimitiveSpec(
    name="takeoff",
    summary=(
        "Take off and climb to alt_m above the origin (ArduCopter: guided takeoff; ArduPlane: "
        "its TAKEOFF mode); done within tolerance_m of it."
    ),
    params=obj(
        "Parameters of takeoff.",
        {
            "alt_m": altitude_m(
                "Altitude above the mission origin to climb to; at most the vehicle's "
                "envelope ceiling.",
                exclusive_minimum=0,
            ),
            "tolerance_m": distance_m(
                "How far below alt_m counts as there.", maximum=1000, default=1
            ),
        },
        required=["alt_m"],
    ),
    events=raises_done,
    check=_check,
)
