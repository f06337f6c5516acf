"""What ``clark validate`` proves of the safety envelope across states and vehicles.

Why separate: :mod:`clark_engine.mission.envelope_checks` checks one primitive's own targets
and legs, called by the primitive; these checks look at a whole mission at once, following
each behaviour (:mod:`clark_engine.mission.flow`): start positions apart and inside the
geofence, the first leg from where a vehicle is known to be, the planned places of two
vehicles, endurance against states and the dry run's length, and the dry run's GPS error
against what the vehicles declare. :func:`clark_engine.mission.cross_checks.run_all` runs
:func:`check_mission`.
"""

from __future__ import annotations

import math
from collections.abc import Iterator, Mapping
from dataclasses import dataclass
from typing import Final

from clark_engine.mission.envelope import Envelope
from clark_engine.mission.envelope_checks import (
    check_leg,
    fence_zones,
    separation_m,
    separation_source,
    side,
)
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
        f"{agent.name} starts {side(zone, by_m)}, so it breaches its geofence before it "
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
