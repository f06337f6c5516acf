"""A strict YAML loader on PyYAML that remembers where every value came from.

Why not ``yaml.safe_load``: it silently keeps the last of two duplicate keys,
reads ``on``/``off``/``yes``/``no`` as booleans (YAML 1.1), turns ``1:30`` into
90 and ``010`` into 8, expands alias bombs without limit, and forgets line
numbers. A mission file must not mean something other than what its author
sees, and every later error must point at the exact place to change.

This loader composes the document with PyYAML (libyaml's parser when present),
then builds plain JSON-compatible data itself:

* scalars resolve by the YAML 1.2 core schema: booleans are only ``true`` and
  ``false`` (any case style YAML 1.2 allows), integers are decimal, ``0o`` or
  ``0x``, there are no sexagesimal numbers and no timestamps;
* a bare ``on``/``off``/``yes``/``no`` is kept as text and reported, because
  other YAML tools would read it as a boolean;
* duplicate keys are reported, every one of them;
* nesting depth and the number of values built (which counts alias expansion)
  are bounded, so a small file cannot exhaust memory;
* the line and column of every key and value is kept, by document path.
"""

from __future__ import annotations

import math
import re
from dataclasses import dataclass, field
from typing import Any, cast

import yaml
from yaml.composer import Composer
from yaml.nodes import MappingNode, Node, ScalarNode, SequenceNode
from yaml.resolver import BaseResolver

from clark_engine.mission.findings import DocPath, Finding, Location, error, format_path

#: Largest file the loader reads. Missions are hand-written; 4 MiB is ~100x a large one.
MAX_FILE_BYTES = 4 * 1024 * 1024
#: Deepest nesting of mappings and sequences accepted.
MAX_DEPTH = 64
#: Values the loader may build beyond the ones written out in the file (alias expansion).
MAX_ALIAS_EXPANSION = 10_000

#: Most digits a whole number may have. No setting takes more than ten; past 4300, Python
#: will not turn a number into text (a ``0x`` literal of 5,000 digits is read, then
#: breaks every message that quotes it, jsonschema's own included).
MAX_INT_DIGITS = 1000
#: The same bound in bits, for ``0x`` and ``0o`` literals (10^1000 is about 2^3322).
_MAX_INT_BITS = 3322

BOOL_WORDS = frozenset({"yes", "no", "on", "off"})

_STR = "tag:yaml.org,2002:str"
_INT = "tag:yaml.org,2002:int"
_FLOAT = "tag:yaml.org,2002:float"
_BOOL = "tag:yaml.org,2002:bool"
_NULL = "tag:yaml.org,2002:null"
_MAP = "tag:yaml.org,2002:map"
#: Plain yes/no/on/off: text to us, a boolean to YAML 1.1 tools; reported where found.
#: A tag of our own keeps them apart from quoted or explicitly tagged text (!!str yes).
_BOOL_WORD = "tag:clark-engine,2026:bool-word"
_SEQ = "tag:yaml.org,2002:seq"
_SCALAR_TAGS = frozenset({_STR, _INT, _FLOAT, _BOOL, _NULL, _BOOL_WORD})

_INT_RE = re.compile(r"^(?:[-+]?[0-9]+|0o[0-7]+|0x[0-9a-fA-F]+)$")
_FLOAT_RE = re.compile(
    r"^(?:[-+]?(?:\.[0-9]+|[0-9]+(?:\.[0-9]*)?)(?:[eE][-+]?[0-9]+)?"
    r"|[-+]?\.(?:inf|Inf|INF)|\.(?:nan|NaN|NAN))$"
)


class _Core12Resolver(BaseResolver):
    """Implicit tags of the YAML 1.2 core schema, nothing from YAML 1.1."""


_Core12Resolver.add_implicit_resolver(
    _BOOL, re.compile(r"^(?:true|True|TRUE|false|False|FALSE)$"), list("tTfF")
)
_Core12Resolver.add_implicit_resolver(_INT, _INT_RE, list("-+0123456789"))
_Core12Resolver.add_implicit_resolver(_FLOAT, _FLOAT_RE, list("-+0123456789."))
_Core12Resolver.add_implicit_resolver(
    _NULL, re.compile(r"^(?:~|null|Null|NULL|)$"), ["~", "n", "N", ""]
)
_Core12Resolver.add_implicit_resolver(
    _BOOL_WORD, re.compile(r"^(?i:yes|no|on|off)$"), list("yYnNoO")
)


class _DepthError(Exception):
    """Raised inside composition when nesting passes :data:`MAX_DEPTH`."""

    def __init__(self, mark: yaml.Mark | None) -> None:
        super().__init__("nesting too deep")
        self.mark = mark


class _BoundedComposer(Composer):
    """PyYAML's composer with a nesting bound and a count of nodes written out."""

    def __init__(self) -> None:
        super().__init__()
        self._depth = 0
        self.node_count = 0

    def compose_node(self, parent: Node | None, index: int) -> Node | None:
        self._depth += 1
        self.node_count += 1
        if self._depth > MAX_DEPTH:
            # peek_event comes from the parser this composer is mixed with.
            raise _DepthError(cast(Any, self).peek_event().start_mark)
        try:
            return super().compose_node(parent, index)
        finally:
            self._depth -= 1


try:  # libyaml's parser when PyYAML was built with it (the yaml package does not re-export it)
    from yaml._yaml import CParser as _CParser

    HAVE_LIBYAML = True
except ImportError:  # pragma: no cover - PyYAML built without libyaml
    HAVE_LIBYAML = False

if HAVE_LIBYAML:

    class _Loader(_BoundedComposer, _Core12Resolver, _CParser):
        """libyaml parses; our composer and resolver build nodes."""

        def __init__(self, stream: str) -> None:
            _CParser.__init__(self, stream)
            _BoundedComposer.__init__(self)
            _Core12Resolver.__init__(self)

else:  # pragma: no cover - PyYAML built without libyaml

    class _Loader(  # type: ignore[no-redef]
        yaml.reader.Reader,
        yaml.scanner.Scanner,
        yaml.parser.Parser,
        _BoundedComposer,
        _Core12Resolver,
    ):
        """Pure-Python fallback with the same behaviour."""

        def __init__(self, stream: str) -> None:
            yaml.reader.Reader.__init__(self, stream)
            yaml.scanner.Scanner.__init__(self)
            yaml.parser.Parser.__init__(self)
            _BoundedComposer.__init__(self)
            _Core12Resolver.__init__(self)


@dataclass(frozen=True, slots=True)
class Mark:
    """A 1-based line and column in a source file."""

    line: int
    column: int


@dataclass(slots=True)
class Document:
    """A loaded YAML document: plain data plus where each part of it was written.

    Attributes:
        file: The file name as the user gave it; every finding names it.
        data: JSON-compatible data (dict, list, str, int, float, bool, None).
        value_marks: Document path -> position of the value at that path.
        key_marks: Document path -> position of the mapping key naming that path.
        findings: Problems found while loading (duplicate keys, boolean words).
    """

    file: str
    data: Any
    value_marks: dict[DocPath, Mark] = field(default_factory=dict)
    key_marks: dict[DocPath, Mark] = field(default_factory=dict)
    findings: list[Finding] = field(default_factory=list)

    def location(self, path: DocPath, *, key: bool = False) -> Location:
        """Where ``path`` was written; the nearest written ancestor if it was not.

        Args:
            path: Document path of the value.
            key: Point at the key naming the value rather than the value itself
                (used for unknown keys, so the caret lands on the misspelling).
        """
        probe = path
        while True:
            marks = self.key_marks if key else self.value_marks
            mark = marks.get(probe) or self.value_marks.get(probe)
            if mark is not None:
                return Location(self.file, mark.line, mark.column, path)
            if not probe:
                return Location(self.file, 1, 1, path)
            probe = probe[:-1]
            key = False


class YamlLoadError(Exception):
    """The file cannot be turned into data at all; ``findings`` says why."""

    def __init__(self, findings: list[Finding]) -> None:
        super().__init__("; ".join(f.message for f in findings))
        self.findings = findings


def _mark(ymark: yaml.Mark | None) -> Mark:
    if ymark is None:
        return Mark(1, 1)
    return Mark(ymark.line + 1, ymark.column + 1)


class _Builder:
    """Turns a composed node tree into plain data, marks and findings."""

    def __init__(self, file: str, budget: int) -> None:
        self.doc = Document(file=file, data=None)
        self.budget = budget
        self.built = 0

    def loc(self, node: Node, path: DocPath) -> Location:
        mark = _mark(node.start_mark)
        return Location(self.doc.file, mark.line, mark.column, path)

    def build(self, node: Node, path: DocPath, depth: int = 0) -> Any:
        self.built += 1
        if self.built > self.budget:
            raise YamlLoadError(
                [
                    error(
                        "E-YAML-ALIAS",
                        self.loc(node, path),
                        "aliases expand to more than "
                        f"{MAX_ALIAS_EXPANSION} values beyond those written out; "
                        "this looks like an alias bomb, write the values out or use fewer aliases",
                    )
                ]
            )
        if depth > MAX_DEPTH:
            raise YamlLoadError(
                [
                    error(
                        "E-YAML-DEPTH",
                        self.loc(node, path),
                        f"values nest deeper than {MAX_DEPTH} levels (or an alias refers to "
                        "itself); flatten the structure",
                    )
                ]
            )
        self.doc.value_marks.setdefault(path, _mark(node.start_mark))
        if isinstance(node, ScalarNode):
            return self.scalar(node, path)
        if isinstance(node, SequenceNode):
            if node.tag not in (_SEQ,):
                self.bad_tag(node, path)
            return [self.build(item, (*path, i), depth + 1) for i, item in enumerate(node.value)]
        if isinstance(node, MappingNode):
            if node.tag not in (_MAP,):
                self.bad_tag(node, path)
            return self.mapping(node, path, depth)
        raise AssertionError(f"unexpected YAML node {node!r}")  # pragma: no cover

    def bad_tag(self, node: Node, path: DocPath) -> None:
        self.doc.findings.append(
            error(
                "E-YAML-TAG",
                self.loc(node, path),
                f"the tag {node.tag!r} is not supported; remove it, missions use plain YAML values",
            )
        )

    def scalar(self, node: ScalarNode, path: DocPath) -> Any:
        tag, value = node.tag, node.value
        if tag not in _SCALAR_TAGS:
            self.bad_tag(node, path)
            return value
        if tag == _BOOL_WORD:
            self.doc.findings.append(
                error(
                    "E-YAML-BOOL-WORD",
                    self.loc(node, path),
                    f"bare {value!r} is a boolean to YAML 1.1 tools but text to Clark; "
                    f"write true or false for a yes/no setting, or quote it ('{value}') "
                    "if you mean the word",
                )
            )
            return value
        if tag == _STR:
            return value
        if tag == _NULL:
            return None
        if tag == _BOOL:
            if value.lower() not in ("true", "false"):
                self.doc.findings.append(
                    error("E-YAML-VALUE", self.loc(node, path), f"{value!r} is not true or false")
                )
                return value
            return value.lower() == "true"
        if tag == _INT:
            digits = len(value.lstrip("+-"))
            try:
                if value[:2] in ("0o", "0x"):
                    whole = int(value, 0)
                    if whole.bit_length() > _MAX_INT_BITS:
                        digits = int(whole.bit_length() * math.log10(2)) + 1
                        raise ValueError("too many digits")
                    return whole
                if digits > MAX_INT_DIGITS:
                    raise ValueError("too many digits")
                return int(value, 10)
            except ValueError:
                what = (
                    f"this whole number has about {digits} digits, more than any setting "
                    "takes; write a value in the setting's range"
                    if digits > MAX_INT_DIGITS
                    else f"{value!r} is not an integer"
                )
                self.doc.findings.append(error("E-YAML-VALUE", self.loc(node, path), what))
                return value
        # float
        try:
            number = float(value.lower().replace(".inf", "inf").replace(".nan", "nan"))
        except ValueError:
            self.doc.findings.append(
                error("E-YAML-VALUE", self.loc(node, path), f"{value!r} is not a number")
            )
            return value
        if not math.isfinite(number):
            self.doc.findings.append(
                error(
                    "E-YAML-VALUE",
                    self.loc(node, path),
                    f"{value!r} is not a finite number; write a finite value",
                )
            )
            return value
        return number

    def key_text(self, key: Node, path: DocPath) -> str | None:
        if not isinstance(key, ScalarNode):
            self.doc.findings.append(
                error(
                    "E-YAML-KEY",
                    self.loc(key, path),
                    "a key must be a plain word, not a list or mapping; rewrite this key",
                )
            )
            return None
        text: str = key.value
        if key.tag == _BOOL_WORD:
            self.doc.findings.append(
                error(
                    "E-YAML-BOOL-WORD",
                    self.loc(key, path),
                    f"the key {text!r} is read as a boolean by YAML 1.1 tools; "
                    f"quote it ('{text}') or choose another word",
                )
            )
        return text

    def mapping(self, node: MappingNode, path: DocPath, depth: int) -> dict[str, Any]:
        result: dict[str, Any] = {}
        first_seen: dict[str, Node] = {}
        merged: dict[str, Any] = {}
        for key_node, value_node in node.value:
            key = self.key_text(key_node, path)
            if key is None:
                continue
            if key == "<<" and isinstance(key_node, ScalarNode) and not key_node.style:
                self.merge(key_node, value_node, path, depth, merged)
                continue
            child = (*path, key)
            if key in first_seen:
                first = _mark(first_seen[key].start_mark)
                self.doc.findings.append(
                    error(
                        "E-YAML-DUPLICATE-KEY",
                        self.loc(key_node, child),
                        f"the key {key!r} appears twice in this mapping (first at line "
                        f"{first.line}); YAML tools disagree on which one wins, so keep one",
                    )
                )
                continue
            first_seen[key] = key_node
            self.doc.key_marks[child] = _mark(key_node.start_mark)
            result[key] = self.build(value_node, child, depth + 1)
        for key, value in merged.items():
            result.setdefault(key, value)
        return result

    def merge(
        self, key_node: Node, value_node: Node, path: DocPath, depth: int, into: dict[str, Any]
    ) -> None:
        """YAML merge keys (``<<: *defaults``): explicit keys win over merged ones."""
        sources = value_node.value if isinstance(value_node, SequenceNode) else [value_node]
        for source in sources:
            if not isinstance(source, MappingNode):
                # An alias's node carries the anchor's position; point at the '<<' instead.
                self.doc.findings.append(
                    error(
                        "E-YAML-MERGE",
                        self.loc(key_node, path),
                        "'<<' merges mappings only; point it at an anchored mapping (<<: *name)",
                    )
                )
                continue
            built = self.mapping(source, path, depth + 1)
            for key, value in built.items():
                into.setdefault(key, value)


def _syntax_finding(file: str, exc: yaml.YAMLError, text: str = "") -> Finding:
    mark = getattr(exc, "problem_mark", None) or getattr(exc, "context_mark", None)
    where = _mark(mark)
    problem = getattr(exc, "problem", None) or str(exc)
    context = getattr(exc, "context", None)
    opened = getattr(exc, "context_mark", None)
    message = f"{context}, {problem}" if context else str(problem)
    if context and opened is not None and mark is not None and opened.line != mark.line:
        message += f" (it was opened at line {opened.line + 1}, column {opened.column + 1})"
    hint = "fix the YAML syntax here"
    lines = text.splitlines()
    at_tab = (
        mark is not None
        and mark.line < len(lines)
        and lines[mark.line][mark.column : mark.column + 1] == "\t"
    )
    if at_tab or "\\t" in message or "'\\t'" in message:
        hint = "indent with spaces; YAML does not allow tabs for indentation"
    elif "mapping values are not allowed" in message:
        hint = "a value containing ': ' must be quoted, or the indentation is off"
    elif "could not find expected ':'" in message:
        hint = "a key is missing its ':' or the line is indented wrongly"
    return error("E-YAML-SYNTAX", Location(file, where.line, where.column), f"{message}; {hint}")


def decode_text(raw: bytes, file: str) -> str:
    """Decode a file's bytes as UTF-8 text, refusing binary and oversized input.

    Raises:
        YamlLoadError: The bytes are not a text file a mission could be.
    """
    here = Location(file, 1, 1)
    if len(raw) > MAX_FILE_BYTES:
        raise YamlLoadError(
            [
                error(
                    "E-YAML-TOO-LARGE",
                    here,
                    f"the file is {len(raw)} bytes; missions are limited to {MAX_FILE_BYTES} bytes",
                )
            ]
        )
    if b"\x00" in raw[:8192]:
        raise YamlLoadError(
            [
                error(
                    "E-YAML-BINARY",
                    here,
                    "this is a binary file, not YAML text; give a mission file",
                )
            ]
        )
    try:
        return raw.decode("utf-8-sig")
    except UnicodeDecodeError as exc:
        line = raw[: exc.start].count(b"\n") + 1
        column = exc.start - (raw.rfind(b"\n", 0, exc.start) + 1) + 1
        raise YamlLoadError(
            [
                error(
                    "E-YAML-BINARY",
                    Location(file, line, column),
                    f"the file is not UTF-8 text (byte {exc.start + 1} is not valid UTF-8); "
                    "save it as UTF-8",
                )
            ]
        ) from None


def load_yaml(text: str, file: str) -> Document:
    """Load one YAML document strictly, keeping positions and collecting findings.

    Args:
        text: The document's text.
        file: The name to report in findings (as the user wrote it).

    Returns:
        The document. Non-fatal problems (duplicate keys, boolean words) are in
        ``Document.findings``; the data is still returned so validation goes on.

    Raises:
        YamlLoadError: Nothing usable could be read (syntax error, empty file,
            several documents, alias bomb, nesting too deep).
    """
    loader = _Loader(text)
    try:
        try:
            node = loader.get_single_node()
        except _DepthError as exc:
            mark = _mark(exc.mark)
            raise YamlLoadError(
                [
                    error(
                        "E-YAML-DEPTH",
                        Location(file, mark.line, mark.column),
                        f"values nest deeper than {MAX_DEPTH} levels; flatten the structure",
                    )
                ]
            ) from None
        except yaml.composer.ComposerError as exc:
            if "expected a single document" in str(exc):
                where = _mark(exc.problem_mark)
                raise YamlLoadError(
                    [
                        error(
                            "E-YAML-MULTI-DOC",
                            Location(file, where.line, where.column),
                            "a mission is one YAML document; remove the second '---' document",
                        )
                    ]
                ) from None
            raise YamlLoadError([_syntax_finding(file, exc, text)]) from None
        except yaml.YAMLError as exc:
            raise YamlLoadError([_syntax_finding(file, exc, text)]) from None
        except RecursionError:
            raise YamlLoadError(
                [
                    error(
                        "E-YAML-DEPTH", Location(file, 1, 1), "values nest too deeply; flatten them"
                    )
                ]
            ) from None
    finally:
        loader.dispose()
    if node is None or (isinstance(node, ScalarNode) and node.tag == _NULL):
        raise YamlLoadError(
            [
                error(
                    "E-YAML-EMPTY",
                    Location(file, 1, 1),
                    "the file holds no YAML document; start a mission with 'clark: 1'",
                )
            ]
        )
    builder = _Builder(file, budget=loader.node_count + MAX_ALIAS_EXPANSION)
    builder.doc.data = builder.build(node, ())
    return builder.doc


def describe_path(path: DocPath) -> str:
    """Re-exported convenience: render a document path for messages."""
    return format_path(path)
