"""ClarkLink messages as the engine sees them: plain dataclasses in engineering units.

The wire form is Protocol Buffers (``clarklink.proto``, compiled into
``_generated/``); only :mod:`clark_engine.link.wire` translates between the two,
so no other module ever touches a ``_pb2`` object. Units are in the field
names. On the wire, positions are quantised to 1e-7 degrees, altitudes to
millimetres, speeds to cm/s and angles to centidegrees: a decoded message
equals the sent one to within that resolution.

The set is the thesis's Table 3.4 (Heartbeat, Agent Status, Picture Data, Mode
Change Request, Activate Controller, Agent Attitude) plus what the engine needs:
Terminate, and Behavior State for the station's view. Every message carries the
sending agent's id and the GPS time at which it was packed.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from enum import IntEnum

#: Version of the message set; Heartbeat carries it so peers can tell.
CLARKLINK_VERSION = 6  # the thesis's Clark Link was version 5


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


Message = (
    Heartbeat
    | AgentStatus
    | PictureData
    | ModeChangeRequest
    | ActivateController
    | AgentAttitude
    | Terminate
    | BehaviorState
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
}

#: Messages that command another agent: never acted on unless authenticated
#: (when the mission has a key) and from the same mission.
COMMANDS: tuple[type, ...] = (ModeChangeRequest, ActivateController, Terminate)
