"""What the checks before flight share: a *did you mean*, and where an agent's key was written.

Why separate: every module of checks (:mod:`clark_engine.mission.cross_checks` and those it
runs) words its suggestions and places its findings the same way; this keeps that in one
place without the checks importing each other.
"""

from __future__ import annotations

import difflib
from collections.abc import Iterable

from clark_engine.mission.findings import Location
from clark_engine.mission.model import Agent


def hint(word: str, choices: Iterable[str]) -> str:
    """``did you mean ...?`` for the choice closest to ``word``, else the choices."""
    options = sorted(choices)
    close = difflib.get_close_matches(word, options, n=1)
    if close:
        return f"did you mean {close[0]!r}?"
    return "choose one of: " + ", ".join(options) if options else "there are none"


def raw_loc(agent: Agent, key: str) -> Location:
    """Where ``key`` of the agent's entry was written; the agent's own place without it."""
    return agent.locations.get(key, agent.location)
