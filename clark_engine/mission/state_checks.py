"""Checks of each behaviour's states and transitions: events, timeouts, done, reachability.

Why separate: they walk one agent's resolved state tree: every transition's event is one
the engine knows (:data:`SIMPLE_EVENTS`, ``mode:``, ``rc:``, ``lost:``, ``found:``) and can
happen for this agent; a timeout has its transition and its ``timeout_s``; a ``done`` can
be raised; every state can be entered; no transition crosses between regions of a parallel
state. A transition's condition is :mod:`clark_engine.mission.condition_checks`'s.
:func:`clark_engine.mission.cross_checks.run_all` runs them.
"""

from __future__ import annotations

import re
from collections.abc import Iterator

from clark_engine.behaviors import behaviors
from clark_engine.mission.check_help import hint
from clark_engine.mission.condition_checks import check_condition
from clark_engine.mission.findings import Finding, Location, error, warning
from clark_engine.mission.model import Agent, Mission, State, Transition
from clark_engine.mission.peer_conditions import ALWAYS_EVENT, check_always

SIMPLE_EVENTS = frozenset(
    {
        "done",
        "timeout",
        "activate",
        "deactivate",
        "terminate",
        "mcs_lost",
        "autopilot_lost",
        ALWAYS_EVENT,
    }
)
STATION_EVENTS = frozenset({"activate", "deactivate", "mcs_lost"})
_RC_EVENT = re.compile(r"^rc:([A-Za-z0-9_]+):(high|low)$")


def check_states(mission: Mission, agent: Agent, root: State) -> Iterator[Finding]:
    """Events are known, timeouts have targets, done can happen, states are reachable."""
    targeted = {t.target for s in root.walk() for t in s.transitions if t.target}
    for state in root.walk():
        events = {t.event for t in state.transitions}
        for transition in state.transitions:
            yield from _check_event(mission, agent, state, transition.event, transition.location)
            yield from check_always(transition)
            if transition.condition is not None:
                yield from check_condition(mission, agent, transition.condition, transition)
            yield from _check_region_crossing(root, state, transition)
        if state.timeout_s is not None and "timeout" not in events:
            yield error(
                "E-TIMEOUT-TARGET",
                state.timeout_location or state.location,
                f"state {state.dotted} times out after {state.timeout_s:g} s but has no "
                "timeout transition; add transitions: {timeout: <state>}",
            )
        if "timeout" in events and state.timeout_s is None:
            loc = next(t.location for t in state.transitions if t.event == "timeout")
            yield error(
                "E-TIMEOUT-MISSING",
                loc,
                f"state {state.dotted} moves on timeout but has no timeout_s; add timeout_s",
            )
        if "done" in events and not _can_finish(state):
            loc = next(t.location for t in state.transitions if t.event == "done")
            yield warning(
                "W-DONE-NEVER",
                loc,
                f"state {state.dotted} never finishes ({_why_never(state)}), so its done "
                "transition is never taken; use another event or a primitive that finishes",
            )
        if state.children and not state.parallel and state.initial is not None:
            for child in state.children.values():
                if child.name == state.initial:
                    continue
                if not any(t[: len(child.path)] == child.path for t in targeted):
                    yield warning(
                        "W-STATE-UNREACHABLE",
                        child.location,
                        f"state {child.dotted} is never entered: it is not initial and no "
                        "transition leads to it; add a transition or remove it",
                    )


def _check_region_crossing(root: State, state: State, transition: Transition) -> Iterator[Finding]:
    """A transition may not jump from one region of a parallel state into a sibling region."""
    if not transition.target:
        return
    for depth in range(len(state.path)):
        parent = root.find(state.path[:depth])
        if parent is None or not parent.parallel:
            continue
        source_region = state.path[depth]
        target_prefix = transition.target[:depth]
        if (
            target_prefix == state.path[:depth]
            and len(transition.target) > depth
            and transition.target[depth] != source_region
        ):
            yield error(
                "E-STATE-PARALLEL",
                transition.location,
                f"{'.'.join(state.path[: depth + 1])} and "
                f"{'.'.join(transition.target[: depth + 1])} are regions of the parallel state "
                f"{parent.dotted}, which run together; a transition cannot move between "
                "regions, so target a state outside the parallel state",
            )


def _can_finish(state: State) -> bool:
    if state.unresolved:
        return True  # unknown after an error reported elsewhere: no guess either way
    if state.primitive is not None:
        return "done" in behaviors()[state.primitive].events(state.params)
    if state.parallel:
        finishing = [_can_finish(c) or c.final for c in state.children.values()]
        return any(finishing) if state.finish == "any" else all(finishing)
    return any(c.final for c in state.children.values())


def _why_never(state: State) -> str:
    if state.primitive is not None:
        return f"{state.primitive} with these parameters raises no done"
    if state.parallel:
        if state.finish == "any":
            return "none of its regions finishes"
        return "one of its regions never finishes; finish: any ends it with the first region"
    return "none of its states is final"


def _check_event(
    mission: Mission, agent: Agent, state: State, event: str, where: Location
) -> Iterator[Finding]:
    if event == "terminate":
        yield warning(
            "W-TERMINATE-EVENT",
            where,
            "a station's Terminate ends the agent at once (thesis 7.3.5: terminal mode, "
            "interfaces closed), so this transition is never taken; remove it",
        )
        return
    if event in SIMPLE_EVENTS:
        if event in STATION_EVENTS and not mission.stations:
            yield error(
                "E-NO-STATION",
                where,
                f"{event} comes from a mission control station, and this mission has none; "
                "add an agent with role mcs",
            )
        if event == "autopilot_lost" and not agent.is_vehicle:
            yield error("E-EVENT-UNKNOWN", where, "a station has no autopilot to lose")
        return
    head, _, rest = event.partition(":")
    if head == "mode" and rest:
        modes = agent.hardware.modes
        if not agent.is_vehicle:
            yield error(
                "E-EVENT-UNKNOWN",
                where,
                f"{agent.name} is a station and has no autopilot; mode events are for vehicles",
            )
        elif rest not in modes:
            yield error(
                "E-MODE-UNKNOWN",
                where,
                f"the autopilot of {agent.name} has no mode {rest!r}; {hint(rest, modes)}",
            )
        return
    if head == "rc":
        match = _RC_EVENT.match(event)
        if match is None:
            yield error(
                "E-EVENT-UNKNOWN",
                where,
                f"{event!r} is not an RC event; write rc:<channel>:high or rc:<channel>:low",
            )
            return
        yield from _check_rc_channel(agent, match.group(1), where)
        return
    if head in ("lost", "found") and rest:
        if rest not in mission.agents and rest not in mission.unresolved:
            yield error(
                "E-AGENT-UNKNOWN",
                where,
                f"{event!r} names no agent of this mission; {hint(rest, mission.agents)}",
            )
        elif rest == agent.name:
            yield error("E-EVENT-UNKNOWN", where, f"{agent.name!r} cannot lose itself; name a peer")
        return
    known = [
        *sorted(SIMPLE_EVENTS),
        "mode:<MODE>",
        "rc:<channel>:high|low",
        "lost:<agent>",
        "found:<agent>",
    ]
    yield error(
        "E-EVENT-UNKNOWN",
        where,
        f"{event!r} is not an event; {hint(event, SIMPLE_EVENTS)} (events: {', '.join(known)})",
    )


def _check_rc_channel(agent: Agent, channel: str, where: Location) -> Iterator[Finding]:
    if not agent.is_vehicle:
        yield error(
            "E-EVENT-UNKNOWN", where, "a station has no RC receiver; rc events are for vehicles"
        )
        return
    autopilot = agent.hardware.part("autopilot") or {}
    count = int(autopilot.get("rc_channel_count", 16))
    if channel.isdigit():
        if not 1 <= int(channel) <= count:
            yield error(
                "E-CHANNEL-UNKNOWN",
                where,
                f"RC channel {channel} does not exist; the autopilot has channels 1..{count}",
            )
        return
    named = agent.hardware.channels.get(channel)
    if named is None or named.rc is None:
        with_rc = [n for n, c in agent.hardware.channels.items() if c.rc is not None]
        yield error(
            "E-CHANNEL-UNKNOWN",
            where,
            f"{agent.name!r} has no RC channel named {channel!r}; {hint(channel, with_rc)} "
            "or give the channel number",
        )
