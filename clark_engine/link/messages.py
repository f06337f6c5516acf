"""ClarkLink messages as the engine sees them: plain dataclasses in engineering units.

The wire form is Protocol Buffers (``clarklink.proto``, compiled into
``_generated/``); only :mod:`clark_engine.link.wire` translates between the two,
so no other module ever touches a ``_pb2`` object. Units are in the field
names. On the wire, positions are quantised to 1e-7 degrees, altitudes to
millimetres, speeds to cm/s and angles to centidegrees: a decoded message
equals the sent one to within that resolution.

The set is the thesis's Table 3.4 (Heartbeat, Agent Status, Picture Data, Mode
Change Request, Activate Controller, Agent Attitude) plus what the engine needs:
Terminate, Behavior State for the station's view, and Vehicle Health (armed, battery,
GPS, pre-arm, the autopilot's latest warning, the failsafe in force) for the station to
see safety. Every message carries the sending agent's id and the GPS time at which it
was packed.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from enum import IntEnum

#: Version of the message set; Heartbeat carries it so peers can tell.
CLARKLINK_VERSION = 7  # the thesis's Clark Link was version 5; 7 added Vehicle Health

MAX_HEALTH_TEXT_BYTES = 50
"""Longest autopilot text Vehicle Health carries, in UTF-8 bytes: one STATUSTEXT chunk."""

MAX_FAILSAFE_TEXT_BYTES = 32
"""Longest failsafe description Vehicle Health carries, in UTF-8 bytes (``rtl: mcs_lost``)."""

MAX_SEVERITY_SENT = 4
"""Vehicle Health carries the autopilot's texts of this MAV_SEVERITY or worse (WARNING)."""


class AgentType(IntEnum):
    """What kind of agent sends a heartbeat."""

    VEHICLE = 1
    MCS = 2


class Condition(IntEnum):
    """An agent's own view of its health, sent in every heartbeat."""

    OK = 1
    DEGRADED = 2  # an interface is down or a peer is lost, but the agent still runs
    FAILSAFE = 3  # a failsafe action is in progress
    TERMINATED = 4  # the agent has terminated and commands nothing


class PrearmState(IntEnum):
    """The autopilot's pre-arm checks as SYS_STATUS reports them (Vehicle Health)."""

    UNKNOWN = 1  # no SYS_STATUS yet, or the autopilot does not report its pre-arm checks
    PASSING = 2
    FAILING = 3


def fit_text(text: str, max_bytes: int) -> str:
    """``text`` cut to at most ``max_bytes`` of UTF-8, at a character boundary.

    What an agent puts in a bounded text field of a message (Vehicle Health's): the
    autopilot's text is untrusted and may hold anything, so characters that UTF-8
    cannot encode (lone surrogates) become ``?`` first; nothing else is changed.
    Escaping is the business of whoever shows it.
    """
    data = text.encode("utf-8", errors="replace")  # a lone surrogate becomes "?"
    if len(data) <= max_bytes:
        return data.decode("utf-8")
    return data[:max_bytes].decode("utf-8", errors="ignore")  # drops a cut character


@dataclass(frozen=True, slots=True)
class Heartbeat:
    """Presence and identity; peers add an agent to their fleet table on its first one."""

    agent_id: int
    gps_time_ms: int
    mission_id: int
    agent_type: AgentType
    condition: Condition = Condition.OK
    payload_count: int = 0
    clarklink_version: int = CLARKLINK_VERSION


@dataclass(frozen=True, slots=True)
class AgentStatus:
    """Where an agent is and what its autopilot is doing (thesis Table 3.4)."""

    agent_id: int
    gps_time_ms: int
    lat_deg: float
    lon_deg: float
    alt_m: float  # above the mission origin
    ground_speed_m_s: float
    climb_rate_m_s: float
    heading_deg: float  # 0 <= heading < 360, clockwise from true north
    mode: int  # the autopilot's custom_mode number (names are in the sender's profile)


@dataclass(frozen=True, slots=True)
class PictureData:
    """A picture was taken: where, and which one (the capture time is gps_time_ms)."""

    agent_id: int
    gps_time_ms: int
    lat_deg: float
    lon_deg: float
    alt_m: float
    image_index: int


@dataclass(frozen=True, slots=True)
class ModeChangeRequest:
    """The station asks one agent's autopilot to change mode."""

    agent_id: int  # the sender (normally the station)
    gps_time_ms: int
    target_id: int
    mode: int  # custom_mode number in the target's firmware


@dataclass(frozen=True, slots=True)
class ActivateController:
    """The station switches an agent's controller on or off (events activate/deactivate)."""

    agent_id: int
    gps_time_ms: int
    target_id: int  # 0 means every agent
    active: bool
    start_time_ms: int = 0  # GPS time to act at; 0 means at once
    option: int = 0  # the thesis's "optional field", free for the mission's use


@dataclass(frozen=True, slots=True)
class AgentAttitude:
    """Roll, pitch and yaw of an agent."""

    agent_id: int
    gps_time_ms: int
    roll_deg: float
    pitch_deg: float
    yaw_deg: float


@dataclass(frozen=True, slots=True)
class Terminate:
    """End the mission: every target stops commanding and goes to its terminal mode."""

    agent_id: int
    gps_time_ms: int
    target_id: int = 0  # 0 means every agent
    reason: str = ""


@dataclass(frozen=True, slots=True)
class BehaviorState:
    """Which states of an agent's behaviour are active, for the station's view."""

    agent_id: int
    gps_time_ms: int
    active_states: tuple[str, ...] = field(default_factory=tuple)  # dotted paths
    last_event: str = ""


@dataclass(frozen=True, slots=True)
class VehicleHealth:
    """A vehicle's health as its runtime sees it, for the station (issue 17).

    Agent Status stays as the thesis defined it; this is what an operator needs besides
    to judge whether a vehicle is safe to fly and still safe: whether it is armed, its
    battery, its GPS, its autopilot's pre-arm checks and latest warning, and the
    failsafe its runtime has applied. Vehicles send it (the telemetry key
    ``vehicle_health``); a station has no autopilot and sends none.

    ``text`` and ``failsafe`` are bounded on both ends (:data:`MAX_HEALTH_TEXT_BYTES`,
    :data:`MAX_FAILSAFE_TEXT_BYTES` of UTF-8: the sender cuts with :func:`fit_text`, the
    encoder refuses longer, the decoder rejects longer) and untrusted: whoever shows them
    escapes them.
    """

    agent_id: int
    gps_time_ms: int
    armed: bool = False
    battery_v: float | None = None  # None: the autopilot does not measure it
    battery_pct: int | None = None  # remaining charge, 0..100; None: unknown
    gps_fix_type: int = 0  # MAVLink GPS_FIX_TYPE: 0 no GPS, 1 no fix, 2 2-D, 3 3-D, ... 8
    satellites: int | None = None  # satellites visible; None: unknown
    prearm: PrearmState = PrearmState.UNKNOWN
    text_severity: int = 0  # MAV_SEVERITY of ``text`` (0..4); 0 when there is no text
    text: str = ""  # the autopilot's latest STATUSTEXT of WARNING or worse; "" when none
    failsafe: str = ""  # the failsafe in force and why (``hold: mcs_lost``); "" when none
    autopilot_lost: bool = False  # the runtime has not heard its autopilot for its timeout
    text_age_s: int = 0  # whole seconds since ``text`` arrived; 0 when there is no text


Message = (
    Heartbeat
    | AgentStatus
    | PictureData
    | ModeChangeRequest
    | ActivateController
    | AgentAttitude
    | Terminate
    | BehaviorState
    | VehicleHealth
)

#: Message class -> the name used in missions' telemetry and in logs.
MESSAGE_NAMES: dict[type, str] = {
    Heartbeat: "heartbeat",
    AgentStatus: "agent_status",
    PictureData: "picture_data",
    ModeChangeRequest: "mode_change_request",
    ActivateController: "activate_controller",
    AgentAttitude: "agent_attitude",
    Terminate: "terminate",
    BehaviorState: "behavior_state",
    VehicleHealth: "vehicle_health",
}

#: Messages that command another agent: never acted on unless authenticated
#: (when the mission has a key) and from the same mission.
COMMANDS: tuple[type, ...] = (ModeChangeRequest, ActivateController, Terminate)
