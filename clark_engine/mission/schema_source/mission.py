"""Schema of a mission file (``schemas/mission.schema.json``).

The mission's settings and its agents (hardware, telemetry, launch, behaviour) are declared
here; the sections that only a dry run reads (``checks``, ``operator``, ``faults``,
``sim``, ``campaign``) are :mod:`.dry_run`'s.
"""

from __future__ import annotations

from typing import Any

from clark_engine.behaviors.shared import AGENT_NAME_SCHEMA, POINT_SCHEMA
from clark_engine.mission.model import (
    ARMED_BY,
    COMPUTER_LOST_ACTIONS,
    COMPUTER_LOST_RANGE_S,
    DEFAULT_COMPUTER_LOST_S,
    TELEMETRY_MESSAGES,
)
from clark_engine.mission.schema_source.common import (
    DIALECT,
    NAME_PATTERN,
    Schema,
    array,
    boolean,
    integer,
    number,
    obj,
    origin_amsl_m,
    path_string,
    rate_hz,
    schema_id,
    string,
)
from clark_engine.mission.schema_source.dry_run import (
    agent_sim,
    campaign,
    check,
    fault,
    operator,
    sim,
)
from clark_engine.mission.schema_source.envelope import (
    agent_envelope_schema,
    mission_envelope_schema,
    zone_def,
)
from clark_engine.mission.schema_source.hardware_profile import (
    PART_KINDS,
    agent_hardware_schema,
    part_reference_schema,
)
from clark_engine.mission.schema_source.states import state_defs

#: Highest telemetry rate a mission may ask for; far above any radio's budget.
MAX_TELEMETRY_HZ = 100

_MESSAGE_DESCRIPTIONS = {
    "heartbeat": "Heartbeat: mission id, agent type, ClarkLink version, condition; peers add "
    "an agent to their fleet table on its first heartbeat.",
    "agent_status": "Agent Status: position, altitude, velocity, heading and autopilot mode.",
    "agent_attitude": "Agent Attitude: roll, pitch and yaw.",
    "behavior_state": "Behavior State: active states and last event, for the station's view.",
    "vehicle_health": "Vehicle Health: armed, battery, GPS fix and satellites, the autopilot's "
    "pre-arm checks and latest warning, and the failsafe in force, for the station's view "
    "(docs/clarklink.md). Vehicles only: a station has no autopilot and sends none.",
}


def _rate(message: str) -> Schema:
    long_form = obj(
        "Rate and destinations of " + message + ".",
        {
            "rate_hz": number(
                "How often the message is sent.",
                unit="Hz",
                exclusive_minimum=0,
                maximum=MAX_TELEMETRY_HZ,
            ),
            "to": array(
                "Agents that receive it; every agent when omitted.",
                AGENT_NAME_SCHEMA,
                min_items=1,
                unique=True,
            ),
        },
        required=["rate_hz"],
    )
    return {
        "description": _MESSAGE_DESCRIPTIONS[message] + " A rate in Hz, or {rate_hz, to}.",
        "x-unit": "Hz",
        "x-expected": "a rate in Hz, or {rate_hz: .., to: [agent, ..]}",
        "anyOf": [
            number(
                "Rate in Hz, sent to every agent.",
                unit="Hz",
                exclusive_minimum=0,
                maximum=MAX_TELEMETRY_HZ,
            ),
            long_form,
        ],
    }


def _hardware_overrides() -> Schema:
    """Per-agent hardware: change any field of a part, or swap it ({profile: other})."""
    schema = agent_hardware_schema()
    for kind in PART_KINDS:
        schema["properties"][kind] = part_reference_schema(kind, require_profile=False)
    schema["description"] = (
        "Per-agent changes to the platform: fields deep-merged onto a part, or "
        "{profile: name, ...} (or just a name) to swap the part for another profile."
    )
    return schema


def _agent() -> Schema:
    return obj(
        "One agent: a vehicle, or a mission control station (role mcs).",
        {
            "id": integer("ClarkLink agent id, unique in the mission.", minimum=1, maximum=65535),
            "description": string("What this agent does, in your words."),
            "role": string(
                "vehicle or mcs; taken from the platform profile when omitted.",
                enum=["vehicle", "mcs"],
            ),
            "profile": string(
                "Platform profile from hardware_profiles/platforms (e.g. super_cub, mcs_laptop).",
                pattern=NAME_PATTERN,
            ),
            "hardware": _hardware_overrides(),
            "telemetry": obj(
                "Messages this agent sends periodically: message -> rate.",
                {m: _rate(m) for m in TELEMETRY_MESSAGES},
            ),
            "behavior": {"$ref": "#/$defs/state"},
            "failsafe": obj(
                "What the agent does when something it depends on goes silent.",
                {
                    "mcs_lost": string(
                        "On silence from every station: hold position, return to launch, "
                        "land, or continue. Never resumes by itself when the station returns.",
                        enum=["hold", "rtl", "land", "continue"],
                        default="hold",
                    ),
                    "computer_lost": string(
                        "What the vehicle's autopilot does by itself when this mission "
                        "computer falls silent (a crash, a cable): return to launch, land, "
                        "or hold where it is (a rover stops; it cannot land). The engine sets "
                        "it up as ArduPilot's ground-station failsafe, driven by the mission "
                        "computer's heartbeat, before the behaviour starts; it cannot be "
                        "turned off here. rtl for aircraft and hold for rovers when omitted.",
                        enum=list(COMPUTER_LOST_ACTIONS),
                    ),
                    "computer_lost_s": number(
                        "Seconds from the mission computer's last heartbeat to the "
                        "autopilot's reaction (ArduPilot's FS_GCS_TIMEOUT, FS_LONG_TIMEOUT on "
                        "ArduPlane; ArduRover waits its FS_TIMEOUT, 1.5 s by default, more).",
                        unit="s",
                        minimum=COMPUTER_LOST_RANGE_S[0],
                        maximum=COMPUTER_LOST_RANGE_S[1],
                        default=DEFAULT_COMPUTER_LOST_S,
                    ),
                },
            ),
            "terminal_mode": string(
                "Mode the vehicle is left in when the mission terminates; the autopilot "
                "profile's terminal_mode when omitted."
            ),
            "launch": _launch(),
            "envelope": agent_envelope_schema(),
            "sim": agent_sim(),
            "position": POINT_SCHEMA
            | {
                "description": "Where the agent is: a station's location (for radio range "
                "checks), a vehicle's start. A vehicle starts on the ground (no up_m) unless "
                "launch.airborne, when up_m is the height at which the pilot hands it over. "
                "The mission origin when omitted."
            },
        },
        required=["id", "profile"],
    )


def _launch() -> Schema:
    return obj(
        "Vehicles only: how the vehicle gets going before its behaviour runs. A real "
        "ArduPilot vehicle starts disarmed on the ground; this says who arms it and whether "
        "the pilot has it flying before the behaviour starts.",
        {
            "armed_by": string(
                "Who arms the vehicle. pilot: the safety pilot arms it and the engine never "
                "does; the behaviour starts once it is armed (and, with airborne, flying). "
                "engine: the engine arms it when its behaviour first needs it (a guided or "
                "takeoff state); the behaviour starts once the autopilot is ready.",
                enum=list(ARMED_BY),
                default=ARMED_BY[0],
            ),
            "airborne": boolean(
                "Aircraft only: the pilot has armed it and taken off before the behaviour "
                "starts, and the behaviour starts once it flies. Needs armed_by pilot and a "
                "position whose up_m is the height at which the pilot hands it over.",
                default=False,
            ),
        },
    )


def build() -> dict[str, Any]:
    """The whole mission schema."""
    return {
        "$schema": DIALECT,
        "$id": schema_id("mission"),
        "$comment": "Generated by `python -m clark_engine.mission.schema_source`; do not edit.",
        "title": "Clark Engine mission",
        "description": "A multi-vehicle mission: its agents, their hardware, telemetry and "
        "behaviour, and what a dry run must observe.",
        "type": "object",
        "required": ["clark", "mission", "agents"],
        "additionalProperties": False,
        "properties": {
            "clark": {"const": 1, "description": "Version of the mission language (1)."},
            "mission": obj(
                "Settings shared by every agent (the thesis's mission configuration section).",
                {
                    "id": integer(
                        "Mission id; agents ignore peers that run another mission.",
                        minimum=1,
                        maximum=4294967295,
                    ),
                    "name": string(
                        "A short name of lower-case letters, digits, - and _ (e.g. "
                        "cooperative-follow); compiled configs go to <output>/<name>/.",
                        pattern=r"^[a-z0-9][a-z0-9_-]*$",
                    ),
                    "description": string("What the mission is for, in your words."),
                    "loop_hz": rate_hz(
                        "Rate of every agent's loop: one tick steps behaviour, commands and "
                        "telemetry.",
                        exclusive_minimum=0,
                    ),
                    "heartbeat_timeout_s": number(
                        "Silence after which a peer counts as lost.",
                        unit="s",
                        exclusive_minimum=0,
                        maximum=3600,
                        default=3,
                    ),
                    "origin": obj(
                        "Reference point of the local north/east/up frame, on the ground. "
                        "Every altitude in the mission, and every alt_m the engine reports, "
                        "is metres above it (the field is taken as flat at its height); "
                        "only alt_amsl_m is above mean sea level.",
                        {
                            "lat": number("Latitude.", unit="deg", minimum=-90, maximum=90),
                            "lon": number("Longitude.", unit="deg", minimum=-180, maximum=180),
                            "alt_amsl_m": origin_amsl_m(
                                "Height of the ground at the origin above mean sea level "
                                "(a survey, a map, or the autopilot's home on the field). "
                                "Altitudes above the origin are worked out from it, so a "
                                "vehicle on the ground that reads more than 10 m above or "
                                "below the origin does not start its behaviour."
                            ),
                        },
                        required=["lat", "lon", "alt_amsl_m"],
                    ),
                    "key_file": path_string(
                        "File holding the mission's 32-byte ClarkLink key (made by clark "
                        "keygen), relative to this file and inside its folder (no absolute "
                        "path, no ..). With a key every packet is authenticated; without one, "
                        "commands from the station are not."
                    ),
                    "log_level": string(
                        "Level of the mission and interface logs.",
                        enum=["DEBUG", "INFO", "WARNING", "ERROR", "CRITICAL"],
                        default="INFO",
                    ),
                },
                required=["id", "name", "loop_hz", "origin"],
            ),
            "include": obj(
                "Extra folders of your own, relative to this file and inside its folder "
                "(no absolute path, no ..), searched besides the shipped ones.",
                {
                    "behaviors": array(
                        "Folders of behaviour block files.", path_string("A folder.")
                    ),
                    "hardware_profiles": array(
                        "Folders of hardware profile files.", path_string("A folder.")
                    ),
                },
            ),
            "envelope": mission_envelope_schema(),
            "agents": {
                "type": "object",
                "description": "Agents by name.",
                "minProperties": 1,
                "propertyNames": {"pattern": NAME_PATTERN},
                "additionalProperties": {"$ref": "#/$defs/agent"},
            },
            "checks": array("Expectations the dry run evaluates.", {"$ref": "#/$defs/check"}),
            "operator": array(
                "What the station operator and pilots do during a dry run, in time order.",
                {"$ref": "#/$defs/operator"},
            ),
            "faults": array("Faults the dry run injects.", {"$ref": "#/$defs/fault"}),
            "sim": sim(),
            "campaign": campaign(),
        },
        "$defs": {
            "agent": _agent(),
            "check": check(),
            "operator": operator(),
            "fault": fault(),
            "zone": zone_def(),
            **state_defs(),
        },
    }
