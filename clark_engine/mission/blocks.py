"""Behaviour blocks: reusable behaviours with declared parameters, from behaviors/.

A block file names itself, declares its parameters as a JSON Schema (defaults
included) and gives its machine, in which a value written ``$name`` stands for
parameter ``name``. Missions (and other blocks) use it like a primitive:
``use: aileron_doublet`` with ``with: {amplitude_us: 120}``.
"""

from __future__ import annotations

import difflib
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from jsonschema import Draft202012Validator

from clark_engine.behaviors import behaviors
from clark_engine.mission.findings import Finding, Location, error
from clark_engine.mission.plugin_data import clash_message
from clark_engine.mission.schemas import check_schema, validate_data
from clark_engine.mission.yaml_loader import Document, YamlLoadError, decode_text, load_yaml


@dataclass(slots=True)
class Block:
    """A loaded, schema-valid behaviour block.

    Attributes:
        name: What missions write after ``use:``.
        doc: The block file (for locations).
        description: What the block does.
        parameters: JSON Schema of the block's ``with:``.
        machine: The block's state, as written (``$name`` references unresolved).
        checker: Compiled validator for ``parameters``.
    """

    name: str
    doc: Document
    description: str
    parameters: dict[str, Any]
    machine: dict[str, Any]
    checker: Draft202012Validator

    def defaults(self) -> dict[str, Any]:
        """Parameter name -> declared default."""
        return {
            key: prop["default"]
            for key, prop in self.parameters.get("properties", {}).items()
            if isinstance(prop, dict) and "default" in prop
        }

    def default_location(self, param: str) -> Location:
        """Where a parameter's default is written in the block file."""
        return self.doc.location(("parameters", "properties", param, "default"))


class BlockLibrary:
    """Every behaviour block visible to a mission, read on first use."""

    def __init__(self, folders: Sequence[tuple[Path, str] | tuple[Path, str, str]]) -> None:
        """Index ``folders``: (folder, how to show its paths in findings[, plugin origin]).

        A folder an installed plugin adds carries its origin (which plugin and entry
        point, :mod:`clark_engine.mission.plugin_data`), which a duplicate name names.
        """
        self._files: dict[str, tuple[Path, str]] = {}
        self._origins: dict[str, str] = {}
        self._blocks: dict[str, Block | None] = {}
        self.findings: list[Finding] = []
        for entry in folders:
            folder, shown = entry[0], entry[1]
            origin = entry[2] if len(entry) == 3 else ""
            for file in sorted(folder.rglob("*.yaml")):
                display = f"{shown}/{file.relative_to(folder).as_posix()}"
                if file.stem in self._files:
                    taken = (self._files[file.stem][1], self._origins[file.stem])
                    message = (
                        clash_message("block", file.stem, (display, origin), taken)
                        if origin or taken[1]
                        else f"a block named {file.stem!r} already exists in {taken[0]}; "
                        "rename one of them"
                    )
                    self.findings.append(
                        error("E-BLOCK-DUPLICATE", Location(display, 1, 1), message)
                    )
                    continue
                if file.stem in behaviors():
                    self.findings.append(
                        error(
                            "E-BLOCK-SHADOWED",
                            Location(display, 1, 1),
                            f"a block named {file.stem!r} has the name of a behaviour: "
                            f"`use: {file.stem}` runs the behaviour, never this block "
                            "(a behaviour added to the engine or by a plugin takes the "
                            "name); rename the block, file and `block:` alike",
                        )
                    )
                    continue
                self._files[file.stem] = (file, display)
                self._origins[file.stem] = origin

    def names(self) -> list[str]:
        """Names of every visible block."""
        return sorted(self._files)

    def origin_of(self, name: str) -> tuple[str, str]:
        """(how the block's file is shown, the plugin that adds it or "")."""
        return self._files[name][1], self._origins[name]

    def __contains__(self, name: object) -> bool:
        return name in self._files

    def suggest(self, word: str, extra: Sequence[str] = ()) -> str:
        """A "did you mean" clause among blocks and ``extra`` names."""
        close = difflib.get_close_matches(word, [*self._files, *extra], n=1)
        return f"did you mean {close[0]!r}?" if close else "see docs/reference.md for the list"

    def get(self, name: str) -> Block | None:
        """The block, or None when it is unknown or invalid (findings say why)."""
        if name in self._blocks:
            return self._blocks[name]
        self._blocks[name] = None
        if name not in self._files:
            return None
        file, display = self._files[name]
        try:
            doc = load_yaml(decode_text(file.read_bytes(), display), display)
        except YamlLoadError as exc:
            self.findings.extend(exc.findings)
            return None
        problems = [*doc.findings, *validate_data("behavior", doc.data, doc)]
        if problems:
            self.findings.extend(problems)
            if any(p.is_error for p in problems):
                return None
        data = doc.data
        if data["block"] != name:
            self.findings.append(
                error(
                    "E-BLOCK-NAME",
                    doc.location(("block",)),
                    f"the file is {file.name} but names block {data['block']!r}; "
                    "make the two agree",
                )
            )
            return None
        parameters = data.get("parameters") or {"type": "object", "properties": {}}
        parameters.setdefault("type", "object")
        parameters.setdefault("additionalProperties", False)
        problem = check_schema(parameters)
        if problem is not None:
            self.findings.append(
                error(
                    "E-BLOCK-PARAMS",
                    doc.location(("parameters",)),
                    f"the parameters are not a valid JSON Schema: {problem}",
                )
            )
            return None
        block = Block(
            name=name,
            doc=doc,
            description=str(data["description"]),
            parameters=parameters,
            machine=data["machine"],
            checker=Draft202012Validator(parameters),
        )
        self._blocks[name] = block
        return block
