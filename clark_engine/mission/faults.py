"""Faults a dry run injects: one grammar and one set of rules for both ways to write them.

A mission lists faults under ``faults:`` (``{corrupt: {share: 0.2, from_s: 0, to_s: 60}}``);
``clark dry-run --fault`` takes the same faults as short text (``corrupt:0.2@0-60``).
:func:`parse_fault_text` turns the text into the mission's form, and :func:`fault_problems`
checks either form by the same rules (a window that ends after it starts, a share within
0..1, a link between two different agents), so that no fault reaches the simulator that
``clark validate`` would not have accepted in a mission.
"""

from __future__ import annotations

import difflib
import math
import re
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any, Final

from clark_engine.mission.schema_source.common import NAME_PATTERN, TIME_MAX_S

FAULT_KINDS: Final = ("kill", "link_drop", "station_silent", "autopilot_disconnect", "corrupt")
"""Every kind of fault, as written in a mission and on the command line."""

FAULT_HELP: Final = (
    "kill:AGENT@T, link_drop:A,B@T1-T2, station_silent@T1-T2, "
    "autopilot_disconnect:AGENT@T1-T2, corrupt:SHARE@T1-T2 or corrupt:SHARE (seconds)"
)
"""The text forms, for messages and ``--help``."""

#: Longer text is not a fault (and is not echoed back whole).
MAX_FAULT_TEXT: Final = 200
_NAME: Final = re.compile(NAME_PATTERN)
_SECONDS: Final = re.compile(r"^(?:[0-9]+(?:\.[0-9]*)?|\.[0-9]+)$")
_SHARE: Final = re.compile(r"^[+-]?(?:[0-9]+(?:\.[0-9]*)?|\.[0-9]+)$")


class FaultError(ValueError):
    """A fault's text does not follow the grammar or breaks a rule.

    Attributes:
        message: What is wrong and what to write instead.
        broken_rule: True when the text is a fault that breaks a rule (a reversed
            window), not text outside the grammar.
    """

    def __init__(self, message: str, *, broken_rule: bool = False) -> None:
        super().__init__(message)
        self.message = message
        self.broken_rule = broken_rule


@dataclass(frozen=True, slots=True)
class FaultProblem:
    """One rule a fault breaks.

    Attributes:
        code: The check code (``E-FAULT-WINDOW``, ``E-VALUE``, ``E-FAULT-LINK``).
        message: What is wrong and how to fix it.
    """

    code: str
    message: str


def _number(value: Any) -> float | None:
    if isinstance(value, bool) or not isinstance(value, int | float):
        return None
    try:
        return float(value)
    except OverflowError:  # a whole number past every float: no time, no share
        return math.inf if value > 0 else -math.inf


def fault_problems(fault: Mapping[str, Any]) -> list[FaultProblem]:
    """The rules a fault (in the mission's form) breaks, beyond its schema.

    The schema checks shapes and plain ranges; these are the rules that need two values
    together, or that a schema's ranges let through (a share of ``.nan``). Agent names are
    checked against a mission elsewhere: a fault on its own knows no agents.
    """
    if len(fault) != 1:
        return []
    ((kind, body),) = fault.items()
    if not isinstance(body, Mapping):
        return []
    problems: list[FaultProblem] = []
    for key in ("at_s", "from_s", "to_s"):
        value = _number(body.get(key))
        if value is not None and not (math.isfinite(value) and 0 <= value <= TIME_MAX_S):
            problems.append(
                FaultProblem(
                    "E-FAULT-WINDOW",
                    f"{key} {value:g} is not a time of a run; give seconds from the start "
                    f"(0 to {TIME_MAX_S})",
                )
            )
    start, end = _number(body.get("from_s")), _number(body.get("to_s"))
    if start is not None and end is not None and end <= start and not problems:
        problems.append(
            FaultProblem(
                "E-FAULT-WINDOW",
                f"reversed window: the {kind} fault ends at {end:g} s, not after it starts at "
                f"{start:g} s; make to_s later than from_s",
            )
        )
    share = _number(body.get("share")) if kind == "corrupt" else None
    if share is not None and not 0.0 <= share <= 1.0:  # also false for nan
        problems.append(
            FaultProblem(
                "E-VALUE",
                f"a share of {share:g} is not a share of the packets; give one from 0 to 1 "
                "(0.2 corrupts one packet in five)",
            )
        )
    between = body.get("between")
    if kind == "link_drop" and isinstance(between, list | tuple) and len(between) == 2:
        a, b = between
        if a == b:
            problems.append(
                FaultProblem(
                    "E-FAULT-LINK",
                    f"a link joins two agents, and this one names {a!r} twice; "
                    "name the two agents whose link drops",
                )
            )
    return problems


def _seconds(text: str, what: str) -> float:
    if not _SECONDS.match(text):
        raise FaultError(f"{what} {text!r} is not a time; give seconds, such as 30 or 12.5")
    value = float(text)
    if not math.isfinite(value):
        raise FaultError(f"{what} {text!r} is too large a time")
    return value


def _window(when: str) -> dict[str, float]:
    start, dash, end = when.partition("-")
    if not dash:
        raise FaultError(f"{when!r} is one time; this fault needs a window T1-T2 (seconds)")
    from_s, to_s = _seconds(start, "the start"), _seconds(end, "the end")
    if to_s <= from_s:
        raise FaultError(
            f"reversed window: {when!r} ends at {to_s:g} s, not after it starts at {from_s:g} s; "
            f"write the earlier time first ({to_s:g}-{from_s:g})",
            broken_rule=True,
        )
    return {"from_s": from_s, "to_s": to_s}


def _agent(text: str) -> str:
    if not _NAME.match(text):
        raise FaultError(
            f"{text!r} is not an agent name (lowercase letters, digits and _, "
            "starting with a letter)"
        )
    return text


def parse_fault_text(text: str) -> dict[str, Any]:
    """A fault in the command line's short form, in the mission's form.

    ``kill:slash_a@30`` becomes ``{"kill": {"agent": "slash_a", "at_s": 30.0}}``; the result
    obeys :func:`fault_problems` as well as the grammar.

    Raises:
        FaultError: Not one of the forms of :data:`FAULT_HELP`, or a rule broken (the
            message says which, and what to write).
    """
    text = text.strip()
    if len(text) > MAX_FAULT_TEXT:
        raise FaultError(f"longer than {MAX_FAULT_TEXT} characters; write {FAULT_HELP}")
    head, at, when = text.partition("@")
    kind, colon, arg = head.partition(":")
    if kind not in FAULT_KINDS:
        close = difflib.get_close_matches(kind, FAULT_KINDS, n=1)
        hint = f"did you mean {close[0]}? " if close else ""
        raise FaultError(f"{kind!r} is not a kind of fault; {hint}write {FAULT_HELP}")
    if kind == "station_silent" and colon:
        raise FaultError("station_silent takes no argument; write station_silent@T1-T2")
    if kind != "station_silent" and not arg:
        raise FaultError(f"{kind} needs an argument; write {FAULT_HELP}")
    if not at and kind != "corrupt":
        raise FaultError(f"{kind} needs a time after @; write {FAULT_HELP}")
    fault: dict[str, Any]
    if kind == "kill":
        if "-" in when:
            raise FaultError(f"kill happens at one time, not over {when!r}; write kill:AGENT@T")
        fault = {"kill": {"agent": _agent(arg), "at_s": _seconds(when, "the time")}}
    elif kind == "link_drop":
        names = arg.split(",")
        if len(names) != 2:
            raise FaultError(f"a link joins two agents: write link_drop:A,B@T1-T2, not {arg!r}")
        fault = {"link_drop": {"between": [_agent(n) for n in names], **_window(when)}}
    elif kind == "station_silent":
        fault = {"station_silent": _window(when)}
    elif kind == "autopilot_disconnect":
        fault = {"autopilot_disconnect": {"agent": _agent(arg), **_window(when)}}
    else:
        if not _SHARE.match(arg):
            raise FaultError(f"{arg!r} is not a share; give one from 0 to 1, such as 0.2")
        fault = {"corrupt": {"share": float(arg), **(_window(when) if at else {})}}
    problems = fault_problems(fault)
    if problems:
        raise FaultError(problems[0].message, broken_rule=True)
    return fault
