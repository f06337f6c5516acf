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
at the same time are processed in a fixed order: physics and autopilot
telemetry, radio deliveries, camera answers, scenario, then agent ticks in the
mission's agent order.
"""

from __future__ import annotations

import heapq
import math
import random
import time
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from clark_engine.io.autopilot import AutopilotAdapter, AutopilotSettings, gps_time_ms_from_unix_us
from clark_engine.link.auth import load_key
from clark_engine.mission.compiler import agent_config
from clark_engine.mission.geo import parse_point
from clark_engine.mission.model import Mission
from clark_engine.runtime.commands import (
    CloseInterfaces,
    Command,
    Goto,
    PayloadCommand,
    RcOverride,
    SendPacket,
    SetMode,
    SetServo,
)
from clark_engine.runtime.config import AgentConfig, config_from_dict
from clark_engine.runtime.events import PacketReceived, StationCommand
from clark_engine.runtime.logbook import Logbook
from clark_engine.runtime.machine import StateChange
from clark_engine.runtime.runtime import AgentRuntime
from clark_engine.sim.autopilot import SimAutopilot
from clark_engine.sim.camera import SimCamera
from clark_engine.sim.model import VehicleModel
from clark_engine.sim.radio import RadioMesh
from clark_engine.sim.recording import Photo, Recording, StateEntry, Track
from clark_engine.sim.vehicles import make_vehicle

#: Vehicle physics and autopilot telemetry step.
PHYSICS_STEP_S = 0.02
#: Tracks are sampled this often (plots, distance and separation checks).
SAMPLE_PERIOD_S = 0.1
#: The simulated GPS time at t = 0: 2026-01-01 00:00:00 UTC, fixed for reproducible logs.
START_UNIX_US = 1_767_225_600_000_000
#: Aircraft starting with no height start at this height (take-offs are not simulated).
DEFAULT_START_UP_M = 40.0

_AUTOPILOT_COMMANDS = (Goto, SetMode, SetServo, RcOverride)


@dataclass(slots=True)
class Window:
    """A time window [from_s, to_s)."""

    from_s: float
    to_s: float

    def covers(self, t_s: float) -> bool:
        """True when ``t_s`` is inside the window."""
        return self.from_s <= t_s < self.to_s


@dataclass(slots=True)
class SimAgent:
    """One agent's pieces in the simulation."""

    name: str
    config: AgentConfig
    runtime: AgentRuntime
    logbook: Logbook
    tick_offset_s: float
    model: VehicleModel | None = None
    autopilot: SimAutopilot | None = None
    adapter: AutopilotAdapter | None = None
    cameras: dict[str, SimCamera] = field(default_factory=dict)
    alive: bool = True
    closed: bool = False
    ticks: int = 0
    autopilot_down: list[Window] = field(default_factory=list)
    signal_keys: list[tuple[str, str, int]] = field(default_factory=list)  # (label, via, number)
    failsafe_seen: bool = False
    autopilot_lost_seen: bool = False

    def next_tick_s(self) -> float:
        """When this agent ticks next."""
        return self.tick_offset_s + self.ticks / self.config.loop_hz

    def link_up(self, t_s: float) -> bool:
        """True when its autopilot link is not disconnected by a fault."""
        return not any(w.covers(t_s) for w in self.autopilot_down)


@dataclass(slots=True)
class DryRunResult:
    """What a dry run produced."""

    recording: Recording
    configs: dict[str, AgentConfig]
    agents: dict[str, SimAgent]
    radio: RadioMesh
    wall_s: float


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
    ) -> None:
        self.mission = mission
        self.seed = seed
        self.until_s = until_s
        self.progress = progress
        self.speed = speed
        self.recording = Recording()
        sim = mission.sim
        self.radio = RadioMesh(
            random.Random(f"{seed}:radio"),
            latency_s=float(sim.get("radio_latency_s", 0.005)),
            loss_rate=float(sim.get("radio_loss", 0.0)),
        )
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
            offset = random.Random(f"{seed}:phase:{name}").random() / config.loop_hz
            sim_agent = SimAgent(name, config, runtime, logbook, offset)
            self.agents[name] = sim_agent
            runtime.state_listeners.append(self._state_listener(name))
            self.recording.states[name] = []
            radio = agent.hardware.part("radio")
            if radio is not None:
                self.radio.add_agent(name, agent.id, radio)
            for payload, profile in agent.hardware.payloads.items():
                if profile.get("payload_kind") == "camera":
                    sim_agent.cameras[payload] = SimCamera(
                        payload, profile, random.Random(f"{seed}:camera:{name}:{payload}")
                    )
            if agent.is_vehicle:
                self._build_vehicle(sim_agent, agent.raw, agent.hardware.parts, sim)
        self._apply_faults([*mission.faults, *extra_faults])
        self._operator = sorted(
            (float(item["at_s"]), index, item) for index, item in enumerate(mission.operator)
        )
        self._signal_channels()
        self._position_cache: dict[str, tuple[float, float, float]] | None = None
        #: Agent -> called with every byte string its simulated autopilot emits (real-time
        #: mode forwards them to a ground station over UDP).
        self.autopilot_taps: dict[str, Callable[[bytes], None]] = {}
        #: Called once per loop iteration with the simulated time (real-time mode reads
        #: its ground-station sockets here and passes what arrived to inject()).
        self.on_step: Callable[[float], None] | None = None
        # (next tick time, agent order, name): one heap instead of a scan per event
        self._order = {name: i for i, name in enumerate(self.agents)}
        self._ticks = [(a.next_tick_s(), self._order[a.name], a.name) for a in self.agents.values()]
        heapq.heapify(self._ticks)
        # Every camera with its agent, in agent order; the earliest answer any of them has
        # pending; and whether one was commanded or answered since that was worked out
        # (so that the loop does not ask every camera at every event).
        self._cameras_list = [(a, c) for a in self.agents.values() for c in a.cameras.values()]
        self._cameras_s = math.inf
        self._cameras_changed = True

    # -- setup ---------------------------------------------------------------------------

    def _build_vehicle(
        self,
        sim_agent: SimAgent,
        raw: Mapping[str, Any],
        parts: Mapping[str, Mapping[str, Any]],
        sim: Mapping[str, Any],
    ) -> None:
        mission = self.mission
        start = parse_point(raw["position"], mission.origin) if "position" in raw else None
        north, east, up = (start.north_m, start.east_m, start.up_m) if start else (0.0, 0.0, 0.0)
        airframe, autopilot = parts["airframe"], parts["autopilot"]
        setup = raw.get("sim") or {}
        if airframe.get("class") != "rover" and up <= 0:
            up = DEFAULT_START_UP_M
        model = make_vehicle(
            airframe,
            autopilot,
            sim_agent.config.channels,
            mission.origin,
            (north, east, up),
            random.Random(f"{self.seed}:vehicle:{sim_agent.name}"),
            gps_noise_m=float(sim.get("gps_noise_m", 0.5)),
            heading_deg=float(setup.get("heading_deg", 0.0)),
            armed=bool(setup.get("armed", True)),
            mode=setup.get("mode"),
            rc_override_timeout_s=None,  # the simulated autopilot's RC_OVERRIDE_TIME applies
        )
        sim_agent.model = model
        sim_agent.autopilot = SimAutopilot.from_profile(
            model,
            autopilot,
            home_lat_deg=mission.origin.lat_deg,
            home_lon_deg=mission.origin.lon_deg,
            home_alt_m=mission.origin.alt_m,
            start_time_unix_us=START_UNIX_US,
        )
        sim_agent.adapter = AutopilotAdapter(
            AutopilotSettings.from_config(sim_agent.config), logger=sim_agent.logbook.interface
        )
        self.recording.tracks[sim_agent.name] = Track()
        self._to_autopilot(sim_agent, sim_agent.adapter.start(0.0), 0.0)

    def _apply_faults(self, faults: Sequence[Mapping[str, Any]]) -> None:
        self._kills: list[tuple[float, str]] = []
        for fault in faults:
            ((kind, body),) = fault.items()
            start, end = float(body.get("from_s", 0.0)), float(body.get("to_s", math.inf))
            if kind == "kill":
                self._kills.append((float(body["at_s"]), str(body["agent"])))
            elif kind == "link_drop":
                a, b = (str(n) for n in body["between"])
                self.radio.drop_link(a, b, start, end)
            elif kind == "station_silent":
                for agent in self.mission.stations:
                    self.radio.silence(agent.name, start, end)
            elif kind == "autopilot_disconnect":
                self.agents[str(body["agent"])].autopilot_down.append(Window(start, end))
            elif kind == "corrupt":
                self.radio.corrupt(float(body["share"]), start, end)
        self._kills.sort()

    def _signal_channels(self) -> None:
        """The control channels each agent's doublets and sweeps drive, to record."""
        for sim_agent in self.agents.values():
            machine = sim_agent.config.machine
            if machine is None:
                continue
            seen: set[str] = set()
            for state in machine.walk():
                if state.primitive not in ("doublet", "sine_sweep"):
                    continue
                channel = state.params["channel"]
                via = state.params.get("via", "rc_override")
                number = channel["rc"] if via == "rc_override" else channel["servo"]
                label = f"rc{number}" if via == "rc_override" else f"servo{number}"
                if label not in seen:
                    seen.add(label)
                    sim_agent.signal_keys.append((label, via, int(number)))
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
        wall_start = time.perf_counter()
        physics_steps = 0
        next_sample_s = 0.0
        next_progress_wall = wall_start + 1.0
        t = 0.0
        while True:
            # The next event: the earliest of the physics step, the next tick, radio
            # arrival, camera answer, operator action and kill.
            physics_s = physics_steps * PHYSICS_STEP_S
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
            if self.speed is not None:
                self._pace(wall_start, t)
            if abs(t - physics_s) < 1e-9:
                self._physics(t)
                physics_steps += 1
                if t >= next_sample_s - 1e-9:
                    self._sample(t)
                    next_sample_s += SAMPLE_PERIOD_S
            self._radio(t)
            if self._cameras_s <= t or self._cameras_changed:  # else none has an answer due
                self._cameras(t)
            self._scenario(t)
            while self._ticks and self._ticks[0][0] <= t + 1e-9:
                _, order, name = heapq.heappop(self._ticks)
                sim_agent = self.agents[name]
                if not self._ticking_agent(name):
                    continue
                self._tick(sim_agent, t)
                heapq.heappush(self._ticks, (sim_agent.next_tick_s(), order, name))
            if self.on_step is not None:
                self.on_step(t)
            if self.progress is not None and time.perf_counter() >= next_progress_wall:
                self.progress(t, self.until_s)
                next_progress_wall = time.perf_counter() + 1.0
        self.recording.end_s = min(t, self.until_s)
        for sim_agent in self.agents.values():
            sim_agent.logbook.close()
        return DryRunResult(
            self.recording,
            {name: a.config for name, a in self.agents.items()},
            self.agents,
            self.radio,
            time.perf_counter() - wall_start,
        )

    def _pace(self, wall_start: float, t_s: float) -> None:
        assert self.speed is not None
        due = wall_start + t_s / self.speed
        delay = due - time.perf_counter()
        if delay > 0:
            time.sleep(delay)

    def _ticking_agent(self, name: str) -> bool:
        agent = self.agents[name]
        return agent.alive and not agent.closed

    def _physics(self, t_s: float) -> None:
        self._position_cache = None
        for sim_agent in self.agents.values():
            if sim_agent.model is None or sim_agent.autopilot is None:
                continue
            if t_s > 0:
                sim_agent.model.step(PHYSICS_STEP_S)
            data = sim_agent.autopilot.advance(t_s)
            if not data:
                continue  # nothing due: the usual case between streamed messages
            tap = self.autopilot_taps.get(sim_agent.name)
            if tap is not None:
                tap(data)
            if sim_agent.adapter is None or not sim_agent.alive or sim_agent.closed:
                continue
            if not sim_agent.link_up(t_s):
                continue
            for event in sim_agent.adapter.receive(data, t_s):
                out = sim_agent.runtime.deliver(event, t_s)  # type: ignore[arg-type]
                if out:
                    self._route(sim_agent, out, t_s)

    def _sample(self, t_s: float) -> None:
        for name, track in self.recording.tracks.items():
            model = self.agents[name].model
            assert model is not None
            truth = model.truth()
            track.add(
                t_s,
                truth.north_m,
                truth.east_m,
                truth.up_m,
                truth.roll_deg,
                truth.pitch_deg,
                truth.yaw_deg,
            )

    def _positions(self) -> dict[str, tuple[float, float, float]]:
        """Every agent's position, as of the last physics step (cached until the next)."""
        if self._position_cache is not None:
            return self._position_cache
        positions: dict[str, tuple[float, float, float]] = {}
        for name, sim_agent in self.agents.items():
            if sim_agent.model is not None:
                truth = sim_agent.model.truth()
                positions[name] = (truth.north_m, truth.east_m, truth.up_m)
            else:
                agent = self.mission.agents[name]
                positions[name] = (
                    agent.position.north_m,
                    agent.position.east_m,
                    agent.position.up_m,
                )
        return positions

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
                if event.kind == "captured" and sim_agent.model is not None:
                    truth = sim_agent.model.truth()
                    self.recording.photos.setdefault(sim_agent.name, []).append(
                        Photo(t_s, truth.north_m, truth.east_m, truth.up_m)
                    )
                if sim_agent.alive and not sim_agent.closed:
                    self._route(sim_agent, sim_agent.runtime.deliver(event, t_s), t_s)

    def _scenario(self, t_s: float) -> None:
        while self._kills and self._kills[0][0] <= t_s + 1e-9:
            _, name = self._kills.pop(0)
            sim_agent = self.agents[name]
            sim_agent.alive = False
            sim_agent.logbook.mission.error("killed by the dry run's fault at %.2f s", t_s)
            self.radio.silence(name, t_s)
        while self._operator and self._operator[0][0] <= t_s + 1e-9:
            _, _, item = self._operator.pop(0)
            self._operate(item, t_s)

    def _operate(self, item: Mapping[str, Any], t_s: float) -> None:
        if "rc" in item:
            body = item["rc"]
            model = self.agents[str(body["agent"])].model
            if model is not None:
                model.set_pilot({int(body["channel"]): int(body["pwm_us"])})
            return
        stations = [a for a in self.agents.values() if not a.config.is_vehicle]
        if not stations:
            return
        station = stations[0]
        if not station.alive or station.closed:
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
        model = sim_agent.model
        if model is not None and sim_agent.signal_keys:
            # RC inputs and servo outputs, each read only if a recorded signal is on it.
            inputs: tuple[int, ...] | None = None
            outputs: tuple[int, ...] | None = None
            for label, via, number in sim_agent.signal_keys:
                if via == "rc_override":
                    values = inputs = model.rc_inputs() if inputs is None else inputs
                else:
                    values = outputs = model.servo_outputs() if outputs is None else outputs
                pwm = values[number - 1] if number - 1 < len(values) else 0
                self.recording.signals[(sim_agent.name, label)].append((t_s, int(pwm)))

    def _route(self, sim_agent: SimAgent, commands: Sequence[Command], t_s: float) -> None:
        for command in commands:
            if isinstance(command, _AUTOPILOT_COMMANDS):
                if sim_agent.adapter is not None:
                    self._to_autopilot(sim_agent, sim_agent.adapter.command(command, t_s), t_s)
            elif isinstance(command, SendPacket):
                if sim_agent.name in self.radio.agents:
                    # Positions only matter to radios with a range: skip measuring them else.
                    positions = self._positions() if self.radio.uses_positions else None
                    self.radio.send(
                        sim_agent.name, command.data, command.destination, t_s, positions
                    )
            elif isinstance(command, PayloadCommand):
                camera = sim_agent.cameras.get(command.payload)
                if camera is not None:
                    camera.command(command, t_s)
                    self._cameras_changed = True
            elif isinstance(command, CloseInterfaces):
                sim_agent.closed = True
                if sim_agent.adapter is not None:
                    self._to_autopilot(sim_agent, sim_agent.adapter.close(t_s), t_s)
                if sim_agent.name in self.radio.agents:
                    self.radio.silence(sim_agent.name, t_s)

    def inject(self, agent: str, data: bytes, t_s: float) -> None:
        """Bytes from an outside ground station to an agent's simulated autopilot."""
        autopilot = self.agents[agent].autopilot
        if autopilot is not None and data:
            autopilot.receive(data, t_s)

    def _to_autopilot(self, sim_agent: SimAgent, data: bytes, t_s: float) -> None:
        if data and sim_agent.autopilot is not None and sim_agent.link_up(t_s):
            sim_agent.autopilot.receive(data, t_s)
