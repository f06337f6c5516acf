"""waypoint_tour: visit a list of positions in order, optionally looping.

Each waypoint is sent in turn as a guided target once the previous one is
within tolerance. Without ``loop`` the tour raises ``done`` at the last one;
with it, the tour runs until a transition leaves the state.
"""

from __future__ import annotations

from collections.abc import Iterator, Mapping
from typing import Any

from clark_engine.mission.findings import Finding
from clark_engine.mission.primitives._shared import (
    POINT_SCHEMA,
    RESOLVED_POINT_SCHEMA,
    SPEED_SCHEMA,
    TOLERANCE_SCHEMA,
    check_orbit_tolerance,
    check_points,
    check_speed,
    check_tour_legs,
)
from clark_engine.mission.primitives.base import PrimitiveSpec, UseContext
from clark_engine.mission.schema_source.common import array, boolean, obj


def _events(params: Mapping[str, Any]) -> frozenset[str]:
    return frozenset() if params.get("loop") else frozenset({"done"})


def _check(ctx: UseContext) -> Iterator[Finding]:
    yield from check_points(ctx, list(ctx.params["waypoints"]), "waypoints", indexed=True)
    yield from check_tour_legs(ctx)
    yield from check_speed(ctx)
    yield from check_orbit_tolerance(ctx)


_WAYPOINTS = array("The positions to visit, in order.", POINT_SCHEMA, min_items=1)

SPEC = PrimitiveSpec(
    name="waypoint_tour",
    summary="Visit waypoints in order (optionally forever); done at the last one unless loop.",
    params=obj(
        "Parameters of waypoint_tour.",
        {
            "waypoints": _WAYPOINTS,
            "loop": boolean("Start again at the first waypoint after the last.", default=False),
            "tolerance_m": TOLERANCE_SCHEMA,
            "speed_m_s": SPEED_SCHEMA,
        },
        required=["waypoints"],
    ),
    compiled=lambda: {"waypoints": {**_WAYPOINTS, "items": RESOLVED_POINT_SCHEMA}},
    events=_events,
    check=_check,
)
