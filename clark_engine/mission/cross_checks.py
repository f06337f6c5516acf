"""Checks before flight: what the schema cannot see.

Every check takes the resolved :class:`Mission` and yields findings; none stops
at the first problem. Checks that belong to one primitive (a doublet's width,
a sweep's Nyquist limit, a photo trigger's camera) live beside that primitive;
this module runs them and checks everything that spans agents and states:
ids and addresses, rates, events and transitions, conditions, dry-run
expectations.
"""

from __future__ import annotations

import difflib
import re
from collections.abc import Iterable, Iterator, Mapping
from typing import Any

from clark_engine.behaviors import UseContext, behaviors
from clark_engine.behaviors.shared import off_the_globe
from clark_engine.mission import envelope_checks
from clark_engine.mission.faults import fault_problems
from clark_engine.mission.findings import Finding, Location, error, rehome, warning
from clark_engine.mission.flow import entry_leaves
from clark_engine.mission.model import Agent, Mission, State, Transition
from clark_engine.mission.peer_conditions import (
    ALWAYS_EVENT,
    PEER_CONDITIONS,
    check_always,
    check_peer_condition,
)
from clark_engine.mission.variation import sim_schema as mission_varied_fields_schema
from clark_engine.mission.variation import variation_problems

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
#: A rate whose loop divider is off by more than this is reported.
RATE_DIVIDER_TOLERANCE = 0.01
#: The lowest telemetry rate: once a day. Below it a message is in effect never sent, and
#: its loop divider (loop_hz / rate) outgrows every integer a float can hold.
MIN_RATE_HZ = 1.0 / 86400.0


def _hint(word: str, choices: Iterable[str]) -> str:
    options = sorted(choices)
    close = difflib.get_close_matches(word, options, n=1)
    if close:
        return f"did you mean {close[0]!r}?"
    return "choose one of: " + ", ".join(options) if options else "there are none"


def run_all(mission: Mission, bad_states: set[tuple[str, tuple[str, ...]]]) -> list[Finding]:
    """Run every check on ``mission``.

    Args:
        mission: The resolved mission.
        bad_states: (agent, state path) pairs whose parameters failed their schema;
            their primitive checks are skipped (they would only repeat the error).
    """
    findings: list[Finding] = []
    findings.extend(check_ids(mission))
    findings.extend(check_addresses(mission))
    findings.extend(check_loop_rate(mission))
    for agent in mission.agents.values():
        problem = off_the_globe(agent.position, mission.origin)
        if problem:
            findings.append(
                error("E-POSITION", _raw_loc(agent, "position"), f"the agent {problem}")
            )
        findings.extend(check_telemetry(mission, agent))
        findings.extend(check_agent_modes(mission, agent))
        findings.extend(check_launch(agent))
        if agent.behavior is not None:
            findings.extend(check_states(mission, agent, agent.behavior))
            findings.extend(check_primitives(mission, agent, agent.behavior, bad_states))
            findings.extend(check_takeoff(agent, agent.behavior))
            findings.extend(check_launch_flight(agent, agent.behavior))
    findings.extend(envelope_checks.check_mission(mission))
    findings.extend(check_expectations(mission))
    findings.extend(check_operator(mission))
    findings.extend(check_faults(mission))
    findings.extend(check_variations(mission))
    return findings


def _named_agent(mission: Mission, name: str, where: Location) -> Iterator[Finding]:
    if name != "all" and name not in mission.agents and name not in mission.unresolved:
        yield error(
            "E-AGENT-UNKNOWN",
            where,
            f"there is no agent {name!r} in this mission; {_hint(name, mission.agents)}",
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
                    + _hint(mode, agent.hardware.modes),
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


def check_ids(mission: Mission) -> Iterator[Finding]:
    """Agent ids are unique (ClarkLink routes by id)."""
    seen: dict[int, Agent] = {}
    for agent in mission.agents.values():
        first = seen.get(agent.id)
        if first is not None:
            yield error(
                "E-ID-DUPLICATE",
                _raw_loc(agent, "id"),
                f"agents {first.name!r} and {agent.name!r} both have id {agent.id}; give each "
                "agent its own id",
                _raw_loc(first, "id"),
            )
        else:
            seen[agent.id] = agent


def _raw_loc(agent: Agent, key: str) -> Location:
    return agent.locations.get(key, agent.location)


def check_addresses(mission: Mission) -> Iterator[Finding]:
    """Radio addresses are unique and match the radio's address format."""
    seen: dict[str, Agent] = {}
    for agent in mission.agents.values():
        address = agent.radio_address
        if address is None:
            continue
        radio = agent.hardware.part("radio") or {}
        pattern = radio.get("address_pattern")
        where = _raw_loc(agent, "radio_address")
        if pattern and not re.fullmatch(pattern, address):
            yield error(
                "E-ADDRESS-FORMAT",
                where,
                f"{address!r} is not an address for the "
                f"{agent.hardware.part_profiles.get('radio')} radio (expected to match "
                f"{pattern}); copy it from the radio's label",
            )
        first = seen.get(address.upper())
        if first is not None:
            yield error(
                "E-ADDRESS-DUPLICATE",
                where,
                f"agents {first.name!r} and {agent.name!r} have the same radio address "
                f"{address!r}; each radio has its own address",
                _raw_loc(first, "radio_address"),
            )
        else:
            seen[address.upper()] = agent


def check_loop_rate(mission: Mission) -> Iterator[Finding]:
    """loop_hz is within what each agent's mission computer was measured to hold."""
    for agent in mission.agents.values():
        limit = agent.hardware.max_loop_hz
        if limit is not None and mission.loop_hz > limit:
            yield error(
                "E-LOOP-HZ",
                _mission_loc(mission, "loop_hz"),
                f"loop_hz {mission.loop_hz:g} is above the {limit:g} Hz that the mission "
                f"computer of {agent.name} ({agent.hardware.part_profiles.get('computer')}) was "
                "measured to hold; lower loop_hz or give it a faster computer",
                agent.location,
            )


def _mission_loc(mission: Mission, key: str) -> Location:
    return mission.locations.get(key, Location(mission.file, 1, 1, ("mission", key)))


def check_telemetry(mission: Mission, agent: Agent) -> Iterator[Finding]:
    """Rates fit the loop, destinations exist, heartbeats come often enough."""
    for item in agent.telemetry.values():
        if item.rate_hz > mission.loop_hz:
            yield error(
                "E-RATE",
                item.location,
                f"{item.rate_hz:g} Hz is above loop_hz {mission.loop_hz:g}; the loop can send "
                "at most once per tick, so lower the rate or raise mission.loop_hz",
            )
        elif item.rate_hz < MIN_RATE_HZ:
            yield error(
                "E-RATE",
                item.location,
                f"{item.rate_hz:g} Hz is less than once a day ({MIN_RATE_HZ:.3g} Hz), so the "
                f"message is in effect never sent; send it at least once a day or remove it",
            )
        else:
            ticks = mission.loop_hz / item.rate_hz
            actual = mission.loop_hz / max(1, round(ticks))
            if abs(actual - item.rate_hz) > RATE_DIVIDER_TOLERANCE * item.rate_hz:
                yield warning(
                    "W-RATE-DIVIDER",
                    item.location,
                    f"{item.rate_hz:g} Hz is not a whole divider of loop_hz {mission.loop_hz:g}; "
                    f"it will be sent every {round(ticks)} ticks ({actual:.3g} Hz); pick a rate "
                    "that divides loop_hz",
                )
        if agent.name in item.to:
            yield error(
                "E-TELEMETRY-SELF",
                item.location,
                f"{agent.name} sends {item.message} to itself; list only other agents in to:",
            )
        for name in item.to:
            if name not in mission.agents and name not in mission.unresolved:
                yield error(
                    "E-AGENT-UNKNOWN",
                    item.location,
                    f"{item.message} goes to {name!r}, which is not an agent of this mission; "
                    + _hint(name, mission.agents),
                )
    heartbeat = agent.telemetry.get("heartbeat")
    written = agent.raw.get("telemetry")
    if heartbeat is None:
        if not (isinstance(written, Mapping) and "heartbeat" in written):
            yield warning(
                "W-NO-HEARTBEAT",
                _raw_loc(agent, "telemetry"),
                f"{agent.name} sends no heartbeat, so no peer will ever add it to its fleet "
                "table; add heartbeat: 1 to its telemetry",
            )
    elif 1.0 / heartbeat.rate_hz >= mission.heartbeat_timeout_s:
        yield error(
            "E-HEARTBEAT-RATE",
            heartbeat.location,
            f"a heartbeat every {1.0 / heartbeat.rate_hz:g} s is not within heartbeat_timeout_s "
            f"{mission.heartbeat_timeout_s:g} s, so peers will count {agent.name!r} lost between "
            "heartbeats; send heartbeats faster or raise mission.heartbeat_timeout_s",
        )


def check_agent_modes(mission: Mission, agent: Agent) -> Iterator[Finding]:
    """Terminal mode and failsafes name modes the autopilot has."""
    if not agent.is_vehicle:
        return
    modes = agent.hardware.modes
    autopilot = agent.hardware.part("autopilot") or {}
    if agent.terminal_mode is not None and agent.terminal_mode not in modes:
        yield error(
            "E-MODE-UNKNOWN",
            _raw_loc(agent, "terminal_mode"),
            f"the autopilot of {agent.name} ({agent.profile}) has no mode "
            f"{agent.terminal_mode!r}; " + _hint(agent.terminal_mode, modes),
        )
    action = agent.failsafe.get("mcs_lost", "hold")
    needed = {"rtl": autopilot.get("rtl_mode"), "land": autopilot.get("land_mode")}
    if action in needed and needed[action] is None:
        yield error(
            "E-FAILSAFE",
            _raw_loc(agent, "failsafe"),
            f"failsafe {action} needs a {action.upper()} mode, which the autopilot of "
            f"{agent.name} does not have; choose hold or rtl",
        )
    declared = agent.raw.get("failsafe")
    if isinstance(declared, Mapping) and "mcs_lost" in declared and not mission.stations:
        yield warning(
            "W-NO-STATION",
            _raw_loc(agent, "failsafe"),
            "failsafe.mcs_lost can never trigger: the mission has no station (role mcs); "
            "add one or remove it",
        )


def check_launch(agent: Agent) -> Iterator[Finding]:
    """``launch`` fits the agent, and the start position's height agrees with it.

    A station has nothing to launch; only an aircraft can be handed over in flight,
    and only by the pilot who armed it; a vehicle on the ground starts at no height,
    and one handed over in flight starts at the height the pilot hands it over at
    (the dry run starts it there, flying).
    """
    if not agent.is_vehicle:
        if "launch" in agent.raw:
            yield error(
                "E-LAUNCH-STATION",
                _raw_loc(agent, "launch"),
                f"{agent.name} is a station (role mcs) and has no vehicle to arm or fly; "
                "remove launch",
            )
        return
    launch = agent.launch
    if launch is None:
        return
    rover = agent.airframe_class == "rover"
    position = agent.position
    if launch.airborne and rover:
        yield error(
            "E-LAUNCH-AIRBORNE",
            launch.locate("airborne"),
            f"{agent.name} ({agent.profile}) is a rover and never flies; remove launch.airborne",
        )
        return
    if launch.airborne and launch.engine_arms:
        yield error(
            "E-LAUNCH-AIRBORNE",
            launch.locate("airborne"),
            f"airborne: true says the pilot arms {agent.name} and takes off before its "
            "behaviour starts, so the engine never arms it; write armed_by: pilot, or leave "
            "airborne out and take off in a takeoff state",
            launch.locate("armed_by"),
        )
    if launch.airborne and position.up_m <= 0:
        yield error(
            "E-LAUNCH-HEIGHT",
            _raw_loc(agent, "position") if "position" in agent.raw else launch.locate("airborne"),
            f"{agent.name} starts airborne, but its position has no height above the origin; "
            "say at what height the pilot hands it over: position: "
            f"[{position.north_m:.0f}, {position.east_m:.0f}, <up_m>]",
            launch.locate("airborne"),
        )
    if not launch.airborne and position.up_m > 0:
        fix = (
            "remove up_m"
            if rover
            else "remove up_m, or declare launch: {airborne: true} if the pilot takes off "
            "before the behaviour starts"
        )
        yield error(
            "E-LAUNCH-HEIGHT",
            _raw_loc(agent, "position"),
            f"{agent.name} starts on the ground{' (a rover)' if rover else ''}, but its position "
            f"is {position.up_m:g} m above the origin; {fix}",
            *([launch.location] if "launch" in agent.raw else []),
        )


#: Why an aircraft on the ground goes nowhere for a guided target, by airframe class.
_GROUNDED = {
    "multirotor": "ArduCopter ignores guided targets until it has taken off",
    "fixed_wing": "ArduPlane does not take off to reach a guided target",
}


def check_takeoff(agent: Agent, root: State) -> Iterator[Finding]:
    """An aircraft that starts on the ground takes off before it flies to guided targets."""
    launch = agent.launch
    grounded = _GROUNDED.get(agent.airframe_class or "")
    if launch is None or launch.airborne or grounded is None:
        return
    states = root.walk()
    if any(state.traits.takes_off for state in states):
        return
    guided = next((s for s in states if s.traits.guided), None)
    if guided is None:
        return
    what = f"state {guided.dotted} ({guided.primitive})" if guided.path else guided.primitive
    yield warning(
        "W-TAKEOFF-MISSING",
        guided.mission_use or guided.use_location or guided.location,
        f"{agent.name} ({agent.profile}) starts on the ground and its {what} flies to a "
        f"guided target, but no state takes off, and {grounded}; add a takeoff state before "
        "the first guided one, or declare launch: {airborne: true} if the pilot takes off",
    )


#: How long ArduCopter stays armed on the ground without taking off (DISARM_DELAY's default).
DISARM_DELAY_S = 10


def check_launch_flight(agent: Agent, root: State) -> Iterator[Finding]:
    """A ground-start multirotor armed by its pilot takes off in its first state.

    ArduCopter disarms a copter that was armed on the ground and has not taken off
    after DISARM_DELAY (10 s). The safety pilot arms it once it is ready, whatever the
    behaviour is doing; a first state that waits (for an activation, a timer, a
    transition) before its takeoff leaves the copter disarmed by the time the takeoff
    comes, and the takeoff then fails. A behaviour without any takeoff is
    W-TAKEOFF-MISSING's.
    """
    launch = agent.launch
    if (
        launch is None
        or launch.airborne
        or launch.engine_arms
        or agent.airframe_class != "multirotor"
        or not any(state.traits.takes_off for state in root.walk())
    ):
        return
    first = entry_leaves(root)
    if not first or any(leaf.traits.takes_off or leaf.unresolved for leaf in first):
        return
    leaf = first[0]
    what = leaf.primitive or ("a final state" if leaf.final else "an empty state")
    default = "" if "armed_by" in dict(launch.key_locations) else ", the default"
    yield warning(
        "W-LAUNCH-NO-FLIGHT",
        launch.locate("armed_by"),
        f"{agent.name} ({agent.profile}) starts on the ground and its pilot arms it "
        f"(launch.armed_by: pilot{default}), but its first state {leaf.dotted} ({what}) does "
        f"not take off: ArduCopter disarms a copter that has not taken off {DISARM_DELAY_S} s "
        "after it was armed (DISARM_DELAY), so the takeoff that comes later fails; write "
        "launch: {armed_by: engine}, so that the engine arms it when it takes off, or make "
        "takeoff its first state",
        leaf.mission_use or leaf.use_location or leaf.location,
    )


def check_states(mission: Mission, agent: Agent, root: State) -> Iterator[Finding]:
    """Events are known, timeouts have targets, done can happen, states are reachable."""
    targeted = {t.target for s in root.walk() for t in s.transitions if t.target}
    for state in root.walk():
        events = {t.event for t in state.transitions}
        for transition in state.transitions:
            yield from _check_event(mission, agent, state, transition.event, transition.location)
            yield from check_always(transition)
            if transition.condition is not None:
                yield from _check_condition(mission, agent, transition.condition, transition)
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
                f"the autopilot of {agent.name} has no mode {rest!r}; {_hint(rest, modes)}",
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
                f"{event!r} names no agent of this mission; {_hint(rest, mission.agents)}",
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
        f"{event!r} is not an event; {_hint(event, SIMPLE_EVENTS)} (events: {', '.join(known)})",
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
            f"{agent.name!r} has no RC channel named {channel!r}; {_hint(channel, with_rc)} "
            "or give the channel number",
        )


def _check_condition(
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
                yield from _check_condition(mission, agent, item, transition, (*here, i))
        elif key == "not":
            yield from _check_condition(mission, agent, value, transition, here)
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
                    + _hint(mode, agent.hardware.modes),
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
            + _hint(target, mission.agents),
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


def check_primitives(
    mission: Mission,
    agent: Agent,
    root: State,
    bad_states: set[tuple[str, tuple[str, ...]]],
) -> Iterator[Finding]:
    """Run each primitive's own checks, with the agent's hardware in view."""
    for state in root.walk():
        if state.primitive is None or (agent.name, state.path) in bad_states:
            continue
        spec = behaviors()[state.primitive]
        use_loc = state.use_location or state.location
        if spec.needs_autopilot and not agent.is_vehicle:
            yield error(
                "E-ROLE",
                use_loc,
                f"{state.primitive} commands a vehicle, and {agent.name!r} is a station; "
                "give it to a vehicle",
            )
            continue

        def locate(param: str, _state: State = state, _use: Location = use_loc) -> Location:
            base = param.split("[", 1)[0]
            return _state.param_locations.get(param) or _state.param_locations.get(base) or _use

        ctx = UseContext(mission, agent, state.params, locate, use_loc)
        for finding in spec.check(ctx):
            yield _rehome(finding, state, mission)


def _rehome(finding: Finding, state: State, mission: Mission) -> Finding:
    """Point a finding about a block's own value at the mission's use of the block."""
    return rehome(finding, mission.file, state.mission_use)


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
                    + _hint(name, mission.agents),
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
                    + _hint(state_path, [s.dotted for s in agent.behavior.walk()[1:]]),
                )
            elif kinds[0] == "signal" and not state.unresolved and state.primitive not in signals:
                yield error(
                    "E-CHECK-SHAPE",
                    where,
                    f"state {state_path!r} runs {state.primitive or 'no primitive'}; a signal "
                    f"check needs a {' or '.join(signals)} state",
                )
