"""Validate a file: read, load, check against its schema, resolve, run every check.

This is the front door of the mission layer. It recognises what a file is (a
mission, a behaviour block or a hardware profile), reports every problem it
finds rather than the first, and hands back the resolved mission when there
are no errors, ready to compile.
"""

from __future__ import annotations

import hashlib
import os
from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from clark_engine.data import data_dir
from clark_engine.errors import UsageError
from clark_engine.mission import envelope
from clark_engine.mission.blocks import BlockLibrary
from clark_engine.mission.cross_checks import run_all
from clark_engine.mission.findings import DocPath, Finding, Location, error, warning
from clark_engine.mission.geo import LocalPoint, Origin, parse_point
from clark_engine.mission.model import (
    ARMED_BY,
    DEFAULT_COMPUTER_LOST_S,
    TELEMETRY_MESSAGES,
    Agent,
    Launch,
    Mission,
    Telemetry,
)
from clark_engine.mission.paths import confine, too_long
from clark_engine.mission.plugin_data import BLOCKS_GROUP, PROFILES_GROUP, plugin_folders
from clark_engine.mission.profiles import HardwareResolver, ProfileLibrary
from clark_engine.mission.schemas import validate_data
from clark_engine.mission.state_tree import BehaviorResolver
from clark_engine.mission.yaml_loader import Document, YamlLoadError, decode_text, load_yaml


@dataclass(slots=True)
class Validation:
    """The outcome of validating one file.

    Attributes:
        file: The file as the user named it.
        kind: ``mission``, ``block`` or ``profile``.
        findings: Every finding, sorted by position.
        mission: The resolved mission, when the file is a mission without errors.
    """

    file: str
    kind: str
    findings: list[Finding] = field(default_factory=list)
    mission: Mission | None = None

    @property
    def errors(self) -> list[Finding]:
        """The findings that make the file invalid."""
        return [f for f in self.findings if f.is_error]

    @property
    def ok(self) -> bool:
        """True when there are no errors (warnings allowed)."""
        return not self.errors


def display_path(path: Path) -> str:
    """How to show a path in findings: relative to the working directory when inside it."""
    try:
        return os.path.relpath(path) if path.resolve().is_relative_to(Path.cwd()) else str(path)
    except (OSError, ValueError):
        return str(path)


#: Longest file path a command reads (characters): Linux's PATH_MAX.
MAX_COMMAND_PATH_CHARS = 4096


def read_source(path: Path) -> bytes:
    """Read a file the user named, turning OS errors into usage errors (exit code 2).

    Raises:
        UsageError: Missing, a directory, or unreadable.
    """
    shown = str(path)
    # Before any filesystem call: Path.is_dir() raises on a name too long for the system.
    long = too_long(shown, MAX_COMMAND_PATH_CHARS)
    if long is not None:
        raise UsageError(f"{shown[:60]}...: the path is too long ({long})")
    try:
        if path.is_dir():
            raise UsageError(
                f"{shown} is a directory; give a mission file (e.g. {shown}/mission.yaml)"
            )
        return path.read_bytes()
    except FileNotFoundError:
        raise UsageError(f"{shown}: no such file") from None
    except PermissionError:
        raise UsageError(f"{shown}: permission denied; check the file's permissions") from None
    except OSError as exc:
        raise UsageError(f"{shown}: cannot read it ({exc.strerror or exc})") from None


#: Findings that already explain a value, after which a schema type error there says nothing new.
_EXPLAINING = frozenset(
    {
        "E-YAML-BOOL-WORD",
        "E-YAML-VALUE",
        "E-YAML-TAG",
        "E-BLOCK-PARAM",
        "E-STATE-UNKNOWN",
        "E-INCLUDE-PATH",
    }
)
_GENERIC = frozenset({"E-TYPE", "E-VALUE", "E-FORMAT", "E-NAME"})


def _dedupe(findings: list[Finding]) -> list[Finding]:
    """Sorted findings without repeats, and without generic errors where a specific one is."""
    explained = {
        (f.location.file, f.location.line, f.location.column)
        for f in findings
        if f.code in _EXPLAINING
    }
    seen: set[tuple[str, int | None, int | None, str, str]] = set()
    out = []
    for f in sorted(findings, key=Finding.sort_key):
        where = (f.location.file, f.location.line, f.location.column)
        if f.code in _GENERIC and where in explained:
            continue
        key = (f.location.file, f.location.line, f.location.column, f.code, f.message)
        if key not in seen:
            seen.add(key)
            out.append(f)
    return out


def validate_path(path: Path, shown: str | None = None) -> Validation:
    """Validate one file, whatever it is.

    Raises:
        UsageError: The file cannot be read.
    """
    shown = shown or display_path(path)
    raw = read_source(path)
    try:
        doc = load_yaml(decode_text(raw, shown), shown)
    except YamlLoadError as exc:
        return Validation(shown, "unknown", _dedupe(exc.findings))
    data = doc.data
    kind = "mission"
    if isinstance(data, dict) and "clark" not in data:
        if "block" in data:
            kind = "block"
        elif "profile" in data and "kind" in data:
            kind = "profile"
    if kind == "block":
        result = _validate_block(path, doc)
    elif kind == "profile":
        result = _validate_profile(path, doc)
    else:
        result = _validate_mission(path, doc, raw)
    result.findings = _dedupe([*doc.findings, *result.findings])
    if not result.ok:
        result.mission = None
    return result


def _validate_block(path: Path, doc: Document) -> Validation:
    library = BlockLibrary([(path.parent, display_path(path.parent))])
    name = path.stem
    block = library.get(name)
    findings = list(library.findings)
    if block is not None:
        # Check the machine as if the block were used with its defaults, and with the
        # first of its declared examples for required parameters that have no default.
        given: dict[str, Any] = {}
        unchecked: list[str] = []
        properties = block.parameters.get("properties", {})
        for param in block.parameters.get("required", []):
            prop = properties.get(param, {})
            if "default" in prop:
                continue
            if prop.get("examples"):
                given[param] = prop["examples"][0]
            else:
                unchecked.append(param)
        if unchecked:
            findings.append(
                warning(
                    "W-BLOCK-UNCHECKED",
                    doc.location(("parameters", "required")),
                    f"the machine was not checked on its own: required parameter(s) "
                    f"{', '.join(unchecked)} have no default or examples; add examples: [...] "
                    "to each (it is still checked wherever a mission uses the block)",
                )
            )
        else:
            resolver = BehaviorResolver(library)
            resolver.resolve({"use": name, "with": given}, doc, ())
            findings.extend(resolver.findings)
    return Validation(doc.file, "block", findings)


def _validate_profile(path: Path, doc: Document) -> Validation:
    shipped = data_dir("hardware_profiles")
    folders: list[tuple[Path, str] | tuple[Path, str, str]] = [(shipped, display_path(shipped))]
    inside = path.resolve().is_relative_to(shipped.resolve())
    for plugin in plugin_folders(PROFILES_GROUP):
        if path.resolve().is_relative_to(plugin.path.resolve()):
            # The plugin's file being validated: shown as the user named it, as a shipped one.
            folders.append((plugin.path, display_path(plugin.path), plugin.origin))
            inside = True
        else:
            folders.append((plugin.path, plugin.shown, plugin.origin))
    if not inside:
        folders.append((path.parent, display_path(path.parent)))
    library = ProfileLibrary(folders)
    composed = library.compose(path.stem) if path.stem in library.names() else None
    findings = [f for f in library.findings if f.location.file == doc.file or f.is_error]
    if composed is None and not findings:
        findings.extend(validate_data("hardware-profile", doc.data, doc))
    return Validation(doc.file, "profile", findings)


def _libraries(
    path: Path, data: Mapping[str, Any], doc: Document
) -> tuple[ProfileLibrary, BlockLibrary, list[Finding]]:
    findings: list[Finding] = []
    profile_dirs: list[tuple[Path, str] | tuple[Path, str, str]] = [
        (data_dir("hardware_profiles"), display_path(data_dir("hardware_profiles")))
    ]
    block_dirs: list[tuple[Path, str] | tuple[Path, str, str]] = [
        (data_dir("behaviors"), display_path(data_dir("behaviors")))
    ]
    declared = data.get("include")
    include: Mapping[str, Any] = declared if isinstance(declared, Mapping) else {}
    for key, dirs in (("hardware_profiles", profile_dirs), ("behaviors", block_dirs)):
        for i, folder in enumerate(include.get(key) or []):
            if not isinstance(folder, str):
                continue
            long = too_long(folder)
            if long is not None:
                findings.append(
                    error(
                        "E-INCLUDE-PATH",
                        doc.location(("include", key, i)),
                        f"this folder's path is too long: {long}; name a folder next to the "
                        "mission, e.g. my_" + key,
                    )
                )
                continue
            shipped = [data_dir("hardware_profiles"), data_dir("behaviors")]
            confined, why = confine(path.parent, folder, shipped)
            if confined is None:
                findings.append(
                    error(
                        "E-INCLUDE-PATH",
                        doc.location(("include", key, i)),
                        f"a mission may include only folders inside its own folder (or the "
                        f"shipped {key}), and this one is not: {why}; move the folder next to "
                        "the mission and name it relative to the mission, e.g. my_" + key,
                    )
                )
                continue
            full = confined
            if not full.is_dir():
                findings.append(
                    error(
                        "E-INCLUDE-MISSING",
                        doc.location(("include", key, i)),
                        f"{folder!r} is not a folder next to the mission ({full}); fix the path",
                    )
                )
                continue
            if any(full == d[0].resolve() for d in dirs):
                continue
            dirs.append((full, display_path(full)))
    # Then the installed plugins' folders (docs/plugins.md), searched as the others are.
    for group, dirs in ((PROFILES_GROUP, profile_dirs), (BLOCKS_GROUP, block_dirs)):
        for plugin in plugin_folders(group):
            if not any(plugin.path.resolve() == d[0].resolve() for d in dirs):
                dirs.append((plugin.path, plugin.shown, plugin.origin))
    return ProfileLibrary(profile_dirs), BlockLibrary(block_dirs), findings


def installed_libraries() -> tuple[ProfileLibrary, BlockLibrary]:
    """The hardware profiles and behaviour blocks every mission sees, before its ``include:``.

    The shipped folders, then the installed plugins' (``clark profiles``, ``clark behaviors
    --blocks``); each library's ``findings`` hold any name two of them both declare.

    Raises:
        PluginError: A plugin's entry point fails to load or names no folder.
    """
    profile_dirs: list[tuple[Path, str] | tuple[Path, str, str]] = [
        (data_dir("hardware_profiles"), display_path(data_dir("hardware_profiles")))
    ]
    block_dirs: list[tuple[Path, str] | tuple[Path, str, str]] = [
        (data_dir("behaviors"), display_path(data_dir("behaviors")))
    ]
    for group, dirs in ((PROFILES_GROUP, profile_dirs), (BLOCKS_GROUP, block_dirs)):
        dirs.extend((p.path, p.shown, p.origin) for p in plugin_folders(group))
    return ProfileLibrary(profile_dirs), BlockLibrary(block_dirs)


def _dirty(findings: list[Finding], prefix: DocPath, *, own: bool = False) -> bool:
    """True when an error lies under ``prefix`` (or exactly at it, with ``own``)."""
    n = len(prefix)
    if own:
        return any(f.is_error and f.location.path == prefix for f in findings)
    return any(f.is_error and f.location.path[:n] == prefix for f in findings)


#: Mission settings every later check depends on; with one of them broken, checks stop there.
_NEEDED_SETTINGS = ("id", "name", "loop_hz", "origin", "heartbeat_timeout_s")


def _validate_mission(path: Path, doc: Document, raw: bytes) -> Validation:
    result = Validation(doc.file, "mission")
    schema_findings = validate_data("mission", doc.data, doc)
    result.findings.extend(schema_findings)
    data = doc.data
    root_broken = any(
        f.is_error and f.location.path in ((), ("agents",), ("mission",)) for f in schema_findings
    )
    settings_broken = any(_dirty(schema_findings, ("mission", key)) for key in _NEEDED_SETTINGS)
    if not isinstance(data, dict) or root_broken or settings_broken:
        return result
    profiles, blocks, include_findings = _libraries(path, data, doc)
    result.findings.extend(include_findings)
    mission = _build_mission(doc, data, raw, schema_findings, profiles, blocks, result.findings)
    result.findings.extend(profiles.findings)
    result.findings.extend(blocks.findings)
    result.mission = mission
    return result


def _campaign_section(
    doc: Document, data: dict[str, Any], schema_findings: list[Finding]
) -> dict[str, Any]:
    """The mission's ``campaign:`` (clark campaign) and where each key was written."""
    declared = data.get("campaign")
    if not isinstance(declared, dict) or _dirty(schema_findings, ("campaign",)):
        return {}
    locations = {key: doc.location(("campaign", key)) for key in declared}
    for name in declared.get("min_pass_rates") or {}:
        locations[f"min_pass_rates.{name}"] = doc.location(("campaign", "min_pass_rates", name))
    return {"campaign": dict(declared), "campaign_locations": locations}


def _build_mission(
    doc: Document,
    data: dict[str, Any],
    raw: bytes,
    schema_findings: list[Finding],
    profiles: ProfileLibrary,
    blocks: BlockLibrary,
    findings: list[Finding],
) -> Mission:
    section = data["mission"]

    def listed(key: str) -> list[dict[str, Any]]:
        value = data.get(key)
        return (
            list(value) if isinstance(value, list) and not _dirty(schema_findings, (key,)) else []
        )

    operator, faults = listed("operator"), listed("faults")
    declared_sim = data.get("sim")
    sim: dict[str, Any] = declared_sim if isinstance(declared_sim, dict) else {}
    declared_checks = data.get("checks")
    checks: list[dict[str, Any]] = (
        list(declared_checks)
        if isinstance(declared_checks, list) and not _dirty(schema_findings, ("checks",))
        else []
    )
    origin_raw = section["origin"]
    origin = Origin(
        float(origin_raw["lat"]), float(origin_raw["lon"]), float(origin_raw["alt_amsl_m"])
    )
    mission = Mission(
        file=doc.file,
        id=int(section["id"]),
        name=str(section["name"]),
        loop_hz=float(section["loop_hz"]),
        heartbeat_timeout_s=float(section.get("heartbeat_timeout_s", 3.0)),
        origin=origin,
        log_level=str(section.get("log_level", "INFO")),
        agents={},
        description=section.get("description"),
        source_sha256=hashlib.sha256(raw).hexdigest(),
        key_file=section.get("key_file"),
        operator=operator,
        operator_locations=[doc.location(("operator", i)) for i in range(len(operator))],
        faults=faults,
        fault_locations=[doc.location(("faults", i)) for i in range(len(faults))],
        sim=dict(sim) if not _dirty(schema_findings, ("sim",)) else {},
        sim_locations={key: doc.location(("sim", key)) for key in sim},
        locations={key: doc.location(("mission", key)) for key in section},
        checks=checks,
        check_locations=[doc.location(("checks", i)) for i in range(len(checks))],
        **_campaign_section(doc, data, schema_findings),
    )
    hardware = HardwareResolver(profiles)
    resolver = BehaviorResolver(blocks)
    bad_states: set[tuple[str, tuple[str, ...]]] = set()
    for name, agent_raw in data["agents"].items():
        agent_path: DocPath = ("agents", name)
        if (
            not isinstance(agent_raw, dict)
            or any(
                _dirty(schema_findings, (*agent_path, key))
                for key in ("id", "profile", "hardware", "role")
            )
            or (_dirty(schema_findings, agent_path) and not ({"id", "profile"} <= set(agent_raw)))
        ):
            mission.unresolved.add(name)
            continue
        agent = _build_agent(doc, name, agent_raw, mission, hardware, schema_findings, findings)
        if agent is None:
            mission.unresolved.add(name)
            continue
        mission.agents[name] = agent
    findings.extend(_envelopes(doc, data, mission, schema_findings))
    # Behaviours last: checks inside them look at every agent's telemetry and hardware.
    for name, agent in mission.agents.items():
        raw_behavior = agent.raw.get("behavior")
        if not isinstance(raw_behavior, dict) or (
            _dirty(schema_findings, ("agents", name, "behavior"))
            and _structural(schema_findings, ("agents", name, "behavior"))
        ):
            continue
        agent.behavior = resolver.resolve(raw_behavior, doc, ("agents", name, "behavior"))
        bad_states |= {(name, state_path) for state_path in resolver.bad_paths}
    findings.extend(resolver.findings)
    findings.extend(run_all(mission, bad_states))
    return mission


def _envelopes(
    doc: Document, data: dict[str, Any], mission: Mission, schema_findings: list[Finding]
) -> list[Finding]:
    """Read the mission's envelope and each vehicle's, check them, resolve each vehicle's.

    A vehicle whose own envelope the schema rejected gets none (its error says why, and
    the checks that need it wait); a broken mission envelope leaves every vehicle without.
    """
    if _dirty(schema_findings, ("envelope",)):
        return []
    mission.envelope = envelope.read_decl(
        doc, ("envelope",), data.get("envelope"), mission.origin, "mission", doc.location(())
    )
    written: dict[str, envelope.EnvelopeDecl] = {}
    for name, agent in mission.agents.items():
        path: DocPath = ("agents", name, "envelope")
        if _dirty(schema_findings, path):
            continue
        decl = envelope.read_decl(
            doc, path, agent.raw.get("envelope"), mission.origin, name, agent.location
        )
        agent.envelope_decl = decl
        if "envelope" in agent.raw:
            written[name] = decl
        if agent.is_vehicle:
            agent.envelope = envelope.resolve(
                mission.envelope,
                decl,
                airframe=agent.hardware.part("airframe"),
                radio_range_m=agent.hardware.radio_range_m,
                home=agent.position,
                name=name,
            )
    vehicles = [a.name for a in mission.agents.values() if a.is_vehicle]
    stations = [a.name for a in mission.stations]
    return list(
        envelope.check_decl(mission.envelope, written, vehicles, stations, mission.unresolved)
    )


#: Schema errors about one scalar's value (a name's spelling, a number's range): the
#: behaviour around it still has its shape, and is resolved and checked with the rest.
_VALUE_ERRORS = frozenset({"E-FORMAT", "E-NAME", "E-RANGE", "E-VALUE"})


def _structural(findings: list[Finding], prefix: DocPath) -> bool:
    """True when the errors under ``prefix`` are about shape, not values.

    Errors in parameters (under ``with``) and errors about one scalar's value (a
    transition to ``Home``) leave the behaviour's shape intact: it is still resolved,
    so that the errors elsewhere in it are reported too, and the resolver reports the
    value again with what it knows (``did you mean 'home'?``).
    """
    n = len(prefix)
    for f in findings:
        if not f.is_error or f.location.path[:n] != prefix:
            continue
        rest = f.location.path[n:]
        if "with" not in rest and f.code not in _VALUE_ERRORS:
            return True
    return False


def _build_agent(
    doc: Document,
    name: str,
    raw: dict[str, Any],
    mission: Mission,
    hardware_resolver: HardwareResolver,
    schema_findings: list[Finding],
    findings: list[Finding],
) -> Agent | None:
    path: DocPath = ("agents", name)

    def clean(key: str) -> Any:
        """The agent's value for ``key`` when the schema found nothing wrong in it."""
        return None if _dirty(schema_findings, (*path, key)) else raw.get(key)

    overrides = raw.get("hardware") or {}
    result = hardware_resolver.resolve(
        name,
        str(raw["profile"]),
        doc.location((*path, "profile")),
        overrides,
        doc,
        (*path, "hardware"),
    )
    findings.extend(result.findings)
    hardware = result.hardware
    if hardware is None:
        return None
    role = clean("role") or hardware.role
    if role != hardware.role:
        findings.append(
            error(
                "E-ROLE",
                doc.location((*path, "role")),
                f"role {role!r} contradicts profile {hardware.platform!r}, which is a "
                f"{hardware.role}; remove role: or name {'an' if role == 'mcs' else 'a'} {role} "
                "platform",
            )
        )
        return None
    telemetry: dict[str, Telemetry] = {}
    declared = raw.get("telemetry")
    if isinstance(declared, Mapping) and not _dirty(
        schema_findings, (*path, "telemetry"), own=True
    ):
        for message in TELEMETRY_MESSAGES:
            spec = declared.get(message)
            if spec is None or _dirty(schema_findings, (*path, "telemetry", message)):
                continue
            where = doc.location((*path, "telemetry", message))
            if isinstance(spec, Mapping):
                telemetry[message] = Telemetry(
                    message, float(spec["rate_hz"]), tuple(spec.get("to", ())), where
                )
            else:
                telemetry[message] = Telemetry(message, float(spec), (), where)
    position = LocalPoint(0.0, 0.0, 0.0)
    if clean("position") is not None:
        position = parse_point(raw["position"], mission.origin)
    radio = hardware.part("radio") or {}
    autopilot = hardware.part("autopilot") or {}
    terminal = clean("terminal_mode") or autopilot.get("terminal_mode")
    locations = {key: doc.location((*path, key)) for key in raw}
    radio_override = overrides.get("radio") if isinstance(overrides, Mapping) else None
    if isinstance(radio_override, Mapping) and "address" in radio_override:
        locations["radio_address"] = doc.location((*path, "hardware", "radio", "address"))
    elif "radio" in result.origins:
        locations["radio_address"] = result.origins["radio"].locate(
            ("address",), doc.location(path)
        )
    locations.setdefault("telemetry", doc.location(path))
    if role == "vehicle" and autopilot and autopilot.get("safety_setup") is False:
        where = (
            result.origins["autopilot"].locate(("safety_setup",), doc.location(path))
            if "autopilot" in result.origins
            else doc.location(path)
        )
        findings.append(
            warning(
                "W-AUTOPILOT-SAFETY-OFF",
                where,
                f"{name}'s autopilot profile says safety_setup: false, so the engine will not "
                "set the autopilot's own fence or its reaction to a dead mission computer: "
                "if this computer stops, the vehicle flies on to its last target. Use it "
                "only on the bench; remove it for any flight",
            )
        )
    # Launch checks compare launch with the start position; with either one broken the
    # schema's error comes first and they wait.
    launch = (
        _launch(doc, path, raw)
        if role == "vehicle"
        and not any(_dirty(schema_findings, (*path, key)) for key in ("launch", "position"))
        else None
    )
    return Agent(
        name=name,
        id=int(raw["id"]),
        role=role,
        profile=str(raw["profile"]),
        hardware=hardware,
        telemetry=telemetry,
        behavior=None,
        failsafe=_failsafe(clean("failsafe") or {}, role, hardware.part("airframe")),
        terminal_mode=str(terminal) if terminal is not None else None,
        position=position,
        radio_address=str(radio["address"]) if radio.get("address") is not None else None,
        location=doc.location(path),
        launch=launch,
        raw=raw,
        locations=locations,
        computer_lost_s=float(
            (clean("failsafe") or {}).get("computer_lost_s", DEFAULT_COMPUTER_LOST_S)
        ),
    )


def _failsafe(
    declared: Mapping[str, Any], role: str, airframe: Mapping[str, Any] | None
) -> dict[str, str]:
    """The agent's failsafe actions, defaults filled in (``computer_lost`` for vehicles only).

    A vehicle's autopilot returns to launch when its mission computer falls silent, a
    rover's holds: a rover's home is no safer than where it stopped, and it cannot land.
    """
    actions = {"mcs_lost": str(declared.get("mcs_lost", "hold"))}
    if role == "vehicle":
        rover = (airframe or {}).get("class") == "rover"
        actions["computer_lost"] = str(declared.get("computer_lost", "hold" if rover else "rtl"))
    return actions


def _launch(doc: Document, path: DocPath, raw: Mapping[str, Any]) -> Launch:
    """A vehicle's ``launch`` as written, its defaults filled in, with where each part is."""
    declared = raw.get("launch")
    given: Mapping[str, Any] = declared if isinstance(declared, Mapping) else {}
    where = (*path, "launch")
    return Launch(
        armed_by=str(given.get("armed_by", ARMED_BY[0])),
        airborne=bool(given.get("airborne", False)),
        location=doc.location(where) if "launch" in raw else doc.location(path),
        key_locations=tuple((key, doc.location((*where, key))) for key in given),
    )


def location_of(mission: Mission, key: str) -> Location:
    """Where a mission setting was written."""
    return mission.locations.get(key, Location(mission.file, 1, 1, ("mission", key)))
