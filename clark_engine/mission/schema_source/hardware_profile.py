"""JSON Schema source for hardware profiles (``hardware_profiles/<kinds>/<name>.yaml``).

A hardware profile describes one part a vehicle or station is built from: an
airframe, an autopilot, a radio, a mission computer, a payload, or a platform
that composes those parts into what a mission's agent names as its
``profile:``. Profiles compose by ``extends`` (the child is deep-merged onto its
parent), so a single file is usually partial. Two schemas follow from that:

* :func:`build` validates any one profile *file*: the common keys, and the keys
  of the file's ``kind``, each with its type, unit and range. Nothing
  kind-specific is required here, because a child states only what it changes;
  unknown keys are rejected so a misspelling is caught in the file that has it.
* :func:`kind_schema` validates a *merged* profile of one kind (after the
  engine has resolved the ``extends`` chain) and adds the keys it must have.

What JSON Schema cannot say (``extends`` names a profile of the same kind, mode
names used by ``guided_mode`` exist in ``modes``, PWM minimum <= trim <= maximum,
names are unique, the file stem equals ``profile``) the engine checks after
loading; docs/hardware-profiles.md lists those checks.

:func:`part_reference_schema`, :func:`part_override_schema` and
:func:`agent_hardware_schema` (and :data:`.hardware_parts.CHANNEL_SCHEMA`) are
self-contained (no ``$ref``) so the mission schema can embed them for per-agent overrides.

This module assembles those documents, with the keys every profile shares and the
platform's; each part kind's keys are :mod:`.hardware_parts`'s, and the helpers both use
:mod:`.profile_common`'s.
"""

from __future__ import annotations

from typing import Any

from clark_engine.mission.schema_source.common import (
    DIALECT,
    NAME_PATTERN,
    Schema,
    boolean,
    obj,
    schema_id,
    string,
    time_s,
)
from clark_engine.mission.schema_source.hardware_parts import (
    KIND_PROPERTIES,
    airframe_rules,
    channel_schema,
    channels_schema,
    radio_rules,
)
from clark_engine.mission.schema_source.profile_common import (
    allow,
    article,
    forbidden,
    host_port,
    kind_in,
    kind_is,
    profile_name,
    tagged_union_complete,
)

#: The six kinds of profile, in the order the guide presents them.
KINDS: tuple[str, ...] = ("airframe", "autopilot", "radio", "computer", "payload", "platform")

#: Folder under ``hardware_profiles/`` that holds each kind.
KIND_FOLDERS: dict[str, str] = {kind: f"{kind}s" for kind in KINDS}

#: The parts a platform composes, besides its payloads.
PART_KINDS: tuple[str, ...] = ("airframe", "autopilot", "radio", "computer")

#: Keys every profile may carry, whatever its kind.
COMMON_KEYS: tuple[str, ...] = ("profile", "kind", "extends", "abstract", "description", "source")

#: Keys each kind requires once its ``extends`` chain is merged (unless ``abstract``).
REQUIRED_AFTER_MERGE: dict[str, tuple[str, ...]] = {
    "airframe": (
        "class",
        "cruise_speed_m_s",
        "max_speed_m_s",
        "min_speed_m_s",
        "max_climb_rate_m_s",
        "max_descent_rate_m_s",
        "max_turn_rate_deg_s",
        "max_altitude_m",
        "controls",
    ),
    "autopilot": (
        "firmware",
        "connection",
        "modes",
        "guided_mode",
        "hold_mode",
        "rtl_mode",
        "terminal_mode",
        "manual_mode",
        "channels",
    ),
    "radio": ("link", "throughput_bps", "max_packet_bytes", "frame_overhead_bytes"),
    "computer": ("max_loop_hz",),
    "payload": ("payload_kind", "connection", "min_interval_s", "capture_delay_s"),
    "platform": ("role",),
}

_ONE_LINE_PATTERN = r"^[^\n]+$"


# --------------------------------------------------------------------------- kinds


def _common_properties(*, kind: str | None = None) -> dict[str, Schema]:
    kind_property: Schema = string(
        "Which kind of part this profile describes; it decides which other keys are allowed.",
        enum=list(KINDS),
    )
    if kind is not None:
        kind_property["const"] = kind
    return {
        "profile": string(
            "The profile's unique name (unique across all kinds); the file is named after it.",
            pattern=NAME_PATTERN,
        ),
        "kind": kind_property,
        "extends": profile_name(
            "Name of a profile of the same kind that this one is deep-merged onto: mappings "
            "merge key by key, lists and single values replace the parent's."
        ),
        "abstract": boolean(
            "True for a base meant only to be extended (e.g. a generic Pixhawk); an agent "
            "cannot use it directly and it need not be complete.",
            default=False,
        ),
        "description": string(
            "One sentence saying what this part is.", pattern=_ONE_LINE_PATTERN, min_length=1
        ),
        "source": string(
            "Where the measured figures come from (e.g. 'thesis 5.1.1', a datasheet).",
            min_length=1,
        ),
    }


def _gui_schema() -> Schema:
    return obj(
        "The operator's live view (mission control station only): where it is served and "
        "when it counts as gone.",
        {
            "address": host_port(
                "host:port the station serves the operator's view on.",
                default="127.0.0.1:5600",
            ),
            "timeout_s": time_s(
                "The view counts as disconnected after this long without contact, in seconds.",
                exclusive_minimum=0,
                maximum=86400,
                default=5,
            ),
        },
    )


def _override_properties(kind: str) -> dict[str, Schema]:
    """Return the keys a reference may override on a part of ``kind``: its own keys."""
    if kind == "platform":
        raise ValueError("a platform is not a part of another platform")
    try:
        return KIND_PROPERTIES[kind]()
    except KeyError:
        raise ValueError(f"unknown profile kind {kind!r}; expected one of {KINDS}") from None


def part_reference_schema(kind: str, *, require_profile: bool = True) -> Schema:
    """Return the schema of a part reference: a name, or ``{profile: NAME, ...overrides}``.

    The overrides are any of that kind's keys; the engine deep-merges them onto the
    named profile. The returned schema is self-contained, so the mission schema can
    embed it.

    Args:
        kind: The part's kind: airframe, autopilot, radio, computer or payload.
        require_profile: Whether the mapping form must name ``profile``. True in a
            platform; False for a mission's per-agent ``hardware:`` overrides, where
            the mapping changes the platform's part and ``profile`` swaps it.

    Returns:
        A JSON Schema accepting either form.

    Raises:
        ValueError: ``kind`` is not a part kind.

    """
    overrides = _override_properties(kind)
    mapping = obj(
        f"The {kind} profile named by `profile`, with these keys deep-merged onto it.",
        {
            "profile": profile_name(f"Name of the {kind} profile to use."),
            **overrides,
        },
        required=["profile"] if require_profile else None,
    )
    del mapping["type"]  # the type is checked once, by the string-or-mapping rule below
    return {
        "type": ["string", "object"],
        "description": f"{article(kind).capitalize()} {kind}: its profile name, or a mapping "
        "with `profile:` and the keys to change on it.",
        "if": {"type": "string"},
        "then": profile_name(f"Name of the {kind} profile to use."),
        "else": mapping,
    }


def _payloads_schema(*, require_profile: bool) -> Schema:
    return {
        "type": "object",
        "description": "Payload name (what behaviours call it, e.g. camera) -> its payload "
        "profile, by name or with overrides.",
        "propertyNames": {
            "pattern": NAME_PATTERN,
            "description": "A payload name: lower-case letters, digits and _, starting with a "
            "letter.",
        },
        "additionalProperties": part_reference_schema("payload", require_profile=require_profile),
    }


def _platform_properties() -> dict[str, Schema]:
    return {
        "role": string(
            "vehicle (flies or drives, with an autopilot) or mcs (the mission control station).",
            enum=["vehicle", "mcs"],
        ),
        **{kind: part_reference_schema(kind) for kind in PART_KINDS},
        "payloads": _payloads_schema(require_profile=True),
        "channels": channels_schema(
            "Channel entries for this build, merged key by key onto the autopilot's channel "
            "map (change a limit, add a switch, or null a servo output a mixer owns)."
        ),
        "gui": _gui_schema(),
    }


def _platform_rules() -> list[Schema]:
    return [
        {
            "if": kind_is("role", "mcs"),
            "then": {
                "properties": {
                    "airframe": forbidden(
                        "A mission control station (role mcs) has no airframe; remove it."
                    ),
                    "autopilot": forbidden(
                        "A mission control station (role mcs) has no autopilot; remove it."
                    ),
                }
            },
        },
        {
            "if": kind_is("role", "vehicle"),
            "then": {
                "properties": {
                    "gui": forbidden(
                        "Only a mission control station (role mcs) serves the operator's view; "
                        "remove gui or set role: mcs."
                    )
                }
            },
        },
    ]


def part_override_schema(kind: str) -> Schema:
    """Return the schema of per-agent changes to one part: a mapping of that kind's keys.

    The engine deep-merges it onto the part the agent's platform resolved. Unlike a
    part reference it names no ``profile``: an agent changes its platform's parts,
    and flies a different part by naming a different platform. Self-contained.

    Args:
        kind: The part's kind: airframe, autopilot, radio, computer or payload.

    Returns:
        A JSON Schema for the mapping.

    Raises:
        ValueError: ``kind`` is not a part kind.

    """
    return obj(
        f"Changes to this agent's {kind}, deep-merged onto the one its platform names.",
        _override_properties(kind),
    )


def agent_hardware_schema() -> Schema:
    """Return the schema of an agent's ``hardware:`` key: per-agent changes to its platform.

    Each part (``airframe``, ``autopilot``, ``radio``, ``computer``) takes a mapping of
    changes deep-merged onto the platform's resolved part. ``payloads`` takes, per
    payload name, changes to the platform's payload of that name, or a part reference
    (a profile name or ``{profile: NAME, ...}``) that replaces it or adds a payload.
    ``channels`` merges onto the platform's channel map. Self-contained, for embedding
    in the mission schema.

    Returns:
        A JSON Schema for the ``hardware:`` mapping.

    """
    return obj(
        "Changes to this agent's platform, deep-merged onto its resolved parts (e.g. the "
        "autopilot's serial device or this radio's address).",
        {
            **{kind: part_override_schema(kind) for kind in PART_KINDS},
            "payloads": _payloads_schema(require_profile=False),
            "channels": channels_schema(
                "Channel entries merged key by key onto the platform's channel map."
            ),
        },
    )


def _kind_fields(kind: str) -> Schema:
    """Return the keys a ``kind`` profile may have beyond the common ones, and their rules."""
    builders = {**KIND_PROPERTIES, "platform": _platform_properties}
    rules = {
        "airframe": airframe_rules,
        "radio": radio_rules,
        "platform": _platform_rules,
    }
    out: Schema = {
        "description": f"Keys of a {kind} profile.",
        "properties": builders[kind](),
    }
    if kind in rules:
        out["allOf"] = rules[kind]()
    return out


def _kind_keys(kind: str) -> list[str]:
    """Return the names of the keys a ``kind`` profile may have beyond the common ones."""
    return list(_kind_fields(kind)["properties"])


def _kind_complete(kind: str) -> Schema:
    """Return what a merged, non-abstract profile of ``kind`` must contain."""
    needed: Schema = {"required": list(REQUIRED_AFTER_MERGE[kind])}
    nested: dict[str, Schema] = {}
    if kind == "autopilot":
        nested["connection"] = tagged_union_complete(
            "kind", {"serial": ["device", "baud_bps"], "udp": ["address"], "tcp": ["address"]}
        )
    elif kind == "radio":
        nested["connection"] = tagged_union_complete(
            "kind", {"serial": ["device", "baud_bps"], "udp": ["port"]}
        )
    elif kind == "payload":
        nested["connection"] = tagged_union_complete(
            "kind", {"tcp": ["address"], "udp": ["address"]}
        )
    if nested:
        needed["properties"] = nested
    if kind == "platform":
        needed["allOf"] = [
            {"if": kind_is("role", "vehicle"), "then": {"required": list(PART_KINDS)}},
            {"if": kind_is("role", "mcs"), "then": {"required": ["radio", "computer"]}},
        ]
    return {
        "description": f"A merged {kind} profile that an agent can use is complete.",
        "if": {"properties": {"abstract": {"const": True}}, "required": ["abstract"]},
        "else": needed,
    }


def _defs() -> dict[str, Schema]:
    defs: dict[str, Schema] = {"channel": channel_schema()}
    for kind in KINDS:
        defs[kind] = _kind_fields(kind)
        defs[f"{kind}_complete"] = _kind_complete(kind)
    return defs


# --------------------------------------------------------------------------- documents


def build() -> dict[str, Any]:
    """Return the schema of one hardware-profile file, of any kind.

    Returns:
        A JSON Schema 2020-12 document. The common keys are in ``properties``; each
        kind's keys are selected by ``kind`` through if/then, and
        ``unevaluatedProperties: false`` rejects any key the file's kind does not have.

    """
    branches: list[Schema] = []
    for kind in KINDS:
        branches.append({"if": kind_is("kind", kind), "then": {"$ref": f"#/$defs/{kind}"}})
        branches.append({"if": kind_is("kind", kind), "then": allow(_kind_keys(kind))})
    # Without a valid kind no key set applies: accept the rest so the one error
    # reported is the kind's, not one per key.
    branches.append({"if": kind_in("kind", list(KINDS)), "else": {"additionalProperties": True}})
    return {
        "$schema": DIALECT,
        "$id": schema_id("hardware-profile"),
        "title": "Clark Engine hardware profile",
        "description": "One part a vehicle or station is built from (airframe, autopilot, "
        "radio, mission computer, payload) or a platform composing them. A file may extend "
        "another profile of its kind and state only what differs, so nothing kind-specific "
        "is required here; the engine checks completeness after merging.",
        "type": "object",
        "properties": _common_properties(),
        "required": ["profile", "kind", "description"],
        "allOf": branches,
        "unevaluatedProperties": False,
        "$defs": _defs(),
    }


def kind_schema(kind: str) -> dict[str, Any]:
    """Return the schema of a merged profile of one kind, with the keys it must then have.

    The engine applies it after deep-merging a profile onto its ``extends`` chain
    (and a part onto a platform's and an agent's changes). The common keys are
    allowed but not required, so the merged data may be checked with or without
    them. An ``abstract`` profile is exempt from the completeness requirements.

    Args:
        kind: One of :data:`KINDS`.

    Returns:
        A JSON Schema 2020-12 document with the same ``$defs`` as :func:`build`.

    Raises:
        ValueError: ``kind`` is not a profile kind.

    """
    if kind not in KINDS:
        raise ValueError(f"unknown profile kind {kind!r}; expected one of {', '.join(KINDS)}")
    return {
        "$schema": DIALECT,
        "$id": schema_id(f"hardware-profile-{kind}"),
        "title": f"Clark Engine {kind} profile, merged",
        "description": f"{article(kind).capitalize()} {kind} profile after its `extends` "
        "chain is merged.",
        "type": "object",
        "properties": _common_properties(kind=kind),
        "allOf": [
            {"$ref": f"#/$defs/{kind}"},
            allow(_kind_keys(kind)),
            {"$ref": f"#/$defs/{kind}_complete"},
        ],
        "unevaluatedProperties": False,
        "$defs": _defs(),
    }
