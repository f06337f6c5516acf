"""JSON Schema source of each part kind's keys: airframe, autopilot, radio, computer, payload.

Why separate: :mod:`.hardware_profile` assembles the profile documents (a file of any kind,
a merged profile of one kind, the platform that composes parts, a mission's overrides);
what each part declares (its keys with their types, units and ranges, and the rules
between them) is a table of facts per part, kept here, one builder per kind, with the
autopilot's channel map (:data:`CHANNEL_SCHEMA`) that platforms and missions override.
"""

from __future__ import annotations

from typing import Any

from clark_engine.mission.schema_source.common import (
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
    string,
    time_s,
)
from clark_engine.mission.schema_source.profile_common import (
    forbidden,
    host_port,
    kind_in,
    kind_is,
    nullable,
    tagged_union,
)

#: Largest magnitude of an ArduPilot parameter a profile sets: 2^24, the largest whole
#: number a 32-bit float (how ArduPilot stores parameters) holds exactly.
PARAMETER_LIMIT = 2**24

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

_PWM_MIN_US = 800
_PWM_MAX_US = 2200
_MODE_NAME_PATTERN = r"^[A-Z][A-Z0-9_]*$"


def channel_schema() -> Schema:
    """One control or switch channel of an autopilot (the schema's ``channel`` definition)."""
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
            "rc": nullable(
                integer("RC input channel number (RCn, 1-18).", minimum=1, maximum=18),
                "null: this control has no RC input of its own.",
            ),
            "servo": nullable(
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
CHANNEL_SCHEMA: Schema = channel_schema()


def channels_schema(description: str) -> Schema:
    """A channel map: channel name -> its channel (:func:`channel_schema`)."""
    return {
        "type": "object",
        "description": description,
        "propertyNames": {
            "pattern": NAME_PATTERN,
            "description": "A channel name: lower-case letters, digits and _, starting with a "
            "letter.",
        },
        "additionalProperties": channel_schema(),
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


def airframe_rules() -> list[Schema]:
    """The rules between an airframe's keys: the controls its class can have."""
    rules: list[Schema] = []
    for cls, controls in CONTROLS_BY_CLASS.items():
        rules.append(
            {
                "if": kind_is("class", cls),
                "then": {"properties": {"controls": {"items": {"enum": list(controls)}}}},
            }
        )
    rules.append(
        {
            "if": kind_is("class", "fixed_wing"),
            "then": {"properties": {"min_speed_m_s": {"exclusiveMinimum": 0}}},
        }
    )
    rules.append(
        {
            "if": kind_in("class", ["multirotor", "rover"]),
            "then": {
                "properties": {
                    "min_speed_m_s": {"const": 0},
                    "max_bank_deg": forbidden(
                        "max_bank_deg applies to fixed wings only; remove it."
                    ),
                }
            },
        }
    )
    rules.append(
        {
            "if": kind_is("class", "rover"),
            "then": {
                "properties": {
                    "max_climb_rate_m_s": {"const": 0},
                    "max_descent_rate_m_s": {"const": 0},
                    "max_altitude_m": {"const": 0},
                    "wingspan_m": forbidden("A rover has no wingspan; give length_m instead."),
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
    return tagged_union(
        "How the mission computer reaches the autopilot's MAVLink stream.",
        {
            "serial": _serial_connection(baud_default=115200),
            "udp": {
                "address": host_port(
                    "host:port the engine listens on for the autopilot's UDP stream (where "
                    "SITL or a MAVLink router sends it, e.g. 127.0.0.1:14550)."
                )
            },
            "tcp": {
                "address": host_port(
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
        "channels": channels_schema(
            "Control or switch name -> its RC input, servo output and PWM limits. Names the "
            "airframe lists under `controls` must appear here; switches (e.g. mode_switch) may "
            "be added."
        ),
    }


def _radio_connection() -> Schema:
    return tagged_union(
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
        "range_m": nullable(
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


def radio_rules() -> list[Schema]:
    """The rules between a radio's keys, by its link."""
    return [
        {
            "if": kind_is("link", "xbee_digimesh"),
            "then": {"properties": {"connection": {"properties": {"kind": {"const": "serial"}}}}},
        },
        {
            "if": kind_is("link", "udp"),
            "then": {
                "properties": {
                    "connection": {"properties": {"kind": {"const": "udp"}}},
                    "api_mode": forbidden("api_mode is an XBee setting; remove it for a udp link."),
                    "network_id": forbidden(
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
    return tagged_union(
        "How the mission computer reaches the payload.",
        {
            "tcp": {
                "role": string(
                    "Which side listens: server (the mission computer listens and the payload "
                    "connects, as in the thesis) or client.",
                    enum=["server", "client"],
                    default="server",
                ),
                "address": host_port(
                    "host:port to listen on (server) or connect to (client).",
                ),
            },
            "udp": {
                "address": host_port("host:port of the payload's UDP endpoint."),
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


KIND_PROPERTIES = {
    "airframe": _airframe_properties,
    "autopilot": _autopilot_properties,
    "radio": _radio_properties,
    "computer": _computer_properties,
    "payload": _payload_properties,
}
