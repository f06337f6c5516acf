"""Real time: each simulated autopilot on a UDP port, for a ground station nobody here wrote.

``clark dry-run MISSION --realtime --mavlink-port BASE`` runs the dry run at
wall-clock speed and puts vehicle k (the mission's vehicles in agent order,
k = 0, 1, ...) on UDP port BASE + k, so MAVProxy, QGroundControl, MAVSDK or
pymavlink can watch and command the simulated vehicle while the engine flies it.

The convention is the one of a MAVLink endpoint that waits for its ground
stations, as ``mavproxy.py --out=udpin:0.0.0.0:14550`` does for its clients:
the simulated autopilot *listens* on its port and answers every station that
has sent it a datagram (its heartbeat, usually), up to
:data:`~clark_engine.io.transports.MAX_UDP_PEERS` at once. A station therefore
connects as a UDP client that sends first: ``udpout:HOST:PORT`` for MAVProxy and
pymavlink, ``udpout://HOST:PORT`` for MAVSDK, a UDP link with HOST:PORT as its
remote (server) address for QGroundControl. The other direction (the vehicle
sending to a fixed 14550, as ArduPilot SITL's ``--out``) was not chosen because
one fixed destination cannot serve several vehicles and several stations, and a
listener needs no configuration on the station's side beyond the port.

The bridge is a shell around the simulator, which stays pure: it uses the
:class:`~clark_engine.dryrun.engine.DryRun` hooks only. ``autopilot_taps`` hand it
every byte string a simulated autopilot emits, which it sends to that vehicle's
stations; ``on_step`` lets it read its sockets (never blocking) once per loop
iteration, at least every physics step (20 ms), and pass what arrived to
:meth:`~clark_engine.dryrun.engine.DryRun.inject` at the current simulated time.
All peers of one vehicle share one MAVLink stream, as behind a router: each
sees the others' answers (and the engine's), and each answer is addressed to
whoever asked.
"""

from __future__ import annotations

import signal
import threading
import time
from collections.abc import Callable, Iterator, Sequence
from contextlib import contextmanager
from dataclasses import dataclass
from types import FrameType, TracebackType
from typing import Any, Final

from clark_engine.dryrun.engine import DryRun
from clark_engine.errors import UsageError
from clark_engine.io.transports import TransportError, UdpTransport
from clark_engine.mission.model import Mission

DEFAULT_HOST: Final = "127.0.0.1"
"""Loopback: a real-time dry run is reachable from this machine only unless asked otherwise."""

MAX_DATAGRAM_BYTES: Final = 1400
"""Largest datagram sent: whole MAVLink frames up to this size, so that a station on another
machine gets them without IP fragmentation over an Ethernet-sized MTU."""

_MAVLINK2_STX: Final = 0xFD
_MAVLINK1_STX: Final = 0xFE
_MAVLINK2_SIGNED: Final = 0x01
_MAVLINK2_SIGNATURE_BYTES: Final = 13


@dataclass(frozen=True, slots=True)
class Endpoint:
    """Where one simulated vehicle's autopilot waits for ground stations."""

    agent: str
    """The vehicle's agent name in the mission."""
    host: str
    """The address its socket is bound to."""
    port: int
    """Its UDP port: the base port plus the vehicle's index among the mission's vehicles."""
    system_id: int
    """Its MAVLink system id (MAV_SYSID), which a station sees in its HEARTBEAT."""

    @property
    def address(self) -> str:
        """``host:port``, as connection strings write it."""
        return f"{self.host}:{self.port}"


def datagrams(data: bytes, limit: int = MAX_DATAGRAM_BYTES) -> list[bytes]:
    """Split a byte string of whole MAVLink frames into datagrams of whole frames.

    A simulated autopilot's ``advance`` returns everything due at once (a
    parameter list is a few kilobytes); stations parse any number of frames per
    datagram, but a datagram above the path's MTU is fragmented, and one lost
    fragment loses every frame in it. Frames are never cut: a frame longer than
    ``limit`` (none is) or bytes that do not start a frame go out as they are.
    """
    out: list[bytes] = []
    start = end = 0
    size = len(data)
    while end < size:
        stx = data[end]
        if stx == _MAVLINK2_STX and end + 2 < size:
            frame = 12 + data[end + 1]
            if data[end + 2] & _MAVLINK2_SIGNED:
                frame += _MAVLINK2_SIGNATURE_BYTES
        elif stx == _MAVLINK1_STX and end + 1 < size:
            frame = 8 + data[end + 1]
        else:
            frame = size - end  # not a frame start: keep the rest together
        if end > start and end + frame - start > limit:
            out.append(data[start:end])
            start = end
        end = min(size, end + frame)
    if end > start:
        out.append(data[start:end])
    return out


def vehicle_names(mission: Mission) -> list[str]:
    """The mission's vehicles in its agent order: vehicle k is the k-th of these."""
    return [name for name, agent in mission.agents.items() if agent.is_vehicle]


def vehicle_ports(vehicles: Sequence[str], base_port: int) -> dict[str, int]:
    """Vehicle agent -> UDP port: BASE + k for the k-th vehicle.

    Raises:
        UsageError: No vehicle, or ports that do not fit in 1-65535.
    """
    if not vehicles:
        raise UsageError("--realtime: the mission has no vehicle to put on a MAVLink port")
    last = base_port + len(vehicles) - 1
    if base_port < 1 or last > 65535:
        raise UsageError(
            f"--mavlink-port {base_port}: {len(vehicles)} vehicle(s) need UDP ports "
            f"{base_port}-{last}, which must lie within 1-65535 (e.g. --mavlink-port 14560)"
        )
    return {name: base_port + k for k, name in enumerate(vehicles)}


class StopSwitch:
    """Ends a run early, as if ``--until`` were now (Ctrl-C in a real-time run).

    :meth:`stop` is safe from any thread and from a signal handler: it only sets a
    flag; the run's own thread ends the loop at its next step (:meth:`check`), so
    the logs close and the report is written as after a normal end.
    """

    def __init__(self) -> None:
        self._stop = threading.Event()
        self.stopped_at_s: float | None = None
        """The simulated time at which :meth:`stop` took effect; None while running."""
        self.stopped_by = "Ctrl-C"
        """What stopped it (``Ctrl-C``, ``SIGTERM``), for the line that says so."""

    def stop(self, reason: str = "Ctrl-C") -> None:
        """End the run at its next step; ``reason`` says what stopped it."""
        if not self._stop.is_set():
            self.stopped_by = reason
        self._stop.set()

    def check(self, run: DryRun, t_s: float) -> None:
        """Called at every step of ``run``: end it now when :meth:`stop` was called."""
        if self._stop.is_set() and self.stopped_at_s is None:
            self.stopped_at_s = t_s
            run.until_s = min(run.until_s, t_s)

    def attach(self, run: DryRun) -> None:
        """Check at every step of ``run`` (after any hook it already has)."""
        previous = run.on_step

        def step(t_s: float) -> None:
            if previous is not None:
                previous(t_s)
            self.check(run, t_s)

        run.on_step = step


class MavlinkBridge:
    """Each simulated vehicle's autopilot on a UDP port of its own, during one dry run.

    Built before the run, so that a port in use is reported before anything is
    simulated or written: the constructor binds one socket per vehicle;
    :meth:`attach` hooks them into the run, which must be paced at wall-clock
    speed (``DryRun(speed=1.0)``) for a station to make sense of it; :meth:`close`
    unhooks and closes them. Use it as a context manager around :meth:`DryRun.run`.

    Args:
        vehicles: The vehicles' agent names in the mission's order
            (:func:`vehicle_names`); vehicle k listens on ``base_port + k``.
        base_port: The first vehicle's port.
        host: The address to bind: loopback by default; ``0.0.0.0`` lets stations on
            other machines connect (mind what the network may reach).

    Raises:
        UsageError: No vehicle, ports out of range, or a port that cannot be bound (in
            use, or a host that is not this machine's); nothing stays open.
    """

    def __init__(
        self, vehicles: Sequence[str], base_port: int, *, host: str = DEFAULT_HOST
    ) -> None:
        self._run: DryRun | None = None
        self._previous_step: Callable[[float], None] | None = None
        self._switch = StopSwitch()
        self.endpoints: list[Endpoint] = []
        """One per vehicle, in the mission's agent order, once attached."""
        self._transports: dict[str, UdpTransport] = {}
        ports = vehicle_ports(vehicles, base_port)
        for name, port in ports.items():
            try:
                self._transports[name] = UdpTransport(bind=(host, port))
            except TransportError as exc:
                self._close_sockets()
                raise UsageError(
                    f"--realtime: {name}'s {exc}; choose another --mavlink-port (the "
                    f"vehicles need {min(ports.values())}-{max(ports.values())}) or "
                    "--mavlink-host"
                ) from None

    def attach(self, run: DryRun) -> None:
        """Hook the sockets into a run that has not started.

        Raises:
            ValueError: A vehicle of the bridge has no simulated autopilot in the run.
        """
        endpoints = []
        for name, transport in self._transports.items():
            agent = run.agents.get(name)
            if agent is None or agent.backend is None:
                raise ValueError(f"{name!r} is not a simulated vehicle of this run")
            host, port = transport.address
            endpoints.append(Endpoint(name, host, port, agent.backend.system_id))
        for name, transport in self._transports.items():
            run.autopilot_taps[name] = self._tap(transport, run.autopilot_taps.get(name))
        self._run = run
        self._previous_step = run.on_step
        run.on_step = self._step
        self.endpoints = endpoints

    # -- public -------------------------------------------------------------------------

    def stop(self, reason: str = "Ctrl-C") -> None:
        """End the run at the next loop iteration, as if ``--until`` were now.

        Safe from any thread and from a signal handler: it only sets a flag; the
        run's own thread ends the loop, so the logs close and the report is written
        as after a normal end.
        """
        self._switch.stop(reason)

    @property
    def stopped_at_s(self) -> float | None:
        """The simulated time at which :meth:`stop` took effect; None while running."""
        return self._switch.stopped_at_s

    @property
    def stopped_by(self) -> str:
        """What stopped the run (``Ctrl-C``, ``SIGTERM``)."""
        return self._switch.stopped_by

    def peers(self, agent: str) -> tuple[tuple[str, int], ...]:
        """The UDP addresses of the stations a vehicle has heard, oldest first."""
        return self._transports[agent].peers

    def close(self) -> None:
        """Unhook from the run and close every socket; calling it again does nothing."""
        run, self._run = self._run, None
        if run is not None:
            for name in self._transports:
                run.autopilot_taps.pop(name, None)
            if run.on_step == self._step:
                run.on_step = self._previous_step
        self._close_sockets()

    def __enter__(self) -> MavlinkBridge:
        return self

    def __exit__(
        self,
        exc_type: type[BaseException] | None,
        exc: BaseException | None,
        tb: TracebackType | None,
    ) -> None:
        self.close()

    # -- hooks --------------------------------------------------------------------------

    def _tap(
        self, transport: UdpTransport, previous: Callable[[bytes], None] | None
    ) -> Callable[[bytes], None]:
        def forward(data: bytes) -> None:
            if previous is not None:
                previous(data)
            if not transport.peers:
                return  # nobody has connected yet: nothing to send, nothing to split
            try:
                for datagram in datagrams(data):
                    transport.send(datagram)
            except TransportError:
                pass  # a station's socket error must not stop the flight; UDP may drop

        return forward

    def _step(self, t_s: float) -> None:
        run = self._run
        assert run is not None  # hooked by attach(), unhooked by close()
        if self._previous_step is not None:
            self._previous_step(t_s)
        for name, transport in self._transports.items():
            try:
                data = transport.receive()
            except TransportError:
                continue  # as above: the run goes on; the station retries
            if data:
                run.inject(name, data, t_s)
        self._switch.check(run, t_s)

    def _close_sockets(self) -> None:
        for transport in self._transports.values():
            transport.close()


@contextmanager
def stop_on_interrupt(stop: Callable[[str], None]) -> Iterator[None]:
    """Within the block, the first Ctrl-C (SIGINT) or SIGTERM calls ``stop`` instead.

    A real-time run has no end a person waits for, so Ctrl-C is its normal end, and
    SIGTERM (a service manager, ``kill``, a CI runner's timeout) is the same end asked
    by a program: the loop finishes its step, the logs close and the report is written.
    ``stop`` is given ``"Ctrl-C"`` or ``"SIGTERM"``. After the first, both signals act
    as they did before the block (a second Ctrl-C raises KeyboardInterrupt, for a run
    that does not stop). Signal handlers belong to the main thread; elsewhere (a test
    running the dry run in a thread) this does nothing, and a signal ignored on purpose
    (a background job's SIGINT) stays ignored.
    """
    if threading.current_thread() is not threading.main_thread():
        yield  # not ours to change
        return
    names = {signal.SIGINT: "Ctrl-C", signal.SIGTERM: "SIGTERM"}
    previous: dict[signal.Signals, Any] = {}
    for signum in names:
        installed = signal.getsignal(signum)
        if installed == signal.SIG_IGN:
            continue
        # None: a handler not set from Python; put Python's default back in its place.
        if installed is None:
            installed = signal.default_int_handler if signum == signal.SIGINT else signal.SIG_DFL
        previous[signum] = installed

    def restore() -> None:
        for signum, handler in previous.items():
            signal.signal(signum, handler)

    def interrupted(signum: int, frame: FrameType | None) -> None:
        restore()
        stop(names[signal.Signals(signum)])

    for signum in previous:
        signal.signal(signum, interrupted)
    try:
        yield
    finally:
        restore()


class StopFlag:
    """A foreground tool's stop: true once SIGINT or SIGTERM came, or ``until_s`` passed.

    ``clark autopilot-sim`` and ``clark radio-sim`` serve until a person (Ctrl-C) or a
    service manager (SIGTERM) stops them, and then clean up (SITL stopped, links
    removed); calling the flag polls it, :meth:`wait` sleeps on it.

    Args:
        until_s: Wall seconds after which it is true by itself; None: never.
    """

    def __init__(self, until_s: float | None = None) -> None:
        self._deadline = None if until_s is None else time.monotonic() + until_s
        self._event = threading.Event()

    def __call__(self) -> bool:
        """True once stopped (a signal, :meth:`set`, or the time is up)."""
        if self._deadline is not None and time.monotonic() >= self._deadline:
            self._event.set()
        return self._event.is_set()

    def set(self) -> None:
        """Stop now."""
        self._event.set()

    def wait(self) -> None:
        """Sleep until it is true."""
        while not self():
            left = None if self._deadline is None else self._deadline - time.monotonic()
            self._event.wait(1.0 if left is None else max(0.0, min(1.0, left)))

    def _on_signal(self, signum: int, frame: FrameType | None) -> None:
        self._event.set()

    @contextmanager
    def on_signals(self) -> Iterator[None]:
        """Within the block, SIGINT and SIGTERM set the flag (from the main thread only)."""
        if threading.current_thread() is not threading.main_thread():
            yield
            return
        previous = {sig: signal.getsignal(sig) for sig in (signal.SIGINT, signal.SIGTERM)}
        for sig in previous:
            signal.signal(sig, self._on_signal)
        try:
            yield
        finally:
            for sig, handler in previous.items():
                signal.signal(sig, handler)
