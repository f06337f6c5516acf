"""MAVLink in: each message the autopilot sends folded into the adapter's state and events.

The adapter's :meth:`~clark_engine.io.autopilot.AutopilotAdapter.receive` parses the
bytes; :class:`MessageDecoder` takes each message, by family: HEARTBEAT (mode, armed, the
autopilot's identity), GLOBAL_POSITION_INT with ATTITUDE, VFR_HUD and SYSTEM_TIME
(:class:`~clark_engine.runtime.events.VehicleState`, on the mission origin's datum and
GPS time), the readiness messages (GPS_RAW_INT, EKF_STATUS_REPORT, SYS_STATUS,
HOME_POSITION, EXTENDED_SYS_STATE: :class:`~clark_engine.runtime.events.AutopilotStatus`),
RC_CHANNELS, PARAM_VALUE and STATUSTEXT (written to the interface log through
:func:`~clark_engine.untrusted.printable`, so a text can never forge a log line). Also
the events the adapter adds to the runtime's (:class:`ParamValue`,
:class:`AutopilotMessage`) and GPS time from Unix time.

Separate from the adapter because turning what arrives into events is one concern, and
the adapter's other half (commands out, requests tracked until answered, the safety
set-up) another. :class:`MessageDecoder` is owned by the adapter and keeps no state of its
own: what it learns (the latest heartbeat, the status, the boot clock) is the adapter's,
which its commands read too, so it works through a back-reference.
"""

from __future__ import annotations

import logging
import math
import operator
from collections.abc import Mapping
from dataclasses import dataclass, replace
from typing import TYPE_CHECKING, Any, Final

from pymavlink.dialects.v20 import ardupilotmega as mavlink2

from clark_engine.io.autopilot_settings import FIRMWARE_VEHICLE_TYPES
from clark_engine.io.mission_upload import MISSION_PROGRESS_MESSAGES
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

if TYPE_CHECKING:
    from clark_engine.io.autopilot import AutopilotAdapter

GPS_EPOCH_UNIX_MS: Final = 315_964_800_000
"""The GPS epoch, 1980-01-06 00:00:00 UTC, in milliseconds of Unix time."""

GPS_LEAP_SECONDS: Final = 18
"""GPS time minus UTC, in seconds: constant since 2017-01-01 (no leap second has been
announced since, and the IERS plans none before their abolition)."""

FALLBACK_ALT_GAP_M: Final = 20.0
"""GLOBAL_POSITION_INT's ``alt`` this far from a 3-D fix's GPS_RAW_INT ``alt`` is the
barometer's height of an autopilot whose EKF has not taken over yet (ArduRover, ArduPlane;
measured on SITL): the GPS's height above sea level is used instead. GPS and EKF heights
of a working vehicle differ by a few metres."""

MOVING_SPEED_M_S: Final = 0.5
"""Below this ground speed the course over ground is noise, and the heading is the yaw."""

REASON_WINDOW_S: Final = 1.0
"""STATUSTEXT warnings this long before a refusal are its reason (ArduPilot explains a
refused arm or mode change in a STATUSTEXT, queued around the COMMAND_ACK)."""

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

UINT16_MAX: Final = 65535
"""MAVLink's "unused" RC channel width, and its "no change" in RC_CHANNELS_OVERRIDE."""
_STATUS_MESSAGES: Final = frozenset(
    {"GPS_RAW_INT", "EKF_STATUS_REPORT", "SYS_STATUS", "HOME_POSITION", "EXTENDED_SYS_STATE"}
)
"""Messages :attr:`AutopilotAdapter.status` is made of."""
_MISSION_ANSWERS: Final = frozenset({"MISSION_REQUEST_INT", "MISSION_REQUEST", "MISSION_ACK"})
"""The autopilot's side of an upload (the safety set-up's fence list)."""
_HEALTH_MESSAGES: Final = frozenset({"SYS_STATUS", "GPS_RAW_INT"})
"""Messages :class:`AutopilotHealth` is made of; one is sent each time either arrives."""
_RC_CHANNEL_FIELDS: Final = operator.attrgetter(
    *(f"chan{i}_raw" for i in range(1, RC_OVERRIDE_CHANNELS + 1))
)
"""RC_CHANNELS' 18 widths as a tuple, read in one call (it arrives at the stream rate)."""


def gps_time_ms_from_unix_us(time_unix_usec: int) -> int:
    """GPS time in milliseconds since the GPS epoch, from Unix time in microseconds.

    GPS time does not count leap seconds, so it runs :data:`GPS_LEAP_SECONDS` ahead
    of UTC. Integer arithmetic, so the result is exact to the millisecond (truncated).
    """
    return time_unix_usec // 1000 - GPS_EPOCH_UNIX_MS + GPS_LEAP_SECONDS * 1000


def message_fields(msg: Any) -> dict[str, Any]:
    """A MAVLink message's fields as plain Python values, by field name."""
    fields = dict(msg.to_dict())
    fields.pop("mavpackettype", None)
    return fields


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


class MessageDecoder:
    """Each MAVLink message from the autopilot, into the adapter's state and the events.

    Args:
        adapter: The adapter that owns it, whose state the messages update.
    """

    def __init__(self, adapter: AutopilotAdapter) -> None:
        self._adapter = adapter
        self._settings = adapter.settings
        self._log = adapter._log

    def handle(self, msg: Any, now_s: float, events: list[AutopilotEvent]) -> None:
        """One parsed message: counted, folded into the adapter's state, its events appended."""
        kind = msg.get_type()
        if kind == "BAD_DATA":
            self._adapter.bad_frames += 1
            return
        if (msg.get_srcSystem(), msg.get_srcComponent()) != self._adapter._autopilot_ids:
            self._adapter.foreign_messages += 1
            return
        self._adapter._latest[kind] = msg
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
            self._adapter._attitude = msg
        elif kind == "VFR_HUD":
            self._adapter._vfr_hud = msg
        elif kind == "SYSTEM_TIME":
            self._check_boot(msg.time_boot_ms)
            self._adapter._gps_at_boot_ms = (
                (gps_time_ms_from_unix_us(msg.time_unix_usec), msg.time_boot_ms)
                if msg.time_unix_usec
                else None
            )
        elif kind == "RC_CHANNELS":
            events.append(RcChannels(self._rc_values(_RC_CHANNEL_FIELDS(msg))))
        elif kind == "PARAM_VALUE":
            events.append(self._on_param(msg, now_s))
        elif kind in _MISSION_ANSWERS:
            own = (self._settings.source_system_id, self._settings.source_component_id)
            safety = self._adapter._safety
            if safety is None or not safety.on_mission(msg, own, now_s):
                self._adapter._missions.on_answer(msg, own, now_s)
        elif kind in MISSION_PROGRESS_MESSAGES:
            self._adapter._missions.on_progress(msg)
        elif kind == "COMMAND_ACK":
            self._adapter._tracker.on_ack(msg, now_s, events)
        elif kind == "STATUSTEXT":
            events.append(self._on_text(msg, now_s))
        elif kind in _STATUS_MESSAGES:
            status = self._on_status(kind, msg)
            if status is not None:
                events.append(status)
            if kind in _HEALTH_MESSAGES:
                events.append(self._adapter.health)
        elif kind == "AUTOPILOT_VERSION":
            first = self._adapter._version is None
            self._adapter._version = int(msg.flight_sw_version)
            if first:
                self._log.info(
                    "autopilot %d answers: ArduPilot %s",
                    self._settings.system_id,
                    self._adapter.flight_sw_version,
                    extra=LogEvent.AUTOPILOT_FOUND.extra,
                )
        if kind in self._adapter._wanted:
            self._adapter._wanted.discard(kind)
            events.append(AutopilotMessage(kind, message_fields(msg)))

    def _on_text(self, msg: Any, now_s: float) -> AutopilotText:
        severity = int(msg.severity)
        text = str(msg.text)
        shown = printable(text)
        if severity <= mavlink2.MAV_SEVERITY_WARNING:
            self._adapter._warnings = [
                w for w in self._adapter._warnings if now_s - w[0] <= REASON_WINDOW_S
            ]
            self._adapter._warnings.append((now_s, shown))
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
            self._settings.system_id,
            shown,
            extra=LogEvent.AUTOPILOT_TEXT.extra,
        )
        return AutopilotText(severity, text)

    def _on_status(self, kind: str, msg: Any) -> AutopilotStatus | None:
        """Fold one readiness message into :attr:`status`; the new status when it changed."""
        old = self._adapter._status
        if kind == "GPS_RAW_INT":
            fixed = int(msg.fix_type) >= mavlink2.GPS_FIX_TYPE_3D_FIX
            self._adapter._gps_alt_amsl_m = msg.alt / 1000.0 if fixed else None
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
        self._adapter._status = new
        if new.ready != old.ready or new.waiting_for != old.waiting_for:
            if new.ready:
                self._log.info(
                    "autopilot %d is ready",
                    self._settings.system_id,
                    extra=LogEvent.AUTOPILOT_READINESS.extra,
                )
            else:
                self._log.info(
                    "autopilot %d waits for %s",
                    self._settings.system_id,
                    ", ".join(new.waiting_for),
                    extra=LogEvent.AUTOPILOT_READINESS.extra,
                )
        return new

    def _on_heartbeat(self, msg: Any, now_s: float) -> AutopilotHeartbeat | None:
        if msg.autopilot == mavlink2.MAV_AUTOPILOT_INVALID:
            return None  # not a flight controller's heartbeat (a companion sharing the id)
        if self._adapter._heartbeat_s is not None and now_s - self._adapter._heartbeat_s > (
            self._settings.heartbeat_timeout_s
        ):
            self._adapter._reconnected(
                f"heard again after {now_s - self._adapter._heartbeat_s:.1f} s"
            )
        self._adapter._heartbeat_s = now_s
        self._check_identity(msg)
        custom_mode = int(msg.custom_mode)
        if (
            self._adapter._heartbeat is not None
            and custom_mode != self._adapter._heartbeat.custom_mode
        ):
            # A new mode starts at its default speed, with no guided target.
            self._adapter._speed_accepted = None
            self._adapter._targeted = False
        beat = AutopilotHeartbeat(
            mode=self._adapter._mode_names.get(custom_mode, f"UNKNOWN_{custom_mode}"),
            custom_mode=custom_mode,
            armed=bool(msg.base_mode & mavlink2.MAV_MODE_FLAG_SAFETY_ARMED),
        )
        self._adapter._heartbeat = beat
        return beat

    def _check_identity(self, msg: Any) -> None:
        problem = None
        if msg.autopilot != mavlink2.MAV_AUTOPILOT_ARDUPILOTMEGA:
            problem = f"autopilot type {msg.autopilot} is not ArduPilot (3)"
        elif self._settings.firmware is not None:
            allowed = FIRMWARE_VEHICLE_TYPES[self._settings.firmware]
            if msg.type not in allowed:
                problem = (
                    f"vehicle type {msg.type} in HEARTBEAT is not {self._settings.firmware}'s; "
                    "check the autopilot profile (mode numbers differ between firmwares)"
                )
        if problem != self._adapter._problem:
            if problem is not None:
                self._log.error(
                    "autopilot %d: %s",
                    self._settings.system_id,
                    problem,
                    extra=LogEvent.AUTOPILOT_IDENTITY.extra,
                )
            self._adapter._problem = problem

    def _check_boot(self, time_boot_ms: int) -> None:
        # The boot clock running backwards means the autopilot rebooted: its stream
        # intervals are back to defaults and its SYSTEM_TIME reference is void.
        if (
            self._adapter._last_boot_ms is not None
            and time_boot_ms + 1000 < self._adapter._last_boot_ms
        ):
            self._adapter._reconnected("rebooted")
        self._adapter._last_boot_ms = time_boot_ms

    def _alt_amsl_m(self, msg: Any) -> float:
        """The vehicle's height above sea level, GLOBAL_POSITION_INT's or the GPS's.

        The GPS's while GLOBAL_POSITION_INT's is a fallback estimator's barometer height
        (see :data:`FALLBACK_ALT_GAP_M`).
        """
        fused = float(msg.alt) / 1000.0
        gps = self._adapter._gps_alt_amsl_m
        if gps is not None and abs(fused - gps) > FALLBACK_ALT_GAP_M:
            return gps
        return fused

    def _on_position(self, msg: Any, now_s: float) -> VehicleState | None:
        self._adapter._position_s = now_s
        self._adapter._positions_counted += 1
        if self._adapter._heartbeat is None or self._adapter._attitude is None:
            return None
        if msg.lat == 0 and msg.lon == 0:
            return None  # ArduPilot's "no position yet" (before its first GPS fix)
        status = self._adapter._status
        if status.gps_fix_type < mavlink2.GPS_FIX_TYPE_3D_FIX and not status.position_ok:
            # Not a position yet: ArduPlane dead-reckons from 0, 0 before its fix (SITL
            # drifted 35 m from there, at up to 26 m/s), with no fix and no EKF position.
            return None
        vx_m_s, vy_m_s = msg.vx / 100.0, msg.vy / 100.0
        speed_m_s = math.hypot(vx_m_s, vy_m_s)
        yaw_deg = math.degrees(self._adapter._attitude.yaw) % 360.0
        if speed_m_s >= MOVING_SPEED_M_S:
            heading_deg = math.degrees(math.atan2(vy_m_s, vx_m_s)) % 360.0
        else:
            heading_deg = yaw_deg
        gps_ms: int | None = None
        if self._adapter._gps_at_boot_ms is not None:
            gps_at, boot_at = self._adapter._gps_at_boot_ms
            gps_ms = gps_at + (msg.time_boot_ms - boot_at)
        hud = self._adapter._vfr_hud
        state = VehicleState(
            gps_time_ms=gps_ms,
            lat_deg=msg.lat / 1e7,
            lon_deg=msg.lon / 1e7,
            alt_m=self._alt_amsl_m(msg) - self._settings.origin_alt_amsl_m,
            ground_speed_m_s=float(hud.groundspeed) if hud is not None else speed_m_s,
            climb_rate_m_s=float(hud.climb) if hud is not None else -msg.vz / 100.0,
            heading_deg=heading_deg,
            roll_deg=math.degrees(self._adapter._attitude.roll),
            pitch_deg=math.degrees(self._adapter._attitude.pitch),
            yaw_deg=yaw_deg,
            mode=self._adapter._heartbeat.mode,
            custom_mode=self._adapter._heartbeat.custom_mode,
            armed=self._adapter._heartbeat.armed,
        )
        self._adapter._state = state
        return state

    def _rc_values(self, raw: tuple[int, ...]) -> tuple[int, ...]:
        """RC_CHANNELS' widths with "unused" as 0; the last answer again while they repeat.

        They arrive at the stream rate and change only when a stick or an override moves.
        """
        if raw != self._adapter._rc_raw:
            self._adapter._rc_raw = raw
            self._adapter._rc = tuple(0 if v == UINT16_MAX else int(v) for v in raw)
        return self._adapter._rc

    def _on_param(self, msg: Any, now_s: float) -> ParamValue:
        name = str(msg.param_id)
        self._adapter._param_types[name] = int(msg.param_type)
        self._adapter._requests = [
            r for r in self._adapter._requests if not (isinstance(r.key, str) and r.key == name)
        ]
        for answer in self._adapter._param_answers.pop(name, ()):
            answer(float(msg.param_value), int(msg.param_type), now_s)
        return ParamValue(
            name=name,
            value=float(msg.param_value),
            param_type=int(msg.param_type),
            index=int(msg.param_index),
            count=int(msg.param_count),
        )
