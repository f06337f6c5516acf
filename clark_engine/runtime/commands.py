"""Typed commands the runtime core emits for its shells to carry out.

``AgentRuntime.tick`` (and ``deliver``) return these; the shells turn them into
MAVLink, radio frames and payload requests. Nothing here knows a wire format.
"""

from __future__ import annotations

from dataclasses import dataclass, field


@dataclass(frozen=True, slots=True)
class Goto:
    """Fly or drive to a position in guided mode (SET_POSITION_TARGET_GLOBAL_INT).

    Attributes:
        lat_deg: Target latitude.
        lon_deg: Target longitude.
        alt_m: Target altitude above the mission origin (ignored by rovers).
        speed_m_s: Requested ground speed, None for the autopilot's own.
        velocity_north_m_s: The target's own velocity north, for a target that moves
            (ArduCopter flies it as a position and velocity target); None: a fixed point.
        velocity_east_m_s: The target's own velocity east.
    """

    lat_deg: float
    lon_deg: float
    alt_m: float
    speed_m_s: float | None = None
    velocity_north_m_s: float | None = None
    velocity_east_m_s: float | None = None


@dataclass(frozen=True, slots=True)
class SetMode:
    """Change the autopilot's flight mode."""

    mode: str
    custom_mode: int


@dataclass(frozen=True, slots=True)
class Arm:
    """Arm or disarm the motors (MAV_CMD_COMPONENT_ARM_DISARM).

    ArduPilot runs its arming checks first and refuses with its reason (a
    ``PreArm:`` text) when one fails; the engine never forces an arm.
    """

    armed: bool = True


@dataclass(frozen=True, slots=True)
class Takeoff:
    """Take off and climb to ``alt_m`` above home (MAV_CMD_NAV_TAKEOFF).

    ArduCopter takes it in the guided mode, armed and on the ground; the takeoff
    primitive sees to those.
    """

    alt_m: float


@dataclass(frozen=True, slots=True)
class SetServo:
    """Drive one servo output directly (MAV_CMD_DO_SET_SERVO); for outputs with no function."""

    servo: int
    pwm_us: int


@dataclass(frozen=True, slots=True)
class RcOverride:
    """Override RC inputs (RC_CHANNELS_OVERRIDE); channel -> pulse width, 0 releases it."""

    pwm_us: dict[int, int] = field(default_factory=dict)


@dataclass(frozen=True, slots=True)
class PayloadCommand:
    """Ask a payload to act; for a camera, ``capture`` takes one picture."""

    payload: str
    action: str
    request_id: int


@dataclass(frozen=True, slots=True)
class SendPacket:
    """Put one encoded ClarkLink packet on the radio.

    Attributes:
        data: The packet's bytes.
        destination: Agent name, ``""`` for broadcast.
        destination_id: Agent id, 0 for broadcast.
        radio_address: The destination's radio address when the mission gives one.
    """

    data: bytes
    destination: str = ""
    destination_id: int = 0
    radio_address: str | None = None


@dataclass(frozen=True, slots=True)
class CloseInterfaces:
    """Terminate: close the autopilot, radio and payload connections (thesis 7.3.5)."""


Command = (
    Goto
    | SetMode
    | Arm
    | Takeoff
    | SetServo
    | RcOverride
    | PayloadCommand
    | SendPacket
    | CloseInterfaces
)
