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
    set in its top-level ``sim:`` mapping (added; in a block, a key already there replaced).

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
    found = re.search(r"^sim:[ \t]*\n((?:[ \t]+.*\n)*)", text, flags=re.M)
    assert found is not None, "the mission has a top-level sim: mapping"
    # A block's key that ``extra`` sets again is replaced (a duplicate key is an error).
    kept = [
        line
        for line in found[1].splitlines()
        if not any(re.match(rf"  {re.escape(str(key))}:", line) for key in keys)
    ]
    lines = [
        "  " + yaml.safe_dump({key: value}, default_flow_style=True, width=10**6).strip()[1:-1]
        for key, value in keys.items()
    ]
    return text[: found.start()] + "sim:\n" + "\n".join(lines + kept) + "\n" + text[found.end() :]
