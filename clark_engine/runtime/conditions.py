"""A transition's condition (the schema's ``when``) resolved once into what decides it.

The machine resolves every condition when it is built, so a tick reads no string: this
module turns a condition as the compiled config writes it into a function of the context
and the time in the state. Conditions on another agent (its state, where it is) are
:mod:`~clark_engine.runtime.peer_conditions`'; this module combines them with the rest.
Separate from the runtime because it needs only the config: it keeps no state of the
agent's and is the same for every tick.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping
from typing import Any

from clark_engine.mission.peer_conditions import PEER_CONDITIONS
from clark_engine.runtime.config import AgentConfig
from clark_engine.runtime.context import PrimitiveContext, ground_distance_m
from clark_engine.runtime.machine import Holds
from clark_engine.runtime.peer_conditions import resolve_peer_condition


def resolve_condition(when: Mapping[str, Any], config: AgentConfig) -> Holds:
    """A transition's condition resolved once into what decides it each time.

    Called when the machine is built, so the condition's kind, bounds and agent are
    read once and a tick reads no string: ``all``/``any``/``not`` combine their
    parts; ``mode`` compares the vehicle's mode; ``distance_m`` (to a peer, read by
    the id the peer table gives; loading proved it a peer), ``altitude_m``,
    ``speed_m_s`` and ``in_state_s`` hold while the figure is below ``lt`` and above
    ``gt``, and never while it is unknown; a condition on another agent (its state,
    where it is) is :mod:`~clark_engine.runtime.peer_conditions`', on fresh data only.
    A condition with no key always holds.
    """
    for key, value in when.items():  # exactly one key (the schema's)
        if key in ("all", "any"):
            parts = tuple(resolve_condition(item, config) for item in value)
            if key == "all":
                return lambda ctx, s: all(part(ctx, s) for part in parts)
            return lambda ctx, s: any(part(ctx, s) for part in parts)
        if key == "not":
            inner = resolve_condition(value, config)
            return lambda ctx, s: not inner(ctx, s)
        if key == "mode":
            mode = value["is"]
            return lambda ctx, _s: ctx.vehicle is not None and ctx.vehicle.mode == mode
        if key in PEER_CONDITIONS:  # another agent's state or relative position
            return resolve_peer_condition(key, value, config)
        return _bounded(_measurement(key, value, config), value.get("lt"), value.get("gt"))
    return _always


def _measurement(
    key: str, value: Mapping[str, Any], config: AgentConfig
) -> Callable[[PrimitiveContext, float], float | None]:
    """What a bounded condition measures, None while it is unknown."""
    if key == "in_state_s":
        return _in_state_s
    if key == "distance_m":
        peer = config.peer(str(value["to"]))
        if peer is None:  # loading refuses it; a config built in code may not have
            return _unknown
        peer_id = peer.id

        def distance(ctx: PrimitiveContext, _s: float) -> float | None:
            vehicle = ctx.vehicle
            status = ctx.peer_status_by_id(peer_id)
            if vehicle is None or status is None:
                return None
            return ground_distance_m(
                vehicle.lat_deg, vehicle.lon_deg, status.lat_deg, status.lon_deg
            )

        return distance
    if key == "altitude_m":
        return _altitude_m
    if key == "speed_m_s":
        return _speed_m_s
    return _unknown


def _always(_ctx: PrimitiveContext, _in_state_s: float) -> bool:
    return True


def _unknown(_ctx: PrimitiveContext, _in_state_s: float) -> float | None:
    return None


def _in_state_s(_ctx: PrimitiveContext, in_state_s: float) -> float | None:
    return in_state_s


def _altitude_m(ctx: PrimitiveContext, _in_state_s: float) -> float | None:
    return ctx.vehicle.alt_m if ctx.vehicle is not None else None


def _speed_m_s(ctx: PrimitiveContext, _in_state_s: float) -> float | None:
    return ctx.vehicle.ground_speed_m_s if ctx.vehicle is not None else None


def _bounded(
    measure: Callable[[PrimitiveContext, float], float | None],
    lt: float | None,
    gt: float | None,
) -> Holds:
    """Holds while the measure is known, below ``lt`` and above ``gt`` (each when given)."""

    def holds(ctx: PrimitiveContext, in_state_s: float) -> bool:
        measured = measure(ctx, in_state_s)
        if measured is None:
            return False
        if lt is not None and not measured < lt:
            return False
        return not (gt is not None and not measured > gt)

    return holds
