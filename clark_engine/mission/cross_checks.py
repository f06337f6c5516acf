"""Checks before flight: what the schema cannot see.

Every check takes the resolved :class:`Mission` and yields findings; none stops
at the first problem. Checks that belong to one primitive (a doublet's width,
a sweep's Nyquist limit, a photo trigger's camera) live beside that primitive;
:func:`run_all` runs them (:func:`check_primitives`) and the checks that span agents and
states, one module per subject:

- :mod:`~clark_engine.mission.agent_checks`: ids and radio addresses, ``loop_hz`` and
  telemetry rates, heartbeats, terminal modes and failsafes;
- :mod:`~clark_engine.mission.launch_checks`: ``launch``, the start height, the takeoff;
- :mod:`~clark_engine.mission.state_checks`: events, timeouts, done, reachability,
  parallel regions, with :mod:`~clark_engine.mission.condition_checks` for conditions;
- :mod:`~clark_engine.mission.envelope_mission_checks`: the envelope across states and
  vehicles;
- :mod:`~clark_engine.mission.dry_run_checks`: the operator, faults, variations and the
  dry run's expectations.
"""

from __future__ import annotations

from collections.abc import Iterator

from clark_engine.behaviors import UseContext, behaviors
from clark_engine.behaviors.shared import off_the_globe
from clark_engine.mission import envelope_mission_checks
from clark_engine.mission.agent_checks import (
    check_addresses,
    check_agent_modes,
    check_ids,
    check_loop_rate,
    check_telemetry,
)
from clark_engine.mission.check_help import raw_loc
from clark_engine.mission.dry_run_checks import (
    check_expectations,
    check_faults,
    check_operator,
    check_variations,
)
from clark_engine.mission.findings import Finding, Location, error, rehome
from clark_engine.mission.launch_checks import check_launch, check_launch_flight, check_takeoff
from clark_engine.mission.model import Agent, Mission, State
from clark_engine.mission.state_checks import check_states


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
            findings.append(error("E-POSITION", raw_loc(agent, "position"), f"the agent {problem}"))
        findings.extend(check_telemetry(mission, agent))
        findings.extend(check_agent_modes(mission, agent))
        findings.extend(check_launch(agent))
        if agent.behavior is not None:
            findings.extend(check_states(mission, agent, agent.behavior))
            findings.extend(check_primitives(mission, agent, agent.behavior, bad_states))
            findings.extend(check_takeoff(agent, agent.behavior))
            findings.extend(check_launch_flight(agent, agent.behavior))
    findings.extend(envelope_mission_checks.check_mission(mission))
    findings.extend(check_expectations(mission))
    findings.extend(check_operator(mission))
    findings.extend(check_faults(mission))
    findings.extend(check_variations(mission))
    return findings


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
