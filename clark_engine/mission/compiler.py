"""Compile a resolved mission into one self-contained config per agent.

The thesis hand-wrote one config file per agent with three sections (mission,
Clark, agent; section 3.2). The compiler generates them: everything an agent
needs at flight time is in its file (the mission settings, the interfaces to
enable and how to reach them, its hardware with channel maps, the telemetry
schedule in ticks, the peer table, and the behaviour with every name already
resolved), so a mission computer needs nothing but that file.

Output is deterministic: the same mission, compiled from the same working
folder, gives byte-identical files (keys in a fixed order, no timestamps; rates
and distances are written as JSON numbers, so 10 Hz appears as 10.0). Source
locations inside the configs name files as the findings do, which is why the
working folder matters.
"""

from __future__ import annotations

import json
import os
import shutil
import tempfile
from collections.abc import Callable, Iterable, Mapping
from pathlib import Path
from typing import Any

from clark_engine import __version__
from clark_engine.behaviors import CompileContext, behaviors
from clark_engine.errors import UsageError
from clark_engine.mission.envelope import DeclaredZone
from clark_engine.mission.geo import LocalPoint, parse_point, round_coordinate, to_global
from clark_engine.mission.model import TELEMETRY_MESSAGES, TICK_PHASES, Agent, Mission, State

CONFIG_VERSION = 1
#: The order of the phases of one tick (thesis 7.3.3-7.3.4); the runtime follows it.
DEFAULT_TICK_PHASES = TICK_PHASES


def _point(point: LocalPoint, mission: Mission) -> dict[str, float]:
    lat, lon, alt = to_global(point, mission.origin)
    return {
        "north_m": round(point.north_m, 3),
        "east_m": round(point.east_m, 3),
        "up_m": round(point.up_m, 3),
        "lat": round_coordinate(lat),
        "lon": round_coordinate(lon),
        "alt_m": round(alt, 3),
    }


def _params(state: State, agent: Agent, mission: Mission) -> dict[str, Any]:
    """Parameters with names resolved, as the behaviour's declaration resolves them.

    Points to both frames, channels to their map, agents to ``{name, id}``
    (:attr:`clark_engine.behaviors.Behavior.compile`).
    """
    assert state.primitive is not None
    context = CompileContext(
        mission=mission,
        agent=agent,
        point=lambda raw: _point(parse_point(raw, mission.origin), mission),
    )
    params = behaviors()[state.primitive].compile(dict(state.params), context)
    return dict(sorted(params.items()))


def _state(state: State, agent: Agent, mission: Mission) -> dict[str, Any]:
    return {
        "name": state.name,
        "path": ".".join(state.path),
        "kind": state.kind,
        "description": state.description,
        "primitive": state.primitive,
        "params": _params(state, agent, mission) if state.primitive else {},
        "block": state.block,
        "initial": state.initial,
        "parallel": state.parallel,
        "finish": state.finish,
        "final": state.final,
        "timeout_s": state.timeout_s,
        "transitions": [
            {
                "event": t.event,
                "target": ".".join(t.target),
                "when": t.condition,
                "source": t.location.prefix(),
            }
            for t in state.transitions
        ],
        "source": state.location.prefix(),
        "states": [_state(child, agent, mission) for child in state.children.values()],
    }


def _part(data: Mapping[str, Any] | None) -> dict[str, Any] | None:
    if data is None:
        return None
    return {k: v for k, v in data.items() if k != "abstract"}


def _telemetry(agent: Agent, mission: Mission) -> list[dict[str, Any]]:
    out = []
    for message in TELEMETRY_MESSAGES:
        item = agent.telemetry.get(message)
        if item is None:
            continue
        out.append(
            {
                "message": message,
                "rate_hz": item.rate_hz,
                "every_ticks": max(1, round(mission.loop_hz / item.rate_hz)),
                "to": list(item.to),
            }
        )
    return out


def _zone(zone: DeclaredZone, mission: Mission) -> dict[str, Any]:
    if zone.zone.kind == "circle":
        return {
            "kind": "circle",
            "center": _point(zone.points[0], mission),
            "radius_m": zone.zone.radius_m,
        }
    return {"kind": "polygon", "points": [_point(p, mission) for p in zone.points]}


def _envelope(agent: Agent, mission: Mission) -> dict[str, Any] | None:
    """A vehicle's resolved safety envelope (altitudes above the origin); None for a station."""
    envelope = agent.envelope
    if envelope is None:
        return None
    compiled: dict[str, Any] = {
        "ceiling_m": float(envelope.ceiling_m),
        "floor_m": float(envelope.floor_m),
        "legal_ceiling_m": float(envelope.legal_ceiling_m),
        "margin_m": float(envelope.margin_m),
        "geofence": {
            "default_radius_m": (
                float(envelope.default_radius_m) if envelope.default_radius_m is not None else None
            ),
            "home": _point(envelope.home, mission),
            "include": [_zone(z, mission) for z in envelope.include],
            "exclude": [_zone(z, mission) for z in envelope.exclude],
        },
        "min_separation_m": float(envelope.min_separation_m),
        "separation": {name: float(m) for name, m in sorted(envelope.separation.items())},
        "on_breach": envelope.on_breach,
        "on_near_miss": envelope.on_near_miss,
        "outside": envelope.outside,
        "endurance_s": float(envelope.endurance_s) if envelope.endurance_s is not None else None,
    }
    # Written only when not 0, so that a mission that declares no position error compiles
    # to the config it compiled to before the figure existed, byte for byte.
    if envelope.position_error_m > 0:
        compiled["position_error_m"] = float(envelope.position_error_m)
    peers = {
        other.name: float(other.envelope.position_error_m)
        for other in mission.agents.values()
        if other.name != agent.name
        and other.envelope is not None
        and other.envelope.position_error_m > 0
    }
    if peers:
        compiled["peer_position_error_m"] = dict(sorted(peers.items()))
    return compiled


def _peers(agent: Agent, mission: Mission) -> list[dict[str, Any]]:
    peers = []
    for other in mission.agents.values():
        if other.name == agent.name:
            continue
        sends = {m: t.rate_hz for m, t in other.telemetry.items() if t.reaches(agent.name)}
        peers.append(
            {
                "name": other.name,
                "id": other.id,
                "role": other.role,
                "radio_address": other.radio_address,
                "sends": dict(sorted(sends.items())),
                # A station's Mode Change Request carries the target firmware's number.
                "modes": dict(sorted(other.hardware.modes.items())),
                # Where it may fly, for a station to draw and judge its alarms by. A
                # vehicle keeps its own envelope only: fifty peers' envelopes in every
                # vehicle's config cost its loading (schema validation) seconds.
                "envelope": _envelope(other, mission) if not agent.is_vehicle else None,
            }
        )
    return peers


def _launch(agent: Agent) -> dict[str, Any] | None:
    """How a vehicle gets going (``launch``, defaults filled in); None for a station."""
    if not agent.is_vehicle or agent.launch is None:
        return None
    return {"armed_by": agent.launch.armed_by, "airborne": agent.launch.airborne}


def agent_config(mission: Mission, agent: Agent) -> dict[str, Any]:
    """The compiled config of one agent (plain data, valid against agent-config)."""
    hw = agent.hardware
    is_vehicle = agent.is_vehicle
    return {
        "clark_config": CONFIG_VERSION,
        "generator": f"clark-engine {__version__}",
        "source": {"file": mission.file, "sha256": mission.source_sha256},
        "mission": {
            "id": mission.id,
            "name": mission.name,
            "description": mission.description,
            "agent": agent.name,
            "agent_id": agent.id,
            "loop_hz": mission.loop_hz,
            "heartbeat_timeout_s": mission.heartbeat_timeout_s,
            "origin": {
                "lat": mission.origin.lat_deg,
                "lon": mission.origin.lon_deg,
                "alt_amsl_m": mission.origin.alt_amsl_m,
            },
            "authenticated": mission.key_file is not None,
            "key_file": mission.key_file,
            "tick_phases": list(DEFAULT_TICK_PHASES),
            "log": {
                "level": mission.log_level,
                "mission_log": f"{agent.name}.mission.log",
                "interface_log": f"{agent.name}.interface.log",
                "fleet_csv": f"{agent.name}.fleet.csv",
                "message_log": f"{agent.name}.messages.csv",
            },
        },
        "clark": {
            "testing_mode": False,
            "enable": {
                "radio": hw.part("radio") is not None,
                "autopilot": is_vehicle and hw.part("autopilot") is not None,
                "payload": bool(hw.payloads),
                "gui": not is_vehicle,
            },
            "gui": hw.gui if not is_vehicle else None,
        },
        "agent": {
            "name": agent.name,
            "id": agent.id,
            "role": agent.role,
            "profile": agent.profile,
            "terminal_mode": agent.terminal_mode if is_vehicle else None,
            "failsafe": (
                {**agent.failsafe, "computer_lost_s": agent.computer_lost_s} if is_vehicle else {}
            ),
            "launch": _launch(agent),
            "position": _point(agent.position, mission),
            "hardware": {
                "profiles": dict(sorted(hw.part_profiles.items())),
                "airframe": _part(hw.part("airframe")),
                "autopilot": _part(hw.part("autopilot")),
                "radio": _part(hw.part("radio")),
                "computer": _part(hw.part("computer")),
                "payloads": {
                    name: {"profile": hw.payload_profiles[name], **_part(data)}  # type: ignore[dict-item]
                    for name, data in sorted(hw.payloads.items())
                },
            },
        },
        "telemetry": _telemetry(agent, mission),
        "peers": _peers(agent, mission),
        "envelope": _envelope(agent, mission),
        "machine": _state(agent.behavior, agent, mission) if agent.behavior is not None else None,
    }


def render(config: Mapping[str, Any]) -> str:
    """The exact bytes written for a config: 2-space JSON, keys in build order."""
    return json.dumps(config, indent=2, ensure_ascii=False, allow_nan=False) + "\n"


def compile_mission(mission: Mission, agents: Iterable[str] | None = None) -> dict[str, str]:
    """Render configs: agent name -> file text.

    Args:
        mission: A mission that validated without errors.
        agents: Only these agents (all when None).

    Raises:
        UsageError: An agent name that is not in the mission.
    """
    names = list(mission.agents) if agents is None else list(agents)
    for name in names:
        if name not in mission.agents:
            raise UsageError(
                f"{mission.file}: there is no agent {name!r}; agents: {', '.join(mission.agents)}"
            )
    return {name: render(agent_config(mission, mission.agents[name])) for name in names}


def foreign_files(
    folder: Path, marker: str | None, recognise: Callable[[Path, str], bool]
) -> list[str]:
    """The files in ``folder`` (relative, ``/``-separated) that the engine did not write.

    The engine's own files are those its ``marker`` file lists; without a marker file
    (no ``marker``, or output from before markers) ``recognise`` tells them file by file.

    Raises:
        UsageError: ``folder`` is a file, or cannot be read.
    """
    if not folder.exists():
        return []
    if not folder.is_dir():
        raise UsageError(f"{folder} is a file, not a folder; choose another output folder")
    listed: set[str] | None = None
    try:
        if marker is not None:
            data = json.loads((folder / marker).read_text(encoding="utf-8"))
            if isinstance(data, dict) and isinstance(data.get("files"), list):
                listed = {str(name) for name in data["files"]}
    except (OSError, ValueError):
        listed = None
    try:
        present = sorted(
            path.relative_to(folder).as_posix()
            for path in folder.rglob("*")
            if not path.is_dir() or path.is_symlink()
        )
    except OSError as exc:
        raise UsageError(f"cannot read {folder}: {exc.strerror or exc}") from None
    return [
        name
        for name in present
        if name != marker
        and not (name in listed if listed is not None else recognise(folder / name, name))
    ]


def write_marker(folder: Path, marker: str, what: str) -> None:
    """List every file in ``folder`` in its ``marker`` file, saying the engine wrote them."""
    files = sorted(
        path.relative_to(folder).as_posix()
        for path in folder.rglob("*")
        if not path.is_dir() and path.name != marker
    )
    payload = {"written_by": f"clark-engine {__version__}", "what": what, "files": files}
    (folder / marker).write_text(json.dumps(payload, indent=2) + "\n", encoding="utf-8")


def swap_in(staging: Path, target: Path) -> None:
    """Put the complete folder ``staging`` in the place of ``target`` (a sibling).

    Renames only: the old folder is moved aside, the new one into place, then the
    old one deleted. Check :func:`foreign_files` first: this replaces the whole folder.

    Raises:
        OSError: A rename failed (the old folder is back in place when it can be).
    """
    if not target.exists():
        os.rename(staging, target)
        return
    old = Path(tempfile.mkdtemp(prefix=f".{target.name}.old-", dir=target.parent))
    os.rename(target, old / target.name)
    try:
        os.rename(staging, target)
    except OSError:
        os.rename(old / target.name, target)
        raise
    finally:
        shutil.rmtree(old, ignore_errors=True)


def _is_config(path: Path, name: str) -> bool:
    """A config ``clark compile`` wrote: ``<agent>.json`` holding a ``clark_config`` key.

    Every config says so itself, so the configs folder needs no marker file (and holds
    nothing but what is copied to the mission computers).
    """
    if "/" in name or not name.endswith(".json") or path.is_symlink():
        return False
    try:
        data = json.loads(path.read_text(encoding="utf-8"))
    except (OSError, ValueError):
        return False
    return isinstance(data, dict) and "clark_config" in data


def write_configs(
    files: Mapping[str, str], out_dir: Path, mission_name: str, keep: Iterable[str] = ()
) -> Path:
    """Write configs to ``out_dir/<mission>/<agent>.json`` all at once or not at all.

    The folder is written complete beside the target (a hidden sibling) and moved
    into place only when every file was written, so a failure never leaves a half
    mission behind. It replaces the configs an earlier compile wrote there, so the
    config of an agent removed from the mission does not linger; a file the engine
    did not write (anything but a compiled config, :func:`_is_config`) is never
    deleted: the compile refuses instead.

    Args:
        files: Agent name -> config text (:func:`compile_mission`).
        out_dir: The ``-o`` folder.
        mission_name: The mission's name, the folder inside ``out_dir``.
        keep: Agents whose config from an earlier compile stays as it is (``--agent``
            compiles a few agents of a mission; the others' configs are kept).

    Returns:
        The folder the configs are in.

    Raises:
        UsageError: The output folder cannot be created or written, or it holds
            files that ``clark compile`` did not write.
    """
    target = out_dir / mission_name
    foreign = foreign_files(target, None, _is_config)
    if foreign:
        shown = ", ".join(foreign[:5]) + (
            f" and {len(foreign) - 5} more" if len(foreign) > 5 else ""
        )
        raise UsageError(
            f"{target} holds files clark compile did not write ({shown}); nothing written: "
            "move them elsewhere or choose another output folder"
        )
    try:
        out_dir.mkdir(parents=True, exist_ok=True)
        staging = Path(tempfile.mkdtemp(prefix=f".{mission_name}.incomplete-", dir=out_dir))
        staging.chmod(0o755)  # mkdtemp's 700 would become the configs folder's mode
    except OSError as exc:
        raise UsageError(f"cannot create {out_dir}: {exc.strerror or exc}") from None
    try:
        for name, text in files.items():
            (staging / f"{name}.json").write_text(text, encoding="utf-8")
        for name in keep:
            earlier = target / f"{name}.json"
            if name not in files and earlier.is_file():
                shutil.copy2(earlier, staging / earlier.name)
        swap_in(staging, target)
    except OSError as exc:
        raise UsageError(f"cannot write configs to {target}: {exc.strerror or exc}") from None
    finally:
        shutil.rmtree(staging, ignore_errors=True)
    return target
