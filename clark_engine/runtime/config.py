"""A compiled agent config, as typed objects the runtime is built from.

``clark compile`` writes plain JSON valid against ``agent_config.schema.json``;
this module reads it back into frozen dataclasses so the runtime never indexes
dictionaries by string at flight time. Loading validates the file against the
schema first: a config edited by hand is checked as strictly as a compiled one.
"""

from __future__ import annotations

import json
from collections.abc import Iterator, Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any

from clark_engine.errors import ClarkError, UsageError
from clark_engine.mission.fence import Fence, Zone
from clark_engine.mission.model import DEFAULT_COMPUTER_LOST_S, TICK_PHASES
from clark_engine.mission.peer_conditions import PEER_CONDITIONS

if TYPE_CHECKING:
    from clark_engine.behaviors.declaration import Traits


class ConfigError(ClarkError):
    """A compiled config that is not valid for this engine."""


@dataclass(frozen=True, slots=True)
class ChannelSpec:
    """A control channel resolved through the agent's profile."""

    name: str
    rc: int | None
    servo: int | None
    pwm_min_us: int
    pwm_trim_us: int
    pwm_max_us: int


@dataclass(frozen=True, slots=True)
class TransitionSpec:
    """A resolved transition: event, target path, optional structured condition."""

    event: str
    target: str
    when: Mapping[str, Any] | None
    source: str


@dataclass(frozen=True, slots=True)
class StateSpec:
    """A resolved state of the behaviour (see the compiler for the meaning of each field)."""

    name: str
    path: str
    kind: str
    primitive: str | None
    params: Mapping[str, Any]
    block: str | None
    initial: str | None
    parallel: bool
    finish: str
    final: bool
    timeout_s: float | None
    transitions: tuple[TransitionSpec, ...]
    source: str
    states: tuple[StateSpec, ...]

    @property
    def traits(self) -> Traits:
        """What the behaviour it runs is (takes pictures, lands...); none without one."""
        from clark_engine.behaviors import traits_of

        return traits_of(self.primitive)

    def walk(self) -> list[StateSpec]:
        """This state and every descendant, parents first."""
        out = [self]
        for child in self.states:
            out.extend(child.walk())
        return out


@dataclass(frozen=True, slots=True)
class TelemetrySpec:
    """One scheduled message."""

    message: str
    rate_hz: float
    every_ticks: int
    to: tuple[str, ...]


@dataclass(frozen=True, slots=True)
class EnvelopeSpec:
    """A vehicle's safety envelope, as the compiled config holds it (docs/safety.md).

    Altitudes are metres above the mission origin; the fence is on the local plane,
    metres north and east of the origin (:mod:`clark_engine.mission.fence`).

    Attributes:
        ceiling_m: Highest altitude above the origin.
        floor_m: Lowest altitude above the origin in guided flight (aircraft).
        legal_ceiling_m: The legal limit the mission flies under.
        margin_m: How far inside the envelope targets are kept.
        fence: The geofence (the default circle around home included).
        default_radius_m: The default circle's radius when no zone was declared, else None.
        home_north_m: The vehicle's start, north of the origin.
        home_east_m: The vehicle's start, east of the origin.
        min_separation_m: Smallest 3-D distance from any other vehicle.
        separation: Other vehicle -> the distance kept from it, where a pair says.
        on_breach: hold, rtl or land on a fence, altitude or endurance breach.
        on_near_miss: hold, rtl or land when another vehicle comes too close.
        outside: clamp or refuse a target outside the envelope.
        endurance_s: Time armed allowed; None when none is declared.
        raw: The envelope as the config holds it.
        position_error_m: How far this vehicle's reported horizontal position may be
            from the truth (``envelope.position_error_m``; 0: its reports are the truth).
        peer_position_error_m: Other vehicle -> the same figure for it, where not 0.
    """

    ceiling_m: float
    floor_m: float
    legal_ceiling_m: float
    margin_m: float
    fence: Fence
    default_radius_m: float | None
    home_north_m: float
    home_east_m: float
    min_separation_m: float
    separation: Mapping[str, float]
    on_breach: str
    on_near_miss: str
    outside: str
    endurance_s: float | None
    raw: Mapping[str, Any]
    position_error_m: float = 0.0
    peer_position_error_m: Mapping[str, float] = field(default_factory=dict)

    def separation_from_m(self, peer: str) -> float:
        """The smallest distance this vehicle keeps from ``peer`` (the truth's)."""
        return float(self.separation.get(peer, self.min_separation_m))

    def position_errors_m(self, peer: str) -> float:
        """How far the two reported positions may together be off: both vehicles' figures.

        Two reports this much farther apart than the separation are two vehicles at least
        the separation apart, whichever way each GPS is off (the error is horizontal, so a
        3-D distance shrinks by at most its length).
        """
        return self.position_error_m + float(self.peer_position_error_m.get(peer, 0.0))

    def reported_separation_from_m(self, peer: str) -> float:
        """The distance kept from ``peer`` on reported positions.

        The separation, widened by both vehicles' position errors so that it holds on the
        truth.
        """
        return self.separation_from_m(peer) + self.position_errors_m(peer)


def _zone(data: Mapping[str, Any]) -> Zone:
    if data["kind"] == "circle":
        center = data["center"]
        return Zone.circle((float(center["north_m"]), float(center["east_m"])), data["radius_m"])
    return Zone.polygon((float(p["north_m"]), float(p["east_m"])) for p in data["points"])


def envelope_from_dict(data: Mapping[str, Any]) -> EnvelopeSpec:
    """The typed envelope from its compiled form (valid against the agent-config schema)."""
    fence = data["geofence"]
    home = fence["home"]
    include = tuple(_zone(z) for z in fence["include"])
    radius = fence["default_radius_m"]
    if radius is not None:
        include = (Zone.circle((float(home["north_m"]), float(home["east_m"])), float(radius)),)
    return EnvelopeSpec(
        ceiling_m=float(data["ceiling_m"]),
        floor_m=float(data["floor_m"]),
        legal_ceiling_m=float(data["legal_ceiling_m"]),
        margin_m=float(data["margin_m"]),
        fence=Fence(include, tuple(_zone(z) for z in fence["exclude"])),
        default_radius_m=float(radius) if radius is not None else None,
        home_north_m=float(home["north_m"]),
        home_east_m=float(home["east_m"]),
        min_separation_m=float(data["min_separation_m"]),
        separation={str(k): float(v) for k, v in data["separation"].items()},
        on_breach=str(data["on_breach"]),
        on_near_miss=str(data["on_near_miss"]),
        outside=str(data["outside"]),
        endurance_s=float(data["endurance_s"]) if data["endurance_s"] is not None else None,
        raw=data,
        position_error_m=float(data.get("position_error_m", 0.0)),
        peer_position_error_m={
            str(k): float(v) for k, v in data.get("peer_position_error_m", {}).items()
        },
    )


@dataclass(frozen=True, slots=True)
class PeerSpec:
    """Another agent of the mission.

    Attributes:
        envelope: Where the peer may fly (a vehicle's envelope); None for a station.
    """

    name: str
    id: int
    role: str
    radio_address: str | None
    sends: Mapping[str, float]
    modes: Mapping[str, int]
    envelope: EnvelopeSpec | None = None


@dataclass(frozen=True, slots=True)
class LaunchSpec:
    """How a vehicle gets going before its behaviour runs (the mission's ``launch``).

    Attributes:
        armed_by: ``pilot``: the safety pilot arms and the engine never does;
            ``engine``: the engine arms when the behaviour first needs it.
        airborne: The pilot has the aircraft flying before the behaviour starts.
    """

    armed_by: str = "pilot"
    airborne: bool = False

    @property
    def engine_arms(self) -> bool:
        """True when the engine may arm the vehicle."""
        return self.armed_by == "engine"


@dataclass(frozen=True, slots=True)
class AgentConfig:
    """Everything one agent runs from.

    Attributes:
        origin_alt_amsl_m: The height of the ground at the mission origin above mean sea
            level: the one AMSL figure, from which every altitude above the origin is
            worked out.
        envelope: The vehicle's safety envelope; None for a station.
        firmware: The autopilot's ArduPilot firmware (``arducopter``, ``arduplane``,
            ``ardurover``); None for a station, or a profile that names none.
        computer_lost_s: Seconds from the mission computer's last heartbeat to the
            autopilot's own reaction (``failsafe.computer_lost``).
        safety_setup: The engine sets the autopilot's fence and computer-lost failsafe
            before the behaviour starts (the autopilot profile's ``safety_setup``).
        raw: The config as loaded (for the parts the runtime passes through, such as
            connection settings the shells read).
    """

    mission_id: int
    mission_name: str
    agent: str
    agent_id: int
    role: str
    loop_hz: float
    heartbeat_timeout_s: float
    origin_lat_deg: float
    origin_lon_deg: float
    origin_alt_amsl_m: float
    authenticated: bool
    key_file: str | None
    tick_phases: tuple[str, ...]
    log_level: str
    log_files: Mapping[str, str]
    modes: Mapping[str, int]
    terminal_mode: str | None
    hold_mode: str | None
    guided_mode: str | None
    rtl_mode: str | None
    land_mode: str | None
    airframe_class: str | None
    launch: LaunchSpec
    wait_ready: bool
    failsafe: Mapping[str, str]
    channels: Mapping[str, ChannelSpec]
    payloads: Mapping[str, Mapping[str, Any]]
    autopilot_timeout_s: float
    telemetry: tuple[TelemetrySpec, ...]
    peers: tuple[PeerSpec, ...]
    machine: StateSpec | None
    raw: Mapping[str, Any]
    envelope: EnvelopeSpec | None = None
    firmware: str | None = None
    computer_lost_s: float = DEFAULT_COMPUTER_LOST_S
    safety_setup: bool = True

    @property
    def is_vehicle(self) -> bool:
        """True for vehicles, False for stations."""
        return self.role == "vehicle"

    @property
    def is_aircraft(self) -> bool:
        """True for vehicles that fly (any airframe but a rover)."""
        return self.is_vehicle and self.airframe_class != "rover"

    def peer(self, name: str) -> PeerSpec | None:
        """A peer by name."""
        return next((p for p in self.peers if p.name == name), None)


def _state(data: Mapping[str, Any]) -> StateSpec:
    return StateSpec(
        name=data["name"],
        path=data["path"],
        kind=data["kind"],
        primitive=data["primitive"],
        params=data["params"],
        block=data.get("block"),
        initial=data["initial"],
        parallel=bool(data["parallel"]),
        finish=data.get("finish", "all"),
        final=bool(data["final"]),
        timeout_s=data["timeout_s"],
        transitions=tuple(
            TransitionSpec(t["event"], t["target"], t["when"], t["source"])
            for t in data["transitions"]
        ),
        source=data["source"],
        states=tuple(_state(child) for child in data["states"]),
    )


def config_from_dict(data: Mapping[str, Any], *, source: str | None = None) -> AgentConfig:
    """Build the typed config from a dict that is valid against agent-config, and prove it.

    Loading proves the config before anything flies (docs/runtime.md#loading-a-config):
    the whole dict against the agent-config schema (every state's primitive known and
    its parameters valid against that primitive's own schema, the tick phases each once,
    every condition well formed), then what a schema cannot say (a followed agent and a
    condition's agent are peers of this config, by name and id), then every state's
    runtime primitive built once from its parameters.

    Args:
        data: The config as JSON gives it.
        source: The file it was read from, for messages; None for a config compiled in
            this process.

    Raises:
        ConfigError: Anything unknown or malformed, with the file and the JSON path.
    """
    where = source if source is not None else _agent_label(data)
    _check_schema(data, where)
    config = _build(data)
    _check_references(config, data, where)
    _build_primitives(config, where)
    return config


#: Appended to every refusal: the cure for a config from another engine version.
_RECOMPILE = "compile the mission again with clark compile"


def _agent_label(data: Mapping[str, Any]) -> str:
    """How a config that was never a file is named in a message."""
    mission = data.get("mission")
    agent = mission.get("agent") if isinstance(mission, Mapping) else None
    return f"the compiled config of {agent}" if isinstance(agent, str) else "a compiled config"


def _path_key(error: Any) -> tuple[tuple[bool, Any], ...]:
    """Order errors by where they are (list indices and keys never compared together)."""
    return tuple((isinstance(p, str), p) for p in error.absolute_path)


def _check_schema(data: Mapping[str, Any], where: str) -> None:
    """Refuse the first problem the agent-config schema finds, at its JSON path."""
    from jsonschema.exceptions import best_match

    from clark_engine.mission.schemas import validator

    problems = sorted(validator("agent-config").iter_errors(dict(data)), key=_path_key)
    if not problems:
        return
    first = problems[0]
    if first.validator in ("anyOf", "oneOf") and first.context:
        first = best_match([first])  # the branch that fits the value, not "none of them"
    path = list(first.absolute_path)
    phases = data["mission"].get("tick_phases") if path[:2] == ["mission", "tick_phases"] else None
    if isinstance(phases, list) and all(isinstance(p, str) for p in phases):
        check_tick_phases(phases, where)  # says what is missing, doubled or unknown
    message = first.message
    if path[-1:] == ["primitive"] and first.validator == "enum":
        from clark_engine.behaviors import behaviors

        message = f"unknown primitive {first.instance!r}: this engine has {', '.join(behaviors())}"
    state = _state_of(data, path, primitive=path[-1:] != ["primitive"])
    raise ConfigError(
        f"{message}{state}; {_RECOMPILE}",
        file=where,
        path=_json_path(path),
    )


def _json_path(path: list[Any]) -> str:
    return ".".join(str(p) for p in path) or "(top)"


def _state_of(data: Mapping[str, Any], path: list[Any], *, primitive: bool = True) -> str:
    """`` (state climb, primitive takeoff)`` for a path inside the machine, else ``""``.

    Without the primitive when ``primitive`` is False (the problem is the primitive).
    """
    if not path or path[0] != "machine" or not isinstance(data.get("machine"), Mapping):
        return ""
    state: Any = data["machine"]
    rest = path[1:]
    while len(rest) >= 2 and rest[0] == "states" and isinstance(rest[1], int):
        children = state.get("states") if isinstance(state, Mapping) else None
        if not isinstance(children, list) or not 0 <= rest[1] < len(children):
            break
        state, rest = children[rest[1]], rest[2:]
    if not isinstance(state, Mapping):
        return ""
    name = state.get("path") or "(root)"
    used = state.get("primitive")
    said = f", primitive {used}" if primitive and isinstance(used, str) else ""
    return f" (state {name}{said})"


def check_tick_phases(phases: Sequence[str], where: str | None = None) -> None:
    """Refuse tick phases that are not each of :data:`TICK_PHASES` exactly once.

    The schema says as much; this is the runtime's own guard, for configs built in
    code (``dataclasses.replace``) as well as loaded: an empty list would run no
    timeouts, so no failsafe would ever fire.

    Raises:
        ConfigError: A phase missing, doubled or unknown.
    """
    if len(phases) == len(TICK_PHASES) and set(phases) == set(TICK_PHASES):
        return
    missing = [p for p in TICK_PHASES if p not in phases]
    doubled = sorted({p for p in phases if phases.count(p) > 1})
    unknown = [p for p in phases if p not in TICK_PHASES]
    said = [
        f"{label} {', '.join(map(repr, names))}"
        for label, names in (("missing", missing), ("doubled", doubled), ("unknown", unknown))
        if names
    ]
    raise ConfigError(
        f"the tick phases must be {', '.join(TICK_PHASES)}, each once, in any order "
        f"({'; '.join(said)}); {_RECOMPILE}",
        file=where,
        path="mission.tick_phases",
    )


def _states_with_paths(spec: StateSpec, where: str) -> Iterator[tuple[StateSpec, str]]:
    """Every state with its JSON path in the config (``machine.states.1``), parents first."""
    yield spec, where
    for index, child in enumerate(spec.states):
        yield from _states_with_paths(child, f"{where}.states.{index}")


def _conditions(when: Mapping[str, Any], where: str) -> Iterator[tuple[Mapping[str, Any], str]]:
    """Every condition inside ``when`` (itself included) with its JSON path."""
    yield when, where
    for key, value in when.items():
        if key in ("all", "any"):
            for index, item in enumerate(value):
                yield from _conditions(item, f"{where}.{key}.{index}")
        elif key == "not":
            yield from _conditions(value, f"{where}.not")


def _check_references(config: AgentConfig, data: Mapping[str, Any], where: str) -> None:
    """Refuse a followed agent or a condition's agent that is not a peer of this config.

    The runtime finds them in the peer table (a followed agent by its id): a name the
    table lacks would make the state wait forever for a status that never comes.
    """
    check_tick_phases(config.tick_phases, where)
    if config.machine is None:
        return
    from clark_engine.behaviors import behaviors

    declared = behaviors()
    peers = {p.name: p.id for p in config.peers}
    for state, at in _states_with_paths(config.machine, "machine"):
        behavior = declared.get(state.primitive) if state.primitive is not None else None
        for name in behavior.agent_params if behavior is not None else ():
            target = state.params.get(name)
            if isinstance(target, Mapping) and peers.get(target["name"]) != target["id"]:
                raise ConfigError(
                    f"follows {target['name']!r} (id {target['id']}), which is not a peer of "
                    f"this config{_peer_list(peers)}{_state_hint(state)}; {_RECOMPILE}",
                    file=where,
                    path=f"{at}.params.{name}",
                )
        for index, transition in enumerate(state.transitions):
            if transition.when is None:
                continue
            for condition, place in _conditions(transition.when, f"{at}.transitions.{index}.when"):
                _check_peer_condition(condition, peers, state, place, where)
                distance = condition.get("distance_m")
                if isinstance(distance, Mapping) and distance["to"] not in peers:
                    raise ConfigError(
                        f"measures the distance to {distance['to']!r}, which is not a peer of "
                        f"this config{_peer_list(peers)}{_state_hint(state)}; {_RECOMPILE}",
                        file=where,
                        path=f"{place}.distance_m.to",
                    )


def _check_peer_condition(
    condition: Mapping[str, Any],
    peers: Mapping[str, int],
    state: StateSpec,
    place: str,
    where: str,
) -> None:
    """Refuse a condition on another agent (its state, where it is) that is not a peer."""
    for key in PEER_CONDITIONS:
        body = condition.get(key)
        if isinstance(body, Mapping) and body["agent"] not in peers:
            raise ConfigError(
                f"waits for {body['agent']!r} ({key}), which is not a peer of this "
                f"config{_peer_list(peers)}{_state_hint(state)}; {_RECOMPILE}",
                file=where,
                path=f"{place}.{key}.agent",
            )


def _peer_list(peers: Mapping[str, int]) -> str:
    listed = ", ".join(f"{name} (id {id_})" for name, id_ in peers.items())
    return f" ({listed})" if listed else " (it has none)"


def _state_hint(state: StateSpec) -> str:
    used = f", primitive {state.primitive}" if state.primitive else ""
    return f" (state {state.path or '(root)'}{used})"


def _build_primitives(config: AgentConfig, where: str) -> None:
    """Build every state's runtime primitive once, so that none fails when entered.

    The machine builds a fresh one on every entry (a primitive keeps its state); this
    proves, before the first tick, that each state's parameters make one. A primitive's
    own refusal (a channel without the output its ``via`` needs) is a ConfigError;
    anything else a valid config cannot raise, and is reported at the state all the same.
    """
    if config.machine is None:
        return
    from clark_engine.behaviors import make_behavior

    for state, at in _states_with_paths(config.machine, "machine"):
        if state.primitive is None:
            continue
        try:
            make_behavior(state)
        except ConfigError as exc:
            raise ConfigError(
                f"{exc.message}{_state_hint(state)}", file=where, path=f"{at}.params"
            ) from None
        except (KeyError, TypeError, ValueError) as exc:
            raise ConfigError(
                f"its parameters do not make a {state.primitive} ({type(exc).__name__}: "
                f"{exc}){_state_hint(state)}; {_RECOMPILE}",
                file=where,
                path=f"{at}.params",
            ) from None


def _build(data: Mapping[str, Any]) -> AgentConfig:
    """The typed config from a dict the schema accepted."""
    mission, agent = data["mission"], data["agent"]
    hardware = agent["hardware"]
    autopilot = hardware.get("autopilot") or {}
    airframe = hardware.get("airframe") or {}
    launch = agent.get("launch") or {}
    failsafe: Mapping[str, Any] = agent.get("failsafe") or {}
    channels = {
        name: ChannelSpec(
            name,
            spec.get("rc"),
            spec.get("servo"),
            int(spec["pwm_min_us"]),
            int(spec["pwm_trim_us"]),
            int(spec["pwm_max_us"]),
        )
        for name, spec in (autopilot.get("channels") or {}).items()
    }
    return AgentConfig(
        mission_id=int(mission["id"]),
        mission_name=str(mission["name"]),
        agent=str(mission["agent"]),
        agent_id=int(mission["agent_id"]),
        role=str(agent["role"]),
        loop_hz=float(mission["loop_hz"]),
        heartbeat_timeout_s=float(mission["heartbeat_timeout_s"]),
        origin_lat_deg=float(mission["origin"]["lat"]),
        origin_lon_deg=float(mission["origin"]["lon"]),
        origin_alt_amsl_m=float(mission["origin"]["alt_amsl_m"]),
        authenticated=bool(mission["authenticated"]),
        key_file=mission["key_file"],
        tick_phases=tuple(mission["tick_phases"]),
        log_level=str(mission["log"]["level"]),
        log_files={k: v for k, v in mission["log"].items() if k != "level"},
        modes=dict(autopilot.get("modes") or {}),
        terminal_mode=agent.get("terminal_mode"),
        hold_mode=autopilot.get("hold_mode"),
        guided_mode=autopilot.get("guided_mode"),
        rtl_mode=autopilot.get("rtl_mode"),
        land_mode=autopilot.get("land_mode"),
        airframe_class=airframe.get("class"),
        launch=LaunchSpec(
            armed_by=str(launch.get("armed_by", "pilot")),
            airborne=bool(launch.get("airborne", False)),
        ),
        wait_ready=bool(autopilot.get("wait_ready", True)),
        failsafe={k: v for k, v in failsafe.items() if isinstance(v, str)},
        channels=channels,
        payloads=dict(hardware.get("payloads") or {}),
        autopilot_timeout_s=float(autopilot.get("heartbeat_timeout_s", 3.0)),
        telemetry=tuple(
            TelemetrySpec(t["message"], float(t["rate_hz"]), int(t["every_ticks"]), tuple(t["to"]))
            for t in data["telemetry"]
        ),
        peers=tuple(
            PeerSpec(
                p["name"],
                int(p["id"]),
                p["role"],
                p["radio_address"],
                dict(p["sends"]),
                dict(p["modes"]),
                envelope_from_dict(p["envelope"]) if p["envelope"] is not None else None,
            )
            for p in data["peers"]
        ),
        machine=_state(data["machine"]) if data["machine"] is not None else None,
        raw=data,
        envelope=envelope_from_dict(data["envelope"]) if data["envelope"] is not None else None,
        firmware=autopilot.get("firmware"),
        computer_lost_s=float(failsafe.get("computer_lost_s", DEFAULT_COMPUTER_LOST_S)),
        safety_setup=bool(autopilot.get("safety_setup", True)),
    )


def load_config(path: Path) -> AgentConfig:
    """Read a compiled config file.

    Raises:
        UsageError: The file cannot be read or is not JSON.
        ConfigError: It is JSON but not a valid compiled config.
    """
    try:
        text = path.read_text(encoding="utf-8")
    except FileNotFoundError:
        raise UsageError(f"{path}: no such file") from None
    except OSError as exc:
        raise UsageError(f"{path}: cannot read it ({exc.strerror or exc})") from None
    try:
        data = json.loads(text)
    except json.JSONDecodeError as exc:
        raise ConfigError(
            f"{path}:{exc.lineno}:{exc.colno}: not JSON ({exc.msg}); "
            "give a config written by clark compile"
        ) from None
    if not isinstance(data, dict):
        raise ConfigError(f"{path}: not a compiled agent config (expected a JSON object)")
    return config_from_dict(data, source=str(path))
