"""Checks of conditions on another agent: its behaviour state and its relative position.

A transition may wait for another agent (``agent_state``, ``ahead_m``, ``behind_m``,
``above_m``, ``within_m``). What the schema cannot see is checked here, each at the line
of the value to change: the agent exists and is not this one, the state path exists in
that agent's behaviour, and the data the condition decides on actually reaches this agent
(the peer sends it a Behavior State or an Agent Status at a rate). Nothing is added to the
link silently: a missing telemetry line is an error that names the line to add.
"""

from __future__ import annotations

import difflib
from collections.abc import Iterator, Mapping
from typing import Any

from clark_engine.mission.findings import Finding, error
from clark_engine.mission.model import Agent, Mission, Transition

#: The event of transitions taken as soon as their condition holds: the runtime raises it
#: every tick while a state with such a transition is active (an eventless transition, as
#: SCXML and XState call it), so that waiting for another agent needs no polling state.
ALWAYS_EVENT = "always"

#: Conditions on another agent, each with the telemetry message it is decided on.
PEER_CONDITIONS: Mapping[str, str] = {
    "agent_state": "behavior_state",
    "ahead_m": "agent_status",
    "behind_m": "agent_status",
    "above_m": "agent_status",
    "within_m": "agent_status",
}

#: What a suggested telemetry line asks for: twice a second is enough for a condition
#: that a tick or two decides, and cheap on the thesis's XBee links.
SUGGESTED_RATE_HZ = 2


def check_peer_condition(
    mission: Mission,
    agent: Agent,
    key: str,
    value: Mapping[str, Any],
    transition: Transition,
    here: tuple[str | int, ...],
) -> Iterator[Finding]:
    """Findings about one condition on another agent (``key`` in :data:`PEER_CONDITIONS`).

    Args:
        mission: The resolved mission.
        agent: The agent whose transition carries the condition.
        key: The condition's kind.
        value: Its body (``{agent, in}`` or ``{agent, lt, gt, bearing_deg}``).
        transition: The transition, for locations.
        here: Path of the condition inside the transition's ``when``.
    """
    name = str(value.get("agent"))
    where = transition.condition_location((*here, "agent"))
    if name not in mission.agents:
        if name not in mission.unresolved:
            yield error(
                "E-AGENT-UNKNOWN",
                where,
                f"the condition waits for {name!r}, which is not an agent of this mission; "
                + _hint(name, list(mission.agents)),
            )
        return
    if name == agent.name:
        yield error(
            "E-CONDITION-SELF",
            where,
            f"{key} compares {agent.name} with itself; name another agent (for this agent's "
            "own state, use in_state_s or the transition's event)",
        )
        return
    peer = mission.agents[name]
    if key == "agent_state":
        yield from _check_state_path(peer, str(value.get("in")), transition, here)
    else:
        station = next((who for who in (agent, peer) if not who.is_vehicle), None)
        if station is not None:
            yield error(
                "E-CONDITION",
                transition.condition_location(here),
                f"{key} needs the positions of both agents, and {station.name} is a station "
                "with no position; compare two vehicles",
            )
            return
        yield from _check_bounds(key, value, transition, here)
    message = PEER_CONDITIONS[key]
    sent = peer.telemetry.get(message)
    if sent is None or not sent.reaches(agent.name):
        what = "behaviour state" if message == "behavior_state" else "position"
        elsewhere = f" (it sends {message} to {', '.join(sent.to)} only)" if sent else ""
        yield error(
            "E-CONDITION-DATA",
            where,
            f"the condition needs the {what} of {name}, but {name} sends no {message} to "
            f"{agent.name}{elsewhere}; add {message}: {{rate_hz: {SUGGESTED_RATE_HZ}, to: "
            f"[{agent.name}]}} to agents.{name}.telemetry (or add {agent.name} to its to:)",
        )


def check_always(transition: Transition) -> Iterator[Finding]:
    """An ``always`` transition has a condition: without one it would leave at once."""
    if transition.event == ALWAYS_EVENT and transition.condition is None:
        yield error(
            "E-ALWAYS-WHEN",
            transition.location,
            "an always transition is taken on the first tick its condition holds, and this "
            "one has none, so the state would be left at once; write {to: <state>, when: "
            "<condition>}",
        )


def _check_state_path(
    peer: Agent, path: str, transition: Transition, here: tuple[str | int, ...]
) -> Iterator[Finding]:
    """The state path names a state of the peer's resolved behaviour (blocks expanded)."""
    where = transition.condition_location((*here, "in"))
    root = peer.behavior
    if root is None:
        yield error(
            "E-STATE-UNKNOWN",
            where,
            f"{peer.name} has no behaviour, so it is never in state {path!r}; name an agent "
            "with a behavior:",
        )
        return
    if root.find(tuple(path.split("."))) is not None:
        return
    paths = [s.dotted for s in root.walk() if s.path]
    close = difflib.get_close_matches(path, paths, n=1)
    if close:
        hint = f"did you mean {close[0]!r}?"
    elif paths:
        hint = "its states: " + ", ".join(paths[:12]) + (", ..." if len(paths) > 12 else "")
    else:
        hint = f"its behavior: is one use: with no named states; give {peer.name} states:"
    yield error(
        "E-STATE-UNKNOWN",
        where,
        f"the behaviour of {peer.name} has no state {path!r} (a dotted path from the top of "
        f"its behavior:, as its Behavior State reports it); {hint}",
    )


def _check_bounds(
    key: str, value: Mapping[str, Any], transition: Transition, here: tuple[str | int, ...]
) -> Iterator[Finding]:
    """A relative-position condition compares with something, and can hold."""
    where = transition.condition_location(here)
    low, high = value.get("gt"), value.get("lt")
    if low is None and high is None:
        yield error(
            "E-CONDITION",
            where,
            f"{key} compares with nothing; give lt (below) or gt (above), or both",
        )
    elif low is not None and high is not None and low >= high:
        yield error(
            "E-CONDITION",
            where,
            f"{key} above {low:g} and below {high:g} can never hold; make gt smaller than lt",
        )


def _hint(word: str, choices: list[str]) -> str:
    close = difflib.get_close_matches(word, sorted(choices), n=1)
    if close:
        return f"did you mean {close[0]!r}?"
    return "choose one of: " + ", ".join(sorted(choices)) if choices else "there are none"
