"""The station view's protocol basics: the JSON type and its encoding, version, bounds, actions.

Separate from the builders because every module of the view (the hello, the rows, the
commands, the server, the replay) speaks this protocol (docs/station-view.md, "The
protocol"), and a module of its own below them all keeps them from importing each
other in a circle.
"""

from __future__ import annotations

import json
import math
from collections.abc import Mapping
from typing import Any, Final

Json = dict[str, Any]

PROTOCOL_VERSION: Final = 1
"""Version of the messages between the server and the page; ``hello`` carries it."""

ACTIONS: Final = ("activate", "deactivate", "mode", "terminate")
"""What the operator may ask for (the thesis's Clark View, requirements 5.2.3-5.2.5)."""

MAX_LOG_LINES: Final = 500
"""Mission-log lines held for the view; older ones are dropped (the log file keeps all)."""

MAX_LOG_TEXT_CHARS: Final = 500
"""Longest mission-log line shown; longer ones are cut (``...``)."""


def rounded(value: float | None, digits: int = 2) -> float | None:
    """A figure for the page: rounded, and None for None or a non-finite number."""
    if value is None or not math.isfinite(value):
        return None
    return round(value, digits)


def page_json(message: Json) -> str:
    """A message as compact JSON; a NaN or infinity (JSON has none) becomes null."""
    try:
        return json.dumps(message, separators=(",", ":"), allow_nan=False)
    except ValueError:
        return json.dumps(_finite(message), separators=(",", ":"), allow_nan=False)


def _finite(value: Any) -> Any:
    """``value`` with every NaN and infinity, however deep, replaced by None."""
    if isinstance(value, float):
        return value if math.isfinite(value) else None
    if isinstance(value, dict):
        return {k: _finite(v) for k, v in value.items()}
    if isinstance(value, list | tuple):
        return [_finite(v) for v in value]
    return value


def agent_names(hello: Mapping[str, Any], *, vehicles_only: bool = False) -> list[str]:
    """The agents' names in a hello message."""
    return [str(a["name"]) for a in hello["agents"] if not vehicles_only or a.get("role") != "mcs"]


def modes_of(hello: Mapping[str, Any]) -> dict[str, frozenset[str]]:
    """Each agent's settable modes, by name, from a hello message."""
    return {str(a["name"]): frozenset(str(m["name"]) for m in a["modes"]) for a in hello["agents"]}


__all__ = [
    "ACTIONS",
    "MAX_LOG_LINES",
    "MAX_LOG_TEXT_CHARS",
    "PROTOCOL_VERSION",
    "Json",
    "agent_names",
    "modes_of",
    "page_json",
    "rounded",
]
