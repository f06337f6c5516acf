"""One vehicle's autopilot served alone, for ``clark run`` to fly: ``clark autopilot-sim``.

A rehearsal on the bench runs the engine as it flies (``clark run``, one process
per agent) against autopilots that are not in the air. ``clark dry-run
--realtime`` serves autopilots too, but it also flies its own copy of every agent,
which then shares each autopilot with ``clark run``. This module serves one
vehicle's autopilot and nothing else, with the vehicle's safety pilot, as the
bench has it:

- :class:`ServedSimulated`: the dry run's simulated autopilot and physics
  (:func:`~clark_engine.dryrun.world.build_vehicle`), stepped at wall-clock pace,
  its SYSTEM_TIME from the wall clock, on a UDP port that answers whoever sends
  to it (``clark run --autopilot-connection udpout:HOST:PORT``), as
  :mod:`clark_engine.dryrun.rehearsal` serves a dry run's vehicles.
- :class:`ServedSitl`: real ArduPilot SITL at real time
  (:func:`~clark_engine.dryrun.world.build_sitl_vehicle`: booted at the agent's
  start, with the flight parameters the simulated autopilot has). The pilot and
  the parameter set-up speak on SITL's SERIAL0 and SERIAL2; ``clark run`` connects
  to SERIAL1 (``--autopilot-connection tcp:127.0.0.1:PORT``), as a mission
  computer on a flight controller's TELEM port.

The safety pilot is the dry run's :class:`~clark_engine.dryrun.pilot.SimPilot`: it
arms a vehicle the mission says the pilot arms once the autopilot says it is
ready, and centres a copter's throttle once it flies; a vehicle handed over in
flight is flown up first (SITL) or starts in the air (simulated). SITL is never
sped up here: its GPS time would run ahead of the wall clock, and the agents'
logs, tied together by GPS time, would disagree (``clark dry-run --autopilot
sitl`` is the fast way).

What the vehicle does is announced as lines for a person or a test to wait on
(``say``): where ``clark run`` connects, the autopilot ready, the vehicle armed.
"""

from __future__ import annotations

import contextlib
import select
import time
from collections.abc import Callable, Mapping
from dataclasses import replace
from typing import Any, Final

from pymavlink.dialects.v20 import ardupilotmega as mavlink2

from clark_engine.dryrun.backend import SimulatedBackend
from clark_engine.dryrun.engine import PHYSICS_STEP_S
from clark_engine.dryrun.pilot import SimPilot
from clark_engine.dryrun.rehearsal import StopFlag, datagrams
from clark_engine.dryrun.report import drawn_line
from clark_engine.dryrun.sitl_backend import SitlBackend
from clark_engine.dryrun.world import build_sitl_vehicle, build_vehicle
from clark_engine.errors import UsageError
from clark_engine.io.transports import TransportError, UdpTransport
from clark_engine.mission.compiler import agent_config
from clark_engine.mission.model import Mission
from clark_engine.mission.variation import resolve_mission
from clark_engine.runtime.config import config_from_dict
from clark_engine.sitl.errors import SitlError
from clark_engine.sitl.launcher import SitlInstall
from clark_engine.untrusted import printable

SITL_STEP_S: Final = 0.05
"""How far SITL's clock is let run between two looks at what its SERIAL0 sent."""

PILOT_STREAMS: Final = ("SYS_STATUS", "EKF_STATUS_REPORT", "GLOBAL_POSITION_INT", "SYSTEM_TIME")
"""What the pilot reads on SERIAL0 (EXTENDED_SYS_STATE too, for a copter): asked for at
1 Hz, since on SERIAL0 nobody else asks (in a dry run the engine's adapter does).
SYSTEM_TIME tells how far SITL's GPS clock is from this machine's."""

PILOT_STREAM_INTERVAL_US: Final = 1_000_000
STREAM_RETRY_S: Final = 1.0
"""Stream requests are sent again this often until the stream arrives (ArduPilot drops
those it gets before it is ready)."""

COMPUTER_SILENT_S: Final = 2.0
"""The mission computer's heartbeat (1 Hz) missing this long is announced."""

DEFAULT_LISTEN: Final = "127.0.0.1:14550"
"""Where the simulated autopilot listens unless ``--listen`` says otherwise."""

Say = Callable[[str], None]
Stopped = Callable[[], bool]


def _vehicle(mission: Mission, name: str) -> tuple[Any, Any]:
    agent = mission.agents[name]
    return agent, config_from_dict(agent_config(mission, agent))


class _Announcer:
    """Says what the autopilot does, as the bench sees it, each line with its time.

    Once each: the autopilot ready (as the pilot sees it), the vehicle armed. Every
    change of flight mode, and every text of notice severity or worse the autopilot
    sends (a failsafe, a fence breach, a refused arm). And the mission computer's
    heartbeat: when it is first heard, and when it has been silent for
    :data:`COMPUTER_SILENT_S` (with the time of the last one), which is what
    ArduPilot's ground-station failsafe counts from. ArduPilot forwards a ground
    station's HEARTBEAT to its other links (``MAVLink_routing::handle_heartbeat``), so
    on SITL the pilot's link hears ``clark run``'s; the simulated autopilot's port hears
    it directly. Times are the autopilot's (SITL's clock, or the simulation's).
    """

    def __init__(
        self, name: str, pilot: SimPilot, say: Say, modes: Mapping[str, int], system_id: int
    ) -> None:
        self._name = name
        self._pilot = pilot
        self._say = say
        self._ready_said = False
        self._armed_said = False
        self._mode_names = {int(number): mode for mode, number in modes.items()}
        self._system_id = system_id
        self._parser = mavlink2.MAVLink(None, 255, 25)
        self._parser.robust_parsing = True
        self._mode: int | None = None
        self._computer_s: float | None = None  # its last heartbeat
        self._computer_silent = False

    def hear(self, data: bytes, now_s: float) -> None:
        """Bytes from the autopilot, or from ``clark run`` to it, at ``now_s``."""
        if not data:
            return
        for msg in self._parser.parse_buffer(data) or []:
            kind = msg.get_type()
            if msg.get_srcSystem() != self._system_id:
                if kind == "HEARTBEAT" and msg.type == mavlink2.MAV_TYPE_GCS:
                    self._computer(msg, now_s)
            elif kind == "HEARTBEAT" and msg.autopilot == mavlink2.MAV_AUTOPILOT_ARDUPILOTMEGA:
                mode = int(msg.custom_mode)
                if mode != self._mode:
                    self._mode = mode
                    name = self._mode_names.get(mode, f"UNKNOWN_{mode}")
                    self._say(f"{self._name}: mode {name} at {now_s:.2f} s")
            elif kind == "STATUSTEXT" and msg.severity <= mavlink2.MAV_SEVERITY_NOTICE:
                text = printable(str(msg.text))
                self._say(f'{self._name}: autopilot says "{text}" at {now_s:.2f} s')

    def _computer(self, msg: Any, now_s: float) -> None:
        if self._computer_s is None or self._computer_silent:
            again = " again" if self._computer_silent else ""
            self._say(
                f"{self._name}: mission computer (system {msg.get_srcSystem()}) heard{again} "
                f"at {now_s:.2f} s"
            )
        self._computer_s = now_s
        self._computer_silent = False

    def __call__(self, now_s: float) -> None:
        if not self._ready_said and self._pilot.sees_ready:
            self._ready_said = True
            self._say(f"{self._name}: autopilot ready at {now_s:.1f} s")
        if not self._armed_said and self._pilot.armed_at_s is not None:
            self._armed_said = True
            who = "the pilot" if self._pilot.arms else "the engine"
            self._say(f"{self._name}: armed by {who} at {self._pilot.armed_at_s:.1f} s")
        last = self._computer_s
        if last is not None and not self._computer_silent and now_s - last > COMPUTER_SILENT_S:
            self._computer_silent = True
            self._say(f"{self._name}: no heartbeat from the mission computer since {last:.2f} s")


class ServedSimulated:
    """A simulated autopilot on a UDP port, stepped at wall-clock pace.

    Args:
        mission: The resolved mission.
        agent: The vehicle's name.
        host: The address to listen on.
        port: The UDP port (0: any free one; :attr:`connection` says which).
        ready_s: Instead of the firmware's boot timeline (about 42 s for ArduRover),
            ready this many seconds after power-on (``sim.autopilot_ready_s``).
        seed: Seeds the vehicle's GPS noise.
    """

    def __init__(
        self,
        mission: Mission,
        agent: str,
        *,
        host: str = "127.0.0.1",
        port: int = 0,
        ready_s: float | None = None,
        seed: int | None = None,
    ) -> None:
        if ready_s is not None:  # ready when asked: no jitter on top (sim.jitter.ready_s)
            jitter = {**mission.sim.get("jitter", {}), "ready_s": 0}
            mission = replace(
                mission, sim={**mission.sim, "autopilot_ready_s": ready_s, "jitter": jitter}
            )
        run_seed = int(mission.sim.get("seed", 0)) if seed is None else seed
        # The world the mission declares, drawn as its dry run with this seed draws it.
        mission, self.drawn = resolve_mission(mission, run_seed)
        self.seed = run_seed
        spec, config = _vehicle(mission, agent)
        self.name = agent
        self.backend: SimulatedBackend
        self.backend, self.pilot = build_vehicle(mission, spec, config, run_seed, wall_clock=True)
        self.transport = UdpTransport(bind=(host, port))
        self._modes = dict(config.modes)
        self._announce: _Announcer | None = None  # while serving

    @property
    def connection(self) -> str:
        """What ``clark run --autopilot-connection`` takes to reach it."""
        host, port = self.transport.address[:2]
        return f"udpout:{host}:{port}"

    def _emit(self, data: bytes, t_s: float) -> None:
        if not data:
            return
        if self._announce is not None:
            self._announce.hear(data, t_s)
        if not self.pilot.done:
            self.pilot.hear(data, t_s)
        if self.transport.peers:
            for datagram in datagrams(data):
                with contextlib.suppress(TransportError):  # UDP may drop; the engine asks again
                    self.transport.send(datagram)

    def serve(self, stopped: Stopped, say: Say = print) -> None:
        """Step the physics every PHYSICS_STEP_S of wall time until ``stopped()``."""
        announce = self._announce = _Announcer(
            self.name, self.pilot, say, self._modes, self.backend.system_id
        )
        start = time.monotonic()
        steps = 0
        self._emit(self.backend.step(0.0, 0.0), 0.0)
        fd = self.transport.fileno()
        while not stopped():
            if fd is not None:
                select.select([fd], [], [], PHYSICS_STEP_S / 4)
            t_s = time.monotonic() - start
            try:
                data = self.transport.receive()
            except TransportError:
                data = b""
            if data:
                announce.hear(data, t_s)
                self.backend.send(data, t_s)
            while (steps + 1) * PHYSICS_STEP_S <= t_s:
                steps += 1
                self._emit(self.backend.step(steps * PHYSICS_STEP_S, PHYSICS_STEP_S), t_s)
            announce(t_s)

    def close(self) -> None:
        """Close its port."""
        self.transport.close()


class ServedSitl:
    """Real ArduPilot SITL at real time; ``clark run`` on its SERIAL1, the pilot on SERIAL0.

    Starting it starts SITL (listening); :meth:`serve` connects it (its clock
    starts), flies a vehicle handed over in flight up to its position, then runs
    SITL's clock on, playing the pilot, until ``stopped()``.

    Args:
        mission: The resolved mission.
        agent: The vehicle's name.
        install: The SITL launcher.

    Raises:
        SitlError: SITL could not start.
    """

    def __init__(self, mission: Mission, agent: str, install: SitlInstall) -> None:
        self.seed = int(mission.sim.get("seed", 0))
        # The world the mission declares (SIM_WIND_*, the GPS error), drawn as its dry run
        # with the mission's seed draws it.
        mission, self.drawn = resolve_mission(mission, self.seed)
        spec, config = _vehicle(mission, agent)
        self.name = agent
        self.backend: SitlBackend
        self.backend, self.pilot, self._fly_up = build_sitl_vehicle(
            mission, spec, config, install, 1.0, seed=self.seed
        )
        self._modes = dict(config.modes)
        self._mav = mavlink2.MAVLink(self, srcSystem=255, srcComponent=25)
        self._out = bytearray()
        self._parser = mavlink2.MAVLink(None, 255, 25)
        self._parser.robust_parsing = True
        copter = spec.hardware.parts["airframe"].get("class") == "multirotor"
        self._streams = {*PILOT_STREAMS, *(("EXTENDED_SYS_STATE",) if copter else ())}
        self._next_request_s = 0.0

    @property
    def connection(self) -> str:
        """What ``clark run --autopilot-connection`` takes: SITL's SERIAL1."""
        return f"tcp:127.0.0.1:{self.backend.process.ports.serial1_tcp_port}"

    @property
    def instance(self) -> int:
        """The SITL instance number it runs on."""
        return self.backend.process.instance

    def write(self, data: bytes) -> None:
        """Where the pilot's stream requests are encoded."""
        self._out += data

    def _ask_streams(self, t_s: float) -> None:
        if not self._streams or t_s < self._next_request_s:
            return
        self._next_request_s = t_s + STREAM_RETRY_S
        system = self.backend.system_id
        for name in sorted(self._streams):
            msg_id = int(getattr(mavlink2, f"MAVLINK_MSG_ID_{name}"))
            self._mav.command_long_send(
                system, 1, mavlink2.MAV_CMD_SET_MESSAGE_INTERVAL, 0,
                msg_id, PILOT_STREAM_INTERVAL_US, 0, 0, 0, 0, 0,
            )  # fmt: skip
        data, self._out = bytes(self._out), bytearray()
        self.backend.send(data, t_s)

    def serve(self, stopped: Stopped, say: Say = print) -> None:
        """Connect SITL, fly it up if the mission hands it over in flight, then run on."""
        self.backend.connect()
        if self._fly_up is not None:
            say(f"{self.name}: flying up to its start point")
            self.backend.fly_up(**self._fly_up)
        self.backend.start_run_here()
        announce = _Announcer(self.name, self.pilot, say, self._modes, self.backend.system_id)
        t_s = 0.0
        clock_said = False
        while not stopped():
            t_s += SITL_STEP_S
            data = self.backend.step(t_s, SITL_STEP_S)
            for msg in self._parser.parse_buffer(data) or []:
                self._streams.discard(msg.get_type())
                if not clock_said and msg.get_type() == "SYSTEM_TIME" and msg.time_unix_usec:
                    clock_said = True
                    say(self._clock_note(msg.time_unix_usec / 1e6 - time.time()))
            self._ask_streams(t_s)
            announce.hear(data, t_s)
            if not self.pilot.done:
                self.pilot.hear(data, t_s)
            announce(t_s)

    def _clock_note(self, ahead_s: float) -> str:
        """Says how far SITL's GPS clock is from this machine's (``ahead_s`` > 0: ahead).

        SITL's GPS time is the wall clock when it started plus its simulated time, which
        starts only when SERIAL0 is connected: it lags by SITL's start-up (0.2-1 s seen).
        The agents' logs are tied together by GPS time, so their latencies and
        ``clark analyze --checks``'s clocks carry this offset; real GPS receivers agree.
        """
        way = "ahead of" if ahead_s > 0 else "behind"
        return f"{self.name}: SITL's GPS clock is {abs(ahead_s):.2f} s {way} this machine's"

    def close(self) -> None:
        """Stop SITL."""
        self.backend.close()


def _load(path_text: str, agent: str) -> Mission:
    """The resolved mission, with ``agent`` one of its vehicles.

    Raises:
        UsageError: No such file, agent, or the agent is the station.
        ClarkError: The mission is invalid (its findings are printed first).
    """
    from clark_engine.validation import load_mission

    mission = load_mission(path_text)
    vehicles = [name for name, a in mission.agents.items() if a.role != "mcs"]
    if agent not in mission.agents:
        raise UsageError(
            f"{path_text}: there is no agent {agent!r}; vehicles: {', '.join(vehicles)}"
        )
    if agent not in vehicles:
        raise UsageError(
            f"{agent} is the mission's station, which has no autopilot; vehicles: "
            f"{', '.join(vehicles)}"
        )
    return mission


def _listen_address(text: str) -> tuple[str, int]:
    host, sep, port = text.rpartition(":")
    if not sep or not host or not port.isdigit() or not 0 <= int(port) <= 65535:
        raise UsageError(f"--listen {text!r}: use HOST:PORT (e.g. 127.0.0.1:14561)")
    return host, int(port)


def serve_vehicle(args: Any) -> int:
    """``clark autopilot-sim MISSION --agent NAME``: serve its autopilot until stopped.

    Prints where ``clark run`` connects, then what the vehicle does (ready, armed) as
    it happens; SIGINT, SIGTERM or ``--until`` end it (SITL stopped, the port closed).

    Returns:
        0 after a clean stop.

    Raises:
        UsageError: A bad option, or SITL not found (exit 2).
        ClarkError: An invalid mission, or SITL failed while serving (exit 1).
    """
    mission = _load(args.mission, args.agent)
    server: ServedSimulated | ServedSitl
    if args.autopilot == "sitl":
        for given, option in ((args.listen, "--listen"), (args.ready_s, "--ready-s")):
            if given is not None:
                raise UsageError(
                    f"{option} only applies to the simulated autopilot: SITL serves its "
                    "SERIAL1 on TCP and boots in its own time"
                )
        try:
            install = SitlInstall.find(args.sitl, instances=args.sitl_instances)
        except SitlError as exc:
            raise UsageError(str(exc)) from None
        server = ServedSitl(mission, args.agent, install)
        kind = f"ArduPilot SITL (instance {server.instance}, real time)"
    else:
        for given, option in ((args.sitl, "--sitl"), (args.sitl_instances, "--sitl-instances")):
            if given is not None:
                raise UsageError(f"{option} only applies with --autopilot sitl")
        host, port = _listen_address(args.listen or DEFAULT_LISTEN)
        try:
            server = ServedSimulated(
                mission, args.agent, host=host, port=port, ready_s=args.ready_s
            )
        except TransportError as exc:
            raise UsageError(f"--listen {host}:{port}: {exc}") from None
        kind = "the simulated autopilot (real time)"

    def say(line: str) -> None:
        print(line, flush=True)

    say(f"clark autopilot-sim: {args.agent}'s autopilot on {kind}")
    if server.drawn:
        say(drawn_line(server.seed, server.drawn))
    say(f"{args.agent}: clark run connects with --autopilot-connection {server.connection}")
    stop = StopFlag(args.until)
    try:
        with stop.on_signals():
            server.serve(stop, say)
    finally:
        server.close()
    say(f"{args.agent}: stopped")
    return 0
