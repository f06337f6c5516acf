"""Validate documents against the shipped JSON Schemas and word the errors for people.

jsonschema reports errors such as ``Additional properties are not allowed
('lopp_hz' was unexpected)`` at a path. This module turns each into a finding
at the exact line and column (the misspelt key itself, not its parent), with a
stable code and a sentence saying what to change (``did you mean 'loop_hz'?``,
the allowed range with its unit, ...).
"""

from __future__ import annotations

import difflib
import functools
import json
import math
import re
from collections.abc import Iterable, Iterator, Mapping
from typing import Any

import jsonschema
from jsonschema import Draft202012Validator
from jsonschema.exceptions import ValidationError, best_match

from clark_engine.data import data_dir
from clark_engine.mission.findings import DocPath, Finding, error
from clark_engine.mission.schema_source.common import NAME_PATTERN
from clark_engine.mission.yaml_loader import Document

SCHEMA_NAMES = {
    "mission": "mission.schema.json",
    "behavior": "behavior.schema.json",
    "hardware-profile": "hardware_profile.schema.json",
    "agent-config": "agent_config.schema.json",
}

_SEXAGESIMAL = re.compile(r"^[-+]?\d+(:[0-5]?\d)+(\.\d*)?$")
_QUOTED = re.compile(r"'([^']*)'")

_TYPE_WORDS = {
    "object": "a mapping (key: value lines)",
    "array": "a list",
    "string": "text",
    "number": "a number",
    "integer": "a whole number",
    "boolean": "true or false",
    "null": "nothing (null)",
}


def schema_text(name: str) -> str:
    """The text of a schema by its short name (``mission``, ``agent-config``...).

    The shipped file, which describes the built-in behaviours; when a behaviour plugin
    is installed, the schema is built again from its source with the plugins'
    behaviours in it, so that editors complete them and loading a config compiled with
    them checks their parameters.

    Raises:
        KeyError: Unknown name.
    """
    file_name = SCHEMA_NAMES[name]
    if name != "hardware-profile":
        from clark_engine.behaviors import plugins

        if plugins():
            return _with_plugins(file_name)
    return (data_dir("schemas") / file_name).read_text(encoding="utf-8")


@functools.cache
def _with_plugins(file_name: str) -> str:
    from clark_engine.behaviors import plugin_schemas
    from clark_engine.mission.schema_source.render import render

    with plugin_schemas():
        return render(file_name)


@functools.cache
def validator(name: str) -> Draft202012Validator:
    """A compiled validator for a shipped schema.

    Cached for the life of the process: schemas are immutable data, and building
    a validator costs more than most validations.
    """
    schema = json.loads(schema_text(name))
    return Draft202012Validator(schema)


def show_number(value: int | float) -> str:
    """A number as a message quotes it: short, whatever its size.

    ``repr`` would write out all 401 digits of ``10**400``, and raises ``ValueError``
    past Python's 4300-digit limit (a hexadecimal ``0x`` literal has none); ``float()``
    of it raises ``OverflowError``. A huge whole number is shown in scientific notation,
    or by its count of digits when no float holds it.
    """
    if isinstance(value, int) and not isinstance(value, bool) and abs(value) >= 10**15:
        try:
            return f"{float(value):.4g}"
        except OverflowError:
            digits = int(abs(value).bit_length() * math.log10(2)) + 1
            return f"a {digits}-digit number"
    return repr(value)


def quote(value: Any) -> str:
    """A value as a message quotes it: numbers by :func:`show_number`, long text cut short."""
    if isinstance(value, int | float) and not isinstance(value, bool):
        return show_number(value)
    if isinstance(value, str) and len(value) > 60:
        return f"{value[:40]!r}... ({len(value)} characters)"
    return repr(value)


def _describe_type(value: Any) -> str:
    if isinstance(value, bool):
        return f"{str(value).lower()}"
    if isinstance(value, int | float):
        return show_number(value)
    if isinstance(value, dict):
        return "a mapping"
    if isinstance(value, list):
        return "a list"
    if value is None:
        return "nothing"
    if isinstance(value, str):
        return f"the text {quote(value)}"
    return repr(value)


def _unit(schema: Mapping[str, Any]) -> str:
    unit = schema.get("x-unit")
    return f" {unit}" if unit else ""


def _in_unit(schema: Mapping[str, Any]) -> str:
    unit = schema.get("x-unit")
    return f" (in {unit})" if unit else ""


def _property_names(schema: Mapping[str, Any]) -> set[str]:
    """Every property name a schema (with its allOf/then branches) declares."""
    names = set(schema.get("properties", {}))
    for branch in schema.get("allOf", []):
        names |= _property_names(branch.get("then", {}))
        names |= _property_names(branch)
    return names


def _suggest(word: str, choices: Iterable[str]) -> str:
    close = difflib.get_close_matches(word, sorted(choices), n=1, cutoff=0.6)
    return f"; did you mean {close[0]!r}?" if close else ""


#: Keys the language renamed or moved: (path of the mapping, old key) -> (new key, what to
#: write instead). Old missions get E-KEY-RENAMED saying so, not a bare unknown key.
RENAMED_KEYS: dict[tuple[DocPath, str], tuple[str, str]] = {
    (("mission", "origin"), "alt_m"): (
        "alt_amsl_m",
        "origin.alt_m is now origin.alt_amsl_m, the ground's height at the origin above mean "
        "sea level (every other altitude is above the origin); rename the key",
    ),
    (("mission",), "ceiling_m"): (
        "envelope.ceiling_m",
        "mission.ceiling_m moved to the safety envelope: write it as ceiling_m under a "
        "top-level envelope: section (envelope: {ceiling_m: ...}), beside mission:",
    ),
    (("sim",), "sitl_tolerance_s"): (
        "sitl_tolerance.time_floor_s",
        "sim.sitl_tolerance_s is now sim.sitl_tolerance, which also compares positions, "
        "altitudes and the checks' figures: each state's entry may differ by a share of its "
        "leg, never less than time_floor_s (3 s by default); to keep your floor write "
        "sitl_tolerance: {time_floor_s: ...} in sim:",
    ),
}


def _renamed(path: DocPath, key: str) -> tuple[str, str] | None:
    """The new name of ``key`` in the mapping at ``path`` and what to write; None if not renamed."""
    return RENAMED_KEYS.get((tuple(path), key))


def _convert(err: ValidationError, doc: Document, base: DocPath) -> Iterator[Finding]:
    path: DocPath = (*base, *err.absolute_path)
    schema: Mapping[str, Any] = err.schema if isinstance(err.schema, Mapping) else {}
    kind = err.validator
    instance = err.instance
    in_property_names = "propertyNames" in err.absolute_schema_path

    if in_property_names:
        key = str(instance)
        yield error(
            "E-NAME",
            doc.location((*path, key), key=True),
            f"{quote(key)} is not a valid name here; {_pattern_advice(err)}",
        )
        return
    if kind == "not":
        reason = str(schema.get("description") or "these settings contradict each other")
        yield error(
            "E-CONFLICT", doc.location(path), f"{reason.rstrip('.')}; remove or change this value"
        )
        return
    if kind in ("additionalProperties", "unevaluatedProperties"):
        known = _property_names(schema) | set(
            (err.parent.schema or {}).get("properties", {}) if err.parent else ()
        )
        if kind == "additionalProperties" and isinstance(instance, Mapping):
            extras = [k for k in instance if k not in schema.get("properties", {})]
        else:
            extras = _QUOTED.findall(err.message.split("(")[-1]) or list(instance)
        for key in extras:
            renamed = _renamed(path, str(key))
            if renamed is not None:
                yield error("E-KEY-RENAMED", doc.location((*path, key), key=True), renamed[1])
                continue
            others = known - {key}
            if not others:
                hint = "; nothing may be given here, remove it"
            else:
                hint = _suggest(key, others) or f"; allowed keys: {', '.join(sorted(others))}"
            yield error(
                "E-KEY-UNKNOWN",
                doc.location((*path, key), key=True),
                f"unknown key {key!r}{hint}",
            )
        return
    if kind == "required":
        present = set(instance) if isinstance(instance, Mapping) else set()
        renamed_to = {
            new: old for (where, old), (new, _) in RENAMED_KEYS.items() if where == tuple(path)
        }
        for key in err.validator_value:
            if key in present or renamed_to.get(key) in present:
                continue  # present, or present under its old name (E-KEY-RENAMED says so)
            prop = schema.get("properties", {}).get(key, {})
            what = prop.get("description", "")
            yield error(
                "E-KEY-MISSING",
                doc.location(path),
                f"{key!r} is missing"
                + (f": {what[0].lower()}{what[1:].rstrip('.')}" if what else "")
                + f"; add {key}: here",
            )
        return
    if kind == "const" and path == ("clark",):
        yield error(
            "E-VERSION",
            doc.location(path),
            f"this engine reads mission language version 1, not {json.dumps(instance)}; "
            "write clark: 1",
        )
        return
    if kind == "type":
        expected = err.validator_value
        expected_list = expected if isinstance(expected, list) else [expected]
        words = " or ".join(_TYPE_WORDS.get(str(t), str(t)) for t in expected_list)
        hint = ""
        if (
            isinstance(instance, str)
            and _SEXAGESIMAL.match(instance)
            and ("number" in expected_list or "integer" in expected_list)
        ):
            hint = "; times are plain numbers of seconds here (write 90, not 1:30)"
        elif isinstance(instance, float) and "integer" in expected_list:
            hint = "; write a whole number"
        elif isinstance(instance, int | float) and expected_list == ["string"]:
            hint = (
                "; YAML reads bare digits as a number (dropping leading zeros): quote it, "
                'e.g. "0013A200..."'
            )
        yield error(
            "E-TYPE",
            doc.location(path),
            f"expected {words}{_in_unit(schema)}, got {_describe_type(instance)}{hint}",
        )
        return
    if kind in ("minimum", "maximum", "exclusiveMinimum", "exclusiveMaximum"):
        unit = _unit(schema)
        bound = err.validator_value
        relation = {
            "minimum": f"below the minimum {bound}{unit}",
            "maximum": f"above the maximum {bound}{unit}",
            "exclusiveMinimum": f"not above {bound}{unit}",
            "exclusiveMaximum": f"not below {bound}{unit}",
        }[kind]
        allowed = _allowed_range(schema)
        yield error(
            "E-RANGE",
            doc.location(path),
            f"{show_number(instance)}{unit} is {relation}; give a value {allowed}",
        )
        return
    if kind in ("enum", "const"):
        options = err.validator_value if kind == "enum" else [err.validator_value]
        listing = ", ".join(str(o) for o in options)
        written = instance if isinstance(instance, str) else quote(instance)
        yield error(
            "E-VALUE",
            doc.location(path),
            f"{quote(instance)} is not allowed here{_suggest(written, map(str, options))}; "
            f"choose one of: {listing}",
        )
        return
    if kind == "pattern":
        code = "E-NAME" if err.validator_value == NAME_PATTERN else "E-FORMAT"
        yield error(
            code,
            doc.location(path),
            f"{quote(instance)} is not valid here; {_pattern_advice(err)}",
        )
        return
    if kind == "uniqueItems":
        yield error(
            "E-COUNT", doc.location(path), "a name is listed twice here; list each one once"
        )
        return
    if kind == "minLength":
        yield error("E-VALUE", doc.location(path), "this must not be empty; write a value")
        return
    if kind == "maxLength":
        yield error(
            "E-VALUE",
            doc.location(path),
            f"this is {len(instance)} characters long; write at most {err.validator_value} "
            "characters here",
        )
        return
    if kind in ("minItems", "maxItems", "minProperties", "maxProperties"):
        singular, plural = ("item", "items") if "Items" in kind else ("entry", "entries")
        noun = singular if err.validator_value == 1 else plural
        bound = err.validator_value
        relation = "at least" if kind.startswith("min") else "at most"
        yield error(
            "E-COUNT",
            doc.location(path),
            f"give {relation} {bound} {noun} here (found {len(instance)})",
        )
        return
    if kind in ("anyOf", "oneOf"):
        # When exactly one alternative accepts the value's type (a mapping, a list, ...),
        # what is wrong is inside that alternative: report its own errors.
        same_type = _branches_of_type(err, instance)
        if len(same_type) == 1 and same_type[0]:
            for inner_err in same_type[0]:
                yield from _convert(inner_err, doc, base)
            return
        expected = schema.get("x-expected")
        if expected:
            yield error(
                "E-TYPE", doc.location(path), f"expected {expected}, got {_describe_type(instance)}"
            )
            return
        inner = best_match(err.context) if err.context else None
        if inner is not None:
            yield from _convert(inner, doc, base)
            return
    if kind == "items" and err.validator_value is False:
        yield error(
            "E-COUNT", doc.location(path), "too many items in this list; remove the extra ones"
        )
        return
    yield error("E-SCHEMA", doc.location(path), err.message)


def _pattern_advice(err: ValidationError) -> str:
    """What a value matching the failed pattern looks like, for the message."""
    if err.validator_value == NAME_PATTERN:
        return "use lower-case letters, digits and _, starting with a letter (e.g. slash_a)"
    schema = err.schema if isinstance(err.schema, Mapping) else {}
    described = schema.get("description")
    if described:
        return f"expected {described[0].lower()}{described[1:].rstrip('.')}"
    return f"it must match {err.validator_value}"


_JSON_TYPES: dict[str, tuple[type, ...]] = {
    "object": (dict,),
    "array": (list,),
    "string": (str,),
    "number": (int, float),
    "integer": (int,),
    "boolean": (bool,),
    "null": (type(None),),
}


def _branches_of_type(err: ValidationError, instance: Any) -> list[list[ValidationError]]:
    """Errors of each anyOf/oneOf alternative whose declared type fits ``instance``."""
    alternatives = err.validator_value if isinstance(err.validator_value, list) else []
    fitting: list[list[ValidationError]] = []
    required: list[set[str]] = []
    for index, alternative in enumerate(alternatives):
        declared = alternative.get("type") if isinstance(alternative, Mapping) else None
        if declared is None:
            continue
        kinds = declared if isinstance(declared, list) else [declared]
        fits = any(
            isinstance(instance, _JSON_TYPES.get(k, ()))
            and not (isinstance(instance, bool) and k in ("number", "integer"))
            for k in kinds
        )
        if fits:
            fitting.append([e for e in err.context if e.relative_schema_path[0] == index])
            required.append(set(alternative.get("required", ())))
    if len(fitting) > 1 and isinstance(instance, Mapping):
        # Several mapping forms: the one whose required keys the user wrote is meant.
        meant = [
            f for f, keys in zip(fitting, required, strict=True) if keys and keys <= set(instance)
        ]
        if len(meant) == 1:
            return meant
    return fitting


def _allowed_range(schema: Mapping[str, Any]) -> str:
    unit = _unit(schema)
    low = schema.get("minimum")
    low_x = schema.get("exclusiveMinimum")
    high = schema.get("maximum")
    high_x = schema.get("exclusiveMaximum")
    parts = []
    if low is not None:
        parts.append(f"at least {low}{unit}")
    if low_x is not None:
        parts.append(f"above {low_x}{unit}")
    if high is not None:
        parts.append(f"at most {high}{unit}")
    if high_x is not None:
        parts.append(f"below {high_x}{unit}")
    return " and ".join(parts) or "in range"


def validate_data(
    name: str,
    data: Any,
    doc: Document,
    base: DocPath = (),
    *,
    checker: Draft202012Validator | None = None,
) -> list[Finding]:
    """Every schema error in ``data`` as findings located through ``doc``.

    Args:
        name: Short name of the shipped schema (ignored when ``schema`` is given).
        data: The data to check.
        doc: The document the data was read from (for line and column).
        base: Path of ``data`` inside ``doc``.
        checker: A validator to use instead of a shipped schema's (block parameters).
    """
    checker = checker if checker is not None else validator(name)
    findings: list[Finding] = []
    for err in checker.iter_errors(data):
        findings.extend(_convert(err, doc, base))
    return findings


def check_schema(schema: Mapping[str, Any]) -> str | None:
    """None when ``schema`` is a valid JSON Schema 2020-12, else the reason."""
    try:
        Draft202012Validator.check_schema(dict(schema))
    except jsonschema.SchemaError as exc:
        return str(exc.message)
    return None
