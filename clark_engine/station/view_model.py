"""What the station's view shows, as JSON-able dicts built from the station's runtime.

Pure: no clock, no socket, no thread. The shell side (:mod:`clark_engine.station.live_view`)
calls :meth:`StationView.observe` after every tick of the station's loop and
:meth:`StationView.snapshot` at the view's update rate, both on the loop's thread, and
hands the snapshot to the server (:mod:`clark_engine.station.server`), which sends it on.

Three kinds of data (docs/station-view.md, "The protocol"):

- **hello** (:func:`build_hello`): what does not change during a run: the mission, every
  agent (name, id, role, airframe class, the modes its profile allows, how often it sends
  its heartbeat) and the mission's plan in metres north and east of the origin (each
  vehicle's waypoints and tours, any other point in its primitives' parameters; a tour
  that runs beside a ``photo_trigger`` is a survey line).
- **state** (:meth:`StationView.snapshot`): the live part, from the station's fleet table
  (:class:`~clark_engine.link.fleet.AgentRecord`: its peers' Agent Status, Behavior State,
  Picture Data, heartbeat condition and link statistics) and its clock; plus what is new
  since the last snapshot, each item with a sequence number: track points (one per Agent
  Status received), photos (one per Picture Data) and mission-log lines
  (:class:`MissionLogBuffer`).
- **commands** (:class:`CommandRequest` in, lifecycle out): ``pending`` until the target
  shows that it took effect, then ``done``; ``refused`` when the station will not send it
  or its runtime says no; ``unanswered`` when nothing showed it within
  :attr:`StationView.answer_timeout_s` (see :func:`answer_timeout_s`).

Stale and lost (docs/station-view.md, "Stale and lost"): an agent is *lost* when the
fleet table says so (silent for longer than ``mission.heartbeat_timeout_s``); it is
*stale* when it is not lost and silent for longer than :func:`stale_after_s`: one and a
half of its heartbeat periods (one heartbeat missed, with room for jitter), at most half
the heartbeat timeout.
"""

from __future__ import annotations

import logging
import math
from collections import deque
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from typing import Any, Final

from clark_engine.behaviors import Plan, behaviors
from clark_engine.link.fleet import AgentRecord, Sample
from clark_engine.link.messages import (
    AgentAttitude,
    AgentStatus,
    BehaviorState,
    Condition,
    PictureData,
    VehicleHealth,
)
from clark_engine.mission.fence import Zone
from clark_engine.mission.geo import Origin, parse_point, to_local
from clark_engine.runtime.command_delivery import took_effect
from clark_engine.runtime.config import AgentConfig, EnvelopeSpec, StateSpec
from clark_engine.runtime.events import StationCommand
from clark_engine.runtime.log_events import RECORD_ATTRIBUTE, UNDECLARED, LogEvent
from clark_engine.runtime.log_lines import line_safe
from clark_engine.runtime.runtime import AgentRuntime
from clark_engine.station.alarms import AlarmChange, AlarmWatch, failsafe_words

Json = dict[str, Any]

PROTOCOL_VERSION: Final = 1
"""Version of the messages between the server and the page; ``hello`` carries it."""

ACTIONS: Final = ("activate", "deactivate", "mode", "terminate")
"""What the operator may ask for (the thesis's Clark View, requirements 5.2.3-5.2.5)."""

MAX_LOG_LINES: Final = 500
"""Mission-log lines held for the view; older ones are dropped (the log file keeps all)."""

MAX_LOG_TEXT_CHARS: Final = 500
"""Longest mission-log line shown; longer ones are cut (``...``)."""

MAX_COMMANDS_SHOWN: Final = 50
"""Commands kept with their lifecycle; older ones leave the view."""

MIN_ANSWER_TIMEOUT_S: Final = 5.0
"""The shortest wait before a command with no sign of effect is ``unanswered``."""

STALE_HEARTBEATS: Final = 1.5
"""An agent silent for this many of its heartbeat periods is stale (one missed, plus jitter)."""

UNSETTABLE_MODES: Final = frozenset({"INITIALISING"})
"""Modes an autopilot reports but never accepts as a request (ArduPilot's boot mode)."""

GPS_FIX_NAMES: Final = (  # app.js's GPS_FIXES
    "no GPS",
    "no fix",
    "2-D fix",
    "3-D fix",
    "DGPS",
    "RTK float",
    "RTK fixed",
    "static",
    "PPP",
)
"""MAVLink's GPS_FIX_TYPE by number, as the page shows it."""


_CONDITION_WORDS: Final = {member: member.name.lower() for member in Condition}


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


def answer_timeout_s(heartbeat_timeout_s: float) -> float:
    """How long a command waits for a sign of effect before it is ``unanswered``.

    Twice the mission's heartbeat timeout, and at least :data:`MIN_ANSWER_TIMEOUT_S`:
    a Behavior State goes out in the tick after a change, a mode shows in the next Agent
    Status and a terminated agent's last heartbeat goes at once, so anything slower is a
    link that is failing, which the heartbeat timeout is the mission's measure of.
    """
    return max(MIN_ANSWER_TIMEOUT_S, 2.0 * heartbeat_timeout_s)


def _round(value: float | None, digits: int = 2) -> float | None:
    """A figure for the page: rounded, and None for None or a non-finite number."""
    if value is None or not math.isfinite(value):
        return None
    return round(value, digits)


def _origin(config: AgentConfig) -> Origin:
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
        "north_m": _round(point.north_m),
        "east_m": _round(point.east_m),
        "up_m": _round(point.up_m),
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
    origin = _origin(config)
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
            "center": {"north_m": _round(zone.center[0]), "east_m": _round(zone.center[1])},
            "radius_m": _round(zone.radius_m),
        }
    return {
        "kind": "polygon",
        "points": [{"north_m": _round(n), "east_m": _round(e)} for n, e in zone.corners],
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
        "ceiling_m": _round(envelope.ceiling_m),
        "floor_m": _round(envelope.floor_m),
        "margin_m": _round(envelope.margin_m),
        "min_separation_m": _round(envelope.min_separation_m),
        "separation": {name: _round(m) for name, m in sorted(envelope.separation.items())},
        "default_radius_m": _round(envelope.default_radius_m),
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
    origin = _origin(station)
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
                "stale_after_s": _round(
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


# -- the mission log -------------------------------------------------------------------------


@dataclass(frozen=True, slots=True)
class LogLine:
    """One mission-log line as the view holds it.

    Attributes:
        seq: Its sequence number (1, 2, ...), for the page to ask for what it lacks.
        now_s: The station's runtime time it was logged at.
        level: ``INFO``, ``WARNING``...
        text: The message, escaped (no control character) and at most
            :data:`MAX_LOG_TEXT_CHARS` long.
        event: The event it records (:mod:`clark_engine.runtime.log_events`; not sent
            to the page; used to tell the runtime's answer to a command).
        levelno: The numeric level (not sent).
    """

    seq: int
    now_s: float
    level: str
    text: str
    event: str
    levelno: int

    def to_json(self) -> Json:
        """The line as the page receives it."""
        return {"seq": self.seq, "t": _round(self.now_s, 3), "level": self.level, "text": self.text}


class MissionLogBuffer(logging.Handler):
    """A copy of the station's mission-log lines, the newest :data:`MAX_LOG_LINES`.

    Added to the logbook's mission logger (:attr:`~clark_engine.runtime.logbook.Logbook.mission`),
    as the logbook's docstring invites a shell to; the logbook's own filter has already
    escaped every argument, and the line is escaped again and cut here, so nothing
    received over the air reaches the page as markup or a forged line (the page also
    writes it as text, never as HTML).

    Args:
        max_lines: How many lines are held; older ones are dropped.
    """

    def __init__(self, max_lines: int = MAX_LOG_LINES) -> None:
        super().__init__(level=logging.NOTSET)
        self.lines: deque[LogLine] = deque(maxlen=max_lines)
        self.seq = 0
        self._logger: logging.Logger | None = None

    def attach(self, logger: logging.Logger) -> None:
        """Start copying ``logger``'s lines."""
        self.detach()
        logger.addHandler(self)
        self._logger = logger

    def detach(self) -> None:
        """Stop copying."""
        if self._logger is not None:
            self._logger.removeHandler(self)
            self._logger = None

    def emit(self, record: logging.LogRecord) -> None:
        """Keep one line (never raises into the logging call)."""
        try:
            text = record.getMessage()
        except Exception:  # a bad format must not break the station's loop
            text = str(record.msg)
        self.seq += 1
        self.lines.append(
            LogLine(
                self.seq,
                float(getattr(record, "clark_now_s", 0.0)),
                record.levelname,
                line_safe(text, MAX_LOG_TEXT_CHARS),
                str(getattr(record, RECORD_ATTRIBUTE, UNDECLARED)),
                record.levelno,
            )
        )

    def since(self, seq: int) -> list[LogLine]:
        """The lines held with a sequence number above ``seq``, oldest first."""
        return [line for line in self.lines if line.seq > seq]


# -- commands --------------------------------------------------------------------------------


@dataclass(frozen=True, slots=True)
class CommandRequest:
    """An operator's command from the page, already checked by the server.

    Attributes:
        id: The server's number for it (the page follows its lifecycle by it).
        action: One of :data:`ACTIONS`.
        target: An agent's name, or ``""`` for every agent.
        mode: The mode's name, for ``mode``.
        operator: The name the page gave, escaped and bounded (may be empty).
        address: The page's remote address as the server saw it.
    """

    id: int
    action: str
    target: str
    mode: str = ""
    operator: str = ""
    address: str = ""


@dataclass(slots=True)
class _Target:
    """One agent a command is aimed at, and what it has shown since."""

    name: str
    agent_id: int
    status: str = "pending"
    behaviour: Sample[BehaviorState] | None = None
    mode_number: int | None = None


@dataclass(slots=True)
class _Command:
    request: CommandRequest
    sent_s: float
    status: str
    detail: str = ""
    targets: list[_Target] = field(default_factory=list)
    done_s: float | None = None

    def to_json(self) -> Json:
        return {
            "id": self.request.id,
            "action": self.request.action,
            "target": self.request.target or "all",
            "mode": self.request.mode or None,
            "by": {"name": self.request.operator, "address": self.request.address},
            "sent_s": _round(self.sent_s, 3),
            "status": self.status,
            "detail": self.detail,
            "targets": {t.name: t.status for t in self.targets},
            "done_s": _round(self.done_s, 3),
        }


# -- rows, track points and photos: shared by the live view and the replay --------------------


def mode_name(modes: Mapping[str, int], number: int) -> str | None:
    """The name of a custom mode number in an agent's profile (None when it has none)."""
    return next((name for name, n in modes.items() if n == number), None)


def link_json(
    *,
    packets: int,
    lost_packets: int,
    loss_ratio: float | None,
    latency_mean_ms: float | None,
    bad_tags: int,
    malformed: int,
    duplicates: int,
) -> Json:
    """An agent row's ``link``: packets received from it, their loss and latency."""
    return {
        "packets": packets,
        "lost_packets": lost_packets,
        "loss_ratio": _round(loss_ratio, 4),
        "latency_mean_ms": _round(latency_mean_ms, 1),
        "bad_tags": bad_tags,
        "malformed": malformed,
        "duplicates": duplicates,
    }


MAX_ACTIVE_STATES_SHOWN: Final = 32
"""Active states shown per agent: deeper than any mission nests (a forged Behavior State
may name hundreds)."""
MAX_STATE_NAME_CHARS: Final = 100
"""Longest state or event name shown, escaped (a dotted path of a deep state fits)."""


def agent_row(
    info: Mapping[str, Any],
    origin: Origin,
    *,
    heard: bool,
    link: Json | None = None,
    lost: bool = False,
    since_heartbeat_s: float | None = None,
    condition: str | None = None,
    status: AgentStatus | None = None,
    status_age_s: float | None = None,
    mode: str | None = None,
    behaviour: BehaviorState | None = None,
    behaviour_age_s: float | None = None,
    attitude: AgentAttitude | None = None,
    health: VehicleHealth | None = None,
    health_age_s: float | None = None,
    in_alarm: bool = False,
) -> Json:
    """One agent's row of a ``state`` message (docs/station-view.md, "The protocol").

    The live view (:class:`StationView`, from the station's fleet table) and the replay
    (:mod:`clark_engine.station.replay`, from a run's logs) both build their rows here, so
    the page gets the same shape from either.

    Args:
        info: The agent's entry in ``hello`` (name, id, role, airframe, stale_after_s;
            a null ``stale_after_s`` is never stale).
        origin: The mission's origin, for metres north and east.
        heard: Whether anything was heard from it; when False, the rest is left null.
        link: Its :func:`link_json`, or None when unknown.
        lost: Whether the fleet table counts it lost.
        since_heartbeat_s: Seconds since its latest heartbeat.
        condition: Its heartbeat's condition, lower case (``ok``, ``failsafe``...).
        status: Its latest Agent Status, if any.
        status_age_s: Seconds since that Agent Status arrived.
        mode: The name of ``status.mode`` in its profile, if known.
        behaviour: Its latest Behavior State, if any.
        behaviour_age_s: Seconds since it arrived (the replay: since the change).
        attitude: Its latest Agent Attitude, if any.
        health: Its latest Vehicle Health, if any (``armed`` comes from it).
        health_age_s: Seconds since that Vehicle Health arrived.
        in_alarm: Whether an alarm in force is about it.
    """
    out: Json = {
        "id": int(info["id"]),
        "name": info["name"],
        "role": info["role"],
        "airframe": info.get("airframe"),
        "heard": heard,
        "lost": False,
        "stale": False,
        "since_heartbeat_s": None,
        "condition": None,
        "position": None,
        "mode": None,
        "armed": None,  # from Vehicle Health; unknown without it
        "behaviour": None,
        "attitude": None,
        "health": None,
        "alarm": in_alarm,
        "link": link,
    }
    if not heard:
        return out
    stale_after = info.get("stale_after_s")
    out["since_heartbeat_s"] = _round(since_heartbeat_s, 2)
    out["lost"] = lost
    out["stale"] = (
        not lost
        and since_heartbeat_s is not None
        and stale_after is not None
        and since_heartbeat_s > float(stale_after)
    )
    out["condition"] = condition
    if status is not None:
        local = to_local(status.lat_deg, status.lon_deg, status.alt_m, origin)
        out["position"] = {
            "lat": round(status.lat_deg, 7),
            "lon": round(status.lon_deg, 7),
            "north_m": _round(local.north_m),
            "east_m": _round(local.east_m),
            "alt_m": _round(status.alt_m),
            "ground_speed_m_s": _round(status.ground_speed_m_s),
            "climb_rate_m_s": _round(status.climb_rate_m_s),
            "heading_deg": _round(status.heading_deg, 1),
            "age_s": _round(status_age_s, 2),
        }
        out["mode"] = {"number": status.mode, "name": mode}
    if behaviour is not None:
        # Names from the air: a control character or a bidirectional override (U+202E
        # shows the operator a reversed name) is escaped, and a flood of them is cut.
        out["behaviour"] = {
            "active": [
                line_safe(name, MAX_STATE_NAME_CHARS)
                for name in behaviour.active_states[:MAX_ACTIVE_STATES_SHOWN]
            ],
            "last_event": line_safe(behaviour.last_event, MAX_STATE_NAME_CHARS),
            "age_s": _round(behaviour_age_s, 2),
        }
    if attitude is not None:
        out["attitude"] = {
            "roll_deg": _round(attitude.roll_deg, 1),
            "pitch_deg": _round(attitude.pitch_deg, 1),
            "yaw_deg": _round(attitude.yaw_deg, 1),
        }
    if health is not None:
        out["armed"] = health.armed
        out["health"] = health_json(health, health_age_s)
    return out


def health_json(health: VehicleHealth, age_s: float | None) -> Json:
    """An agent row's ``health``: its latest Vehicle Health, texts escaped and bounded.

    ``text_age_s`` is the text's age now: its age when the vehicle sent the health, plus
    the health's own age at the station. The row's ``armed`` is the health's; the page
    names the fix type (0 no GPS ... 6 RTK fixed, :data:`GPS_FIX_NAMES`). Kept small: a
    state carries one per vehicle, five times a second.
    """
    fix = health.gps_fix_type
    text = line_safe(health.text, 100) if health.text else None
    return {
        "battery_v": _round(health.battery_v, 2),
        "battery_pct": health.battery_pct,
        "gps_fix_type": fix,
        "satellites": health.satellites,
        "prearm": health.prearm.name.lower(),
        "text": text,
        "text_severity": health.text_severity if text else None,
        "text_age_s": _round(health.text_age_s + (age_s or 0.0), 1) if text else None,
        "failsafe": line_safe(health.failsafe, 64) or None,
        "autopilot_lost": health.autopilot_lost,
        "age_s": _round(age_s, 2),
    }


def track_point_json(
    seq: int,
    agent_id: int,
    t_s: float,
    lat_deg: float,
    lon_deg: float,
    alt_m: float,
    origin: Origin,
) -> Json:
    """One track point (an Agent Status received) as the page receives it."""
    local = to_local(lat_deg, lon_deg, alt_m, origin)
    return {
        "seq": seq,
        "agent": agent_id,
        "t": _round(t_s, 3),
        "north_m": _round(local.north_m),
        "east_m": _round(local.east_m),
        "alt_m": _round(alt_m),
    }


def photo_json(seq: int, agent_id: int, t_s: float, picture: PictureData, origin: Origin) -> Json:
    """One photo (a Picture Data received) as the page receives it."""
    local = to_local(picture.lat_deg, picture.lon_deg, picture.alt_m, origin)
    return {
        "seq": seq,
        "agent": agent_id,
        "t": _round(t_s, 3),
        "image_index": picture.image_index,
        "gps_time_ms": picture.gps_time_ms,
        "lat": round(picture.lat_deg, 7),
        "lon": round(picture.lon_deg, 7),
        "north_m": _round(local.north_m),
        "east_m": _round(local.east_m),
        "alt_m": _round(picture.alt_m),
    }


# -- the live view ---------------------------------------------------------------------------


@dataclass(frozen=True, slots=True)
class Snapshot:
    """One ``state`` message's content, built on the station's loop thread.

    Attributes:
        state: The current part (agents, station, commands, checks), replaced whole by
            the next snapshot.
        track: Track points new since the last snapshot, each with a ``seq``.
        photos: Photos new since the last snapshot, each with a ``seq``.
        log: Mission-log lines new since the last snapshot, each with a ``seq``.
    """

    state: Json
    track: list[Json]
    photos: list[Json]
    log: list[Json]


class StationView:
    """The station's view of its fleet, built from its runtime; one per station.

    Everything here runs on the station loop's thread (the runtime is single-threaded):
    :meth:`observe` after each tick, :meth:`snapshot` at the update rate, and
    :meth:`execute` for each command the page sent.

    Args:
        runtime: The station's runtime.
        hello: The :func:`build_hello` message (the agents' modes and heartbeat rates).
        log: The mission-log copy, attached by the caller to the runtime's mission
            logger; None shows no log (and a refusal logged by the runtime is then
            not seen, so such a command ends ``unanswered``).
        answer_timeout: Seconds before ``unanswered``; :func:`answer_timeout_s` of
            the mission's heartbeat timeout by default.
    """

    def __init__(
        self,
        runtime: AgentRuntime,
        hello: Json,
        *,
        log: MissionLogBuffer | None = None,
        answer_timeout: float | None = None,
    ) -> None:
        self.runtime = runtime
        self.config = runtime.config
        self.hello = hello
        self.log = log
        self.origin = _origin(self.config)
        self.answer_timeout_s = (
            answer_timeout
            if answer_timeout is not None
            else answer_timeout_s(self.config.heartbeat_timeout_s)
        )
        self.checks: list[Json] | None = None
        """A rehearsal's checks as they are evaluated; None where nothing evaluates them."""
        self._agents: dict[int, Json] = {int(a["id"]): a for a in hello["agents"]}
        self._by_name = {str(a["name"]): a for a in hello["agents"]}
        self._seen_status: dict[int, Sample[AgentStatus]] = {}
        self._seen_picture: dict[int, Sample[PictureData]] = {}
        envelopes = {p.name: p.envelope for p in self.config.peers if p.envelope is not None}
        self.alarms = AlarmWatch(envelopes, self.config.heartbeat_timeout_s)
        """Breaches, near misses and failsafes, judged after every tick (docs/station-view.md)."""
        self._track_seq = 0
        self._photo_seq = 0
        self._new_track: list[Json] = []
        self._new_photos: list[Json] = []
        self._log_sent = 0
        self._commands: deque[_Command] = deque(maxlen=MAX_COMMANDS_SHOWN)
        self._track_cap = 10_000  # new points held between two snapshots at most

    # -- per tick ------------------------------------------------------------------------

    def observe(self, now_s: float) -> None:
        """Take what arrived since the last call: track points, photos, alarms, answers."""
        fleet = self.runtime.fleet
        alarms = self.alarms
        for record in fleet.agents():
            status = record.sample(AgentStatus)
            if status is not None and status is not self._seen_status.get(record.agent_id):
                self._seen_status[record.agent_id] = status
                self._track_point(record, status)
                value = status.value
                local = to_local(value.lat_deg, value.lon_deg, value.alt_m, self.origin)
                alarms.see_position(
                    record.name, local.north_m, local.east_m, value.alt_m, status.received_s
                )
            picture = record.sample(PictureData)
            if picture is not None and picture is not self._seen_picture.get(record.agent_id):
                self._seen_picture[record.agent_id] = picture
                self._photo(record, picture)
            health = record.sample(VehicleHealth)
            alarms.see_condition(
                record.name,
                failsafe_words(
                    _CONDITION_WORDS[record.condition],
                    health.value.failsafe if health is not None else None,
                ),
            )
        changes = alarms.evaluate(now_s)
        if changes:
            self._log_alarms(changes)
        for command in self._commands:
            if command.status == "pending":
                self._follow(command, now_s)

    def _log_alarms(self, changes: list[AlarmChange]) -> None:
        """One mission-log line per alarm raised and per alarm cleared: never one per tick."""
        logbook = self.runtime.logbook
        if logbook.closed:
            return
        for change in changes:
            alarm = change.alarm
            if change.raised:
                logbook.mission.warning(
                    "ALARM %d %s: %s",
                    alarm.id,
                    alarm.kind,
                    alarm.text,
                    extra=LogEvent.ALARM_RAISED.extra,
                )
                continue
            lasted_s = (alarm.cleared_s or alarm.raised_s) - alarm.raised_s
            worst = ""
            if alarm.kind == "near miss":
                worst = f"; closest {-alarm.worst:.1f} m"
            elif alarm.kind == "breach":
                side = "over" if alarm.what == "ceiling" else "outside"
                worst = f"; at worst {alarm.worst:.1f} m {side}"
            logbook.mission.info(
                "alarm %d cleared after %.1f s (%s: %s)%s",
                alarm.id,
                lasted_s,
                alarm.kind + (f" {alarm.what}" if alarm.what else ""),
                " and ".join(alarm.agents),
                worst,
                extra=LogEvent.ALARM_CLEARED.extra,
            )

    def _track_point(self, record: AgentRecord, sample: Sample[AgentStatus]) -> None:
        value = sample.value
        self._track_seq += 1
        if len(self._new_track) < self._track_cap:
            self._new_track.append(
                track_point_json(
                    self._track_seq,
                    record.agent_id,
                    sample.received_s,
                    value.lat_deg,
                    value.lon_deg,
                    value.alt_m,
                    self.origin,
                )
            )

    def _photo(self, record: AgentRecord, sample: Sample[PictureData]) -> None:
        self._photo_seq += 1
        if len(self._new_photos) < self._track_cap:
            self._new_photos.append(
                photo_json(
                    self._photo_seq, record.agent_id, sample.received_s, sample.value, self.origin
                )
            )

    # -- the snapshot --------------------------------------------------------------------

    def snapshot(self, now_s: float) -> Snapshot:
        """The ``state`` message now, with what is new since the previous snapshot."""
        self.observe(now_s)
        runtime = self.runtime
        fleet = runtime.fleet
        agents: list[Json] = []
        alarmed = self.alarms.in_alarm()
        for info in self.hello["agents"]:
            agent_id = int(info["id"])
            row = self._agent(info, fleet.record(agent_id), agent_id, now_s)
            row["alarm"] = info["name"] in alarmed
            agents.append(row)
        log: list[Json] = []
        if self.log is not None:
            lines = self.log.since(self._log_sent)
            if lines:
                self._log_sent = lines[-1].seq
            log = [line.to_json() for line in lines]
        track, self._new_track = self._new_track, []
        photos, self._new_photos = self._new_photos, []
        state: Json = {
            "type": "state",
            "t": _round(now_s, 3),
            "station": {
                "name": self.config.agent,
                "id": self.config.agent_id,
                "gps_time_ms": runtime.context.gps_time_ms,
                "terminated": runtime.terminated,
                "unknown_packets": fleet.unknown_packets,
            },
            "agents": agents,
            "commands": [c.to_json() for c in self._commands],
            "checks": self.checks,
            "alarms": [a.to_json() for a in self.alarms.shown(now_s)],
        }
        return Snapshot(state, track, photos, log)

    def _agent(
        self, info: Mapping[str, Any], record: AgentRecord | None, agent_id: int, now_s: float
    ) -> Json:
        stats = self.runtime.fleet.stats(agent_id)
        link: Json | None = None
        if stats is not None:
            link = link_json(
                packets=stats.packets,
                lost_packets=stats.lost,
                loss_ratio=stats.loss_ratio,
                latency_mean_ms=stats.latency_mean_ms,
                bad_tags=stats.bad_tags,
                malformed=stats.malformed,
                duplicates=stats.duplicates,
            )
        if record is None:
            return agent_row(info, self.origin, heard=False, link=link)
        status = record.sample(AgentStatus)
        behaviour = record.sample(BehaviorState)
        attitude = record.sample(AgentAttitude)
        health = record.sample(VehicleHealth)
        return agent_row(
            info,
            self.origin,
            heard=True,
            link=link,
            lost=record.lost,
            since_heartbeat_s=record.since_heartbeat_s(now_s),
            condition=record.condition.name.lower(),
            status=status.value if status is not None else None,
            status_age_s=now_s - status.received_s if status is not None else None,
            mode=self._mode_name(info, status.value.mode) if status is not None else None,
            behaviour=behaviour.value if behaviour is not None else None,
            behaviour_age_s=now_s - behaviour.received_s if behaviour is not None else None,
            attitude=attitude.value if attitude is not None else None,
            health=health.value if health is not None else None,
            health_age_s=now_s - health.received_s if health is not None else None,
        )

    def _mode_name(self, info: Mapping[str, Any], number: int) -> str | None:
        peer = self.config.peer(str(info["name"]))
        if peer is None:
            return None
        return mode_name(peer.modes, number)

    # -- commands ------------------------------------------------------------------------

    def execute(
        self,
        request: CommandRequest,
        deliver: Callable[[StationCommand], None],
        now_s: float,
    ) -> Json:
        """Log, check and send one operator command; returns its lifecycle entry.

        The command is written in the station's mission log with who sent it (the name
        the page gave and its address, both escaped by the logbook), then checked (the
        station still runs; the target is an agent of the mission that has not
        terminated; the mode is one of its profile's), then handed to ``deliver``
        (the shell's :meth:`~clark_engine.shells.realtime.RealtimeShell.deliver`), which
        sends it as ClarkLink through the station's runtime. A warning the runtime logs
        about it while it does is its refusal.
        """
        runtime = self.runtime
        who = request.operator or "(no name)"
        target_text = request.target or "all"
        what = f"{request.action} {target_text}" + (f" {request.mode}" if request.mode else "")
        if not runtime.logbook.closed:
            runtime.logbook.mission.info(
                "view command %d from %s at %s: %s",
                request.id,
                who,
                request.address,
                what,
                extra=LogEvent.VIEW_COMMAND.extra,
            )
        command = _Command(request, now_s, "pending", targets=self._targets(request))
        self._commands.append(command)
        refusal = self._refusal(request, command)
        if refusal is not None:
            return self._refuse(command, refusal, now_s)
        mark = self.log.seq if self.log is not None else 0
        deliver(StationCommand(request.action, request.target, request.mode))
        if self.log is not None:
            for line in self.log.since(mark):
                if line.event == LogEvent.STATION_COMMAND and line.levelno >= logging.WARNING:
                    return self._refuse(command, f"the station's runtime: {line.text}", now_s)
        # A terminate of the whole fleet: the station's runtime keeps listening until every
        # agent confirms (or falls silent), then terminates itself; followed like the rest.
        self._follow(command, now_s)
        return command.to_json()

    def _targets(self, request: CommandRequest) -> list[_Target]:
        if request.target:
            info = self._by_name.get(request.target)
            return [] if info is None else [_Target(request.target, int(info["id"]))]
        vehicles = [a for a in self.hello["agents"] if a["role"] != "mcs"]
        return [_Target(str(a["name"]), int(a["id"])) for a in vehicles]

    def _refusal(self, request: CommandRequest, command: _Command) -> str | None:
        if self.runtime.terminated:
            return "the station has terminated"
        if request.action not in ACTIONS:
            return f"unknown action {request.action!r}"
        if request.target and request.target not in self._by_name:
            return f"no agent {request.target!r} in the mission"
        if request.action == "mode":
            info = self._by_name.get(request.target)
            if info is None:
                return "a mode change needs one agent"
            modes = {m["name"]: m["number"] for m in info["modes"]}
            if request.mode not in modes:
                return f"{request.target} has no mode {request.mode!r}"
            command.targets[0].mode_number = int(modes[request.mode])
        if not command.targets:
            return "no vehicle to command"
        for target in command.targets:
            record = self.runtime.fleet.record(target.agent_id)
            if record is not None and record.condition == Condition.TERMINATED:
                if request.target:
                    return f"{target.name} has terminated"
                target.status = "terminated"  # of every agent: it can answer nothing
            if record is not None:
                sample = record.sample(BehaviorState)
                target.behaviour = sample
        if all(t.status == "terminated" for t in command.targets):
            return "every vehicle has terminated"
        return None

    def _refuse(self, command: _Command, reason: str, now_s: float) -> Json:
        command.status = "refused"
        command.detail = reason
        command.done_s = now_s
        for target in command.targets:
            if target.status == "pending":
                target.status = "refused"
        if not self.runtime.logbook.closed:
            self.runtime.logbook.mission.warning(
                "view command %d refused: %s",
                command.request.id,
                reason,
                extra=LogEvent.VIEW_COMMAND.extra,
            )
        return command.to_json()

    def _follow(self, command: _Command, now_s: float) -> None:
        """Look for each target's sign of effect; end the command when all showed one."""
        fleet = self.runtime.fleet
        action = command.request.action
        for target in command.targets:
            if target.status != "pending":
                continue
            record = fleet.record(target.agent_id)
            if record is not None and took_effect(
                action,
                record,
                command.sent_s,
                behaviour_before=target.behaviour,
                mode_number=target.mode_number,
            ):
                target.status = "done"
        waiting = [t.name for t in command.targets if t.status == "pending"]
        if not waiting:
            command.status = "done"
            command.done_s = now_s
            command.detail = _evidence(action, command.request.mode)
        elif self.runtime.terminated or now_s - command.sent_s >= self.answer_timeout_s:
            # A terminated station hears nothing more: what has not answered never will.
            command.status = "unanswered"
            command.done_s = now_s
            for target in command.targets:
                if target.status == "pending":
                    target.status = "unanswered"
            answered = [t.name for t in command.targets if t.status == "done"]
            waited = (
                "before the station terminated"
                if self.runtime.terminated
                else f"in {self.answer_timeout_s:g} s"
            )
            command.detail = f"no sign of effect from {', '.join(waiting)} {waited}" + (
                f" (done: {', '.join(answered)})" if answered else ""
            )
            if not self.runtime.logbook.closed:
                self.runtime.logbook.mission.warning(
                    "view command %d unanswered: %s",
                    command.request.id,
                    command.detail,
                    extra=LogEvent.VIEW_COMMAND.extra,
                )

    def commands(self) -> list[Json]:
        """Every command kept, oldest first, with its lifecycle."""
        return [c.to_json() for c in self._commands]


def _evidence(action: str, mode: str) -> str:
    return {
        "activate": "its Behavior State shows the activation",
        "deactivate": "its Behavior State shows the deactivation",
        "mode": f"its Agent Status reports {mode}",
        "terminate": "its heartbeat reports it terminated",
    }.get(action, "")


def agent_names(hello: Mapping[str, Any], *, vehicles_only: bool = False) -> list[str]:
    """The agents' names in a hello message."""
    return [str(a["name"]) for a in hello["agents"] if not vehicles_only or a.get("role") != "mcs"]


def modes_of(hello: Mapping[str, Any]) -> dict[str, frozenset[str]]:
    """Each agent's settable modes, by name, from a hello message."""
    return {str(a["name"]): frozenset(str(m["name"]) for m in a["modes"]) for a in hello["agents"]}


__all__ = [
    "ACTIONS",
    "PROTOCOL_VERSION",
    "CommandRequest",
    "LogLine",
    "MissionLogBuffer",
    "Snapshot",
    "StationView",
    "agent_names",
    "agent_row",
    "answer_timeout_s",
    "build_hello",
    "link_json",
    "mode_name",
    "modes_of",
    "photo_json",
    "plan_of",
    "stale_after_s",
    "track_point_json",
]
