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

The runtime owns a helper object per concern, each in a module of its own and each
reading and changing the runtime's state through a back-reference (one agent's state,
one owner): :class:`~clark_engine.runtime.safety.Safety` (the rules above),
:class:`~clark_engine.runtime.packets_in.PacketIntake` (packets in, who may command),
:class:`~clark_engine.runtime.station_commands.StationCommands` (a station's commands
out) and :class:`~clark_engine.runtime.telemetry.Telemetry` (messages and packets out).
This module keeps the events in, the tick's phases and what leaves. Over 800 lines
because those three share the runtime's state at every step (the events feed the tick's
phases, whose commands leave through the same guard) and each is read top to bottom in
the order a tick runs; what had a seam of its own is in the helpers above.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping
from typing import Any, Final

from clark_engine.behaviors import make_behavior as make_primitive
from clark_engine.link.auth import CounterStore, ReplayStore
from clark_engine.link.codec import Codec
from clark_engine.link.errors import ReplayStoreError
from clark_engine.link.fleet import AgentFound, AgentLost, FleetTable, ForeignAgent
from clark_engine.link.messages import (
    MAX_SEVERITY_SENT,
    BehaviorState,
)
from clark_engine.mission.geo import Origin
from clark_engine.mission.model import TICK_PHASES
from clark_engine.mission.peer_conditions import ALWAYS_EVENT
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
from clark_engine.runtime.conditions import resolve_condition
from clark_engine.runtime.config import AgentConfig, check_tick_phases
from clark_engine.runtime.context import PrimitiveContext
from clark_engine.runtime.envelope import PeerPositions, largest_separation_m
from clark_engine.runtime.envelope_guard import EnvelopeCounts, EnvelopeGuard
from clark_engine.runtime.envelope_watch import Breach, EnvelopeWatch
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
from clark_engine.runtime.launch import LaunchGate
from clark_engine.runtime.log_events import LogEvent
from clark_engine.runtime.logbook import (
    Logbook,
)
from clark_engine.runtime.machine import BehaviorMachine, Holds, StateChange
from clark_engine.runtime.mode_owner import ModeOwner
from clark_engine.runtime.packets_in import PacketIntake
from clark_engine.runtime.peer_conditions import AlwaysWatch
from clark_engine.runtime.safety import GUARDED, Safety
from clark_engine.runtime.station_commands import StationCommands
from clark_engine.runtime.telemetry import Telemetry

#: Commands that move the vehicle; never sent while the autopilot is lost or after terminate.
VEHICLE_COMMANDS = (Goto, SetMode, Arm, Takeoff, SetServo, RcOverride, UploadMission)
_STATION_EVENTS: Final = frozenset({"activate", "deactivate"})
"""Events a station's Activate Controller raises: one that does nothing is logged so."""

#: An RC input above this is a switch in its high position, below the low one (ArduPilot's
#: auxiliary-switch thresholds); the events fire on crossing, not while held.
RC_HIGH_US = 1800
RC_LOW_US = 1200


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
        #: The safety rules: failsafes, the envelope in flight, the autopilot's set-up.
        self._safety = Safety(self)
        #: What this agent sends each tick, and the packets it sends.
        self._telemetry = Telemetry(self)
        #: The tick's phases, resolved to methods once (:meth:`_resolve_phases`).
        self._phases = self._resolve_phases(config.tick_phases)
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
        #: Whether the vehicle is in a mode the engine put it in (a breach never fights
        #: a pilot or a station who took it).
        self._modes = ModeOwner()
        #: The last navigation command that left: "goto" or "takeoff" (the floor is
        #: watched only in guided flight to a Goto, never in a take-off's climb).
        self._last_navigation: str | None = None
        if envelope is not None:
            self.logbook.closing.append(self._safety.envelope_summary)
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
        self._peer_by_id = {p.id: p for p in config.peers}
        #: Packets from the air: checked, logged, and a station's commands acted on.
        self._intake = PacketIntake(self)
        #: A station's operator commands out: sent, sent again until taken, a fleet terminate.
        self._station = StationCommands(self)
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
            self._intake.receive(event.data, now_s)
        elif isinstance(event, VehicleState):
            self._vehicle(event, now_s)
        elif isinstance(event, AutopilotHeartbeat):
            self._autopilot_heartbeat(event, now_s)
        elif isinstance(event, RcChannels):
            self._rc(event)
        elif isinstance(event, AutopilotStatus):
            self.context.autopilot = event
        elif isinstance(event, AutopilotSafetyResult):
            self._safety.set_up_result(event, now_s)
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
            self._station.command(event, now_s)
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
            self._intake.mode_requests.clear()  # a request for a mode again is news now
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
            self._safety.set_up_autopilot(now_s)
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
            self._safety.watch(now_s)
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
            "telemetry": self._telemetry.phase,
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
        if self._station.terminating is not None:
            self._station.terminate_all_progress(now_s)
            if self.terminated:
                return
        if self._station.unconfirmed:
            self._station.resend_unconfirmed(now_s)
        if self._intake.scheduled:
            gps_now = self._gps_now_ms(now_s)
            if gps_now is not None:
                due = [e for e in self._intake.scheduled if e[0] <= gps_now]
                for item in sorted(due):
                    self._intake.scheduled.remove(item)
                    self._events.append(item[1])
        self._safety.silences(now_s)

    def _machine_phase(self, now_s: float = 0.0) -> None:
        """Events, then the state machine and its primitives (``now_s`` is the context's)."""
        if self.machine is None or not self._started:
            if "mcs_lost" in self._events:
                self._safety.apply_failsafe()
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
            self._intake.air_events.clear()
            return
        events, self._events = self._events, []
        self._intake.air_events.clear()
        for event in events:
            taken = self.failsafe is None and self.machine.dispatch(event, self.context)
            if event == "mcs_lost":
                if taken:
                    self.logbook.mission.warning(
                        "mcs_lost handled by the behaviour", extra=LogEvent.FAILSAFE_HANDLED.extra
                    )
                else:
                    self._safety.apply_failsafe()
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
            outbox.commands = self._safety.void_requests(outbox.commands)
        for command in outbox.commands:
            if isinstance(command, SetMode):
                self._modes.engine_asked(command.mode)
            elif isinstance(command, Takeoff) and self.config.airframe_class == "fixed_wing":
                self._modes.engine_asked("TAKEOFF")  # the adapter's way of taking off
        self._commands.extend(outbox.commands)
        outbox.commands = []
        if outbox.messages:
            self._telemetry.pending.extend(outbox.messages)
            outbox.messages = []

    # -- terminate -----------------------------------------------------------------------

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
        last = self._telemetry.heartbeat()
        if last is not None:
            self._telemetry.send([last], "", now_s)
        self._commands.append(CloseInterfaces())
        self.logbook.mission.warning(
            "terminated%s",
            f"; vehicle to {terminal}" if terminal else "",
            extra=LogEvent.AGENT_TERMINATED.extra,
        )
        if self.close_logbook_on_terminate:
            self.logbook.close()

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
        """The machine's resolver: :func:`~clark_engine.runtime.conditions.resolve_condition`."""
        return resolve_condition(when, self.config)

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
    def behavior_started(self) -> bool:
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
            self._telemetry.states.append(
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
                if isinstance(command, GUARDED):
                    return self._safety.guard(commands)
        return commands

    @staticmethod
    def _closing(commands: list[Command]) -> bool:
        return any(isinstance(c, CloseInterfaces) for c in commands)
