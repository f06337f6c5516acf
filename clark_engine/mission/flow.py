"""Which states a behaviour may run, in what order, and where its vehicle is when each starts.

Static checks that go beyond one state need to follow the machine: which states a
vehicle starts in, which it can ever reach, and, for the envelope's checks, where it
is known to be when a guided state begins (its start position before it has gone
anywhere, the last waypoint of a tour it finished), so that the straight line it then
flies can be proved inside the geofence. This module answers those questions from the
resolved :class:`~clark_engine.mission.model.State` tree, the way the runtime's machine
moves (:mod:`clark_engine.runtime.machine`): entering a state enters its initial child
(every region of a parallel state), ``done`` and ``timeout`` belong to the state that
raised them, other events are taken by the innermost active state with a transition on
them, and a machine whose child is final is done.

It proves only what always holds and says nothing where the position is unknown (a
state left mid-flight on an external event, a follow, anything the pilot flies): a
check then has no leg to check, never a wrong one.
"""

from __future__ import annotations

from collections.abc import Iterator
from dataclasses import dataclass

from clark_engine.behaviors import Plan, behaviors
from clark_engine.mission.findings import Location
from clark_engine.mission.geo import LocalPoint, Origin, parse_point
from clark_engine.mission.model import Agent, State, Transition


@dataclass(frozen=True, slots=True)
class Spot:
    """A place a vehicle is known to be at when a state begins.

    Attributes:
        point: The place (heights above the origin; a rover's are ignored).
        label: How a message names it ("its start position", "waypoint 3 of state
            survey").
        location: Where the place was written.
    """

    point: LocalPoint
    label: str
    location: Location


def entry_leaves(state: State) -> list[State]:
    """The states without children that entering ``state`` enters (every parallel region's)."""
    if not state.children:
        return [state]
    if state.parallel:
        return [leaf for child in state.children.values() for leaf in entry_leaves(child)]
    first = state.children.get(state.initial or "")
    return entry_leaves(first) if first is not None else []


def _ancestors(root: State, leaf: State) -> list[State]:
    """The states above ``leaf``, innermost first (the root included)."""
    out: list[State] = []
    for depth in range(len(leaf.path) - 1, -1, -1):
        node = root.find(leaf.path[:depth])
        if node is not None:
            out.append(node)
    return out


def exits(root: State, leaf: State) -> Iterator[tuple[Transition, bool]]:
    """Every transition that can take the machine out of ``leaf``.

    Yields (transition, own): ``own`` is True for the leaf's own transitions, False
    for its ancestors' (taken while the leaf is active: their ``done``, their
    ``timeout``, and external events the leaf has no transition for).
    """
    for transition in leaf.transitions:
        yield transition, True
    for ancestor in _ancestors(root, leaf):
        for transition in ancestor.transitions:
            yield transition, False


def _targets(root: State, transition: Transition) -> list[State]:
    target = root.find(transition.target) if transition.target else None
    return entry_leaves(target) if target is not None else []


def reachable_leaves(root: State) -> list[State]:
    """Every state without children that the behaviour can ever be in, in walk order."""
    seen: dict[tuple[str, ...], State] = {}
    pending = entry_leaves(root)
    while pending:
        leaf = pending.pop()
        if leaf.path in seen:
            continue
        seen[leaf.path] = leaf
        for transition, _own in exits(root, leaf):
            pending.extend(_targets(root, transition))
    return [s for s in root.walk() if s.path in seen]


def point_location(state: State, param: str) -> Location:
    """Where a primitive's parameter (``to``, ``waypoints[2]``) was written."""
    base = param.split("[", 1)[0]
    fallback = state.use_location or state.location
    return state.param_locations.get(param) or state.param_locations.get(base) or fallback


def plan(state: State) -> Plan:
    """What the state's behaviour plans (its fixed targets, a climb); nothing when unknown."""
    if state.unresolved or state.primitive is None:
        return Plan()
    found = behaviors().get(state.primitive)
    return found.plan(state.params) if found is not None else Plan()


def waypoints(state: State, origin: Origin) -> list[tuple[LocalPoint, str]]:
    """The fixed targets of a state's behaviour, in order: (point, parameter)."""
    return [(parse_point(raw, origin), param) for raw, param in plan(state).points]


def waypoint_label(state: State, param: str) -> str:
    """How a message names a waypoint parameter of a state ("waypoint 2 of state survey")."""
    where = f" of state {state.dotted}" if state.path else ""
    if param == "to":
        return f"waypoint{where}" if where else "its waypoint"
    if not param.startswith("waypoints["):  # another behaviour's points (an orbit's circle)
        return f"a point round its {param}{where}"
    return f"waypoint {param[len('waypoints[') : -1]}{where}"


def start_spot(agent: Agent) -> Spot:
    """Where the vehicle starts: its ``position:`` (the origin when it writes none)."""
    return Spot(
        agent.position,
        "its start position",
        agent.locations.get("position", agent.location),
    )


def known_entries(agent: Agent, origin: Origin) -> dict[tuple[str, ...], list[Spot]]:
    """For each state without children, the places the vehicle is known to enter it at.

    The vehicle enters its first states at its start. It stays over the spot it
    entered a takeoff, hold or land at (and a wait, unless the pilot flies it:
    ``launch.airborne``); it is at a waypoint state's point, or a tour's last one, when
    that state is done; it is home (its start, for a vehicle armed on the ground) when
    return_home is done. Anything else leaves its position unknown, and no place is
    passed on.
    """
    root = agent.behavior
    if root is None:
        return {}
    airborne = agent.launch is not None and agent.launch.airborne
    entries: dict[tuple[str, ...], dict[tuple[str, float, float, float], Spot]] = {}
    by_path: dict[tuple[str, ...], State] = {}
    pending: list[State] = []

    def add(leaf: State, spot: Spot) -> None:
        key = (spot.label, spot.point.north_m, spot.point.east_m, spot.point.up_m)
        known = entries.setdefault(leaf.path, {})
        by_path[leaf.path] = leaf
        if key not in known:
            known[key] = spot
            pending.append(leaf)

    start = start_spot(agent)
    for leaf in entry_leaves(root):
        add(leaf, start)
    while pending:
        leaf = pending.pop()
        here = list(entries[leaf.path].values())
        traits = leaf.traits
        still = (
            leaf.primitive is None
            or traits.stays_put
            or (traits.stays_put_on_ground and not airborne)
        )
        during = here if still else []
        done = during
        planned = plan(leaf)
        points = waypoints(leaf, origin)
        if points and not planned.loop:
            point, param = points[-1]
            done = [Spot(point, waypoint_label(leaf, param), point_location(leaf, param))]
        elif traits.home_when_done and not airborne:
            done = [start]
        elif planned.climb_to_m is not None:
            alt_m = planned.climb_to_m
            done = [
                Spot(
                    LocalPoint(s.point.north_m, s.point.east_m, alt_m),
                    f"{s.label}, {alt_m:g} m up after its takeoff,",
                    s.location,
                )
                for s in here
            ]
        for transition, own in exits(root, leaf):
            passed = done if own and transition.event == "done" else during
            for target in _targets(root, transition):
                for spot in passed:
                    add(target, spot)
    return {path: list(spots.values()) for path, spots in entries.items()}
