"""Geofence geometry on the mission's local plane: zones, margins, and clamping a target.

One module answers "is this point inside the fence, by how much, and where is the
nearest point that is" for everybody who asks: ``clark validate`` proving waypoints
and tour legs before flight, the runtime clamping a Goto and watching its own
position, the dry run judging a whole run, and the station drawing the fence. It
works in metres north and east of the mission origin (:mod:`clark_engine.mission.geo`),
where a few kilometres of field are flat to well under a GPS error, and it is pure:
no clock, no I/O, nothing of the engine but plain numbers, so the runtime may use it.

The rule is ArduPilot's (``AC_PolyFence_loader``): a vehicle is inside the fence when
it is inside **every** inclusion zone and outside **every** exclusion zone. A fence's
*margin* at a point is the smallest distance from the point to a boundary it must not
cross, positive when the point is inside the fence and negative outside, so
``margin >= 2`` reads "inside, at least 2 m from every edge".
"""

from __future__ import annotations

import math
from collections.abc import Iterable, Sequence
from dataclasses import dataclass

Point2 = tuple[float, float]
"""A point on the local plane: (north_m, east_m)."""

#: Steps a segment is walked in when looking for where it leaves the fence, at most.
_SEGMENT_SAMPLES = 256
#: How finely the crossing point of a segment is found (metres along it).
_SEGMENT_RESOLUTION_M = 0.05


@dataclass(frozen=True, slots=True)
class Zone:
    """One zone of a geofence: a polygon (``corners``) or a circle (``center``, ``radius_m``).

    Attributes:
        kind: ``polygon`` or ``circle``.
        corners: A polygon's corners in order, the last joined to the first.
        center: A circle's centre.
        radius_m: A circle's radius.
    """

    kind: str
    corners: tuple[Point2, ...] = ()
    center: Point2 = (0.0, 0.0)
    radius_m: float = 0.0

    @staticmethod
    def polygon(corners: Iterable[Point2]) -> Zone:
        """A polygon zone from its corners (north_m, east_m), in order."""
        return Zone("polygon", tuple((float(n), float(e)) for n, e in corners))

    @staticmethod
    def circle(center: Point2, radius_m: float) -> Zone:
        """A circle zone."""
        return Zone("circle", center=(float(center[0]), float(center[1])), radius_m=radius_m)

    def contains(self, north_m: float, east_m: float) -> bool:
        """True when the point is inside the zone (on the edge counts as inside)."""
        return self.signed_distance_m(north_m, east_m) >= 0.0

    def signed_distance_m(self, north_m: float, east_m: float) -> float:
        """Distance from the point to the zone's edge: positive inside, negative outside."""
        if self.kind == "circle":
            return self.radius_m - math.hypot(north_m - self.center[0], east_m - self.center[1])
        edge = min(_segment_distance_m((north_m, east_m), a, b) for a, b in _edges(self.corners))
        return edge if _inside_polygon(north_m, east_m, self.corners) else -edge

    def nearest_on_edge(self, north_m: float, east_m: float) -> Point2:
        """The point of the zone's edge nearest the given point."""
        if self.kind == "circle":
            dn, de = north_m - self.center[0], east_m - self.center[1]
            length = math.hypot(dn, de)
            if length < 1e-9:
                dn, de, length = 1.0, 0.0, 1.0
            k = self.radius_m / length
            return self.center[0] + dn * k, self.center[1] + de * k
        best: Point2 = self.corners[0]
        best_m = math.inf
        for a, b in _edges(self.corners):
            p = _project((north_m, east_m), a, b)
            d = math.hypot(p[0] - north_m, p[1] - east_m)
            if d < best_m:
                best, best_m = p, d
        return best

    def first_crossing(self, start: Point2, end: Point2) -> float | None:
        """Where the segment from ``start`` to ``end`` first crosses the zone's edge, exactly.

        The answer is a fraction 0..1 of the segment's length, or None when it crosses
        no edge (touching one, or running along it, is not crossing). Exact where
        :meth:`Fence.leaves_at` samples, so a static check finds a small zone on a long
        leg: a segment whose ends are both inside a polygon and that crosses an edge
        leaves it; one whose ends are both outside a zone and that crosses an edge goes
        through it.
        """
        dn, de = end[0] - start[0], end[1] - start[1]
        if dn * dn + de * de < 1e-18:
            return None
        if self.kind == "circle":
            length2 = dn * dn + de * de
            fn, fe = start[0] - self.center[0], start[1] - self.center[1]
            b = 2.0 * (fn * dn + fe * de)
            c = fn * fn + fe * fe - self.radius_m**2
            disc = b * b - 4.0 * length2 * c
            if disc <= 1e-9:
                return None  # misses the circle, or only touches it
            root = math.sqrt(disc)
            hits = [(-b - root) / (2.0 * length2), (-b + root) / (2.0 * length2)]
            inside = [t for t in hits if 0.0 < t < 1.0]
            return min(inside) if inside else None
        best: float | None = None
        for a, b2 in _edges(self.corners):
            t = _proper_crossing(start, end, a, b2)
            if t is not None and (best is None or t < best):
                best = t
        return best

    def self_crossing(self) -> tuple[int, int] | None:
        """For a polygon, the first pair of edges (by index) that cross; None when none do."""
        if self.kind != "polygon":
            return None
        edges = list(_edges(self.corners))
        count = len(edges)
        for i in range(count):
            for j in range(i + 1, count):
                if j == i + 1 or (i == 0 and j == count - 1):
                    continue  # neighbours share a corner
                if _segments_cross(*edges[i], *edges[j]):
                    return i, j
        return None

    @property
    def area_m2(self) -> float:
        """The zone's area (a polygon's by the shoelace formula)."""
        if self.kind == "circle":
            return math.pi * self.radius_m**2
        total = 0.0
        for (n1, e1), (n2, e2) in _edges(self.corners):
            total += n1 * e2 - n2 * e1
        return abs(total) / 2.0


@dataclass(frozen=True, slots=True)
class Fence:
    """A vehicle's geofence: inside every inclusion zone, outside every exclusion zone.

    A fence with no zones at all holds everywhere (its margin is infinite).
    """

    include: tuple[Zone, ...] = ()
    exclude: tuple[Zone, ...] = ()

    def margin_m(self, north_m: float, east_m: float) -> float:
        """Smallest distance to a boundary: positive inside the fence, negative outside."""
        margin = math.inf
        for zone in self.include:
            margin = min(margin, zone.signed_distance_m(north_m, east_m))
        for zone in self.exclude:
            margin = min(margin, -zone.signed_distance_m(north_m, east_m))
        return margin

    def contains(self, north_m: float, east_m: float, margin_m: float = 0.0) -> bool:
        """True when the point is inside the fence, at least ``margin_m`` from every edge."""
        return self.margin_m(north_m, east_m) >= margin_m

    def nearest_inside(self, north_m: float, east_m: float, margin_m: float) -> Point2 | None:
        """The point nearest the given one that is inside by ``margin_m``; None if none found.

        Each violated zone pushes the point to its edge and ``margin_m`` further in; a
        few rounds settle zones that meet. Zones too small for the margin, or corners too
        tight, give None: the caller refuses rather than guess.
        """
        point = (north_m, east_m)
        for _ in range(8):
            if self.margin_m(*point) >= margin_m - 1e-6:
                return point
            worst = self._worst_zone(*point)
            if worst is None:
                return None
            zone, inclusion = worst
            edge = zone.nearest_on_edge(*point)
            inward = _inward(zone, edge, inclusion)
            if inward is None:
                return None
            point = (edge[0] + inward[0] * margin_m, edge[1] + inward[1] * margin_m)
        return point if self.margin_m(*point) >= margin_m - 1e-6 else None

    def leaves_at(self, start: Point2, end: Point2, margin_m: float = 0.0) -> float | None:
        """How far along the line from ``start`` to ``end`` it first comes within ``margin_m``.

        The answer is a fraction 0..1 of the line's length, or None when it never does.
        A start already inside the margin band counts from the first point where the
        margin falls below the start's own (a vehicle near the edge may still move away
        from it, but not further out).
        """
        length = math.hypot(end[0] - start[0], end[1] - start[1])
        if length < 1e-9:
            return None
        floor = min(margin_m, self.margin_m(*start))
        steps = max(1, min(_SEGMENT_SAMPLES, math.ceil(length / 0.5)))
        previous = 0.0
        for i in range(1, steps + 1):
            t = i / steps
            if self.margin_m(*_lerp(start, end, t)) < floor - 1e-6:
                low, high = previous, t
                while (high - low) * length > _SEGMENT_RESOLUTION_M:
                    mid = (low + high) / 2
                    if self.margin_m(*_lerp(start, end, mid)) < floor - 1e-6:
                        high = mid
                    else:
                        low = mid
                return low
            previous = t
        return None

    def clamp(self, start: Point2, target: Point2, margin_m: float) -> Point2 | None:
        """Where a vehicle at ``start`` may be sent instead of ``target``.

        The target itself when it and the straight line to it stay ``margin_m`` inside;
        otherwise the target moved to the nearest point that is, and then cut where the
        line from ``start`` would leave the fence. None when no such point is found
        (the caller then refuses the target).
        """
        goal = target
        if self.margin_m(*goal) < margin_m:
            moved = self.nearest_inside(*goal, margin_m)
            if moved is None:
                return None
            goal = moved
        cut = self.leaves_at(start, goal, margin_m)
        if cut is not None:
            goal = _lerp(start, goal, cut)
        return goal

    def _worst_zone(self, north_m: float, east_m: float) -> tuple[Zone, bool] | None:
        worst: tuple[Zone, bool] | None = None
        worst_m = math.inf
        for zone in self.include:
            d = zone.signed_distance_m(north_m, east_m)
            if d < worst_m:
                worst, worst_m = (zone, True), d
        for zone in self.exclude:
            d = -zone.signed_distance_m(north_m, east_m)
            if d < worst_m:
                worst, worst_m = (zone, False), d
        return worst


def _edges(corners: Sequence[Point2]) -> Iterable[tuple[Point2, Point2]]:
    for i, a in enumerate(corners):
        yield a, corners[(i + 1) % len(corners)]


def _lerp(a: Point2, b: Point2, t: float) -> Point2:
    return a[0] + (b[0] - a[0]) * t, a[1] + (b[1] - a[1]) * t


def _project(p: Point2, a: Point2, b: Point2) -> Point2:
    dn, de = b[0] - a[0], b[1] - a[1]
    length2 = dn * dn + de * de
    if length2 < 1e-18:
        return a
    t = max(0.0, min(1.0, ((p[0] - a[0]) * dn + (p[1] - a[1]) * de) / length2))
    return a[0] + dn * t, a[1] + de * t


def _segment_distance_m(p: Point2, a: Point2, b: Point2) -> float:
    q = _project(p, a, b)
    return math.hypot(p[0] - q[0], p[1] - q[1])


def _inside_polygon(north_m: float, east_m: float, corners: Sequence[Point2]) -> bool:
    """Even-odd rule (a ray to the east); a point on an edge is inside."""
    inside = False
    for (n1, e1), (n2, e2) in _edges(corners):
        if _segment_distance_m((north_m, east_m), (n1, e1), (n2, e2)) < 1e-9:
            return True
        if (n1 > north_m) != (n2 > north_m):
            east_at = e1 + (north_m - n1) * (e2 - e1) / (n2 - n1)
            if east_m < east_at:
                inside = not inside
    return inside


def _orientation(a: Point2, b: Point2, c: Point2) -> float:
    return (b[0] - a[0]) * (c[1] - a[1]) - (b[1] - a[1]) * (c[0] - a[0])


def _segments_cross(a: Point2, b: Point2, c: Point2, d: Point2) -> bool:
    """True when segments a-b and c-d cross or touch."""
    o1, o2 = _orientation(a, b, c), _orientation(a, b, d)
    o3, o4 = _orientation(c, d, a), _orientation(c, d, b)
    if (o1 > 0) != (o2 > 0) and (o3 > 0) != (o4 > 0) and 0 not in (o1, o2, o3, o4):
        return True
    return any(
        abs(o) < 1e-12 and _segment_distance_m(p, s, e) < 1e-9
        for o, p, s, e in ((o1, c, a, b), (o2, d, a, b), (o3, a, c, d), (o4, b, c, d))
    )


def _proper_crossing(p: Point2, q: Point2, a: Point2, b: Point2) -> float | None:
    """The fraction along p-q at which it crosses segment a-b, strictly inside both; else None."""
    o1, o2 = _orientation(p, q, a), _orientation(p, q, b)
    o3, o4 = _orientation(a, b, p), _orientation(a, b, q)
    span_pq = max(1.0, abs(q[0] - p[0]) + abs(q[1] - p[1]))
    span_ab = max(1.0, abs(b[0] - a[0]) + abs(b[1] - a[1]))
    eps = 1e-9 * span_pq * span_ab  # orientations scale with both lengths

    def opposite(u: float, v: float) -> bool:
        return (u > eps and v < -eps) or (u < -eps and v > eps)

    if opposite(o1, o2) and opposite(o3, o4):
        return o3 / (o3 - o4)
    return None


def _inward(zone: Zone, edge: Point2, inclusion: bool) -> Point2 | None:
    """The unit direction from a point of ``zone``'s edge into the fence's allowed side."""
    if zone.kind == "circle":
        dn, de = zone.center[0] - edge[0], zone.center[1] - edge[1]
        length = math.hypot(dn, de)
        if length < 1e-9:
            return None
        sign = 1.0 if inclusion else -1.0
        return sign * dn / length, sign * de / length
    # A polygon: probe a little to each side of the edge point along the edge's normal.
    for a, b in _edges(zone.corners):
        if _segment_distance_m(edge, a, b) < 1e-6:
            dn, de = b[0] - a[0], b[1] - a[1]
            length = math.hypot(dn, de)
            if length < 1e-9:
                continue
            normal = (-de / length, dn / length)
            probe = (edge[0] + normal[0] * 0.01, edge[1] + normal[1] * 0.01)
            inside = _inside_polygon(*probe, zone.corners)
            if inside != inclusion:
                normal = (-normal[0], -normal[1])
            return normal
    return None
