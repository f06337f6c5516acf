"""Fuzzing the validator: whatever a user writes, validation reports findings, never crashes.

Mutations of the valid example missions (keys dropped, values of the wrong type,
keys renamed, states rewired) and byte-level damage to their text. Bounded so the
suite stays fast; a crash here is a bug in the engine, not in the input.
"""

from __future__ import annotations

import copy
import tempfile
from pathlib import Path
from typing import Any

import yaml
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from clark_engine.mission.compiler import compile_mission
from clark_engine.mission.validate import validate_path

ROOT = Path(__file__).resolve().parent.parent
SOURCES = {
    p.name: p.read_text(encoding="utf-8") for p in sorted((ROOT / "missions").glob("*.yaml"))
}
DATA = {name: yaml.safe_load(text) for name, text in SOURCES.items()}

SCALARS = st.one_of(
    st.none(),
    st.booleans(),
    st.integers(min_value=-(10**6), max_value=10**6),
    st.floats(allow_nan=False, allow_infinity=False, width=32),
    st.text(alphabet="abcxyz_:.$ 0123456789", max_size=12),
)
VALUES = st.recursive(
    SCALARS,
    lambda inner: st.one_of(
        st.lists(inner, max_size=3),
        st.dictionaries(st.text(alphabet="abcdefghij_", min_size=1, max_size=8), inner, max_size=3),
    ),
    max_leaves=6,
)


def _paths(node: Any, prefix: tuple[Any, ...] = ()) -> list[tuple[Any, ...]]:
    out = [prefix]
    if isinstance(node, dict):
        for key, value in node.items():
            out.extend(_paths(value, (*prefix, key)))
    elif isinstance(node, list):
        for i, value in enumerate(node):
            out.extend(_paths(value, (*prefix, i)))
    return out


def _validate_text(text: str) -> None:
    with tempfile.TemporaryDirectory() as tmp:
        path = Path(tmp) / "fuzz.yaml"
        path.write_text(text, encoding="utf-8")
        result = validate_path(path, "fuzz.yaml")
    for finding in result.findings:
        assert finding.message and finding.code and finding.location.line is not None
    if result.mission is not None:
        compile_mission(result.mission)  # anything that validates must compile


@st.composite
def mutated(draw: st.DrawFn) -> str:
    name = draw(st.sampled_from(sorted(DATA)))
    data = copy.deepcopy(DATA[name])
    for _ in range(draw(st.integers(min_value=1, max_value=3))):
        paths = [p for p in _paths(data) if p]
        path = draw(st.sampled_from(paths))
        parent: Any = data
        for part in path[:-1]:
            parent = parent[part]
        action = draw(st.sampled_from(["delete", "replace", "rename", "retarget"]))
        key = path[-1]
        if action == "delete":
            del parent[key]
        elif action == "replace":
            parent[key] = draw(VALUES)
        elif action == "rename" and isinstance(parent, dict):
            parent[draw(st.text(alphabet="abcdefghij_", min_size=1, max_size=8))] = parent.pop(key)
        elif action == "retarget" and isinstance(parent, dict):
            parent[key] = draw(st.sampled_from(["idle", "chase", "excite", "nowhere", "a.b", "$x"]))
    return yaml.safe_dump(data, sort_keys=False)


# derandomize: the suite runs the same examples every time; benchmarks/fuzz_validate.py
# runs many more with fresh randomness.
@settings(
    max_examples=150,
    deadline=None,
    derandomize=True,
    suppress_health_check=[HealthCheck.too_slow],
)
@given(mutated())
def test_mutated_missions_give_findings_not_crashes(text: str) -> None:
    _validate_text(text)


def test_agent_settings_of_the_wrong_shape() -> None:
    """Found by fuzzing: a failsafe written as a word instead of a mapping."""
    text = SOURCES["supercub_sysid_rc.yaml"].replace(
        "failsafe: {mcs_lost: continue}", "failsafe: idle"
    )
    assert "failsafe: idle" in text
    _validate_text(text)


def test_checks_of_the_wrong_shape() -> None:
    """Found by fuzzing: checks written as a boolean instead of a list."""
    _validate_text(SOURCES["cooperative_follow.yaml"].split("checks:")[0] + "checks: true\n")


@settings(
    max_examples=100,
    deadline=None,
    derandomize=True,
    suppress_health_check=[HealthCheck.too_slow],
)
@given(
    st.sampled_from(sorted(SOURCES)),
    st.lists(
        st.tuples(st.integers(min_value=0), st.sampled_from(list(":{}[]-#&*!|>'\"\t\n ab1"))),
        min_size=1,
        max_size=4,
    ),
)
def test_damaged_text_gives_findings_not_crashes(name: str, edits: list[tuple[int, str]]) -> None:
    text = SOURCES[name]
    for position, char in edits:
        i = position % len(text)
        text = text[:i] + char + text[i + 1 :]
    _validate_text(text)
