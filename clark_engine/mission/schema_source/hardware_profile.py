"""JSON Schema source for hardware profiles (``hardware_profiles/<kinds>/<name>.yaml``).

A hardware profile describes one part a vehicle or station is built from: an
airframe, an autopilot, a radio, a mission computer, a payload, or a platform
that composes those parts into what a mission's agent names as its
``profile:``. Profiles compose by ``extends`` (the child is deep-merged onto its
parent), so a single file is usually partial. Two schemas follow from that:

* :func:`build` validates any one profile *file*: the common keys, and the keys
  of the file's ``kind``, each with its type, unit and range. Nothing
  kind-specific is required here, because a child states only what it changes;
  unknown keys are rejected so a misspelling is caught in the file that has it.
* :func:`kind_schema` validates a *merged* profile of one kind (after the
  engine has resolved the ``extends`` chain) and adds the keys it must have.

What JSON Schema cannot say (``extends`` names a profile of the same kind, mode
names used by ``guided_mode`` exist in ``modes``, PWM minimum <= trim <= maximum,
names are unique, the file stem equals ``profile``) the engine checks after
loading; docs/hardware-profiles.md lists those checks.

:data:`CHANNEL_SCHEMA`, :func:`part_reference_schema`, :func:`part_override_schema`
and :func:`agent_hardware_schema` are self-contained (no ``$ref``) so the mission
schema can embed them for per-agent overrides.
"""

from __future__ import annotations

import copy
from typing import Any

from clark_engine.mission.schema_source.common import (
    DIALECT,
    NAME_PATTERN,
    SPEED_MAX_M_S,
    Schema,
    altitude_m,
    array,
    boolean,
    distance_m,
    integer,
    length_m,
    mass_kg,
    number,
    obj,
    rate_hz,
    schema_id,
    string,
    time_s,
)

#: Largest magnitude of an ArduPilot parameter a profile sets: 2^24, the largest whole
#: number a 32-bit float (how ArduPilot stores parameters) holds exactly.
PARAMETER_LIMIT = 2**24

#: The six kinds of profile, in the order the guide presents them.
KINDS: tuple[str, ...] = ("airframe", "autopilot", "radio", "computer", "payload", "platform")

#: Folder under ``hardware_profiles/`` that holds each kind.
KIND_FOLDERS: dict[str, str] = {kind: f"{kind}s" for kind in KINDS}

#: Control names an airframe may list, and that channel maps resolve.
CONTROL_NAMES: tuple[str, ...] = (
    "aileron",
    "elevator",
    "rudder",
    "throttle",
    "roll",
    "pitch",
    "yaw",
    "steering",
)

#: The controls each airframe class can physically have.
CONTROLS_BY_CLASS: dict[str, tuple[str, ...]] = {
    "fixed_wing": ("aileron", "elevator", "rudder", "throttle"),
    "multirotor": ("roll", "pitch", "yaw", "throttle"),
    "rover": ("steering", "throttle"),
}

#: The parts a platform composes, besides its payloads.
PART_KINDS: tuple[str, ...] = ("airframe", "autopilot", "radio", "computer")

#: Keys every profile may carry, whatever its kind.
COMMON_KEYS: tuple[str, ...] = ("profile", "kind", "extends", "abstract", "description", "source")

#: Keys each kind requires once its ``extends`` chain is merged (unless ``abstract``).
REQUIRED_AFTER_MERGE: dict[str, tuple[str, ...]] = {
    "airframe": (
        "class",
        "cruise_speed_m_s",
        "max_speed_m_s",
        "min_speed_m_s",
        "max_climb_rate_m_s",
        "max_descent_rate_m_s",
        "max_turn_rate_deg_s",
        "max_altitude_m",
        "controls",
    ),
    "autopilot": (
        "firmware",
        "connection",
        "modes",
        "guided_mode",
        "hold_mode",
        "rtl_mode",
        "terminal_mode",
        "manual_mode",
        "channels",
    ),
    "radio": ("link", "throughput_bps", "max_packet_bytes", "frame_overhead_bytes"),
    "computer": ("max_loop_hz",),
    "payload": ("payload_kind", "connection", "min_interval_s", "capture_delay_s"),
    "platform": ("role",),
}

_PWM_MIN_US = 800
_PWM_MAX_US = 2200
_MODE_NAME_PATTERN = r"^[A-Z][A-Z0-9_]*$"
_HOST_PORT_PATTERN = r"^[^\s:]+:[0-9]{1,5}$"
_ONE_LINE_PATTERN = r"^[^\n]+$"


# --------------------------------------------------------------------------- helpers


def _article(word: str) -> str:
    """'an' before a vowel sound, else 'a' (an airframe, a radio)."""
    return "an" if word[:1] in "aeiou" else "a"


def _kind_is(key: str, value: str) -> Schema:
    """Build an ``if`` clause: the mapping has ``key`` and it equals ``value``."""
    return {"properties": {key: {"const": value}}, "required": [key]}


def _kind_in(key: str, values: list[str]) -> Schema:
    """Build an ``if`` clause: the mapping has ``key`` and it is one of ``values``."""
    return {"properties": {key: {"enum": values}}, "required": [key]}


def _nullable(schema: Schema, meaning: str) -> Schema:
    """Allow ``null`` besides the schema's own type; ``meaning`` says what null stands for."""
    out = dict(schema)
    out["type"] = [schema["type"], "null"]
    out["description"] = f"{schema['description']} {meaning}"
    return out


def _forbidden(reason: str) -> Schema:
    """Build a property schema that rejects any value; ``reason`` says why and what to do.

    Used instead of ``false`` because jsonschema reports a ``false`` subschema without
    the path of the key it rejected; a failing ``not`` keeps the path, and the error's
    ``schema["description"]`` carries the reason.
    """
    return {"not": {}, "description": reason}


def _host_port(description: str, *, default: str | None = None) -> Schema:
    """Build a ``host:port`` string property."""
    return string(description, pattern=_HOST_PORT_PATTERN, default=default)


def _profile_name(description: str) -> Schema:
    return string(description, pattern=NAME_PATTERN)


def _allow(keys: list[str]) -> Schema:
    """Build a subschema that never fails and marks ``keys`` as known.

    ``unevaluatedProperties`` counts a key as known only through subschemas that
    pass. Keeping "which keys exist" apart from "what values they take" means a
    wrong value is reported once, at the value, and not again as an unknown key.
    """
    return {"properties": dict.fromkeys(keys, True)}


def _keys_and_values(if_: Schema, then: Schema, keys: list[str]) -> list[Schema]:
    """Build two allOf branches under one condition: the checks, and the keys they allow."""
    return [{"if": if_, "then": then}, {"if": if_, "then": _allow(keys)}]


def _tagged_union(
    description: str,
    variants: dict[str, dict[str, Schema]],
    *,
    tag: str = "kind",
    tag_description: str,
) -> Schema:
    """Build a mapping whose ``tag`` selects which other keys it may have.

    Each variant's keys live in an if/then branch so an error names the key that
    is wrong for *that* variant. When the tag is absent (a child profile that
    overrides only, say, ``device``) or unknown (the tag's own error is
    reported), the union of all variants' keys is accepted and type-checked.
    """
    union: dict[str, Schema] = {}
    for props in variants.values():
        for key, schema in props.items():
            union.setdefault(key, schema)
    branches: list[Schema] = []
    for name, props in variants.items():
        branches += _keys_and_values(
            _kind_is(tag, name), {"properties": copy.deepcopy(props)}, list(props)
        )
    known = _kind_in(tag, list(variants))
    branches.append({"if": known, "else": {"properties": union}})
    branches.append({"if": known, "else": _allow(list(union))})
    return {
        "type": "object",
        "description": description,
        "properties": {tag: string(tag_description, enum=list(variants))},
        "allOf": branches,
        "unevaluatedProperties": False,
    }


def _tagged_union_complete(tag: str, required: dict[str, list[str]]) -> Schema:
    """Require what a merged tagged union must contain: the tag and each variant's keys."""
    return {
        "required": [tag],
        "allOf": [
            {"if": _kind_is(tag, name), "then": {"required": keys}}
            for name, keys in required.items()
            if keys
        ],
    }


# --------------------------------------------------------------------------- channels


def _channel_schema() -> Schema:
    pwm: dict[str, Any] = {"unit": "us", "minimum": _PWM_MIN_US, "maximum": _PWM_MAX_US}
    return obj(
        "One control or switch channel: the RC input the pilot's receiver drives it on, the "
        "SERVOn output the autopilot drives for it, and the PWM limits every command to it is "
        "checked against. Every entry of an agent's effective channel map needs all three PWM "
        "values. A control surface is commanded through its RC input (RC override): "
        "ArduPilot refuses DO_SET_SERVO on an output that has a SERVOn_FUNCTION such as "
        "aileron. `servo` names the output to read back from SERVO_OUTPUT_RAW, and can take a "
        "direct servo command only if that output has no function.",
        {
            "rc": _nullable(
                integer("RC input channel number (RCn, 1-18).", minimum=1, maximum=18),
                "null: this control has no RC input of its own.",
            ),
            "servo": _nullable(
                integer("Autopilot servo output number (SERVOn, 1-16).", minimum=1, maximum=16),
                "null: no output drives this control alone (e.g. a V-tail mixes elevator and "
                "rudder onto two outputs), so it is commanded through `rc` only.",
            ),
            "pwm_min_us": integer(
                "Lowest pulse width the channel may be commanded to, in microseconds (ArduPilot's "
                "RCn_MIN default is 1100).",
                **pwm,
            ),
            "pwm_trim_us": integer(
                "Neutral pulse width, in microseconds: stick centred (1500), throttle closed for "
                "a plane or copter (1100), stopped for a rover (1500).",
                **pwm,
            ),
            "pwm_max_us": integer(
                "Highest pulse width the channel may be commanded to, in microseconds (ArduPilot's "
                "RCn_MAX default is 1900).",
                **pwm,
            ),
        },
    )


#: The schema of one channel entry (read-only; ``copy.deepcopy`` it before changing it).
CHANNEL_SCHEMA: Schema = _channel_schema()


def _channels_schema(description: str) -> Schema:
    return {
        "type": "object",
        "description": description,
        "propertyNames": {
            "pattern": NAME_PATTERN,
            "description": "A channel name: lower-case letters, digits and _, starting with a "
            "letter.",
        },
        "additionalProperties": _channel_schema(),
    }


# --------------------------------------------------------------------------- kinds


def _common_properties(*, kind: str | None = None) -> dict[str, Schema]:
    kind_property: Schema = string(
        "Which kind of part this profile describes; it decides which other keys are allowed.",
        enum=list(KINDS),
    )
    if kind is not None:
        kind_property["const"] = kind
    return {
        "profile": string(
            "The profile's unique name (unique across all kinds); the file is named after it.",
            pattern=NAME_PATTERN,
        ),
        "kind": kind_property,
        "extends": _profile_name(
            "Name of a profile of the same kind that this one is deep-merged onto: mappings "
            "merge key by key, lists and single values replace the parent's."
        ),
        "abstract": boolean(
            "True for a base meant only to be extended (e.g. a generic Pixhawk); an agent "
            "cannot use it directly and it need not be complete.",
            default=False,
        ),
        "description": string(
            "One sentence saying what this part is.", pattern=_ONE_LINE_PATTERN, min_length=1
        ),
        "source": string(
            "Where the measured figures come from (e.g. 'thesis 5.1.1', a datasheet).",
            min_length=1,
        ),
    }


def _airframe_properties() -> dict[str, Schema]:
    speed: dict[str, Any] = {"unit": "m/s", "minimum": 0, "maximum": SPEED_MAX_M_S}
    return {
        "class": string(
            "Airframe class; selects the simulator's vehicle model and the controls it can have.",
            enum=list(CONTROLS_BY_CLASS),
        ),
        "mass_kg": mass_kg("Empty flying mass without payload, in kilograms.", exclusive_minimum=0),
        "wingspan_m": length_m("Wingspan, in metres.", exclusive_minimum=0),
        "wheelbase_m": length_m(
            "Diagonal motor-to-motor distance of a multirotor (or axle distance of a rover), "
            "in metres.",
            exclusive_minimum=0,
        ),
        "length_m": length_m("Overall length, in metres.", exclusive_minimum=0),
        "max_payload_kg": mass_kg("Largest payload mass the airframe carries, in kilograms."),
        "cruise_speed_m_s": number(
            "The speed the vehicle is normally flown or driven at, in metres per second. "
            "Never asked of the autopilot (guided legs fly the mission's speed_m_s or the "
            "autopilot's own); the dry run's fixed-wing model cruises at it.",
            **speed,
        ),
        "max_speed_m_s": number(
            "Highest speed the vehicle may be commanded to, in metres per second.", **speed
        ),
        "min_speed_m_s": number(
            "Lowest speed the vehicle may be commanded to, in metres per second: stall speed "
            "plus a margin for a fixed wing, 0 for a multirotor or rover.",
            **speed,
        ),
        "max_climb_rate_m_s": number(
            "Highest sustained climb rate, in metres per second (0 for a rover).", **speed
        ),
        "max_descent_rate_m_s": number(
            "Highest sustained descent rate, in metres per second (0 for a rover).", **speed
        ),
        "max_turn_rate_deg_s": number(
            "Highest sustained heading change rate, in degrees per second: the steadiest "
            "turn its autopilot flies (a plane pulled up in a bank turns faster for a "
            "moment, as ArduPlane SITL's does).",
            unit="deg/s",
            exclusive_minimum=0,
            maximum=720,
        ),
        "max_bank_deg": number(
            "Largest bank angle in turns, in degrees (fixed wing only).",
            unit="deg",
            exclusive_minimum=0,
            maximum=80,
        ),
        "max_altitude_m": altitude_m(
            "Service ceiling above ground that a simulator may let the vehicle reach, in metres "
            "(0 for a rover). A mission's own ceiling is set in the mission.",
            minimum=0,
        ),
        "endurance_s": time_s(
            "Typical flight or drive time on one battery, in seconds.",
            exclusive_minimum=0,
            maximum=86400,
        ),
        "controls": {
            **array(
                "Controls the airframe physically has; behaviour blocks name these, and the "
                "autopilot's channel map turns each into an RC input and a servo output.",
                string("A control name.", enum=list(CONTROL_NAMES)),
                min_items=1,
            ),
            "uniqueItems": True,
        },
    }


def _airframe_rules() -> list[Schema]:
    rules: list[Schema] = []
    for cls, controls in CONTROLS_BY_CLASS.items():
        rules.append(
            {
                "if": _kind_is("class", cls),
                "then": {"properties": {"controls": {"items": {"enum": list(controls)}}}},
            }
        )
    rules.append(
        {
            "if": _kind_is("class", "fixed_wing"),
            "then": {"properties": {"min_speed_m_s": {"exclusiveMinimum": 0}}},
        }
    )
    rules.append(
        {
            "if": _kind_in("class", ["multirotor", "rover"]),
            "then": {
                "properties": {
                    "min_speed_m_s": {"const": 0},
                    "max_bank_deg": _forbidden(
                        "max_bank_deg applies to fixed wings only; remove it."
                    ),
                }
            },
        }
    )
    rules.append(
        {
            "if": _kind_is("class", "rover"),
            "then": {
                "properties": {
                    "max_climb_rate_m_s": {"const": 0},
                    "max_descent_rate_m_s": {"const": 0},
                    "max_altitude_m": {"const": 0},
                    "wingspan_m": _forbidden("A rover has no wingspan; give length_m instead."),
                }
            },
        }
    )
    return rules


def _serial_connection(*, baud_default: int | None) -> dict[str, Schema]:
    return {
        "device": string(
            "Serial device the part is plugged into, e.g. /dev/ttyACM0 or /dev/ttyUSB0.",
            min_length=1,
        ),
        "baud_bps": integer(
            "Serial line rate, in bits per second; must match the device's own setting.",
            unit="bit/s",
            minimum=1200,
            maximum=4_000_000,
            default=baud_default,
        ),
    }


def _autopilot_connection() -> Schema:
    return _tagged_union(
        "How the mission computer reaches the autopilot's MAVLink stream.",
        {
            "serial": _serial_connection(baud_default=115200),
            "udp": {
                "address": _host_port(
                    "host:port the engine listens on for the autopilot's UDP stream (where "
                    "SITL or a MAVLink router sends it, e.g. 127.0.0.1:14550)."
                )
            },
            "tcp": {
                "address": _host_port(
                    "host:port of the MAVLink TCP server (e.g. 127.0.0.1:5760 for SITL)."
                )
            },
        },
        tag_description="Link type: serial (USB or UART), udp or tcp.",
    )


def _autopilot_properties() -> dict[str, Schema]:
    ids: dict[str, Any] = {"minimum": 1, "maximum": 255}
    mode_name: dict[str, Any] = {
        "pattern": _MODE_NAME_PATTERN,
    }
    return {
        "firmware": string(
            "ArduPilot firmware the autopilot runs; decides the mode numbers and vehicle model.",
            enum=["arduplane", "arducopter", "ardurover"],
        ),
        "connection": _autopilot_connection(),
        "mavlink": obj(
            "MAVLink settings of the link to the autopilot.",
            {
                "version": integer(
                    "MAVLink protocol version to speak.", minimum=1, maximum=2, default=2
                ),
                "system_id": integer(
                    "The autopilot's MAVLink system id (SYSID_THISMAV).", default=1, **ids
                ),
                "component_id": integer(
                    "The autopilot's MAVLink component id (1 = MAV_COMP_ID_AUTOPILOT1).",
                    default=1,
                    **ids,
                ),
                "source_system_id": integer(
                    "System id the engine sends as. Before the behaviour starts the engine "
                    "makes it the autopilot's ground-station id (MAV_GCS_SYSID, SYSID_MYGCS "
                    "before ArduPilot 4.7): ArduPilot takes RC overrides, and counts heartbeats "
                    "for its failsafe, only from that id, so a ground station flying beside "
                    "the engine must use another.",
                    default=255,
                    **ids,
                ),
                "source_component_id": integer(
                    "Component id the engine sends as (191 = MAV_COMP_ID_ONBOARD_COMPUTER).",
                    default=191,
                    **ids,
                ),
                "dialect": string(
                    "MAVLink dialect (pymavlink module name).",
                    enum=["ardupilotmega", "common"],
                    default="ardupilotmega",
                ),
            },
        ),
        "stream_rate_hz": number(
            "Rate the engine requests autopilot telemetry at, in hertz.",
            unit="Hz",
            exclusive_minimum=0,
            maximum=50,
            default=10,
        ),
        "max_stream_rate_hz": number(
            "Highest telemetry rate the autopilot can output, in hertz (Pixhawk: 50).",
            unit="Hz",
            exclusive_minimum=0,
            maximum=400,
            default=50,
        ),
        "wait_ready": boolean(
            "Start the behaviour only once the autopilot reports itself ready: a 3-D GPS fix, "
            "an EKF position, the pre-arm checks passed and a home position.",
            default=True,
        ),
        "safety_setup": boolean(
            "Before the behaviour starts, set the autopilot's own fence from the vehicle's "
            "envelope and its reaction to a dead mission computer (failsafe.computer_lost), "
            "read them back, and start the behaviour only if they took. false is for a bench "
            "autopilot that cannot hold a fence (no GPS): every validation and every run then "
            "warns that the autopilot holds nothing of the envelope.",
            default=True,
        ),
        "heartbeat_timeout_s": number(
            "The autopilot counts as lost after this long without a heartbeat, in seconds.",
            unit="s",
            exclusive_minimum=0,
            maximum=60,
            default=3,
        ),
        "modes": {
            "type": "object",
            "description": "ArduPilot flight-mode name (upper case, as pymavlink names it) -> "
            "custom_mode number of that firmware.",
            "propertyNames": {
                "pattern": _MODE_NAME_PATTERN,
                "description": "A flight-mode name: upper case, as pymavlink names it "
                "(e.g. GUIDED).",
            },
            "additionalProperties": integer(
                "custom_mode number of the mode.", minimum=0, maximum=4_294_967_295
            ),
            "minProperties": 1,
        },
        "guided_mode": string(
            "Mode (a name from `modes`) the engine uses to fly to a commanded position.",
            **mode_name,
        ),
        "hold_mode": string(
            "Mode (a name from `modes`) that holds position or circles in place.", **mode_name
        ),
        "rtl_mode": string("Mode (a name from `modes`) that returns to launch.", **mode_name),
        "land_mode": string(
            "Mode (a name from `modes`) that lands where the vehicle is; the land primitive "
            "needs it (ArduCopter: LAND). Leave it out for firmware that cannot land on the "
            "spot (ArduPlane lands through an AUTO mission; a rover never flies).",
            **mode_name,
        ),
        "terminal_mode": string(
            "Mode (a name from `modes`) the vehicle is put in when the mission terminates.",
            **mode_name,
        ),
        "manual_mode": string(
            "Mode (a name from `modes`) in which the pilot's sticks drive the controls directly.",
            **mode_name,
        ),
        "parameters": {
            "type": "object",
            "description": "ArduPilot parameters this vehicle's autopilot is set up with, where "
            "they differ from the firmware's defaults and matter to how it flies (WP_SPEED, "
            "WPNAV_SPEED, AIRSPEED_CRUISE, ...), in ArduPilot's names and units. The dry run's "
            "simulated autopilot flies with them, and a SITL autopilot (--autopilot sitl) is "
            "set to them before the run; the engine never writes them to a real vehicle.",
            "propertyNames": {
                "pattern": "^[A-Z][A-Z0-9_]{0,15}$",
                "description": "An ArduPilot parameter name (upper case, at most 16 characters).",
            },
            "additionalProperties": number(
                "Its value. ArduPilot keeps parameters as 32-bit floats, which hold every "
                "whole number up to 2^24 exactly; no parameter a profile sets goes beyond.",
                minimum=-PARAMETER_LIMIT,
                maximum=PARAMETER_LIMIT,
            ),
        },
        "rc_channel_count": integer(
            "Number of RC input channels the autopilot reports.",
            minimum=1,
            maximum=18,
            default=16,
        ),
        "servo_channel_count": integer(
            "Number of servo outputs the autopilot drives.", minimum=1, maximum=16, default=16
        ),
        "channels": _channels_schema(
            "Control or switch name -> its RC input, servo output and PWM limits. Names the "
            "airframe lists under `controls` must appear here; switches (e.g. mode_switch) may "
            "be added."
        ),
    }


def _radio_connection() -> Schema:
    return _tagged_union(
        "How the mission computer reaches the radio.",
        {
            "serial": _serial_connection(baud_default=None),
            "udp": {
                "port": integer(
                    "UDP port the radio listens on and sends to on other agents.",
                    minimum=1,
                    maximum=65535,
                    default=14600,
                ),
                "broadcast": string(
                    "IPv4 address that messages to all agents are sent to (the subnet's "
                    "broadcast address; 127.255.255.255 on one machine).",
                    pattern=r"^[0-9]{1,3}(\.[0-9]{1,3}){3}$",
                    default="127.255.255.255",
                ),
            },
        },
        tag_description="Link type: serial (an XBee on USB or UART) or udp.",
    )


def _radio_properties() -> dict[str, Schema]:
    return {
        "link": string(
            "Radio technology: an XBee DigiMesh module, or UDP over a LAN or loopback.",
            enum=["xbee_digimesh", "udp"],
        ),
        "connection": _radio_connection(),
        "address": string(
            "This radio's own address (XBee: 64-bit address in 16 hex digits; UDP: host:port). "
            "Usually set per agent in the mission; it must match `address_pattern`.",
            min_length=1,
        ),
        "address_pattern": {
            **string("Regular expression every agent's radio address must match.", min_length=1),
            "format": "regex",
        },
        "throughput_bps": number(
            "Measured application throughput, in bits per second; the link budget check "
            "compares all agents' telemetry against it. At most 10 Gbit/s.",
            unit="bit/s",
            exclusive_minimum=0,
            maximum=10**10,
        ),
        "max_packet_bytes": integer(
            "Largest payload one packet may carry, in bytes; no ClarkLink bundle may exceed it.",
            unit="byte",
            minimum=1,
            maximum=65507,
        ),
        "frame_overhead_bytes": integer(
            "Bytes the radio adds to each packet on the serial or network side (XBee API "
            "transmit request: 18; IPv4 + UDP headers: 28), in bytes.",
            unit="byte",
            minimum=0,
            maximum=65535,
        ),
        "range_m": _nullable(
            distance_m(
                "Range the mission's waypoints must stay within, from the station, in metres.",
                exclusive_minimum=0,
            ),
            "null or absent: unlimited.",
        ),
        "api_mode": integer(
            "XBee API mode (AP setting): 1 = API without escapes, 2 = API with escapes. "
            "Transparent mode (0) cannot address agents and is not supported.",
            minimum=1,
            maximum=2,
            default=1,
        ),
        "network_id": string(
            "XBee network id (ID setting), hexadecimal; radios only talk within one network.",
            pattern=r"^[0-9A-Fa-f]{1,4}$",
        ),
    }


def _radio_rules() -> list[Schema]:
    return [
        {
            "if": _kind_is("link", "xbee_digimesh"),
            "then": {"properties": {"connection": {"properties": {"kind": {"const": "serial"}}}}},
        },
        {
            "if": _kind_is("link", "udp"),
            "then": {
                "properties": {
                    "connection": {"properties": {"kind": {"const": "udp"}}},
                    "api_mode": _forbidden(
                        "api_mode is an XBee setting; remove it for a udp link."
                    ),
                    "network_id": _forbidden(
                        "network_id is an XBee setting; remove it for a udp link."
                    ),
                }
            },
        },
    ]


def _computer_properties() -> dict[str, Schema]:
    return {
        "max_loop_hz": rate_hz(
            "Measured highest loop rate the engine holds on this computer, in hertz; a "
            "mission's loop_hz must not exceed it.",
            exclusive_minimum=0,
        ),
        "cpu": string("Processor, e.g. '900 MHz quad-core ARM Cortex-A7'.", min_length=1),
        "os": string("Operating system, e.g. 'Raspbian Lite'.", min_length=1),
        "ram_mb": integer(
            "Memory, in mebibytes (at most 1 TiB).", unit="MB", minimum=1, maximum=2**20
        ),
    }


def _payload_connection() -> Schema:
    return _tagged_union(
        "How the mission computer reaches the payload.",
        {
            "tcp": {
                "role": string(
                    "Which side listens: server (the mission computer listens and the payload "
                    "connects, as in the thesis) or client.",
                    enum=["server", "client"],
                    default="server",
                ),
                "address": _host_port(
                    "host:port to listen on (server) or connect to (client).",
                ),
            },
            "udp": {
                "address": _host_port("host:port of the payload's UDP endpoint."),
            },
        },
        tag_description="Link type: tcp or udp.",
    )


def _payload_properties() -> dict[str, Schema]:
    return {
        "payload_kind": string("What the payload is.", enum=["camera", "sensor"]),
        "connection": _payload_connection(),
        "protocol": string(
            "Message format spoken with the payload: ASCII lines.",
            enum=["ascii"],
            default="ascii",
        ),
        "min_interval_s": time_s(
            "Shortest time between two capture requests, in seconds; photo_trigger may not ask "
            "more often.",
            maximum=3600,
        ),
        "capture_delay_s": time_s(
            "Time from a capture request to its confirmation, in seconds.", maximum=3600
        ),
        "resolution_mp": number(
            "Sensor resolution, in megapixels (cameras).",
            unit="MP",
            exclusive_minimum=0,
            maximum=10_000,
        ),
        # A survey's ground footprint: h * sensor / focal length (clark_engine.behaviors.survey).
        "sensor_width_mm": number(
            "Width of the image sensor (the picture's long side, flown across a survey's "
            "lines), in millimetres (cameras); with sensor_height_mm and focal_length_mm it "
            "gives the ground a picture covers.",
            unit="mm",
            exclusive_minimum=0,
            maximum=100,
        ),
        "sensor_height_mm": number(
            "Height of the image sensor (the picture's short side, along a survey's lines), "
            "in millimetres (cameras).",
            unit="mm",
            exclusive_minimum=0,
            maximum=100,
        ),
        "focal_length_mm": number(
            "Focal length of the lens, in millimetres (cameras).",
            unit="mm",
            exclusive_minimum=0,
            maximum=2000,
        ),
    }


def _gui_schema() -> Schema:
    return obj(
        "The operator's live view (mission control station only): where it is served and "
        "when it counts as gone.",
        {
            "address": _host_port(
                "host:port the station serves the operator's view on.",
                default="127.0.0.1:5600",
            ),
            "timeout_s": time_s(
                "The view counts as disconnected after this long without contact, in seconds.",
                exclusive_minimum=0,
                maximum=86400,
                default=5,
            ),
        },
    )


_KIND_PROPERTIES = {
    "airframe": _airframe_properties,
    "autopilot": _autopilot_properties,
    "radio": _radio_properties,
    "computer": _computer_properties,
    "payload": _payload_properties,
}


def _override_properties(kind: str) -> dict[str, Schema]:
    """Return the keys a reference may override on a part of ``kind``: its own keys."""
    if kind == "platform":
        raise ValueError("a platform is not a part of another platform")
    try:
        return _KIND_PROPERTIES[kind]()
    except KeyError:
        raise ValueError(f"unknown profile kind {kind!r}; expected one of {KINDS}") from None


def part_reference_schema(kind: str, *, require_profile: bool = True) -> Schema:
    """Return the schema of a part reference: a name, or ``{profile: NAME, ...overrides}``.

    The overrides are any of that kind's keys; the engine deep-merges them onto the
    named profile. The returned schema is self-contained, so the mission schema can
    embed it.

    Args:
        kind: The part's kind: airframe, autopilot, radio, computer or payload.
        require_profile: Whether the mapping form must name ``profile``. True in a
            platform; False for a mission's per-agent ``hardware:`` overrides, where
            the mapping changes the platform's part and ``profile`` swaps it.

    Returns:
        A JSON Schema accepting either form.

    Raises:
        ValueError: ``kind`` is not a part kind.

    """
    overrides = _override_properties(kind)
    mapping = obj(
        f"The {kind} profile named by `profile`, with these keys deep-merged onto it.",
        {
            "profile": _profile_name(f"Name of the {kind} profile to use."),
            **overrides,
        },
        required=["profile"] if require_profile else None,
    )
    del mapping["type"]  # the type is checked once, by the string-or-mapping rule below
    return {
        "type": ["string", "object"],
        "description": f"{_article(kind).capitalize()} {kind}: its profile name, or a mapping "
        "with `profile:` and the keys to change on it.",
        "if": {"type": "string"},
        "then": _profile_name(f"Name of the {kind} profile to use."),
        "else": mapping,
    }


def _payloads_schema(*, require_profile: bool) -> Schema:
    return {
        "type": "object",
        "description": "Payload name (what behaviours call it, e.g. camera) -> its payload "
        "profile, by name or with overrides.",
        "propertyNames": {
            "pattern": NAME_PATTERN,
            "description": "A payload name: lower-case letters, digits and _, starting with a "
            "letter.",
        },
        "additionalProperties": part_reference_schema("payload", require_profile=require_profile),
    }


def _platform_properties() -> dict[str, Schema]:
    return {
        "role": string(
            "vehicle (flies or drives, with an autopilot) or mcs (the mission control station).",
            enum=["vehicle", "mcs"],
        ),
        **{kind: part_reference_schema(kind) for kind in PART_KINDS},
        "payloads": _payloads_schema(require_profile=True),
        "channels": _channels_schema(
            "Channel entries for this build, merged key by key onto the autopilot's channel "
            "map (change a limit, add a switch, or null a servo output a mixer owns)."
        ),
        "gui": _gui_schema(),
    }


def _platform_rules() -> list[Schema]:
    return [
        {
            "if": _kind_is("role", "mcs"),
            "then": {
                "properties": {
                    "airframe": _forbidden(
                        "A mission control station (role mcs) has no airframe; remove it."
                    ),
                    "autopilot": _forbidden(
                        "A mission control station (role mcs) has no autopilot; remove it."
                    ),
                }
            },
        },
        {
            "if": _kind_is("role", "vehicle"),
            "then": {
                "properties": {
                    "gui": _forbidden(
                        "Only a mission control station (role mcs) serves the operator's view; "
                        "remove gui or set role: mcs."
                    )
                }
            },
        },
    ]


def part_override_schema(kind: str) -> Schema:
    """Return the schema of per-agent changes to one part: a mapping of that kind's keys.

    The engine deep-merges it onto the part the agent's platform resolved. Unlike a
    part reference it names no ``profile``: an agent changes its platform's parts,
    and flies a different part by naming a different platform. Self-contained.

    Args:
        kind: The part's kind: airframe, autopilot, radio, computer or payload.

    Returns:
        A JSON Schema for the mapping.

    Raises:
        ValueError: ``kind`` is not a part kind.

    """
    return obj(
        f"Changes to this agent's {kind}, deep-merged onto the one its platform names.",
        _override_properties(kind),
    )


def agent_hardware_schema() -> Schema:
    """Return the schema of an agent's ``hardware:`` key: per-agent changes to its platform.

    Each part (``airframe``, ``autopilot``, ``radio``, ``computer``) takes a mapping of
    changes deep-merged onto the platform's resolved part. ``payloads`` takes, per
    payload name, changes to the platform's payload of that name, or a part reference
    (a profile name or ``{profile: NAME, ...}``) that replaces it or adds a payload.
    ``channels`` merges onto the platform's channel map. Self-contained, for embedding
    in the mission schema.

    Returns:
        A JSON Schema for the ``hardware:`` mapping.

    """
    return obj(
        "Changes to this agent's platform, deep-merged onto its resolved parts (e.g. the "
        "autopilot's serial device or this radio's address).",
        {
            **{kind: part_override_schema(kind) for kind in PART_KINDS},
            "payloads": _payloads_schema(require_profile=False),
            "channels": _channels_schema(
                "Channel entries merged key by key onto the platform's channel map."
            ),
        },
    )


def _kind_fields(kind: str) -> Schema:
    """Return the keys a ``kind`` profile may have beyond the common ones, and their rules."""
    builders = {**_KIND_PROPERTIES, "platform": _platform_properties}
    rules = {
        "airframe": _airframe_rules,
        "radio": _radio_rules,
        "platform": _platform_rules,
    }
    out: Schema = {
        "description": f"Keys of a {kind} profile.",
        "properties": builders[kind](),
    }
    if kind in rules:
        out["allOf"] = rules[kind]()
    return out


def _kind_keys(kind: str) -> list[str]:
    """Return the names of the keys a ``kind`` profile may have beyond the common ones."""
    return list(_kind_fields(kind)["properties"])


def _kind_complete(kind: str) -> Schema:
    """Return what a merged, non-abstract profile of ``kind`` must contain."""
    needed: Schema = {"required": list(REQUIRED_AFTER_MERGE[kind])}
    nested: dict[str, Schema] = {}
    if kind == "autopilot":
        nested["connection"] = _tagged_union_complete(
            "kind", {"serial": ["device", "baud_bps"], "udp": ["address"], "tcp": ["address"]}
        )
    elif kind == "radio":
        nested["connection"] = _tagged_union_complete(
            "kind", {"serial": ["device", "baud_bps"], "udp": ["port"]}
        )
    elif kind == "payload":
        nested["connection"] = _tagged_union_complete(
            "kind", {"tcp": ["address"], "udp": ["address"]}
        )
    if nested:
        needed["properties"] = nested
    if kind == "platform":
        needed["allOf"] = [
            {"if": _kind_is("role", "vehicle"), "then": {"required": list(PART_KINDS)}},
            {"if": _kind_is("role", "mcs"), "then": {"required": ["radio", "computer"]}},
        ]
    return {
        "description": f"A merged {kind} profile that an agent can use is complete.",
        "if": {"properties": {"abstract": {"const": True}}, "required": ["abstract"]},
        "else": needed,
    }


def _defs() -> dict[str, Schema]:
    defs: dict[str, Schema] = {"channel": _channel_schema()}
    for kind in KINDS:
        defs[kind] = _kind_fields(kind)
        defs[f"{kind}_complete"] = _kind_complete(kind)
    return defs


# --------------------------------------------------------------------------- documents


def build() -> dict[str, Any]:
    """Return the schema of one hardware-profile file, of any kind.

    Returns:
        A JSON Schema 2020-12 document. The common keys are in ``properties``; each
        kind's keys are selected by ``kind`` through if/then, and
        ``unevaluatedProperties: false`` rejects any key the file's kind does not have.

    """
    branches: list[Schema] = []
    for kind in KINDS:
        branches.append({"if": _kind_is("kind", kind), "then": {"$ref": f"#/$defs/{kind}"}})
        branches.append({"if": _kind_is("kind", kind), "then": _allow(_kind_keys(kind))})
    # Without a valid kind no key set applies: accept the rest so the one error
    # reported is the kind's, not one per key.
    branches.append({"if": _kind_in("kind", list(KINDS)), "else": {"additionalProperties": True}})
    return {
        "$schema": DIALECT,
        "$id": schema_id("hardware-profile"),
        "title": "Clark Engine hardware profile",
        "description": "One part a vehicle or station is built from (airframe, autopilot, "
        "radio, mission computer, payload) or a platform composing them. A file may extend "
        "another profile of its kind and state only what differs, so nothing kind-specific "
        "is required here; the engine checks completeness after merging.",
        "type": "object",
        "properties": _common_properties(),
        "required": ["profile", "kind", "description"],
        "allOf": branches,
        "unevaluatedProperties": False,
        "$defs": _defs(),
    }


def kind_schema(kind: str) -> dict[str, Any]:
    """Return the schema of a merged profile of one kind, with the keys it must then have.

    The engine applies it after deep-merging a profile onto its ``extends`` chain
    (and a part onto a platform's and an agent's changes). The common keys are
    allowed but not required, so the merged data may be checked with or without
    them. An ``abstract`` profile is exempt from the completeness requirements.

    Args:
        kind: One of :data:`KINDS`.

    Returns:
        A JSON Schema 2020-12 document with the same ``$defs`` as :func:`build`.

    Raises:
        ValueError: ``kind`` is not a profile kind.

    """
    if kind not in KINDS:
        raise ValueError(f"unknown profile kind {kind!r}; expected one of {', '.join(KINDS)}")
    return {
        "$schema": DIALECT,
        "$id": schema_id(f"hardware-profile-{kind}"),
        "title": f"Clark Engine {kind} profile, merged",
        "description": f"{_article(kind).capitalize()} {kind} profile after its `extends` "
        "chain is merged.",
        "type": "object",
        "properties": _common_properties(kind=kind),
        "allOf": [
            {"$ref": f"#/$defs/{kind}"},
            _allow(_kind_keys(kind)),
            {"$ref": f"#/$defs/{kind}_complete"},
        ],
        "unevaluatedProperties": False,
        "$defs": _defs(),
    }
