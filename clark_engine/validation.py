"""Full validation: the mission layer's checks plus the ones that need ClarkLink.

The mission layer imports nothing else of the engine; the link layer knows
nothing of missions. The checks that need both (the radio link budget from real
encoded sizes, the mission's key file) live here, where the command line and
the demo call them.
"""

from __future__ import annotations

import stat
import sys
from collections import defaultdict
from pathlib import Path
from typing import TextIO

from clark_engine.behaviors import behaviors
from clark_engine.errors import ClarkError, UsageError
from clark_engine.link import wire
from clark_engine.link.auth import load_key
from clark_engine.link.budget import Flow, MeshBudget, PacketCosts, mesh_budget
from clark_engine.link.messages import (
    MAX_FAILSAFE_TEXT_BYTES,
    MAX_HEALTH_TEXT_BYTES,
    MAX_SEVERITY_SENT,
    AgentAttitude,
    AgentStatus,
    AgentType,
    BehaviorState,
    Condition,
    Heartbeat,
    Message,
    PictureData,
    PrearmState,
    VehicleHealth,
)
from clark_engine.link.packet import HEADER_BYTES, TAG_BYTES
from clark_engine.mission.findings import Finding, Location, error, warning
from clark_engine.mission.model import Agent, Mission, State
from clark_engine.mission.paths import confine
from clark_engine.mission.validate import Validation, validate_path

#: Larger than any GPS time in milliseconds this century: the worst case for its varint.
WORST_GPS_TIME_MS = 2**42 - 1
#: Worst cases are capped to what the wire carries (a profile may say anything).
WIRE_MAX_ALTITUDE_M = 2_000_000.0
WIRE_MAX_SPEED_M_S = 40_000_000.0
#: A climb rate at least this big takes the field's full two bytes on the wire.
MIN_WORST_CLIMB_M_S = 2.0
#: Telemetry only a vehicle sends: a station has no autopilot, so its runtime sends none of
#: these (and the budget does not count them).
VEHICLE_ONLY_TELEMETRY = ("agent_status", "agent_attitude", "vehicle_health")
#: Utilisation of the measured throughput above which the budget warns, and errs.
WARN_UTILISATION = 0.70
ERROR_UTILISATION = 1.00


def validate_file(path: Path, shown: str | None = None) -> Validation:
    """Validate a file completely: mission checks, key file and link budget.

    Raises:
        UsageError: The file cannot be read.
    """
    result = validate_path(path, shown)
    mission = result.mission
    if result.kind != "mission" or mission is None:
        return result
    extra = [
        *check_key_file(mission, path),
        *check_station_telemetry(mission),
        *check_link_budget(mission),
    ]
    result.findings = sorted([*result.findings, *extra], key=Finding.sort_key)
    if not result.ok:
        result.mission = None
    return result


def load_mission(path_text: str, errors: TextIO | None = None) -> Mission:
    """The resolved mission of a file a command was given, for the commands that run it.

    ``clark run``, ``clark autopilot-sim`` and ``clark radio-sim`` need a valid mission
    and nothing else; its errors are printed (to ``errors``, stderr by default) before
    the command fails.

    Raises:
        UsageError: No such file, or it cannot be read (exit 2).
        ClarkError: The mission is invalid (exit 1).
    """
    path = Path(path_text)
    if not path.is_file():
        raise UsageError(f"{path_text}: no such file")
    result = validate_file(path, path_text)
    if result.mission is None:
        for finding in result.errors:
            print(finding.format_text(), file=errors or sys.stderr)
        raise ClarkError(f"{path_text} is not a valid mission; `clark validate {path_text}`")
    return result.mission


def mission_to_fly(
    mission_path: Path | str, err: TextIO, *, quiet: bool, nothing: str
) -> Mission | None:
    """The valid mission a dry run or a campaign flies, its findings printed first.

    Errors are always printed to ``err``, warnings unless ``quiet``; an invalid mission
    prints ``PATH: invalid; NOTHING`` (``nothing simulated``, ``nothing flown``) and gives
    None, for the command's exit status 1.

    Raises:
        UsageError: The file cannot be read, or it is a file of another kind (a block).
    """
    validation = validate_file(Path(mission_path), str(mission_path))
    for finding in validation.findings:
        if finding.is_error or not quiet:
            print(finding.format_text(), file=err)
    if validation.kind != "mission" and validation.ok:
        raise UsageError(f"{mission_path} is a {validation.kind}, not a mission")
    if validation.mission is None:
        print(f"{mission_path}: invalid; {nothing}", file=err)
    return validation.mission


def _mission_location(mission: Mission, key: str) -> Location:
    return mission.locations.get(key, Location(mission.file, 1, 1, ("mission", key)))


def check_key_file(mission: Mission, mission_path: Path) -> list[Finding]:
    """The key file exists, is private and holds a key; commands without one are warned about."""
    if mission.key_file is None:
        if mission.stations:
            station = mission.stations[0]
            return [
                warning(
                    "W-NO-KEY",
                    station.location,
                    f"station {station.name} sends commands (mode change, activate, terminate) "
                    "that any radio in range could forge, and the mission has no key: make one "
                    "with `clark keygen KEYFILE` and name it in mission.key_file",
                )
            ]
        return []
    where = _mission_location(mission, "key_file")
    key_path, why = confine(mission_path.parent, mission.key_file)
    if key_path is None:
        # Refused before anything is opened: the answer must not say whether, or with what
        # mode, a file exists outside the mission's folder.
        return [
            error(
                "E-KEY-PATH",
                where,
                f"key_file must name a file in the mission's folder, and this one does not: "
                f"{why}; put the key beside the mission (clark keygen mission.key) and write "
                "key_file: mission.key",
            )
        ]
    try:
        load_key(key_path)
    except ClarkError as exc:
        return [error("E-KEY-FILE", where, f"{exc.message}")]
    mode = key_path.stat().st_mode
    if stat.S_IMODE(mode) & 0o077:  # load_key refuses these too; kept for clarity
        return [error("E-KEY-FILE", where, "the key file is readable by others; chmod 600 it")]
    return []


def check_station_telemetry(mission: Mission) -> list[Finding]:
    """A station's telemetry names no message that only a vehicle can send."""
    findings: list[Finding] = []
    for agent in mission.agents.values():
        if agent.is_vehicle:
            continue
        for name in VEHICLE_ONLY_TELEMETRY:
            item = agent.telemetry.get(name)
            if item is None:
                continue
            findings.append(
                warning(
                    "W-TELEMETRY-VEHICLE-ONLY",
                    item.location,
                    f"{agent.name} is a station: it has no autopilot, so it sends no {name} "
                    f"(only vehicles do); remove {name} from its telemetry",
                )
            )
    return findings


# -- worst-case messages ------------------------------------------------------------------


def _worst_paths(state: State) -> list[str]:
    """The set of states active at once whose dotted paths are longest in total."""
    if state.parallel:
        return [path for child in state.children.values() for path in _worst_paths(child)]
    if state.children:
        options = [_worst_paths(child) for child in state.children.values()]
        return max(options, key=lambda paths: sum(len(p) + 2 for p in paths))
    return [".".join(state.path)] if state.path else []


def _worst_event(mission: Mission, agent: Agent) -> str:
    names = ["autopilot_lost", "deactivate"]
    names += [f"lost:{a}" for a in mission.agents] + [f"found:{a}" for a in mission.agents]
    if agent.behavior is not None:
        names += [t.event for s in agent.behavior.walk() for t in s.transitions]
    names += [f"mode:{m}" for m in agent.hardware.modes]
    return max(names, key=len)


def worst_messages(mission: Mission, agent: Agent) -> dict[str, Message]:
    """Each message the agent may send periodically, with its costliest contents."""
    t = WORST_GPS_TIME_MS
    airframe = agent.hardware.part("airframe") or {}
    top_speed = min(float(airframe.get("max_speed_m_s", 100.0)), WIRE_MAX_SPEED_M_S)
    # Even a rover reports a small climb rate (GPS noise); a zero would drop the field.
    climb = min(
        max(
            float(airframe.get("max_descent_rate_m_s", 0.0)),
            float(airframe.get("max_climb_rate_m_s", 0.0)),
            MIN_WORST_CLIMB_M_S,
        ),
        WIRE_MAX_SPEED_M_S,
    )
    highest_mode = max(agent.hardware.modes.values(), default=0)
    ceiling_m = agent.envelope.legal_ceiling_m if agent.envelope is not None else 0.0
    altitude = -min(max(ceiling_m, float(airframe.get("max_altitude_m", 0.0))), WIRE_MAX_ALTITUDE_M)
    messages: dict[str, Message] = {
        "heartbeat": Heartbeat(
            agent_id=agent.id,
            gps_time_ms=t,
            mission_id=mission.id,
            agent_type=AgentType.VEHICLE if agent.is_vehicle else AgentType.MCS,
            condition=Condition.TERMINATED,
            payload_count=len(agent.hardware.payloads),
        ),
        "agent_status": AgentStatus(
            agent_id=agent.id,
            gps_time_ms=t,
            lat_deg=-89.9999999,
            lon_deg=-179.9999999,
            alt_m=altitude,
            ground_speed_m_s=top_speed,
            climb_rate_m_s=-climb,
            heading_deg=359.99,
            mode=highest_mode,
        ),
        "agent_attitude": AgentAttitude(
            agent_id=agent.id, gps_time_ms=t, roll_deg=-179.99, pitch_deg=-89.99, yaw_deg=-179.99
        ),
        "picture_data": PictureData(
            agent_id=agent.id,
            gps_time_ms=t,
            lat_deg=-89.9999999,
            lon_deg=-179.9999999,
            alt_m=altitude,
            image_index=2**32 - 1,
        ),
    }
    # The autopilot's longest warning and the longest failsafe text, every optional figure
    # present at its widest, a text hours old: what no Vehicle Health can exceed.
    messages["vehicle_health"] = VehicleHealth(
        agent_id=agent.id,
        gps_time_ms=t,
        armed=True,
        battery_v=65.534,
        battery_pct=100,
        gps_fix_type=8,
        satellites=254,
        prearm=PrearmState.FAILING,
        text_severity=MAX_SEVERITY_SENT,
        text="W" * MAX_HEALTH_TEXT_BYTES,
        failsafe="F" * MAX_FAILSAFE_TEXT_BYTES,
        autopilot_lost=True,
        text_age_s=2**32 - 1,
    )
    paths = _worst_paths(agent.behavior) if agent.behavior is not None else []
    messages["behavior_state"] = BehaviorState(
        agent_id=agent.id,
        gps_time_ms=t,
        active_states=tuple(paths),
        last_event=_worst_event(mission, agent),
    )
    return messages


def _order(message: Message) -> int:
    return wire.MESSAGE_ORDER.index(type(message))


def mission_flows(mission: Mission) -> list[Flow]:
    """Every periodic message of every agent, with its worst-case encoded size."""
    flows: list[Flow] = []
    for agent in mission.agents.values():
        worst = worst_messages(mission, agent)
        for name, item in agent.telemetry.items():
            if not agent.is_vehicle and name in VEHICLE_ONLY_TELEMETRY:
                continue  # never sent (W-TELEMETRY-VEHICLE-ONLY)
            flows.append(
                Flow(
                    sender=agent.name,
                    message=name,
                    every_ticks=max(1, round(mission.loop_hz / item.rate_hz)),
                    destinations=item.to,
                    size_bytes=wire.encoded_size(worst[name]),
                    order=_order(worst[name]),
                )
            )
        if agent.behavior is None:
            continue
        declared = behaviors()
        for state in agent.behavior.walk():
            behavior = declared.get(state.primitive) if state.primitive is not None else None
            for sent in behavior.sends(state.params, agent) if behavior is not None else ():
                flows.append(
                    Flow(
                        sender=agent.name,
                        message=sent.message,
                        every_ticks=max(1, round(sent.interval_s * mission.loop_hz)),
                        destinations=sent.to,
                        size_bytes=wire.encoded_size(worst[sent.message]),
                        order=_order(worst[sent.message]),
                    )
                )
    return flows


# -- the budget check ---------------------------------------------------------------------


def _meshes(mission: Mission) -> dict[tuple[str, str], list[Agent]]:
    """Agents grouped by the mesh they share: radio link kind and network id."""
    groups: dict[tuple[str, str], list[Agent]] = defaultdict(list)
    for agent in mission.agents.values():
        radio = agent.hardware.part("radio")
        if radio is None:
            continue
        groups[(str(radio.get("link")), str(radio.get("network_id", "")))].append(agent)
    return groups


def _sender_flows(mission: Mission, sender: str) -> list[Flow]:
    return [f for f in mission_flows(mission) if f.sender == sender]


def _flow_location(mission: Mission, sender: str, message: str) -> Location:
    agent = mission.agents[sender]
    item = agent.telemetry.get(message)
    if item is not None:
        return item.location
    return agent.locations.get("behavior", agent.location)


def check_link_budget(mission: Mission) -> list[Finding]:
    """Each mesh's telemetry fits its measured throughput and its packet limit."""
    findings: list[Finding] = []
    flows = mission_flows(mission)
    tag = TAG_BYTES if mission.key_file is not None else 0
    meshes = _meshes(mission)
    if len(meshes) > 1:
        groups = [
            f"{', '.join(a.name for a in agents)} on {agents[0].hardware.part_profiles['radio']}"
            for agents in meshes.values()
        ]
        # Blame the agents that are not on the station's radio (or the smallest group).
        groups_list = sorted(
            meshes.values(), key=lambda g: (any(not a.is_vehicle for a in g), len(g))
        )
        first = groups_list[0][0]
        findings.append(
            error(
                "E-LINK-MIXED",
                first.locations.get("hardware", first.location),
                "the agents are on radios that cannot hear each other ("
                + "; ".join(groups)
                + "); give every agent the same kind of radio and network",
            )
        )
    for (link, _network), agents in sorted(meshes.items()):
        radios = [a.hardware.part("radio") or {} for a in agents]
        throughput = min(float(r["throughput_bps"]) for r in radios)
        costs = PacketCosts(
            header_bytes=HEADER_BYTES,
            tag_bytes=tag,
            frame_bytes=max(int(r.get("frame_overhead_bytes", 0)) for r in radios),
            max_packet_bytes=min(int(r["max_packet_bytes"]) for r in radios),
        )
        names = [a.name for a in agents]
        budget = mesh_budget(flows, names, mission.loop_hz, costs, throughput)
        radio_name = agents[0].hardware.part_profiles.get("radio", link)
        findings.extend(_budget_findings(mission, budget, radio_name, costs))
    return findings


def _budget_findings(
    mission: Mission, budget: MeshBudget, radio: str, costs: PacketCosts
) -> list[Finding]:
    findings: list[Finding] = []
    for load in budget.loads:
        for message, size in load.unsendable:
            findings.append(
                error(
                    "E-LINK-PACKET",
                    _flow_location(mission, load.sender, message),
                    f"{message} of {load.sender} can take {size} bytes, more than the "
                    f"{costs.room_bytes} bytes of messages a {radio} packet carries after its "
                    f"header{' and tag' if costs.tag_bytes else ''}, so it cannot be sent; "
                    "shorten what it carries (state names, for behavior_state)",
                )
            )
        if load.split_ticks:
            largest = load.largest_bundle_messages
            biggest = max(
                largest,
                key=lambda m: next(
                    (f.size_bytes for f in _sender_flows(mission, load.sender) if f.message == m), 0
                ),
            )
            findings.append(
                warning(
                    "W-LINK-SPLIT",
                    _flow_location(mission, load.sender, biggest),
                    f"{load.sender} can have {load.largest_bundle_bytes} bytes due in one tick "
                    f"({', '.join(largest)}), more than one {radio} packet carries "
                    f"({costs.room_bytes} bytes of messages); it is split and pays the packet "
                    f"overhead again; send {biggest} less often, to fewer agents, or shorten it",
                )
            )
    share = budget.utilisation
    if share <= WARN_UTILISATION:
        return findings
    sender, message, _ = budget.costliest(1)[0]
    messages = ", ".join(
        f"{m} {bps / 1000:.1f} kbps from {n} agent{'s' * (n != 1)}"
        for m, bps, n in budget.by_message()[:3]
    )
    senders = ", ".join(f"{s} {bps / 1000:.1f} kbps" for s, bps in budget.by_sender()[:3])
    text = (
        f"the agents on the {radio} mesh send {budget.bits_per_s / 1000:.1f} kbps, "
        f"{share:.0%} of its measured {budget.throughput_bps / 1000:g} kbps "
        f"(by message: {messages}; by agent: {senders}); lower those rates or mission.loop_hz"
    )
    where = _flow_location(mission, sender, message)
    if share > ERROR_UTILISATION:
        findings.append(error("E-LINK-BUDGET", where, text))
    else:
        findings.append(
            warning("W-LINK-BUDGET", where, text + f" to stay under {WARN_UTILISATION:.0%}")
        )
    return findings
