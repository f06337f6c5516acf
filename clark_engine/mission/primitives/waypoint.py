"""waypoint: go to one position and finish there.

Guided navigation: the runtime sends the target to the autopilot (guided mode)
and raises ``done`` once the vehicle is within ``tolerance_m`` of it.
"""

from __future__ import annotations

from collections.abc import Iterator

from clark_engine.mission.findings import Finding
from clark_engine.mission.primitives._shared import (
    POINT_SCHEMA,
    RESOLVED_POINT_SCHEMA,
    SPEED_SCHEMA,
    TOLERANCE_SCHEMA,
    check_orbit_tolerance,
    check_points,
    check_speed,
)
from clark_engine.mission.primitives.base import PrimitiveSpec, UseContext, raises_done
from clark_engine.mission.schema_source.common import obj


def _check(ctx: UseContext) -> Iterator[Finding]:
    yield from check_points(ctx, [ctx.params["to"]], "to", indexed=False)
    yield from check_speed(ctx)
    yield from check_orbit_tolerance(ctx)


SPEC = PrimitiveSpec(
    name="waypoint",
    summary="Go to one position in guided mode; done within tolerance_m of it.",
    params=obj(
        "Parameters of waypoint.",
        {
            "to": POINT_SCHEMA,
            "tolerance_m": TOLERANCE_SCHEMA,
            "speed_m_s": SPEED_SCHEMA,
        },
        required=["to"],
    ),
    compiled=lambda: {"to": RESOLVED_POINT_SCHEMA},
    events=raises_done,
    check=_check,
)
