"""Checks of a transition's condition: the agents, modes and bounds inside it.

Why separate: a condition is a small language of its own (``all``, ``any``, ``not``, an
autopilot mode, bounds on a value, the distance to another agent, the peer conditions of
:mod:`clark_engine.mission.peer_conditions`), checked recursively, each part at its own
line. :mod:`clark_engine.mission.state_checks` calls :func:`check_condition` for every
guarded transition.
"""

from __future__ import annotations

from collections.abc import Iterator, Mapping
from typing import Any

from clark_engine.mission.check_help import hint
from clark_engine.mission.findings import Finding, error
from clark_engine.mission.model import Agent, Mission, Transition
from clark_engine.mission.peer_conditions import PEER_CONDITIONS, check_peer_condition


def check_condition(
    mission: Mission,
    agent: Agent,
    condition: Mapping[str, Any],
    transition: Transition,
    at: tuple[str | int, ...] = (),
) -> Iterator[Finding]:
    """Agents, modes and bounds inside a transition's condition, each at its own line."""
    for key, value in condition.items():
        here = (*at, key)
        if key in ("all", "any"):
            for i, item in enumerate(value):
                yield from check_condition(mission, agent, item, transition, (*here, i))
        elif key == "not":
            yield from check_condition(mission, agent, value, transition, here)
        elif key == "mode":
            mode = str(value.get("is"))
            if not agent.is_vehicle:
                yield error(
                    "E-EVENT-UNKNOWN",
                    transition.condition_location(here),
                    f"{agent.name} is a station and has no autopilot mode to test",
                )
            elif mode not in agent.hardware.modes:
                yield error(
                    "E-MODE-UNKNOWN",
                    transition.condition_location((*here, "is")),
                    f"the autopilot of {agent.name} has no mode {mode!r}; "
                    + hint(mode, agent.hardware.modes),
                )
        elif key in PEER_CONDITIONS:
            yield from check_peer_condition(mission, agent, key, value, transition, here)
        else:
            yield from _check_bounds(key, value, transition, here)
            if key == "distance_m":
                yield from _check_distance_target(mission, agent, value, transition, here)


def _check_bounds(
    key: str, value: Mapping[str, Any], transition: Transition, here: tuple[str | int, ...]
) -> Iterator[Finding]:
    low, high = value.get("gt"), value.get("lt")
    if low is None and high is None:
        yield error(
            "E-CONDITION",
            transition.condition_location(here),
            f"{key} compares with nothing; give lt (below) or gt (above), or both",
        )
    elif low is not None and high is not None and low >= high:
        yield error(
            "E-CONDITION",
            transition.condition_location(here),
            f"{key} above {low:g} and below {high:g} can never hold; make gt smaller than lt",
        )


def _check_distance_target(
    mission: Mission,
    agent: Agent,
    value: Mapping[str, Any],
    transition: Transition,
    here: tuple[str | int, ...],
) -> Iterator[Finding]:
    target = str(value.get("to"))
    where = transition.condition_location((*here, "to"))
    if target not in mission.agents and target not in mission.unresolved:
        yield error(
            "E-AGENT-UNKNOWN",
            where,
            f"the condition measures distance to {target!r}, which is not an agent; "
            + hint(target, mission.agents),
        )
    elif target == agent.name:
        yield error("E-CONDITION", where, "the distance from an agent to itself is always 0")
    elif target in mission.agents:
        status = mission.agents[target].telemetry.get("agent_status")
        if status is None or not status.reaches(agent.name):
            yield error(
                "E-FOLLOW-STATUS",
                where,
                f"the condition needs the position of {target} but it sends no agent_status "
                f"to {agent.name}; add agent_status to agents.{target}.telemetry",
            )
