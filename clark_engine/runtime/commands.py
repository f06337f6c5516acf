"""Typed commands the runtime core emits for its shells to carry out.

``AgentRuntime.tick`` (and ``deliver``) return these; the shells turn them into
MAVLink, radio frames and payload requests. Nothing here knows a wire format.
"""

from __future__ import annotations

from collections.abc import Iterable
from dataclasses import dataclass, field
from typing import get_args


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
        loiter_radius_m: For ArduPlane, the radius to circle the target at
            (DO_REPOSITION's param3: kept by ArduPlane for later targets until GUIDED is
            entered again); None for WP_LOITER_RAD. Other firmware ignore it.
        loiter_ccw: For ArduPlane, circle it counter-clockwise (DO_REPOSITION's param4).
    """

    lat_deg: float
    lon_deg: float
    alt_m: float
    speed_m_s: float | None = None
    velocity_north_m_s: float | None = None
    velocity_east_m_s: float | None = None
    loiter_radius_m: float | None = None
    loiter_ccw: bool = False


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
class SetParam:
    """One autopilot parameter the safety set-up writes, then reads back.

    Attributes:
        names: The parameter's name, then the names older ArduPilot versions give it,
            newest first. With more than one, each is read first and the first the
            autopilot answers to is the one set.
        value: The value, in the parameter's own unit (RTL_ALT in centimetres). For an
            integer parameter, a whole number: ArduPilot truncates.
        at_most: Only lower the parameter: it is read first, and left as it is when it
            already reads ``value`` or less (a return altitude chosen under the ceiling).
    """

    names: tuple[str, ...]
    value: float
    at_most: bool = False

    @property
    def name(self) -> str:
        """The newest of its names."""
        return self.names[0]


@dataclass(frozen=True, slots=True)
class FenceZone:
    """One zone of the autopilot's own fence, uploaded in its fence list.

    Attributes:
        inclusion: True for a zone the vehicle stays inside, False for one it keeps out of.
        corners_deg: A polygon's corners in order, as (latitude, longitude); empty for a
            circle.
        center_deg: A circle's centre (latitude, longitude); None for a polygon.
        radius_m: A circle's radius.
    """

    inclusion: bool
    corners_deg: tuple[tuple[float, float], ...] = ()
    center_deg: tuple[float, float] | None = None
    radius_m: float = 0.0


@dataclass(frozen=True, slots=True)
class UploadFence:
    """Replace the autopilot's fence list with these zones (none: clear it).

    ArduPilot keeps its inclusion and exclusion zones in a list of its own, uploaded
    with the MAVLink mission protocol (MAV_MISSION_TYPE_FENCE).
    """

    zones: tuple[FenceZone, ...] = ()


@dataclass(frozen=True, slots=True)
class MissionItem:
    """One item of a mission for the autopilot to fly in its AUTO mode.

    Attributes:
        kind: ``waypoint`` (fly to the position, MAV_CMD_NAV_WAYPOINT) or ``speed``
            (change the speed from here on, MAV_CMD_DO_CHANGE_SPEED, no position).
        lat_deg: A waypoint's latitude.
        lon_deg: A waypoint's longitude.
        alt_m: A waypoint's altitude above the mission origin (the engine's one datum;
            the adapter converts it to the autopilot's frame).
        speed_m_s: A speed item's speed: ground speed, airspeed for ArduPlane.
    """

    kind: str
    lat_deg: float = 0.0
    lon_deg: float = 0.0
    alt_m: float = 0.0
    speed_m_s: float = 0.0

    @property
    def navigates(self) -> bool:
        """True for an item the vehicle flies to (a position the envelope must judge)."""
        return self.kind == "waypoint"


@dataclass(frozen=True, slots=True)
class UploadMission:
    """Replace the autopilot's mission with these items, to fly in AUTO.

    ArduPilot keeps the mission in a list uploaded with the MAVLink mission protocol
    (MAV_MISSION_TYPE_MISSION); its item 0 is home, which the adapter fills in. The
    adapter answers with a :class:`~clark_engine.runtime.events.MissionUploadResult`
    carrying ``upload_id``, and reports the mission's progress as
    :class:`~clark_engine.runtime.events.MissionProgress`, counted in these items. The
    runtime's envelope guard judges every waypoint first and refuses the whole upload
    when one is outside (never half a mission).

    Attributes:
        upload_id: The behaviour's id for this upload (``PrimitiveContext.next_request_id``).
        items: The mission, in order.
        what: What the mission is, in words, for the logs (``survey field: 3 lines``).
    """

    upload_id: int
    items: tuple[MissionItem, ...]
    what: str = ""


@dataclass(frozen=True, slots=True)
class Pause:
    """Wait before the next step of a safety set-up.

    The autopilot acts on some changes only in a loop of its own (ArduPilot applies a
    FENCE_ENABLE change at 10 Hz).

    Attributes:
        seconds: How long.
    """

    seconds: float


@dataclass(frozen=True, slots=True)
class SetUpAutopilotSafety:
    """Set the autopilot's own fence and its reaction to a dead mission computer.

    The runtime issues it once, when the autopilot is ready and before the behaviour
    starts (docs/safety.md#held-by-the-autopilot); the adapter answers with an
    :class:`~clark_engine.runtime.events.AutopilotSafetyResult`. The adapter carries it
    out in order, each step once the one before it took, and stops at the first that
    does not:

    1. ``gcs_id_names``: the parameter naming whose heartbeat the autopilot's
       ground-station failsafe watches is set to the adapter's own MAVLink system id
       (a heartbeat follows at once), so that the mission computer's silence is what
       the failsafe reacts to.
    2. ``steps``: parameters set and read back, the fence list uploaded, and pauses, in
       order.

    Attributes:
        gcs_id_names: That parameter's names, newest first (MAV_GCS_SYSID, then
            SYSID_MYGCS before ArduPilot 4.7); empty to leave it.
        steps: What to set, in order.
        on_close: Parameters written as the engine leaves on purpose (a clean stop): the
            ground-station failsafe is turned off, since the engine's departure then is
            no loss. Sent once, not read back.
        summary: What it sets up, in words, for the logs.
    """

    gcs_id_names: tuple[str, ...]
    steps: tuple[SetParam | UploadFence | Pause, ...]
    on_close: tuple[SetParam, ...] = ()
    summary: str = ""


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
    | SetUpAutopilotSafety
    | UploadMission
    | CloseInterfaces
)

#: Every type of :data:`Command`: what each shell's dispatch must cover, exactly.
COMMAND_TYPES: frozenset[type] = frozenset(get_args(Command))

#: The commands the autopilot adapter carries out (MAVLink to the autopilot); the others
#: are the radio's (SendPacket), a payload's (PayloadCommand) or the shell's own
#: (CloseInterfaces).
AUTOPILOT_COMMANDS: tuple[type, ...] = (
    Goto,
    SetMode,
    Arm,
    Takeoff,
    SetServo,
    RcOverride,
    SetUpAutopilotSafety,
    UploadMission,
)


class UnknownCommandError(TypeError):
    """A shell was handed a command type it does not carry out: an engine bug.

    Never a user's mistake, so not a ``ClarkError``: a command dropped in silence would
    fly a mission with one of its commands missing (a dry run that drops what the
    real-time shell forwards is no rehearsal of it).
    """


def unknown_command(command: object, shell: str) -> UnknownCommandError:
    """The error for a command ``shell`` has no way to carry out, naming its type."""
    return UnknownCommandError(
        f"{shell}: no way to carry out a {type(command).__name__} command ({command!r}); "
        "every command type needs an entry in this shell's dispatch"
    )


def check_dispatch(handled: Iterable[type], shell: str) -> None:
    """Refuse, at import, a shell whose dispatch does not cover the command types exactly.

    Each shell checks its table against :data:`COMMAND_TYPES` when its module loads,
    so a new command type fails every shell that lacks it before anything runs.

    Raises:
        UnknownCommandError: A command type missing from ``handled``, or a type in it
            that is no command.
    """
    handled = frozenset(handled)
    missing = sorted(t.__name__ for t in COMMAND_TYPES - handled)
    extra = sorted(t.__name__ for t in handled - COMMAND_TYPES)
    if missing or extra:
        raise UnknownCommandError(
            f"{shell}: its command dispatch does not match the command types "
            f"(missing: {', '.join(missing) or 'none'}; not commands: {', '.join(extra) or 'none'})"
        )
