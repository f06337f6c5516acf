"""Helpers shared by the hardware profile's schema sources: conditional keys, small types.

Why separate: :mod:`.hardware_profile` (the documents, the platform and a mission's
overrides) and :mod:`.hardware_parts` (each part kind's keys) build their schemas with the
same ``if``/``then`` clauses, tagged unions and small property builders; they live here so
that neither imports the other's internals.
"""

from __future__ import annotations

import copy

from clark_engine.mission.schema_source.common import (
    NAME_PATTERN,
    Schema,
    string,
)

_HOST_PORT_PATTERN = r"^[^\s:]+:[0-9]{1,5}$"


def article(word: str) -> str:
    """'an' before a vowel sound, else 'a' (an airframe, a radio)."""
    return "an" if word[:1] in "aeiou" else "a"


def kind_is(key: str, value: str) -> Schema:
    """Build an ``if`` clause: the mapping has ``key`` and it equals ``value``."""
    return {"properties": {key: {"const": value}}, "required": [key]}


def kind_in(key: str, values: list[str]) -> Schema:
    """Build an ``if`` clause: the mapping has ``key`` and it is one of ``values``."""
    return {"properties": {key: {"enum": values}}, "required": [key]}


def nullable(schema: Schema, meaning: str) -> Schema:
    """Allow ``null`` besides the schema's own type; ``meaning`` says what null stands for."""
    out = dict(schema)
    out["type"] = [schema["type"], "null"]
    out["description"] = f"{schema['description']} {meaning}"
    return out


def forbidden(reason: str) -> Schema:
    """Build a property schema that rejects any value; ``reason`` says why and what to do.

    Used instead of ``false`` because jsonschema reports a ``false`` subschema without
    the path of the key it rejected; a failing ``not`` keeps the path, and the error's
    ``schema["description"]`` carries the reason.
    """
    return {"not": {}, "description": reason}


def host_port(description: str, *, default: str | None = None) -> Schema:
    """Build a ``host:port`` string property."""
    return string(description, pattern=_HOST_PORT_PATTERN, default=default)


def profile_name(description: str) -> Schema:
    """Build a property that names a profile (a lower-case name)."""
    return string(description, pattern=NAME_PATTERN)


def allow(keys: list[str]) -> Schema:
    """Build a subschema that never fails and marks ``keys`` as known.

    ``unevaluatedProperties`` counts a key as known only through subschemas that
    pass. Keeping "which keys exist" apart from "what values they take" means a
    wrong value is reported once, at the value, and not again as an unknown key.
    """
    return {"properties": dict.fromkeys(keys, True)}


def _keys_and_values(if_: Schema, then: Schema, keys: list[str]) -> list[Schema]:
    """Build two allOf branches under one condition: the checks, and the keys they allow."""
    return [{"if": if_, "then": then}, {"if": if_, "then": allow(keys)}]


def tagged_union(
    description: str,
    variants: dict[str, dict[str, Schema]],
    *,
    tag: str = "kind",
    tag_description: str,
) -> Schema:
    """Build a mapping whose ``tag`` selects which other keys it may have.

    Each variant's keys live in an if/then branch so an error names the key that
    is wrong for *that* variant. When the tag is absent (a child profile that
    overrides only, say, ``device``) or unknown (the tag's own error is
    reported), the union of all variants' keys is accepted and type-checked.
    """
    union: dict[str, Schema] = {}
    for props in variants.values():
        for key, schema in props.items():
            union.setdefault(key, schema)
    branches: list[Schema] = []
    for name, props in variants.items():
        branches += _keys_and_values(
            kind_is(tag, name), {"properties": copy.deepcopy(props)}, list(props)
        )
    known = kind_in(tag, list(variants))
    branches.append({"if": known, "else": {"properties": union}})
    branches.append({"if": known, "else": allow(list(union))})
    return {
        "type": "object",
        "description": description,
        "properties": {tag: string(tag_description, enum=list(variants))},
        "allOf": branches,
        "unevaluatedProperties": False,
    }


def tagged_union_complete(tag: str, required: dict[str, list[str]]) -> Schema:
    """Require what a merged tagged union must contain: the tag and each variant's keys."""
    return {
        "required": [tag],
        "allOf": [
            {"if": kind_is(tag, name), "then": {"required": keys}}
            for name, keys in required.items()
            if keys
        ],
    }
