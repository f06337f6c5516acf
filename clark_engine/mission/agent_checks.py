"""Checks of each agent's declaration: its id, radio address, rates and modes.

Why separate: these read one agent's keys (and compare them across agents, where a value
must be unique) against its hardware and the mission's loop, not its behaviour: unique ids
(ClarkLink routes by id) and radio addresses in the radio's format; ``loop_hz`` against each
mission computer; telemetry rates against the loop, their destinations and the heartbeat
against ``heartbeat_timeout_s``; the terminal mode and failsafes against the autopilot's
modes. :func:`clark_engine.mission.cross_checks.run_all` runs them.
"""

from __future__ import annotations

import re
from collections.abc import Iterator, Mapping

from clark_engine.mission.check_help import hint, raw_loc
from clark_engine.mission.findings import Finding, Location, error, warning
from clark_engine.mission.model import Agent, Mission

#: A rate whose loop divider is off by more than this is reported.
RATE_DIVIDER_TOLERANCE = 0.01
#: The lowest telemetry rate: once a day. Below it a message is in effect never sent, and
#: its loop divider (loop_hz / rate) outgrows every integer a float can hold.
MIN_RATE_HZ = 1.0 / 86400.0


def check_ids(mission: Mission) -> Iterator[Finding]:
    """Agent ids are unique (ClarkLink routes by id)."""
    seen: dict[int, Agent] = {}
    for agent in mission.agents.values():
        first = seen.get(agent.id)
        if first is not None:
            yield error(
                "E-ID-DUPLICATE",
                raw_loc(agent, "id"),
                f"agents {first.name!r} and {agent.name!r} both have id {agent.id}; give each "
                "agent its own id",
                raw_loc(first, "id"),
            )
        else:
            seen[agent.id] = agent


def check_addresses(mission: Mission) -> Iterator[Finding]:
    """Radio addresses are unique and match the radio's address format."""
    seen: dict[str, Agent] = {}
    for agent in mission.agents.values():
        address = agent.radio_address
        if address is None:
            continue
        radio = agent.hardware.part("radio") or {}
        pattern = radio.get("address_pattern")
        where = raw_loc(agent, "radio_address")
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
                raw_loc(first, "radio_address"),
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
                    + hint(name, mission.agents),
                )
    heartbeat = agent.telemetry.get("heartbeat")
    written = agent.raw.get("telemetry")
    if heartbeat is None:
        if not (isinstance(written, Mapping) and "heartbeat" in written):
            yield warning(
                "W-NO-HEARTBEAT",
                raw_loc(agent, "telemetry"),
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
            raw_loc(agent, "terminal_mode"),
            f"the autopilot of {agent.name} ({agent.profile}) has no mode "
            f"{agent.terminal_mode!r}; " + hint(agent.terminal_mode, modes),
        )
    action = agent.failsafe.get("mcs_lost", "hold")
    needed = {"rtl": autopilot.get("rtl_mode"), "land": autopilot.get("land_mode")}
    if action in needed and needed[action] is None:
        yield error(
            "E-FAILSAFE",
            raw_loc(agent, "failsafe"),
            f"failsafe {action} needs a {action.upper()} mode, which the autopilot of "
            f"{agent.name} does not have; choose hold or rtl",
        )
    declared = agent.raw.get("failsafe")
    if isinstance(declared, Mapping) and "mcs_lost" in declared and not mission.stations:
        yield warning(
            "W-NO-STATION",
            raw_loc(agent, "failsafe"),
            "failsafe.mcs_lost can never trigger: the mission has no station (role mcs); "
            "add one or remove it",
        )
