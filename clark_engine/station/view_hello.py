"""The ``hello`` message: what does not change during a run, sent to a page first.

Separate from the live state because it is built once, from compiled configs alone (the
live view from the station's, the replay from the mission's): the mission, every agent
(name, id, role, airframe class, the modes its profile allows, how often it sends its
heartbeat, its envelope) and the mission's plan in metres north and east of the origin
(each vehicle's waypoints and tours, any other point in its primitives' parameters; a
tour that runs beside a ``photo_trigger`` is a survey line).

Stale and lost (docs/station-view.md, "Stale and lost"): an agent is *lost* when the
fleet table says so (silent for longer than ``mission.heartbeat_timeout_s``); it is
*stale* when it is not lost and silent for longer than :func:`stale_after_s`, which the
hello carries for each agent.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any, Final

from clark_engine.behaviors import Plan, behaviors
from clark_engine.mission.fence import Zone
from clark_engine.mission.geo import Origin, parse_point
from clark_engine.runtime.config import AgentConfig, EnvelopeSpec, StateSpec
from clark_engine.station.view_commands import answer_timeout_s
from clark_engine.station.view_protocol import ACTIONS, PROTOCOL_VERSION, Json, rounded

STALE_HEARTBEATS: Final = 1.5
"""An agent silent for this many of its heartbeat periods is stale (one missed, plus jitter)."""

UNSETTABLE_MODES: Final = frozenset({"INITIALISING"})
"""Modes an autopilot reports but never accepts as a request (ArduPilot's boot mode)."""


def stale_after_s(heartbeat_hz: float | None, heartbeat_timeout_s: float) -> float:
    """Silence after which an agent that is not lost is shown as stale.

    One and a half heartbeat periods (a heartbeat missed, with room for jitter), at most
    half the mission's heartbeat timeout (so *stale* always comes well before *lost*).
    Without a known heartbeat rate: half the timeout.
    """
    half = heartbeat_timeout_s / 2
    if not heartbeat_hz or heartbeat_hz <= 0:
        return half
    return min(STALE_HEARTBEATS / heartbeat_hz, half)


def origin_of(config: AgentConfig) -> Origin:
    """The mission's origin, as a compiled config gives it."""
    return Origin(config.origin_lat_deg, config.origin_lon_deg, config.origin_alt_amsl_m)


# -- hello: the mission, its agents and its plan ---------------------------------------------


def _is_point(value: object) -> bool:
    """A compiled absolute point: north/east metres and latitude/longitude both given.

    The compiler writes every point of a primitive's parameters in both frames
    (``clark_engine.mission.compiler._point``); relative offsets (``follow_agent``'s
    ``offset``) have no latitude, and are not positions.
    """
    return isinstance(value, Mapping) and {"north_m", "east_m", "lat", "lon"} <= value.keys()


def _local(value: Any, origin: Origin) -> Json:
    point = parse_point(value, origin)
    return {
        "north_m": rounded(point.north_m),
        "east_m": rounded(point.east_m),
        "up_m": rounded(point.up_m),
    }


def _points_in(value: Any) -> list[Any]:
    """Every compiled absolute point inside a parameter value, in order."""
    if _is_point(value):
        return [value]
    if isinstance(value, Mapping):
        return [p for item in value.values() for p in _points_in(item)]
    if isinstance(value, list | tuple):
        return [p for item in value for p in _points_in(item)]
    return []


def _runs_photos(state: StateSpec) -> bool:
    return state.traits.takes_pictures or any(_runs_photos(s) for s in state.states)


def plan_of(config: AgentConfig) -> list[Json]:
    """One vehicle's plan in metres from the origin: its tours, waypoints and other points.

    Each item names the state it belongs to (its dotted path) and its primitive:

    - ``{"kind": "tour", "points": [...], "loop": bool, "survey": bool}`` for a
      ``waypoint_tour`` or a ``survey``; ``survey`` when it takes pictures itself or a
      ``photo_trigger`` runs beside it in a parallel state (a survey line: pictures are
      taken along it);
    - ``{"kind": "waypoint", "points": [one]}`` for a ``waypoint``;
    - ``{"kind": "points", "points": [...]}`` for any point in another primitive's
      parameters.
    """
    if config.machine is None:
        return []
    origin = origin_of(config)
    items: list[Json] = []

    def visit(state: StateSpec, photos_beside: bool) -> None:
        if state.primitive is not None:
            params = state.params
            base: Json = {"state": state.path or "(behavior)", "primitive": state.primitive}
            behavior = behaviors().get(state.primitive)
            plan = behavior.plan(params) if behavior is not None else Plan()
            if plan.kind == "route" and plan.points:
                items.append(
                    {
                        **base,
                        "kind": "tour",
                        "points": [_local(p, origin) for p, _param in plan.points],
                        "loop": plan.loop,
                        "survey": photos_beside or state.traits.takes_pictures,
                    }
                )
            elif plan.kind == "target" and plan.points:
                items.append(
                    {
                        **base,
                        "kind": "waypoint",
                        "points": [_local(p, origin) for p, _ in plan.points],
                    }
                )
            else:
                found = _points_in(params)
                if found:
                    items.append(
                        {**base, "kind": "points", "points": [_local(p, origin) for p in found]}
                    )
        for child in state.states:
            beside = photos_beside or (
                state.parallel
                and any(_runs_photos(other) for other in state.states if other is not child)
            )
            visit(child, beside)

    visit(config.machine, False)
    return items


def _zone_json(zone: Zone) -> Json:
    if zone.kind == "circle":
        return {
            "kind": "circle",
            "center": {"north_m": rounded(zone.center[0]), "east_m": rounded(zone.center[1])},
            "radius_m": rounded(zone.radius_m),
        }
    return {
        "kind": "polygon",
        "points": [{"north_m": rounded(n), "east_m": rounded(e)} for n, e in zone.corners],
    }


def envelope_json(envelope: EnvelopeSpec | None) -> Json | None:
    """A vehicle's envelope as the page draws it: its zones in metres from the origin.

    ``include`` holds the default circle around home when the mission declared no
    inclusion zone (``default_radius_m`` says so); the page draws a vehicle's zones in its
    colour and names its ceiling in its row.
    """
    if envelope is None:
        return None
    return {
        "ceiling_m": rounded(envelope.ceiling_m),
        "floor_m": rounded(envelope.floor_m),
        "margin_m": rounded(envelope.margin_m),
        "min_separation_m": rounded(envelope.min_separation_m),
        "separation": {name: rounded(m) for name, m in sorted(envelope.separation.items())},
        "default_radius_m": rounded(envelope.default_radius_m),
        "include": [_zone_json(z) for z in envelope.fence.include],
        "exclude": [_zone_json(z) for z in envelope.fence.exclude],
        "on_breach": envelope.on_breach,
        "on_near_miss": envelope.on_near_miss,
    }


def _settable_modes(modes: Mapping[str, int]) -> list[Json]:
    return [
        {"name": name, "number": int(number)}
        for name, number in sorted(modes.items(), key=lambda item: (item[1], item[0]))
        if name not in UNSETTABLE_MODES
    ]


def build_hello(
    station: AgentConfig,
    fleet: Mapping[str, AgentConfig] | None = None,
    *,
    plan_source: str = "",
    update_hz: float | None = None,
) -> Json:
    """The ``hello`` message: the mission, its agents and its plan.

    Args:
        station: The station's compiled config (its peer table names every agent with
            its id, role and modes).
        fleet: Every agent's compiled config by name, when known (from the mission file,
            or the compiled configs beside the station's): the airframes, start
            positions and plans come from them. Without it the agents are listed with
            what the station's config says, and the plan is empty.
        plan_source: Where the fleet's configs came from, in words, for the page.
        update_hz: The rate at which ``state`` messages are sent.
    """
    fleet = dict(fleet or {})
    origin = origin_of(station)
    agents: list[Json] = []
    plans: dict[str, list[Json]] = {}
    for peer in station.peers:
        config = fleet.get(peer.name)
        position = ((config.raw.get("agent") or {}).get("position")) if config else None
        heartbeat_hz = peer.sends.get("heartbeat")
        agents.append(
            {
                "name": peer.name,
                "id": peer.id,
                "role": peer.role,
                "airframe": config.airframe_class if config is not None else None,
                "modes": _settable_modes(peer.modes),
                "heartbeat_hz": heartbeat_hz,
                "stale_after_s": rounded(
                    stale_after_s(heartbeat_hz, station.heartbeat_timeout_s), 3
                ),
                "home": _local(position, origin) if position else None,
                "envelope": envelope_json(peer.envelope),
            }
        )
        if config is not None and config.is_vehicle:
            plans[peer.name] = plan_of(config)
    own_position = (station.raw.get("agent") or {}).get("position")
    return {
        "type": "hello",
        "protocol": PROTOCOL_VERSION,
        "mission": {
            "name": station.mission_name,
            "id": station.mission_id,
            "description": (station.raw.get("mission") or {}).get("description"),
            "origin": {
                "lat": station.origin_lat_deg,
                "lon": station.origin_lon_deg,
                "alt_amsl_m": station.origin_alt_amsl_m,
            },
            "loop_hz": station.loop_hz,
            "heartbeat_timeout_s": station.heartbeat_timeout_s,
            "authenticated": station.authenticated,
        },
        "station": {
            "name": station.agent,
            "id": station.agent_id,
            "home": _local(own_position, origin) if own_position else None,
        },
        "agents": agents,
        "plan": plans,
        "plan_source": plan_source if fleet else "",
        "answer_timeout_s": answer_timeout_s(station.heartbeat_timeout_s),
        "update_hz": update_hz,
        "actions": list(ACTIONS),
    }


__all__ = ["build_hello", "envelope_json", "origin_of", "plan_of", "stale_after_s"]
