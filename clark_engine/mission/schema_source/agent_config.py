"""Schema of a compiled agent config (``schemas/agent_config.schema.json``).

The config is what ``clark compile`` writes and what an agent runs from: the
thesis's three sections (mission, Clark, agent) plus the telemetry schedule,
the peer table and the resolved behaviour.
"""

from __future__ import annotations

from typing import Any

from clark_engine.behaviors import in_schemas
from clark_engine.mission.model import (
    ARMED_BY,
    COMPUTER_LOST_ACTIONS,
    COMPUTER_LOST_RANGE_S,
    TELEMETRY_MESSAGES,
    TICK_PHASES,
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
    resolved_point,
    schema_id,
    string,
)
from clark_engine.mission.schema_source.states import condition_schema

_NULLABLE_STRING: Schema = {"type": ["string", "null"]}


def _nullable(schema: Schema) -> Schema:
    return {"anyOf": [{"type": "null"}, schema], "description": schema.get("description", "")}


_point = resolved_point


def _zone() -> Schema:
    return {
        "description": "A geofence zone: a polygon of points, or a circle.",
        "oneOf": [
            obj(
                "A polygon.",
                {
                    "kind": {"const": "polygon"},
                    "points": array("Its corners in order.", _point(), min_items=3),
                },
                required=["kind", "points"],
            ),
            obj(
                "A circle.",
                {
                    "kind": {"const": "circle"},
                    "center": _point(),
                    "radius_m": number("Its radius.", unit="m", exclusive_minimum=0),
                },
                required=["kind", "center", "radius_m"],
            ),
        ],
    }


def _envelope() -> Schema:
    """A vehicle's resolved safety envelope (docs/safety.md)."""
    actions = ["hold", "rtl", "land"]
    return obj(
        "Where the vehicle may fly, every default filled in; altitudes above the origin.",
        {
            "ceiling_m": number("Highest altitude above the origin.", unit="m", minimum=0),
            "floor_m": number(
                "Lowest altitude above the origin in guided flight.", unit="m", minimum=0
            ),
            "legal_ceiling_m": number(
                "The legal limit above the origin.", unit="m", exclusive_minimum=0
            ),
            "margin_m": number(
                "How far inside the envelope targets are kept.", unit="m", minimum=0
            ),
            "geofence": obj(
                "Where on the ground: inside every inclusion zone, outside every exclusion zone.",
                {
                    "default_radius_m": {
                        "type": ["number", "null"],
                        "exclusiveMinimum": 0,
                        "x-unit": "m",
                        "description": "With no inclusion zone: the radius of the circle "
                        "around home the vehicle stays in; null when zones are declared.",
                    },
                    "home": _point(),
                    "include": array("Inclusion zones.", _zone()),
                    "exclude": array("Exclusion zones.", _zone()),
                },
                required=["default_radius_m", "home", "include", "exclude"],
            ),
            "min_separation_m": number(
                "Smallest 3-D distance from any other vehicle.", unit="m", minimum=0
            ),
            "separation": {
                "type": "object",
                "description": "Other vehicle -> the smallest distance kept from it, where "
                "the mission sets one for the pair.",
                "additionalProperties": {"type": "number", "minimum": 0},
            },
            "on_breach": string("On a fence, altitude or endurance breach.", enum=actions),
            "on_near_miss": string("On another vehicle inside the separation.", enum=actions),
            "outside": string(
                "A target outside the envelope is clamped or refused.", enum=["clamp", "refuse"]
            ),
            "endurance_s": {
                "type": ["number", "null"],
                "exclusiveMinimum": 0,
                "x-unit": "s",
                "description": "Time armed allowed; null when none is declared.",
            },
            "position_error_m": number(
                "How far the vehicle's reported horizontal position may be from the truth "
                "(95 % of the time); absent when 0.",
                unit="m",
                minimum=0,
            ),
            "peer_position_error_m": {
                "type": "object",
                "description": "Other vehicle -> how far its reported horizontal position "
                "may be from the truth, for the vehicles whose figure is not 0. The runtime "
                "keeps this vehicle's figure and the other's on top of the pair's "
                "separation, on the reported positions; absent when every other vehicle's "
                "figure is 0.",
                "additionalProperties": {"type": "number", "minimum": 0},
            },
        },
        required=[
            "ceiling_m",
            "floor_m",
            "legal_ceiling_m",
            "margin_m",
            "geofence",
            "min_separation_m",
            "separation",
            "on_breach",
            "on_near_miss",
            "outside",
            "endurance_s",
        ],
    )


def _state() -> Schema:
    transition = obj(
        "A resolved transition.",
        {
            "event": string("Event that triggers it."),
            "target": string("Dotted path of the target state from the root."),
            "when": _nullable({"$ref": "#/$defs/condition"})
            | {"description": "Structured condition (the mission's), or null."},
            "source": string("Where it was written (file:line:column)."),
        },
        required=["event", "target", "when", "source"],
    )
    state = obj(
        "A resolved state: blocks expanded, defaults applied, names resolved.",
        {
            "name": string("State name; empty at the root."),
            "path": string("Dotted path from the root; empty at the root."),
            "kind": string(
                "What the state is.", enum=["primitive", "machine", "parallel", "final", "empty"]
            ),
            "description": _NULLABLE_STRING | {"description": "The author's note."},
            "primitive": {
                "enum": [None, *in_schemas()],
                "description": "Primitive the state runs (null for none): "
                + ", ".join(in_schemas())
                + ".",
            },
            "params": {
                "type": "object",
                "description": "Primitive parameters: defaults applied, points in both frames, "
                "channels as their resolved map, agents as {name, id}; checked against the "
                "primitive's own parameters (params_<primitive>).",
            },
            "block": _NULLABLE_STRING | {"description": "Block the state came from."},
            "initial": _NULLABLE_STRING | {"description": "First child of a machine."},
            "parallel": boolean("Children run side by side."),
            "finish": string(
                "Parallel states: all or any region finishing finishes it.", enum=["all", "any"]
            ),
            "final": boolean("Reaching it finishes the parent."),
            "timeout_s": {
                "type": ["number", "null"],
                "description": "Timeout after entry.",
                "x-unit": "s",
            },
            "transitions": array("Outgoing transitions in the order written.", transition),
            "source": string("Where the state was written (file:line:column)."),
            "states": array("Child states in the order written.", {"$ref": "#/$defs/state"}),
        },
        required=[
            "name",
            "path",
            "kind",
            "primitive",
            "params",
            "initial",
            "parallel",
            "finish",
            "final",
            "timeout_s",
            "transitions",
            "source",
            "states",
        ],
    )
    state["allOf"] = [
        {
            "if": {"properties": {"primitive": {"const": name}}},
            "then": {"properties": {"params": {"$ref": f"#/$defs/params_{name}"}}},
        }
        for name in in_schemas()
    ]
    return state


def build() -> dict[str, Any]:
    """The whole agent-config schema."""
    part = {
        "type": ["object", "null"],
        "description": "The merged profile of this part (see the hardware-profile schema).",
    }
    return {
        "$schema": DIALECT,
        "$id": schema_id("agent-config"),
        "$comment": "Generated by `python -m clark_engine.mission.schema_source`; do not edit.",
        "title": "Clark Engine compiled agent config",
        "description": "Everything one agent needs to run its part of a mission, written by "
        "clark compile.",
        "type": "object",
        "additionalProperties": False,
        "required": [
            "clark_config",
            "generator",
            "source",
            "mission",
            "clark",
            "agent",
            "telemetry",
            "peers",
            "envelope",
            "machine",
        ],
        "properties": {
            "clark_config": {"const": 1, "description": "Version of the config format."},
            "generator": string("Engine and version that wrote the file."),
            "source": obj(
                "The mission file the config was compiled from.",
                {
                    "file": string("Path as given to clark compile."),
                    "sha256": string(
                        "SHA-256 of the mission file's bytes.", pattern="^[0-9a-f]{64}$"
                    ),
                },
                required=["file", "sha256"],
            ),
            "mission": obj(
                "Mission section (thesis 3.2.1).",
                {
                    "id": integer("Mission id.", minimum=1, maximum=4294967295),
                    "name": string("Mission name."),
                    "description": _NULLABLE_STRING | {"description": "The author's note."},
                    "agent": string("This agent's name.", pattern=NAME_PATTERN),
                    "agent_id": integer("This agent's id.", minimum=1, maximum=65535),
                    "loop_hz": number("Loop rate.", unit="Hz", exclusive_minimum=0),
                    "heartbeat_timeout_s": number(
                        "Silence after which a peer is lost.", unit="s", exclusive_minimum=0
                    ),
                    "origin": obj(
                        "Reference point of the local frame, on the ground; every alt_m is "
                        "above it.",
                        {
                            "lat": number("Latitude.", unit="deg", minimum=-90, maximum=90),
                            "lon": number("Longitude.", unit="deg", minimum=-180, maximum=180),
                            "alt_amsl_m": number(
                                "Height of the ground there above mean sea level.", unit="m"
                            ),
                        },
                        required=["lat", "lon", "alt_amsl_m"],
                    ),
                    "authenticated": boolean("Every packet carries a tag made with the key."),
                    "key_file": _NULLABLE_STRING
                    | {
                        "description": "The key file as the mission names it, relative to the "
                        "mission file; copy it beside the config. Never the key itself."
                    },
                    "tick_phases": array(
                        "Order of the phases of one tick: each phase exactly once (without "
                        "timeouts no timeout or failsafe would ever fire).",
                        string("A phase.", enum=list(TICK_PHASES)),
                        min_items=len(TICK_PHASES),
                        max_items=len(TICK_PHASES),
                        unique=True,
                    ),
                    "log": obj(
                        "Log level and file names (thesis 2.4.1-2.4.4, 7.3.6).",
                        {
                            "level": string(
                                "Log level.", enum=["DEBUG", "INFO", "WARNING", "ERROR", "CRITICAL"]
                            ),
                            "mission_log": string("Mission log file."),
                            "interface_log": string("Interface log file."),
                            "fleet_csv": string("Fleet table CSV, a row per tick."),
                            "message_log": string("Every packet sent and received."),
                        },
                        required=[
                            "level",
                            "mission_log",
                            "interface_log",
                            "fleet_csv",
                            "message_log",
                        ],
                    ),
                },
                required=[
                    "id",
                    "name",
                    "description",
                    "agent",
                    "agent_id",
                    "loop_hz",
                    "heartbeat_timeout_s",
                    "origin",
                    "authenticated",
                    "key_file",
                    "tick_phases",
                    "log",
                ],
            ),
            "clark": obj(
                "Clark section (thesis 3.2.2): which interfaces run.",
                {
                    "testing_mode": boolean("When true, enable decides each interface."),
                    "enable": obj(
                        "Interfaces to start.",
                        {
                            k: boolean(f"Start the {k} interface.")
                            for k in ("radio", "autopilot", "payload", "gui")
                        },
                        required=["radio", "autopilot", "payload", "gui"],
                    ),
                    "gui": {
                        "type": ["object", "null"],
                        "description": "The station's GUI settings (address, timeout_s).",
                    },
                },
                required=["testing_mode", "enable", "gui"],
            ),
            "agent": obj(
                "Agent section (thesis 3.2.3).",
                {
                    "name": string("Agent name.", pattern=NAME_PATTERN),
                    "id": integer("Agent id.", minimum=1, maximum=65535),
                    "role": string("vehicle or mcs.", enum=["vehicle", "mcs"]),
                    "profile": string("Platform profile.", pattern=NAME_PATTERN),
                    "terminal_mode": _NULLABLE_STRING
                    | {"description": "Mode left in on termination."},
                    "failsafe": obj(
                        "What the agent does when something it depends on goes silent; "
                        "empty for a station.",
                        {
                            "mcs_lost": string(
                                "The runtime's action on every station's silence.",
                                enum=["hold", "rtl", "land", "continue"],
                            ),
                            "computer_lost": string(
                                "The autopilot's own action on the mission computer's "
                                "silence (ArduPilot's GCS failsafe, set up by the engine).",
                                enum=list(COMPUTER_LOST_ACTIONS),
                            ),
                            "computer_lost_s": number(
                                "Seconds from the mission computer's last heartbeat to the "
                                "autopilot's reaction.",
                                unit="s",
                                minimum=COMPUTER_LOST_RANGE_S[0],
                                maximum=COMPUTER_LOST_RANGE_S[1],
                            ),
                        },
                    ),
                    "launch": _nullable(
                        obj(
                            "How the vehicle gets going before its behaviour runs (the "
                            "mission's launch, defaults filled in); null for a station.",
                            {
                                "armed_by": string(
                                    "pilot: the safety pilot arms and the engine never does; "
                                    "engine: the engine arms when the behaviour first needs it.",
                                    enum=list(ARMED_BY),
                                ),
                                "airborne": boolean(
                                    "The pilot has armed the aircraft and taken off before "
                                    "the behaviour starts."
                                ),
                            },
                            required=["armed_by", "airborne"],
                        )
                    ),
                    "position": _point(),
                    "hardware": obj(
                        "The merged hardware, every part resolved.",
                        {
                            "profiles": {
                                "type": "object",
                                "description": "Part -> profile it came from.",
                            },
                            "airframe": part,
                            "autopilot": part,
                            "radio": part,
                            "computer": part,
                            "payloads": {
                                "type": "object",
                                "description": "Payload name -> merged profile.",
                            },
                        },
                        required=[
                            "profiles",
                            "airframe",
                            "autopilot",
                            "radio",
                            "computer",
                            "payloads",
                        ],
                    ),
                },
                required=[
                    "name",
                    "id",
                    "role",
                    "profile",
                    "terminal_mode",
                    "failsafe",
                    "launch",
                    "position",
                    "hardware",
                ],
            ),
            "telemetry": array(
                "Messages sent periodically.",
                obj(
                    "One scheduled message.",
                    {
                        "message": string("Message.", enum=list(TELEMETRY_MESSAGES)),
                        "rate_hz": number("Rate.", unit="Hz", exclusive_minimum=0),
                        "every_ticks": integer("Sent once every this many ticks.", minimum=1),
                        "to": array(
                            "Destinations; empty for broadcast.",
                            string("Agent.", pattern=NAME_PATTERN),
                        ),
                    },
                    required=["message", "rate_hz", "every_ticks", "to"],
                ),
            ),
            "peers": array(
                "Every other agent of the mission (the fleet table's expected members).",
                obj(
                    "A peer.",
                    {
                        "name": string("Peer name.", pattern=NAME_PATTERN),
                        "id": integer("Peer id.", minimum=1, maximum=65535),
                        "role": string("vehicle or mcs.", enum=["vehicle", "mcs"]),
                        "radio_address": _NULLABLE_STRING
                        | {"description": "The peer's radio address."},
                        "sends": {
                            "type": "object",
                            "description": "Message -> rate in Hz it sends to this agent.",
                            "additionalProperties": {"type": "number"},
                        },
                        "modes": {
                            "type": "object",
                            "description": "The peer's autopilot modes (name -> number), for "
                            "Mode Change Requests; empty for stations.",
                            "additionalProperties": {"type": "integer"},
                        },
                        "envelope": _nullable({"$ref": "#/$defs/envelope"})
                        | {
                            "description": "The peer's safety envelope, in a station's "
                            "config (null in a vehicle's, and for a station peer)."
                        },
                    },
                    required=["name", "id", "role", "radio_address", "sends", "modes", "envelope"],
                ),
            ),
            "envelope": _nullable({"$ref": "#/$defs/envelope"})
            | {"description": "This vehicle's safety envelope; null for a station."},
            "machine": _nullable({"$ref": "#/$defs/state"}),
        },
        "$defs": {
            "state": _state(),
            "envelope": _envelope(),
            "condition": condition_schema(),
            **{f"params_{name}": spec.config_params() for name, spec in in_schemas().items()},
        },
    }
