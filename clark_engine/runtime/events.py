"""Typed events the runtime core receives from its shells.

The core never reads a device: the shells (a real-time loop on a mission
computer, or the simulator) turn bytes into these events and hand them to
``AgentRuntime.deliver`` with the time they arrived. Units are in the names;
angles in degrees, positions in degrees and metres above the mission origin.
"""

from __future__ import annotations

from dataclasses import dataclass
from enum import Enum


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


class LandedState(Enum):
    """Whether the vehicle is on the ground or flying (MAVLink's MAV_LANDED_STATE)."""

    UNKNOWN = "unknown"
    ON_GROUND = "on_ground"
    IN_AIR = "in_air"
    TAKING_OFF = "taking_off"
    LANDING = "landing"


@dataclass(frozen=True, slots=True)
class AutopilotStatus:
    """What the autopilot reports about its readiness and whether it flies.

    The adapter sends one whenever any field changes. ``ready`` is the gate the
    runtime waits for before a behaviour starts (``wait_ready`` in the autopilot
    profile): ArduPilot refuses to arm until its pre-arm checks pass, and refuses
    the guided mode until its EKF has an absolute position.

    Attributes:
        gps_fix_type: GPS_RAW_INT's fix type (0-1 none, 2 2-D, 3 3-D, 4 DGPS, 5-6 RTK).
        position_ok: The EKF estimates an absolute horizontal position
            (EKF_STATUS_REPORT, and not in its constant-position mode); None before
            the first report.
        prearm_ok: SYS_STATUS's pre-arm check bit is healthy; None when the autopilot
            does not report that bit.
        home: Home (latitude, longitude, altitude above mean sea level) from
            HOME_POSITION; None until the autopilot has set it.
        landed: On the ground or in the air (EXTENDED_SYS_STATE); UNKNOWN when the
            autopilot does not say.
    """

    gps_fix_type: int = 0
    position_ok: bool | None = None
    prearm_ok: bool | None = None
    home: tuple[float, float, float] | None = None
    landed: LandedState = LandedState.UNKNOWN

    @property
    def ready(self) -> bool:
        """A 3-D fix, an EKF position, passed pre-arm checks (when reported) and a home."""
        return not self.waiting_for

    @property
    def waiting_for(self) -> tuple[str, ...]:
        """What readiness still waits for, in words, in the order ArduPilot gets there."""
        missing: list[str] = []
        if self.gps_fix_type < 3:
            missing.append("a 3-D GPS fix")
        if not self.position_ok:
            missing.append("an EKF position")
        if self.prearm_ok is False:
            missing.append("the pre-arm checks")
        if self.home is None:
            missing.append("a home position")
        return tuple(missing)


@dataclass(frozen=True, slots=True)
class AutopilotHealth:
    """The autopilot's battery, GPS and pre-arm checks, for the vehicle's Vehicle Health.

    The adapter sends one each time SYS_STATUS or GPS_RAW_INT arrives (their stream
    rates, 1 and 2 Hz), from the latest of both: a battery's voltage changes at every
    sample, so "on change" would mean at every message anyway, and a fixed rate is what
    the runtime's telemetry needs. Figures the autopilot marks as not measured are None.

    Attributes:
        battery_v: SYS_STATUS ``voltage_battery``; None when not measured (65535).
        battery_pct: SYS_STATUS ``battery_remaining``, 0..100; None when unknown (-1).
        gps_fix_type: GPS_RAW_INT ``fix_type`` (MAVLink GPS_FIX_TYPE: 0 no GPS, 1 no
            fix, 2 2-D, 3 3-D, 4 DGPS, 5 RTK float, 6 RTK fixed, 7 static, 8 PPP).
        satellites: GPS_RAW_INT ``satellites_visible``; None when unknown (255).
        prearm_ok: SYS_STATUS's pre-arm check bit is healthy; None when not reported.
    """

    battery_v: float | None = None
    battery_pct: int | None = None
    gps_fix_type: int = 0
    satellites: int | None = None
    prearm_ok: bool | None = None


@dataclass(frozen=True, slots=True)
class AutopilotText:
    """A STATUSTEXT from the autopilot (a PreArm reason, a mode refusal, a notice).

    Attributes:
        severity: MAVLink's MAV_SEVERITY (0 emergency .. 7 debug).
        text: The text as received; untrusted: escape it before writing it anywhere.
    """

    severity: int
    text: str


@dataclass(frozen=True, slots=True)
class CommandRefused:
    """The autopilot refused a command, or never answered it (from the autopilot adapter).

    Attributes:
        command: What was sent, in MAVLink's words (``MAV_CMD_DO_SET_MODE``, ``PARAM_SET``).
        result: ArduPilot's answer without the prefix (``FAILED``, ``DENIED``,
            ``UNSUPPORTED``, ``TEMPORARILY_REJECTED``), or ``NO_ANSWER`` after
            the adapter's last retry went unanswered.
        request: What the engine asked for, in words (``SetMode GUIDED (15)``).
        reason: ArduPilot's explanation: the warnings it sent in STATUSTEXT around the
            refusal (``PreArm: Need Position Estimate``), escaped, joined by ``; ``;
            empty when it gave none.
    """

    command: str
    result: str
    request: str
    reason: str = ""


@dataclass(frozen=True, slots=True)
class AutopilotSafetyResult:
    """How the autopilot's safety set-up ended (the adapter's answer to SetUpAutopilotSafety).

    Attributes:
        problem: Empty when every parameter took and the fence list was accepted; else
            what did not, in words (``FENCE_ALT_MAX did not take: reads 100, asked 118``).
        parameter: The parameter that did not take; None when every one did, or when
            the fence upload failed.
        retry: The set-up was cut short by the autopilot's silence or reboot, not by an
            answer: worth asking again once the autopilot is back.
    """

    problem: str = ""
    parameter: str | None = None
    retry: bool = False

    @property
    def ok(self) -> bool:
        """True when everything took."""
        return not self.problem


@dataclass(frozen=True, slots=True)
class MissionUploadResult:
    """How an :class:`~clark_engine.runtime.commands.UploadMission` ended.

    From the autopilot adapter (the autopilot's MISSION_ACK, or its silence), or from the
    runtime's envelope guard when it refused the upload before it left.

    Attributes:
        upload_id: The command's ``upload_id``.
        accepted: True when the autopilot took the whole mission.
        result: ArduPilot's MAV_MISSION_RESULT without its prefix (``ACCEPTED``,
            ``NO_SPACE``, ``INVALID_PARAM5_X``), ``NO_ANSWER`` when the autopilot never
            finished answering, ``ENVELOPE`` when the guard refused it.
        reason: Why, in words (the autopilot's warnings, or the guard's note); escaped.
    """

    upload_id: int
    accepted: bool
    result: str
    reason: str = ""


@dataclass(frozen=True, slots=True)
class MissionProgress:
    """Where the autopilot is in the mission the engine uploaded.

    From MISSION_ITEM_REACHED and MISSION_CURRENT. Counted in the
    :class:`~clark_engine.runtime.commands.UploadMission`'s items (its first is 0): the
    home item ArduPilot keeps in front is left out by the adapter.

    Attributes:
        item: The item reached (``reached``) or now being flown.
        total: How many items the mission has, when the message says (MISSION_CURRENT).
        reached: True for MISSION_ITEM_REACHED: the item is done; False for
            MISSION_CURRENT: the item is the one flown now.
    """

    item: int
    total: int | None = None
    reached: bool = False


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
    VehicleState
    | AutopilotHeartbeat
    | AutopilotStatus
    | AutopilotHealth
    | AutopilotText
    | CommandRefused
    | AutopilotSafetyResult
    | MissionUploadResult
    | MissionProgress
    | RcChannels
    | PacketReceived
    | PayloadEvent
    | StationCommand
)
