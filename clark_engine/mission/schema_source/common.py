"""Helpers shared by the schema sources: ids, and terse builders for typed properties.

Every property a user sets carries a description; numbers carry their unit
(in the description and in the ``x-unit`` annotation), their range and their
default where they have one, so the language reference and editor hovers can
show all three.
"""

from __future__ import annotations

from typing import Any

DIALECT = "https://json-schema.org/draft/2020-12/schema"
NAME_PATTERN = r"^[a-z][a-z0-9_]*$"

Schema = dict[str, Any]


def schema_id(name: str) -> str:
    """The ``$id`` of a shipped schema. A URN: it names the schema, it is not fetched."""
    return f"urn:clark-engine:schema:{name}"


def number(
    description: str,
    *,
    unit: str | None = None,
    minimum: float | None = None,
    maximum: float | None = None,
    exclusive_minimum: float | None = None,
    exclusive_maximum: float | None = None,
    default: float | None = None,
    integer: bool = False,
) -> Schema:
    """A number (or integer) property with its unit, range and default."""
    out: Schema = {"type": "integer" if integer else "number", "description": description}
    if unit is not None:
        out["x-unit"] = unit
    if minimum is not None:
        out["minimum"] = minimum
    if maximum is not None:
        out["maximum"] = maximum
    if exclusive_minimum is not None:
        out["exclusiveMinimum"] = exclusive_minimum
    if exclusive_maximum is not None:
        out["exclusiveMaximum"] = exclusive_maximum
    if default is not None:
        out["default"] = default
    return out


def integer(description: str, **kw: Any) -> Schema:
    """An integer property; same keywords as :func:`number`."""
    return number(description, integer=True, **kw)


def string(
    description: str,
    *,
    pattern: str | None = None,
    enum: list[str] | None = None,
    default: str | None = None,
    min_length: int | None = None,
) -> Schema:
    """A string property, optionally constrained by a pattern or a list of values."""
    out: Schema = {"type": "string", "description": description}
    if pattern is not None:
        out["pattern"] = pattern
    if enum is not None:
        out["enum"] = enum
    if default is not None:
        out["default"] = default
    if min_length is not None:
        out["minLength"] = min_length
    return out


def boolean(description: str, *, default: bool | None = None) -> Schema:
    """A true/false property."""
    out: Schema = {"type": "boolean", "description": description}
    if default is not None:
        out["default"] = default
    return out


def obj(
    description: str,
    properties: dict[str, Schema],
    *,
    required: list[str] | None = None,
    additional: bool | Schema = False,
) -> Schema:
    """A mapping with known keys; unknown keys are rejected unless ``additional`` says so."""
    out: Schema = {
        "type": "object",
        "description": description,
        "properties": properties,
        "additionalProperties": additional,
    }
    if required:
        out["required"] = required
    return out


def array(
    description: str, items: Schema, *, min_items: int | None = None, unique: bool = False
) -> Schema:
    """A list whose items all follow ``items`` (each only once with ``unique``)."""
    out: Schema = {"type": "array", "description": description, "items": items}
    if min_items is not None:
        out["minItems"] = min_items
    if unique:
        out["uniqueItems"] = True
    return out
