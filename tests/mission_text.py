"""Editing an example mission's text for a test, whatever the style of its ``sim:`` mapping.

Tests change a setting or two of an example (its autopilots ready sooner, a world
declared) by text, so that the file keeps its comments and its other lines where they
were. The examples write ``sim:`` either on one line (``sim: {duration_s: 90, seed: 1}``)
or as a block (one key per line, as ``cooperative_follow.yaml`` does to declare its world).
"""

from __future__ import annotations

import re

import yaml


def with_sim_keys(text: str, extra: str) -> str:
    """``text`` with the keys of ``extra`` (a flow mapping's inside: ``"a: 1, b: {c: 2}"``)
    added to its top-level ``sim:`` mapping.

    Raises:
        AssertionError: The text has no top-level ``sim:`` mapping, or ``extra`` is not a
            mapping: the test's own mistake, said plainly.
    """
    keys = yaml.safe_load("{" + extra + "}")
    assert isinstance(keys, dict) and keys, f"not a mapping's keys: {extra!r}"
    one_line, count = re.subn(
        r"^sim: \{(.*)\}$", lambda m: f"sim: {{{m[1]}, {extra}}}", text, flags=re.M
    )
    if count == 1:
        return one_line
    lines = [
        "  " + yaml.safe_dump({key: value}, default_flow_style=True, width=10**6).strip()[1:-1]
        for key, value in keys.items()
    ]
    block, count = re.subn(
        r"^sim:[ \t]*\n", lambda m: m[0] + "\n".join(lines) + "\n", text, count=1, flags=re.M
    )
    assert count == 1, "the mission has a top-level sim: mapping"
    return block
