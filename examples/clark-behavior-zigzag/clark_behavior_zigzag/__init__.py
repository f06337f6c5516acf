"""zigzag: fly a zig-zag across a line, from a start point along a heading.

A Clark Engine behaviour plugin (see docs/plugins.md). The corners alternate
``width_m / 2`` to the left and to the right of the line that leaves ``start`` at
``heading_deg``, each ``advance_m`` further along it; the vehicle flies them in
guided mode, as a tour, and raises ``done`` at the last. A sweep that covers a
strip, or a search pattern, in one ``use:``.
"""

from __future__ import annotations

import math
from collections.abc import Iterator, Mapping, Sequence
from typing import TYPE_CHECKING, Any

from clark_engine.behaviors import Behavior, Params, Plan, Traits, UseContext, param
from clark_engine.behaviors.base import BehaviorRuntime, Point, Status
from clark_engine.behaviors.declaration import raises_done
from clark_engine.behaviors.flight import GuidedLeg, Target, distance_m
from clark_engine.behaviors.shared import (
    POINT_SCHEMA,
    RESOLVED_POINT_SCHEMA,
    SPEED_SCHEMA,
    TOLERANCE_SCHEMA,
    check_points,
    check_speed,
)
from clark_engine.mission.findings import Finding
from clark_engine.mission.schema_source.common import count, number
from clark_engine.mission.schema_source.common import distance_m as distance_schema

if TYPE_CHECKING:
    from clark_engine.runtime.context import PrimitiveContext

EARTH_RADIUS_M = 6_371_000.0


class ZigzagParams(Params):
    """Parameters of zigzag."""

    DESCRIPTION = "Parameters of zigzag."
    REQUIRED = ("start", "heading_deg", "advance_m", "width_m", "legs")

    start: Point = param(
        {**POINT_SCHEMA, "description": "Where the zig-zag starts (its first corner is next)."},
        compiled=lambda: RESOLVED_POINT_SCHEMA,
        convert=Point.from_config,
    )
    heading_deg: float = param(
        number("Direction of the line, degrees from north.", unit="deg", minimum=0, maximum=360)
    )
    advance_m: float = param(
        distance_schema(
            "How far along the line each corner is from the one before.",
            exclusive_minimum=0,
            maximum=10000,
        )
    )
    width_m: float = param(
        distance_schema(
            "Distance between the left and the right corners.", exclusive_minimum=0, maximum=10000
        )
    )
    legs: int = param(count("Corners to fly.", minimum=1, maximum=100))
    tolerance_m: float = param(TOLERANCE_SCHEMA)
    speed_m_s: float | None = param(SPEED_SCHEMA)


def corners_m(
    heading_deg: float, advance_m: float, width_m: float, legs: int
) -> list[tuple[float, float]]:
    """(north, east) of each corner from the start, in metres."""
    along = math.radians(heading_deg)
    across = along + math.pi / 2
    out = []
    for i in range(1, legs + 1):
        side = width_m / 2 if i % 2 else -width_m / 2
        out.append(
            (
                i * advance_m * math.cos(along) + side * math.cos(across),
                i * advance_m * math.sin(along) + side * math.sin(across),
            )
        )
    return out


def _shifted(raw: Any, north_m: float, east_m: float) -> Any:
    """A point, in the form it was given in, moved north and east (both frames if both)."""
    if isinstance(raw, Sequence) and not isinstance(raw, str):
        up = raw[2] if len(raw) > 2 else 0
        return [raw[0] + north_m, raw[1] + east_m, up]
    out = dict(raw)
    if "north_m" in raw or "lat" not in raw:
        out["north_m"] = raw.get("north_m", 0) + north_m
        out["east_m"] = raw.get("east_m", 0) + east_m
    if "lat" in raw:
        lat = float(raw["lat"])
        out["lat"] = lat + math.degrees(north_m / EARTH_RADIUS_M)
        out["lon"] = float(raw["lon"]) + math.degrees(
            east_m / (EARTH_RADIUS_M * math.cos(math.radians(lat)))
        )
    return out


def _plan(params: Mapping[str, Any]) -> Plan:
    """The corners, as points of the same form as ``start`` (the station draws a route)."""
    corners = corners_m(
        float(params["heading_deg"]),
        float(params["advance_m"]),
        float(params["width_m"]),
        int(params["legs"]),
    )
    start = params["start"]
    points = [(start, "start")]
    points += [(_shifted(start, n, e), f"corner {i}") for i, (n, e) in enumerate(corners, 1)]
    return Plan(points=points)


def _check(ctx: UseContext) -> Iterator[Finding]:
    # Every corner inside the envelope and in radio range, as a tour's waypoints are.
    yield from check_points(ctx, [p for p, _ in _plan(ctx.params).points], "start", indexed=True)
    yield from check_speed(ctx)


def _compile(params: dict[str, Any], ctx: Any) -> dict[str, Any]:
    params["start"] = ctx.point(params["start"])
    return params


class Zigzag(BehaviorRuntime):
    """What zigzag commands in flight, tick by tick.

    `start`: `SetMode(guided)` and a `Goto` to the start point; then, as a
    `waypoint_tour` does, each corner in turn once the vehicle is within `tolerance_m`
    of the one before (3-D for aircraft, ground distance for rovers); DONE at the last.
    """

    name = "zigzag"
    params_type = ZigzagParams
    params: ZigzagParams

    def __init__(self, params: ZigzagParams | Mapping[str, Any]) -> None:
        super().__init__(params)
        p = self.params
        start = p.start
        self.targets = [Target(start.lat, start.lon, start.alt_m)]
        for north_m, east_m in corners_m(p.heading_deg, p.advance_m, p.width_m, p.legs):
            moved = _shifted({"lat": start.lat, "lon": start.lon}, north_m, east_m)
            self.targets.append(Target(moved["lat"], moved["lon"], start.alt_m))
        self.index = 0
        self._leg = GuidedLeg(p.speed_m_s)
        self._three_d = True

    def start(self, ctx: PrimitiveContext) -> None:
        """Enter guided mode and send the start point."""
        self._three_d = ctx.config.is_aircraft
        self.index = 0
        self._leg.begin(ctx)
        if not self._leg.failed:
            self._leg.go(ctx, self.targets[0])

    def update(self, ctx: PrimitiveContext) -> Status:
        """Move on to the next corner on arrival; DONE after the last."""
        if self._leg.failed:
            return Status.FAILED
        remaining_m = distance_m(ctx, self.targets[self.index], three_d=self._three_d)
        if remaining_m is not None and remaining_m <= self.params.tolerance_m:
            if self.index + 1 == len(self.targets):
                return Status.DONE
            self.index += 1
            self._leg.go(ctx, self.targets[self.index])
        self._leg.track(ctx)
        return Status.RUNNING


BEHAVIOR = Behavior(
    name="zigzag",
    summary=(
        "Fly a zig-zag across a line from a start point along a heading; done at the last corner."
    ),
    parameters=ZigzagParams,
    runtime=Zigzag,
    events=raises_done,
    traits=Traits(guided=True, flies=True),
    check=_check,
    compile=_compile,
    plan=_plan,
)
