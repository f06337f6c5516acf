"""Conditions on another agent, resolved once into closures that read the fleet table.

``agent_state`` holds while another agent's behaviour is in a state; ``ahead_m``,
``behind_m``, ``above_m`` and ``within_m`` compare where it is with where this agent is.
Each is resolved when the machine is built: the peer's name becomes its id, the state
path a string to compare with, the bounds numbers, and the staleness bound is worked out
from the rate the peer declares sending the message to this agent. A tick then reads the
peer's record by id and looks nothing up by name.

What a peer sends is hostile: its state paths are only compared (equal, or a descendant
by prefix), never interpreted, and their size is bounded by the packet's. A peer's data
counts only while it is fresh: a condition on a peer never holds while its record is
lost (no heartbeat for ``heartbeat_timeout_s``) or its last message of the kind the
condition reads is older than :data:`STALE_PERIODS` of the periods it declared, so a lost
peer never satisfies a condition.

Geometry (docs/runtime.md, "Conditions on other agents"): offsets are metres north and
east on the local tangent plane at the two positions (the equirectangular approximation of
:func:`~clark_engine.runtime.context.ground_distance_m`, exact to well under a metre over
the kilometres a condition compares). *Ahead* is along this agent's heading as its
runtime knows it (its course over ground while it moves at 0.5 m/s or more, where its
nose points below that), or along a fixed ``bearing_deg``; *behind* is the opposite.
*Above* compares both agents' altitudes above the mission origin (one datum: each
vehicle's own reports, converted by its runtime). *Within* is the straight-line distance,
ground distance and height difference together.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping
from typing import Any, Final

from clark_engine.link.messages import AgentStatus, BehaviorState
from clark_engine.mission.peer_conditions import ALWAYS_EVENT, PEER_CONDITIONS
from clark_engine.runtime.config import AgentConfig, StateSpec
from clark_engine.runtime.context import EARTH_RADIUS_M, PrimitiveContext
from clark_engine.runtime.events import VehicleState
from clark_engine.runtime.machine import StateChange

#: A peer's message older than this many of its declared periods is stale: two may be
#: lost in a row (a bad spell of the radio) and the condition still decides on the third.
STALE_PERIODS: Final = 3.0

#: What a condition decides with: the agent's context and the time in the state.
Holds = Callable[[PrimitiveContext, float], bool]
#: A figure between this agent and a peer's last status; None while either is unknown.
_Measure = Callable[[VehicleState, AgentStatus], float]


def stale_after_s(rate_hz: float) -> float:
    """Age beyond which a message sent at ``rate_hz`` no longer counts (3 periods)."""
    return STALE_PERIODS / rate_hz


def resolve_peer_condition(key: str, value: Mapping[str, Any], config: AgentConfig) -> Holds:
    """The closure deciding one condition on another agent, built once.

    Args:
        key: One of :data:`~clark_engine.mission.peer_conditions.PEER_CONDITIONS`.
        value: The condition's body as the compiled config gives it.
        config: This agent's config: the peer table (ids, and the rates each peer sends
            each message to this agent at).

    Returns:
        A closure that never holds when the peer is not in the table or sends this agent
        nothing the condition can read (loading refuses the first, ``clark validate``
        the second; a config built in code may have either).
    """
    peer = config.peer(str(value["agent"]))
    rate_hz = None if peer is None else peer.sends.get(PEER_CONDITIONS[key])
    if peer is None or not rate_hz:
        return _never
    peer_id, stale_s = peer.id, stale_after_s(rate_hz)
    if key == "agent_state":
        return _in_state(peer_id, stale_s, str(value["in"]))
    bearing = value.get("bearing_deg")
    measure: _Measure
    if key == "ahead_m":
        measure = _ahead(bearing, 1.0)
    elif key == "behind_m":
        measure = _ahead(bearing, -1.0)
    elif key == "above_m":
        measure = _above
    else:
        measure = _within
    return _bounded(peer_id, stale_s, measure, value.get("lt"), value.get("gt"))


class AlwaysWatch:
    """Says, each tick, whether an active state's ``always`` transition could be taken.

    The runtime raises ``always`` only when this says so: the state machine library's
    trigger costs about 0.2 ms even when no guard holds (docs/performance.md), seven
    times a whole tick, and a rover waits in such a state for most of a leapfrog. Asking
    first changes nothing the machine decides: when no guard of an active state holds,
    ``dispatch`` takes no transition; when one does, the machine decides which, as ever.

    It follows the machine's changes (:meth:`on_change`, from the runtime's listener) to
    know which states with ``always`` transitions are active and since when, so that a
    guard's ``in_state_s`` is the one the machine gives it.
    """

    def __init__(self, spec: StateSpec, resolve: Callable[[Mapping[str, Any]], Holds]) -> None:
        """Resolve the guard of every ``always`` transition of the behaviour ``spec``, once."""
        self._guards: dict[str, tuple[Holds, ...]] = {}
        self._add(spec, resolve)
        #: Active states with ``always`` transitions -> when they were entered.
        self._entered: dict[str, float] = {}

    def _add(self, spec: StateSpec, resolve: Callable[[Mapping[str, Any]], Holds]) -> None:
        guards = tuple(
            resolve(t.when) if t.when is not None else _always_holds
            for t in spec.transitions
            if t.event == ALWAYS_EVENT
        )
        if guards:
            self._guards[spec.path] = guards
        for child in spec.states:
            self._add(child, resolve)

    @property
    def watching(self) -> bool:
        """Whether the behaviour has any ``always`` transition at all."""
        return bool(self._guards)

    def on_change(self, change: StateChange) -> None:
        """Follow one change of the active states."""
        entered = self._entered
        for path in change.exited:
            entered.pop(path, None)
        for path in change.entered:
            if path in self._guards:
                entered[path] = change.time_s

    def due(self, ctx: PrimitiveContext) -> bool:
        """Whether a guard of an active state's ``always`` transition holds now."""
        now_s = ctx.now_s
        for path, entered_s in self._entered.items():
            for holds in self._guards[path]:
                if holds(ctx, now_s - entered_s):
                    return True
        return False


def _always_holds(_ctx: PrimitiveContext, _in_state_s: float) -> bool:
    return True  # an always transition without when: clark validate refuses it


def _never(_ctx: PrimitiveContext, _in_state_s: float) -> bool:
    return False


def _in_state(peer_id: int, stale_s: float, path: str) -> Holds:
    """Holds while the peer's fresh Behavior State has ``path`` or a descendant active."""
    prefix = path + "."

    def holds(ctx: PrimitiveContext, _in_state_s: float) -> bool:
        record = ctx.fleet.record(peer_id)
        if record is None or record.lost:
            return False
        sample = record.sample(BehaviorState)
        if sample is None or ctx.now_s - sample.received_s > stale_s:
            return False
        return any(a == path or a.startswith(prefix) for a in sample.value.active_states)

    return holds


def _bounded(
    peer_id: int, stale_s: float, measure: _Measure, lt: float | None, gt: float | None
) -> Holds:
    """Holds while the figure is known from fresh data, below ``lt`` and above ``gt``."""

    def holds(ctx: PrimitiveContext, _in_state_s: float) -> bool:
        vehicle = ctx.vehicle
        record = ctx.fleet.record(peer_id)
        if vehicle is None or record is None or record.lost:
            return False
        sample = record.sample(AgentStatus)
        if sample is None or ctx.now_s - sample.received_s > stale_s:
            return False
        figure = measure(vehicle, sample.value)
        if lt is not None and not figure < lt:
            return False
        return not (gt is not None and not figure > gt)

    return holds


def offset_m(
    lat1_deg: float, lon1_deg: float, lat2_deg: float, lon2_deg: float
) -> tuple[float, float]:
    """Metres north and east from the first position to the second (local tangent plane)."""
    mean_lat = math.radians((lat1_deg + lat2_deg) / 2)
    north = math.radians(lat2_deg - lat1_deg) * EARTH_RADIUS_M
    east = math.radians(lon2_deg - lon1_deg) * EARTH_RADIUS_M * math.cos(mean_lat)
    return north, east


def _ahead(bearing_deg: float | None, sign: float) -> _Measure:
    """How far the peer is ahead (``sign`` 1) or behind (-1) along the reference direction."""

    def measure(vehicle: VehicleState, status: AgentStatus) -> float:
        north, east = offset_m(vehicle.lat_deg, vehicle.lon_deg, status.lat_deg, status.lon_deg)
        direction = math.radians(vehicle.heading_deg if bearing_deg is None else bearing_deg)
        return sign * (north * math.cos(direction) + east * math.sin(direction))

    return measure


def _above(vehicle: VehicleState, status: AgentStatus) -> float:
    return status.alt_m - vehicle.alt_m


def _within(vehicle: VehicleState, status: AgentStatus) -> float:
    north, east = offset_m(vehicle.lat_deg, vehicle.lon_deg, status.lat_deg, status.lon_deg)
    return math.sqrt(north * north + east * east + (status.alt_m - vehicle.alt_m) ** 2)
