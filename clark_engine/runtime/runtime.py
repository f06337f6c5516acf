"""AgentRuntime: one agent's loop, pure: no clock, no sleep, no socket.

The thesis's mission layer was a hand-written loop per mission (3.3, figure
3.2): read the interfaces, update the agents, compute, command, send, log, wait.
Here the loop is the engine's. A shell (the real-time loop on a mission
computer, or the simulator) owns time and I/O; it hands every event to
:meth:`AgentRuntime.deliver` as it arrives (so data is in the fleet table the
moment it lands) and calls :meth:`AgentRuntime.tick` once per sample period.
Both return the typed commands for the shell to carry out.

A tick runs the phases in the order the compiled config gives (thesis
7.3.3-7.3.4): ``timeouts`` (peers', the station's and the autopilot's
silence), ``machine`` (events, then the state machine and its primitives),
``commands`` (what the primitives asked for, filtered by safety), ``telemetry``
(every message due this tick, bundled per destination through ClarkLink) and
``log`` (a fleet-table row).

Safety (thesis 7.3.5 and the issue): a peer silent past the heartbeat timeout
raises ``lost:<peer>``; once the behaviour runs, no station in contact for that
timeout (counted from the behaviour's start at the earliest) raises ``mcs_lost``
and runs the declared failsafe (hold by default) with no automatic resume; an
autopilot silent for its timeout (counted from the first tick, whatever the
clock's origin) raises ``autopilot_lost`` and every vehicle command is dropped
until its next VehicleState, never replayed; Terminate from a station stops all
commanding, puts the vehicle in its terminal mode, closes the interfaces and
flushes the logs.
Commands (mode change, activate, terminate) are acted on only when they come
from a station of this mission and, when the mission has a key, authenticated:
the codec rejects every other packet before anything is looked at.
"""

from __future__ import annotations

import logging
import math
from collections.abc import Callable, Mapping
from typing import Any, Final

from clark_engine.behaviors import make_behavior as make_primitive
from clark_engine.link.auth import CounterStore, ReplayStore
from clark_engine.link.codec import Codec
from clark_engine.link.errors import ClarkLinkError, MalformedPacket, ReplayStoreError
from clark_engine.link.fleet import AgentFound, AgentLost, FleetTable, ForeignAgent
from clark_engine.link.messages import (
    MAX_FAILSAFE_TEXT_BYTES,
    MAX_HEALTH_TEXT_BYTES,
    MAX_SEVERITY_SENT,
    MESSAGE_NAMES,
    ActivateController,
    AgentAttitude,
    AgentStatus,
    AgentType,
    BehaviorState,
    Condition,
    Heartbeat,
    Message,
    ModeChangeRequest,
    PictureData,
    PrearmState,
    Terminate,
    VehicleHealth,
    fit_text,
)
from clark_engine.link.packet import BROADCAST, Packet
from clark_engine.mission.geo import Origin, to_local
from clark_engine.mission.model import TELEMETRY_MESSAGES, TICK_PHASES
from clark_engine.mission.peer_conditions import ALWAYS_EVENT, PEER_CONDITIONS
from clark_engine.runtime.autopilot_safety import SafetyPlanError, safety_setup
from clark_engine.runtime.command_delivery import (
    COMMAND_RESEND_S,
    COMMAND_SENDS,
    ActedOn,
    Unconfirmed,
    command_key,
)
from clark_engine.runtime.commands import (
    Arm,
    CloseInterfaces,
    Command,
    Goto,
    RcOverride,
    SendPacket,
    SetMode,
    SetServo,
    Takeoff,
    UploadMission,
)
from clark_engine.runtime.config import AgentConfig, PeerSpec, check_tick_phases
from clark_engine.runtime.context import PrimitiveContext, ground_distance_m
from clark_engine.runtime.envelope import (
    Breach,
    EnvelopeCounts,
    EnvelopeGuard,
    EnvelopeWatch,
    ModeOwner,
    PeerPositions,
    largest_separation_m,
)
from clark_engine.runtime.events import (
    AutopilotHealth,
    AutopilotHeartbeat,
    AutopilotSafetyResult,
    AutopilotStatus,
    AutopilotText,
    CommandRefused,
    Event,
    MissionProgress,
    MissionUploadResult,
    PacketReceived,
    PayloadEvent,
    RcChannels,
    StationCommand,
    VehicleState,
)
from clark_engine.runtime.launch import LaunchGate, is_airborne
from clark_engine.runtime.log_events import LogEvent
from clark_engine.runtime.logbook import (
    AIR_LINES_PER_INTERVAL,
    AIR_SUMMARY_S,
    BROADCAST_PEER,
    Logbook,
)
from clark_engine.runtime.machine import BehaviorMachine, Holds, StateChange
from clark_engine.runtime.mission_envelope import refused_by_envelope
from clark_engine.runtime.peer_conditions import AlwaysWatch, resolve_peer_condition

#: Commands that move the vehicle; never sent while the autopilot is lost or after terminate.
VEHICLE_COMMANDS = (Goto, SetMode, Arm, Takeoff, SetServo, RcOverride, UploadMission)
#: Commands the envelope guard checks as they leave (AgentRuntime._guard).
_STATION_EVENTS: Final = frozenset({"activate", "deactivate"})
"""Events a station's Activate Controller raises: one that does nothing is logged so."""

_GUARDED = (Goto, Takeoff, UploadMission)
#: An RC input above this is a switch in its high position, below the low one (ArduPilot's
#: auxiliary-switch thresholds); the events fire on crossing, not while held.
RC_HIGH_US = 1800
RC_LOW_US = 1200
#: The behaviour's one-off requests, not carried out after an autopilot loss by the states
#: that made them before or during it (AgentRuntime._void_requests).
_REQUESTS = (SetMode, Arm, Takeoff)
#: A station terminating the fleet sends Terminate again to each agent that has not yet
#: confirmed it (a heartbeat with the terminated condition) this often: one broadcast on
#: a lossy radio is not enough to stop every vehicle.
TERMINATE_RESEND_S = 1.0
#: Vehicle Health's figures outside these are sent as unknown (the wire refuses them).
_BATTERY_V_MAX = 65.534
_GPS_FIX_TYPE_MAX = 8
_SATELLITES_MAX = 254
#: Most messages one packet may hold from an agent not in the mission: one of each kind.
_MAX_MESSAGES_UNKNOWN = len(MESSAGE_NAMES)
#: An autopilot safety set-up cut short by the autopilot's silence is asked for again no
#: sooner than this after, once the autopilot is back.
SAFETY_RETRY_S = 5.0
#: Most activations timed for a GPS time held at once
#: (docs/runtime.md#commands-from-the-air-are-bounded). One per
#: station, kind (activate, deactivate) and target (this agent, every agent) is held
#: (:meth:`AgentRuntime._schedule`), so this bounds a mission with four stations or more;
#: beyond it a new one is dropped and the ones held stay.
MAX_SCHEDULED_ACTIVATIONS = 16
#: An activation timed further ahead of this agent's GPS time than this is not held: a
#: synchronised start is seconds away, and a slot held for hours by a forged far-future
#: start would refuse the station's next one as long.
MAX_ACTIVATION_AHEAD_S = 600.0
#: A mode request for the mode one was passed on for less than this ago is not passed on
#: again: the autopilot adapter already sends it until the autopilot answers.
MODE_REQUEST_REPEAT_S = 1.0
#: Message-log rows of a mission agent's packets are written for up to this many times
#: the packets a second its telemetry is configured to send, plus
#: :data:`RECEIVED_ROWS_SPARE_PER_TICK` a tick of the mission's loop (behaviour states,
#: photos, commands: an agent sends at most a packet to each destination a tick, split
#: bundles aside), in each of the logbook's air intervals; beyond, on a mission without a
#: key, someone is sending in its name, and the rest are counted in the summary.
RECEIVED_ROWS_RATE_FACTOR = 2
RECEIVED_ROWS_SPARE_PER_TICK = 2


class TooManyMessages(MalformedPacket):
    """A packet holding more messages than its sender may send in one (a stuffed packet).

    Rejected whole and counted as malformed against its sender: one packet must not
    write hundreds of message-log rows or feed hundreds of messages to the fleet table.
    """


#: Messages that command an agent (a tuple: isinstance checks it faster than a union).
_COMMAND_MESSAGES = (ModeChangeRequest, ActivateController, Terminate)


class AgentRuntime:
    """One agent's runtime core, built from its compiled config.

    Attributes:
        config: The compiled config.
        fleet: The fleet table (thesis Clark Agent list).
        codec: ClarkLink encoder and decoder for this agent.
        context: What the primitives see.
        machine: The behaviour state machine (None for an agent without behaviour).
        logbook: Mission log, interface log, fleet CSV, message log.
        terminated: True once the agent has terminated; it then does nothing.
        failsafe: The failsafe in force (``hold``, ``rtl``...), None when none.
        breach: The envelope breach whose action was applied as the failsafe, None
            when none was (docs/runtime.md#the-envelope-in-flight).
        envelope_guard: Keeps every Goto and Takeoff inside the envelope (vehicles
            with an envelope; None otherwise).
        envelope_watch: Watches the vehicle and its peers against the envelope each
            tick (None where there is no guard).
        failsafe_reason: Why it is in force: ``mcs_lost``, or the envelope breach's kind
            (``fence``, ``ceiling``, ``floor``, ``endurance``, ``separation slash_a``);
            "" when none. With ``failsafe`` it is Vehicle Health's ``failsafe`` text
            (``hold: mcs_lost``, ``rtl: fence``).
    """

    def __init__(
        self,
        config: AgentConfig,
        *,
        key: bytes | None = None,
        counter_store: CounterStore | None = None,
        replay_store: ReplayStore | None = None,
        logbook: Logbook | None = None,
        gps_epoch_ms: int | None = None,
        autopilot_connected: bool = True,
    ) -> None:
        """Build the runtime.

        Args:
            config: The agent's compiled config.
            key: The mission key, when the mission has one (``config.authenticated``).
            counter_store: Where the packet counter's high-water mark persists.
            replay_store: Where the marks of the packets accepted persist, so that a
                restarted agent accepts none of them again (authenticated missions;
                the shell calls ``codec.save_replay_marks()`` on a clean stop).
            logbook: Where the logs go; an in-memory logbook when None.
            gps_epoch_ms: GPS time at runtime time 0, for agents without an autopilot
                (stations); vehicles take GPS time from their autopilot.
            autopilot_connected: False for a vehicle run without its autopilot on
                purpose (``clark run --no-autopilot``, testing mode): it is lost as
                any silent autopilot is, but that is said once as information, not
                as an error.
        """
        if config.authenticated and key is None:
            raise ValueError(f"mission {config.mission_name} is authenticated: give its key")
        self.config = config
        self._autopilot_connected = autopilot_connected
        radio = config.raw["agent"]["hardware"].get("radio") or {}
        self.max_packet_bytes = int(radio.get("max_packet_bytes", 256))
        self.codec = Codec(
            config.mission_id,
            config.agent_id,
            key if config.authenticated else None,
            counter_store=counter_store,
            replay_store=replay_store,
            max_packet_bytes=max(self.max_packet_bytes, 64),
            clock=self._link_now_s,
        )
        self.fleet = FleetTable(
            config.agent_id,
            config.mission_id,
            config.heartbeat_timeout_s,
            expected={p.id: p.name for p in config.peers},
        )
        self.logbook = logbook if logbook is not None else Logbook.in_memory(config)
        self.context = PrimitiveContext(config, self.fleet, log=self.logbook.mission)
        #: The tick's phases, resolved to methods once (:meth:`_resolve_phases`).
        self._phases = self._resolve_phases(config.tick_phases)
        #: The telemetry schedule, each message resolved to its builder once.
        self._telemetry_plan = self._resolve_telemetry()
        self.machine = (
            BehaviorMachine(
                config.machine,
                make_primitive,
                self._evaluate,
                self._on_change,
                resolve=self._resolve_condition,
            )
            if config.machine is not None
            else None
        )
        #: The behaviour's ``always`` transitions: the machine phase raises the event when
        #: one of an active state's could be taken; None when it has none.
        watch = AlwaysWatch(config.machine, self._resolve_condition) if config.machine else None
        self._always = watch if watch is not None and watch.watching else None
        self.terminated = False
        self.close_logbook_on_terminate = True
        """False when the owner closes the logbook after its own stop (the real-time shell
        logs what the stop does, its links closed last, after the terminate)."""
        self.failsafe: str | None = None
        self.breach: Breach | None = None
        envelope = config.envelope if config.is_vehicle else None
        self.envelope_guard = (
            EnvelopeGuard(config, envelope, self.logbook.mission) if envelope is not None else None
        )
        self.envelope_watch = EnvelopeWatch(config, envelope) if envelope is not None else None
        self._peer_positions = PeerPositions(
            config,
            self.fleet,
            largest_separation_m(envelope) if envelope is not None else 0.0,
        )
        self._origin = Origin(
            config.origin_lat_deg, config.origin_lon_deg, config.origin_alt_amsl_m
        )
        self._here_cache: tuple[VehicleState, tuple[float, float]] | None = None
        #: Whether the vehicle is in a mode the engine put it in (a breach never fights
        #: a pilot or a station who took it).
        self._modes = ModeOwner()
        #: The last navigation command that left: "goto" or "takeoff" (the floor is
        #: watched only in guided flight to a Goto, never in a take-off's climb).
        self._last_navigation: str | None = None
        if envelope is not None:
            self.logbook.closing.append(self._envelope_summary)
        elif config.is_vehicle:
            self.logbook.mission.warning(
                "no envelope in this config: targets are not checked and nothing is "
                "watched; compile the mission again with clark compile",
                extra=LogEvent.AGENT_NO_ENVELOPE.extra,
            )
        self.failsafe_reason = ""
        #: When the behaviour may start (readiness, arming, take-off, as the mission says).
        self.launch = LaunchGate(config, self.logbook.mission)
        #: The autopilot's safety set-up: ``due`` (to be sent), ``sent``, ``done`` or
        #: ``failed``; and when one cut short by a silence may be sent again.
        self._safety_state = "done" if self.launch.safety_done else "due"
        self._safety_due_s = -math.inf
        #: Called with every state change, after the runtime's own handling (the
        #: simulator records them; a shell could show them).
        self.state_listeners: list[Callable[[StateChange], None]] = []
        self._started = False
        self._tick = 0
        self._events: list[str] = []
        self._commands: list[Command] = []
        self._state_messages: list[BehaviorState] = []
        # Activations the station timed for a GPS time: (gps ms, event, sender id, target
        # id), at most one per (sender, event, target) and MAX_SCHEDULED_ACTIVATIONS in all.
        self._scheduled: list[tuple[int, str, int, int]] = []
        # Behaviour events from the air (activate, deactivate) queued in _events and not yet
        # dispatched: each is queued once per tick, however many packets ask for it.
        self._air_events: set[str] = set()
        # A vehicle: the station commands it acted on, so that a station's copy of one is
        # not acted on again (runtime/command_delivery.py).
        self._acted_on = ActedOn()
        # A station: the commands it sent one vehicle and has not seen take, by (target
        # id, activate/deactivate or mode); sent again until they do, a few times at most.
        self._unconfirmed: dict[tuple[int, str], Unconfirmed] = {}
        # When a mode request for each mode was last passed on (runtime s), until the
        # vehicle reports another mode: a repeat sooner than MODE_REQUEST_REPEAT_S is
        # coalesced. At most one entry per mode of the profile.
        self._mode_requests: dict[str, float] = {}
        # The failsafe's SetMode when the autopilot was lost as it was applied: it is sent
        # when the autopilot returns (the failsafe still holds); nothing else of the loss is.
        self._failsafe_unsent: SetMode | None = None
        # True from an autopilot loss until the behaviour changes state after the return:
        # the mode, arm and takeoff requests of the states active across the loss were
        # made while nobody heard them, so they are not carried out later.
        self._requests_void = False
        self._mcs_lost_raised = False
        self._trim_failed = False  # the last trim of the replay marks failed (logged once)
        #: The runtime time of the first tick: every silence is counted from it at the
        #: earliest, whatever the shell's clock origin (a monotonic clock is not 0 at boot).
        self._first_tick_s: float | None = None
        #: When the behaviour started (runtime time); station silence counts from then.
        self._started_s: float | None = None
        #: Stations heard and not lost since; mcs_lost is about this set being empty.
        self._stations_in_contact: set[int] = set()
        #: Since when no station has been in contact (None while one is); a station never
        #: heard is silent from the first tick.
        self._stations_silent_since_s: float | None = None
        # Messages primitives queued (Picture Data) wait here for the telemetry phase.
        self._pending_messages: list[tuple[Message, tuple[str, ...]]] = []
        self._gps_epoch_ms = gps_epoch_ms
        # Vehicle Health: the autopilot's latest battery, GPS and pre-arm figures, its
        # latest text of WARNING or worse with when it arrived, and whether it is armed.
        self._health: AutopilotHealth | None = None
        self._warning: tuple[AutopilotText, float] | None = None
        self._armed = False
        self._vehicle_gps: tuple[int, float] | None = None  # (gps ms, runtime s) of last fix
        self._autopilot_seen_s: float | None = None
        self._autopilot_lost = False
        self._stations = {p.id for p in config.peers if p.role == "mcs"}
        self._station_names = sorted(p.name for p in config.peers if p.role == "mcs")
        self._last_mode: str | None = None
        self._rc_levels: dict[int, str] = {}
        self._rc_last: tuple[int, ...] | None = None  # the widths _rc_levels was last set from
        self._rc_names: dict[int, list[str]] = {}
        for name, channel in config.channels.items():
            if channel.rc is not None:
                self._rc_names.setdefault(channel.rc, []).append(name)
        self._peer_by_name = {p.name: p for p in config.peers}
        #: A station's terminate of the whole fleet under way: each agent that has not yet
        #: confirmed -> when Terminate last went to it. None when none is under way.
        self._terminating: dict[int, float] | None = None
        self._terminate_sent_s = 0.0
        #: Most messages one packet of each peer may hold: what it is configured to send
        #: (each telemetry message once) and one of every ClarkLink message besides
        #: (Behavior State, Picture Data, a station's command); more is a stuffed packet.
        self._message_caps = {p.id: len(p.sends) + len(MESSAGE_NAMES) for p in config.peers}
        #: Packets of each peer whose message-log rows are written per air interval.
        self._received_rows_allowance = {
            p.id: math.ceil(
                AIR_SUMMARY_S
                * (
                    RECEIVED_ROWS_RATE_FACTOR * sum(p.sends.values())
                    + RECEIVED_ROWS_SPARE_PER_TICK * config.loop_hz
                )
            )
            for p in config.peers
        }
        self._peer_by_id = {p.id: p for p in config.peers}
        self.logbook.mission.info(
            "agent %s (id %d) of mission %s (id %d) at %g Hz, %d peers",
            config.agent,
            config.agent_id,
            config.mission_name,
            config.mission_id,
            config.loop_hz,
            len(config.peers),
            extra=LogEvent.AGENT_START.extra,
        )

    # -- time --------------------------------------------------------------------------

    def _trim_replay_marks(self) -> None:
        """Trim the live replay marks of peers that slowed down (Codec.trim_replay_marks).

        A write that fails leaves the marks on disk, which stay safe; it is logged once
        until a trim succeeds again, not every tick.
        """
        try:
            self.codec.trim_replay_marks()
        except ReplayStoreError as exc:
            if not self._trim_failed:
                self._trim_failed = True
                self.logbook.interface.warning(
                    "replay marks not trimmed: %s", exc, extra=LogEvent.AGENT_REPLAY_MARKS.extra
                )
        else:
            self._trim_failed = False

    def _link_now_s(self) -> float:
        """The codec's clock: the runtime's, set before each packet is decoded.

        Replay reservations follow the packets' pace on it, in simulated time too.
        """
        return self.context.now_s

    def anchor_gps_time(self, gps_epoch_ms: int) -> None:
        """Set the GPS time at runtime time 0, for a shell whose clock is known only later.

        A real-time dry run whose simulated autopilots give the wall clock's GPS time
        anchors every runtime to the wall clock when its clock starts, so that a station
        (which has no autopilot) stamps its logs on the vehicles' time base: one time
        base in every log, and latencies that mean something.
        """
        self._gps_epoch_ms = gps_epoch_ms

    def _gps_now_ms(self, now_s: float) -> int | None:
        if self._vehicle_gps is not None:
            gps_ms, at_s = self._vehicle_gps
            return gps_ms + round((now_s - at_s) * 1000)
        if self._gps_epoch_ms is not None:
            return self._gps_epoch_ms + round(now_s * 1000)
        return None

    def _set_time(self, now_s: float) -> None:
        self.context.now_s = now_s
        self.context.gps_time_ms = self._gps_now_ms(now_s)
        self.logbook.set_time(now_s, self.context.gps_time_ms)

    def note_time(self, now_s: float) -> None:
        """Stamp the lines logged from now on with ``now_s``, and do nothing else.

        For a shell that logs its own stop after the terminate (no tick moves the
        clock any more), so those lines carry the time they happened.
        """
        self._set_time(now_s)

    # -- events in -----------------------------------------------------------------------

    def deliver(self, event: Event, now_s: float) -> list[Command]:
        """Apply one incoming event at once; returns commands it caused (rarely any).

        Behaviour events it raises (``activate``, ``mode:AUTO``, ``lost:x``...) are
        queued and dispatched, in arrival order, in the next tick's machine phase.
        """
        if self.terminated:
            return []
        self._set_time(now_s)
        if isinstance(event, PacketReceived):
            self._receive(event.data, now_s)
        elif isinstance(event, VehicleState):
            self._vehicle(event, now_s)
        elif isinstance(event, AutopilotHeartbeat):
            self._autopilot_heartbeat(event, now_s)
        elif isinstance(event, RcChannels):
            self._rc(event)
        elif isinstance(event, AutopilotStatus):
            self.context.autopilot = event
        elif isinstance(event, AutopilotSafetyResult):
            self._safety_result(event, now_s)
        elif isinstance(event, AutopilotHealth):
            self._health = event
        elif isinstance(event, AutopilotText):
            if event.severity <= MAX_SEVERITY_SENT:
                self._warning = (event, now_s)
        elif isinstance(event, CommandRefused):
            self.logbook.mission.warning(
                "autopilot refused %s: %s%s",
                event.request,
                event.result,
                f" ({event.reason})" if event.reason else "",
                extra=LogEvent.AUTOPILOT_REFUSED.extra,
            )
        elif isinstance(event, PayloadEvent):
            if self.machine is not None and self._started:
                self.machine.deliver_payload(self.context, event)
        elif isinstance(event, (MissionUploadResult, MissionProgress)):
            if self.machine is not None and self._started:
                self.machine.deliver_mission(self.context, event)
        elif isinstance(event, StationCommand):
            self._station_command(event, now_s)
        if not self._commands:
            return []  # most deliveries cause nothing
        return self._drain()

    def _vehicle(self, state: VehicleState, now_s: float) -> None:
        self.context.vehicle = state
        self._armed = state.armed
        if state.gps_time_ms:
            self._vehicle_gps = (state.gps_time_ms, now_s)
            self.context.gps_time_ms = state.gps_time_ms
        self._autopilot_seen_s = now_s
        if self._autopilot_lost:
            self._autopilot_back()
        self._mode_seen(state.mode)

    def _autopilot_heartbeat(self, beat: AutopilotHeartbeat, now_s: float) -> None:
        # Heard, but the loss ends only with a VehicleState: the behaviour must see where
        # the vehicle is and its mode now before anything commands it again.
        self._autopilot_seen_s = now_s
        self._armed = beat.armed
        self._mode_seen(beat.mode)

    def _autopilot_back(self) -> None:
        """End an autopilot loss: nothing of the loss is replayed; a failsafe holds again.

        Commands dropped while the autopilot was silent stay dropped: a target, a mode or
        an arm decided then may be wrong now (the pilot may have taken the vehicle). What
        goes out from here on is what the behaviour and the failsafe say from now on;
        the failsafe's mode, when the loss swallowed it, is the failsafe's demand now.
        """
        self._autopilot_lost = False
        unsent, self._failsafe_unsent = self._failsafe_unsent, None
        if unsent is not None and not self.terminated:
            self._commands.append(unsent)
        self.logbook.interface.warning(
            "autopilot heard again; commanding it again (nothing of the silent time is sent%s)",
            f"; failsafe {self.failsafe}: {unsent.mode}" if unsent is not None else "",
            extra=LogEvent.AUTOPILOT_BACK.extra,
        )

    def _mode_seen(self, mode: str) -> None:
        self._modes.mode_reported(mode)
        if mode != self._last_mode:
            self._mode_requests.clear()  # a request for a mode again is news now
            if self._last_mode is not None:
                self.logbook.mission.info(
                    "autopilot mode %s -> %s",
                    self._last_mode,
                    mode,
                    extra=LogEvent.AUTOPILOT_MODE.extra,
                )
            self._last_mode = mode
            self._events.append(f"mode:{mode}")

    def _rc(self, channels: RcChannels) -> None:
        if channels.pwm_us == self._rc_last:
            return  # the same widths again (the usual case, at the stream rate): same levels
        self._rc_last = channels.pwm_us
        for index, pwm in enumerate(channels.pwm_us):
            number = index + 1
            if pwm <= 0:
                continue
            level = "high" if pwm > RC_HIGH_US else "low" if pwm < RC_LOW_US else "mid"
            previous = self._rc_levels.get(number)
            self._rc_levels[number] = level
            if previous is None or previous == level or level == "mid":
                continue  # the first reading sets the level; events fire on crossings
            self._events.append(f"rc:{number}:{level}")
            for name in self._rc_names.get(number, ()):
                self._events.append(f"rc:{name}:{level}")

    def _receive(self, data: bytes, now_s: float) -> None:
        gps_now = self.context.gps_time_ms  # deliver's _set_time just worked it out
        try:
            packet = self.codec.decode(data)
        except ClarkLinkError as exc:
            self._rejected(exc, len(data), now_s, gps_now)
            return
        if packet.sender_id == self.config.agent_id:
            return
        if packet.destination_id not in (BROADCAST, self.config.agent_id):
            return
        cap = self._message_caps.get(packet.sender_id, _MAX_MESSAGES_UNKNOWN)
        if len(packet.messages) > cap:
            self._rejected(
                TooManyMessages(
                    f"{len(packet.messages)} messages in one packet; "
                    f"{self._peer_name(packet.sender_id)} sends at most {cap}",
                    sender_id=packet.sender_id,
                    mission_id=packet.mission_id,
                ),
                len(data),
                now_s,
                gps_now,
            )
            return
        found = self.fleet.receive(packet, now_s, gps_now)
        if found:  # rarely: a first heartbeat, a return, another mission
            self._fleet_events(found)
        if self.logbook.tables:  # a dry run without a report drops these rows: skip their work
            # Rows within the air allowance: a mission agent's at up to twice its
            # configured rate (anyone may send in its name on a mission without a key),
            # an agent not in the mission's a few per interval; the rest are counted.
            sender = packet.sender_id
            allowance = self._received_rows_allowance.get(sender)
            if self.logbook.from_air(
                now_s,
                "unknown" if allowance is None else "received",
                self._peer_name(sender),
                packet.size_bytes,
                "accepted",
                AIR_LINES_PER_INTERVAL if allowance is None else allowance,
            ):
                self._log_received(packet, now_s, gps_now)
        self._commands_in(packet, now_s)

    def _rejected(
        self, exc: ClarkLinkError, size_bytes: int, now_s: float, gps_now: int | None
    ) -> None:
        """A packet not acted on: counted against its claimed sender, logged within bounds."""
        self._fleet_events(self.fleet.note_error(exc, now_s))
        self.logbook.rejected(
            now_s, gps_now, self._peer_name(exc.sender_id), size_bytes, type(exc).__name__, str(exc)
        )

    def _log_received(self, packet: Packet, now_s: float, gps_now: int | None) -> None:
        """One message-log row per message of an accepted packet."""
        peer = self._peer_name(packet.sender_id)
        for message in packet.messages:
            stamp = message.gps_time_ms or None
            # Picture Data is stamped at capture, not when sent: no latency from it.
            latency = None
            if stamp is not None and gps_now is not None and not isinstance(message, PictureData):
                latency = gps_now - stamp
            self.logbook.message(
                "received",
                now_s,
                gps_now,
                peer,
                packet.counter,
                packet.size_bytes,
                MESSAGE_NAMES[type(message)],
                stamp,
                latency,
                "",
            )

    def _peer_name(self, agent_id: int | None) -> str:
        if agent_id is None:
            return ""
        peer = self._peer_by_id.get(agent_id)
        return peer.name if peer is not None else f"#{agent_id}"

    def _commands_in(self, packet: Packet, now_s: float) -> None:
        """Act on commands: only from a station of this mission, authenticated when keyed."""
        for message in packet.messages:
            if isinstance(message, _COMMAND_MESSAGES):
                break
        else:
            return  # telemetry only: the usual packet, looked at without building a list
        commands = [m for m in packet.messages if isinstance(m, _COMMAND_MESSAGES)]
        sender = self._peer_by_id.get(packet.sender_id)
        size = packet.size_bytes
        if sender is None or sender.role != "mcs":
            name = self._peer_name(packet.sender_id)
            if self.logbook.from_air(now_s, "ignored", name, size, "not a station"):
                self.logbook.mission.warning(
                    "ignored %d command(s) from %s: only a station commands",
                    len(commands),
                    name,
                    extra=LogEvent.COMMAND_IGNORED.extra,
                )
            return
        if self.config.authenticated and not packet.authenticated:
            if self.logbook.from_air(now_s, "ignored", sender.name, size, "unauthenticated"):
                self.logbook.mission.warning(
                    "ignored unauthenticated command(s) from %s",
                    sender.name,
                    extra=LogEvent.COMMAND_IGNORED.extra,
                )
            return
        me = self.config.agent_id
        for message in commands:
            if isinstance(message, Terminate) and message.target_id in (0, me):
                self.logbook.mission.warning(
                    "terminate from %s%s",
                    sender.name,
                    f": {message.reason}" if message.reason else "",
                    extra=LogEvent.COMMAND_TERMINATE.extra,
                )
                self._terminate(now_s, None)
                return
            if isinstance(message, ActivateController | ModeChangeRequest) and (
                message.target_id in (0, me)
                and not self._acted_on.first_time(command_key(sender.id, message))
            ):
                if self.logbook.from_air(now_s, "command", sender.name, size, "copy"):
                    self.logbook.mission.info(
                        "a copy of a command from %s acted on already: ignored",
                        sender.name,
                        extra=LogEvent.COMMAND_IGNORED.extra,
                    )
                continue
            if isinstance(message, ActivateController) and message.target_id in (0, me):
                event = "activate" if message.active else "deactivate"
                gps_now = self._gps_now_ms(now_s)
                start_ms = message.start_time_ms
                if start_ms and (gps_now is None or start_ms > gps_now):
                    # The station asked for a synchronised start at a GPS time.
                    self._schedule(start_ms, event, sender, message.target_id, gps_now, size)
                else:
                    self._air_event(event, sender.name, size)
            if isinstance(message, ModeChangeRequest) and message.target_id == me:
                self._mode_request(message.mode, sender.name, size)

    def _air_event(self, event: str, sender: str, size_bytes: int) -> None:
        """Queue a station's ``activate`` or ``deactivate`` for the next machine phase, once.

        However many packets ask for it before the tick, the event is dispatched once:
        a flood must not make a tick's work grow. A repeat after the other kind moves it
        behind that one, so the order of the last of each kind is kept (activate,
        deactivate, activate in one tick ends active).
        """
        now_s = self.context.now_s
        if event in self._air_events:
            if self._events and self._events[-1] == event:
                if self.logbook.from_air(now_s, "command", sender, size_bytes, "coalesced"):
                    self.logbook.mission.info(
                        "%s from %s: coalesced with the one queued this tick",
                        event,
                        sender,
                        extra=LogEvent.COMMAND_RECEIVED.extra,
                    )
                return
            self._events.remove(event)
        self._air_events.add(event)
        self._events.append(event)
        if self.logbook.from_air(now_s, "command", sender, size_bytes, event):
            self.logbook.mission.info(
                "%s from %s", event, sender, extra=LogEvent.COMMAND_RECEIVED.extra
            )

    def _schedule(
        self,
        start_ms: int,
        event: str,
        sender: PeerSpec,
        target_id: int,
        gps_now: int | None,
        size_bytes: int,
    ) -> None:
        """Hold a timed activation, bounded: one per (sender, kind, target), the first kept.

        On a mission without a key nothing tells the station's packets from a forger's
        that claims its id, so what is held must not depend on who sends more: the first
        received of each (sender, kind, target) stands and a later one, a repeat or a
        new time, is dropped (counted, and logged within the air allowance). A forger
        therefore cannot evict a command the station sent before the flood began; at
        worst it holds a free slot for :data:`MAX_ACTIVATION_AHEAD_S`. Keeping the
        earliest due instead would let anyone evict by claiming an earlier time, and
        keeping the latest received would let a flood evict everything. When
        :data:`MAX_SCHEDULED_ACTIVATIONS` are held, a new one is dropped.
        """
        now_s = self.context.now_s
        why = reason = ""
        for held_ms, held_event, held_sender, held_target in self._scheduled:
            if (held_event, held_sender, held_target) == (event, sender.id, target_id):
                why = (
                    "repeated"
                    if held_ms == start_ms
                    else f"one from {sender.name} for GPS time {held_ms} is held"
                )
                reason = "coalesced" if held_ms == start_ms else "one held"
                break
        else:
            if gps_now is not None and start_ms - gps_now > MAX_ACTIVATION_AHEAD_S * 1000:
                why, reason = f"more than {MAX_ACTIVATION_AHEAD_S:g} s ahead", "too far ahead"
            elif len(self._scheduled) >= MAX_SCHEDULED_ACTIVATIONS:
                why = f"{MAX_SCHEDULED_ACTIVATIONS} timed activations held, the most"
                reason = "full"
        if why:
            if self.logbook.from_air(now_s, "command", sender.name, size_bytes, reason):
                self.logbook.mission.warning(
                    "%s from %s at GPS time %d not held: %s",
                    event,
                    sender.name,
                    start_ms,
                    why,
                    extra=LogEvent.COMMAND_SCHEDULED.extra,
                )
            return
        self._scheduled.append((start_ms, event, sender.id, target_id))
        if self.logbook.from_air(now_s, "command", sender.name, size_bytes, f"{event} timed"):
            self.logbook.mission.info(
                "%s from %s at GPS time %d",
                event,
                sender.name,
                start_ms,
                extra=LogEvent.COMMAND_SCHEDULED.extra,
            )

    def _mode_request(self, custom_mode: int, sender: str, size_bytes: int) -> None:
        """A station's mode request, passed on once per mode per :data:`MODE_REQUEST_REPEAT_S`.

        Until the vehicle reports another mode: then a request for any mode is passed on
        at once. A flood of requests for one mode, or for several in turn, reaches the
        autopilot adapter (which tracks each command until answered) a bounded number
        of times.
        """
        now_s = self.context.now_s
        names = [n for n, number in self.config.modes.items() if number == custom_mode]
        if not names or not self.config.is_vehicle:
            if self.logbook.from_air(now_s, "command", sender, size_bytes, "no such mode"):
                self.logbook.mission.warning(
                    "mode request %d from %s: no such mode",
                    custom_mode,
                    sender,
                    extra=LogEvent.COMMAND_MODE_REQUEST.extra,
                )
            return
        mode = names[0]
        last_s = self._mode_requests.get(mode)
        if last_s is not None and 0 <= now_s - last_s < MODE_REQUEST_REPEAT_S:
            if self.logbook.from_air(now_s, "command", sender, size_bytes, "coalesced"):
                self.logbook.mission.info(
                    "mode request %s from %s: coalesced with the one %.1f s ago",
                    mode,
                    sender,
                    now_s - last_s,
                    extra=LogEvent.COMMAND_MODE_REQUEST.extra,
                )
            return
        self._mode_requests[mode] = now_s
        if self.logbook.from_air(now_s, "command", sender, size_bytes, "mode request"):
            self.logbook.mission.info(
                "mode request %s from %s", mode, sender, extra=LogEvent.COMMAND_MODE_REQUEST.extra
            )
        self._commands.append(SetMode(mode, custom_mode))

    def _fleet_events(self, events: list[Any]) -> None:
        for event in events:
            if isinstance(event, AgentFound):
                self._events.append(f"found:{event.name or event.agent_id}")
                self.logbook.mission.info(
                    "found %s", event.name or event.agent_id, extra=LogEvent.FLEET_FOUND.extra
                )
                if event.agent_id in self._stations:
                    self._stations_in_contact.add(event.agent_id)
                    self._stations_silent_since_s = None
                    self._mcs_lost_raised = False  # a later silence raises it again
            elif isinstance(event, AgentLost):
                self._events.append(f"lost:{event.name or event.agent_id}")
                self.logbook.mission.warning(
                    "lost %s (silent %.1f s)",
                    event.name,
                    event.silent_s,
                    extra=LogEvent.FLEET_LOST.extra,
                )
                if event.agent_id in self._stations:
                    self._stations_in_contact.discard(event.agent_id)
                    if not self._stations_in_contact and self._stations_silent_since_s is None:
                        # Silent since that station was last heard; the timeouts phase
                        # raises mcs_lost (at once when the behaviour runs).
                        self._stations_silent_since_s = self.context.now_s - event.silent_s
            elif isinstance(event, ForeignAgent):
                self.logbook.mission.warning(
                    "agent %d runs mission %d, not ours: ignored",
                    event.agent_id,
                    event.mission_id,
                    extra=LogEvent.FLEET_FOREIGN.extra,
                )

    def _station_command(self, command: StationCommand, now_s: float) -> None:
        """An operator's command at this station: sent to its targets as ClarkLink."""
        if self.config.is_vehicle:
            self.logbook.mission.warning(
                "station command %s on a vehicle: ignored",
                command.action,
                extra=LogEvent.STATION_COMMAND.extra,
            )
            return
        gps = self._gps_now_ms(now_s) or 0
        me = self.config.agent_id
        target = self._peer_by_name.get(command.target) if command.target else None
        if command.target and target is None:
            self.logbook.mission.warning(
                "station command for unknown agent %s",
                command.target,
                extra=LogEvent.STATION_COMMAND.extra,
            )
            return
        target_id = target.id if target is not None else 0
        message: Message
        if command.action in ("activate", "deactivate"):
            message = ActivateController(me, gps, target_id, command.action == "activate")
        elif command.action == "mode" and target is not None and command.mode in target.modes:
            message = ModeChangeRequest(me, gps, target_id, int(target.modes[command.mode]))
        elif command.action == "terminate":
            message = Terminate(me, gps, target_id, "operator")
        else:
            self.logbook.mission.warning(
                "station command %s not understood", command, extra=LogEvent.STATION_COMMAND.extra
            )
            return
        if self._terminating is not None:
            self.logbook.mission.warning(
                "station command %s %s ignored: the fleet is terminating",
                command.action,
                command.target or "all",
                extra=LogEvent.STATION_COMMAND.extra,
            )
            return
        self.logbook.mission.info(
            "operator: %s %s",
            command.action,
            command.target or "all",
            extra=LogEvent.STATION_COMMAND.extra,
        )
        destination = command.target if target is not None else ""
        self._send([message], destination, now_s)
        if target is not None and isinstance(message, ActivateController | ModeChangeRequest):
            # Sent again until the target shows it took (command_delivery.py); a new
            # command of the same family replaces the one before, copies and all.
            family = "mode" if isinstance(message, ModeChangeRequest) else "activate"
            self._unconfirmed.pop((target.id, family), None)
            if message.gps_time_ms:
                record = self.fleet.record(target.id)
                self._unconfirmed[(target.id, family)] = Unconfirmed(
                    message,
                    command.action,
                    target.name,
                    now_s,
                    now_s,
                    behaviour_before=None if record is None else record.sample(BehaviorState),
                )
        if command.action == "terminate" and target is None:
            self._begin_terminate_all(now_s)

    def _begin_terminate_all(self, now_s: float) -> None:
        """Terminate the fleet, then this station: the station waits for confirmations.

        The broadcast just sent may not reach every agent, and once the station has
        terminated it hears nothing: so it keeps running (commanding nothing else) until
        every other agent it can reach confirms with a terminated heartbeat, sending
        Terminate again to those that have not every :data:`TERMINATE_RESEND_S`; an agent
        lost, or still silent after :meth:`_terminate_all_wait_s`, is logged unconfirmed.
        Then the station runs its own terminate sequence (thesis 7.3.5).
        """
        waiting: dict[int, float] = {}
        for peer in self.config.peers:
            if peer.id in self._stations:
                continue
            record = self.fleet.record(peer.id)
            if record is not None and record.condition == Condition.TERMINATED:
                continue  # terminated already (lost since, as it stopped sending)
            if record is None or record.lost:
                self.logbook.mission.warning(
                    "terminate: %s %s: it cannot confirm",
                    peer.name,
                    "never heard" if record is None else "is lost",
                    extra=LogEvent.TERMINATE_FLEET.extra,
                )
            else:
                waiting[peer.id] = now_s
        self._terminating = waiting
        self._terminate_sent_s = now_s
        if waiting:
            self.logbook.mission.info(
                "terminate: waiting for %s to confirm (at most %.1f s)",
                ", ".join(sorted(self._peer_by_id[i].name for i in waiting)),
                self._terminate_all_wait_s(),
                extra=LogEvent.TERMINATE_FLEET.extra,
            )
        self._terminate_all_progress(now_s)

    def _terminate_all_wait_s(self) -> float:
        """How long a fleet terminate waits for confirmations.

        An agent that terminated but whose last heartbeat was lost is declared lost within
        the heartbeat timeout of its previous one; two resend periods more cover a first
        Terminate lost on the way.
        """
        return self.config.heartbeat_timeout_s + 2 * TERMINATE_RESEND_S

    def _terminate_all_progress(self, now_s: float) -> None:
        """Confirmations taken, Terminate sent again where due, the station's own at the end."""
        waiting = self._terminating
        assert waiting is not None
        for agent_id in list(waiting):
            name = self._peer_by_id[agent_id].name
            record = self.fleet.record(agent_id)
            if record is not None and record.condition == Condition.TERMINATED:
                del waiting[agent_id]
                self.logbook.mission.info(
                    "terminate: %s confirmed", name, extra=LogEvent.TERMINATE_FLEET.extra
                )
            elif record is not None and record.lost:
                del waiting[agent_id]
                self.logbook.mission.warning(
                    "terminate: %s fell silent unconfirmed",
                    name,
                    extra=LogEvent.TERMINATE_FLEET.extra,
                )
        late = now_s - self._terminate_sent_s >= self._terminate_all_wait_s()
        if waiting and late:
            names = ", ".join(sorted(self._peer_by_id[i].name for i in waiting))
            self.logbook.mission.error(
                "terminate: no confirmation from %s", names, extra=LogEvent.TERMINATE_FLEET.extra
            )
        if not waiting or late:
            self._terminating = None
            self._terminate(now_s, None)
            return
        gps = self._gps_now_ms(now_s) or 0
        for agent_id, sent_s in list(waiting.items()):
            if now_s - sent_s >= TERMINATE_RESEND_S - 1e-9:
                waiting[agent_id] = now_s
                message = Terminate(self.config.agent_id, gps, agent_id, "operator")
                self._send([message], self._peer_by_id[agent_id].name, now_s)

    def _resend_unconfirmed(self, now_s: float) -> None:
        """A station's commands not yet seen to take: sent again, or given up after a few."""
        for key, pending in list(self._unconfirmed.items()):
            what = f"{pending.action} {pending.target}"
            if pending.confirmed_by(self.fleet.record(key[0])):
                del self._unconfirmed[key]
                if pending.sends > 1:
                    self.logbook.mission.info(
                        "%s: took after %d sends",
                        what,
                        pending.sends,
                        extra=LogEvent.COMMAND_RESEND.extra,
                    )
            elif now_s - pending.last_sent_s < COMMAND_RESEND_S - 1e-9:
                continue
            elif pending.sends >= COMMAND_SENDS:
                del self._unconfirmed[key]
                self.logbook.mission.warning(
                    "%s: not seen to take after %d sends in %.1f s",
                    what,
                    pending.sends,
                    now_s - pending.first_sent_s,
                    extra=LogEvent.COMMAND_RESEND.extra,
                )
            else:
                pending.sends += 1
                pending.last_sent_s = now_s
                self.logbook.mission.info(
                    "%s: not seen to take yet, sent again (%d of %d)",
                    what,
                    pending.sends,
                    COMMAND_SENDS,
                    extra=LogEvent.COMMAND_RESEND.extra,
                )
                self._send([pending.message], pending.target, now_s)

    # -- the tick ------------------------------------------------------------------------

    def tick(self, now_s: float) -> list[Command]:
        """Run one sample period; returns the commands and packets to carry out."""
        if self.terminated:
            return []
        self._set_time(now_s)
        self.context.tick = self._tick
        if self._first_tick_s is None:
            self._first_tick_s = now_s
            if self._stations_silent_since_s is None and not self._stations_in_contact:
                self._stations_silent_since_s = now_s
        if not self._started and self._safety_state == "due":
            self._autopilot_safety(now_s)
        self._trim_replay_marks()
        opening = (
            not self._started
            and self.failsafe is None
            and self.launch.update(self.context.autopilot, self.context.vehicle)
        )
        if opening:
            self._started = True
            self._started_s = now_s
        if self.envelope_watch is not None:
            # Before the machine starts: a breach in force as the gate opens is acted on
            # instead of starting a behaviour that its failsafe would stop at once.
            self._watch(now_s)
        if opening and self.failsafe is None and self.machine is not None:
            self.machine.start(self.context)
            self._collect_outbox()
        for phase in self._phases:
            if self.terminated:
                break
            phase(now_s)
        self._tick += 1
        return self._drain()

    def _resolve_phases(self, phases: tuple[str, ...]) -> tuple[Callable[[float], None], ...]:
        """The tick's phases as this runtime's methods, in the config's order, once.

        Resolved when the runtime is built, so a tick runs no string switch; a config
        whose phases are not each phase exactly once is refused here as at load (an
        empty list would switch off every timeout and failsafe).

        Raises:
            ConfigError: A phase missing, doubled or unknown.
        """
        check_tick_phases(phases)
        methods: dict[str, Callable[[float], None]] = {
            "timeouts": self._timeouts_phase,
            "machine": self._machine_phase,
            "commands": self._commands_phase,
            "telemetry": self._telemetry,
            "log": self._log_phase,
        }
        if set(methods) != set(TICK_PHASES):  # an engine bug, found by every test
            raise RuntimeError(f"tick phases without a method: {set(TICK_PHASES) ^ set(methods)}")
        return tuple(methods[phase] for phase in phases)

    def _timeouts_phase(self, now_s: float) -> None:
        """Peers', the stations' and the autopilot's silence; the air's log summary."""
        self._timeouts(now_s)
        if self.logbook.air_pending:
            self.logbook.summarise_air(now_s)

    def _commands_phase(self, now_s: float) -> None:
        """What the primitives asked for, collected for the shell."""
        self._collect_outbox()

    def _log_phase(self, now_s: float) -> None:
        """A fleet-table row, when the logbook keeps tables."""
        if self.logbook.tables:
            rows = self.fleet.csv_rows(now_s, text=True)
            self.logbook.fleet_row(now_s, self.fleet.csv_header(), rows)

    def _timeouts(self, now_s: float) -> None:
        lost = self.fleet.check_timeouts(now_s)
        if lost:
            self._fleet_events(lost)
        if self._terminating is not None:
            self._terminate_all_progress(now_s)
            if self.terminated:
                return
        if self._unconfirmed:
            self._resend_unconfirmed(now_s)
        if self._scheduled:
            gps_now = self._gps_now_ms(now_s)
            if gps_now is not None:
                due = [e for e in self._scheduled if e[0] <= gps_now]
                for item in sorted(due):
                    self._scheduled.remove(item)
                    self._events.append(item[1])
        silent_since = self._stations_silent_since_s
        if (
            silent_since is not None
            and self._started_s is not None
            and not self._mcs_lost_raised
            and self._stations
        ):
            # No station in contact: silent since it was last heard, or since the first
            # tick when none ever was; counted from the behaviour's start at the earliest,
            # because before it the behaviour commands nothing a failsafe would stop.
            silent_s = now_s - max(silent_since, self._started_s)
            if silent_s > self.config.heartbeat_timeout_s:
                self.logbook.mission.error(
                    "no station heard for %.1f s", silent_s, extra=LogEvent.STATION_SILENT.extra
                )
                self._mcs_lost()
        if not self.config.is_vehicle or self._autopilot_lost:
            return
        seen = self._autopilot_seen_s
        if seen is None:
            # Counted from the first tick: an autopilot that never speaks is lost too.
            seen = self._first_tick_s if self._first_tick_s is not None else now_s
        if now_s - seen > self.config.autopilot_timeout_s:
            self._autopilot_lost = True
            self._requests_void = True
            self._events.append("autopilot_lost")
            if self._autopilot_connected:
                self.logbook.interface.error(
                    "autopilot silent for %.1f s: lost; no more commands to it",
                    now_s - seen,
                    extra=LogEvent.AUTOPILOT_LOST.extra,
                )
            else:
                self.logbook.interface.info(
                    "no autopilot (testing mode): treated as lost after %.1f s; commands "
                    "to it are dropped",
                    now_s - seen,
                    extra=LogEvent.AUTOPILOT_LOST.extra,
                )

    def _machine_phase(self, now_s: float = 0.0) -> None:
        """Events, then the state machine and its primitives (``now_s`` is the context's)."""
        if self.machine is None or not self._started:
            if "mcs_lost" in self._events:
                self._apply_failsafe()
            ignored = [e for e in self._events if e != "mcs_lost"]
            if self.machine is not None and ignored:
                # An activation before the vehicle can fly must not act minutes later.
                self.logbook.mission.info(
                    "before the behaviour starts (waiting for %s): ignored %s",
                    ", ".join(self.launch.waiting_for) or "the next tick",
                    ", ".join(ignored),
                    extra=LogEvent.BEHAVIOR_EVENT_IGNORED.extra,
                )
            self._events.clear()
            self._air_events.clear()
            return
        events, self._events = self._events, []
        self._air_events.clear()
        for event in events:
            taken = self.failsafe is None and self.machine.dispatch(event, self.context)
            if event == "mcs_lost":
                if taken:
                    self.logbook.mission.warning(
                        "mcs_lost handled by the behaviour", extra=LogEvent.FAILSAFE_HANDLED.extra
                    )
                else:
                    self._apply_failsafe()
            elif not taken and event in _STATION_EVENTS:
                self._say_ignored(event)
            if self.terminated:
                return
        if self._always is not None and self.failsafe is None and self._always.due(self.context):
            # Transitions taken as soon as their condition holds (another agent's state,
            # where it is): raised on the tick a guard of an active state holds.
            self.machine.dispatch(ALWAYS_EVENT, self.context)
            if self.terminated:
                return
        if self.failsafe is None:
            self.machine.step(self.context)
        if self.context.terminate_requested:
            self._terminate(self.context.now_s, self.context.terminal_mode)

    def _say_ignored(self, event: str) -> None:
        """Log a station's activate or deactivate that did nothing, and why.

        The operator who sent it reads in the log that it was dropped, not only that it
        arrived. Once per tick at most (the station's events are coalesced per tick), and through
        the air's rate limit, as every line a packet makes.
        """
        now_s = self.context.now_s
        if not self.logbook.from_air(now_s, "command", "station", 0, f"{event} ignored"):
            return
        if self.failsafe is not None:
            self.logbook.mission.warning(
                "%s: ignored: the failsafe %s holds (a failsafe is final: the behaviour "
                "does not resume)",
                event,
                self.failsafe,
                extra=LogEvent.BEHAVIOR_EVENT_IGNORED.extra,
            )
        else:
            assert self.machine is not None
            active = ", ".join(self.machine.active_paths()) or "the behaviour's root"
            self.logbook.mission.info(
                "%s: ignored: no active state takes it (active: %s)",
                event,
                active,
                extra=LogEvent.BEHAVIOR_EVENT_IGNORED.extra,
            )

    def _collect_outbox(self) -> None:
        outbox = self.context.outbox
        if self._requests_void and outbox.commands:
            outbox.commands = self._void_requests(outbox.commands)
        for command in outbox.commands:
            if isinstance(command, SetMode):
                self._modes.engine_asked(command.mode)
            elif isinstance(command, Takeoff) and self.config.airframe_class == "fixed_wing":
                self._modes.engine_asked("TAKEOFF")  # the adapter's way of taking off
        self._commands.extend(outbox.commands)
        outbox.commands = []
        if outbox.messages:
            self._pending_messages.extend(outbox.messages)
            outbox.messages = []

    def _telemetry(self, now_s: float) -> None:
        by_destination: dict[str, list[Message]] = {}
        for every_ticks, build, destinations in self._telemetry_plan:
            if self._tick % every_ticks:
                continue
            message = build()
            if message is None:
                continue
            for destination in destinations:
                by_destination.setdefault(destination, []).append(message)
        for message, to in self._pending_messages:
            for destination in to or ("",):
                by_destination.setdefault(destination, []).append(message)
        self._pending_messages.clear()
        for state in self._state_messages:
            for station in self._station_names:
                by_destination.setdefault(station, []).append(state)
        self._state_messages.clear()
        for destination in sorted(by_destination):
            self._send(by_destination[destination], destination, now_s)

    def _send(self, messages: list[Message], destination: str, now_s: float) -> None:
        peer = self._peer_by_name.get(destination) if destination else None
        destination_id = peer.id if peer is not None else BROADCAST
        gps = self._gps_now_ms(now_s)
        for sent in self.codec.encode_packets(messages, destination_id, self.max_packet_bytes):
            self._commands.append(
                SendPacket(
                    sent.data, destination, destination_id, peer.radio_address if peer else None
                )
            )
            for message in sent.messages:
                self.logbook.message(
                    "sent",
                    now_s,
                    gps,
                    destination or BROADCAST_PEER,
                    sent.counter,
                    len(sent.data),
                    MESSAGE_NAMES[type(message)],
                    message.gps_time_ms or None,
                    None,
                    "",
                )

    def _resolve_telemetry(
        self,
    ) -> tuple[tuple[int, Callable[[], Message | None], tuple[str, ...]], ...]:
        """The telemetry schedule with each message resolved to its builder, once.

        Each entry: send every this many ticks, the method that builds the message
        (None when there is nothing to say yet), the destinations (``""``: broadcast).
        """
        builders: dict[str, Callable[[], Message | None]] = {
            "heartbeat": self._heartbeat,
            "agent_status": self._agent_status,
            "agent_attitude": self._agent_attitude,
            "behavior_state": self._behavior_state,
            "vehicle_health": self._health_now,
        }
        if set(builders) != set(TELEMETRY_MESSAGES):  # an engine bug, found by every test
            raise RuntimeError(
                f"telemetry messages without a builder: {set(TELEMETRY_MESSAGES) ^ set(builders)}"
            )
        return tuple(
            (spec.every_ticks, builders[spec.message], spec.to or ("",))
            for spec in self.config.telemetry
        )

    def _heartbeat(self) -> Message | None:
        return Heartbeat(
            agent_id=self.config.agent_id,
            gps_time_ms=self.context.gps_time_ms or 0,
            mission_id=self.config.mission_id,
            agent_type=AgentType.VEHICLE if self.config.is_vehicle else AgentType.MCS,
            condition=self._condition(),
            payload_count=len(self.config.payloads),
        )

    def _agent_status(self) -> Message | None:
        vehicle = self.context.vehicle
        if vehicle is None:
            return None
        return AgentStatus(
            agent_id=self.config.agent_id,
            gps_time_ms=self.context.gps_time_ms or 0,
            lat_deg=vehicle.lat_deg,
            lon_deg=vehicle.lon_deg,
            alt_m=vehicle.alt_m,
            ground_speed_m_s=max(0.0, vehicle.ground_speed_m_s),
            climb_rate_m_s=vehicle.climb_rate_m_s,
            heading_deg=vehicle.heading_deg % 360.0,
            mode=vehicle.custom_mode,
        )

    def _agent_attitude(self) -> Message | None:
        vehicle = self.context.vehicle
        if vehicle is None:
            return None
        return AgentAttitude(
            self.config.agent_id,
            self.context.gps_time_ms or 0,
            vehicle.roll_deg,
            vehicle.pitch_deg,
            vehicle.yaw_deg,
        )

    def _behavior_state(self) -> Message | None:
        if self.machine is None:
            return None
        return BehaviorState(
            self.config.agent_id,
            self.context.gps_time_ms or 0,
            self.machine.active_paths(),
            self.machine.last_event,
        )

    def _health_now(self) -> Message | None:
        if not self.config.is_vehicle:
            return None
        return self._vehicle_health(self.config.agent_id, self.context.gps_time_ms or 0)

    def _vehicle_health(self, me: int, gps: int) -> VehicleHealth:
        """Vehicle Health now: what the autopilot last said, and the failsafe in force.

        Every figure is sent within the wire's range or as unknown (an autopilot's
        garbled figure must not stop the tick: the encoder refuses what is out of
        range), and the texts are cut to their bounds at a character boundary.
        """
        health = self._health or AutopilotHealth()
        battery_v = health.battery_v
        if battery_v is not None and not 0.0 <= battery_v <= _BATTERY_V_MAX:
            battery_v = None
        pct = health.battery_pct if health.battery_pct in range(101) else None
        satellites = health.satellites
        if satellites is not None and not 0 <= satellites <= _SATELLITES_MAX:
            satellites = None
        severity, text, age_s = 0, "", 0
        if self._warning is not None:
            said, at_s = self._warning
            text = fit_text(said.text, MAX_HEALTH_TEXT_BYTES)
            severity = max(0, said.severity) if text else 0
            age_s = max(0, int(self.context.now_s - at_s)) if text else 0
        failsafe = ""
        if self.failsafe is not None:
            why = f": {self.failsafe_reason}" if self.failsafe_reason else ""
            failsafe = fit_text(f"{self.failsafe}{why}", MAX_FAILSAFE_TEXT_BYTES)
        prearm = {None: PrearmState.UNKNOWN, True: PrearmState.PASSING}.get(
            health.prearm_ok, PrearmState.FAILING
        )
        return VehicleHealth(
            agent_id=me,
            gps_time_ms=gps,
            armed=self._armed,
            battery_v=battery_v,
            battery_pct=pct,
            gps_fix_type=health.gps_fix_type
            if 0 <= health.gps_fix_type <= _GPS_FIX_TYPE_MAX
            else 0,
            satellites=satellites,
            prearm=prearm,
            text_severity=severity,
            text=text,
            failsafe=failsafe,
            autopilot_lost=self._autopilot_lost,
            text_age_s=age_s,
        )

    def _condition(self) -> Condition:
        if self.terminated:
            return Condition.TERMINATED
        if self.failsafe is not None:
            return Condition.FAILSAFE
        lost = any(r.lost for r in self.fleet.agents())
        return Condition.DEGRADED if self._autopilot_lost or lost else Condition.OK

    # -- safety --------------------------------------------------------------------------

    def _mcs_lost(self) -> None:
        """Queue mcs_lost; the machine phase gives the behaviour the first chance at it."""
        if self._mcs_lost_raised:
            return
        self._mcs_lost_raised = True
        self._events.append("mcs_lost")
        self.logbook.mission.error(
            "every station is silent: mcs_lost", extra=LogEvent.STATION_LOST.extra
        )

    def _void_requests(self, commands: list[Command]) -> list[Command]:
        """The behaviour's commands without the requests of states active across a loss.

        A primitive asks for a mode, an arm or a takeoff when its state starts and asks
        again while the vehicle reports what it reported then; a state entered before or
        during an autopilot loss asked while nobody heard, from a view of the vehicle
        that is stale now, so its asking again after the return would carry out a
        request of the silent time. Targets, servos and overrides still go: the
        autopilot acts on a target only in its guided mode, whoever chose it.
        """
        kept: list[Command] = [c for c in commands if not isinstance(c, _REQUESTS)]
        if len(kept) != len(commands) and not self._autopilot_lost:
            self.logbook.mission.info(
                "not sent, asked for by a state active while the autopilot was lost: %s",
                ", ".join(type(c).__name__ for c in commands if isinstance(c, _REQUESTS)),
                extra=LogEvent.COMMAND_VOIDED.extra,
            )
        return kept

    def _apply_failsafe(self, action: str | None = None, *, breach: Breach | None = None) -> None:
        """A failsafe: the machine stopped, then the action's mode; never applied twice.

        Args:
            action: ``hold``, ``rtl``, ``land`` or ``continue``; None: the declared
                mcs_lost failsafe (when the behaviour does not handle the event).
            breach: The envelope breach this failsafe answers. Its mode is sent only
                when the vehicle is in a mode the engine put it in: a pilot, a station
                or the autopilot's own failsafe that took the vehicle is not fought.
        """
        if action is None:
            action = (
                self.config.failsafe.get("mcs_lost", "hold")
                if self.config.is_vehicle
                else "continue"
            )
        # `clark analyze --checks` and `clark replay` read this line (log_checks): keep it.
        self.logbook.mission.error("failsafe %s", action, extra=LogEvent.FAILSAFE_ACT.extra)
        if action == "continue" or self.failsafe is not None:
            return
        mode = {
            "hold": self.config.hold_mode,
            "rtl": self.config.rtl_mode,
            "land": self.config.land_mode,
        }.get(action)
        self.failsafe = action
        self.failsafe_reason = (
            "mcs_lost"
            if breach is None
            else f"{breach.kind} {breach.peer}"
            if breach.peer
            else breach.kind
        )
        if self.machine is not None:
            self.machine.stop(self.context)
            self._collect_outbox()
        if self.envelope_guard is not None:
            self.envelope_guard.end_episode()  # the behaviour sends no more targets
        if breach is not None and not self._modes.engine_holds:
            reported = self._modes.reported or "an unknown mode"
            self.logbook.mission.warning(
                "failsafe %s: no mode sent: the vehicle is in %s, a mode the engine did not "
                "put it in (its pilot, the station or the autopilot chose it); the "
                "behaviour is stopped",
                action,
                reported,
                extra=LogEvent.FAILSAFE_NO_MODE.extra,
            )
            return
        if mode is not None and mode in self.config.modes:
            command = SetMode(mode, int(self.config.modes[mode]))
            self._modes.engine_asked(mode)
            self._commands.append(command)
            if self._autopilot_lost:
                self._failsafe_unsent = command  # sent when the autopilot returns

    def _here(self, vehicle: VehicleState) -> tuple[float, float]:
        """The vehicle's position on the local plane (north, east), once per state."""
        cached = self._here_cache
        if cached is not None and cached[0] is vehicle:
            return cached[1]
        point = to_local(vehicle.lat_deg, vehicle.lon_deg, 0.0, self._origin)
        here = (point.north_m, point.east_m)
        self._here_cache = (vehicle, here)
        return here

    def _watch(self, now_s: float) -> None:
        """The vehicle and its peers against the envelope; a breach's action, once.

        Run at the start of every tick, before the machine phase. Before the behaviour
        starts the engine commands nothing, so a breach then is logged only; from the
        tick the launch gate opens, the first breach in force (begun then or before)
        applies its action as a failsafe, and any later one is logged only.
        """
        watch, vehicle = self.envelope_watch, self.context.vehicle
        if watch is None or vehicle is None:
            return
        result = watch.look(
            vehicle,
            self._peer_positions.fixes(now_s, self._here(vehicle)),
            now_s,
            guided_flight=self._guided_flight(vehicle),
        )
        for ended in result.ended:
            self.logbook.mission.info(
                "envelope breach over: %s",
                ended.describe(),
                extra=LogEvent.ENVELOPE_BREACH_OVER.extra,
            )
        acting = result.active and self._started and self.failsafe is None
        act = result.active[0] if acting else None
        if act is not None:
            self.breach = act
            self.logbook.mission.error(
                "envelope breach: %s: %s",
                act.describe(),
                act.action,
                extra=LogEvent.ENVELOPE_BREACH.extra,
            )
            self._apply_failsafe(act.action, breach=act)
        for breach in result.began:
            if breach is act:
                continue
            if not self._started:
                self.logbook.mission.warning(
                    "envelope breach: %s: logged only (the behaviour has not started, "
                    "the engine commands nothing)",
                    breach.describe(),
                    extra=LogEvent.ENVELOPE_BREACH.extra,
                )
            else:
                self.logbook.mission.error(
                    "envelope breach: %s: %s not applied (the failsafe %s holds; a failsafe "
                    "is applied once)",
                    breach.describe(),
                    breach.action,
                    self.failsafe,
                    extra=LogEvent.ENVELOPE_BREACH.extra,
                )

    def _guided_flight(self, vehicle: VehicleState) -> bool:
        """An aircraft in the air, in the guided mode, flying to a Goto (not taking off)."""
        return (
            self.config.is_aircraft
            and vehicle.mode == self.config.guided_mode
            and self._last_navigation == "goto"
            and is_airborne(self.context.autopilot, vehicle)
        )

    def _envelope_summary(self) -> None:
        """The mission log's closing line: what the guard did, and the breach, if any."""
        guard = self.envelope_guard
        if guard is None:
            return
        guard.end_episode()
        counts = guard.counts
        breach = self.breach
        self.logbook.mission.log(
            logging.WARNING if counts.clamped or counts.refused or breach else logging.INFO,
            "envelope: %s; %s",
            counts.describe(),
            (
                f"breach at t={breach.began_s:.3f}: {breach.describe()}: {breach.action}"
                if breach is not None
                else "no breach acted on"
            ),
            extra=LogEvent.ENVELOPE_SUMMARY.extra,
        )

    def _terminate(self, now_s: float, mode: str | None) -> None:
        """Thesis 7.3.5: stop commanding, terminal mode, close interfaces, flush logs."""
        if self.terminated:
            return
        # Nothing queued before is sent, except packets; what stopping primitives emit
        # is sent: it hands control back (an RC override released, a servo to trim).
        self._commands = [c for c in self._commands if isinstance(c, SendPacket)]
        if self.machine is not None and self._started:
            self.machine.stop(self.context)
            self._commands.extend(self.context.outbox.commands)
            self.context.outbox.commands = []
        terminal = mode or self.config.terminal_mode
        if self.config.is_vehicle and terminal is not None and terminal in self.config.modes:
            self._commands.append(SetMode(terminal, int(self.config.modes[terminal])))
        self.terminated = True
        # A last heartbeat tells every peer (and the station's view) this agent is done.
        last = self._heartbeat()
        if last is not None:
            self._send([last], "", now_s)
        self._commands.append(CloseInterfaces())
        self.logbook.mission.warning(
            "terminated%s",
            f"; vehicle to {terminal}" if terminal else "",
            extra=LogEvent.AGENT_TERMINATED.extra,
        )
        if self.close_logbook_on_terminate:
            self.logbook.close()

    # -- the autopilot's safety set-up -----------------------------------------------------

    def _autopilot_safety(self, now_s: float) -> None:
        """Ask the autopilot to hold the envelope itself, once it can (before the start).

        Sent once the vehicle reports where it is and, when the profile waits for
        readiness, its home (FENCE_ALT_MAX and the return altitude are above home): not
        after its pre-arm checks, which a fence left on the autopilot by an earlier
        mission may fail until this set-up replaces it.
        """
        status = self.context.autopilot
        if (
            self._autopilot_lost
            or self.terminated
            or self.context.vehicle is None
            or now_s < self._safety_due_s
            or (self.config.wait_ready and (status is None or status.home is None))
        ):
            return
        try:
            command = safety_setup(self.config, status.home if status is not None else None)
        except SafetyPlanError as exc:
            self._safety_state = "failed"
            self.launch.safety_result(str(exc))
            self.logbook.mission.error(
                "the autopilot's safety set-up cannot be made: %s; the behaviour will not start",
                exc,
                extra=LogEvent.SAFETY_SETUP.extra,
            )
            return
        self._safety_state = "sent"
        self._commands.append(command)
        self.logbook.mission.info(
            "setting up the autopilot's own safety (the behaviour waits for it): %s",
            command.summary,
            extra=LogEvent.SAFETY_SETUP.extra,
        )

    def _safety_result(self, result: AutopilotSafetyResult, now_s: float) -> None:
        """The adapter's answer: the gate may open, or says why it will not."""
        if self._safety_state != "sent":
            return  # an answer to nothing asked (a set-up already ended)
        self.launch.safety_result(result.problem)
        if result.ok:
            self._safety_state = "done"
            self.logbook.mission.info(
                "the autopilot's fence and its reaction to a dead mission computer are set "
                "and read back",
                extra=LogEvent.SAFETY_SETUP.extra,
            )
            return
        if result.retry:
            self._safety_state = "due"
            self._safety_due_s = now_s + SAFETY_RETRY_S
            self.logbook.mission.error(
                "the autopilot's safety set-up was cut short: %s; asked again once the "
                "autopilot is back",
                result.problem,
                extra=LogEvent.SAFETY_SETUP.extra,
            )
            return
        self._safety_state = "failed"
        self.logbook.mission.error(
            "the autopilot's safety set-up failed: %s; the behaviour will not start: fix "
            "the autopilot (or its profile) and start again",
            result.problem,
            extra=LogEvent.SAFETY_SETUP.extra,
        )

    # -- machine callbacks ---------------------------------------------------------------

    def _evaluate(self, when: Mapping[str, Any], ctx: PrimitiveContext, in_state_s: float) -> bool:
        """Decide a structured transition condition as written (the schema's kinds).

        The machine resolves every condition once instead (:meth:`_resolve_condition`);
        this decides one as written, for callers that hold a condition as data.

        Args:
            when: The condition, as the compiled config gives it.
            ctx: The agent's context (vehicle, peers, clock).
            in_state_s: Time since the state owning the transition was entered.
        """
        return self._resolve_condition(when)(ctx, in_state_s)

    def _resolve_condition(self, when: Mapping[str, Any]) -> Holds:
        """A transition's condition resolved once into what decides it each time.

        Called when the machine is built, so the condition's kind, bounds and agent are
        read once and a tick reads no string: ``all``/``any``/``not`` combine their
        parts; ``mode`` compares the vehicle's mode; ``distance_m`` (to a peer, read by
        the id the peer table gives; loading proved it a peer), ``altitude_m``,
        ``speed_m_s`` and ``in_state_s`` hold while the figure is below ``lt`` and above
        ``gt``, and never while it is unknown; a condition on another agent (its state,
        where it is) is :mod:`~clark_engine.runtime.peer_conditions`', on fresh data only.
        A condition with no key always holds.
        """
        for key, value in when.items():  # exactly one key (the schema's)
            if key in ("all", "any"):
                parts = tuple(self._resolve_condition(item) for item in value)
                if key == "all":
                    return lambda ctx, s: all(part(ctx, s) for part in parts)
                return lambda ctx, s: any(part(ctx, s) for part in parts)
            if key == "not":
                inner = self._resolve_condition(value)
                return lambda ctx, s: not inner(ctx, s)
            if key == "mode":
                mode = value["is"]
                return lambda ctx, _s: ctx.vehicle is not None and ctx.vehicle.mode == mode
            if key in PEER_CONDITIONS:  # another agent's state or relative position
                return resolve_peer_condition(key, value, self.config)
            return _bounded(self._measurement(key, value), value.get("lt"), value.get("gt"))
        return _always

    def _measurement(
        self, key: str, value: Mapping[str, Any]
    ) -> Callable[[PrimitiveContext, float], float | None]:
        """What a bounded condition measures, None while it is unknown."""
        if key == "in_state_s":
            return _in_state_s
        if key == "distance_m":
            peer = self.config.peer(str(value["to"]))
            if peer is None:  # loading refuses it; a config built in code may not have
                return _unknown
            peer_id = peer.id

            def distance(ctx: PrimitiveContext, _s: float) -> float | None:
                vehicle = ctx.vehicle
                status = ctx.peer_status_by_id(peer_id)
                if vehicle is None or status is None:
                    return None
                return ground_distance_m(
                    vehicle.lat_deg, vehicle.lon_deg, status.lat_deg, status.lon_deg
                )

            return distance
        if key == "altitude_m":
            return _altitude_m
        if key == "speed_m_s":
            return _speed_m_s
        return _unknown

    def terminate(self, now_s: float, reason: str) -> list[Command]:
        """Run this agent's own terminate sequence now and return the commands it produced.

        What a shell calls when it stops (SIGINT, SIGTERM, the end of a timed run): the
        same sequence a station's terminate command runs (thesis 7.3.5), for this agent
        only, with nothing sent to any other agent's behaviour: the primitives stopped
        (what they emit to hand control back is kept), the vehicle to its terminal mode,
        a last heartbeat, :class:`CloseInterfaces`; the logbook is closed. Commands
        queued before and not yet drained are dropped, except packets.

        Args:
            now_s: The runtime's time.
            reason: Why, for the mission log (``SIGTERM``, ``--until``).

        Returns:
            The commands to carry out; empty when the runtime already terminated.
        """
        if self.terminated:
            return []
        self._set_time(now_s)
        if not self.logbook.closed:
            self.logbook.mission.warning(
                "terminating: %s", reason, extra=LogEvent.AGENT_TERMINATING.extra
            )
        self._terminate(now_s, None)
        return self._drain()

    @property
    def behaviour_started(self) -> bool:
        """True once the launch gate opened and the behaviour (state machine) started.

        Before then the agent waits for readiness, arming or take-off as its mission
        says; a status display shows that rather than an empty state.
        """
        return self._started

    @property
    def envelope_counts(self) -> EnvelopeCounts | None:
        """What the envelope guard did with the targets so far; None without a guard."""
        return self.envelope_guard.counts if self.envelope_guard is not None else None

    @property
    def autopilot_lost(self) -> bool:
        """True from the autopilot's timeout to its next VehicleState: vehicle commands dropped."""
        return self._autopilot_lost

    def _on_change(self, change: StateChange) -> None:
        if self._always is not None:
            self._always.on_change(change)
        if not self._autopilot_lost:
            self._requests_void = False  # a state entered now asks afresh
        self.logbook.mission.info(
            "%s: %s -> %s (active: %s)",
            change.event,
            change.source or "(start)",
            change.target or "(behavior)",
            ", ".join(change.active),
            extra=LogEvent.BEHAVIOR_CHANGE.extra,
        )
        if self._stations and self.machine is not None:
            self._state_messages.append(
                BehaviorState(
                    self.config.agent_id,
                    self.context.gps_time_ms or 0,
                    tuple(change.active),
                    change.event,
                )
            )
        for listener in self.state_listeners:
            listener(change)

    # -- output --------------------------------------------------------------------------

    def _drain(self) -> list[Command]:
        commands, self._commands = self._commands, []
        if self._autopilot_lost or (self.terminated and not self._closing(commands)):
            commands = [c for c in commands if not isinstance(c, VEHICLE_COMMANDS)]
        elif self.envelope_guard is not None:
            for command in commands:
                if isinstance(command, _GUARDED):
                    return self._guard(commands)
        return commands

    def _guard(self, commands: list[Command]) -> list[Command]:
        """The last step before commands leave: every Goto and Takeoff kept in the envelope."""
        guard = self.envelope_guard
        assert guard is not None
        vehicle = self.context.vehicle
        peers = self._peer_positions.fixes(
            self.context.now_s, self._here(vehicle) if vehicle is not None else None
        )
        out: list[Command] = []
        for command in commands:
            if isinstance(command, _GUARDED):
                kept = guard.check(command, self.context.vehicle, peers, self.context.now_s)
                if kept is None:
                    if isinstance(command, UploadMission) and self.machine is not None:
                        self.machine.deliver_mission(self.context, refused_by_envelope(command))
                    continue
                if not isinstance(kept, UploadMission):
                    self._last_navigation = "goto" if isinstance(kept, Goto) else "takeoff"
                command = kept
            out.append(command)
        return out

    @staticmethod
    def _closing(commands: list[Command]) -> bool:
        return any(isinstance(c, CloseInterfaces) for c in commands)


def _always(_ctx: PrimitiveContext, _in_state_s: float) -> bool:
    return True


def _unknown(_ctx: PrimitiveContext, _in_state_s: float) -> float | None:
    return None


def _in_state_s(_ctx: PrimitiveContext, in_state_s: float) -> float | None:
    return in_state_s


def _altitude_m(ctx: PrimitiveContext, _in_state_s: float) -> float | None:
    return ctx.vehicle.alt_m if ctx.vehicle is not None else None


def _speed_m_s(ctx: PrimitiveContext, _in_state_s: float) -> float | None:
    return ctx.vehicle.ground_speed_m_s if ctx.vehicle is not None else None


def _bounded(
    measure: Callable[[PrimitiveContext, float], float | None],
    lt: float | None,
    gt: float | None,
) -> Holds:
    """Holds while the measure is known, below ``lt`` and above ``gt`` (each when given)."""

    def holds(ctx: PrimitiveContext, in_state_s: float) -> bool:
        measured = measure(ctx, in_state_s)
        if measured is None:
            return False
        if lt is not None and not measured < lt:
            return False
        return not (gt is not None and not measured > gt)

    return holds
