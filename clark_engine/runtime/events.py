"""Typed events the runtime core receives from its shells.

The core never reads a device: the shells (a real-time loop on a mission
computer, or the simulator) turn bytes into these events and hand them to
``AgentRuntime.deliver`` with the time they arrived. Units are in the names;
angles in degrees, positions in degrees and metres above the mission origin.
"""

from __future__ import annotations

from dataclasses import dataclass


@dataclass(frozen=True, slots=True)
class VehicleState:
    """The autopilot's latest state (thesis 7.1.2: GPS time, position, velocity, heading, mode).

    Attributes:
        gps_time_ms: GPS time from the autopilot (SYSTEM_TIME), None before a fix.
        lat_deg: Latitude.
        lon_deg: Longitude.
        alt_m: Altitude above the mission origin.
        ground_speed_m_s: Horizontal speed.
        climb_rate_m_s: Vertical speed, positive up.
        heading_deg: Course over ground, 0 <= heading < 360.
        roll_deg: Roll, positive right wing down.
        pitch_deg: Pitch, positive nose up.
        yaw_deg: Yaw.
        mode: Flight mode name in the autopilot's firmware (``GUIDED``).
        custom_mode: The same mode's number.
        armed: True when the motors are armed.
    """

    gps_time_ms: int | None
    lat_deg: float
    lon_deg: float
    alt_m: float
    ground_speed_m_s: float
    climb_rate_m_s: float
    heading_deg: float
    roll_deg: float
    pitch_deg: float
    yaw_deg: float
    mode: str
    custom_mode: int
    armed: bool


@dataclass(frozen=True, slots=True)
class AutopilotHeartbeat:
    """The autopilot is alive (MAVLink HEARTBEAT); silence for 3 s raises autopilot_lost."""

    mode: str
    custom_mode: int
    armed: bool


@dataclass(frozen=True, slots=True)
class RcChannels:
    """RC input pulse widths as the autopilot reports them (RC_CHANNELS).

    Attributes:
        pwm_us: Pulse width per channel; index 0 is channel 1; 0 means no signal.
    """

    pwm_us: tuple[int, ...]


@dataclass(frozen=True, slots=True)
class PacketReceived:
    """Bytes that arrived on the radio, before any decoding or authentication."""

    data: bytes


@dataclass(frozen=True, slots=True)
class PayloadEvent:
    """Something a payload reported (the thesis's camera sent ASCII strings over TCP).

    Attributes:
        payload: The payload's name on this agent (``camera``).
        kind: ``captured`` (a picture was taken), ``refused`` (too soon after the last),
            or ``error``.
        request_id: The capture request this answers.
        detail: Free text from the payload (file name, error text).
    """

    payload: str
    kind: str
    request_id: int
    detail: str = ""


@dataclass(frozen=True, slots=True)
class StationCommand:
    """An operator's command at the station (the thesis's GUI, requirements 5.2.3-5.2.5).

    Attributes:
        action: ``activate``, ``deactivate``, ``mode`` or ``terminate``.
        target: Agent name; ``""`` means every agent.
        mode: Mode name, for ``mode``.
    """

    action: str
    target: str = ""
    mode: str = ""


Event = (
    VehicleState | AutopilotHeartbeat | RcChannels | PacketReceived | PayloadEvent | StationCommand
)
