"""The autopilot adapter: the only place in the engine that knows MAVLink.

:class:`AutopilotAdapter` turns the bytes an ArduPilot autopilot sends into the
runtime's typed events (:class:`~clark_engine.runtime.events.VehicleState`,
:class:`~clark_engine.runtime.events.AutopilotHeartbeat`,
:class:`~clark_engine.runtime.events.RcChannels`, and the few events defined
here), and the runtime's typed commands into the bytes ArduPilot obeys. It is
the thesis's autopilot interface (requirements 4.3.1-4.3.6 and 7.1.1-7.1.5)
without DroneKit, and it is pure: it owns no socket, no thread and no clock.
The shell that owns the link hands it bytes and the time they arrived, and
sends what it returns; the dry run drives the same adapter through an
in-memory pipe to :class:`~clark_engine.sim.ardupilot.autopilot.SimAutopilot`, so the
flight code path is the tested code path.

Lifecycle, for a shell::

    adapter = AutopilotAdapter(AutopilotSettings.from_config(config))
    transport.send(adapter.start(now_s))            # heartbeat, stream requests, version request
    ...every loop...
    for event in adapter.receive(transport.receive(), now_s): runtime.deliver(event, now_s)
    transport.send(adapter.command(command, now_s))  # for each command the runtime emits
    transport.send(adapter.poll(now_s))              # heartbeat, override refresh, retries
    ...on terminate...
    transport.send(adapter.close(now_s)); transport.close()

Decisions a reader would otherwise have to reverse-engineer:

- One MAVLink 2 ``ardupilotmega`` codec object per adapter (pymavlink's
  generated dialect module, never ``mavutil``'s process-wide dialect switch),
  so two adapters in one process share nothing. MAVLink 1 frames still parse.
- Only messages from the autopilot's own system and component id are used;
  everything else on the link (a gimbal, a second vehicle behind a router, a
  ground station's heartbeat) is counted and ignored.
- One datum for every altitude the engine sees: metres above the mission origin.
  ``VehicleState.alt_m`` is GLOBAL_POSITION_INT's ``alt`` (above mean sea level)
  less the origin's ``alt_amsl_m``, and a Goto goes out in ``MAV_FRAME_GLOBAL_INT``
  at the origin's height plus its own. ``relative_alt`` (above home) is never used:
  ArduRover sets its home before its EKF has an origin, at its barometer's height
  (about 0 m above sea level), so a rover on the ground reads some 90 m above home
  at a 90 m field (measured on SITL), and a copter or plane re-homes where it arms.
  Only the commands whose height ArduPilot takes above home (NAV_TAKEOFF, ArduPlane's
  TKOFF_ALT) are converted, with HOME_POSITION's altitude. Until their EKF takes
  over, ArduRover and ArduPlane report their barometer's height in ``alt`` (about 0 m
  on any field: ArduRover for some 30 s after its GPS fix); while a 3-D fix's
  GPS_RAW_INT ``alt`` disagrees with it by more than :data:`FALLBACK_ALT_GAP_M`, the
  GPS's is used instead.
- A GLOBAL_POSITION_INT is a position only with a 3-D fix (GPS_RAW_INT) or an EKF
  absolute position (EKF_STATUS_REPORT). Before its fix ArduPlane sends positions that
  start at 0, 0 and drift from there (dead reckoning: 35 m in 6 s on SITL), and every
  firmware sends 0, 0; neither becomes a :class:`VehicleState`. A fix lost in flight
  while the EKF still has a position does not blind the engine.
- Everything the autopilot must acknowledge (COMMAND_LONG / COMMAND_INT,
  PARAM_SET, PARAM_REQUEST_READ) is tracked: resent by :meth:`poll` after
  :data:`ACK_TIMEOUT_S` (COMMAND_LONG with the ``confirmation`` field counting
  up, as the MAVLink command protocol asks) and, if still unanswered after
  :data:`COMMAND_ATTEMPTS` sends or refused outright, reported as
  :class:`CommandRefused`. MAVLink acknowledges a command by its number only,
  so two outstanding commands with the same number are matched first in,
  first out, as ArduPilot answers them.
"""

from __future__ import annotations

import logging
import math
import operator
from collections.abc import Callable, Mapping
from dataclasses import dataclass, replace
from typing import Any, Final

from pymavlink.dialects.v20 import ardupilotmega as mavlink2

from clark_engine.io.autopilot_setup import ParamAnswer, SafetySetup
from clark_engine.io.mission_upload import (
    MISSION_PROGRESS_MESSAGES,
    MissionUpload,
    MissionUploads,
    fence_items,
    mission_items,
)
from clark_engine.runtime.commands import (
    AUTOPILOT_COMMANDS,
    Arm,
    CloseInterfaces,
    Command,
    Goto,
    PayloadCommand,
    RcOverride,
    SendPacket,
    SetMode,
    SetServo,
    SetUpAutopilotSafety,
    Takeoff,
    UploadFence,
    UploadMission,
    check_dispatch,
    unknown_command,
)
from clark_engine.runtime.config import AgentConfig, ConfigError
from clark_engine.runtime.events import (
    AutopilotHealth,
    AutopilotHeartbeat,
    AutopilotSafetyResult,
    AutopilotStatus,
    AutopilotText,
    CommandRefused,
    LandedState,
    MissionProgress,
    MissionUploadResult,
    RcChannels,
    VehicleState,
)
from clark_engine.runtime.log_events import LogEvent
from clark_engine.untrusted import printable

GPS_EPOCH_UNIX_MS: Final = 315_964_800_000
"""The GPS epoch, 1980-01-06 00:00:00 UTC, in milliseconds of Unix time."""

GPS_LEAP_SECONDS: Final = 18
"""GPS time minus UTC, in seconds: constant since 2017-01-01 (no leap second has been
announced since, and the IERS plans none before their abolition)."""

GCS_HEARTBEAT_PERIOD_S: Final = 1.0
"""Our own HEARTBEAT period; ArduPilot's GCS failsafe (FS_GCS_ENABLE) expects 1 Hz."""

OVERRIDE_REFRESH_S: Final = 0.5
"""Active RC overrides are resent this often, well inside ArduPilot's RC_OVERRIDE_TIME (3 s)."""

ACK_TIMEOUT_S: Final = 1.0
"""How long an acknowledged request waits for its answer before it is resent."""

COMMAND_ATTEMPTS: Final = 3
"""Sends of one command (the first and two retries) before it is reported unanswered."""

STREAM_SILENCE_S: Final = 3.0
"""No GLOBAL_POSITION_INT for this long while heartbeats arrive: ask for the streams again
(the autopilot rebooted, or another ground station turned them off)."""

STREAM_RATE_CHECK_S: Final = 2.0
"""Every this long, once the stream requests are answered, the positions that came are
counted: fewer than half the rate asked for, and the streams are asked for again.
ArduPilot acknowledges a SET_MESSAGE_INTERVAL sent before its first HEARTBEAT and then
streams at its own default (ArduRover SITL: GLOBAL_POSITION_INT at 1 Hz, measured), so an
acknowledgement does not prove the rate: a mission computer powered up with its
autopilot drove on 1 Hz positions, sending its guided targets up to a second late."""

FALLBACK_ALT_GAP_M: Final = 20.0
"""GLOBAL_POSITION_INT's ``alt`` this far from a 3-D fix's GPS_RAW_INT ``alt`` is the
barometer's height of an autopilot whose EKF has not taken over yet (ArduRover, ArduPlane;
measured on SITL): the GPS's height above sea level is used instead. GPS and EKF heights
of a working vehicle differ by a few metres."""

MOVING_SPEED_M_S: Final = 0.5
"""Below this ground speed the course over ground is noise, and the heading is the yaw."""

STREAMED_MESSAGES: Final = (
    "GLOBAL_POSITION_INT",
    "ATTITUDE",
    "VFR_HUD",
    "SYSTEM_TIME",
    "RC_CHANNELS",
    "SERVO_OUTPUT_RAW",
    "SYS_STATUS",
    "GPS_RAW_INT",
    "EKF_STATUS_REPORT",
    "EXTENDED_SYS_STATE",
)
"""Messages :meth:`AutopilotAdapter.start` asks for."""

SLOW_STREAMS: Final = {
    "SYSTEM_TIME": 1.0,
    "SYS_STATUS": 1.0,
    "GPS_RAW_INT": 2.0,
    "SERVO_OUTPUT_RAW": 2.0,
    "EKF_STATUS_REPORT": 1.0,
    "EXTENDED_SYS_STATE": 1.0,
}
"""Messages the runtime needs only now and then, asked for at these rates (Hz) or the
profile's ``stream_rate_hz`` when slower: the clock's sync, health, readiness and raw
GPS do not need the loop rate, and a serial link at 57600 baud has little to spare."""

OPTIONAL_STREAMS: Final = frozenset({"EXTENDED_SYS_STATE"})
"""Streams an ArduPilot firmware may not have (ArduRover has no landed state): a refusal
is noted in the interface log, not reported as a refused command."""

HOME_REQUEST_PERIOD_S: Final = 2.0
"""HOME_POSITION is asked for this often until it arrives. ArduPilot sends it by itself
when home is set, but not to a ground station that connects afterwards."""

REASON_WINDOW_S: Final = 1.0
"""STATUSTEXT warnings this long before a refusal are its reason (ArduPilot explains a
refused arm or mode change in a STATUSTEXT, queued around the COMMAND_ACK)."""

REASON_WAIT_S: Final = 0.5
"""A refusal waits this long for its STATUSTEXT before it is reported."""

SPEED_RETRY_S: Final = 1.0
"""A refused speed change is sent again this long after (ArduRover refuses one until its
guided mode has a target; it is never dropped)."""

EKF_POS_HORIZ_ABS: Final = 0x10
"""EKF_STATUS_REPORT flag: the EKF estimates an absolute horizontal position."""

EKF_CONST_POS_MODE: Final = 0x80
"""EKF_STATUS_REPORT flag: no position source; the EKF assumes the vehicle is still."""

PREARM_CHECK_BIT: Final = 0x10000000
"""MAV_SYS_STATUS_PREARM_CHECK in SYS_STATUS: present when the autopilot reports it,
healthy when its pre-arm checks pass."""

_LANDED_STATES: Final[Mapping[int, LandedState]] = {
    0: LandedState.UNKNOWN,
    1: LandedState.ON_GROUND,
    2: LandedState.IN_AIR,
    3: LandedState.TAKING_OFF,
    4: LandedState.LANDING,
}

RC_OVERRIDE_CHANNELS: Final = 18
"""RC_CHANNELS_OVERRIDE carries channels 1-18."""

_UINT16_MAX: Final = 65535
#: The commands that reach the adapter but are not the autopilot's: answered with ``b""``.
_NOT_THE_AUTOPILOTS: Final = (SendPacket, PayloadCommand, CloseInterfaces)
# AutopilotAdapter.command carries out AUTOPILOT_COMMANDS and answers these with nothing;
# any other type raises, and a command type added without a place here fails on import.
check_dispatch((*AUTOPILOT_COMMANDS, *_NOT_THE_AUTOPILOTS), "the autopilot adapter")
_RC_IGNORE: Final = _UINT16_MAX  # "no change" for every channel
_RC_RELEASE_LOW: Final = 0  # channels 1-8: give the channel back to the pilot
_RC_RELEASE_HIGH: Final = _UINT16_MAX - 1  # channels 9-18: 0 means "ignore" there
_FORCE_ARM_MAGIC: Final = 21196  # MAV_CMD_COMPONENT_ARM_DISARM param2: skip pre-arm checks
_STATUS_MESSAGES: Final = frozenset(
    {"GPS_RAW_INT", "EKF_STATUS_REPORT", "SYS_STATUS", "HOME_POSITION", "EXTENDED_SYS_STATE"}
)
"""Messages :attr:`AutopilotAdapter.status` is made of."""
_MISSION_ANSWERS: Final = frozenset({"MISSION_REQUEST_INT", "MISSION_REQUEST", "MISSION_ACK"})
"""The autopilot's side of an upload (the safety set-up's fence list)."""
_HEALTH_MESSAGES: Final = frozenset({"SYS_STATUS", "GPS_RAW_INT"})
"""Messages :class:`AutopilotHealth` is made of; one is sent each time either arrives."""
_NOT_MEASURED_MV: Final = 65535  # SYS_STATUS.voltage_battery: UINT16_MAX
_UNKNOWN_SATELLITES: Final = 255  # GPS_RAW_INT.satellites_visible: UINT8_MAX
_RC_CHANNEL_FIELDS: Final = operator.attrgetter(
    *(f"chan{i}_raw" for i in range(1, RC_OVERRIDE_CHANNELS + 1))
)
"""RC_CHANNELS' 18 widths as a tuple, read in one call (it arrives at the stream rate)."""

POSITION_ONLY_TYPE_MASK: Final = (
    mavlink2.POSITION_TARGET_TYPEMASK_VX_IGNORE
    | mavlink2.POSITION_TARGET_TYPEMASK_VY_IGNORE
    | mavlink2.POSITION_TARGET_TYPEMASK_VZ_IGNORE
    | mavlink2.POSITION_TARGET_TYPEMASK_AX_IGNORE
    | mavlink2.POSITION_TARGET_TYPEMASK_AY_IGNORE
    | mavlink2.POSITION_TARGET_TYPEMASK_AZ_IGNORE
    | mavlink2.POSITION_TARGET_TYPEMASK_YAW_IGNORE
    | mavlink2.POSITION_TARGET_TYPEMASK_YAW_RATE_IGNORE
)
"""SET_POSITION_TARGET_GLOBAL_INT type_mask using lat, lon and alt only (0x0DF8)."""

POSITION_VELOCITY_TYPE_MASK: Final = (
    mavlink2.POSITION_TARGET_TYPEMASK_AX_IGNORE
    | mavlink2.POSITION_TARGET_TYPEMASK_AY_IGNORE
    | mavlink2.POSITION_TARGET_TYPEMASK_AZ_IGNORE
    | mavlink2.POSITION_TARGET_TYPEMASK_YAW_IGNORE
    | mavlink2.POSITION_TARGET_TYPEMASK_YAW_RATE_IGNORE
)
"""The same with the target's velocity too (0x0DC0): ArduCopter moves the target on
with it between messages, so a moving target is followed without lag. ArduRover ignores
the velocity of a position target (measured), so it gets position only."""


FIRMWARE_VEHICLE_TYPES: Final[Mapping[str, frozenset[int]]] = {
    # Numbers, not names: MAVLink renamed the VTOL types 19-25 between releases.
    "arduplane": frozenset({1, *range(19, 26)}),  # FIXED_WING; QuadPlane VTOL types
    # QUADROTOR, COAXIAL, HELICOPTER, HEXAROTOR, OCTOROTOR, TRICOPTER, DODECAROTOR, DECAROTOR
    "arducopter": frozenset({2, 3, 4, 13, 14, 15, 29, 35}),
    "ardurover": frozenset({10, 11}),  # GROUND_ROVER, SURFACE_BOAT
}
"""HEARTBEAT vehicle types each ArduPilot firmware reports; a mismatch with the profile
means the mode numbers would be read in the wrong table."""


def gps_time_ms_from_unix_us(time_unix_usec: int) -> int:
    """GPS time in milliseconds since the GPS epoch, from Unix time in microseconds.

    GPS time does not count leap seconds, so it runs :data:`GPS_LEAP_SECONDS` ahead
    of UTC. Integer arithmetic, so the result is exact to the millisecond (truncated).
    """
    return time_unix_usec // 1000 - GPS_EPOCH_UNIX_MS + GPS_LEAP_SECONDS * 1000


# -- events this adapter adds to the runtime's ------------------------------------------


@dataclass(frozen=True, slots=True)
class ParamValue:
    """An autopilot parameter's value (PARAM_VALUE), answering a read or echoing a set.

    Attributes:
        name: Parameter name (``RC_OVERRIDE_TIME``).
        value: Its value; integer parameters arrive as their value in a float.
        param_type: MAVLink's MAV_PARAM_TYPE of the parameter.
        index: Its index in the autopilot's table.
        count: Number of parameters the autopilot has.
    """

    name: str
    value: float
    param_type: int
    index: int
    count: int


@dataclass(frozen=True, slots=True)
class AutopilotMessage:
    """A message asked for with :meth:`AutopilotAdapter.request_message` (thesis 7.1.5).

    Attributes:
        name: MAVLink message name (``HOME_POSITION``).
        fields: Its fields as plain Python values, by MAVLink field name.
    """

    name: str
    fields: Mapping[str, Any]


AutopilotEvent = (
    VehicleState
    | AutopilotHeartbeat
    | AutopilotStatus
    | AutopilotHealth
    | AutopilotText
    | RcChannels
    | ParamValue
    | CommandRefused
    | AutopilotMessage
    | AutopilotSafetyResult
    | MissionUploadResult
    | MissionProgress
)
"""Everything :meth:`AutopilotAdapter.receive` returns."""


# -- configuration ----------------------------------------------------------------------


@dataclass(frozen=True, slots=True)
class AutopilotSettings:
    """What the adapter needs to know about one autopilot, from the agent's profile.

    Attributes:
        modes: Mode name -> ArduPilot custom_mode number, from the autopilot profile.
        firmware: ``arduplane``, ``arducopter`` or ``ardurover``; decides how a Goto is
            sent and which HEARTBEAT vehicle types are accepted. None: any ArduPilot.
        system_id: The autopilot's MAVLink system id (SYSID_THISMAV).
        component_id: The autopilot's component id (1, MAV_COMP_ID_AUTOPILOT1).
        source_system_id: Ours. The safety set-up makes it the autopilot's ground-station
            id (MAV_GCS_SYSID): ArduPilot takes RC overrides, and counts heartbeats for its
            failsafe, only from that id.
        source_component_id: Ours (191, MAV_COMP_ID_ONBOARD_COMPUTER).
        stream_rate_hz: Rate asked for each of :data:`STREAMED_MESSAGES`.
        heartbeat_timeout_s: Autopilot silence after which :meth:`AutopilotAdapter.lost`.
        origin_alt_amsl_m: The mission origin's height above mean sea level: altitudes
            above the origin are the autopilot's AMSL altitudes less this.
    """

    modes: Mapping[str, int]
    firmware: str | None = None
    system_id: int = 1
    component_id: int = 1
    source_system_id: int = 255
    source_component_id: int = 191
    stream_rate_hz: float = 10.0
    heartbeat_timeout_s: float = 3.0
    origin_alt_amsl_m: float = 0.0

    def __post_init__(self) -> None:
        for name in ("system_id", "source_system_id"):
            if not 1 <= getattr(self, name) <= 255:
                raise ValueError(f"{name} must be 1..255, not {getattr(self, name)}")
        for name in ("component_id", "source_component_id"):
            if not 0 <= getattr(self, name) <= 255:
                raise ValueError(f"{name} must be 0..255, not {getattr(self, name)}")
        if not self.stream_rate_hz > 0:
            raise ValueError(f"stream_rate_hz must be positive, not {self.stream_rate_hz}")
        if not self.heartbeat_timeout_s > 0:
            raise ValueError(
                f"heartbeat_timeout_s must be positive, not {self.heartbeat_timeout_s}"
            )
        if self.firmware is not None and self.firmware not in FIRMWARE_VEHICLE_TYPES:
            raise ValueError(f"unknown firmware {self.firmware!r}")

    @classmethod
    def from_profile(
        cls, autopilot: Mapping[str, Any], origin_alt_amsl_m: float = 0.0
    ) -> AutopilotSettings:
        """Settings from a resolved autopilot profile (``agent.hardware.autopilot``).

        Args:
            autopilot: The resolved autopilot profile.
            origin_alt_amsl_m: The mission origin's height above mean sea level.
        """
        mav = autopilot.get("mavlink") or {}
        return cls(
            modes=dict(autopilot.get("modes") or {}),
            firmware=autopilot.get("firmware"),
            system_id=int(mav.get("system_id", 1)),
            component_id=int(mav.get("component_id", 1)),
            source_system_id=int(mav.get("source_system_id", 255)),
            source_component_id=int(mav.get("source_component_id", 191)),
            stream_rate_hz=float(autopilot.get("stream_rate_hz", 10.0)),
            heartbeat_timeout_s=float(autopilot.get("heartbeat_timeout_s", 3.0)),
            origin_alt_amsl_m=float(origin_alt_amsl_m),
        )

    @classmethod
    def from_config(cls, config: AgentConfig) -> AutopilotSettings:
        """Settings from a compiled agent config.

        Raises:
            ConfigError: The agent has no autopilot (a station).
        """
        autopilot = (config.raw.get("agent", {}).get("hardware") or {}).get("autopilot")
        if not autopilot:
            raise ConfigError(
                f"agent {config.agent} has no autopilot in its hardware profile; "
                "only vehicles connect to one"
            )
        return cls.from_profile(autopilot, config.origin_alt_amsl_m)


# -- internals ---------------------------------------------------------------------------


class _Outbox:
    """The file pymavlink writes encoded frames to; the adapter hands them back as bytes."""

    def __init__(self) -> None:
        self._data = bytearray()

    def write(self, data: bytes) -> None:
        self._data += data

    def take(self) -> bytes:
        if not self._data:
            return b""  # most polls send nothing
        data, self._data = bytes(self._data), bytearray()
        return data


@dataclass(slots=True)
class _Request:
    """One request waiting for the autopilot's answer.

    ``key`` is the MAV_CMD number for commands (answered by COMMAND_ACK) and the
    parameter name for parameter requests (answered by PARAM_VALUE). ``build``
    makes the message for a given attempt (1 first). ``setup`` marks the stream
    requests, which are retried for as long as the autopilot is heard. ``answered``,
    when given, hears how it ended (the MAV_RESULT, or None when it was given up
    unanswered) and reports a refusal itself; without it a refusal is reported as
    :class:`CommandRefused`.
    """

    command: str
    key: int | str
    request: str
    build: Callable[[int], Any]
    setup: bool = False
    answered: Callable[[int | None, float], None] | None = None
    attempts: int = 0
    due_s: float = 0.0


def _result_name(result: int) -> str:
    entry = mavlink2.enums["MAV_RESULT"].get(result)
    name = entry.name if entry is not None else f"MAV_RESULT_{result}"
    return str(name).removeprefix("MAV_RESULT_")


def _command_name(command: int) -> str:
    entry = mavlink2.enums["MAV_CMD"].get(command)
    return str(entry.name) if entry is not None else f"MAV_CMD_{command}"


def _message_id(name: str) -> int:
    msg_id = getattr(mavlink2, f"MAVLINK_MSG_ID_{name}", None)
    if not isinstance(msg_id, int):
        raise ValueError(f"{name!r} is not a MAVLink message of the ardupilotmega dialect")
    return msg_id


def _param_id(name: str) -> bytes:
    raw = name.encode("ascii", errors="strict") if name.isascii() else b""
    if not raw or len(raw) > 16:
        raise ValueError(f"parameter name {name!r} must be 1-16 ASCII characters")
    return raw


class AutopilotAdapter:
    """MAVLink bytes <-> typed events and commands for one ArduPilot autopilot.

    Thesis requirements, and where each is met: connect (4.3.1) - :meth:`start`;
    state (4.3.2, 7.1.2) - :class:`VehicleState` from :meth:`receive`; command
    (4.3.3, 7.1.1) - :meth:`command`, :meth:`arm`; verify (4.3.4) - :attr:`verified`
    and :meth:`lost`; GPS time (4.3.5, 7.1.3) - ``VehicleState.gps_time_ms``;
    close (4.3.6) - :meth:`close` (the shell then closes the transport); set
    parameters (7.1.4) - :meth:`param_set`; other state (7.1.5) -
    :meth:`request_message` and :meth:`latest`.

    Every method that returns bytes returns complete MAVLink frames, possibly
    several, possibly none (``b""``); send them in order.

    Args:
        settings: The autopilot's ids, modes and rates.
        logger: Where refusals, mismatches and garbage are logged (the agent's
            interface log); this module's logger by default.
    """

    def __init__(self, settings: AutopilotSettings, *, logger: logging.Logger | None = None):
        self.settings = settings
        self._log = logger or logging.getLogger(__name__)
        self._outbox = _Outbox()
        self._mav = mavlink2.MAVLink(
            self._outbox,
            srcSystem=settings.source_system_id,
            srcComponent=settings.source_component_id,
        )
        self._parser = self._new_parser()
        # (system, component) the messages used come from; settings are frozen
        self._autopilot_ids = (settings.system_id, settings.component_id)
        self._mode_names: dict[int, str] = {}
        for name, number in settings.modes.items():
            self._mode_names.setdefault(int(number), name)
        self._interval_us = max(1, round(1e6 / settings.stream_rate_hz))

        self._start_s: float | None = None
        self._next_heartbeat_s = 0.0
        self._requests: list[_Request] = []
        self._late_events: list[AutopilotEvent] = []
        self._overrides: dict[int, int] = {}
        self._override_sent_s = -math.inf
        # The speed the runtime asked for, the one the autopilot accepted in its current
        # mode, and when a refused or unanswered change may be sent again (see _speed).
        self._speed_wanted: float | None = None
        self._speed_accepted: float | None = None
        self._speed_retry_s = -math.inf
        self._targeted = False  # a position target was sent in the current mode
        self._wanted: set[str] = set()
        self._latest: dict[str, Any] = {}
        self._param_types: dict[str, int] = {}

        # What the autopilot told us.
        self._heartbeat: AutopilotHeartbeat | None = None
        self._heartbeat_s: float | None = None
        self._problem: str | None = None
        self._version: int | None = None
        self._next_verify_s = 0.0
        self._verify_attempts = 0
        self._attitude: Any = None
        self._vfr_hud: Any = None
        # The last RC_CHANNELS widths received, and _rc_values' answer for them.
        self._rc_raw: tuple[int, ...] | None = None
        self._rc: tuple[int, ...] = ()
        self._gps_at_boot_ms: tuple[int, int] | None = None  # (GPS ms, autopilot boot ms)
        self._position_s: float | None = None
        # Positions counted since the last rate check (STREAM_RATE_CHECK_S), and its time.
        self._positions_counted = 0
        self._rate_check_s = -math.inf
        self._last_boot_ms: int | None = None
        self._setup_s = -math.inf
        self._setup_due = False
        self._legacy_streams_due = False
        self._state: VehicleState | None = None
        # Readiness (AutopilotStatus), and when HOME_POSITION is next asked for.
        self._status = AutopilotStatus()
        #: A 3-D fix's GPS_RAW_INT altitude above sea level (None without one).
        self._gps_alt_amsl_m: float | None = None
        self._next_home_request_s = -math.inf
        # Recent STATUSTEXT warnings (time, escaped text), the reasons of refusals; and
        # refusals waiting REASON_WAIT_S for theirs: (due time, refusal, refused at).
        self._warnings: list[tuple[float, str]] = []
        self._refusals: list[tuple[float, CommandRefused, float]] = []
        # The safety set-up under way (None when none), who waits for which parameter's
        # answer, and what a clean stop writes (the set-up's on_close, once it took).
        self._safety: SafetySetup | None = None
        self._param_answers: dict[str, list[ParamAnswer]] = {}
        self._on_close: tuple[tuple[str, float], ...] = ()
        # Missions to fly in AUTO (UploadMission), after any fence upload of a set-up.
        self._missions = MissionUploads(
            self._mav,
            self._autopilot_ids,
            lambda cmd: mission_items(
                cmd.items,
                self._status.home,
                self.above_home_m,
                airspeed=settings.firmware == "arduplane",
            ),
            lambda: self._safety is not None,
            self.setup_reasons,
            lambda event: self._late_events.append(event),
            self._log,
        )
        # A clean stop began (stop_commanding): poll only keeps the heartbeat and the
        # stop's own requests going.
        self._stopping = False
        self.left_on_purpose: tuple[str, ...] = ()
        """The parameters :meth:`close` wrote back (the failsafe switched off)."""

        self.bad_frames = 0
        """Frames that failed their checksum or were not MAVLink (garbage on the link)."""
        self.foreign_messages = 0
        """Messages from other systems or components, ignored."""

    # -- status -------------------------------------------------------------------------

    @property
    def verified(self) -> bool:
        """The autopilot is the one configured and it works (thesis 4.3.4).

        True once a HEARTBEAT from the configured system and component has been
        heard, of the firmware's vehicle type, and AUTOPILOT_VERSION has answered
        our request (so the autopilot processes commands, not only streams). When
        the autopilot is heard again after :meth:`lost`, or has rebooted, it is
        False until AUTOPILOT_VERSION answers anew; during the silence itself
        :meth:`lost` is the answer.
        """
        return self._heartbeat is not None and self._version is not None and self._problem is None

    @property
    def problem(self) -> str | None:
        """Why the autopilot heard is not the one configured, if it is not."""
        return self._problem

    @property
    def flight_sw_version(self) -> str | None:
        """ArduPilot's version (``4.5.7``) from AUTOPILOT_VERSION, None before it arrives."""
        if self._version is None:
            return None
        v = self._version
        return f"{(v >> 24) & 0xFF}.{(v >> 16) & 0xFF}.{(v >> 8) & 0xFF}"

    @property
    def state(self) -> VehicleState | None:
        """The latest VehicleState, None before the first one."""
        return self._state

    @property
    def status(self) -> AutopilotStatus:
        """Readiness and landed state as the autopilot last reported them."""
        return self._status

    @property
    def active_overrides(self) -> Mapping[int, int]:
        """RC channels we override now (channel -> pulse width), kept alive by :meth:`poll`."""
        return dict(self._overrides)

    def lost(self, now_s: float) -> bool:
        """No autopilot HEARTBEAT for longer than ``heartbeat_timeout_s``.

        Counted from :meth:`start` until the first heartbeat, so an autopilot that
        never answers is lost too; False before :meth:`start`.
        """
        since = self._heartbeat_s if self._heartbeat_s is not None else self._start_s
        return since is not None and now_s - since > self.settings.heartbeat_timeout_s

    def latest(self, name: str) -> Mapping[str, Any] | None:
        """The last message of this name from the autopilot, as fields (thesis 7.1.5).

        Any message the autopilot sends is kept, streamed or not (``SYS_STATUS``,
        ``GPS_RAW_INT``, ``SERVO_OUTPUT_RAW``...); None if none has arrived.
        """
        msg = self._latest.get(name)
        return None if msg is None else self._fields(msg)

    # -- connection ------------------------------------------------------------------------

    def start(self, now_s: float) -> bytes:
        """Open the conversation (thesis 4.3.1): what to send first.

        Our HEARTBEAT; SET_MESSAGE_INTERVAL for each of :data:`STREAMED_MESSAGES`
        at ``stream_rate_hz``; and MAV_CMD_REQUEST_MESSAGE for AUTOPILOT_VERSION,
        whose answer completes :attr:`verified`. Whatever is lost (an autopilot
        still booting, a UDP link with no peer yet) :meth:`poll` sends again.
        """
        self._start_s = now_s
        self._heartbeat_out(now_s)
        self._queue_setup(now_s)
        self._verify(now_s)
        self._send_due(now_s)
        return self._outbox.take()

    def flush(self) -> bytes:
        """What the adapter queued while receiving: send it now rather than at the next poll.

        An answer from the autopilot may call for the next message at once (the next step
        of a safety set-up, an item of a fence upload it asks for; overrides released
        after a silence); usually nothing (``b""``).
        """
        return self._outbox.take()

    def poll(self, now_s: float) -> bytes:
        """Periodic duties; call every loop (at least every 0.5 s).

        - Our HEARTBEAT at 1 Hz (ArduPilot's GCS failsafe watches it).
        - Active RC overrides resent every :data:`OVERRIDE_REFRESH_S`, so that
          ArduPilot's RC_OVERRIDE_TIME (3 s) never hands the channels back.
        - Unanswered requests resent after :data:`ACK_TIMEOUT_S`; commands given
          up after :data:`COMMAND_ATTEMPTS` sends (reported by the next
          :meth:`receive` as :class:`CommandRefused` ``NO_ANSWER``); stream
          requests retried for as long as the autopilot is heard.
        - The AUTOPILOT_VERSION request repeated every second until answered.
        - The streams asked for again after a reconnection or a reboot, or when no
          GLOBAL_POSITION_INT came for :data:`STREAM_SILENCE_S` while heartbeats do.
        """
        if self._start_s is None:
            return self.start(now_s)
        if now_s >= self._next_heartbeat_s:
            self._heartbeat_out(now_s)
        if self._stopping:
            # The stop's requests (the terminal mode, the failsafe switched off) are
            # resent until answered; nothing else is asked or kept alive.
            if self._requests:
                self._send_due(now_s, heard=not self.lost(now_s))
            self._release_refusals(now_s, self._late_events)
            return self._outbox.take()
        if (
            self._overrides
            and now_s - self._override_sent_s >= OVERRIDE_REFRESH_S
            and not self.lost(now_s)
        ):
            # Not while lost: ArduPilot hands the channels back to the pilot
            # RC_OVERRIDE_TIME after the last override, and an override kept alive
            # through a silence would act again, stale, the moment the link returns.
            self._override_out(dict(self._overrides), now_s)
        heard = self._heartbeat_s is not None and not self.lost(now_s)
        if heard:
            last_position_s = -math.inf if self._position_s is None else self._position_s
            if self._setup_due:
                self._queue_setup(now_s)
            elif now_s - max(self._setup_s, last_position_s) >= STREAM_SILENCE_S:
                self._log.info(
                    "autopilot sends no position; asking for the streams again",
                    extra=LogEvent.AUTOPILOT_STREAMS.extra,
                )
                self._queue_setup(now_s)
            elif now_s - self._rate_check_s >= STREAM_RATE_CHECK_S - 1e-9:
                self._check_stream_rate(now_s)
            if self._legacy_streams_due:
                self._legacy_streams_due = False
                self._mav.send(
                    self._mav.request_data_stream_encode(
                        self.settings.system_id,
                        self.settings.component_id,
                        mavlink2.MAV_DATA_STREAM_ALL,
                        max(1, round(self.settings.stream_rate_hz)),
                        1,
                    )
                )
        if self._version is None and now_s >= self._next_verify_s:
            self._verify(now_s)
        elif heard and self._status.home is None and now_s >= self._next_home_request_s:
            self._request_home(now_s)
        if self._requests:
            self._send_due(now_s, heard=heard)
        if heard:
            self._speed(now_s)
        if self._safety is not None:
            self._safety.poll(now_s)
        if self._missions.busy:
            self._missions.poll(now_s)
        self._release_refusals(now_s, self._late_events)
        return self._outbox.take()

    def stop_commanding(self, now_s: float) -> bytes:
        """A clean stop begins: release the sticks at once and ask for nothing more.

        Every active RC override is released now (rather than left for ArduPilot to
        time out 3 s later), every pending request is forgotten (nothing the behaviour
        asked for is sent again), the wanted speed and a safety set-up under way are
        dropped. What the stop itself sends next (the terminal mode; :meth:`close`'s
        parameters) is tracked as usual, and :meth:`poll` resends it until answered.
        """
        self._stopping = True
        if self._overrides:
            self._override_out(dict.fromkeys(self._overrides, 0), now_s)
            self._overrides.clear()
        self._requests.clear()
        self._param_answers.clear()
        self._safety = None
        self._missions.cancel()
        self._speed_wanted = None
        return self._outbox.take()

    def close(self, now_s: float) -> bytes:
        """Leave the autopilot as the pilot expects it (thesis 4.3.6); send, then close.

        Releases every active RC override at once (rather than letting ArduPilot
        time them out 3 s later) and writes the safety set-up's ``on_close`` (the
        failsafe switched off). Requests still unanswered (those, the terminal mode)
        stay in :attr:`unanswered` for a shell that can wait for their answers
        (:meth:`poll` resends them); closing the transport is the shell's part.
        """
        if self._overrides:
            self._override_out(dict.fromkeys(self._overrides, 0), now_s)
            self._overrides.clear()
        self._stopping = True
        self._safety_close(now_s)
        return self._outbox.take()

    @property
    def unanswered(self) -> list[str]:
        """The requests still waiting for the autopilot's answer, in words.

        Stream set-up excluded: what a clean stop waits for before it closes the link.
        """
        return [r.request for r in self._requests if not r.setup]

    # -- commands ----------------------------------------------------------------------------

    def command(self, cmd: Command, now_s: float) -> bytes:
        """Encode one runtime command (thesis 4.3.3, 7.1.1).

        - :class:`Goto`: for ArduCopter and ArduRover (and an unknown firmware),
          SET_POSITION_TARGET_GLOBAL_INT in ``GLOBAL_RELATIVE_ALT_INT`` with
          position only (:data:`POSITION_ONLY_TYPE_MASK`; not acknowledged by
          MAVLink), or for ArduCopter with the target's velocity when it has one
          (:data:`POSITION_VELOCITY_TYPE_MASK`). ArduPlane reads only the altitude
          from that message, so for ArduPlane it is COMMAND_INT
          MAV_CMD_DO_REPOSITION in the same frame. Both act only in the guided mode,
          as the runtime's primitives expect. A ``speed_m_s`` follows as
          MAV_CMD_DO_CHANGE_SPEED (ground speed; airspeed for ArduPlane, whose
          ground-speed type sets only a minimum), after the target, since ArduRover
          refuses one before its guided mode has a target; sent again after a
          refusal until the autopilot takes it, and again after a mode change
          (ArduPilot starts each mode at its default speed).
        - :class:`SetMode`: COMMAND_LONG MAV_CMD_DO_SET_MODE, base mode
          MAV_MODE_FLAG_CUSTOM_MODE_ENABLED, the profile's number for the name.
        - :class:`SetServo`: COMMAND_LONG MAV_CMD_DO_SET_SERVO.
        - :class:`RcOverride`: RC_CHANNELS_OVERRIDE with every overridden channel
          at its width, the channels this command releases (width 0) at the
          MAVLink release value (0 for channels 1-8, UINT16_MAX-1 for 9-18), and
          every other channel at "ignore" (UINT16_MAX). Overrides stay active, and
          :meth:`poll` keeps them alive, until released.
        - :class:`UploadMission`: the mission protocol's upload, in turn
          (:class:`~clark_engine.io.mission_upload.MissionUploads`); answered by a
          :class:`MissionUploadResult`, then :class:`MissionProgress` as it is flown.
        - Radio, payload and CloseInterfaces commands are not the autopilot's:
          ``b""``.

        Raises:
            UnknownCommandError: Any other type (an engine bug, never dropped).
        """
        if isinstance(cmd, Goto):
            self._goto(cmd, now_s)
            self._speed(now_s)
        elif isinstance(cmd, Arm):
            return self.arm(cmd.armed, now_s)
        elif isinstance(cmd, Takeoff):
            self._takeoff(cmd, now_s)
        elif isinstance(cmd, SetMode):
            number = int(self.settings.modes.get(cmd.mode, cmd.custom_mode))
            if cmd.mode in self.settings.modes and number != cmd.custom_mode:
                self._log.warning(
                    "SetMode %s: the profile says %d, the command %d; sending %d",
                    cmd.mode,
                    number,
                    cmd.custom_mode,
                    number,
                    extra=LogEvent.AUTOPILOT_MODE.extra,
                )
            self._command_long(
                mavlink2.MAV_CMD_DO_SET_MODE,
                f"SetMode {cmd.mode} ({number})",
                now_s,
                mavlink2.MAV_MODE_FLAG_CUSTOM_MODE_ENABLED,
                number,
            )
        elif isinstance(cmd, SetServo):
            self._command_long(
                mavlink2.MAV_CMD_DO_SET_SERVO,
                f"SetServo {cmd.servo} {cmd.pwm_us} us",
                now_s,
                cmd.servo,
                cmd.pwm_us,
            )
        elif isinstance(cmd, RcOverride):
            self._rc_override(cmd, now_s)
        elif isinstance(cmd, SetUpAutopilotSafety):
            self._safety_start(cmd, now_s)
        elif isinstance(cmd, UploadMission):
            self._missions.request(cmd, now_s)
        elif not isinstance(cmd, _NOT_THE_AUTOPILOTS):
            raise unknown_command(cmd, "the autopilot adapter")
        return self._outbox.take()

    def arm(self, armed: bool, now_s: float, *, force: bool = False) -> bytes:
        """Arm or disarm (MAV_CMD_COMPONENT_ARM_DISARM); ``force`` skips pre-arm checks."""
        self._command_long(
            mavlink2.MAV_CMD_COMPONENT_ARM_DISARM,
            ("arm" if armed else "disarm") + (" (forced)" if force else ""),
            now_s,
            1 if armed else 0,
            _FORCE_ARM_MAGIC if force else 0,
        )
        return self._outbox.take()

    def param_request(self, name: str, now_s: float) -> bytes:
        """Ask for one parameter (PARAM_REQUEST_READ); the answer is a :class:`ParamValue`.

        Raises:
            ValueError: The name is not 1-16 ASCII characters.
        """
        param_id = _param_id(name)
        s = self.settings
        self._track(
            _Request(
                "PARAM_REQUEST_READ",
                name,
                f"read {name}",
                lambda _attempt: self._mav.param_request_read_encode(
                    s.system_id, s.component_id, param_id, -1
                ),
            ),
            now_s,
        )
        return self._outbox.take()

    def param_set(self, name: str, value: float, now_s: float) -> bytes:
        """Set one parameter (PARAM_SET, thesis 7.1.4); the echo is a :class:`ParamValue`.

        The value travels as a float holding the number (ArduPilot's encoding, for
        integer parameters too). The type is the one the autopilot last reported
        for the name, else REAL32; ArduPilot converts to the parameter's own type.

        Raises:
            ValueError: The name is not 1-16 ASCII characters.
        """
        self._param_set(name, value, now_s)
        return self._outbox.take()

    def _param_set(
        self,
        name: str,
        value: float,
        now_s: float,
        answered: Callable[[int | None, float], None] | None = None,
    ) -> None:
        param_id = _param_id(name)
        known = self._param_types.get(name, mavlink2.MAV_PARAM_TYPE_REAL32)
        s = self.settings
        self._track(
            _Request(
                "PARAM_SET",
                name,
                f"set {name} = {value:g}",
                lambda _attempt: self._mav.param_set_encode(
                    s.system_id, s.component_id, param_id, float(value), known
                ),
                answered=answered,
            ),
            now_s,
        )

    def request_message(self, name: str, now_s: float) -> bytes:
        """Ask for one message once (MAV_CMD_REQUEST_MESSAGE, thesis 7.1.5).

        When it arrives, :meth:`receive` returns it as an :class:`AutopilotMessage`
        (once); :meth:`latest` keeps it too.

        Raises:
            ValueError: No message of that name in the dialect.
        """
        msg_id = _message_id(name)
        self._wanted.add(name)
        self._command_long(mavlink2.MAV_CMD_REQUEST_MESSAGE, f"request {name}", now_s, msg_id)
        return self._outbox.take()

    # -- the safety set-up (SetUpAutopilotSafety; see io/autopilot_setup.py) ----------------

    def _safety_start(self, cmd: SetUpAutopilotSafety, now_s: float) -> None:
        """Start a safety set-up; one under way is dropped (the runtime asks once at a time)."""
        if self._safety is not None:
            self._log.warning(
                "a new safety set-up replaces the one under way",
                extra=LogEvent.AUTOPILOT_SAFETY.extra,
            )
            self._param_answers.clear()
        self._log.info(
            "safety set-up: %s",
            cmd.summary or "(no summary)",
            extra=LogEvent.AUTOPILOT_SAFETY.extra,
        )
        self._safety = SafetySetup(cmd, self, self._safety_over)
        self._safety.start(now_s)

    def _safety_over(self, result: AutopilotSafetyResult) -> None:
        safety, self._safety = self._safety, None
        if safety is not None:
            # What it switched on, a clean stop switches off, whether or not the rest took.
            close = dict(self._on_close)
            close.update(
                (p.name, p.value) for p in safety.command.on_close if p.name in safety.took_names
            )
            self._on_close = tuple(close.items())
        if result.ok:
            self._log.info(
                "safety set-up: every parameter took", extra=LogEvent.AUTOPILOT_SAFETY.extra
            )
        else:
            self._log.error(
                "safety set-up failed: %s",
                printable(result.problem),
                extra=LogEvent.AUTOPILOT_SAFETY.extra,
            )
        self._late_events.append(result)

    def _safety_close(self, now_s: float) -> None:
        """A clean stop: write the set-up's on_close (the failsafe switched off).

        Only what a set-up switched on (its value read back) is switched off, whether or
        not the set-up as a whole took. Sent at once and tracked: the autopilot's echo
        answers it, :meth:`poll` resends it meanwhile, and a shell that may wait does
        (:attr:`unanswered`); one that may not has sent it once.
        """
        for name, value in self._on_close:
            self._log.info(
                "leaving on purpose: %s = %g", name, value, extra=LogEvent.AUTOPILOT_SAFETY.extra
            )
            self._param_set(name, value, now_s, lambda _result, _at_s: None)
        self.left_on_purpose = tuple(name for name, _value in self._on_close)
        self._on_close = ()

    def _param_silent(self, name: str, now_s: float) -> None:
        for answer in self._param_answers.pop(name, ()):
            answer(None, None, now_s)

    def setup_read(self, name: str, now_s: float, answer: ParamAnswer) -> None:
        """Read a parameter for the safety set-up; ``answer`` hears it or its silence."""
        self._param_answers.setdefault(name, []).append(answer)
        param_id = _param_id(name)
        s = self.settings
        self._track(
            _Request(
                "PARAM_REQUEST_READ",
                name,
                f"read {name}",
                lambda _attempt: self._mav.param_request_read_encode(
                    s.system_id, s.component_id, param_id, -1
                ),
                answered=lambda _result, at_s: self._param_silent(name, at_s),
            ),
            now_s,
        )

    def setup_write(self, name: str, value: float, now_s: float, answer: ParamAnswer) -> None:
        """Set a parameter for the safety set-up; ``answer`` hears its echo or its silence."""
        self._param_answers.setdefault(name, []).append(answer)
        self._param_set(name, value, now_s, lambda _result, at_s: self._param_silent(name, at_s))

    def setup_forget(self, name: str) -> None:
        """Stop asking for a parameter the set-up no longer needs."""
        self._param_answers.pop(name, None)
        self._requests = [r for r in self._requests if r.key != name]

    def setup_heartbeat(self, now_s: float) -> None:
        """Send our HEARTBEAT now, off its 1 Hz grid."""
        self._heartbeat_out(now_s)

    def setup_upload(self, zones: UploadFence, now_s: float) -> MissionUpload:
        """Start replacing the autopilot's fence list."""
        s = self.settings
        return MissionUpload(
            self._mav,
            (s.system_id, s.component_id),
            fence_items(zones.zones),
            int(mavlink2.MAV_MISSION_TYPE_FENCE),
            now_s,
        )

    def setup_heard_since(self, t_s: float) -> bool:
        """True when a HEARTBEAT from the autopilot arrived at or after ``t_s``."""
        return self._heartbeat_s is not None and self._heartbeat_s >= t_s

    def setup_reasons(self, since_s: float, now_s: float) -> str:
        """The autopilot's warnings since ``since_s`` (escaped), joined by ``; ``."""
        return "; ".join(text for t, text in self._warnings if since_s <= t <= now_s)

    def setup_note(self, text: str) -> None:
        """A line of the safety set-up for the interface log."""
        self._log.info("safety set-up: %s", text, extra=LogEvent.AUTOPILOT_SAFETY.extra)

    @property
    def own_system_id(self) -> int:
        """Our MAVLink system id: the one the autopilot's ground-station failsafe watches."""
        return self.settings.source_system_id

    # -- bytes in ---------------------------------------------------------------------------

    def receive(self, data: bytes, now_s: float) -> list[AutopilotEvent]:
        """Parse bytes from the autopilot link, in any chunking; never raises on their content.

        Returns the events they carry, in arrival order, after any the adapter noticed
        since the last call (commands :meth:`poll` gave up on):

        - HEARTBEAT -> :class:`AutopilotHeartbeat` (mode named through the profile's
          modes, ``UNKNOWN_<n>`` for a number it lacks; armed from base_mode).
        - GLOBAL_POSITION_INT -> :class:`VehicleState`, merged with the latest
          ATTITUDE (roll, pitch, yaw), VFR_HUD (ground speed, climb rate) and
          SYSTEM_TIME (GPS time); not before a HEARTBEAT and an ATTITUDE have
          arrived, since mode and attitude have no honest default, and not while
          latitude and longitude are both 0, ArduPilot's "no position" before its
          first GPS fix (a peer must never be told the vehicle is off Africa).
        - STATUSTEXT -> :class:`AutopilotText` (also logged, escaped, in the
          interface log).
        - GPS_RAW_INT, EKF_STATUS_REPORT, SYS_STATUS, HOME_POSITION and
          EXTENDED_SYS_STATE -> :class:`AutopilotStatus` when readiness or the
          landed state changed.
        - SYS_STATUS and GPS_RAW_INT -> :class:`AutopilotHealth`, every time
          (battery, fix type and satellites, pre-arm checks).
        - RC_CHANNELS -> :class:`RcChannels`, 18 channels, "unused" as 0.
        - PARAM_VALUE -> :class:`ParamValue`; COMMAND_ACK refusals -> :class:`CommandRefused`;
          a message asked for by :meth:`request_message` -> :class:`AutopilotMessage`.

        ``gps_time_ms`` is SYSTEM_TIME's Unix time converted to GPS time, carried
        forward to the position's own timestamp with the autopilot's boot clock
        (both messages carry ``time_boot_ms``), so it is exact for the sample
        however often SYSTEM_TIME comes; None until a SYSTEM_TIME with a non-zero
        time (ArduPilot sends 0 before its GPS has time).
        """
        events = self._late_events
        self._late_events = []
        try:
            messages = self._parser.parse_buffer(data) or []
        except Exception:  # a link is untrusted input; a parser bug must not stop the flight
            self._log.exception(
                "MAVLink parser failed; dropping its buffer", extra=LogEvent.AUTOPILOT_PARSER.extra
            )
            self.bad_frames += 1
            self._parser = self._new_parser()
            messages = []
        for msg in messages:
            self._handle(msg, now_s, events)
        if self._late_events:  # what the messages ended (a safety set-up's result)
            events.extend(self._late_events)
            self._late_events = []
        self._release_refusals(now_s, events)
        return events

    # -- internals: receiving ----------------------------------------------------------------

    def _new_parser(self) -> Any:
        parser = mavlink2.MAVLink(None, self.settings.source_system_id, 0)
        parser.robust_parsing = True  # garbage becomes BAD_DATA messages, never exceptions
        return parser

    def _handle(self, msg: Any, now_s: float, events: list[AutopilotEvent]) -> None:
        kind = msg.get_type()
        if kind == "BAD_DATA":
            self.bad_frames += 1
            return
        if (msg.get_srcSystem(), msg.get_srcComponent()) != self._autopilot_ids:
            self.foreign_messages += 1
            return
        self._latest[kind] = msg
        if kind == "HEARTBEAT":
            beat = self._on_heartbeat(msg, now_s)
            if beat is not None:
                events.append(beat)
        elif kind == "GLOBAL_POSITION_INT":
            self._check_boot(msg.time_boot_ms)
            state = self._on_position(msg, now_s)
            if state is not None:
                events.append(state)
        elif kind == "ATTITUDE":
            self._attitude = msg
        elif kind == "VFR_HUD":
            self._vfr_hud = msg
        elif kind == "SYSTEM_TIME":
            self._check_boot(msg.time_boot_ms)
            self._gps_at_boot_ms = (
                (gps_time_ms_from_unix_us(msg.time_unix_usec), msg.time_boot_ms)
                if msg.time_unix_usec
                else None
            )
        elif kind == "RC_CHANNELS":
            events.append(RcChannels(self._rc_values(_RC_CHANNEL_FIELDS(msg))))
        elif kind == "PARAM_VALUE":
            events.append(self._on_param(msg, now_s))
        elif kind in _MISSION_ANSWERS:
            own = (self.settings.source_system_id, self.settings.source_component_id)
            if self._safety is None or not self._safety.on_mission(msg, own, now_s):
                self._missions.on_answer(msg, own, now_s)
        elif kind in MISSION_PROGRESS_MESSAGES:
            self._missions.on_progress(msg)
        elif kind == "COMMAND_ACK":
            self._on_ack(msg, now_s, events)
        elif kind == "STATUSTEXT":
            events.append(self._on_text(msg, now_s))
        elif kind in _STATUS_MESSAGES:
            status = self._on_status(kind, msg)
            if status is not None:
                events.append(status)
            if kind in _HEALTH_MESSAGES:
                events.append(self.health)
        elif kind == "AUTOPILOT_VERSION":
            first = self._version is None
            self._version = int(msg.flight_sw_version)
            if first:
                self._log.info(
                    "autopilot %d answers: ArduPilot %s",
                    self.settings.system_id,
                    self.flight_sw_version,
                    extra=LogEvent.AUTOPILOT_FOUND.extra,
                )
        if kind in self._wanted:
            self._wanted.discard(kind)
            events.append(AutopilotMessage(kind, self._fields(msg)))

    def _on_text(self, msg: Any, now_s: float) -> AutopilotText:
        severity = int(msg.severity)
        text = str(msg.text)
        shown = printable(text)
        if severity <= mavlink2.MAV_SEVERITY_WARNING:
            self._warnings = [w for w in self._warnings if now_s - w[0] <= REASON_WINDOW_S]
            self._warnings.append((now_s, shown))
        level = (
            logging.WARNING
            if severity <= mavlink2.MAV_SEVERITY_WARNING
            else logging.INFO
            if severity <= mavlink2.MAV_SEVERITY_INFO
            else logging.DEBUG
        )
        self._log.log(
            level,
            "autopilot %d says: %s",
            self.settings.system_id,
            shown,
            extra=LogEvent.AUTOPILOT_TEXT.extra,
        )
        return AutopilotText(severity, text)

    def _on_status(self, kind: str, msg: Any) -> AutopilotStatus | None:
        """Fold one readiness message into :attr:`status`; the new status when it changed."""
        old = self._status
        if kind == "GPS_RAW_INT":
            fixed = int(msg.fix_type) >= mavlink2.GPS_FIX_TYPE_3D_FIX
            self._gps_alt_amsl_m = msg.alt / 1000.0 if fixed else None
            new = replace(old, gps_fix_type=int(msg.fix_type))
        elif kind == "EKF_STATUS_REPORT":
            flags = int(msg.flags)
            ok = bool(flags & EKF_POS_HORIZ_ABS) and not flags & EKF_CONST_POS_MODE
            new = replace(old, position_ok=ok)
        elif kind == "SYS_STATUS":
            reported = int(msg.onboard_control_sensors_present) & PREARM_CHECK_BIT
            healthy = int(msg.onboard_control_sensors_health) & PREARM_CHECK_BIT
            new = replace(old, prearm_ok=bool(healthy) if reported else None)
        elif kind == "HOME_POSITION":
            home = (msg.latitude / 1e7, msg.longitude / 1e7, msg.altitude / 1000.0)
            new = replace(old, home=home)
        else:  # EXTENDED_SYS_STATE
            landed = _LANDED_STATES.get(int(msg.landed_state), LandedState.UNKNOWN)
            new = replace(old, landed=landed)
        if new == old:
            return None
        self._status = new
        if new.ready != old.ready or new.waiting_for != old.waiting_for:
            if new.ready:
                self._log.info(
                    "autopilot %d is ready",
                    self.settings.system_id,
                    extra=LogEvent.AUTOPILOT_READINESS.extra,
                )
            else:
                self._log.info(
                    "autopilot %d waits for %s",
                    self.settings.system_id,
                    ", ".join(new.waiting_for),
                    extra=LogEvent.AUTOPILOT_READINESS.extra,
                )
        return new

    @property
    def health(self) -> AutopilotHealth:
        """Battery, GPS and pre-arm checks from the latest SYS_STATUS and GPS_RAW_INT.

        MAVLink's "not measured" values (voltage 65535, remaining -1, satellites 255)
        become None; a figure outside MAVLink's own range (a garbled or hostile
        message) is None too, never passed on.
        """
        sys_status = self._latest.get("SYS_STATUS")
        gps = self._latest.get("GPS_RAW_INT")
        battery_v: float | None = None
        battery_pct: int | None = None
        if sys_status is not None:
            millivolts = int(sys_status.voltage_battery)
            if 0 <= millivolts < _NOT_MEASURED_MV:
                battery_v = millivolts / 1000.0
            remaining = int(sys_status.battery_remaining)
            battery_pct = remaining if 0 <= remaining <= 100 else None
        satellites: int | None = None
        fix_type = 0
        if gps is not None:
            fix_type = int(gps.fix_type)
            if not 0 <= fix_type <= mavlink2.GPS_FIX_TYPE_PPP:
                fix_type = 0
            visible = int(gps.satellites_visible)
            satellites = visible if 0 <= visible < _UNKNOWN_SATELLITES else None
        return AutopilotHealth(
            battery_v=battery_v,
            battery_pct=battery_pct,
            gps_fix_type=fix_type,
            satellites=satellites,
            prearm_ok=self._status.prearm_ok,
        )

    def _on_heartbeat(self, msg: Any, now_s: float) -> AutopilotHeartbeat | None:
        if msg.autopilot == mavlink2.MAV_AUTOPILOT_INVALID:
            return None  # not a flight controller's heartbeat (a companion sharing the id)
        if self._heartbeat_s is not None and now_s - self._heartbeat_s > (
            self.settings.heartbeat_timeout_s
        ):
            self._reconnected(f"heard again after {now_s - self._heartbeat_s:.1f} s")
        self._heartbeat_s = now_s
        self._check_identity(msg)
        custom_mode = int(msg.custom_mode)
        if self._heartbeat is not None and custom_mode != self._heartbeat.custom_mode:
            # A new mode starts at its default speed, with no guided target.
            self._speed_accepted = None
            self._targeted = False
        beat = AutopilotHeartbeat(
            mode=self._mode_names.get(custom_mode, f"UNKNOWN_{custom_mode}"),
            custom_mode=custom_mode,
            armed=bool(msg.base_mode & mavlink2.MAV_MODE_FLAG_SAFETY_ARMED),
        )
        self._heartbeat = beat
        return beat

    def _check_identity(self, msg: Any) -> None:
        problem = None
        if msg.autopilot != mavlink2.MAV_AUTOPILOT_ARDUPILOTMEGA:
            problem = f"autopilot type {msg.autopilot} is not ArduPilot (3)"
        elif self.settings.firmware is not None:
            allowed = FIRMWARE_VEHICLE_TYPES[self.settings.firmware]
            if msg.type not in allowed:
                problem = (
                    f"vehicle type {msg.type} in HEARTBEAT is not {self.settings.firmware}'s; "
                    "check the autopilot profile (mode numbers differ between firmwares)"
                )
        if problem != self._problem:
            if problem is not None:
                self._log.error(
                    "autopilot %d: %s",
                    self.settings.system_id,
                    problem,
                    extra=LogEvent.AUTOPILOT_IDENTITY.extra,
                )
            self._problem = problem

    def _check_boot(self, time_boot_ms: int) -> None:
        # The boot clock running backwards means the autopilot rebooted: its stream
        # intervals are back to defaults and its SYSTEM_TIME reference is void.
        if self._last_boot_ms is not None and time_boot_ms + 1000 < self._last_boot_ms:
            self._reconnected("rebooted")
        self._last_boot_ms = time_boot_ms

    def _reconnected(self, why: str) -> None:
        """Heard again after a loss, or rebooted: set it up again, and forget every command.

        Nothing decided before the return is sent after it (docs/runtime.md#safety):
        commands still waiting for an answer are dropped, the speed of the last target
        is not sent again, and RC overrides are released at once, so the channels are
        the pilot's until the behaviour overrides them anew.
        """
        self._log.warning(
            "autopilot %d %s; setting it up again",
            self.settings.system_id,
            why,
            extra=LogEvent.AUTOPILOT_BACK.extra,
        )
        stale = [r for r in self._requests if not r.setup]
        if stale:
            self._requests = [r for r in self._requests if r.setup]
            self._log.info(
                "autopilot %d: not sent again after the silence: %s",
                self.settings.system_id,
                ", ".join(r.request for r in stale),
                extra=LogEvent.AUTOPILOT_BACK.extra,
            )
        self._speed_wanted = None
        self._targeted = False
        if self._overrides:
            self._log.info(
                "autopilot %d: RC override of channel(s) %s released to the pilot",
                self.settings.system_id,
                ", ".join(str(c) for c in sorted(self._overrides)),
                extra=LogEvent.AUTOPILOT_BACK.extra,
            )
            released = dict.fromkeys(self._overrides, 0)
            self._overrides.clear()
            self._override_out(released, self._override_sent_s)
        if self._safety is not None:
            self._param_answers.clear()
            self._safety.interrupted("went silent" if why.startswith("heard again") else why)
        self._version = None
        self._verify_attempts = 0
        self._next_verify_s = -math.inf
        self._setup_due = True  # poll asks for the streams again at once
        self._gps_at_boot_ms = None
        self._last_boot_ms = None
        self._speed_accepted = None
        self._speed_retry_s = -math.inf
        self._status = AutopilotStatus()  # a rebooted autopilot gets ready again
        self._gps_alt_amsl_m = None
        self._next_home_request_s = -math.inf

    def _alt_amsl_m(self, msg: Any) -> float:
        """The vehicle's height above sea level, GLOBAL_POSITION_INT's or the GPS's.

        The GPS's while GLOBAL_POSITION_INT's is a fallback estimator's barometer height
        (see :data:`FALLBACK_ALT_GAP_M`).
        """
        fused = float(msg.alt) / 1000.0
        gps = self._gps_alt_amsl_m
        if gps is not None and abs(fused - gps) > FALLBACK_ALT_GAP_M:
            return gps
        return fused

    def _on_position(self, msg: Any, now_s: float) -> VehicleState | None:
        self._position_s = now_s
        self._positions_counted += 1
        if self._heartbeat is None or self._attitude is None:
            return None
        if msg.lat == 0 and msg.lon == 0:
            return None  # ArduPilot's "no position yet" (before its first GPS fix)
        status = self._status
        if status.gps_fix_type < mavlink2.GPS_FIX_TYPE_3D_FIX and not status.position_ok:
            # Not a position yet: ArduPlane dead-reckons from 0, 0 before its fix (SITL
            # drifted 35 m from there, at up to 26 m/s), with no fix and no EKF position.
            return None
        vx_m_s, vy_m_s = msg.vx / 100.0, msg.vy / 100.0
        speed_m_s = math.hypot(vx_m_s, vy_m_s)
        yaw_deg = math.degrees(self._attitude.yaw) % 360.0
        if speed_m_s >= MOVING_SPEED_M_S:
            heading_deg = math.degrees(math.atan2(vy_m_s, vx_m_s)) % 360.0
        else:
            heading_deg = yaw_deg
        gps_ms: int | None = None
        if self._gps_at_boot_ms is not None:
            gps_at, boot_at = self._gps_at_boot_ms
            gps_ms = gps_at + (msg.time_boot_ms - boot_at)
        hud = self._vfr_hud
        state = VehicleState(
            gps_time_ms=gps_ms,
            lat_deg=msg.lat / 1e7,
            lon_deg=msg.lon / 1e7,
            alt_m=self._alt_amsl_m(msg) - self.settings.origin_alt_amsl_m,
            ground_speed_m_s=float(hud.groundspeed) if hud is not None else speed_m_s,
            climb_rate_m_s=float(hud.climb) if hud is not None else -msg.vz / 100.0,
            heading_deg=heading_deg,
            roll_deg=math.degrees(self._attitude.roll),
            pitch_deg=math.degrees(self._attitude.pitch),
            yaw_deg=yaw_deg,
            mode=self._heartbeat.mode,
            custom_mode=self._heartbeat.custom_mode,
            armed=self._heartbeat.armed,
        )
        self._state = state
        return state

    def _rc_values(self, raw: tuple[int, ...]) -> tuple[int, ...]:
        """RC_CHANNELS' widths with "unused" as 0; the last answer again while they repeat.

        They arrive at the stream rate and change only when a stick or an override moves.
        """
        if raw != self._rc_raw:
            self._rc_raw = raw
            self._rc = tuple(0 if v == _UINT16_MAX else int(v) for v in raw)
        return self._rc

    def _on_param(self, msg: Any, now_s: float) -> ParamValue:
        name = str(msg.param_id)
        self._param_types[name] = int(msg.param_type)
        self._requests = [
            r for r in self._requests if not (isinstance(r.key, str) and r.key == name)
        ]
        for answer in self._param_answers.pop(name, ()):
            answer(float(msg.param_value), int(msg.param_type), now_s)
        return ParamValue(
            name=name,
            value=float(msg.param_value),
            param_type=int(msg.param_type),
            index=int(msg.param_index),
            count=int(msg.param_count),
        )

    def _on_ack(self, msg: Any, now_s: float, events: list[AutopilotEvent]) -> None:
        s = self.settings
        if msg.target_system not in (0, s.source_system_id) or msg.target_component not in (
            0,
            s.source_component_id,
        ):
            return  # another ground station's answer
        request = next((r for r in self._requests if r.key == msg.command), None)
        if request is None:
            return  # the version probe, or a late duplicate of a retried command
        if msg.result == mavlink2.MAV_RESULT_IN_PROGRESS:
            request.due_s = now_s + ACK_TIMEOUT_S  # alive; wait for the final answer
            return
        self._requests.remove(request)
        if request.answered is not None:
            request.answered(int(msg.result), now_s)
        elif msg.result != mavlink2.MAV_RESULT_ACCEPTED:
            # Reported once its STATUSTEXT, if any, has had time to arrive.
            refusal = CommandRefused(request.command, _result_name(msg.result), request.request)
            self._refusals.append((now_s + REASON_WAIT_S, refusal, now_s))
        if (
            request.setup
            and msg.command == mavlink2.MAV_CMD_SET_MESSAGE_INTERVAL
            and msg.result == mavlink2.MAV_RESULT_UNSUPPORTED
        ):
            self._legacy_streams_due = True  # firmware older than SET_MESSAGE_INTERVAL

    def _release_refusals(self, now_s: float, events: list[AutopilotEvent]) -> None:
        """Report the refusals whose wait for a reason is over, with their reasons."""
        if not self._refusals or self._refusals[0][0] > now_s:
            return
        while self._refusals and self._refusals[0][0] <= now_s:
            _due, refusal, at_s = self._refusals.pop(0)
            reason = "; ".join(
                text for t, text in self._warnings if at_s - REASON_WINDOW_S <= t <= now_s
            )
            self._log.warning(
                "autopilot refused %s (%s): %s%s",
                refusal.request,
                refusal.command,
                refusal.result,
                f": {reason}" if reason else "",
                extra=LogEvent.AUTOPILOT_REFUSED.extra,
            )
            events.append(replace(refusal, reason=reason))

    @staticmethod
    def _fields(msg: Any) -> dict[str, Any]:
        fields = dict(msg.to_dict())
        fields.pop("mavpackettype", None)
        return fields

    # -- internals: sending ------------------------------------------------------------------

    def _heartbeat_out(self, now_s: float) -> None:
        self._mav.send(
            self._mav.heartbeat_encode(
                mavlink2.MAV_TYPE_GCS,
                mavlink2.MAV_AUTOPILOT_INVALID,
                0,
                0,
                mavlink2.MAV_STATE_ACTIVE,
            )
        )
        # On the period grid, without drift; after a long gap, from now.
        self._next_heartbeat_s += GCS_HEARTBEAT_PERIOD_S
        if self._next_heartbeat_s <= now_s:
            self._next_heartbeat_s = now_s + GCS_HEARTBEAT_PERIOD_S

    def _verify(self, now_s: float) -> None:
        # Untracked on purpose: it repeats until AUTOPILOT_VERSION arrives. Every other
        # attempt uses the older MAV_CMD_REQUEST_AUTOPILOT_CAPABILITIES, for firmware
        # that predates MAV_CMD_REQUEST_MESSAGE.
        s = self.settings
        if self._verify_attempts % 2 == 0:
            command, p1 = (
                mavlink2.MAV_CMD_REQUEST_MESSAGE,
                mavlink2.MAVLINK_MSG_ID_AUTOPILOT_VERSION,
            )
        else:
            command, p1 = mavlink2.MAV_CMD_REQUEST_AUTOPILOT_CAPABILITIES, 1
        self._mav.send(
            self._mav.command_long_encode(
                s.system_id, s.component_id, command, 0, p1, 0, 0, 0, 0, 0, 0
            )
        )
        self._verify_attempts += 1
        self._next_verify_s = now_s + ACK_TIMEOUT_S

    def _request_home(self, now_s: float) -> None:
        # Untracked, like the version probe: until home is set ArduPilot has none to send.
        s = self.settings
        self._mav.send(
            self._mav.command_long_encode(
                s.system_id,
                s.component_id,
                mavlink2.MAV_CMD_REQUEST_MESSAGE,
                0,
                mavlink2.MAVLINK_MSG_ID_HOME_POSITION,
                0,
                0,
                0,
                0,
                0,
                0,
            )
        )
        self._next_home_request_s = now_s + HOME_REQUEST_PERIOD_S

    def _check_stream_rate(self, now_s: float) -> None:
        """Ask for the streams again when positions come at under half the rate asked for.

        Counted over the :data:`STREAM_RATE_CHECK_S` since the last check, and only once
        every stream request has been answered (until then the rate is not yet asked for).
        """
        window_s = now_s - self._rate_check_s
        counted, self._positions_counted = self._positions_counted, 0
        self._rate_check_s = now_s
        if any(r.setup for r in self._requests) or not math.isfinite(window_s):
            return
        rate_hz = counted / window_s
        asked_hz = 1e6 / self._interval_us
        if counted and rate_hz < 0.5 * asked_hz:
            self._log.info(
                "autopilot streams positions at %.1f Hz where %.1f Hz was asked for; "
                "asking for the streams again",
                rate_hz,
                asked_hz,
                extra=LogEvent.AUTOPILOT_STREAMS.extra,
            )
            self._queue_setup(now_s)

    def _queue_setup(self, now_s: float) -> None:
        self._setup_s = now_s
        self._rate_check_s = now_s
        self._positions_counted = 0
        self._setup_due = False
        self._requests = [r for r in self._requests if not r.setup]
        for name in STREAMED_MESSAGES:
            msg_id = _message_id(name)
            interval_us = self._interval_us
            if name in SLOW_STREAMS:
                interval_us = max(interval_us, round(1e6 / SLOW_STREAMS[name]))
            self._requests.append(
                _Request(
                    "MAV_CMD_SET_MESSAGE_INTERVAL",
                    mavlink2.MAV_CMD_SET_MESSAGE_INTERVAL,
                    f"stream {name} every {interval_us} us",
                    self._long_builder(
                        mavlink2.MAV_CMD_SET_MESSAGE_INTERVAL, (msg_id, interval_us)
                    ),
                    setup=True,
                    answered=self._optional_stream(name) if name in OPTIONAL_STREAMS else None,
                    due_s=now_s,
                )
            )

    def _optional_stream(self, name: str) -> Callable[[int | None, float], None]:
        def answered(result: int | None, _now_s: float) -> None:
            if result != mavlink2.MAV_RESULT_ACCEPTED:
                why = "no answer" if result is None else _result_name(result)
                self._log.info(
                    "autopilot does not stream %s (%s)",
                    name,
                    why,
                    extra=LogEvent.AUTOPILOT_STREAMS.extra,
                )

        return answered

    def _long_builder(self, command: int, params: tuple[float, ...]) -> Callable[[int], Any]:
        s = self.settings
        p = (*params, *(0.0,) * (7 - len(params)))

        def build(attempt: int) -> Any:
            return self._mav.command_long_encode(
                s.system_id, s.component_id, command, min(attempt - 1, 255), *p
            )

        return build

    def _command_long(self, command: int, request: str, now_s: float, *params: float) -> None:
        self._track(
            _Request(_command_name(command), command, request, self._long_builder(command, params)),
            now_s,
        )

    def _track(self, request: _Request, now_s: float) -> None:
        request.attempts = 1
        request.due_s = now_s + ACK_TIMEOUT_S
        self._mav.send(request.build(1))
        self._requests.append(request)

    def _send_due(self, now_s: float, *, heard: bool = True) -> None:
        for request in list(self._requests):
            if request.due_s > now_s:
                continue
            if request.setup:
                if not heard and request.attempts > 0:
                    continue  # nobody to ask; the setup is redone when it is heard
            elif request.attempts >= COMMAND_ATTEMPTS:
                self._requests.remove(request)
                self._log.warning(
                    "autopilot did not answer %s (%s) after %d sends",
                    request.request,
                    request.command,
                    request.attempts,
                    extra=LogEvent.AUTOPILOT_UNANSWERED.extra,
                )
                if request.answered is not None:
                    request.answered(None, now_s)
                else:
                    self._late_events.append(
                        CommandRefused(request.command, "NO_ANSWER", request.request)
                    )
                continue
            request.attempts += 1
            request.due_s = now_s + ACK_TIMEOUT_S
            self._mav.send(request.build(request.attempts))

    def _goto(self, cmd: Goto, now_s: float) -> None:
        s = self.settings
        lat_e7, lon_e7 = round(cmd.lat_deg * 1e7), round(cmd.lon_deg * 1e7)
        plane = s.firmware == "arduplane"
        self._speed_wanted = cmd.speed_m_s
        self._targeted = True
        where = f"Goto {cmd.lat_deg:.7f} {cmd.lon_deg:.7f} {cmd.alt_m:g} m above the origin"
        alt_amsl_m = float(cmd.alt_m) + s.origin_alt_amsl_m
        frame = mavlink2.MAV_FRAME_GLOBAL_INT
        if plane:
            self._track(
                _Request(
                    "MAV_CMD_DO_REPOSITION",
                    mavlink2.MAV_CMD_DO_REPOSITION,
                    where,
                    lambda _attempt: self._mav.command_int_encode(
                        s.system_id,
                        s.component_id,
                        frame,
                        mavlink2.MAV_CMD_DO_REPOSITION,
                        0,
                        0,
                        -1,  # speed: default
                        0,  # flags: no mode change; the runtime owns the mode
                        cmd.loiter_radius_m or 0,  # loiter radius (> 0: ModeGuided's)
                        1.0 if cmd.loiter_ccw else math.nan,  # non-zero: counter-clockwise
                        lat_e7,
                        lon_e7,
                        alt_amsl_m,
                    ),
                ),
                now_s,
            )
            return
        time_boot_ms = round((now_s - (self._start_s or 0.0)) * 1000) & 0xFFFFFFFF
        moving = (
            s.firmware == "arducopter"
            and cmd.velocity_north_m_s is not None
            and cmd.velocity_east_m_s is not None
        )
        vn_m_s = float(cmd.velocity_north_m_s or 0.0) if moving else 0.0
        ve_m_s = float(cmd.velocity_east_m_s or 0.0) if moving else 0.0
        self._mav.send(
            self._mav.set_position_target_global_int_encode(
                time_boot_ms,
                s.system_id,
                s.component_id,
                frame,
                POSITION_VELOCITY_TYPE_MASK if moving else POSITION_ONLY_TYPE_MASK,
                lat_e7,
                lon_e7,
                alt_amsl_m,
                vn_m_s,
                ve_m_s,
                0,
                0,
                0,
                0,
                0,
                0,
            )
        )

    def _takeoff(self, cmd: Takeoff, now_s: float) -> None:
        """ArduCopter: MAV_CMD_NAV_TAKEOFF. ArduPlane: TKOFF_ALT, then its TAKEOFF mode.

        ArduPlane's NAV_TAKEOFF is for quadplanes only (FAILED on a fixed wing); a
        fixed wing takes off in its TAKEOFF mode, armed, to TKOFF_ALT, so that
        parameter is set to the altitude asked for first (it is written to the
        autopilot's storage, as any PARAM_SET is). Both take their height above home,
        so the Takeoff's height above the origin is converted with home's altitude.
        """
        above_home_m = self.above_home_m(cmd.alt_m)
        if self.settings.firmware == "arduplane":
            number = self.settings.modes.get("TAKEOFF")
            if number is None:
                self._log.error(
                    "Takeoff: the autopilot profile has no TAKEOFF mode",
                    extra=LogEvent.AUTOPILOT_COMMAND.extra,
                )
                return
            self._param_set("TKOFF_ALT", round(above_home_m), now_s)
            self._command_long(
                mavlink2.MAV_CMD_DO_SET_MODE,
                f"SetMode TAKEOFF ({number}) to take off to {cmd.alt_m:g} m above the origin "
                f"({above_home_m:g} m above home)",
                now_s,
                mavlink2.MAV_MODE_FLAG_CUSTOM_MODE_ENABLED,
                int(number),
            )
            return
        self._command_long(
            mavlink2.MAV_CMD_NAV_TAKEOFF,
            f"takeoff to {cmd.alt_m:g} m above the origin ({above_home_m:g} m above home)",
            now_s,
            0,
            0,
            0,
            math.nan,  # yaw: unchanged
            0,
            0,
            above_home_m,
        )

    def above_home_m(self, alt_m: float) -> float:
        """A height above the origin as a height above home (HOME_POSITION's altitude).

        Before the autopilot reports home, home is taken to be at the origin's height
        (the engine's flat field).
        """
        home = self._status.home
        if home is None:
            return float(alt_m)
        return float(alt_m) - (home[2] - self.settings.origin_alt_amsl_m)

    def _speed(self, now_s: float) -> None:
        """Send the speed the runtime wants, until the autopilot accepts it.

        After the position target, not before: ArduRover refuses a speed change in
        its guided mode until that mode has a target. A refusal or no answer is
        retried :data:`SPEED_RETRY_S` later (by :meth:`poll`); a mode change forgets
        the accepted speed, because ArduPilot starts every mode at its default speed.
        """
        wanted = self._speed_wanted
        if (
            wanted is None
            or wanted == self._speed_accepted
            or not self._targeted
            or now_s < self._speed_retry_s
        ):
            return
        self._speed_retry_s = math.inf  # until answered
        plane = self.settings.firmware == "arduplane"
        self._track(
            _Request(
                "MAV_CMD_DO_CHANGE_SPEED",
                mavlink2.MAV_CMD_DO_CHANGE_SPEED,
                f"speed {wanted:g} m/s",
                self._long_builder(
                    mavlink2.MAV_CMD_DO_CHANGE_SPEED,
                    # SPEED_TYPE_AIRSPEED for ArduPlane (its ground-speed type sets only a
                    # minimum), SPEED_TYPE_GROUNDSPEED otherwise; throttle -1: no change.
                    (0 if plane else 1, wanted, -1),
                ),
                answered=lambda result, at_s: self._speed_answered(wanted, result, at_s),
            ),
            now_s,
        )

    def _speed_answered(self, speed_m_s: float, result: int | None, now_s: float) -> None:
        if result == mavlink2.MAV_RESULT_ACCEPTED:
            self._speed_accepted = speed_m_s
            self._speed_retry_s = -math.inf
            return
        why = "no answer" if result is None else _result_name(result)
        if self._speed_retry_s != now_s + SPEED_RETRY_S:
            self._log.info(
                "autopilot did not take speed %g m/s (%s); sending it again in %g s",
                speed_m_s,
                why,
                SPEED_RETRY_S,
                extra=LogEvent.AUTOPILOT_COMMAND.extra,
            )
        self._speed_retry_s = now_s + SPEED_RETRY_S

    def _rc_override(self, cmd: RcOverride, now_s: float) -> None:
        changes: dict[int, int] = {}
        for channel, pwm_us in cmd.pwm_us.items():
            if not 1 <= channel <= RC_OVERRIDE_CHANNELS or not 0 <= pwm_us < _RC_RELEASE_HIGH:
                self._log.error(
                    "RcOverride channel %d width %d us is outside MAVLink's range; ignored",
                    channel,
                    pwm_us,
                    extra=LogEvent.AUTOPILOT_COMMAND.extra,
                )
                continue
            changes[channel] = pwm_us
            if pwm_us == 0:
                self._overrides.pop(channel, None)
            else:
                self._overrides[channel] = pwm_us
        if changes:
            self._override_out({**self._overrides, **changes}, now_s)

    def _override_out(self, channels: Mapping[int, int], now_s: float) -> None:
        values = [_RC_IGNORE] * RC_OVERRIDE_CHANNELS
        for channel, pwm_us in channels.items():
            if pwm_us == 0:
                values[channel - 1] = _RC_RELEASE_LOW if channel <= 8 else _RC_RELEASE_HIGH
            else:
                values[channel - 1] = pwm_us
        s = self.settings
        self._mav.send(self._mav.rc_channels_override_encode(s.system_id, s.component_id, *values))
        self._override_sent_s = now_s
