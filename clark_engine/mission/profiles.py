"""Hardware profiles: find them, compose them (``extends:``), resolve an agent's hardware.

A profile file describes one part (airframe, autopilot, radio, computer,
payload) or a platform that composes parts. Profiles extend one another and a
mission may override any field per agent; the result is deep-merged: mappings
merge key by key, lists and scalars replace. Every merged value remembers the
file and line it came from, so a finding about it points there.
"""

from __future__ import annotations

import copy
import difflib
import functools
import json
from collections.abc import Iterable, Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from jsonschema import Draft202012Validator

from clark_engine.mission.findings import DocPath, Finding, Location, error
from clark_engine.mission.model import PARTS, Channel, Hardware
from clark_engine.mission.plugin_data import clash_message
from clark_engine.mission.schemas import validate_data
from clark_engine.mission.yaml_loader import Document, YamlLoadError, decode_text, load_yaml

PROFILE_KINDS = ("airframe", "autopilot", "radio", "computer", "payload", "platform")
META_KEYS = frozenset({"profile", "kind", "extends", "abstract", "description", "source"})


def deep_merge(base: Any, over: Any) -> Any:
    """Merge ``over`` onto ``base``: mappings key by key, anything else replaced.

    A mapping that changes its ``kind`` (a serial connection becoming a UDP one) is
    replaced whole: the old kind's fields (device, baud) mean nothing to the new one.
    """
    if (
        isinstance(base, Mapping)
        and isinstance(over, Mapping)
        and not ("kind" in over and "kind" in base and over["kind"] != base["kind"])
    ):
        out = dict(base)
        for key, value in over.items():
            out[key] = deep_merge(base[key], value) if key in base else copy.deepcopy(value)
        return out
    return copy.deepcopy(over)


def _record(
    origins: dict[DocPath, Location], data: Any, doc: Document, src: DocPath, dst: DocPath
) -> None:
    """Remember where every leaf of ``data`` (found at ``src`` in ``doc``) was written."""
    origins[dst] = doc.location(src)
    if isinstance(data, Mapping):
        for key, value in data.items():
            _record(origins, value, doc, (*src, key), (*dst, key))
    elif isinstance(data, list):
        for i, value in enumerate(data):
            _record(origins, value, doc, (*src, i), (*dst, i))


def _exists(data: Any, path: DocPath) -> bool:
    """True when ``path`` leads to a value inside ``data``."""
    for part in path:
        try:
            data = data[part]
        except (KeyError, IndexError, TypeError):
            return False
    return True


@dataclass(slots=True)
class Composed:
    """A merged profile (or part) with the origin of each of its values."""

    data: dict[str, Any]
    origins: dict[DocPath, Location] = field(default_factory=dict)

    def locate(self, path: DocPath, fallback: Location) -> Location:
        """Where the value at ``path`` was written, or its nearest written ancestor."""
        probe = path
        while probe:
            if probe in self.origins:
                return self.origins[probe]
            probe = probe[:-1]
        return self.origins.get((), fallback)

    def overlay(self, data: Mapping[str, Any], doc: Document, src: DocPath) -> None:
        """Merge fields written at ``src`` in ``doc`` onto this one."""
        self.data = deep_merge(self.data, dict(data))
        _record(self.origins, data, doc, src, ())
        # Values that were replaced whole (a kind change) keep no stale origins.
        self.origins = {p: loc for p, loc in self.origins.items() if _exists(self.data, p)}


@dataclass(slots=True)
class _Entry:
    name: str
    file: Path
    display: str
    origin: str = ""
    doc: Document | None = None
    loaded: bool = False


class ProfileLibrary:
    """All hardware profiles visible to one mission, loaded on first use.

    Profiles are indexed by file name when the library is made (cheap: no file
    is parsed) and read, checked and merged only when a mission names them.
    """

    def __init__(self, folders: Sequence[tuple[Path, str] | tuple[Path, str, str]]) -> None:
        """Index ``folders``: (folder, how to show its paths in findings[, plugin origin]).

        A folder an installed plugin adds carries its origin (which plugin and entry
        point, :mod:`clark_engine.mission.plugin_data`), which a duplicate name names.
        """
        self._entries: dict[str, _Entry] = {}
        self.findings: list[Finding] = []
        self._composed: dict[str, Composed | None] = {}
        for entry in folders:
            folder, shown = entry[0], entry[1]
            origin = entry[2] if len(entry) == 3 else ""
            for file in sorted(folder.rglob("*.yaml")):
                name = file.stem
                display = f"{shown}/{file.relative_to(folder).as_posix()}"
                taken = self._entries.get(name)
                if taken is not None:
                    message = (
                        clash_message(
                            "profile", name, (display, origin), (taken.display, taken.origin)
                        )
                        if origin or taken.origin
                        else f"a profile named {name!r} already exists in {taken.display}; "
                        "rename one of them"
                    )
                    self.findings.append(
                        error("E-PROFILE-DUPLICATE", Location(display, 1, 1), message)
                    )
                    continue
                self._entries[name] = _Entry(name, file, display, origin)

    def origin_of(self, name: str) -> tuple[str, str]:
        """(how the profile's file is shown, the plugin that adds it or "")."""
        entry = self._entries[name]
        return entry.display, entry.origin

    def names(self, kind: str | None = None) -> list[str]:
        """Names of the profiles (of one kind when given)."""
        if kind is None:
            return sorted(self._entries)
        return sorted(n for n in self._entries if self.kind_of(n) == kind)

    def extending(self, name: str) -> list[str]:
        """Names of the profiles whose ``extends`` is ``name``."""
        out = []
        for other in self.names():
            doc = self._load(other)
            if doc is not None and isinstance(doc.data, dict) and doc.data.get("extends") == name:
                out.append(other)
        return out

    def kind_of(self, name: str) -> str | None:
        """The kind a profile declares, or None when it cannot be read."""
        doc = self._load(name)
        if doc is None or not isinstance(doc.data, dict):
            return None
        kind = doc.data.get("kind")
        return kind if isinstance(kind, str) else None

    def document(self, name: str) -> Document | None:
        """The loaded file of a profile, or None when it is unknown or unreadable."""
        return self._load(name)

    def _load(self, name: str) -> Document | None:
        entry = self._entries.get(name)
        if entry is None:
            return None
        if not entry.loaded:
            entry.loaded = True
            try:
                doc = load_yaml(decode_text(entry.file.read_bytes(), entry.display), entry.display)
            except YamlLoadError as exc:
                self.findings.extend(exc.findings)
                return None
            self.findings.extend(doc.findings)
            problems = validate_data("hardware-profile", doc.data, doc)
            if isinstance(doc.data, dict) and doc.data.get("profile") not in (None, name):
                problems.append(
                    error(
                        "E-PROFILE-NAME",
                        doc.location(("profile",)),
                        f"the file is {entry.file.name} but names profile "
                        f"{doc.data.get('profile')!r}; make the two agree",
                    )
                )
            self.findings.extend(problems)
            if not any(p.is_error for p in problems) and not any(f.is_error for f in doc.findings):
                entry.doc = doc
        return entry.doc

    def compose(self, name: str) -> Composed | None:
        """The profile with its ``extends`` chain merged, or None (findings say why)."""
        if name in self._composed:
            return self._composed[name]
        self._composed[name] = None  # guards against extends cycles while composing
        chain: list[Document] = []
        seen: list[str] = []
        current: str | None = name
        while current is not None:
            if current in seen:
                self.findings.append(
                    error(
                        "E-PROFILE-CYCLE",
                        chain[-1].location(("extends",)),
                        "profiles extend each other in a cycle ("
                        + " -> ".join([*seen, current])
                        + "); break the cycle",
                    )
                )
                return None
            doc = self._load(current)
            if doc is None:
                if chain and current not in self._entries:
                    self.findings.append(
                        error(
                            "E-PROFILE-UNKNOWN",
                            chain[-1].location(("extends",)),
                            f"extends unknown profile {current!r}; "
                            + _suggest(current, self._entries),
                        )
                    )
                return None
            if chain and doc.data.get("kind") != chain[0].data.get("kind"):
                self.findings.append(
                    error(
                        "E-PROFILE-KIND",
                        chain[-1].location(("extends",)),
                        f"a {chain[0].data.get('kind')} profile cannot extend {current!r}, "
                        f"which is {_a(doc.data.get('kind'))}; extend a profile of the same kind",
                    )
                )
                return None
            seen.append(current)
            chain.append(doc)
            parent = doc.data.get("extends")
            current = parent if isinstance(parent, str) else None
        composed = Composed({})
        for doc in reversed(chain):
            body = {k: v for k, v in doc.data.items() if k not in META_KEYS}
            composed.overlay(body, doc, ())
        composed.data["abstract"] = bool(chain[0].data.get("abstract", False))
        self._composed[name] = composed
        return composed


def _a(word: object) -> str:
    """The word with its indefinite article: an airframe, a radio, an mcs."""
    text = str(word)
    return f"an {text}" if text[:1] in "aeio" or text.startswith("mcs") else f"a {text}"


def _unusable(name: str, where: Location) -> Finding:
    return error(
        "E-PROFILE-INVALID",
        where,
        f"profile {name!r} cannot be used because its file has errors (reported with it); "
        "fix that file",
    )


def _suggest(word: str, choices: Iterable[str]) -> str:
    options = sorted(choices)
    close = difflib.get_close_matches(word, options, n=1)
    if close:
        return f"did you mean {close[0]!r}?"
    if options and len(options) <= 40:
        return "choose one of: " + ", ".join(options)
    return "see docs/hardware-profiles.md for the list"


@dataclass(slots=True)
class HardwareResult:
    """What resolving one agent's hardware produced."""

    hardware: Hardware | None
    origins: dict[str, Composed] = field(default_factory=dict)
    findings: list[Finding] = field(default_factory=list)


class HardwareResolver:
    """Resolves agents' hardware: platform -> parts -> per-agent overrides -> channels."""

    def __init__(self, library: ProfileLibrary) -> None:
        """Resolve against ``library``."""
        self.library = library
        self._clean: set[tuple[str, str]] = set()

    def _part(
        self,
        kind: str,
        ref: Any,
        ref_loc: Location,
        ref_doc: Document | None,
        ref_path: DocPath,
        findings: list[Finding],
    ) -> tuple[str, Composed] | None:
        """One part given as a profile name or {profile: name, ...overrides}."""
        overrides: dict[str, Any] = {}
        if isinstance(ref, Mapping):
            overrides = {k: v for k, v in ref.items() if k != "profile"}
            ref = ref.get("profile")
        if not isinstance(ref, str):
            findings.append(
                error(
                    "E-PROFILE-UNKNOWN",
                    ref_loc,
                    f"the {kind} must name a profile (a name, or {{profile: name, ...}})",
                )
            )
            return None
        expected = "payload" if kind.startswith("payload") else kind
        if ref not in self.library.names():
            findings.append(
                error(
                    "E-PROFILE-UNKNOWN",
                    ref_loc,
                    f"there is no hardware profile {ref!r}; "
                    + _suggest(ref, self.library.names(expected)),
                )
            )
            return None
        composed = self.library.compose(ref)
        if composed is None:
            findings.append(_unusable(ref, ref_loc))
            return None
        if composed.data.get("abstract"):
            findings.append(
                error(
                    "E-PROFILE-ABSTRACT",
                    ref_loc,
                    f"{ref!r} is an abstract base profile; name one that extends it ("
                    + ", ".join(self.library.extending(ref))
                    + ")",
                )
            )
            return None
        actual = self.library.kind_of(ref)
        if actual != expected:
            findings.append(
                error(
                    "E-PROFILE-KIND",
                    ref_loc,
                    f"{ref!r} is {_a(actual)} profile, not {_a(expected)}; name {_a(expected)} "
                    f"profile ({', '.join(self.library.names(expected)) or 'none shipped'})",
                )
            )
            return None
        part = Composed(copy.deepcopy(composed.data), dict(composed.origins))
        if overrides and ref_doc is not None:
            part.overlay(overrides, ref_doc, ref_path)
        return ref, part

    def resolve(
        self,
        agent_name: str,
        profile: str,
        profile_loc: Location,
        overrides: Mapping[str, Any],
        mission_doc: Document,
        overrides_path: DocPath,
    ) -> HardwareResult:
        """Resolve one agent's hardware.

        Args:
            agent_name: The agent (for messages).
            profile: The platform profile it names.
            profile_loc: Where it names it.
            overrides: Its ``hardware:`` mapping (may be empty).
            mission_doc: The mission document (for override locations).
            overrides_path: Path of ``hardware:`` in the mission.
        """
        result = HardwareResult(None)
        findings = result.findings
        if profile not in self.library.names():
            findings.append(
                error(
                    "E-PROFILE-UNKNOWN",
                    profile_loc,
                    f"there is no hardware profile {profile!r}; "
                    + _suggest(profile, self.library.names("platform")),
                )
            )
            return result
        platform = self.library.compose(profile)
        if platform is None:
            findings.append(_unusable(profile, profile_loc))
            return result
        if self.library.kind_of(profile) != "platform":
            findings.append(
                error(
                    "E-PROFILE-KIND",
                    profile_loc,
                    f"{profile!r} is {_a(self.library.kind_of(profile))} profile; an agent names a "
                    f"platform ({', '.join(self.library.names('platform'))})",
                )
            )
            return result
        if platform.data.get("abstract"):
            findings.append(
                error(
                    "E-PROFILE-ABSTRACT",
                    profile_loc,
                    f"{profile!r} is an abstract base; name a platform that extends it",
                )
            )
            return result
        platform_doc = self.library.document(profile)
        role = str(platform.data.get("role", "vehicle"))
        hardware = Hardware(platform=profile, role=role, gui=platform.data.get("gui"))
        for kind in PARTS:
            if platform.data.get(kind) is None:
                continue
            resolved = self._layered(
                kind,
                platform.data[kind],
                platform.locate((kind,), profile_loc),
                (platform_doc, (kind,)),
                overrides.get(kind),
                (mission_doc, (*overrides_path, kind)),
                findings,
            )
            if resolved is None:
                continue
            name, part = resolved
            hardware.parts[kind] = part.data
            hardware.part_profiles[kind] = name
            result.origins[kind] = part
        for kind in PARTS:
            if kind in overrides and platform.data.get(kind) is None:
                findings.append(
                    error(
                        "E-PROFILE-PART",
                        mission_doc.location((*overrides_path, kind), key=True),
                        f"{profile!r} has no {kind} to override; remove hardware.{kind}",
                    )
                )
        self._payloads(
            hardware,
            platform,
            platform_doc,
            overrides,
            mission_doc,
            overrides_path,
            profile_loc,
            result,
        )
        self._channels(
            hardware, platform, platform_doc, overrides, mission_doc, overrides_path, result
        )
        for kind, part in result.origins.items():
            findings.extend(self._check_complete(kind, part, profile_loc))
        if not any(f.is_error for f in findings):
            result.hardware = hardware
        return result

    def _layered(
        self,
        kind: str,
        base_ref: Any,
        base_loc: Location,
        base_source: tuple[Document | None, DocPath],
        override: Any,
        override_source: tuple[Document, DocPath],
        findings: list[Finding],
    ) -> tuple[str, Composed] | None:
        """A part as the platform names it, then as the agent changes or swaps it.

        An override that names a profile (``udp_lan`` or ``{profile: udp_lan, ...}``)
        swaps the part; a mapping without one is merged onto the platform's part.
        """
        doc, path = override_source
        if isinstance(override, str) or (isinstance(override, Mapping) and "profile" in override):
            return self._part(kind, override, doc.location(path), doc, path, findings)
        if base_ref is None:
            findings.append(
                error(
                    "E-PROFILE-UNKNOWN",
                    doc.location(path, key=True),
                    f"this agent adds a {kind} its platform does not have; name its profile "
                    "({profile: name, ...})",
                )
            )
            return None
        resolved = self._part(kind, base_ref, base_loc, base_source[0], base_source[1], findings)
        if resolved is not None and isinstance(override, Mapping):
            resolved[1].overlay(override, doc, path)
        return resolved

    def _payloads(
        self,
        hardware: Hardware,
        platform: Composed,
        platform_doc: Document | None,
        overrides: Mapping[str, Any],
        mission_doc: Document,
        overrides_path: DocPath,
        profile_loc: Location,
        result: HardwareResult,
    ) -> None:
        declared: dict[str, Any] = dict(platform.data.get("payloads") or {})
        extra: Mapping[str, Any] = overrides.get("payloads") or {}
        for name in sorted(set(declared) | set(extra)):
            resolved = self._layered(
                "payload",
                declared.get(name),
                platform.locate(("payloads", name), profile_loc),
                (platform_doc, ("payloads", name)),
                extra.get(name),
                (mission_doc, (*overrides_path, "payloads", name)),
                result.findings,
            )
            if resolved is None:
                continue
            profile_name, part = resolved
            hardware.payloads[name] = part.data
            hardware.payload_profiles[name] = profile_name
            result.origins[f"payloads.{name}"] = part

    def _channels(
        self,
        hardware: Hardware,
        platform: Composed,
        platform_doc: Document | None,
        overrides: Mapping[str, Any],
        mission_doc: Document,
        overrides_path: DocPath,
        result: HardwareResult,
    ) -> None:
        autopilot = result.origins.get("autopilot")
        if autopilot is None:
            return
        channels = Composed(
            copy.deepcopy(autopilot.data.get("channels") or {}),
            {k[1:]: v for k, v in autopilot.origins.items() if k[:1] == ("channels",)},
        )
        if platform.data.get("channels") and platform_doc is not None:
            channels.overlay(platform.data["channels"], platform_doc, ("channels",))
        if overrides.get("channels"):
            channels.overlay(overrides["channels"], mission_doc, (*overrides_path, "channels"))
        hardware.parts["autopilot"]["channels"] = channels.data
        for name, spec in channels.data.items():
            where = channels.locate((name,), Location(mission_doc.file))
            try:
                low, trim, high = (
                    int(spec[k]) for k in ("pwm_min_us", "pwm_trim_us", "pwm_max_us")
                )
            except (KeyError, TypeError, ValueError):
                result.findings.append(
                    error(
                        "E-CHANNEL-PWM",
                        where,
                        f"channel {name!r} needs whole-number pwm_min_us, pwm_trim_us and "
                        "pwm_max_us; add the missing ones",
                    )
                )
                continue
            if not low <= trim <= high:
                result.findings.append(
                    error(
                        "E-CHANNEL-PWM",
                        where,
                        f"channel {name!r} has pwm_min_us {low}, pwm_trim_us {trim}, pwm_max_us "
                        f"{high}; they must be in that order (min <= trim <= max)",
                    )
                )
                continue
            hardware.channels[name] = Channel(
                name=name,
                rc=spec.get("rc"),
                servo=spec.get("servo"),
                pwm_min_us=low,
                pwm_trim_us=trim,
                pwm_max_us=high,
            )

    def _check_complete(self, kind: str, part: Composed, fallback: Location) -> list[Finding]:
        """A merged part must have every field its kind requires, with valid values."""
        schema_kind = "payload" if kind.startswith("payloads.") else kind
        data = {k: v for k, v in part.data.items() if k != "abstract"}
        if part.data.get("abstract"):
            return [
                error(
                    "E-PROFILE-ABSTRACT",
                    part.locate((), fallback),
                    f"the {schema_kind} is an abstract base profile; name one that extends it",
                )
            ]
        # Agents on one platform share identical parts; a part found clean once is clean
        # wherever it was written, so it is not checked again.
        key = (schema_kind, json.dumps(data, sort_keys=True, default=str))
        if key in self._clean:
            return []
        located = _OriginDocument(part, fallback)
        findings = validate_data("", data, located, checker=_kind_validator(schema_kind))
        if not findings:
            findings.extend(_part_rules(schema_kind, part, fallback))
        if not findings:
            self._clean.add(key)
        return findings


_MODE_ROLES = (
    "guided_mode",
    "hold_mode",
    "rtl_mode",
    "land_mode",
    "terminal_mode",
    "manual_mode",
)


def _part_rules(kind: str, part: Composed, fallback: Location) -> list[Finding]:
    """Rules across fields of a merged part that a JSON Schema cannot state."""
    data = part.data
    out: list[Finding] = []
    if kind == "autopilot":
        modes = data.get("modes") or {}
        for role in _MODE_ROLES:
            mode = data.get(role)
            if mode is not None and mode not in modes:
                out.append(
                    error(
                        "E-PROFILE-MODE",
                        part.locate((role,), fallback),
                        f"{role} {mode!r} is not one of this autopilot's modes; "
                        + _suggest(str(mode), modes),
                    )
                )
        rate, top = data.get("stream_rate_hz"), data.get("max_stream_rate_hz")
        if rate is not None and top is not None and rate > top:
            out.append(
                error(
                    "E-PROFILE-RANGE",
                    part.locate(("stream_rate_hz",), fallback),
                    f"stream_rate_hz {rate:g} is above max_stream_rate_hz {top:g}, the most "
                    "the autopilot sends; lower it",
                )
            )
    if kind == "airframe":
        low, cruise, top = (
            data.get(k) for k in ("min_speed_m_s", "cruise_speed_m_s", "max_speed_m_s")
        )
        if low is not None and cruise is not None and top is not None and not low <= cruise <= top:
            out.append(
                error(
                    "E-PROFILE-RANGE",
                    part.locate(("cruise_speed_m_s",), fallback),
                    f"speeds must satisfy min <= cruise <= max; got {low:g}, {cruise:g}, "
                    f"{top:g} m/s",
                )
            )
    return out


@functools.cache
def _kind_validator(kind: str) -> Draft202012Validator:
    """Validator for a fully merged part of one kind; built once, schemas are constant."""
    from clark_engine.mission.schema_source.hardware_profile import kind_schema

    return Draft202012Validator(kind_schema(kind))


class _OriginDocument(Document):
    """A Document whose locations come from a merged part's origins."""

    def __init__(self, part: Composed, fallback: Location) -> None:
        super().__init__(file=fallback.file, data=part.data)
        self._part = part
        self._fallback = fallback

    def location(self, path: DocPath, *, key: bool = False) -> Location:
        loc = self._part.locate(path, self._fallback)
        return Location(loc.file, loc.line, loc.column, loc.path)
