"""The shipped schemas: in step with their source, valid, and documented."""

from __future__ import annotations

import json
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import pytest
from jsonschema import Draft202012Validator

from clark_engine.mission.schema_source.render import SCHEMA_FILES, render

ROOT = Path(__file__).resolve().parent.parent


@pytest.mark.parametrize("file_name", SCHEMA_FILES)
def test_schema_file_matches_its_source(file_name: str) -> None:
    on_disk = (ROOT / "schemas" / file_name).read_text(encoding="utf-8")
    assert on_disk == render(file_name), f"schemas/{file_name} is out of date; run `make schemas`"


@pytest.mark.parametrize("file_name", SCHEMA_FILES)
def test_schema_is_valid_2020_12(file_name: str) -> None:
    schema = json.loads((ROOT / "schemas" / file_name).read_text(encoding="utf-8"))
    assert schema["$schema"] == "https://json-schema.org/draft/2020-12/schema"
    Draft202012Validator.check_schema(schema)


def _properties(schema: Any, path: str = "") -> Iterator[tuple[str, dict[str, Any]]]:
    if isinstance(schema, dict):
        for name, prop in (schema.get("properties") or {}).items():
            if isinstance(prop, dict):
                yield f"{path}.{name}", prop
        for key, value in schema.items():
            if key in ("properties", "$defs"):
                for name, sub in value.items():
                    yield from _properties(sub, f"{path}.{name}")
            elif isinstance(value, (dict, list)):
                yield from _properties(value, f"{path}/{key}")
    elif isinstance(schema, list):
        for i, item in enumerate(schema):
            yield from _properties(item, f"{path}[{i}]")


@pytest.mark.parametrize("file_name", ["mission.schema.json", "hardware_profile.schema.json"])
def test_every_property_a_user_sets_is_described(file_name: str) -> None:
    schema = json.loads((ROOT / "schemas" / file_name).read_text(encoding="utf-8"))
    # if/then/else/not branches refine a property described where it is declared.
    refinements = ("/if", "/then", "/else", "/not")
    undocumented = [
        path
        for path, prop in _properties(schema)
        if "description" not in prop
        and "$ref" not in prop
        and prop not in ({}, True)
        and not any(r in path for r in refinements)
    ]
    assert undocumented == []


def test_numbers_with_units_name_their_unit() -> None:
    schema = json.loads((ROOT / "schemas" / "mission.schema.json").read_text(encoding="utf-8"))
    unitless = [
        path
        for path, prop in _properties(schema)
        if path.rsplit(".", 1)[-1].endswith(("_m", "_s", "_hz", "_us", "_deg"))
        and prop.get("type") == "number"
        and "x-unit" not in prop
    ]
    assert unitless == []


def test_example_missions_declare_the_schema_for_editors() -> None:
    for mission in sorted((ROOT / "missions").glob("*.yaml")):
        first = mission.read_text(encoding="utf-8").splitlines()[0]
        assert first == "# yaml-language-server: $schema=../schemas/mission.schema.json", mission
    for block in sorted((ROOT / "behaviors").glob("*.yaml")):
        first = block.read_text(encoding="utf-8").splitlines()[0]
        assert first == "# yaml-language-server: $schema=../schemas/behavior.schema.json", block


def test_runtime_behavior_sections_are_generated_from_the_runtime_classes() -> None:
    # docs/runtime.md's behaviour sections are the runtime classes' docstrings.
    import subprocess
    import sys

    proc = subprocess.run(
        [sys.executable, "tools/gen_runtime_doc.py", "--check"],
        cwd=ROOT,
        capture_output=True,
        text=True,
        timeout=120,
        check=False,
    )
    assert proc.returncode == 0, proc.stdout + proc.stderr + "\nrun `make schemas`"


def test_language_reference_is_generated_from_the_schemas() -> None:
    import subprocess
    import sys

    proc = subprocess.run(
        [sys.executable, "tools/gen_reference.py", "--check"],
        cwd=ROOT,
        capture_output=True,
        text=True,
        timeout=120,
        check=False,
    )
    assert proc.returncode == 0, proc.stdout + proc.stderr + "\nrun `make schemas`"
