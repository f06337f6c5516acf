"""What ``clark validate`` proves about the safety envelope before anything flies.

The envelope as written is checked where it is read (:mod:`.envelope`); this module
checks what the behaviours ask of it, wherever that can be decided from the mission
alone:

- a fixed target (a waypoint, a tour point, a takeoff height) inside its vehicle's
  envelope: under the ceiling, over the floor in guided flight, inside the geofence,
  and far enough inside that the runtime, which keeps every target ``margin_m`` in,
  sends it where it was written (a fixed-wing aircraft circles its target, so it needs
  its circle's radius more);
- every straight leg a vehicle is known to fly (from one tour point to the next, from
  its start to its first target) inside the geofence and clear of its exclusion zones;
- vehicles apart: start positions at least the pair's separation apart, and a warning
  where the planned points and legs of two vehicles come closer (whether both are
  there at once is the dry run's to judge);
- endurance: no state keeps a vehicle flying longer than it can, and a dry run longer
  than an aircraft's endurance lands it.

This module holds the checks of one primitive's own targets and legs: the primitives call
:func:`check_point` and :func:`check_leg` (:mod:`clark_engine.behaviors.shared`, and
follow_agent's checks use :func:`possible_heights` and :func:`goal_distance_range`).
What spans states and vehicles (starts, first legs, plans, endurance, position error) is
:mod:`clark_engine.mission.envelope_mission_checks`'s, whose
:func:`~clark_engine.mission.envelope_mission_checks.check_mission`
:func:`clark_engine.mission.cross_checks.run_all` runs. What cannot be proved (reactive
behaviours) is said once per case as ``W-ENVELOPE-REACTIVE``: the runtime holds the
envelope in flight and the dry run judges it.
"""

from __future__ import annotations

import itertools
import math
from collections.abc import Iterator
from dataclasses import dataclass

from clark_engine.mission.envelope import Envelope
from clark_engine.mission.fence import Fence, Zone
from clark_engine.mission.findings import Finding, Location, error, warning
from clark_engine.mission.flow import (
    reachable_leaves,
)
from clark_engine.mission.geo import LocalPoint
from clark_engine.mission.model import Agent

# ----------------------------------------------------------------------------- zones


@dataclass(frozen=True, slots=True)
class FenceZone:
    """One zone of a vehicle's geofence, with how a message names it and where it was written.

    Attributes:
        zone: The zone on the local plane.
        inclusion: True for a zone the vehicle must stay in, False for one it must keep out of.
        name: How a message names it ("the inclusion polygon envelope.geofence.include[0]").
        location: Where it was written; None for the default circle around home.
    """

    zone: Zone
    inclusion: bool
    name: str
    location: Location | None

    def outside_m(self, point: LocalPoint) -> float:
        """How far the point is on the wrong side of this zone's edge (negative: right side)."""
        inside = self.zone.signed_distance_m(point.north_m, point.east_m)
        return -inside if self.inclusion else inside

    @property
    def notes(self) -> tuple[Location, ...]:
        """The zone's place, as a finding's note."""
        return (self.location,) if self.location is not None else ()


def fence_zones(envelope: Envelope) -> list[FenceZone]:
    """Every zone of the envelope's geofence, the default circle around home included."""
    zones: list[FenceZone] = []
    if envelope.default_radius_m is not None:
        home = envelope.home
        zones.append(
            FenceZone(
                Zone.circle((home.north_m, home.east_m), envelope.default_radius_m),
                True,
                f"its default geofence, the {envelope.default_radius_m:.0f} m circle around "
                "its start",
                None,
            )
        )
    for declared, inclusion in [(z, True) for z in envelope.include] + [
        (z, False) for z in envelope.exclude
    ]:
        side = "inclusion" if inclusion else "exclusion"
        zones.append(
            FenceZone(
                declared.zone,
                inclusion,
                f"the {side} {declared.zone.kind} {declared.location.dotted_path}",
                declared.location,
            )
        )
    return zones


def _worst(envelope: Envelope, point: LocalPoint) -> tuple[FenceZone, float]:
    """The zone whose edge the point is nearest (or furthest beyond), and its margin there."""
    zones = fence_zones(envelope)
    worst = min(zones, key=lambda z: -z.outside_m(point))
    return worst, -worst.outside_m(point)


def side(zone: FenceZone, by_m: float) -> str:
    """How far and on which side of ``zone``'s edge a point ``by_m`` beyond it is, in words."""
    if zone.inclusion:
        return f"{by_m:.1f} m outside {zone.name}"
    return f"{by_m:.1f} m inside {zone.name}"


# ----------------------------------------------------------------------------- points


def check_point(
    agent: Agent,
    point: LocalPoint,
    where: Location,
    label: str,
    use_location: Location,
    *,
    orbit_m: float | None = None,
) -> Iterator[Finding]:
    """A guided target inside its vehicle's envelope, far enough in to be sent as written.

    The ceiling itself, and heights below the origin, are
    :func:`~clark_engine.behaviors.shared.check_ceiling`'s; the floor is
    :func:`check_floor`'s, the margins :func:`check_height_margin`'s, the geofence
    :func:`check_fence_point`'s.

    Args:
        agent: The vehicle.
        point: The target (heights above the origin).
        where: Where the target was written.
        label: What it is, as the message names it ("waypoint 2").
        use_location: The ``use:`` of the state (a note).
        orbit_m: The radius a fixed-wing aircraft circles the target at; None for others.
    """
    yield from check_floor(agent, point.up_m, where, label, use_location)
    yield from check_height_margin(agent, point.up_m, where, label, use_location, guided=True)
    yield from check_fence_point(agent, point, where, label, use_location, orbit_m=orbit_m)


def check_floor(
    agent: Agent, up_m: float, where: Location, label: str, use_location: Location
) -> Iterator[Finding]:
    """An aircraft's guided target is not under its floor (a rover's heights are ignored).

    Heights below the origin are left to ``check_ceiling``, which says so.
    """
    envelope = agent.envelope
    if envelope is None or agent.airframe_class == "rover" or not 0 <= up_m < envelope.floor_m:
        return
    floor_at = envelope.sources.get("floor_m")
    yield error(
        "E-ALTITUDE-FLOOR",
        where,
        f"{label} is {up_m:g} m above the origin, under {agent.name}'s floor of "
        f"{envelope.floor_m:g} m, which holds in guided flight; fly it at least "
        f"{envelope.floor_m + envelope.margin_m:g} m up (the floor plus envelope.margin_m), "
        "or lower the floor",
        use_location,
        *((floor_at,) if floor_at else ()),
    )


def check_height_margin(
    agent: Agent,
    up_m: float,
    where: Location,
    label: str,
    use_location: Location,
    *,
    guided: bool,
) -> Iterator[Finding]:
    """An aircraft's target height is not within ``margin_m`` of its ceiling (or floor).

    The runtime keeps every target ``margin_m`` inside the envelope, so a height nearer
    an edge is sent short of where it was written. The floor holds only in guided
    flight (``guided``); a takeoff climbs through it.
    """
    envelope = agent.envelope
    if envelope is None or agent.airframe_class == "rover":
        return
    margin = envelope.margin_m
    if envelope.ceiling_m - margin < up_m <= envelope.ceiling_m:
        ceiling_at = envelope.sources.get("ceiling_m")
        yield warning(
            "W-ENVELOPE-MARGIN",
            where,
            f"{label} is {up_m:g} m above the origin, within envelope.margin_m {margin:g} m "
            f"of {agent.name}'s ceiling of {envelope.describe_ceiling()}; the runtime "
            f"sends it at {envelope.ceiling_m - margin:g} m, so the vehicle stops short "
            f"of it; fly it at most {envelope.ceiling_m - margin:g} m up",
            use_location,
            *((ceiling_at,) if ceiling_at else ()),
        )
    elif guided and envelope.floor_m <= up_m < envelope.floor_m + margin:
        floor_at = envelope.sources.get("floor_m")
        yield warning(
            "W-ENVELOPE-MARGIN",
            where,
            f"{label} is {up_m:g} m above the origin, within envelope.margin_m {margin:g} m "
            f"of {agent.name}'s floor of {envelope.floor_m:g} m; the runtime sends it at "
            f"{envelope.floor_m + margin:g} m, so the vehicle stops short of it; fly it at "
            f"least {envelope.floor_m + margin:g} m up",
            use_location,
            *((floor_at,) if floor_at else ()),
        )


def check_fence_point(
    agent: Agent,
    point: LocalPoint,
    where: Location,
    label: str,
    use_location: Location,
    *,
    orbit_m: float | None = None,
) -> Iterator[Finding]:
    """A target inside its vehicle's geofence, and far enough inside to be sent as written.

    Outside a zone is an error naming the zone. The runtime keeps targets ``margin_m``
    inside, so one nearer the edge is warned about; a fixed-wing aircraft circles its
    target ``orbit_m`` away, so one nearer the edge than that plus the margin is an
    error (its circle would cross the fence).
    """
    envelope = agent.envelope
    if envelope is None:
        return
    margin = envelope.margin_m
    outside = [(z, z.outside_m(point)) for z in fence_zones(envelope)]
    beyond = sorted((item for item in outside if item[1] > 0), key=lambda item: -item[1])
    if beyond:
        zone, by_m = beyond[0]
        yield error(
            "E-GEOFENCE-POINT",
            where,
            f"{label} is {side(zone, by_m)}, where the runtime never sends {agent.name}; "
            + (
                "move it inside the fence, or change the fence"
                if zone.location is not None
                else "move it closer, or declare a geofence of your own in envelope.geofence"
            ),
            use_location,
            *(loc for z, _ in beyond for loc in z.notes),
        )
        return
    zone, inside_m = _worst(envelope, point)
    if orbit_m is not None and inside_m < orbit_m + margin:
        yield error(
            "E-ORBIT-FENCE",
            where,
            f"{label} is only {inside_m:.1f} m from the edge of {zone.name}, and {agent.name}, "
            f"a fixed-wing aircraft, circles its target about {orbit_m:.0f} m away, so its "
            f"circle would cross the geofence; move the target at least "
            f"{math.ceil(orbit_m + margin)} m inside the fence (its circle plus "
            "envelope.margin_m), or widen the fence",
            use_location,
            *zone.notes,
        )
    elif inside_m < margin:
        yield warning(
            "W-ENVELOPE-MARGIN",
            where,
            f"{label} is only {inside_m:.1f} m from the edge of {zone.name}, within "
            f"envelope.margin_m {margin:g} m; the runtime keeps targets that far inside, so "
            f"the vehicle stops short of it; move it at least {margin:g} m inside",
            use_location,
            *zone.notes,
        )


def check_leg(
    agent: Agent,
    start: LocalPoint,
    end: LocalPoint,
    where: Location,
    label: str,
    *related: Location,
) -> Iterator[Finding]:
    """A straight leg between two targets inside the fence stays inside it all the way.

    A vehicle flies straight to its next target, and the runtime cuts a target short
    where the line to it would leave the fence, so a leg that leaves the fence (a
    concave polygon's corner) or crosses an exclusion zone stops the vehicle at the
    edge and the target is never reached. Legs with an end outside the fence are left to
    that end's own error. Both the exact crossing of each zone's edge and the fence's
    own sampled :meth:`~clark_engine.mission.fence.Fence.leaves_at` are asked.

    Args:
        agent: The vehicle.
        start: Where the leg starts.
        end: The target it flies to.
        where: Where the end was written (the place to change).
        label: The leg, as the message names it ("the leg from waypoint 1 to waypoint 2").
        related: Other places to note (where the start was written).
    """
    envelope = agent.envelope
    if envelope is None:
        return
    a, b = (start.north_m, start.east_m), (end.north_m, end.east_m)
    length = math.hypot(b[0] - a[0], b[1] - a[1])
    fence = envelope.fence()
    if length < 1e-6 or not fence.contains(*a) or not fence.contains(*b):
        return
    first: tuple[float, FenceZone] | None = None
    for zone in fence_zones(envelope):
        alone = Fence((zone.zone,), ()) if zone.inclusion else Fence((), (zone.zone,))
        crossings = (zone.zone.first_crossing(a, b), alone.leaves_at(a, b))
        found = [t for t in crossings if t is not None]
        if found and (first is None or min(found) < first[0]):
            first = (min(found), zone)
    if first is None:
        return
    t, zone = first
    how = "leaves" if zone.inclusion else "crosses"
    yield error(
        "E-GEOFENCE-LEG",
        where,
        f"{label} {how} {zone.name} {t * length:.0f} m along its {length:.0f} m; "
        f"{agent.name} flies straight to its next target and the runtime stops it at the "
        "fence, so the target is never reached; add a waypoint that goes round, or change "
        "the fence",
        *related,
        *zone.notes,
    )


# ----------------------------------------------------------------------------- follow_agent


def possible_heights(agent: Agent) -> tuple[float, float]:
    """The heights above the origin a vehicle may be at while its behaviour runs.

    A rover is on the ground. An aircraft may be anywhere between its floor and its
    ceiling, and down to the ground while it takes off or lands: unless the pilot hands
    it over in flight and its behaviour never lands it, its lowest height is 0.
    """
    envelope = agent.envelope
    if agent.airframe_class == "rover" or envelope is None:
        return 0.0, 0.0
    airborne = agent.launch is not None and agent.launch.airborne
    lands = agent.behavior is not None and any(
        s.traits.lands or s.traits.takes_off for s in reachable_leaves(agent.behavior)
    )
    low = envelope.floor_m if airborne and not lands else 0.0
    return low, envelope.ceiling_m


def goal_distance_range(
    follower: Agent, target: Agent, offset_m: tuple[float, float, float]
) -> tuple[float, float]:
    """The nearest and furthest a follower's goal can be from its target (3-D).

    The goal is the target's position moved by the offset; a rover's goal is on the
    ground, an aircraft's height is kept within its floor and ceiling (less the margin)
    by the runtime. As the target's height varies over :func:`possible_heights`, the
    vertical gap varies piecewise linearly; its extremes are at the ends and the bends.
    """
    north, east, up = offset_m
    ground = math.hypot(north, east)
    low, high = possible_heights(target)
    envelope = follower.envelope
    rover = follower.airframe_class == "rover"
    bottom = envelope.floor_m + envelope.margin_m if envelope is not None else -math.inf
    top = envelope.ceiling_m - envelope.margin_m if envelope is not None else math.inf

    def gap(height: float) -> float:
        if rover:
            return -height
        return min(max(height + up, bottom), max(top, bottom)) - height

    heights = sorted({low, high, *(h for h in (bottom - up, top - up) if low < h < high)})
    gaps = [gap(h) for h in heights]
    smallest = min(abs(g) for g in gaps)
    if any((g1 < 0 < g2) or (g2 < 0 < g1) for g1, g2 in itertools.pairwise(gaps)):
        smallest = 0.0
    largest = max(abs(g) for g in gaps)
    return math.hypot(ground, smallest), math.hypot(ground, largest)


def vertically_apart(follower: Agent, target: Agent, separation_m: float) -> bool:
    """True when the two vehicles' possible heights never come within ``separation_m``."""
    f_low, f_high = possible_heights(follower)
    envelope = follower.envelope
    if follower.airframe_class != "rover" and envelope is not None:
        f_low, f_high = envelope.floor_m, envelope.ceiling_m
    t_low, t_high = possible_heights(target)
    return max(f_low - t_high, t_low - f_high) >= separation_m


def separation_m(a: Agent, b: Agent) -> float | None:
    """The distance the pair keeps apart (either's figure for the other, the larger)."""
    if a.envelope is None or b.envelope is None:
        return None
    return max(a.envelope.separation_from_m(b.name), b.envelope.separation_from_m(a.name))


def separation_source(a: Agent, b: Agent) -> str:
    """What set the pair's separation, for messages."""
    for one, other in ((a, b), (b, a)):
        if one.envelope is not None and other.name in one.envelope.separation:
            return "its envelope.separation"
    return "envelope.min_separation_m"
