"""The geometry of a survey: a lawnmower's lines over a polygon, and its photo marks.

Pure functions of local metres (north, east), with no mission or runtime types, so that
the compiler, the checks and the tests of :mod:`clark_engine.behaviors.survey` share one
definition, and the plan is the same wherever it is worked out (deterministic: no
randomness, no dependence on dictionary order).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import NamedTuple

#: Most photo marks on one line: a mark closer than a metre to the next is not a plan.
MAX_MARKS_PER_LINE = 10_000


class Line(NamedTuple):
    """One planned line in local metres (north, east).

    Attributes:
        start: Where it is flown from.
        end: Where it is flown to.
        photo_from_m: Distance from ``start`` where the area begins.
        photo_to_m: Distance from ``start`` where it ends.
    """

    start: tuple[float, float]
    end: tuple[float, float]
    photo_from_m: float
    photo_to_m: float


def polygon_area_m2(vertices: Sequence[tuple[float, float]]) -> float:
    """Area of a simple polygon (shoelace formula), square metres, whatever its winding."""
    total = 0.0
    for i, (n0, e0) in enumerate(vertices):
        n1, e1 = vertices[(i + 1) % len(vertices)]
        total += n0 * e1 - n1 * e0
    return abs(total) / 2.0


def _cross(o: tuple[float, float], a: tuple[float, float], b: tuple[float, float]) -> float:
    return (a[0] - o[0]) * (b[1] - o[1]) - (a[1] - o[1]) * (b[0] - o[0])


def _segments_cross(
    a: tuple[float, float], b: tuple[float, float], c: tuple[float, float], d: tuple[float, float]
) -> bool:
    """True when segments ab and cd share a point (touching counts)."""
    d1, d2 = _cross(c, d, a), _cross(c, d, b)
    d3, d4 = _cross(a, b, c), _cross(a, b, d)
    if ((d1 > 0) != (d2 > 0) and d1 != 0 and d2 != 0) and (
        (d3 > 0) != (d4 > 0) and d3 != 0 and d4 != 0
    ):
        return True

    def on(p: tuple[float, float], q: tuple[float, float], r: tuple[float, float]) -> bool:
        return (
            _cross(p, q, r) == 0
            and min(p[0], q[0]) <= r[0] <= max(p[0], q[0])
            and min(p[1], q[1]) <= r[1] <= max(p[1], q[1])
        )

    return on(c, d, a) or on(c, d, b) or on(a, b, c) or on(a, b, d)


def self_crossing(vertices: Sequence[tuple[float, float]]) -> tuple[int, int] | None:
    """The first two non-neighbouring edges (by their first vertex) that meet, or None."""
    count = len(vertices)
    edges = [(vertices[i], vertices[(i + 1) % count]) for i in range(count)]
    for i in range(count):
        for j in range(i + 2, count):
            if i == 0 and j == count - 1:
                continue  # neighbours through the closing vertex
            if _segments_cross(*edges[i], *edges[j]):
                return i, j
    return None


def longest_edge_heading_deg(vertices: Sequence[tuple[float, float]]) -> float:
    """Direction of the polygon's longest edge (the first of equals), 0 <= h < 180 degrees."""
    best_length, best = -1.0, 0.0
    for i, (n0, e0) in enumerate(vertices):
        n1, e1 = vertices[(i + 1) % len(vertices)]
        length = math.hypot(n1 - n0, e1 - e0)
        if length > best_length + 1e-9:
            best_length, best = length, math.degrees(math.atan2(e1 - e0, n1 - n0)) % 180.0
    return round(best, 6) % 180.0


def line_count(
    vertices: Sequence[tuple[float, float]], spacing_m: float, heading_deg: float
) -> int:
    """How many lines cover the polygon at this spacing and heading."""
    across = _across(heading_deg)
    offsets = [n * across[0] + e * across[1] for n, e in vertices]
    return max(1, math.ceil((max(offsets) - min(offsets)) / spacing_m - 1e-9))


def _across(heading_deg: float) -> tuple[float, float]:
    """Unit vector (north, east) 90 degrees clockwise of the heading."""
    h = math.radians(heading_deg)
    return (-math.sin(h), math.cos(h))


def lawnmower(
    vertices: Sequence[tuple[float, float]],
    spacing_m: float,
    heading_deg: float,
    run_out_m: float = 0.0,
) -> list[Line]:
    """The lines that cover a polygon, in the order flown, alternating direction.

    The polygon's width across the heading is split into ``ceil(width / spacing)``
    strips, and a line runs down the middle of each (so the outermost pictures
    reach the edges when the spacing is the footprint's width less its overlap). Each
    line is clipped to the polygon: from where it first enters to where it last
    leaves (a concave area's gap inside one line is flown across), then extended by
    ``run_out_m`` at both ends. The first line is the one furthest to the left of
    the heading, flown along it; the next comes back.

    Args:
        vertices: The polygon, (north_m, east_m), in order; simple, area > 0.
        spacing_m: Distance between lines.
        heading_deg: Direction of the lines, clockwise from north.
        run_out_m: Extension of each line past the area at both ends.
    """
    h = math.radians(heading_deg)
    along = (math.cos(h), math.sin(h))
    across = _across(heading_deg)
    offsets = [n * across[0] + e * across[1] for n, e in vertices]
    low, high = min(offsets), max(offsets)
    count = line_count(vertices, spacing_m, heading_deg)
    first = low + ((high - low) - (count - 1) * spacing_m) / 2.0
    lines: list[Line] = []
    for k in range(count):
        c = first + k * spacing_m
        hits: list[float] = []
        for i, (n0, e0) in enumerate(vertices):
            n1, e1 = vertices[(i + 1) % len(vertices)]
            s0, s1 = offsets[i], offsets[(i + 1) % len(vertices)]
            if (s0 > c) == (s1 > c):
                continue
            t = (c - s0) / (s1 - s0)
            n, e = n0 + t * (n1 - n0), e0 + t * (e1 - e0)
            hits.append(n * along[0] + e * along[1])
        if len(hits) < 2:
            continue  # a strip that only touches a vertex
        a, b = min(hits) - run_out_m, max(hits) + run_out_m
        if k % 2:
            a, b = b, a
        start = (c * across[0] + a * along[0], c * across[1] + a * along[1])
        end = (c * across[0] + b * along[0], c * across[1] + b * along[1])
        length = abs(b - a)
        lines.append(Line(start, end, run_out_m, length - run_out_m))
    return lines


def photo_marks(photo_from_m: float, photo_to_m: float, every_m: float) -> list[float]:
    """Where along a line pictures are taken: evenly, at most ``every_m`` apart, both ends."""
    span = max(0.0, photo_to_m - photo_from_m)
    intervals = min(MAX_MARKS_PER_LINE, max(1, math.ceil(span / every_m - 1e-9)))
    step = span / intervals
    return [photo_from_m + i * step for i in range(intervals + 1)]
