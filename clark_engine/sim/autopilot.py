"""A simulated ArduPilot: a MAVLink endpoint in front of a :class:`VehicleModel`.

:class:`SimAutopilot` speaks MAVLink 2 as ArduPilot does, so that the engine's
real :class:`~clark_engine.io.autopilot.AutopilotAdapter` (and pymavlink,
MAVProxy or a ground station, in real-time mode) can fly a simulated vehicle
without knowing it is one. It wraps a :class:`~clark_engine.sim.model.VehicleModel`
(the physics and flight modes) and adds only what the autopilot's MAVLink layer
does: streams at requested intervals, commands and their acknowledgements,
parameters, and the handful of services ground stations probe when they connect.

It is pure and deterministic: no clock, no socket, no randomness. The simulator
hands it incoming bytes with :meth:`SimAutopilot.receive` and collects what it
emits with :meth:`SimAutopilot.advance`; both take the virtual time. Replies to
requests are queued by ``receive`` and leave with the next ``advance``. The
model is stepped by the simulator, not here; sensor noise, if any, is the
model's (its ``truth()`` is reported as it is, but positions come through the model's
``gps_fix()`` when it has one, with the GPS's noise and rate).

What it emits, as ArduPilot does:

- HEARTBEAT at 1 Hz: the firmware's vehicle type, MAV_AUTOPILOT_ARDUPILOTMEGA,
  base_mode with CUSTOM_MODE_ENABLED (and SAFETY_ARMED when armed), custom_mode
  from the model's mode.
- SYS_STATUS, GPS_RAW_INT, GLOBAL_POSITION_INT, ATTITUDE, VFR_HUD, SYSTEM_TIME,
  RC_CHANNELS, SERVO_OUTPUT_RAW at rates from the SR0_* stream parameters by
  default (ArduPilot's stream groups: EXT_STAT, POSITION, EXTRA1, EXTRA2,
  EXTRA3, RC_CHAN), overridden per message by MAV_CMD_SET_MESSAGE_INTERVAL
  (interval -1 stops a message, 0 restores its default) or per group by
  REQUEST_DATA_STREAM.

What it answers (each COMMAND_ACK addressed to whoever asked; several ground
stations, tracked by system and component id, may talk to it at once):

- COMMAND_LONG / COMMAND_INT: DO_SET_MODE, COMPONENT_ARM_DISARM, DO_SET_SERVO,
  DO_CHANGE_SPEED, SET_MESSAGE_INTERVAL, GET_MESSAGE_INTERVAL, REQUEST_MESSAGE
  (HOME_POSITION, AUTOPILOT_VERSION and the streamed messages),
  REQUEST_AUTOPILOT_CAPABILITIES, GET_HOME_POSITION, and DO_REPOSITION
  (COMMAND_INT only); anything else MAV_RESULT_UNSUPPORTED.
- SET_MODE (acknowledged with command = 11, as ArduPilot does);
  SET_POSITION_TARGET_GLOBAL_INT (in the guided mode only; ArduPlane takes
  only the altitude from it, as the real one does); RC_CHANNELS_OVERRIDE (from
  SYSID_MYGCS only, with MAVLink's ignore and release values, each channel
  timing out after RC_OVERRIDE_TIME).
- PARAM_REQUEST_LIST / PARAM_REQUEST_READ / PARAM_SET -> PARAM_VALUE from a
  small table; MISSION_REQUEST_LIST -> MISSION_COUNT 0 (there is never a
  mission; an upload is refused with MISSION_ACK UNSUPPORTED, a clear accepted);
  MISSION_ITEM(_INT) with ``current`` 2, the guided-mode waypoint MAVProxy's
  ``guided`` sends (in the guided mode only), or 3, an altitude change, answered
  with MISSION_ACK as ArduPilot answers them;
  FILE_TRANSFER_PROTOCOL -> a NAK (UnknownCommand), so ground stations fall
  back to the plain parameter protocol; TIMESYNC.

Not simulated: missions (AUTO flies whatever the model does in AUTO), fences,
rally points, velocity or attitude targets, signing, battery (SYS_STATUS
reports the battery as not measured), and more than one MAVLink channel (all
peers share one byte stream, as behind a router).
"""

from __future__ import annotations

import math
import struct
from collections.abc import Callable, Mapping
from dataclasses import dataclass
from typing import Any, Final

from pymavlink.dialects.v20 import ardupilotmega as mavlink2

from clark_engine.sim.model import Truth, VehicleModel

FIRMWARE_TYPES: Final[Mapping[str, int]] = {
    "arduplane": mavlink2.MAV_TYPE_FIXED_WING,
    "arducopter": mavlink2.MAV_TYPE_QUADROTOR,
    "ardurover": mavlink2.MAV_TYPE_GROUND_ROVER,
}
"""HEARTBEAT vehicle type per firmware."""

FIRMWARE_VERSION: Final = (4, 5, 7)
"""The ArduPilot release the simulation claims in AUTOPILOT_VERSION."""

HEARTBEAT_INTERVAL_US: Final = 1_000_000

UINT16_MAX: Final = 65535
_RC_RELEASE_HIGH: Final = UINT16_MAX - 1
_FTP_OP_NAK: Final = 129
_FTP_ERR_UNKNOWN_COMMAND: Final = 7
_FTP_HEADER: Final = struct.Struct("<HBBBBBBI")
_FTP_PAYLOAD_BYTES: Final = 251

STREAM_GROUPS: Final[Mapping[str, str | None]] = {
    "HEARTBEAT": None,
    "SYS_STATUS": "SR0_EXT_STAT",
    "GPS_RAW_INT": "SR0_EXT_STAT",
    "GLOBAL_POSITION_INT": "SR0_POSITION",
    "ATTITUDE": "SR0_EXTRA1",
    "VFR_HUD": "SR0_EXTRA2",
    "SYSTEM_TIME": "SR0_EXTRA3",
    "RC_CHANNELS": "SR0_RC_CHAN",
    "SERVO_OUTPUT_RAW": "SR0_RC_CHAN",
}
"""Streamed messages, in emission order, and the SR0_* parameter (Hz) that sets each
one's default rate (None: HEARTBEAT, always 1 Hz by default)."""

_DATA_STREAM_PARAMS: Final[Mapping[int, str]] = {
    mavlink2.MAV_DATA_STREAM_RAW_SENSORS: "SR0_RAW_SENS",
    mavlink2.MAV_DATA_STREAM_EXTENDED_STATUS: "SR0_EXT_STAT",
    mavlink2.MAV_DATA_STREAM_RC_CHANNELS: "SR0_RC_CHAN",
    mavlink2.MAV_DATA_STREAM_RAW_CONTROLLER: "SR0_RAW_CTRL",
    mavlink2.MAV_DATA_STREAM_POSITION: "SR0_POSITION",
    mavlink2.MAV_DATA_STREAM_EXTRA1: "SR0_EXTRA1",
    mavlink2.MAV_DATA_STREAM_EXTRA2: "SR0_EXTRA2",
    mavlink2.MAV_DATA_STREAM_EXTRA3: "SR0_EXTRA3",
}

_INT8, _INT16, _INT32, _REAL32 = (
    mavlink2.MAV_PARAM_TYPE_INT8,
    mavlink2.MAV_PARAM_TYPE_INT16,
    mavlink2.MAV_PARAM_TYPE_INT32,
    mavlink2.MAV_PARAM_TYPE_REAL32,
)
_INT_RANGES: Final[Mapping[int, tuple[int, int]]] = {
    _INT8: (-128, 127),
    _INT16: (-32768, 32767),
    _INT32: (-(2**31), 2**31 - 1),
}

_COMMON_PARAMS: Final[tuple[tuple[str, float, int], ...]] = (
    ("SYSID_MYGCS", 255, _INT16),
    ("RC_OVERRIDE_TIME", 3.0, _REAL32),
    ("FS_GCS_ENABLE", 0, _INT8),
    ("SR0_RAW_SENS", 0, _INT16),
    ("SR0_EXT_STAT", 2, _INT16),
    ("SR0_RC_CHAN", 2, _INT16),
    ("SR0_RAW_CTRL", 0, _INT16),
    ("SR0_POSITION", 4, _INT16),
    ("SR0_EXTRA1", 4, _INT16),
    ("SR0_EXTRA2", 4, _INT16),
    ("SR0_EXTRA3", 1, _INT16),
    ("SR0_PARAMS", 10, _INT16),
)
"""Parameters every firmware has (after SYSID_THISMAV), with ArduPilot's defaults, except
the SR0_* stream rates: ArduPilot's depend on the board, these are typical GCS settings."""

_FIRMWARE_PARAMS: Final[Mapping[str, tuple[tuple[str, float, int], ...]]] = {
    "arduplane": (
        ("AIRSPEED_CRUISE", 15.0, _REAL32),
        ("AIRSPEED_MIN", 9, _INT16),
        ("AIRSPEED_MAX", 22, _INT16),
        ("WP_RADIUS", 90, _INT16),
    ),
    "arducopter": (
        ("WPNAV_SPEED", 1000.0, _REAL32),
        ("WPNAV_SPEED_UP", 250.0, _REAL32),
        ("RTL_ALT", 1500, _INT32),
        ("FRAME_CLASS", 1, _INT8),
    ),
    "ardurover": (
        ("CRUISE_SPEED", 2.0, _REAL32),
        ("CRUISE_THROTTLE", 50, _INT8),
        ("WP_SPEED", 2.0, _REAL32),
        ("WP_RADIUS", 2.0, _REAL32),
    ),
}
"""A few parameters per firmware with ArduPilot's defaults (units as ArduPilot's)."""


@dataclass(slots=True)
class _Param:
    value: float
    param_type: int


@dataclass(frozen=True, slots=True)
class _Asker:
    """Who sent the message being answered."""

    system_id: int
    component_id: int


class _Outbox:
    def __init__(self) -> None:
        self.data = bytearray()

    def write(self, data: bytes) -> None:
        self.data += data


def _msg_id(name: str) -> int:
    return int(getattr(mavlink2, f"MAVLINK_MSG_ID_{name}"))


def _clamp(value: float, low: int, high: int) -> int:
    rounded = round(value)  # (comparisons, not min and max: several per streamed message)
    return low if rounded < low else high if rounded > high else rounded


class SimAutopilot:
    """One simulated ArduPilot autopilot; see the module docstring for what it does.

    Args:
        model: The vehicle it flies.
        firmware: ``arduplane``, ``arducopter`` or ``ardurover``.
        system_id: Its MAVLink system id (SYSID_THISMAV).
        component_id: Its component id (1).
        modes: Mode name -> custom_mode number; the model's by default.
        guided_mode: The mode in which position targets are flown.
        home_lat_deg: Home latitude (the mission origin).
        home_lon_deg: Home longitude.
        home_alt_m: Home altitude above mean sea level; GLOBAL_POSITION_INT's ``alt``
            is this plus the model's height above home.
        start_time_unix_us: Unix time at ``boot_s``, as its GPS would know it; None
            for a GPS without time (SYSTEM_TIME then carries 0, as ArduPilot's does).
        boot_s: The simulator time at which it boots (``time_boot_ms`` counts from here).
        params: Parameter values to start from instead of the defaults (names must
            exist in its table).

    Raises:
        ValueError: Unknown firmware or parameter name.
    """

    def __init__(
        self,
        model: VehicleModel,
        *,
        firmware: str,
        system_id: int = 1,
        component_id: int = 1,
        modes: Mapping[str, int] | None = None,
        guided_mode: str = "GUIDED",
        home_lat_deg: float,
        home_lon_deg: float,
        home_alt_m: float = 0.0,
        start_time_unix_us: int | None = None,
        boot_s: float = 0.0,
        params: Mapping[str, float] | None = None,
    ) -> None:
        if firmware not in FIRMWARE_TYPES:
            raise ValueError(f"unknown firmware {firmware!r}; use one of {sorted(FIRMWARE_TYPES)}")
        self.model = model
        self.firmware = firmware
        self._sysid = system_id
        self._compid = component_id
        self.modes: Mapping[str, int] = dict(modes if modes is not None else model.modes)
        self._mode_names = {number: name for name, number in reversed(self.modes.items())}
        self.guided_mode = guided_mode
        self.home_lat_deg = home_lat_deg
        self.home_lon_deg = home_lon_deg
        self.home_alt_m = home_alt_m
        self.start_time_unix_us = start_time_unix_us
        self.boot_s = boot_s

        self._outbox = _Outbox()
        self._mav = mavlink2.MAVLink(self._outbox, srcSystem=system_id, srcComponent=component_id)
        self._parser = mavlink2.MAVLink(None, system_id, component_id)
        self._parser.robust_parsing = True

        self._interval_us: dict[str, int | None] = {}  # per-message overrides; None: stopped
        self._due_us: dict[str, int] = {}
        self._next_due_us = 0  # earliest due time over every stream (0: look again)
        # Every stream's interval, in emission order, for advance() to go through whenever
        # something is due; None: to be worked out again (a parameter or an interval changed).
        self._schedule: tuple[tuple[str, int | None], ...] | None = None
        # Message name -> the method that builds it, looked up once rather than per message.
        self._builders: dict[str, Callable[[float], Any]] = {
            name: getattr(self, f"_msg_{name.lower()}")
            for name in (*STREAM_GROUPS, "HOME_POSITION", "AUTOPILOT_VERSION")
        }
        self._boot_ms_at_s = math.nan  # _boot_ms' last time (never equal to a time) and value
        self._boot_ms_value = 0
        # The truth every message built by one advance() call reports (see _truth).
        self._advancing = False
        self._advance_truth: Truth | None = None
        # The RC inputs RC_CHANNELS last reported, and that message, to send again.
        self._rc_key: tuple[int, ...] | None = None
        self._rc_message: Any = None
        # Messages sent again and again with new values (see _msg_global_position_int).
        self._position_message = self._mav.global_position_int_encode(0, 0, 0, 0, 0, 0, 0, 0, 0)
        self._attitude_message = self._mav.attitude_encode(0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0)
        self._hud_message = self._mav.vfr_hud_encode(0.0, 0.0, 0, 0, 0.0, 0.0)
        self._deferred: list[str] = []  # messages asked for, sent after the acknowledgement
        self._params: dict[str, _Param] = {"SYSID_THISMAV": _Param(system_id, _INT16)}
        for name, value, kind in (*_COMMON_PARAMS, *_FIRMWARE_PARAMS[firmware]):
            self._params[name] = _Param(float(value), kind)
        for name, value in (params or {}).items():
            if name not in self._params:
                raise ValueError(f"no parameter {name!r} in the simulated {firmware}")
            self._set_param(name, value)

        self._overrides: dict[int, tuple[int, float]] = {}  # channel -> (width, set at)
        self._target: tuple[float, float, float] | None = None  # guided lat, lon, alt
        self._speed_m_s: float | None = None
        self._peers: dict[tuple[int, int], float] = {}

        self.bad_frames = 0
        """Garbage and corrupted frames received."""

    @classmethod
    def from_profile(
        cls,
        model: VehicleModel,
        autopilot: Mapping[str, Any],
        *,
        home_lat_deg: float,
        home_lon_deg: float,
        home_alt_m: float = 0.0,
        start_time_unix_us: int | None = None,
        boot_s: float = 0.0,
    ) -> SimAutopilot:
        """The autopilot a resolved profile (``agent.hardware.autopilot``) describes.

        Firmware, ids, modes and guided mode come from the profile, so the engine's
        adapter, built from the same profile, finds it where it expects it.
        """
        mav = autopilot.get("mavlink") or {}
        return cls(
            model,
            firmware=str(autopilot["firmware"]),
            system_id=int(mav.get("system_id", 1)),
            component_id=int(mav.get("component_id", 1)),
            modes=dict(autopilot.get("modes") or model.modes),
            guided_mode=str(autopilot.get("guided_mode", "GUIDED")),
            home_lat_deg=home_lat_deg,
            home_lon_deg=home_lon_deg,
            home_alt_m=home_alt_m,
            start_time_unix_us=start_time_unix_us,
            boot_s=boot_s,
        )

    # -- public -----------------------------------------------------------------------------

    @property
    def sysid(self) -> int:
        """Its MAVLink system id."""
        return self._sysid

    @property
    def gcs_peers(self) -> Mapping[tuple[int, int], float]:
        """Ground stations heard: (system id, component id) -> time of their last heartbeat."""
        return dict(self._peers)

    def param(self, name: str) -> float | None:
        """A parameter's value, None if it has no such parameter."""
        entry = self._params.get(name)
        return None if entry is None else entry.value

    def receive(self, data: bytes, now_s: float) -> None:
        """Take bytes from the ground station side and act on every complete message.

        Garbage and corrupted frames are counted and skipped. Answers leave with the
        next :meth:`advance`.
        """
        for msg in self._parser.parse_buffer(data) or []:
            if msg.get_type() == "BAD_DATA":
                self.bad_frames += 1
                continue
            self._handle(msg, now_s)

    def advance(self, now_s: float) -> bytes:
        """Everything due by ``now_s``: queued answers first, then the streams due.

        Each stream is due on its own grid of intervals from its first emission
        (integer microseconds, so a virtual clock keeps exact rates); a message is
        sent at most once per call, so call at least as often as the fastest rate.
        RC overrides older than RC_OVERRIDE_TIME are released first.
        """
        if self._overrides:  # (usually there are none: a call saved at every step)
            self._expire_overrides(now_s)
        now_us = round(now_s * 1e6)
        if now_us < self._next_due_us and not self._outbox.data:
            return b""  # nothing due and no answer queued: the common case, kept cheap
        due_us, send, builders = self._due_us, self._mav.send, self._builders
        self._advancing = True
        for name, interval in self._stream_schedule():
            if interval is None:
                due_us.pop(name, None)
                continue
            due = due_us.setdefault(name, now_us)
            if now_us < due:
                continue
            send(builders[name](now_s))
            due += interval
            due_us[name] = due if due > now_us else now_us + interval
        self._advancing = False
        self._advance_truth = None
        self._next_due_us = min(due_us.values(), default=now_us)
        data, self._outbox.data = bytes(self._outbox.data), bytearray()
        return data

    # -- streams -----------------------------------------------------------------------------

    def _stream_schedule(self) -> tuple[tuple[str, int | None], ...]:
        """(message, interval in us or None when stopped) for every stream, in emission order."""
        if self._schedule is None:
            self._schedule = tuple((name, self._stream_interval_us(name)) for name in STREAM_GROUPS)
        return self._schedule

    def _stream_interval_us(self, name: str) -> int | None:
        if name in self._interval_us:
            return self._interval_us[name]
        return self._default_interval_us(name)

    def _default_interval_us(self, name: str) -> int | None:
        group = STREAM_GROUPS.get(name)
        if group is None:
            return HEARTBEAT_INTERVAL_US if name == "HEARTBEAT" else None
        rate_hz = self._params[group].value
        return round(1e6 / rate_hz) if rate_hz > 0 else None

    def _set_interval(self, name: str, interval_us: int | None, now_s: float) -> None:
        self._next_due_us = 0  # the schedule changed: look at every stream next time
        self._schedule = None
        self._interval_us[name] = interval_us
        if interval_us is not None:
            self._due_us[name] = round(now_s * 1e6) + interval_us

    def _boot_ms(self, now_s: float) -> int:
        # Kept for the next call at the same time: up to four messages of one advance()
        # carry it.
        if now_s != self._boot_ms_at_s:
            self._boot_ms_at_s = now_s
            self._boot_ms_value = max(0, round((now_s - self.boot_s) * 1000)) & 0xFFFFFFFF
        return self._boot_ms_value

    def _unix_us(self, now_s: float) -> int:
        if self.start_time_unix_us is None:
            return 0
        return self.start_time_unix_us + round((now_s - self.boot_s) * 1e6)

    def _build(self, name: str, now_s: float) -> Any:
        return self._builders[name](now_s)

    def _truth(self) -> Truth:
        """The model's true state, for the message builders.

        Within one :meth:`advance` call the model does not move, and up to five of the
        messages it sends report its state: it is read once per call. Outside one
        (answers to requests, which follow commands that may change the model) it is
        read afresh.
        """
        truth = self._advance_truth
        if truth is None:
            truth = self.model.truth()
            if self._advancing:
                self._advance_truth = truth
        return truth

    def _msg_heartbeat(self, now_s: float) -> Any:
        armed = self.model.armed
        base_mode = mavlink2.MAV_MODE_FLAG_CUSTOM_MODE_ENABLED
        if armed:
            base_mode |= mavlink2.MAV_MODE_FLAG_SAFETY_ARMED
        return self._mav.heartbeat_encode(
            FIRMWARE_TYPES[self.firmware],
            mavlink2.MAV_AUTOPILOT_ARDUPILOTMEGA,
            base_mode,
            self.modes.get(self.model.mode, 0),
            mavlink2.MAV_STATE_ACTIVE if armed else mavlink2.MAV_STATE_STANDBY,
        )

    def _msg_sys_status(self, now_s: float) -> Any:
        sensors = (
            mavlink2.MAV_SYS_STATUS_SENSOR_3D_GYRO
            | mavlink2.MAV_SYS_STATUS_SENSOR_3D_ACCEL
            | mavlink2.MAV_SYS_STATUS_SENSOR_3D_MAG
            | mavlink2.MAV_SYS_STATUS_SENSOR_ABSOLUTE_PRESSURE
            | mavlink2.MAV_SYS_STATUS_SENSOR_GPS
            | mavlink2.MAV_SYS_STATUS_SENSOR_RC_RECEIVER
            | mavlink2.MAV_SYS_STATUS_AHRS
        )
        # Battery not measured: UINT16_MAX volts, -1 current and remaining (MAVLink's "unknown").
        return self._mav.sys_status_encode(
            sensors, sensors, sensors, 100, UINT16_MAX, -1, -1, 0, 0, 0, 0, 0, 0
        )

    def _position(self) -> tuple[float, float, float]:
        """Latitude, longitude and height above home as the GPS reports them.

        A model with a GPS (``gps_fix``: seeded noise at the receiver's rate) is read
        through it, as ArduPilot reads its receiver; otherwise the truth is reported.
        """
        fix = getattr(self.model, "gps_fix", None)
        if fix is not None:
            lat, lon, alt = fix()
            return float(lat), float(lon), float(alt)
        t = self._truth()
        return t.lat_deg, t.lon_deg, t.up_m

    def _msg_gps_raw_int(self, now_s: float) -> Any:
        t = self._truth()
        lat, lon, up = self._position()
        unix_us = self._unix_us(now_s)
        return self._mav.gps_raw_int_encode(
            unix_us if unix_us else round((now_s - self.boot_s) * 1e6),
            mavlink2.GPS_FIX_TYPE_3D_FIX,
            round(lat * 1e7),
            round(lon * 1e7),
            round((self.home_alt_m + up) * 1000),
            121,  # HDOP 1.21
            200,  # VDOP 2.00
            _clamp(t.ground_speed_m_s * 100, 0, UINT16_MAX - 1),
            round((t.heading_deg % 360.0) * 100) % 36000,
            12,
        )

    # GLOBAL_POSITION_INT, ATTITUDE and VFR_HUD go out at the telemetry rate: each is one
    # pymavlink message object (built in __init__) whose fields are set before every send,
    # which packs it anew, rather than a new object each time.

    def _msg_global_position_int(self, now_s: float) -> Any:
        t = self._truth()
        lat, lon, up = self._position()
        msg = self._position_message
        msg.time_boot_ms = self._boot_ms(now_s)
        msg.lat = round(lat * 1e7)
        msg.lon = round(lon * 1e7)
        msg.alt = round((self.home_alt_m + up) * 1000)
        msg.relative_alt = round(up * 1000)
        msg.vx = _clamp(t.velocity_north_m_s * 100, -32768, 32767)
        msg.vy = _clamp(t.velocity_east_m_s * 100, -32768, 32767)
        msg.vz = _clamp(-t.climb_rate_m_s * 100, -32768, 32767)
        msg.hdg = round((t.yaw_deg % 360.0) * 100) % 36000
        return msg

    def _msg_attitude(self, now_s: float) -> Any:
        t = self._truth()
        msg = self._attitude_message  # body rates stay 0: the model has none to report
        msg.time_boot_ms = self._boot_ms(now_s)
        msg.roll = math.radians(t.roll_deg)
        msg.pitch = math.radians(t.pitch_deg)
        msg.yaw = math.radians(math.remainder(t.yaw_deg, 360.0))
        return msg

    def _msg_vfr_hud(self, now_s: float) -> Any:
        t = self._truth()
        msg = self._hud_message
        msg.airspeed = t.airspeed_m_s
        msg.groundspeed = t.ground_speed_m_s
        msg.heading = int(t.yaw_deg % 360.0)
        msg.throttle = _clamp(t.throttle_pct, 0, 100)
        msg.alt = self.home_alt_m + t.up_m
        msg.climb = t.climb_rate_m_s
        return msg

    def _msg_system_time(self, now_s: float) -> Any:
        return self._mav.system_time_encode(self._unix_us(now_s), self._boot_ms(now_s))

    def _msg_rc_channels(self, now_s: float) -> Any:
        # The inputs change only when a stick or an override moves: the message is built
        # anew then, and otherwise sent again with only its time updated (21 fields).
        inputs = tuple(self.model.rc_inputs())
        if inputs != self._rc_key or self._rc_message is None:
            used = list(inputs)[:18]
            values = [_clamp(v, 0, UINT16_MAX) if v else UINT16_MAX for v in used]
            values += [UINT16_MAX] * (18 - len(values))
            self._rc_key = inputs
            self._rc_message = self._mav.rc_channels_encode(0, len(used), *values, 255)
        self._rc_message.time_boot_ms = self._boot_ms(now_s)
        return self._rc_message

    def _msg_servo_output_raw(self, now_s: float) -> Any:
        outputs = [_clamp(v, 0, UINT16_MAX) for v in list(self.model.servo_outputs())[:16]]
        outputs += [0] * (16 - len(outputs))
        time_us = max(0, round((now_s - self.boot_s) * 1e6)) & 0xFFFFFFFF
        return self._mav.servo_output_raw_encode(time_us, 0, *outputs)

    def _msg_home_position(self, now_s: float) -> Any:
        return self._mav.home_position_encode(
            round(self.home_lat_deg * 1e7),
            round(self.home_lon_deg * 1e7),
            round(self.home_alt_m * 1000),
            0.0,
            0.0,
            0.0,
            [1.0, 0.0, 0.0, 0.0],
            0.0,
            0.0,
            0.0,
        )

    def _msg_autopilot_version(self, now_s: float) -> Any:
        major, minor, patch = FIRMWARE_VERSION
        capabilities = (
            mavlink2.MAV_PROTOCOL_CAPABILITY_MISSION_FLOAT
            | mavlink2.MAV_PROTOCOL_CAPABILITY_PARAM_FLOAT
            | mavlink2.MAV_PROTOCOL_CAPABILITY_MISSION_INT
            | mavlink2.MAV_PROTOCOL_CAPABILITY_COMMAND_INT
            | mavlink2.MAV_PROTOCOL_CAPABILITY_SET_POSITION_TARGET_GLOBAL_INT
            | mavlink2.MAV_PROTOCOL_CAPABILITY_MAVLINK2
            | mavlink2.MAV_PROTOCOL_CAPABILITY_PARAM_ENCODE_C_CAST
        )
        version = (
            (major << 24) | (minor << 16) | (patch << 8) | mavlink2.FIRMWARE_VERSION_TYPE_OFFICIAL
        )
        zeros8 = [0] * 8
        uid = int.from_bytes(b"CLARK", "big") << 16 | self._sysid << 8 | self._compid
        return self._mav.autopilot_version_encode(
            capabilities, version, 0, 0, 0, zeros8, zeros8, zeros8, 0, 0, uid
        )

    # -- handling ---------------------------------------------------------------------------

    def _handle(self, msg: Any, now_s: float) -> None:
        source = (msg.get_srcSystem(), msg.get_srcComponent())
        if source == (self._sysid, self._compid):
            return  # our own frames echoed back by a shared link
        target_system = getattr(msg, "target_system", 0)
        target_component = getattr(msg, "target_component", 0)
        if target_system not in (0, self._sysid) or target_component not in (0, self._compid):
            return  # addressed to another vehicle or component
        asker = _Asker(*source)
        kind = msg.get_type()
        if kind == "HEARTBEAT":
            if msg.type == mavlink2.MAV_TYPE_GCS or msg.autopilot == mavlink2.MAV_AUTOPILOT_INVALID:
                self._peers[source] = now_s
        elif kind == "COMMAND_LONG":
            params = (msg.param1, msg.param2, msg.param3, msg.param4, msg.param5, msg.param6)
            result = self._command(msg.command, params, msg.param7, None, now_s)
            self._ack(msg.command, result, asker)
            self._send_deferred(now_s)
        elif kind == "COMMAND_INT":
            params = (msg.param1, msg.param2, msg.param3, msg.param4, msg.x, msg.y)
            result = self._command(msg.command, params, msg.z, msg.frame, now_s)
            self._ack(msg.command, result, asker)
            self._send_deferred(now_s)
        elif kind == "SET_MODE":
            result = self._set_mode(msg.base_mode, msg.custom_mode)
            self._ack(_msg_id("SET_MODE"), result, asker)
        elif kind == "SET_POSITION_TARGET_GLOBAL_INT":
            self._position_target(msg)
        elif kind == "RC_CHANNELS_OVERRIDE":
            self._rc_override(msg, now_s)
        elif kind == "PARAM_REQUEST_LIST":
            for index, name in enumerate(self._params):
                self._send_param(name, index)
        elif kind == "PARAM_REQUEST_READ":
            self._param_read(msg)
        elif kind == "PARAM_SET":
            name = str(msg.param_id)
            if name in self._params:  # ArduPilot ignores unknown names without a word
                self._set_param(name, msg.param_value)
                self._send_param(name, list(self._params).index(name))
        elif kind == "REQUEST_DATA_STREAM":
            self._request_data_stream(msg)
        elif kind == "MISSION_REQUEST_LIST":
            self._mav.send(
                self._mav.mission_count_encode(
                    asker.system_id, asker.component_id, 0, msg.mission_type
                )
            )
        elif kind == "MISSION_COUNT":
            self._mav.send(
                self._mav.mission_ack_encode(
                    asker.system_id,
                    asker.component_id,
                    mavlink2.MAV_MISSION_UNSUPPORTED,
                    msg.mission_type,
                )
            )
        elif kind in ("MISSION_ITEM_INT", "MISSION_ITEM"):
            result = self._mission_item(msg, integer=kind == "MISSION_ITEM_INT")
            self._mav.send(
                self._mav.mission_ack_encode(
                    asker.system_id, asker.component_id, result, msg.mission_type
                )
            )
        elif kind == "MISSION_CLEAR_ALL":
            self._mav.send(
                self._mav.mission_ack_encode(
                    asker.system_id,
                    asker.component_id,
                    mavlink2.MAV_MISSION_ACCEPTED,
                    msg.mission_type,
                )
            )
        elif kind == "FILE_TRANSFER_PROTOCOL":
            self._ftp_nak(msg, asker)
        elif kind == "TIMESYNC" and msg.tc1 == 0:
            self._mav.send(self._mav.timesync_encode(round((now_s - self.boot_s) * 1e9), msg.ts1))

    def _ack(self, command: int, result: int, asker: _Asker) -> None:
        self._mav.send(
            self._mav.command_ack_encode(command, result, 0, 0, asker.system_id, asker.component_id)
        )

    def _send_deferred(self, now_s: float) -> None:
        for name in self._deferred:
            self._mav.send(self._build(name, now_s))
        self._deferred.clear()

    def _command(
        self, command: int, params: tuple[float, ...], z: float, frame: int | None, now_s: float
    ) -> int:
        """Carry out one COMMAND_LONG (``frame`` None) or COMMAND_INT; returns MAV_RESULT."""
        p1, p2 = params[0], params[1]
        if command == mavlink2.MAV_CMD_DO_SET_MODE:
            return self._set_mode(int(p1), int(p2))
        if command == mavlink2.MAV_CMD_COMPONENT_ARM_DISARM:
            if p1 not in (0.0, 1.0):
                return int(mavlink2.MAV_RESULT_UNSUPPORTED)
            return self._result(self.model.arm(p1 == 1.0))
        if command == mavlink2.MAV_CMD_DO_SET_SERVO:
            servo = int(p1)
            if not 1 <= servo <= 16:
                return int(mavlink2.MAV_RESULT_FAILED)
            self.model.set_servo(servo, int(p2))
            return int(mavlink2.MAV_RESULT_ACCEPTED)
        if command == mavlink2.MAV_CMD_DO_CHANGE_SPEED:
            return self._change_speed(p2)
        if command == mavlink2.MAV_CMD_SET_MESSAGE_INTERVAL:
            return self._message_interval(int(p1), int(p2), now_s)
        if command == mavlink2.MAV_CMD_GET_MESSAGE_INTERVAL:
            name = self._streamed_name(int(p1))
            if name is None:
                return int(mavlink2.MAV_RESULT_FAILED)
            interval = self._stream_interval_us(name)
            self._mav.send(
                self._mav.message_interval_encode(int(p1), -1 if interval is None else interval)
            )
            return int(mavlink2.MAV_RESULT_ACCEPTED)
        if command == mavlink2.MAV_CMD_REQUEST_MESSAGE:
            return self._request_message(int(p1))
        if command == mavlink2.MAV_CMD_REQUEST_AUTOPILOT_CAPABILITIES:
            if p1 != 1.0:
                return int(mavlink2.MAV_RESULT_DENIED)
            return self._request_message(_msg_id("AUTOPILOT_VERSION"))
        if command == mavlink2.MAV_CMD_GET_HOME_POSITION:
            return self._request_message(_msg_id("HOME_POSITION"))
        if command == mavlink2.MAV_CMD_DO_REPOSITION and frame is not None:
            return self._reposition(params, z, frame)
        return int(mavlink2.MAV_RESULT_UNSUPPORTED)

    @staticmethod
    def _result(ok: bool) -> int:
        return int(mavlink2.MAV_RESULT_ACCEPTED if ok else mavlink2.MAV_RESULT_FAILED)

    def _set_mode(self, base_mode: int, custom_mode: int) -> int:
        # Like ArduPilot: only custom modes; an unknown number or a refusal is FAILED.
        if not base_mode & mavlink2.MAV_MODE_FLAG_CUSTOM_MODE_ENABLED:
            return int(mavlink2.MAV_RESULT_DENIED)
        name = self._mode_names.get(custom_mode)
        if name is None or not self.model.set_mode(name):
            return int(mavlink2.MAV_RESULT_FAILED)
        if name != self.guided_mode:
            self._target = None  # ArduPilot forgets the guided target on leaving guided
        return int(mavlink2.MAV_RESULT_ACCEPTED)

    def _in_guided(self) -> bool:
        return self.model.mode == self.guided_mode

    def _goto(self, lat_deg: float, lon_deg: float, alt_m: float) -> bool:
        self._target = (lat_deg, lon_deg, alt_m)
        return self.model.goto(lat_deg, lon_deg, alt_m, self._speed_m_s)

    def _relative_alt_m(self, alt: float, frame: int) -> float | None:
        if frame in (
            mavlink2.MAV_FRAME_GLOBAL_RELATIVE_ALT_INT,
            mavlink2.MAV_FRAME_GLOBAL_RELATIVE_ALT,
            mavlink2.MAV_FRAME_GLOBAL_TERRAIN_ALT_INT,  # flat terrain at home's altitude
            mavlink2.MAV_FRAME_GLOBAL_TERRAIN_ALT,
        ):
            return float(alt)
        if frame in (mavlink2.MAV_FRAME_GLOBAL_INT, mavlink2.MAV_FRAME_GLOBAL):
            return float(alt) - self.home_alt_m
        return None

    def _change_speed(self, speed_m_s: float) -> int:
        if speed_m_s <= 0:
            return int(mavlink2.MAV_RESULT_FAILED)  # -1 is "no change"; nothing to do
        if self.firmware == "arduplane" and self.model.mode not in (self.guided_mode, "AUTO"):
            return int(mavlink2.MAV_RESULT_FAILED)  # ArduPlane: guided and auto only
        self._speed_m_s = float(speed_m_s)
        if self._target is not None and self._in_guided():
            self._goto(*self._target)
        return int(mavlink2.MAV_RESULT_ACCEPTED)

    def _reposition(self, params: tuple[float, ...], z: float, frame: int) -> int:
        speed, flags, lat_e7, lon_e7 = params[0], int(params[1]), params[4], params[5]
        alt_m = self._relative_alt_m(z, frame)
        if alt_m is None or not (abs(lat_e7) <= 90e7 and abs(lon_e7) <= 180e7):
            return int(mavlink2.MAV_RESULT_DENIED)
        change_mode = bool(flags & mavlink2.MAV_DO_REPOSITION_FLAGS_CHANGE_MODE)
        if change_mode and not self._in_guided():
            self.model.set_mode(self.guided_mode)
        if not self._in_guided():
            return int(mavlink2.MAV_RESULT_FAILED)
        if speed > 0:
            self._speed_m_s = float(speed)
        return self._result(self._goto(lat_e7 / 1e7, lon_e7 / 1e7, alt_m))

    def _mission_item(self, msg: Any, *, integer: bool) -> int:
        """A mission item outside an upload: ArduPilot's guided waypoint and altitude change.

        As ArduPilot's GCS_MAVLINK::handle_mission_item: ``current`` 2 is a guided-mode
        waypoint (accepted in the guided mode only; MAVProxy's ``guided LAT LON ALT``
        sends one), ``current`` 3 an altitude change (always accepted); any other item
        arrives outside an upload, which is an error (uploads are refused here).
        """
        if msg.mission_type != mavlink2.MAV_MISSION_TYPE_MISSION:
            return int(mavlink2.MAV_MISSION_UNSUPPORTED)
        if msg.current not in (2, 3):
            return int(mavlink2.MAV_MISSION_ERROR)
        alt_m = self._relative_alt_m(msg.z, msg.frame)
        lat_deg, lon_deg = (msg.x / 1e7, msg.y / 1e7) if integer else (msg.x, msg.y)
        if alt_m is None or not (abs(lat_deg) <= 90 and abs(lon_deg) <= 180):
            return int(mavlink2.MAV_MISSION_UNSUPPORTED_FRAME)
        if msg.current == 3:
            if self._target is not None and self._in_guided():
                self._goto(self._target[0], self._target[1], alt_m)
            return int(mavlink2.MAV_MISSION_ACCEPTED)
        if not self._in_guided() or not self._goto(lat_deg, lon_deg, alt_m):
            return int(mavlink2.MAV_MISSION_ERROR)
        return int(mavlink2.MAV_MISSION_ACCEPTED)

    def _position_target(self, msg: Any) -> None:
        if not self._in_guided():
            return  # ArduPilot drops position targets outside guided
        alt_m = self._relative_alt_m(msg.alt, msg.coordinate_frame)
        if alt_m is None:
            return
        mask = msg.type_mask
        position_ignored = mask & (
            mavlink2.POSITION_TARGET_TYPEMASK_X_IGNORE | mavlink2.POSITION_TARGET_TYPEMASK_Y_IGNORE
        )
        if self.firmware == "arduplane":
            # ArduPlane takes only the altitude of this message (its GCS_Mavlink.cpp).
            if mask & mavlink2.POSITION_TARGET_TYPEMASK_Z_IGNORE:
                return
            if self._target is not None:
                lat_deg, lon_deg, _ = self._target
            else:
                truth: Truth = self.model.truth()
                lat_deg, lon_deg = truth.lat_deg, truth.lon_deg
            self._goto(lat_deg, lon_deg, alt_m)
            return
        if position_ignored:
            return  # velocity and acceleration targets are not simulated
        self._goto(msg.lat_int / 1e7, msg.lon_int / 1e7, alt_m)

    def _rc_override(self, msg: Any, now_s: float) -> None:
        if msg.get_srcSystem() != round(self._params["SYSID_MYGCS"].value):
            return  # ArduPilot takes overrides only from its ground station
        if self._params["RC_OVERRIDE_TIME"].value == 0:
            return  # overrides disabled
        changes: dict[int, int] = {}
        for channel in range(1, 19):
            value = getattr(msg, f"chan{channel}_raw")
            if channel <= 8:
                if value == UINT16_MAX:
                    continue
                release = value == 0
            else:
                if value in (0, UINT16_MAX):
                    continue
                release = value == _RC_RELEASE_HIGH
            if release:
                if self._overrides.pop(channel, None) is not None:
                    changes[channel] = 0
            else:
                self._overrides[channel] = (int(value), now_s)
                changes[channel] = int(value)
        if changes:
            self.model.set_rc_override(changes)

    def _expire_overrides(self, now_s: float) -> None:
        timeout_s = self._params["RC_OVERRIDE_TIME"].value
        if timeout_s < 0 or not self._overrides:
            return  # negative: overrides never time out
        expired = {
            ch: 0 for ch, (_pwm, at_s) in self._overrides.items() if now_s - at_s > timeout_s
        }
        for channel in expired:
            del self._overrides[channel]
        if expired:
            self.model.set_rc_override(expired)

    # -- parameters --------------------------------------------------------------------------

    def _set_param(self, name: str, value: float) -> None:
        self._next_due_us = 0  # a stream-rate parameter may have changed
        self._schedule = None
        entry = self._params[name]
        if entry.param_type in _INT_RANGES:
            low, high = _INT_RANGES[entry.param_type]
            entry.value = float(_clamp(value, low, high))
        else:
            entry.value = float(struct.unpack("<f", struct.pack("<f", value))[0])
        if name.startswith("SR0_"):  # a new group rate replaces the per-message intervals
            for stream, group in STREAM_GROUPS.items():
                if group == name:
                    self._interval_us.pop(stream, None)
                    self._due_us.pop(stream, None)

    def _send_param(self, name: str, index: int) -> None:
        entry = self._params[name]
        self._mav.send(
            self._mav.param_value_encode(
                name.encode("ascii"), entry.value, entry.param_type, len(self._params), index
            )
        )

    def _param_read(self, msg: Any) -> None:
        names = list(self._params)
        if msg.param_index >= 0:
            if msg.param_index < len(names):
                self._send_param(names[msg.param_index], msg.param_index)
            return
        name = str(msg.param_id)
        if name in self._params:
            self._send_param(name, names.index(name))

    def _request_data_stream(self, msg: Any) -> None:
        rate_hz = msg.req_message_rate if msg.start_stop else 0
        if msg.req_stream_id == mavlink2.MAV_DATA_STREAM_ALL:
            params = list(_DATA_STREAM_PARAMS.values())
        else:
            param = _DATA_STREAM_PARAMS.get(msg.req_stream_id)
            params = [] if param is None else [param]
        for param in params:
            self._set_param(param, rate_hz)

    # -- message requests ---------------------------------------------------------------------

    @staticmethod
    def _streamed_name(msg_id: int) -> str | None:
        entry = mavlink2.mavlink_map.get(msg_id)
        name = None if entry is None else str(entry.msgname)
        return name if name in STREAM_GROUPS else None

    def _message_interval(self, msg_id: int, interval_us: int, now_s: float) -> int:
        name = self._streamed_name(msg_id)
        if name is None:
            return int(mavlink2.MAV_RESULT_FAILED)  # ArduPilot: no such message to stream
        if interval_us == 0:
            self._interval_us.pop(name, None)
            self._schedule = None
            default = self._default_interval_us(name)
            if default is not None:
                self._due_us[name] = round(now_s * 1e6) + default
        elif interval_us < 0:
            self._set_interval(name, None, now_s)
        else:
            self._set_interval(name, max(1000, interval_us), now_s)  # ArduPilot: 1 ms at least
        return int(mavlink2.MAV_RESULT_ACCEPTED)

    def _request_message(self, msg_id: int) -> int:
        entry = mavlink2.mavlink_map.get(msg_id)
        name = None if entry is None else str(entry.msgname)
        if name not in (*STREAM_GROUPS, "HOME_POSITION", "AUTOPILOT_VERSION"):
            return int(mavlink2.MAV_RESULT_FAILED)
        # ArduPilot acknowledges first and sends the message from its next update.
        self._deferred.append(str(name))
        return int(mavlink2.MAV_RESULT_ACCEPTED)

    def _ftp_nak(self, msg: Any, asker: _Asker) -> None:
        seq, session, opcode = struct.unpack_from("<HBB", bytes(msg.payload[:4]))
        header = _FTP_HEADER.pack((seq + 1) & 0xFFFF, session, _FTP_OP_NAK, 1, opcode, 0, 0, 0)
        payload = [*header, _FTP_ERR_UNKNOWN_COMMAND]
        payload += [0] * (_FTP_PAYLOAD_BYTES - len(payload))
        self._mav.send(
            self._mav.file_transfer_protocol_encode(
                msg.target_network, asker.system_id, asker.component_id, payload
            )
        )
