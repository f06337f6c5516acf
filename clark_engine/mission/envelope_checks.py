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

Checks of one primitive's own parameters call :func:`check_point` and
:func:`check_leg` from the primitive (:mod:`clark_engine.behaviors.shared`, and follow_agent's
checks use :func:`possible_heights` and :func:`goal_distance_range`);
:func:`check_mission` checks what spans states and vehicles, and is run by
:func:`clark_engine.mission.cross_checks.run_all`. What cannot be proved (reactive
behaviours) is said once per case as ``W-ENVELOPE-REACTIVE``: the runtime holds the
envelope in flight and the dry run judges it.
"""

from __future__ import annotations

import itertools
import math
from collections.abc import Iterator, Mapping
from dataclasses import dataclass
from typing import Final

from clark_engine.mission.envelope import Envelope
from clark_engine.mission.fence import Fence, Zone
from clark_engine.mission.findings import Finding, Location, error, rehome, warning
from clark_engine.mission.flow import (
    Spot,
    known_entries,
    point_location,
    reachable_leaves,
    start_spot,
    waypoint_label,
    waypoints,
)
from clark_engine.mission.flow import (
    plan as flow_plan,
)
from clark_engine.mission.geo import LocalPoint
from clark_engine.mission.model import Agent, Mission, State
from clark_engine.mission.variation import value_range

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


def _side(zone: FenceZone, by_m: float) -> str:
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
            f"{label} is {_side(zone, by_m)}, where the runtime never sends {agent.name}; "
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


# ----------------------------------------------------------------------------- the mission


def check_mission(mission: Mission) -> Iterator[Finding]:
    """The envelope checks that span states and vehicles."""
    vehicles = [a for a in mission.agents.values() if a.is_vehicle and a.envelope is not None]
    yield from _check_starts(vehicles)
    plans: dict[str, list[_Piece]] = {}
    for agent in vehicles:
        entries = known_entries(agent, mission.origin) if agent.behavior is not None else {}
        yield from _check_start_fence(agent)
        for finding, state in _check_first_legs(mission, agent, entries):
            yield rehome(finding, mission.file, state.mission_use)
        for finding, state in _check_endurance(agent):
            yield rehome(finding, mission.file, state.mission_use)
        plans[agent.name] = _plan(mission, agent, entries)
    yield from _check_duration(mission, vehicles)
    yield from _check_plans(mission, vehicles, plans)
    yield from _check_position_error(mission, vehicles)


WALK_95_FACTOR: Final = math.sqrt(-2.0 * math.log(0.05))
"""A GPS walk of standard deviation ``walk_m`` on each horizontal axis puts a vehicle's
horizontal error (a Rayleigh distribution) within this many ``walk_m`` 95 % of the time:
2.45."""


def _check_position_error(mission: Mission, vehicles: list[Agent]) -> Iterator[Finding]:
    """W-POSITION-ERROR: a dry run whose GPS error is larger than the vehicles declare.

    The runtime keeps each pair's separation plus both vehicles' ``position_error_m`` on
    the positions they report; the dry run judges the separation on the truth, which the
    simulated GPS error (``sim.gps_error``) moves. A vehicle whose figure is smaller than
    the walk's 95 % horizontal error (at the walk's largest draw) may then break its
    separation in a run while its reports keep it. Glitches are not counted: a jump of
    ``glitch_m`` is a fault (ArduPilot's EKF rejects it for a while), not a figure to fly
    every pair that much further apart for. Said once per place where the figure is set
    (or, when no vehicle declares one, at ``sim.gps_error``), naming its vehicles.
    """
    raw = mission.sim.get("gps_error")
    if not isinstance(raw, Mapping) or len(vehicles) < 2:
        return  # no error simulated, or no pair to keep apart
    walk = value_range(raw.get("walk_m", 0.0))
    if walk is None or walk[1] <= 0.0:
        return
    walk_m = walk[1]
    needed_m = math.ceil(WALK_95_FACTOR * walk_m * 10.0) / 10.0
    short: dict[Location | None, list[Agent]] = {}
    for agent in vehicles:
        assert agent.envelope is not None
        if agent.envelope.position_error_m < needed_m:
            short.setdefault(agent.envelope.sources.get("position_error_m"), []).append(agent)
    gps_where = mission.sim_locations.get("gps_error", Location(mission.file))
    drawn = "up to " if walk[0] != walk[1] else ""
    for where, agents in short.items():
        names = ", ".join(a.name for a in agents)
        figures = sorted({a.envelope.position_error_m for a in agents if a.envelope is not None})
        declared = " or ".join(f"{f:g} m" for f in figures)
        yield warning(
            "W-POSITION-ERROR",
            where if where is not None else gps_where,
            f"the dry run's GPS error (sim.gps_error) walks {drawn}{walk_m:g} m on each axis, "
            f"so a reported position is up to {needed_m:g} m from the truth 95 % of the time, "
            f"and {names} declare{'s' if len(agents) == 1 else ''} a position error of {declared} "
            "(envelope.position_error_m): the runtime keeps the separation on reported "
            "positions, and the dry run judges it on the true ones, which may come closer; "
            f"declare envelope.position_error_m: {needed_m:g} (or more)",
            *((gps_where,) if where is not None else ()),
        )


def _position_location(agent: Agent) -> Location:
    return agent.locations.get("position", agent.location)


def _check_starts(vehicles: list[Agent]) -> Iterator[Finding]:
    """No two vehicles start closer than the pair's separation (3-D)."""
    for index, second in enumerate(vehicles):
        for first in vehicles[:index]:
            need = separation_m(first, second)
            if need is None:
                continue
            a, b = first.position, second.position
            distance = math.dist((a.north_m, a.east_m, a.up_m), (b.north_m, b.east_m, b.up_m))
            if distance >= need:
                continue
            unwritten = [v.name for v in (first, second) if "position" not in v.raw]
            why = ""
            if len(unwritten) == 2:
                why = " (neither writes a position:, so both start at the origin)"
            elif unwritten:
                why = f" ({unwritten[0]} writes no position:, so it starts at the origin)"
            yield error(
                "E-SEPARATION-START",
                _position_location(second),
                f"{second.name} starts {distance:.1f} m from {first.name}{why}, closer than the "
                f"{need:g} m the pair keeps apart ({separation_source(first, second)}), so "
                f"they breach it before anything moves; give each its own position: at least "
                f"{need:g} m apart",
                _position_location(first),
            )


def _check_start_fence(agent: Agent) -> Iterator[Finding]:
    """A vehicle starts inside its own geofence."""
    envelope = agent.envelope
    if envelope is None:
        return
    beyond = sorted(
        ((z, z.outside_m(agent.position)) for z in fence_zones(envelope)),
        key=lambda item: -item[1],
    )
    if not beyond or beyond[0][1] <= 0:
        return
    zone, by_m = beyond[0]
    yield error(
        "E-GEOFENCE-POINT",
        _position_location(agent),
        f"{agent.name} starts {_side(zone, by_m)}, so it breaches its geofence before it "
        "moves; start it inside, or change the fence",
        *zone.notes,
    )


def _check_first_legs(
    mission: Mission, agent: Agent, entries: dict[tuple[str, ...], list[Spot]]
) -> Iterator[tuple[Finding, State]]:
    """The leg from where the vehicle is known to be to the first target of a guided state."""
    if agent.behavior is None:
        return
    for state in agent.behavior.walk():
        points = waypoints(state, mission.origin)
        if not points or state.path not in entries:
            continue
        first, param = points[0]
        where = point_location(state, param)
        for spot in entries[state.path]:
            label = f"the leg from {spot.label} to {waypoint_label(state, param)}"
            for finding in check_leg(agent, spot.point, first, where, label, spot.location):
                yield finding, state


def _flies(state: State, aircraft: bool) -> bool:
    """True when the state's behaviour keeps the vehicle moving, so armed, while it runs.

    A hold too, for an aircraft: it hovers or circles (the behaviours' traits say which).
    """
    traits = state.traits
    return traits.flies or (aircraft and traits.flies_if_aircraft)


def _keeps_flying(state: State, aircraft: bool) -> bool:
    """True when the vehicle is armed and moving for as long as ``state`` runs."""
    if state.unresolved:
        return False
    if state.primitive is not None:
        return _flies(state, aircraft)
    leaves = [s for s in state.walk() if s.primitive is not None]
    flying = [s for s in leaves if _flies(s, aircraft)]
    return bool(flying) and all(s in flying or s.traits.takes_pictures for s in leaves)


def _endurance_source(envelope: Envelope) -> str:
    return (
        "envelope.endurance_s"
        if "endurance_s" in envelope.sources
        else "its airframe's endurance_s"
    )


def _check_endurance(agent: Agent) -> Iterator[tuple[Finding, State]]:
    """No state keeps the vehicle flying, by its timeout alone, longer than its endurance."""
    envelope = agent.envelope
    if agent.behavior is None or envelope is None or envelope.endurance_s is None:
        return
    aircraft = agent.airframe_class != "rover"
    endurance = envelope.endurance_s
    for state in agent.behavior.walk():
        if state.timeout_s is None or state.timeout_s <= endurance:
            continue
        if not _keeps_flying(state, aircraft):
            continue
        source = envelope.sources.get("endurance_s")
        yield (
            error(
                "E-ENDURANCE-TIMEOUT",
                state.timeout_location or state.location,
                f"state {state.dotted} may keep {agent.name} going for {state.timeout_s:g} s "
                f"({state.timeout_s / 60:.0f} min), longer than its endurance of "
                f"{endurance:g} s ({_endurance_source(envelope)}), so its "
                f"battery runs out first; shorten timeout_s to under {endurance:g} s and "
                "land or return home after it",
                *((source,) if source else ()),
            ),
            state,
        )


def _check_duration(mission: Mission, vehicles: list[Agent]) -> Iterator[Finding]:
    """A dry run longer than an aircraft's endurance lands it."""
    duration = mission.sim_duration_s
    written = mission.sim_locations.get("duration_s")
    for agent in vehicles:
        envelope = agent.envelope
        root = agent.behavior
        if (
            agent.airframe_class == "rover"
            or envelope is None
            or envelope.endurance_s is None
            or root is None
            or duration <= envelope.endurance_s
        ):
            continue
        leaves = reachable_leaves(root)
        if any(s.traits.lands or s.unresolved for s in leaves):
            continue
        airborne = agent.launch is not None and agent.launch.airborne
        if not airborne and not any(s.traits.takes_off for s in leaves):
            continue  # it never leaves the ground
        behavior_at = agent.locations.get("behavior", agent.location)
        length = "sim.duration_s" if written else "the default sim.duration_s"
        yield warning(
            "W-ENDURANCE-DURATION",
            written or behavior_at,
            f"the dry run lasts {duration:g} s ({length}), longer than {agent.name}'s "
            f"endurance of {envelope.endurance_s:g} s ({_endurance_source(envelope)}), and "
            "no state of its behaviour lands it (land, return_home or "
            "terminate), so the runtime will apply its on_breach action "
            f"({envelope.on_breach}) when its time is up; land it in the behaviour, or "
            "shorten sim.duration_s",
            behavior_at,
        )


# ----------------------------------------------------------------------------- the plans


@dataclass(frozen=True, slots=True)
class _Piece:
    """A place or a straight leg a vehicle is planned to be at or fly (heights above origin)."""

    start: tuple[float, float, float]
    end: tuple[float, float, float]
    label: str
    location: Location
    is_start: bool = False
    mission_use: Location | None = None

    @property
    def box(self) -> tuple[tuple[float, ...], tuple[float, ...]]:
        """The piece's bounding box: its lowest and highest corner."""
        return (
            tuple(map(min, self.start, self.end)),
            tuple(map(max, self.start, self.end)),
        )


Box = tuple[tuple[float, ...], tuple[float, ...]]


def _box_gap_m(a: Box, b: Box) -> float:
    """The distance between two bounding boxes (0 when they overlap): a lower bound."""
    gaps = (
        max(0.0, lo_b - hi_a, lo_a - hi_b) for lo_a, hi_a, lo_b, hi_b in zip(*a, *b, strict=True)
    )
    return math.sqrt(sum(g * g for g in gaps))


def _union(boxes: list[Box]) -> Box:
    return (
        tuple(min(b[0][i] for b in boxes) for i in range(3)),
        tuple(max(b[1][i] for b in boxes) for i in range(3)),
    )


def _xyz(point: LocalPoint, rover: bool) -> tuple[float, float, float]:
    return (point.north_m, point.east_m, 0.0 if rover else point.up_m)


def _plan(
    mission: Mission, agent: Agent, entries: dict[tuple[str, ...], list[Spot]]
) -> list[_Piece]:
    """Where the vehicle is planned to be: its start, its fixed targets, the legs between."""
    rover = agent.airframe_class == "rover"
    start = start_spot(agent)
    here = _xyz(start.point, rover)
    pieces = [_Piece(here, here, "start position", start.location, is_start=True)]
    if agent.behavior is None:
        return pieces
    for state in agent.behavior.walk():
        if state.unresolved:
            continue
        plan = flow_plan(state)
        if plan.climb_to_m is not None:
            for spot in entries.get(state.path, []):
                top = (spot.point.north_m, spot.point.east_m, plan.climb_to_m)
                low = _xyz(spot.point, rover)
                label = f"takeoff of state {state.dotted}" if state.path else "takeoff"
                where = state.use_location or state.location
                pieces.append(_Piece(low, top, label, where, mission_use=state.mission_use))
        points = waypoints(state, mission.origin)
        for index, (point, param) in enumerate(points):
            at = _xyz(point, rover)
            where = point_location(state, param)
            name = waypoint_label(state, param).removeprefix("its ")
            pieces.append(_Piece(at, at, name, where, mission_use=state.mission_use))
            if index + 1 < len(points) or plan.loop:
                nxt, nparam = points[(index + 1) % len(points)]
                leg = f"leg from {name} to {waypoint_label(state, nparam).removeprefix('its ')}"
                pieces.append(
                    _Piece(at, _xyz(nxt, rover), leg, where, mission_use=state.mission_use)
                )
        if points:
            first = _xyz(points[0][0], rover)
            for spot in entries.get(state.path, []):
                leg = f"leg from {spot.label} to {waypoint_label(state, points[0][1])}"
                pieces.append(
                    _Piece(
                        _xyz(spot.point, rover),
                        first,
                        leg,
                        point_location(state, points[0][1]),
                        mission_use=state.mission_use,
                    )
                )
    return pieces


def _check_plans(
    mission: Mission, vehicles: list[Agent], plans: dict[str, list[_Piece]]
) -> Iterator[Finding]:
    """Warn once per pair of vehicles whose planned places or legs come within their separation.

    Bounding boxes (each piece's, and each plan's) skip the pairs that are far apart
    before any distance is worked out: a hundred vehicles are 4950 pairs.
    """
    boxes = {name: [p.box for p in pieces] for name, pieces in plans.items()}
    whole = {name: _union(found) for name, found in boxes.items() if found}
    for index, second in enumerate(vehicles):
        for first in vehicles[:index]:
            need = separation_m(first, second)
            if need is None:
                continue
            a, b = first.position, second.position
            if math.dist((a.north_m, a.east_m, a.up_m), (b.north_m, b.east_m, b.up_m)) < need:
                continue  # they start too close: E-SEPARATION-START says so
            if second.name not in whole or first.name not in whole:
                continue
            if _box_gap_m(whole[second.name], whole[first.name]) >= need:
                continue  # their plans are apart everywhere
            mine_all, mine_boxes = plans[second.name], boxes[second.name]
            theirs_all, theirs_boxes = plans[first.name], boxes[first.name]
            closest: tuple[float, _Piece, _Piece] | None = None
            for mine, mine_box in zip(mine_all, mine_boxes, strict=True):
                for theirs, theirs_box in zip(theirs_all, theirs_boxes, strict=True):
                    if mine.is_start and theirs.is_start:
                        continue  # E-SEPARATION-START's
                    bound = need if closest is None else min(need, closest[0])
                    if _box_gap_m(mine_box, theirs_box) >= bound:
                        continue
                    d = _segment_distance_m(mine.start, mine.end, theirs.start, theirs.end)
                    if closest is None or d < closest[0]:
                        closest = (d, mine, theirs)
            if closest is None or closest[0] >= need:
                continue
            d, mine, theirs = closest
            yield rehome(
                warning(
                    "W-SEPARATION-PLAN",
                    mine.location,
                    f"{second.name}'s {mine.label} comes within {d:.1f} m of {first.name}'s "
                    f"{theirs.label}, closer than the {need:g} m the pair keeps apart "
                    f"({separation_source(first, second)}): if both are there at once they "
                    "break the separation; the dry run judges whether they are (its report "
                    "gives every pair's closest approach); move one of them apart if they "
                    "may be",
                    theirs.location,
                ),
                mission.file,
                mine.mission_use,
            )


def _segment_distance_m(
    p1: tuple[float, float, float],
    q1: tuple[float, float, float],
    p2: tuple[float, float, float],
    q2: tuple[float, float, float],
) -> float:
    """The shortest 3-D distance between segments p1-q1 and p2-q2 (points are segments too).

    The closest points are found on each segment's parameter (clamped to 0..1), the
    textbook way (Ericson, Real-Time Collision Detection, 5.1.9).
    """
    d1 = (q1[0] - p1[0], q1[1] - p1[1], q1[2] - p1[2])
    d2 = (q2[0] - p2[0], q2[1] - p2[1], q2[2] - p2[2])
    r = (p1[0] - p2[0], p1[1] - p2[1], p1[2] - p2[2])
    a = d1[0] * d1[0] + d1[1] * d1[1] + d1[2] * d1[2]
    e = d2[0] * d2[0] + d2[1] * d2[1] + d2[2] * d2[2]
    f = d2[0] * r[0] + d2[1] * r[1] + d2[2] * r[2]
    if a < 1e-12 and e < 1e-12:
        s = t = 0.0
    elif a < 1e-12:
        s, t = 0.0, min(max(f / e, 0.0), 1.0)
    else:
        c = d1[0] * r[0] + d1[1] * r[1] + d1[2] * r[2]
        if e < 1e-12:
            s, t = min(max(-c / a, 0.0), 1.0), 0.0
        else:
            b = d1[0] * d2[0] + d1[1] * d2[1] + d1[2] * d2[2]
            denom = a * e - b * b
            s = min(max((b * f - c * e) / denom, 0.0), 1.0) if denom > 1e-12 else 0.0
            t = (b * s + f) / e
            if t < 0.0:
                s, t = min(max(-c / a, 0.0), 1.0), 0.0
            elif t > 1.0:
                s, t = min(max((b - c) / a, 0.0), 1.0), 1.0
    return math.dist(
        (p1[0] + s * d1[0], p1[1] + s * d1[1], p1[2] + s * d1[2]),
        (p2[0] + t * d2[0], p2[1] + t * d2[1], p2[2] + t * d2[2]),
    )
