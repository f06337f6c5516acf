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
from collections.abc import Callable, Mapping
from typing import Any, Final

from pymavlink.dialects.v20 import ardupilotmega as mavlink2

from clark_engine.io.autopilot_decode import (
    AutopilotEvent,
    MessageDecoder,
    message_fields,
)
from clark_engine.io.autopilot_flight import FlightCommands
from clark_engine.io.autopilot_requests import (
    Request,
    RequestTracker,
    message_id,
    param_id_bytes,
)
from clark_engine.io.autopilot_settings import AutopilotSettings
from clark_engine.io.autopilot_setup import ParamAnswer, SafetySetup
from clark_engine.io.autopilot_setup_link import AdapterSetupLink
from clark_engine.io.autopilot_streams import StreamRequests
from clark_engine.io.mission_upload import MissionUploads, mission_items
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
    UploadMission,
    check_dispatch,
    unknown_command,
)
from clark_engine.runtime.events import (
    AutopilotHealth,
    AutopilotHeartbeat,
    AutopilotStatus,
    CommandRefused,
    VehicleState,
)
from clark_engine.runtime.log_events import LogEvent

GCS_HEARTBEAT_PERIOD_S: Final = 1.0
"""Our own HEARTBEAT period; ArduPilot's GCS failsafe (FS_GCS_ENABLE) expects 1 Hz."""

OVERRIDE_REFRESH_S: Final = 0.5
"""Active RC overrides are resent this often, well inside ArduPilot's RC_OVERRIDE_TIME (3 s)."""

#: The commands that reach the adapter but are not the autopilot's: answered with ``b""``.
_NOT_THE_AUTOPILOTS: Final = (SendPacket, PayloadCommand, CloseInterfaces)
# AutopilotAdapter.command carries out AUTOPILOT_COMMANDS and answers these with nothing;
# any other type raises, and a command type added without a place here fails on import.
check_dispatch((*AUTOPILOT_COMMANDS, *_NOT_THE_AUTOPILOTS), "the autopilot adapter")
_FORCE_ARM_MAGIC: Final = 21196  # MAV_CMD_COMPONENT_ARM_DISARM param2: skip pre-arm checks
_NOT_MEASURED_MV: Final = 65535  # SYS_STATUS.voltage_battery: UINT16_MAX
_UNKNOWN_SATELLITES: Final = 255  # GPS_RAW_INT.satellites_visible: UINT8_MAX
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
        #: Each message received, into this adapter's state and the runtime's events.
        self._decoder = MessageDecoder(self)
        #: The runtime's flight commands (Goto and its speed, Takeoff, RC overrides) out.
        self._flight = FlightCommands(self)
        #: The safety set-up's link to this adapter (parameters, upload, the set-up's hooks).
        #: Every request the autopilot must answer: sent, resent, given up, its refusals.
        self._tracker = RequestTracker(self)
        self._setup_link = AdapterSetupLink(self)
        #: The streams and the one-off messages asked of the autopilot.
        self._streams = StreamRequests(self)
        # (system, component) the messages used come from; settings are frozen
        self._autopilot_ids = (settings.system_id, settings.component_id)
        self._mode_names: dict[int, str] = {}
        for name, number in settings.modes.items():
            self._mode_names.setdefault(int(number), name)
        self._interval_us = max(1, round(1e6 / settings.stream_rate_hz))

        self._start_s: float | None = None
        self._next_heartbeat_s = 0.0
        self._requests: list[Request] = []
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
                self._flight.above_home_m,
                airspeed=settings.firmware == "arduplane",
            ),
            lambda: self._safety is not None,
            self._setup_link.setup_reasons,
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
        return None if msg is None else message_fields(msg)

    # -- connection ------------------------------------------------------------------------

    def start(self, now_s: float) -> bytes:
        """Open the conversation (thesis 4.3.1): what to send first.

        Our HEARTBEAT; SET_MESSAGE_INTERVAL for each of
        :data:`~.autopilot_streams.STREAMED_MESSAGES` at ``stream_rate_hz``; and
        MAV_CMD_REQUEST_MESSAGE for AUTOPILOT_VERSION, whose answer completes
        :attr:`verified`. Whatever is lost (an autopilot still booting, a UDP link with no
        peer yet) :meth:`poll` sends again.
        """
        self._start_s = now_s
        self._heartbeat_out(now_s)
        self._streams.queue(now_s)
        self._streams.verify(now_s)
        self._tracker.send_due(now_s)
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
          GLOBAL_POSITION_INT came for :data:`~.autopilot_streams.STREAM_SILENCE_S` while
          heartbeats do.
        """
        if self._start_s is None:
            return self.start(now_s)
        if now_s >= self._next_heartbeat_s:
            self._heartbeat_out(now_s)
        if self._stopping:
            # The stop's requests (the terminal mode, the failsafe switched off) are
            # resent until answered; nothing else is asked or kept alive.
            if self._requests:
                self._tracker.send_due(now_s, heard=not self.lost(now_s))
            self._tracker.release_refusals(now_s, self._late_events)
            return self._outbox.take()
        if (
            self._overrides
            and now_s - self._override_sent_s >= OVERRIDE_REFRESH_S
            and not self.lost(now_s)
        ):
            # Not while lost: ArduPilot hands the channels back to the pilot
            # RC_OVERRIDE_TIME after the last override, and an override kept alive
            # through a silence would act again, stale, the moment the link returns.
            self._flight.override_out(dict(self._overrides), now_s)
        heard = self._heartbeat_s is not None and not self.lost(now_s)
        if heard:
            self._streams.keep_up(now_s)
        if self._version is None and now_s >= self._next_verify_s:
            self._streams.verify(now_s)
        elif heard and self._status.home is None and now_s >= self._next_home_request_s:
            self._streams.request_home(now_s)
        if self._requests:
            self._tracker.send_due(now_s, heard=heard)
        if heard:
            self._flight.speed(now_s)
        if self._safety is not None:
            self._safety.poll(now_s)
        if self._missions.busy:
            if self.lost(now_s):
                self._missions.drop_waiting()  # never uploaded stale when the link returns
            self._missions.poll(now_s)
        self._tracker.release_refusals(now_s, self._late_events)
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
            self._flight.override_out(dict.fromkeys(self._overrides, 0), now_s)
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
            self._flight.override_out(dict.fromkeys(self._overrides, 0), now_s)
            self._overrides.clear()
        self._stopping = True
        self._setup_link.close(now_s)
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
            self._flight.goto(cmd, now_s)
            self._flight.speed(now_s)
        elif isinstance(cmd, Arm):
            return self.arm(cmd.armed, now_s)
        elif isinstance(cmd, Takeoff):
            self._flight.takeoff(cmd, now_s)
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
            self._tracker.command_long(
                mavlink2.MAV_CMD_DO_SET_MODE,
                f"SetMode {cmd.mode} ({number})",
                now_s,
                mavlink2.MAV_MODE_FLAG_CUSTOM_MODE_ENABLED,
                number,
            )
        elif isinstance(cmd, SetServo):
            self._tracker.command_long(
                mavlink2.MAV_CMD_DO_SET_SERVO,
                f"SetServo {cmd.servo} {cmd.pwm_us} us",
                now_s,
                cmd.servo,
                cmd.pwm_us,
            )
        elif isinstance(cmd, RcOverride):
            self._flight.rc_override(cmd, now_s)
        elif isinstance(cmd, SetUpAutopilotSafety):
            self._setup_link.start(cmd, now_s)
        elif isinstance(cmd, UploadMission):
            self._missions.request(cmd, now_s)
        elif not isinstance(cmd, _NOT_THE_AUTOPILOTS):
            raise unknown_command(cmd, "the autopilot adapter")
        return self._outbox.take()

    def arm(self, armed: bool, now_s: float, *, force: bool = False) -> bytes:
        """Arm or disarm (MAV_CMD_COMPONENT_ARM_DISARM); ``force`` skips pre-arm checks."""
        self._tracker.command_long(
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
        param_id = param_id_bytes(name)
        s = self.settings
        self._tracker.track(
            Request(
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
        param_id = param_id_bytes(name)
        known = self._param_types.get(name, mavlink2.MAV_PARAM_TYPE_REAL32)
        s = self.settings
        self._tracker.track(
            Request(
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
        msg_id = message_id(name)
        self._wanted.add(name)
        self._tracker.command_long(
            mavlink2.MAV_CMD_REQUEST_MESSAGE, f"request {name}", now_s, msg_id
        )
        return self._outbox.take()

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
            self._decoder.handle(msg, now_s, events)
        if self._late_events:  # what the messages ended (a safety set-up's result)
            events.extend(self._late_events)
            self._late_events = []
        self._tracker.release_refusals(now_s, events)
        return events

    # -- internals: receiving ----------------------------------------------------------------

    def _new_parser(self) -> Any:
        parser = mavlink2.MAVLink(None, self.settings.source_system_id, 0)
        parser.robust_parsing = True  # garbage becomes BAD_DATA messages, never exceptions
        return parser

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
            self._flight.override_out(released, self._override_sent_s)
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
