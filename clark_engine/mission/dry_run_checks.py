"""Checks of what a mission says about its dry run: the operator, faults, variations, checks.

Why separate: these read the mission's ``operator:``, ``faults:``, ``sim:`` variations and
``checks:`` (the dry run's expectations), not an agent's flight: each names agents, modes,
channels and states that exist, in an order and a time the dry run can play, and a check
is one some run could pass. :func:`clark_engine.mission.cross_checks.run_all` runs them.
"""

from __future__ import annotations

from collections.abc import Iterator, Mapping
from typing import Any

from clark_engine.behaviors import behaviors
from clark_engine.mission.check_help import hint
from clark_engine.mission.faults import fault_problems
from clark_engine.mission.findings import Finding, Location, error, warning
from clark_engine.mission.model import Agent, Mission
from clark_engine.mission.variation import sim_schema as mission_varied_fields_schema
from clark_engine.mission.variation import variation_problems


def _named_agent(mission: Mission, name: str, where: Location) -> Iterator[Finding]:
    if name != "all" and name not in mission.agents and name not in mission.unresolved:
        yield error(
            "E-AGENT-UNKNOWN",
            where,
            f"there is no agent {name!r} in this mission; {hint(name, mission.agents)}",
        )


def _listens_to(agent: Agent, event: str) -> bool:
    """Whether any state of the agent's behaviour has a transition on ``event``."""
    if agent.behavior is None:
        return False
    return any(t.event == event for state in agent.behavior.walk() for t in state.transitions)


def check_operator(mission: Mission) -> Iterator[Finding]:
    """The operator's actions are sound.

    They name agents, modes and channels that exist, in time order, within the dry run,
    and reach a behaviour that acts on them.
    """
    last = -1.0
    duration_s = mission.sim_duration_s
    for item, where in zip(mission.operator, mission.operator_locations, strict=True):
        at = float(item["at_s"])
        if at >= duration_s:
            yield warning(
                "W-OPERATOR-AFTER-END",
                where,
                f"this action at {at:g} s comes at or after the dry run's end (sim.duration_s "
                f"{duration_s:g} s), so the dry run never plays it; move it earlier or raise "
                "sim.duration_s",
            )
        for event in ("activate", "deactivate"):
            target = mission.agents.get(str(item.get(event, "")))
            if (
                target is not None
                and target.behavior is not None
                and not _listens_to(target, event)
            ):
                yield warning(
                    "W-EVENT-IGNORED",
                    where,
                    f"no state of {target.name}'s behaviour has a transition on {event}, "
                    f"so the {event} sent at {at:g} s arrives and is ignored (its log "
                    f"says so); add `{event}: <state>` to the transitions of the state "
                    "it should leave, or remove the action",
                )
        if at < last:
            yield warning(
                "W-OPERATOR-ORDER",
                where,
                f"this action at {at:g} s is listed after one at {last:g} s; the dry run "
                "acts in time order, so list them in that order to read the mission right",
            )
        last = max(last, at)
        station_actions = [k for k in ("activate", "deactivate", "mode", "terminate") if k in item]
        if station_actions and not mission.stations:
            yield error(
                "E-NO-STATION",
                where,
                f"{station_actions[0]} is sent by a mission control station, and this mission "
                "has none; add an agent with role mcs",
            )
        for key in ("activate", "deactivate", "terminate"):
            if key in item:
                yield from _named_agent(mission, str(item[key]), where)
        if "mode" in item:
            name, mode = str(item["mode"]["agent"]), str(item["mode"]["mode"])
            yield from _named_agent(mission, name, where)
            agent = mission.agents.get(name)
            if agent is not None and mode not in agent.hardware.modes:
                yield error(
                    "E-MODE-UNKNOWN",
                    where,
                    f"the autopilot of {name} has no mode {mode!r}; "
                    + hint(mode, agent.hardware.modes),
                )
        if "rc" in item:
            name = str(item["rc"]["agent"])
            yield from _named_agent(mission, name, where)
            agent = mission.agents.get(name)
            if agent is not None and not agent.is_vehicle:
                yield error("E-ROLE", where, f"{name} is a station: it has no RC receiver")


def check_faults(mission: Mission) -> Iterator[Finding]:
    """Faults name agents that exist, and keep the rules every fault keeps.

    The rules (a window that ends after it starts, a share within 0..1, a link between two
    different agents) are :func:`clark_engine.mission.faults.fault_problems`, the same that
    ``clark dry-run --fault`` applies.
    """
    for item, where in zip(mission.faults, mission.fault_locations, strict=True):
        ((kind, body),) = item.items()
        names = [str(n) for n in body.get("between", [])]
        if "agent" in body:
            names.append(str(body["agent"]))
        for name in dict.fromkeys(names):
            yield from _named_agent(mission, name, where)
        for problem in fault_problems(item):
            yield error(problem.code, where, problem.message)
        if kind == "station_silent" and not mission.stations:
            yield error("E-NO-STATION", where, "there is no station to silence; remove the fault")


def check_variations(mission: Mission) -> Iterator[Finding]:
    """Varied values keep the rules their schema cannot state.

    A uniform written high to low, a fault window a draw could reverse:
    :func:`~clark_engine.mission.variation.variation_problems`.
    """
    for path, code, message in variation_problems(
        mission_varied_fields_schema(), mission.sim, mission.faults
    ):
        parts = path.split(".")
        if parts[0] == "faults":
            where = mission.fault_locations[int(parts[1])]
        else:
            where = mission.sim_locations[parts[1]]
        yield error(code, where, message)


def _checked_state_paths(kind: str, body: Any) -> list[str]:
    """The state paths a check of ``kind`` names (none for kinds that name no state)."""
    if not isinstance(body, Mapping):
        return []
    if kind == "sequence":
        states = body.get("states")
        return [p for p in states if isinstance(p, str)] if isinstance(states, list) else []
    path = body.get("reached") if kind == "state" else body.get("state")
    return [path] if kind in ("state", "signal") and isinstance(path, str) else []


def _check_possible(
    mission: Mission, kind: str, check: Mapping[str, Any], body: Any, where: Location
) -> Iterator[Finding]:
    """A check that no dry run of this mission can pass is an error now, not a FAIL later."""
    duration = mission.sim_duration_s
    by_s = check.get("by_s")
    if isinstance(by_s, int | float) and by_s > duration:
        yield error(
            "E-CHECK-IMPOSSIBLE",
            where,
            f"by_s {by_s:g} s is after the dry run ends (sim.duration_s {duration:g} s), so "
            "the check can never be judged; lower by_s or raise sim.duration_s",
        )
    if not isinstance(body, Mapping):
        return
    low, high = body.get("min"), body.get("max")
    if isinstance(low, int | float) and isinstance(high, int | float) and low > high:
        yield error(
            "E-CHECK-IMPOSSIBLE",
            where,
            f"min {low:g} is above max {high:g}, so no run can pass this {kind} check; "
            "swap them or correct one",
        )
    if kind == "altitude_m" and low is None and high is None:
        yield error(
            "E-CHECK-SHAPE",
            where,
            "an altitude_m check bounds the altitude: give min, max or both (metres above "
            "the origin)",
        )
    agent = mission.agents.get(str(body.get("agent")))
    if agent is None:
        return
    if kind in ("altitude_m", "ends_at", "reached") and not agent.is_vehicle:
        yield error(
            "E-CHECK-IMPOSSIBLE",
            where,
            f"{agent.name} is a station: the dry run records no track of it, so this {kind} "
            "check always fails; check a vehicle",
        )
    if kind == "failsafe" and not agent.is_vehicle:
        yield error(
            "E-CHECK-IMPOSSIBLE",
            where,
            f"{agent.name} is a station: it has no failsafe and no autopilot to lose, so this "
            "check always fails; check a vehicle",
        )
    if kind == "photos" and isinstance(low, int | float) and low > 0:
        cameras = [
            n for n, p in agent.hardware.payloads.items() if p.get("payload_kind") == "camera"
        ]
        if not cameras:
            yield error(
                "E-CHECK-IMPOSSIBLE",
                where,
                f"{agent.name} has no camera, so it takes no pictures and this check always "
                f"fails; add a camera under agents.{agent.name}.hardware.payloads or check "
                "another agent",
            )
        elif agent.behavior is not None and not any(
            s.traits.takes_pictures or s.unresolved for s in agent.behavior.walk()
        ):
            yield error(
                "E-CHECK-IMPOSSIBLE",
                where,
                f"{agent.name} never runs photo_trigger, so it takes no pictures and this "
                "check always fails; add a photo_trigger state or check another agent",
            )


def check_expectations(mission: Mission) -> Iterator[Finding]:
    """Dry-run expectations name agents and states that exist."""
    signals = [name for name, b in behaviors().items() if b.signal is not None]
    for index, check in enumerate(mission.checks):
        where = mission.check_locations[index]
        kinds = [k for k in check if k not in ("name", "by_s")]
        if len(kinds) != 1:
            yield error(
                "E-CHECK-SHAPE",
                where,
                "each check states exactly one expectation (distance_m, reached, separation_m, "
                "altitude_m, ends_at, state, sequence, photos, no_failsafe, failsafe or "
                f"signal); this one has "
                f"{len(kinds) or 'none'}",
            )
            continue
        body = check[kinds[0]]
        yield from _check_possible(mission, kinds[0], check, body, where)
        names: list[str] = []
        if isinstance(body, Mapping):
            names.extend(str(n) for n in body.get("between", []))
            names.extend(str(n) for n in body.get("agents", []))
            if "agent" in body:
                names.append(str(body["agent"]))
        if kinds[0] == "distance_m" and len(set(names)) < len(names):
            yield error(
                "E-CHECK-SHAPE",
                where,
                "a distance check measures between two different agents; name two",
            )
        for name in names:
            if name not in mission.agents and name not in mission.unresolved:
                yield error(
                    "E-AGENT-UNKNOWN",
                    where,
                    f"the check names {name!r}, which is not an agent; "
                    + hint(name, mission.agents),
                )
        paths = _checked_state_paths(kinds[0], body)
        agent = mission.agents.get(str(body.get("agent"))) if paths else None
        if agent is None:
            continue
        if agent.behavior is None:
            if "behavior" in agent.raw:
                continue  # written, but too broken to resolve: its errors say why
            yield error(
                "E-STATE-UNKNOWN",
                where,
                f"{agent.name} has no behaviour, so it never reaches {paths[0]!r}; "
                "give it a behavior or check another agent",
            )
            continue
        for state_path in paths:
            state = agent.behavior.find(tuple(state_path.split(".")))
            if state is None:
                yield error(
                    "E-STATE-UNKNOWN",
                    where,
                    f"{agent.name!r} has no state {state_path!r}; "
                    + hint(state_path, [s.dotted for s in agent.behavior.walk()[1:]]),
                )
            elif kinds[0] == "signal" and not state.unresolved and state.primitive not in signals:
                yield error(
                    "E-CHECK-SHAPE",
                    where,
                    f"state {state_path!r} runs {state.primitive or 'no primitive'}; a signal "
                    f"check needs a {' or '.join(signals)} state",
                )
