"""The dry run: every agent's real runtime against simulated vehicles, radios and cameras.

A discrete-event simulation on a virtual clock. Each agent runs the same
:class:`AgentRuntime` it would fly with, built from its compiled config; its
autopilot commands go through the real MAVLink adapter (:mod:`clark_engine.io`)
as bytes to a simulated ArduPilot (:class:`SimAutopilot`) flying a vehicle
model, and its packets go through the ClarkLink codec onto a simulated radio
mesh. Nothing reads the wall clock and every random draw comes from a generator
seeded from ``--seed``, so the same mission and seed give byte-identical logs
and CSV files.

Time advances from event to event: vehicle physics every ``PHYSICS_STEP_S``,
each agent's ticks at its ``loop_hz`` (with a seeded phase, since the thesis's
agents were not synchronised), radio deliveries and camera answers when they
are due, and the scenario's operator actions and faults at their times. Events
at the same time are processed in a fixed order: physics (every vehicle steps,
then each agent hears its autopilot's telemetry), radio deliveries, camera
answers, scenario, then agent ticks in the mission's agent order.

The world the run advances is built by :mod:`clark_engine.dryrun.world` (each agent's
pieces, its vehicle, the radio mesh) and what happens to it from outside comes from
:mod:`clark_engine.dryrun.scenario` (faults, the operator's script); this module is the
loop: the event schedule and the routes that carry out every agent's commands.

A run is one process. (It could once be split across processes; beside other
runs it was never faster, so it was removed: docs/performance.md, "The dry run's
split removed". ``clark campaign --workers`` uses several cores on many runs.)
"""

from __future__ import annotations

import functools
import heapq
import math
import random
import time
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from clark_engine.behaviors import behaviors
from clark_engine.dryrun.scenario import apply_faults, jittered_operator
from clark_engine.dryrun.sitl_backend import SitlBackend
from clark_engine.dryrun.sitl_pace import SitlPace
from clark_engine.dryrun.sitl_preflight import PLANE_HANDOVER_M, PLANE_HANDOVER_TRIES
from clark_engine.dryrun.world import (
    START_UNIX_US,
    SimAgent,
    build_mesh,
    build_sitl_vehicle,
    build_vehicle,
    tick_phase,
)
from clark_engine.expectations.recording import FlightEntry, Photo, Recording, StateEntry, Track
from clark_engine.io.autopilot import AutopilotAdapter
from clark_engine.io.autopilot_decode import gps_time_ms_from_unix_us
from clark_engine.io.autopilot_settings import AutopilotSettings
from clark_engine.link.auth import load_key
from clark_engine.mission.compiler import agent_config
from clark_engine.mission.model import Agent, Mission
from clark_engine.mission.variation import resolve_mission
from clark_engine.runtime.commands import (
    AUTOPILOT_COMMANDS,
    CloseInterfaces,
    Command,
    PayloadCommand,
    SendPacket,
    SetServo,
    check_dispatch,
    unknown_command,
)
from clark_engine.runtime.config import AgentConfig, config_from_dict
from clark_engine.runtime.events import PacketReceived, StationCommand
from clark_engine.runtime.log_events import LogEvent
from clark_engine.runtime.logbook import Logbook
from clark_engine.runtime.machine import StateChange
from clark_engine.runtime.runtime import AgentRuntime
from clark_engine.sim.camera import SimCamera
from clark_engine.sim.radio import Position, RadioMesh
from clark_engine.sitl.launcher import SitlInstall

#: Vehicle physics and autopilot telemetry step.
PHYSICS_STEP_S = 0.02
#: Tracks are sampled this often (plots, distance and separation checks).
SAMPLE_PERIOD_S = 0.1


@dataclass(slots=True)
class DryRunResult:
    """What a dry run produced.

    Attributes:
        recording: Tracks, states, signals, photos and safety events of every agent.
        configs: Every agent's compiled config.
        agents: Every agent's pieces in the simulation.
        radio: The mesh, with every link's statistics.
        wall_s: Wall-clock seconds of the simulation loop.
        ticks: Agent name -> ticks it ran.
    """

    recording: Recording
    configs: dict[str, AgentConfig]
    agents: dict[str, SimAgent]
    radio: RadioMesh
    wall_s: float
    ticks: dict[str, int] = field(default_factory=dict)


class DryRun:
    """One dry run of a validated mission.

    Args:
        mission: The resolved mission (from validation, without errors).
        mission_path: The mission file (for the key file's relative path).
        seed: Seeds every random draw.
        until_s: Simulated seconds to run.
        log_dir: Where each agent's logs and CSV files go (``<log_dir>/<agent>/``);
            in memory when None.
        extra_faults: Faults given on the command line, in the mission's fault form.
        progress: Called now and then with (simulated time, end time).
        speed: Run at this many simulated seconds per wall-clock second (1 is real
            time); as fast as possible when None.
        wall_clock: The simulated autopilots' SYSTEM_TIME gives the wall clock's time
            (a real-time run with ground stations), not the simulated one.
        sitl: Fly every vehicle's autopilot as a real ArduPilot SITL process from this
            install instead of the simulated one (:mod:`clark_engine.dryrun.sitl_backend`);
            SITL's clock then sets the pace. None: the simulated autopilot.
        sitl_speedup: SITL's speed-up (1: real time).
        operator_script: Play the mission's operator actions for the station (activate,
            deactivate, mode, terminate); False leaves them to a person at the station's
            view (``--station --no-operator-script``). The pilots' ``rc`` actions play
            either way.
    """

    def __init__(
        self,
        mission: Mission,
        mission_path: Path,
        *,
        seed: int,
        until_s: float,
        log_dir: Path | None = None,
        extra_faults: Sequence[Mapping[str, Any]] = (),
        progress: Callable[[float, float], None] | None = None,
        speed: float | None = None,
        wall_clock: bool = False,
        sitl: SitlInstall | None = None,
        sitl_speedup: float = 10.0,
        operator_script: bool = True,
    ) -> None:
        # A mission straight from validation may still hold distributions: this run's draw
        # (run_dry_run draws first, and reports what it drew; drawing again is a no-op).
        mission, _ = resolve_mission(mission, seed)
        self.mission = mission
        self.wall_clock = wall_clock
        self.sitl = sitl
        self.sitl_speedup = sitl_speedup
        self._preflights: dict[str, dict[str, Any]] = {}
        self.preflight_wall_s: dict[str, float] = {}
        """With SITL: the wall seconds each aircraft handed over in flight took to fly up."""
        self.handover_again: dict[str, list[float]] = {}
        """With SITL: a plane off its position at time 0, flown round again: how far off
        it was (metres) each time."""
        self.seed = seed
        self.until_s = until_s
        self.progress = progress
        self.speed = speed
        self.recording = Recording()
        self.radio = build_mesh(mission, seed)
        key = load_key(mission_path.parent / mission.key_file) if mission.key_file else None
        gps_epoch_ms = gps_time_ms_from_unix_us(START_UNIX_US)
        self.agents: dict[str, SimAgent] = {}
        for name, agent in mission.agents.items():
            config = config_from_dict(agent_config(mission, agent))
            logbook = (
                Logbook.to_folder(log_dir, config, overwrite=True)
                if log_dir is not None
                else Logbook.in_memory(config, tables=False)
            )
            runtime = AgentRuntime(config, key=key, logbook=logbook, gps_epoch_ms=gps_epoch_ms)
            offset = tick_phase(seed, name) / config.loop_hz
            sim_agent = SimAgent(name, config, runtime, logbook, offset)
            self.agents[name] = sim_agent
            runtime.state_listeners.append(self._state_listener(name))
            self.recording.states[name] = []
            for payload, profile in agent.hardware.payloads.items():
                if profile.get("payload_kind") == "camera":
                    sim_agent.cameras[payload] = SimCamera(
                        payload, profile, random.Random(f"{seed}:camera:{name}:{payload}")
                    )
            if agent.is_vehicle:
                self._build_vehicle(sim_agent, agent)
        # Agent order (the tie-break of ticks at one time) is the mission's.
        self._order = {name: i for i, name in enumerate(mission.agents)}
        self._vehicles = [a for a in self.agents.values() if a.backend is not None]
        # Stations and agents without a vehicle stay where the mission puts them.
        self._fixed_positions: dict[str, Position] = {
            name: (agent.position.north_m, agent.position.east_m, agent.position.up_m)
            for name, agent in mission.agents.items()
            if not agent.is_vehicle
        }
        self._kills = apply_faults(
            [*mission.faults, *extra_faults], mission=mission, radio=self.radio, agents=self.agents
        )
        station = next((a.name for a in mission.agents.values() if not a.is_vehicle), None)
        operator = jittered_operator(mission, seed)
        # A pilot's stick acts on its vehicle, every other action through the (first)
        # station; without the script, only the pilots' actions play.
        self._operator = [
            entry
            for entry in operator
            if (str(entry[2]["rc"]["agent"]) if "rc" in entry[2] else station) in self.agents
            and (operator_script or "rc" in entry[2])
        ]
        self._station = self.agents.get(station) if station is not None else None
        self._signal_channels()
        #: Every agent's position after the last physics step (only kept when a radio has a
        #: range: only then do positions matter to the mesh).
        self._positions: dict[str, Position] = dict(self._fixed_positions)
        self._ranged = self.radio.uses_positions
        #: Agent -> called with every byte string its simulated autopilot emits (real-time
        #: mode forwards them to a ground station over UDP).
        self.autopilot_taps: dict[str, Callable[[bytes], None]] = {}
        #: Called once per loop iteration with the simulated time (real-time mode reads
        #: its ground-station sockets here and passes what arrived to inject(); a
        #: rehearsal's station view updates and takes its commands here). Whoever sets it
        #: calls the hook that was there before (hooks chain, none replaces another).
        self.on_step: Callable[[float], None] | None = None
        # (next tick time, agent order, name): one heap instead of a scan per event
        self._ticks = [(a.next_tick_s(), self._order[a.name], a.name) for a in self.agents.values()]
        heapq.heapify(self._ticks)
        # Every camera with its agent, in agent order;
        # the earliest answer any of them has pending; and whether one was commanded or
        # answered since that was worked out (so that the loop does not ask every camera
        # at every event).
        self._cameras_list = [(a, c) for a in self.agents.values() for c in a.cameras.values()]
        self._cameras_s = math.inf
        self._cameras_changed = True
        # The loop's position: physics steps done, the next track sample, the time being
        # processed.
        self._physics_steps = 0
        self._sitl_pace: SitlPace | None = None  # SITL runs: slows SITL when the run is late
        self._next_sample_s = 0.0
        self._t = -math.inf

    @property
    def station(self) -> SimAgent | None:
        """The station agent the operator acts through: the mission's first non-vehicle.

        None when the mission has none.
        """
        return self._station

    def command_station(self, command: StationCommand, t_s: float) -> bool:
        """An operator's command to the fleet through the station, as the script's go.

        For a person at a rehearsal's station view: the command is delivered to the
        station's runtime at ``t_s`` (the time of the loop's current step, from
        :attr:`on_step`) and what the runtime answers is carried out, exactly as the
        mission's operator actions are (ClarkLink messages on the simulated radio,
        authenticated when the mission has a key).

        Returns:
            False when nothing was delivered: the station was killed by a fault or has
            terminated (its interfaces are closed).

        Raises:
            RuntimeError: The mission has no station.
        """
        station = self._station
        if station is None:
            raise RuntimeError("the mission has no station agent in this run")
        if not station.alive or station.closed:
            return False
        self._route(station, station.runtime.deliver(command, t_s), t_s)
        return True

    # -- setup ---------------------------------------------------------------------------

    def _build_vehicle(self, sim_agent: SimAgent, agent: Agent) -> None:
        """The vehicle's autopilot and physics (simulated, or SITL), its pilot, its adapter."""
        if self.sitl is not None:
            backend, pilot, plan = build_sitl_vehicle(
                self.mission, agent, sim_agent.config, self.sitl, self.sitl_speedup, self.seed
            )
            sim_agent.backend, sim_agent.pilot = backend, pilot
            if plan is not None:
                self._preflights[sim_agent.name] = plan
        else:
            sim_agent.backend, sim_agent.pilot = build_vehicle(
                self.mission, agent, sim_agent.config, self.seed, wall_clock=self.wall_clock
            )
        sim_agent.adapter = AutopilotAdapter(
            AutopilotSettings.from_config(sim_agent.config), logger=sim_agent.logbook.interface
        )
        self.recording.tracks[sim_agent.name] = Track()
        self.recording.flight[sim_agent.name] = []
        if self.sitl is None:
            self._to_autopilot(sim_agent, sim_agent.adapter.start(0.0), 0.0)

    def _open_sitl(self) -> None:
        """Connect every SITL vehicle; fly up those handed over in flight first.

        A vehicle flown up before the run has its own clock well past 0 when the run
        starts; one on the ground is connected (its clock starts) just before it.
        Planes are flown up last: a copter waits on its position, hovering, for the
        others; a plane handed over as it crosses its position is on it at time 0 only
        if the run starts at once (with several planes, the earlier ones circle their
        positions meanwhile).
        """
        planes_last = sorted(
            self._preflights.items(),
            key=lambda item: getattr(self.agents[item[0]].backend, "firmware", "") == "arduplane",
        )
        for sim_agent in self._vehicles:
            if isinstance(sim_agent.backend, SitlBackend):
                sim_agent.backend.want_reports({via for _, via, _ in sim_agent.signal_keys})
        flown: list[SitlBackend] = []
        for name, plan in planes_last:
            backend = self.agents[name].backend
            assert isinstance(backend, SitlBackend)
            started = time.perf_counter()
            backend.connect()
            backend.fly_up(**plan, meanwhile=functools.partial(_drain, tuple(flown)))
            flown.append(backend)
            self.preflight_wall_s[name] = time.perf_counter() - started
        backends: list[SitlBackend] = []
        for sim_agent in self._vehicles:
            backend = sim_agent.backend
            assert isinstance(backend, SitlBackend)
            backends.append(backend)
            if sim_agent.name not in self._preflights:
                backend.connect()
        # Time 0 on every SITL clock at once: a vehicle connected (or flown up) first
        # would otherwise be ahead of the run, by its share of the connections' wall time.
        for backend in backends:
            backend.start_run_here()
        self._sitl_pace = SitlPace(backends, self.sitl_speedup)
        # The last plane is on its position at time 0 unless the machine held the engine
        # back meanwhile while SITL flew on: then it goes round again (the others wait).
        if flown:
            last, last_name = flown[-1], planes_last[-1][0]
            for _ in range(PLANE_HANDOVER_TRIES):
                miss_m = last.handover_miss_m()
                if miss_m is None or miss_m <= PLANE_HANDOVER_M:
                    break
                self.handover_again.setdefault(last_name, []).append(miss_m)
                last.hand_over_again(meanwhile=functools.partial(_drain, tuple(flown[:-1])))
                for backend in backends:
                    backend.start_run_here()
        for sim_agent in self._vehicles:
            assert sim_agent.adapter is not None
            self._to_autopilot(sim_agent, sim_agent.adapter.start(0.0), 0.0)

    def _settle_sitl(self) -> None:
        """At the run's end: the last ticks' signals from SITL's reports, and the pace kept."""
        for sim_agent in self._vehicles:
            backend = sim_agent.backend
            if isinstance(backend, SitlBackend):
                self._take_reports(sim_agent, settle=True)
                self.recording.pace[sim_agent.name] = backend.pace

    def close(self) -> None:
        """Stop what the run started outside this process (SITL); safe to call twice."""
        for sim_agent in self._vehicles:
            if sim_agent.backend is not None:
                sim_agent.backend.close()

    def _signal_channels(self) -> None:
        """The control channels each agent's doublets and sweeps drive, to record."""
        for sim_agent in self.agents.values():
            machine = sim_agent.config.machine
            if machine is None:
                continue
            seen: set[str] = set()
            declared = behaviors()
            for state in machine.walk():
                behavior = declared.get(state.primitive) if state.primitive is not None else None
                driven = behavior.driven_channel(state.params) if behavior is not None else None
                if driven is None or driven.number is None:
                    continue
                label = driven.label
                if label not in seen:
                    seen.add(label)
                    sim_agent.signal_keys.append((label, driven.via, driven.number))
                    self.recording.signals[(sim_agent.name, label)] = []

    def _state_listener(self, name: str) -> Callable[[StateChange], None]:
        def record(change: StateChange) -> None:
            self.recording.states[name].append(
                StateEntry(change.time_s, change.event, tuple(change.active), tuple(change.entered))
            )

        return record

    # -- the loop ------------------------------------------------------------------------

    def run(self) -> DryRunResult:
        """Simulate until ``until_s``; returns what was recorded."""
        self._wall_start = time.perf_counter()
        self._next_progress_wall = self._wall_start + 1.0
        try:
            if self.sitl is not None:
                self._open_sitl()
                self._wall_start = time.perf_counter()  # the run, not the pre-flights
            if self.wall_clock:
                # The simulated autopilots' GPS time is the wall clock's: the stations'
                # (no autopilot) is anchored to it, time 0 being now. One time base.
                epoch_ms = gps_time_ms_from_unix_us(time.time_ns() // 1000)
                for sim_agent in self.agents.values():
                    sim_agent.runtime.anchor_gps_time(epoch_ms)
            self._advance()
            if self.sitl is not None:
                self._settle_sitl()
        finally:  # the logs so far are complete rows, even when the run failed
            for sim_agent in self.agents.values():
                sim_agent.logbook.close()
            self.close()
        self.recording.end_s = min(self._t, self.until_s)
        for name, sim_agent in self.agents.items():
            if not sim_agent.runtime.behavior_started:
                self.recording.waiting[name] = sim_agent.runtime.launch.waiting_for
        return DryRunResult(
            self.recording,
            {name: a.config for name, a in self.agents.items()},
            self.agents,
            self.radio,
            time.perf_counter() - self._wall_start,
            ticks={name: a.ticks for name, a in self.agents.items()},
        )

    def _advance(self) -> None:
        """Process every event up to ``until_s``.

        ``until_s`` is read at every event: a real-time run's Ctrl-C lowers it.
        """
        while True:
            # The next event: the earliest of the physics step, the next tick, radio
            # arrival, camera answer, operator action and kill.
            physics_s = self._physics_steps * PHYSICS_STEP_S
            t = physics_s
            while self._ticks and not self._ticking_agent(self._ticks[0][2]):
                heapq.heappop(self._ticks)
            if self._ticks and self._ticks[0][0] < t:
                t = self._ticks[0][0]
            radio_s = self.radio.next_event_s()
            if radio_s is not None and radio_s < t:
                t = radio_s
            if self._cameras_changed:
                self._cameras_changed = False
                self._cameras_s = min(
                    (s for _, c in self._cameras_list if (s := c.next_event_s()) is not None),
                    default=math.inf,
                )
            if self._cameras_s < t:
                t = self._cameras_s
            if self._operator and self._operator[0][0] < t:
                t = self._operator[0][0]
            if self._kills and self._kills[0][0] < t:
                t = self._kills[0][0]
            if t > self.until_s + 1e-9:
                break
            self._t = t
            if self.speed is not None:
                self._pace(t)
            if t == physics_s:
                self._physics(t)
                self._physics_steps += 1
                if t >= self._next_sample_s - 1e-9:
                    self._sample(t)
                    self._next_sample_s += SAMPLE_PERIOD_S
            self._radio(t)
            if self._cameras_s <= t or self._cameras_changed:  # else none has an answer due
                self._cameras(t)
            self._scenario(t)
            while self._ticks and self._ticks[0][0] <= t:
                _, order, name = heapq.heappop(self._ticks)
                sim_agent = self.agents[name]
                if not self._ticking_agent(name):
                    continue
                self._tick(sim_agent, t)
                heapq.heappush(self._ticks, (sim_agent.next_tick_s(), order, name))
            if self.on_step is not None:
                self.on_step(t)
            if self.progress is not None and time.perf_counter() >= self._next_progress_wall:
                self.progress(t, self.until_s)
                self._next_progress_wall = time.perf_counter() + 1.0

    def _pace(self, t_s: float) -> None:
        assert self.speed is not None
        due = self._wall_start + t_s / self.speed
        delay = due - time.perf_counter()
        if delay > 0:
            time.sleep(delay)

    def _ticking_agent(self, name: str) -> bool:
        agent = self.agents[name]
        return agent.alive and not agent.closed

    def _physics(self, t_s: float) -> None:
        # Every vehicle steps first, so that any packet sent at this time sees every
        # vehicle where this step put it; then each agent hears its autopilot.
        heard: list[tuple[SimAgent, bytes]] = []
        dt_s = PHYSICS_STEP_S if t_s > 0 else 0.0
        for sim_agent in self._vehicles:
            assert sim_agent.backend is not None
            data = sim_agent.backend.step(t_s, dt_s)
            if data:  # else nothing due: the usual case between streamed messages
                heard.append((sim_agent, data))
        if self._sitl_pace is not None:
            self._sitl_pace.after_step(t_s)
        if self._ranged:
            here: dict[str, Position] = {}
            for sim_agent in self._vehicles:
                truth = sim_agent.backend.truth()  # type: ignore[union-attr]
                here[sim_agent.name] = (truth.north_m, truth.east_m, truth.up_m)
            self._positions.update(here)
        for sim_agent, data in heard:
            tap = self.autopilot_taps.get(sim_agent.name)
            if tap is not None:
                tap(data)
            pilot = sim_agent.pilot
            if pilot is not None and not pilot.done:
                if isinstance(sim_agent.backend, SitlBackend):
                    pilot.hear_messages(sim_agent.backend.heard, t_s)
                else:
                    pilot.hear(data, t_s)
            if sim_agent.adapter is None or not sim_agent.alive or sim_agent.closed:
                continue
            if not sim_agent.link_up(t_s):
                continue
            for event in sim_agent.adapter.receive(data, t_s):
                out = sim_agent.runtime.deliver(event, t_s)  # type: ignore[arg-type]
                if out:
                    self._route(sim_agent, out, t_s)
            self._to_autopilot(sim_agent, sim_agent.adapter.flush(), t_s)

    def _sample(self, t_s: float) -> None:
        flight = self.recording.flight
        for name, track in self.recording.tracks.items():
            backend = self.agents[name].backend
            assert backend is not None
            truth = backend.truth()
            track.add(
                t_s,
                truth.north_m,
                truth.east_m,
                truth.up_m,
                truth.roll_deg,
                truth.pitch_deg,
                truth.yaw_deg,
            )
            armed, mode = backend.flight_status()
            changes = flight[name]
            if not changes or changes[-1].armed != armed or changes[-1].mode != mode:
                changes.append(FlightEntry(t_s, armed, mode))

    def _radio(self, t_s: float) -> None:
        event: PacketReceived | None = None
        for delivery in self.radio.deliveries_until(t_s):
            receiver = self.agents[delivery.receiver]
            if not receiver.alive or receiver.closed:
                continue
            if event is None or event.data is not delivery.packet:
                # One (immutable) event for every receiver of the same broadcast.
                event = PacketReceived(delivery.packet)
            out = receiver.runtime.deliver(event, t_s)
            if out:
                self._route(receiver, out, t_s)

    def _cameras(self, t_s: float) -> None:
        self._cameras_changed = True  # answers are taken (and answering may command others)
        for sim_agent, camera in self._cameras_list:
            for _at_s, event in camera.events_until(t_s):
                if event.kind == "captured" and sim_agent.backend is not None:
                    truth = sim_agent.backend.truth()
                    self.recording.photos.setdefault(sim_agent.name, []).append(
                        Photo(t_s, truth.north_m, truth.east_m, truth.up_m)
                    )
                if sim_agent.alive and not sim_agent.closed:
                    self._route(sim_agent, sim_agent.runtime.deliver(event, t_s), t_s)

    def _scenario(self, t_s: float) -> None:
        while self._kills and self._kills[0][0] <= t_s:
            _, name = self._kills.pop(0)
            sim_agent = self.agents[name]
            sim_agent.alive = False
            self.recording.killed[name] = t_s
            sim_agent.logbook.mission.error(
                "killed by the dry run's fault at %.2f s", t_s, extra=LogEvent.SIM_FAULT.extra
            )
            self._silence(name, t_s)
        while self._operator and self._operator[0][0] <= t_s:
            _, _, item = self._operator.pop(0)
            self._operate(item, t_s)

    def _operate(self, item: Mapping[str, Any], t_s: float) -> None:
        if "rc" in item:
            body = item["rc"]
            backend = self.agents[str(body["agent"])].backend
            if backend is not None:
                backend.set_pilot({int(body["channel"]): int(body["pwm_us"])})
            return
        station = self._station
        if station is None or not station.alive or station.closed:
            return
        for action in ("activate", "deactivate", "terminate"):
            if action in item:
                target = "" if item[action] == "all" else str(item[action])
                command = StationCommand(action, target)
                self._route(station, station.runtime.deliver(command, t_s), t_s)
        if "mode" in item:
            body = item["mode"]
            command = StationCommand("mode", str(body["agent"]), str(body["mode"]))
            self._route(station, station.runtime.deliver(command, t_s), t_s)

    def _tick(self, sim_agent: SimAgent, t_s: float) -> None:
        if self.sitl is None:
            self._record_signals(sim_agent)
        elif sim_agent.signal_later:
            if isinstance(sim_agent.backend, SitlBackend):
                sim_agent.backend.wait_shown()
            self._take_reports(sim_agent)
        out = sim_agent.runtime.tick(t_s)
        sim_agent.ticks += 1
        self._route(sim_agent, out, t_s)
        if sim_agent.adapter is not None and not sim_agent.closed:
            self._to_autopilot(sim_agent, sim_agent.adapter.poll(t_s), t_s)
        runtime = sim_agent.runtime
        if runtime.failsafe is not None and not sim_agent.failsafe_seen:
            sim_agent.failsafe_seen = True
            self.recording.safety.setdefault(sim_agent.name, []).append(
                (t_s, f"failsafe {runtime.failsafe}")
            )
        if runtime.autopilot_lost and not sim_agent.autopilot_lost_seen:
            sim_agent.autopilot_lost_seen = True
            self.recording.safety.setdefault(sim_agent.name, []).append((t_s, "autopilot_lost"))
        if sim_agent.signal_keys:
            if self.sitl is None:
                sim_agent.signal_due_s = t_s
            else:
                self._report_later(sim_agent, out, t_s)

    def _record_signals(self, sim_agent: SimAgent) -> None:
        """What the autopilot received from the previous tick, recorded at that tick's time.

        Read just before the next tick commands anything: the simulated autopilot takes
        a command at once. RC inputs and servo outputs are each read only if a recorded
        signal is on them. (ArduPilot SITL reports a command later:
        :meth:`_report_later`.)
        """
        backend, t_s = sim_agent.backend, sim_agent.signal_due_s
        if backend is None or t_s is None:
            return
        sim_agent.signal_due_s = None
        inputs: tuple[int, ...] | None = None
        outputs: tuple[int, ...] | None = None
        for label, via, number in sim_agent.signal_keys:
            if via == "rc_override":
                values = inputs = backend.rc_inputs() if inputs is None else inputs
            else:
                values = outputs = backend.servo_outputs() if outputs is None else outputs
            pwm = values[number - 1] if number - 1 < len(values) else 0
            self.recording.signals[(sim_agent.name, label)].append((t_s, int(pwm)))

    def _report_later(self, sim_agent: SimAgent, out: Sequence[Command], t_s: float) -> None:
        """On SITL: what the autopilot receives from this tick, read from a later report.

        ArduPlane shows an RC override in its RC_CHANNELS 40-100 ms after it was sent, and
        SITL cannot be paused: the run used to wait for a report after every tick of a
        doublet or sweep, fell 0.15 s further behind SITL at each (56-289 s behind after
        supercub_sysid's excitation), and ArduPlane's GCS failsafe flew RTL in such runs. The
        reports are matched to the ticks as they stream in instead
        (:meth:`~clark_engine.dryrun.sitl_backend.SitlBackend.report_later`), at every tick
        as in a simulated run, and recorded in order once known (:meth:`_take_reports`).
        """
        backend = sim_agent.backend
        if not isinstance(backend, SitlBackend):
            return
        for command in out:
            if isinstance(command, SetServo):
                sim_agent.servo_asked_us[command.servo] = command.pwm_us
        adapter = sim_agent.adapter
        overrides = adapter.active_overrides if adapter is not None else {}
        for label, via, number in sim_agent.signal_keys:
            asked = overrides if via == "rc_override" else sim_agent.servo_asked_us
            want = asked.get(number)
            sim_agent.signal_later.append((label, t_s, backend.report_later(via, number, want)))

    def _take_reports(self, sim_agent: SimAgent, *, settle: bool = False) -> None:
        """Record the ticks' reports SITL has made, in tick order; all of them when ``settle``."""
        later = sim_agent.signal_later
        if settle and later and isinstance(sim_agent.backend, SitlBackend):
            sim_agent.backend.settle_reports()
        done = 0
        for label, t_s, report in later:
            if report.pwm_us is None:
                break
            self.recording.signals[(sim_agent.name, label)].append((t_s, report.pwm_us))
            done += 1
        del later[:done]

    def _route(self, sim_agent: SimAgent, commands: Sequence[Command], t_s: float) -> None:
        """Carry out an agent's commands through :data:`_ROUTES`, one per command type.

        Raises:
            UnknownCommandError: A command type the dry run has no route for (an engine
                bug: the real-time shell would carry it out, so it is never dropped here).
        """
        for command in commands:
            route = _ROUTES.get(type(command))
            if route is None:
                raise unknown_command(command, "the dry run")
            route(self, sim_agent, command, t_s)

    def _route_autopilot(self, sim_agent: SimAgent, command: Any, t_s: float) -> None:
        """To the agent's autopilot, through its adapter (none: a station)."""
        if sim_agent.adapter is not None:
            self._to_autopilot(sim_agent, sim_agent.adapter.command(command, t_s), t_s)

    def _route_packet(self, sim_agent: SimAgent, command: Any, t_s: float) -> None:
        """Onto the simulated radio mesh (an agent without a radio sends nothing)."""
        if sim_agent.name not in self.radio.agents:
            return
        # Positions only matter to radios with a range.
        positions = self._positions if self._ranged else None
        self.radio.send(sim_agent.name, command.data, command.destination, t_s, positions)

    def _route_payload(self, sim_agent: SimAgent, command: Any, t_s: float) -> None:
        """To the simulated camera it names (a payload the agent lacks does nothing)."""
        camera = sim_agent.cameras.get(command.payload)
        if camera is not None:
            camera.command(command, t_s)
            self._cameras_changed = True

    def _route_close(self, sim_agent: SimAgent, command: Any, t_s: float) -> None:
        """Terminate: close the agent's autopilot link and silence its radio."""
        sim_agent.closed = True
        if sim_agent.adapter is not None:
            self._to_autopilot(sim_agent, sim_agent.adapter.close(t_s), t_s)
        if sim_agent.name in self.radio.agents:
            self._silence(sim_agent.name, t_s)

    def _silence(self, name: str, t_s: float) -> None:
        """Silence an agent's radio from ``t_s`` on."""
        if name in self.radio.agents:
            self.radio.silence(name, t_s)

    def inject(self, agent: str, data: bytes, t_s: float) -> None:
        """Bytes from an outside ground station to an agent's simulated autopilot."""
        backend = self.agents[agent].backend
        if backend is not None and data:
            backend.send(data, t_s)

    def _to_autopilot(self, sim_agent: SimAgent, data: bytes, t_s: float) -> None:
        if data and sim_agent.backend is not None and sim_agent.link_up(t_s):
            sim_agent.backend.send(data, t_s)


#: The dry run's dispatch: command type -> how it is carried out. Checked against every
#: command type when this module loads, so none can be added without a route here.
_ROUTES: dict[type, Callable[[DryRun, SimAgent, Any, float], None]] = {
    **dict.fromkeys(AUTOPILOT_COMMANDS, DryRun._route_autopilot),
    SendPacket: DryRun._route_packet,
    PayloadCommand: DryRun._route_payload,
    CloseInterfaces: DryRun._route_close,
}
check_dispatch(_ROUTES, "the dry run")


def _drain(backends: Sequence[SitlBackend]) -> None:
    """Keep SITL vehicles already flown up current while another is (their clock, truth)."""
    for backend in backends:
        backend.drain()
