"""Resolve an agent's behaviour into a tree of :class:`State` with every name looked up.

A behaviour is a ``use:`` of a primitive or block, or an inline machine. Blocks
are expanded in place (their ``$name`` references replaced by the parameters
the user gave or the block's defaults), primitive parameters are checked
against the primitive's schema and completed with its defaults, and every
transition target is resolved to a path from the root. Names resolve here,
when the mission loads, so nothing is looked up by string at flight time.
"""

from __future__ import annotations

import copy
import difflib
import functools
import re
from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import Any, Protocol

from jsonschema import Draft202012Validator

from clark_engine.behaviors import behaviors
from clark_engine.mission.blocks import Block, BlockLibrary
from clark_engine.mission.findings import DocPath, Finding, Location, error
from clark_engine.mission.model import State, Transition
from clark_engine.mission.schema_source.common import TIME_MAX_S
from clark_engine.mission.schema_source.states import condition_schema
from clark_engine.mission.schemas import validate_data
from clark_engine.mission.yaml_loader import Document

_PARAM_REF = re.compile(r"^\$([a-z][a-z0-9_]*)$")
#: Blocks may use blocks; deeper than this is surely a mistake (or a cycle).
MAX_BLOCK_DEPTH = 16


class Locator(Protocol):
    """Anything that says where a document path was written."""

    def location(self, path: DocPath, *, key: bool = False) -> Location:
        """Where ``path`` was written."""
        ...


@dataclass(slots=True)
class _BlockLocator:
    """Locations inside a block file, except values substituted from the caller."""

    doc: Document
    substituted: dict[DocPath, Location] = field(default_factory=dict)

    def location(self, path: DocPath, *, key: bool = False) -> Location:
        probe = path
        while probe:
            if probe in self.substituted:
                return self.substituted[probe]
            probe = probe[:-1]
        return self.doc.location(path, key=key)


@dataclass(slots=True)
class _Frame:
    """Where a piece of behaviour comes from while it is being resolved."""

    locator: Locator
    chain: tuple[str, ...] = ()  # blocks being expanded, outermost first
    use_sites: tuple[Location, ...] = ()  # where each of those blocks was used


class BehaviorResolver:
    """Builds the state tree of one agent's behaviour, collecting findings."""

    def __init__(self, blocks: BlockLibrary) -> None:
        """Resolve ``use:`` names against the primitives and ``blocks``."""
        self.blocks = blocks
        self.findings: list[Finding] = []
        #: State paths (of the last resolve) whose primitive parameters failed their schema.
        self.bad_paths: set[tuple[str, ...]] = set()

    # -- public -------------------------------------------------------------------------

    def resolve(self, raw: Mapping[str, Any], doc: Document, path: DocPath) -> State | None:
        """Resolve the behaviour written at ``path`` in ``doc``.

        Returns:
            The root state, or None when the behaviour is too broken to check further.
        """
        frame = _Frame(locator=doc)
        self.bad_paths = set()
        for key in ("transitions", "timeout_s", "final"):
            if key in raw:
                self.findings.append(
                    error(
                        "E-STATE-ROOT",
                        doc.location((*path, key), key=True),
                        f"the top of a behaviour cannot have {key}: there is nothing around it "
                        "to move to; put the states under states: and give them the " + key,
                    )
                )
        root = self._state("", (), raw, path, frame)
        if root is None:
            return None
        root.transitions = []  # reported above as E-STATE-ROOT; there is nowhere to go
        self._resolve_targets(root, root)
        return root

    # -- building states ----------------------------------------------------------------

    def _state(
        self,
        name: str,
        state_path: tuple[str, ...],
        raw: Mapping[str, Any],
        src: DocPath,
        frame: _Frame,
    ) -> State | None:
        loc = frame.locator.location(src)
        state = State(
            name=name,
            path=state_path,
            location=loc,
            mission_use=frame.use_sites[0] if frame.use_sites else None,
            final=bool(raw.get("final", False)),
            timeout_s=_timeout_s(raw.get("timeout_s")),
            timeout_location=(
                frame.locator.location((*src, "timeout_s")) if "timeout_s" in raw else None
            ),
            description=raw.get("description"),
        )
        self._shape(raw, src, frame, state)
        self._raw_transitions(state, raw, src, frame)
        use = raw.get("use")
        if isinstance(use, str):
            state.use_location = frame.locator.location((*src, "use"))
            if use in behaviors():
                self._primitive(state, use, raw, src, frame)
            elif use in self.blocks:
                self._block(state, use, raw, src, frame)
            else:
                state.unresolved = True
                self.findings.append(
                    error(
                        "E-BLOCK-UNKNOWN",
                        state.use_location,
                        f"{use!r} is neither a primitive nor a behaviour block; "
                        + self.blocks.suggest(use, list(behaviors())),
                        *frame.use_sites,
                    )
                )
            return state
        self._children(state, raw, src, frame)
        return state

    def _shape(self, raw: Mapping[str, Any], src: DocPath, frame: _Frame, state: State) -> None:
        has_use, has_states = "use" in raw, "states" in raw
        where = frame.locator.location(src)
        if has_use and (has_states or "initial" in raw or raw.get("parallel")):
            extra = next(k for k in ("states", "initial", "parallel") if k in raw)
            self.findings.append(
                error(
                    "E-STATE-SHAPE",
                    frame.locator.location((*src, extra), key=True),
                    f"a state either uses a primitive or block (use:) or holds states, not "
                    f"both; move the use: into a child state or remove {extra}:",
                    *frame.use_sites,
                )
            )
        if "with" in raw and not has_use:
            self.findings.append(
                error(
                    "E-STATE-SHAPE",
                    frame.locator.location((*src, "with"), key=True),
                    "with: gives parameters to a use:, but this state has no use:; add one",
                    *frame.use_sites,
                )
            )
        if not has_use and not has_states and not raw.get("final"):
            self.findings.append(
                error(
                    "E-STATE-EMPTY",
                    where,
                    "this state does nothing; give it use: (a primitive or block), states:, "
                    "or mark it final: true",
                    *frame.use_sites,
                )
            )
        if raw.get("parallel") and not has_states:
            self.findings.append(
                error(
                    "E-STATE-SHAPE",
                    frame.locator.location((*src, "parallel"), key=True),
                    "parallel: true runs child states side by side; add them under states:",
                    *frame.use_sites,
                )
            )
        if "finish" in raw and not raw.get("parallel"):
            self.findings.append(
                error(
                    "E-STATE-SHAPE",
                    frame.locator.location((*src, "finish"), key=True),
                    "finish: says when parallel regions end their state; add parallel: true "
                    "or remove finish:",
                    *frame.use_sites,
                )
            )
        if raw.get("final") and raw.get("transitions"):
            self.findings.append(
                error(
                    "E-FINAL-TRANSITIONS",
                    frame.locator.location((*src, "transitions"), key=True),
                    "a final state finishes its parent and is left only by the parent's "
                    "transitions; remove these transitions or final: true",
                    *frame.use_sites,
                )
            )

    def _raw_transitions(
        self, state: State, raw: Mapping[str, Any], src: DocPath, frame: _Frame
    ) -> None:
        """Record transitions with their targets as written; resolved once the tree exists."""
        for event, spec in (raw.get("transitions") or {}).items():
            base = (*src, "transitions", event)
            items: list[tuple[Any, DocPath]]
            if isinstance(spec, list):
                items = [(item, (*base, i)) for i, item in enumerate(spec)]
            else:
                items = [(spec, base)]
            for item, where in items:
                if isinstance(item, Mapping):
                    target, cond, target_path = item.get("to"), item.get("when"), (*where, "to")
                else:
                    target, cond, target_path = item, None, where
                transition = Transition(
                    event=str(event),
                    target=tuple(str(target).split(".")),
                    condition=copy.deepcopy(cond) if cond is not None else None,
                    location=frame.locator.location(target_path),
                )
                if cond is not None:
                    _record_condition(transition, cond, (), (*where, "when"), frame.locator)
                    if frame.chain:
                        self._check_substituted_condition(cond, (*where, "when"), frame)
                state.transitions.append(transition)

    def _check_substituted_condition(self, cond: Any, src: DocPath, frame: _Frame) -> None:
        """A block's ``when:`` after its ``$name`` values were replaced: of the right type.

        The block file's schema lets any condition value be a parameter reference; what the
        user (or the block's default) gave in its place is checked here, found at the value
        given, with the block's use as the related location.
        """
        problems = validate_data(
            "", cond, _AsDocument(frame.locator), src, checker=_condition_checker()
        )
        for finding in problems:
            self.findings.append(
                _with_related(
                    Finding(
                        "E-BLOCK-WHEN",
                        finding.severity,
                        finding.location,
                        "after the block's parameters are put in, its condition is wrong: "
                        + finding.message,
                        finding.related,
                    ),
                    frame.use_sites,
                )
            )

    def _children(self, state: State, raw: Mapping[str, Any], src: DocPath, frame: _Frame) -> None:
        children = raw.get("states") or {}
        state.parallel = bool(raw.get("parallel", False))
        state.finish = str(raw.get("finish", "all"))
        for child_name, child_raw in children.items():
            child = self._state(
                child_name,
                (*state.path, child_name),
                child_raw,
                (*src, "states", child_name),
                frame,
            )
            if child is not None:
                state.children[child_name] = child
        if not children:
            return
        initial = raw.get("initial")
        if state.parallel:
            if initial is not None:
                self.findings.append(
                    error(
                        "E-STATE-INITIAL",
                        frame.locator.location((*src, "initial"), key=True),
                        "parallel regions all start together; remove initial:",
                        *frame.use_sites,
                    )
                )
            return
        if initial is None:
            first = next(iter(children))
            self.findings.append(
                error(
                    "E-STATE-INITIAL",
                    frame.locator.location((*src, "states"), key=True),
                    f"say which child state comes first: add initial: {first}",
                    *frame.use_sites,
                )
            )
            return
        if initial not in children:
            self.findings.append(
                error(
                    "E-STATE-UNKNOWN",
                    frame.locator.location((*src, "initial")),
                    f"initial names {initial!r}, which is not one of its states "
                    f"({', '.join(children)}); " + _name_hint(str(initial), list(children)),
                    *frame.use_sites,
                )
            )
            return
        state.initial = initial

    def _primitive(
        self, state: State, name: str, raw: Mapping[str, Any], src: DocPath, frame: _Frame
    ) -> None:
        spec = behaviors()[name]
        given = raw.get("with") or {}
        if not isinstance(given, Mapping):
            return  # the schema reported it
        problems = validate_data(
            "",
            dict(given),
            _AsDocument(frame.locator),
            (*src, "with"),
            checker=_primitive_checker(name),
        )
        for finding in problems:
            self.findings.append(_with_related(finding, frame.use_sites))
        if any(p.is_error for p in problems):
            self.bad_paths.add(state.path)
            state.unresolved = True
        state.primitive = name
        state.params = spec.with_defaults(copy.deepcopy(dict(given)))
        use_loc = state.use_location or frame.locator.location(src)
        for key, value in state.params.items():
            if key in given:
                state.param_locations[key] = frame.locator.location((*src, "with", key))
                if isinstance(value, list):
                    for i in range(len(value)):
                        state.param_locations[f"{key}[{i}]"] = frame.locator.location(
                            (*src, "with", key, i)
                        )
            else:
                state.param_locations[key] = use_loc

    def _block(
        self, state: State, name: str, raw: Mapping[str, Any], src: DocPath, frame: _Frame
    ) -> None:
        use_loc = state.use_location or frame.locator.location(src)
        state.unresolved = True  # until the block's machine is expanded below
        if name in frame.chain:
            self.findings.append(
                error(
                    "E-BLOCK-CYCLE",
                    use_loc,
                    "blocks use each other in a cycle ("
                    + " -> ".join([*frame.chain, name])
                    + "); break the cycle",
                    *frame.use_sites,
                )
            )
            return
        if len(frame.chain) >= MAX_BLOCK_DEPTH:
            self.findings.append(
                error(
                    "E-BLOCK-CYCLE",
                    use_loc,
                    f"blocks nest deeper than {MAX_BLOCK_DEPTH}; flatten them",
                    *frame.use_sites,
                )
            )
            return
        block = self.blocks.get(name)
        if block is None:
            self.findings.append(
                error(
                    "E-BLOCK-INVALID",
                    use_loc,
                    f"block {name!r} cannot be used because its file has errors (reported with "
                    "that file); fix them first",
                    *frame.use_sites,
                )
            )
            return
        given = raw.get("with") or {}
        if not isinstance(given, Mapping):
            return
        with_doc = _AsDocument(frame.locator)
        problems = validate_data("", dict(given), with_doc, (*src, "with"), checker=block.checker)
        if problems:
            self.findings.extend(_with_related(p, frame.use_sites) for p in problems)
            return
        bindings: dict[str, tuple[Any, Location]] = {
            key: (value, block.default_location(key)) for key, value in block.defaults().items()
        }
        for key, value in given.items():
            bindings[key] = (value, frame.locator.location((*src, "with", key)))
        locator = _BlockLocator(block.doc)
        machine = self._substitute(block, block.machine, ("machine",), bindings, locator, frame)
        if machine is None:
            return
        inner = _Frame(
            locator=locator,
            chain=(*frame.chain, name),
            use_sites=(*frame.use_sites, use_loc),
        )
        for key in ("transitions", "timeout_s", "final"):
            if key in machine:
                self.findings.append(
                    error(
                        "E-BLOCK-SHAPE",
                        block.doc.location(("machine", key), key=True),
                        f"a block's machine cannot have {key}: at its top; the state that uses "
                        "the block sets it",
                        use_loc,
                    )
                )
        body = {
            k: v
            for k, v in machine.items()
            if k not in ("transitions", "timeout_s", "final", "description")
        }
        expanded = self._state(state.name, state.path, body, ("machine",), inner)
        if expanded is None:
            return
        state.unresolved = expanded.unresolved
        state.primitive = expanded.primitive
        state.params = expanded.params
        state.param_locations = expanded.param_locations
        state.children = expanded.children
        state.initial = expanded.initial
        state.parallel = expanded.parallel
        state.finish = expanded.finish
        state.block = name
        state.mission_use = state.mission_use or use_loc
        state.transitions.extend(expanded.transitions)
        if state.description is None:
            state.description = block.description

    def _substitute(
        self,
        block: Block,
        value: Any,
        path: DocPath,
        bindings: Mapping[str, tuple[Any, Location]],
        locator: _BlockLocator,
        frame: _Frame,
        in_with: bool = False,
    ) -> Any:
        """Replace ``$name`` values inside ``with:`` and ``when:`` mappings by their parameters."""
        if isinstance(value, Mapping):
            out = {}
            for key, item in value.items():
                out[key] = self._substitute(
                    block,
                    item,
                    (*path, key),
                    bindings,
                    locator,
                    frame,
                    in_with or key == "with" or _is_when(path, key),
                )
            return out
        if isinstance(value, list):
            return [
                self._substitute(block, item, (*path, i), bindings, locator, frame, in_with)
                for i, item in enumerate(value)
            ]
        if in_with and isinstance(value, str):
            match = _PARAM_REF.match(value)
            if match:
                param = match.group(1)
                if param not in bindings:
                    declared = ", ".join(block.parameters.get("properties", {})) or "none"
                    self.findings.append(
                        error(
                            "E-BLOCK-PARAM",
                            block.doc.location(path),
                            f"${param} is not a parameter of block {block.name!r} with a value "
                            f"(declared: {declared}); declare it with a default, or the user "
                            "must give it",
                            *frame.use_sites,
                        )
                    )
                    return value
                bound, where = bindings[param]
                locator.substituted[path] = where
                return copy.deepcopy(bound)
        return value

    # -- transitions ----------------------------------------------------------------------

    def _resolve_targets(self, root: State, state: State) -> None:
        for transition in state.transitions:
            resolved = _lookup(root, state.path, transition.target)
            if resolved is None:
                visible = _visible_names(root, state.path)
                hint = _name_hint(transition.target[0], visible)
                self.findings.append(
                    error(
                        "E-STATE-UNKNOWN",
                        transition.location,
                        f"on {transition.event}, no state {'.'.join(transition.target)!r} is "
                        f"reachable from {state.dotted}; {hint}",
                    )
                )
                transition.target = ()
            else:
                transition.target = resolved
        for child in state.children.values():
            self._resolve_targets(root, child)


def _timeout_s(value: Any) -> float | None:
    """A state's timeout when it is one the schema accepts; None otherwise.

    The schema reports a timeout out of range (E-RANGE) and the state is still resolved,
    so that the rest of its errors are found too: the checks that follow must not do
    arithmetic on ``10**400`` (OverflowError) or a word.
    """
    if isinstance(value, int | float) and not isinstance(value, bool) and 0 < value <= TIME_MAX_S:
        return float(value)
    return None


def _name_hint(written: str, names: list[str]) -> str:
    """``did you mean 'home'?`` for a misspelt (or capitalised) state name, else the choices."""
    close = [n for n in names if n.lower() == written.lower()]
    close = close or difflib.get_close_matches(written.lower(), names, n=1)
    if close:
        return f"did you mean {close[0]!r}?"
    return "name one of: " + ", ".join(sorted(names))


def _record_condition(
    transition: Transition,
    value: Any,
    sub: tuple[str | int, ...],
    src: DocPath,
    locator: Locator,
) -> None:
    """Remember where each part of a transition's condition was written."""
    transition.condition_locations[sub] = locator.location(src)
    if isinstance(value, Mapping):
        for key, item in value.items():
            _record_condition(transition, item, (*sub, key), (*src, key), locator)
    elif isinstance(value, list):
        for i, item in enumerate(value):
            _record_condition(transition, item, (*sub, i), (*src, i), locator)


def _lookup(
    root: State, from_path: tuple[str, ...], target: tuple[str, ...]
) -> tuple[str, ...] | None:
    """Find ``target`` among the siblings of ``from_path``, then its ancestors' siblings."""
    scope = from_path[:-1]
    while True:
        parent = root.find(scope)
        if parent is not None and target[0] in parent.children:
            found = parent.find(target)
            if found is not None:
                return found.path
        if not scope:
            return None
        scope = scope[:-1]


def _visible_names(root: State, from_path: tuple[str, ...]) -> list[str]:
    names: list[str] = []
    scope = from_path[:-1]
    while True:
        parent = root.find(scope)
        if parent is not None:
            names.extend(parent.children)
        if not scope:
            return names
        scope = scope[:-1]


def _with_related(finding: Finding, sites: tuple[Location, ...]) -> Finding:
    if not sites:
        return finding
    return Finding(
        finding.code,
        finding.severity,
        finding.location,
        finding.message,
        (*finding.related, *sites),
    )


class _AsDocument(Document):
    """Adapts any :class:`Locator` to the Document interface schema validation uses."""

    def __init__(self, locator: Locator) -> None:
        super().__init__(file="", data=None)
        self._locator = locator

    def location(self, path: DocPath, *, key: bool = False) -> Location:
        return self._locator.location(path, key=key)


def _is_when(path: DocPath, key: str | int) -> bool:
    """Whether ``(*path, key)`` is a transition's ``when:`` (``transitions.<event>[.<i>].when``)."""
    if key != "when":
        return False
    return (len(path) >= 2 and path[-2] == "transitions") or (
        len(path) >= 3 and path[-3] == "transitions" and isinstance(path[-1], int)
    )


@functools.cache
def _condition_checker() -> Draft202012Validator:
    """Validator of one condition as a mission writes it (no parameter references)."""
    return Draft202012Validator(
        {"$ref": "#/$defs/condition", "$defs": {"condition": condition_schema()}}
    )


@functools.cache
def _primitive_checker(name: str) -> Draft202012Validator:
    """Validator of one primitive's parameters; built once, the schemas are constant."""
    return Draft202012Validator(behaviors()[name].schema)
