"""The real-time shell: one agent's runtime on a real clock and real links.

The runtime core (:class:`~clark_engine.runtime.runtime.AgentRuntime`) is pure; this
shell owns time and I/O around it, one process per agent, single-threaded around one
:mod:`selectors` loop (DESIGN.md, "Layers"):

- It waits on the autopilot transport, the radio's descriptor, the payloads'
  descriptors (and any reader a caller adds, such as the station's terminal) until
  the next tick deadline, and hands what arrives to the runtime at once: autopilot
  bytes through the :class:`~clark_engine.io.autopilot.AutopilotAdapter` into typed
  events, radio frames as :class:`~clark_engine.runtime.events.PacketReceived`,
  payload lines as :class:`~clark_engine.runtime.events.PayloadEvent`.
- It ticks the runtime at ``loop_hz`` on a drift-free schedule: tick ``k`` is due at
  ``start + k * period`` on :func:`time.monotonic`, never at "the last tick plus a
  sleep", so waiting and work never accumulate into drift. A tick that starts one
  whole period or more late is an *overrun*: the deadlines it missed are skipped (the
  runtime counts rates in ticks, so it is not made to catch up with a burst of ticks),
  counted in :attr:`ShellStats.overruns` and :attr:`ShellStats.skipped_ticks`, and
  logged in the interface log with its size.
- It carries out the commands the runtime returns: vehicle commands through the
  adapter to the transport, :class:`~clark_engine.runtime.commands.SendPacket` to the
  radio (unicast to the peer's radio address, broadcast when the destination is every
  agent), :class:`~clark_engine.runtime.commands.PayloadCommand` to the payload, and
  :class:`~clark_engine.runtime.commands.CloseInterfaces` by ending the loop.
- It waits to the microsecond: Linux's default selector (epoll) counts its timeout in
  whole milliseconds, which Python rounds up, so a wait for 1.3 ms lasts 2 ms and more.
  At 500 Hz that made a tick start 0.6 ms late at the median, a third of the period
  gone before any scheduling delay (``docs/performance.md``). With an epoll selector,
  the shell waits on the epoll descriptor itself with :func:`select.select`, whose
  timeout is in microseconds, then collects the events without waiting
  (:func:`_precise_wait`).
- The cyclic garbage collector leaves start-up alone: when the loop starts, start-up's
  garbage is collected once and every object still alive (modules, schemas, the
  compiled config: 49,000-63,000 in ``clark run``) is moved out of the collector's
  reach with :func:`gc.freeze`, so a collection in the loop looks only at objects made
  since. Otherwise the full collections (one 43 s into a 500 Hz loop with three peers,
  the next three minutes later) traverse them all, 20-26 ms on a quiet machine and up
  to 96 ms on a busy one, in the middle of a tick; frozen, they took 0.5-1.9 ms
  (``docs/performance.md``). :func:`gc.unfreeze` undoes it when the loop ends
  (``gc_freeze``).
- An autopilot transport or a radio that fails is closed and opened again from the
  loop, with a growing back-off (:data:`~clark_engine.shells.links.REOPEN_BACKOFF_S`),
  counted and logged; the loop never stops for it (the runtime's ``autopilot_lost``
  takes care of safety). A radio that reconnects by itself (an XBee dongle pulled out
  and plugged back) reports each loss and return (``Radio.link_events``, drained with
  its frames): one interface-log line each, with its time, counted with the shell's
  own.
- Testing mode (thesis 7.2.9): any interface may be left out (``None``): its commands
  are dropped and counted, and a payload command is answered with an ``error`` event
  at once so the runtime never waits for an answer that cannot come.
- SIGINT and SIGTERM stop it cleanly (:meth:`RealtimeShell.signals`,
  :meth:`RealtimeShell.shutdown`). The stop has parts that keep the vehicle safe and
  always run, each bounded (nothing in them waits on anything but a local file): the RC
  overrides released, the runtime's terminate sequence (its primitives stopped, the
  vehicle to its terminal mode, a last heartbeat), the failsafe the set-up switched on
  switched off, the replay marks saved, every link closed, the logs flushed and closed.
  One part only waits: for the autopilot to confirm the terminal mode and the failsafe
  (resent meanwhile), at most :data:`~clark_engine.shells.stop.STOP_CONFIRM_S`. A
  second signal (and a third) never raises: it cuts that wait short, one line says what
  was skipped, and :meth:`RealtimeShell.run` returns 130. An exception in the loop
  still runs the stop. The stop and the signals are :mod:`clark_engine.shells.stop`,
  mixed into the shell; the links it opens are :mod:`clark_engine.shells.links`.

GPS time (thesis 7.2.11): a vehicle's log lines are stamped with the GPS time its
autopilot reports (the runtime does this from ``VehicleState.gps_time_ms``); an agent
without an autopilot (a station, or a vehicle whose autopilot is disabled) gets the
system clock's GPS time through the runtime's ``gps_epoch_ms`` (:func:`gps_epoch_ms`).

Time: the runtime's clock is the shell's monotonic clock minus its origin (so log
lines read ``t=0.100``, ``t=0.200``...). Tests inject a clock and a selector
(:class:`RealtimeShell` arguments) to run the loop deterministically.
"""

from __future__ import annotations

import contextlib
import gc
import logging
import math
import select
import selectors
import socket
import time
from collections.abc import Callable, Iterator, Mapping
from dataclasses import dataclass, field
from typing import Any, Final, cast

from clark_engine.io.autopilot_decode import gps_time_ms_from_unix_us
from clark_engine.io.payload import PayloadAdapter
from clark_engine.io.radio import LinkEvent, Radio, RadioError
from clark_engine.io.transports import TransportError
from clark_engine.runtime.commands import (
    AUTOPILOT_COMMANDS,
    CloseInterfaces,
    Command,
    PayloadCommand,
    SendPacket,
    check_dispatch,
    unknown_command,
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
    VehicleState,
)
from clark_engine.runtime.log_events import LogEvent
from clark_engine.runtime.runtime import AgentRuntime
from clark_engine.shells.links import AutopilotLink, RadioLink
from clark_engine.shells.stop import ShellStop

EXIT_ABORTED: Final = 130
"""What :meth:`RealtimeShell.run` returns when a second signal shortened the stop (as a
shell's Ctrl-C; the same for SIGTERM, as docs/run.md says)."""

_RUNTIME_EVENTS = (
    VehicleState,
    AutopilotHeartbeat,
    AutopilotStatus,
    AutopilotHealth,
    AutopilotText,
    CommandRefused,
    AutopilotSafetyResult,
    MissionUploadResult,
    MissionProgress,
    RcChannels,
)

_DUE_TOLERANCE_S: Final = 1e-6
"""A deadline this close is due: a wait never ends on the exact float of its deadline."""

Clock = Callable[[], float]

_SelectorEvents = list[tuple[selectors.SelectorKey, int]]


def _precise_wait(selector: selectors.EpollSelector, timeout_s: float) -> _SelectorEvents:
    """``selector.select(timeout_s)`` to the microsecond rather than the millisecond.

    epoll counts its timeout in whole milliseconds (rounded up), :func:`select.select`
    in microseconds; the epoll descriptor is readable when any descriptor it watches
    is ready, so the wait is done by ``select`` on it and the events are collected by
    epoll without waiting. Raises ValueError when the descriptor is too high for
    ``select`` (FD_SETSIZE); the caller then waits on epoll alone.
    """
    readable, _, _ = select.select([selector.fileno()], [], [], timeout_s)
    return selector.select(0) if readable else []


def gps_epoch_ms(unix_time_s: float) -> int:
    """GPS time in ms at the runtime's time 0, from the system clock read at that moment."""
    return gps_time_ms_from_unix_us(round(unix_time_s * 1e6))


@dataclass(slots=True)
class ShellStats:
    """What the loop counted since it started.

    Attributes:
        ticks: Ticks run.
        overruns: Ticks that started one period or more after their deadline.
        skipped_ticks: Deadlines skipped by those overruns.
        worst_overrun_s: The largest lateness of an overrun.
        max_late_s: The largest lateness of any tick (jitter included).
        max_tick_s: The longest a tick took from its start to its end (the runtime, the
            commands carried out, the hooks): an overrun much longer than this came from
            the wait before the tick (the process waiting for a CPU), not from its work.
        tick_s: Every tick's time from start to end, summed (the loop's busy time).
        wakeups: Selector waits that returned.
        autopilot_failures: Times the autopilot link failed or could not be opened.
        autopilot_reopens: Times it was opened again after a failure.
        radio_failures: Times the radio failed or could not be opened, and times it
            reported its link lost (an XBee pulled out, :meth:`Radio.link_events`).
        radio_reopens: Times it was opened again after a failure, or reported its
            link back.
        dropped_commands: Commands for an interface that is disabled or down, per kind.
    """

    ticks: int = 0
    overruns: int = 0
    skipped_ticks: int = 0
    worst_overrun_s: float = 0.0
    max_late_s: float = 0.0
    max_tick_s: float = 0.0
    tick_s: float = 0.0
    wakeups: int = 0
    autopilot_failures: int = 0
    autopilot_reopens: int = 0
    radio_failures: int = 0
    radio_reopens: int = 0
    dropped_commands: dict[str, int] = field(default_factory=dict)

    def drop(self, kind: str) -> None:
        """Count one command that could not be carried out."""
        self.dropped_commands[kind] = self.dropped_commands.get(kind, 0) + 1


class RealtimeShell(ShellStop):
    """One agent's runtime in a selectors loop on a monotonic clock.

    Args:
        runtime: The agent's runtime, built with the shell's clock origin in mind
            (its ``gps_epoch_ms`` for time 0 at ``origin_s``).
        autopilot: The autopilot link; None when disabled (testing mode) or a station.
        radio: The radio link; None when disabled.
        payloads: Payload adapters by payload name, already open; a payload of the
            agent missing here is disabled.
        peer_addresses: Radio address per peer name, overriding the mission's
            (loopback rehearsals: every agent on 127.0.0.1 with its own port).
        loop_hz: Ticks per second (the mission's ``loop_hz`` by default).
        clock: Monotonic seconds (:func:`time.monotonic` by default; tests inject one).
        selector: The selector to wait with (a new default selector by default).
        origin_s: The clock reading that is the runtime's time 0.
        logger: Where the shell's own lines go (the agent's interface log by default).
        gc_freeze: Move every object alive when the loop starts out of the cyclic
            garbage collector's reach while it runs (:func:`gc.freeze`; undone when it
            ends), so a collection never traverses the start-up heap mid-tick. The
            collector is process-wide: give False where something else in the process
            manages it.
    """

    def __init__(
        self,
        runtime: AgentRuntime,
        *,
        autopilot: AutopilotLink | None = None,
        radio: RadioLink | None = None,
        payloads: Mapping[str, PayloadAdapter] | None = None,
        peer_addresses: Mapping[str, str] | None = None,
        loop_hz: float | None = None,
        clock: Clock = time.monotonic,
        selector: selectors.BaseSelector | None = None,
        origin_s: float | None = None,
        logger: logging.Logger | None = None,
        gc_freeze: bool = True,
    ) -> None:
        self.runtime = runtime
        # The shell closes the logbook at the end of its stop, so that the stop's own
        # lines (what the autopilot answered, the marks saved, the links closed) are kept.
        runtime.close_logbook_on_terminate = False
        self.autopilot = autopilot
        self.radio = radio
        self.payloads: dict[str, PayloadAdapter] = dict(payloads or {})
        self.peer_addresses = dict(peer_addresses or {})
        self.loop_hz = float(loop_hz if loop_hz is not None else runtime.config.loop_hz)
        if not self.loop_hz > 0:
            raise ValueError(f"loop_hz must be above 0, not {self.loop_hz}")
        self.period_s = 1.0 / self.loop_hz
        self.clock = clock
        self.origin_s = clock() if origin_s is None else origin_s
        self.selector = selector if selector is not None else selectors.DefaultSelector()
        self.gc_freeze = gc_freeze
        #: Waits to the microsecond on an epoll selector (:func:`_precise_wait`).
        self._precise = isinstance(self.selector, selectors.EpollSelector)
        self.log = logger if logger is not None else runtime.logbook.interface
        self.stats = ShellStats()
        self.start_s: float | None = None
        """Runtime time of the loop's start (deadline 0)."""
        self.stopped_by: str | None = None
        """Why the loop ended (``SIGTERM``, ``terminate``, ``until``...)."""
        #: Called after every tick with the shell and the runtime time (status, scripts).
        self.on_tick: list[Callable[[RealtimeShell, float], None]] = []
        self._readers: dict[int, Callable[[float], None]] = {}
        self._registered: dict[str, int] = {}
        self._stop_reason: str | None = None
        self._signals = 0
        self._in_stop = False
        self.hurried_by: str | None = None
        """The signal that shortened the stop (the second one), or None."""
        self.skipped: list[str] = []
        """What a shortened stop skipped, in words (empty: nothing was left to skip)."""
        #: Tells the person at the terminal how the stop goes (``clark run`` prints it).
        self.announce: Callable[[str], None] | None = None
        self._closing = False
        self._closed = False
        self._wake_r, self._wake_w = socket.socketpair()
        self._wake_r.setblocking(False)
        self._wake_w.setblocking(False)
        self.selector.register(self._wake_r, selectors.EVENT_READ, "wake")

    # -- clock ----------------------------------------------------------------------------

    def now(self) -> float:
        """The runtime's time: the clock minus its origin."""
        return self.clock() - self.origin_s

    # -- control ---------------------------------------------------------------------------

    def stop(self, reason: str = "stop") -> None:
        """End the loop cleanly at its next wake-up; safe from signal handlers and threads."""
        if self._stop_reason is None:
            self._stop_reason = reason
        with contextlib.suppress(OSError):
            self._wake_w.send(b"\0")

    def add_reader(self, fd: int, callback: Callable[[float], None]) -> None:
        """Call ``callback(now_s)`` whenever ``fd`` is readable (the station's terminal)."""
        self._readers[fd] = callback
        self.selector.register(fd, selectors.EVENT_READ, ("reader", fd))

    def remove_reader(self, fd: int) -> None:
        """Stop watching ``fd``."""
        if self._readers.pop(fd, None) is not None:
            with contextlib.suppress(KeyError, ValueError):
                self.selector.unregister(fd)

    def deliver(self, event: Event, now_s: float | None = None) -> None:
        """Hand one event to the runtime now and carry out what it returns."""
        t = self.now() if now_s is None else now_s
        self._carry_out(self.runtime.deliver(event, t), t)

    # -- the loop ---------------------------------------------------------------------------

    def run(self, *, max_ticks: int | None = None, until_s: float | None = None) -> int:
        """Run until stopped, terminated, ``max_ticks`` ticks or ``until_s`` seconds.

        Returns:
            0 after a clean stop, :data:`EXIT_ABORTED` when a second signal shortened it.
        """
        with self._heap_frozen():
            start = self.now()
            self.start_s = start
            period = self.period_s
            self.log.info(
                "real-time shell: loop at %g Hz; autopilot %s; radio %s; payloads %s",
                self.loop_hz,
                self.autopilot.describe if self.autopilot else "disabled",
                self.radio.describe if self.radio else "disabled",
                ", ".join(self.payloads) or "none",
                extra=LogEvent.SHELL_START.extra,
            )
            self._open_links(start)
            k = 0
            try:
                while True:
                    if self._stop_reason is not None:
                        self.stopped_by = self._stop_reason
                        break
                    if self._closing:
                        self.stopped_by = "terminate"
                        break
                    deadline = start + k * period
                    now = self.now()
                    if now < deadline - _DUE_TOLERANCE_S:
                        self._wait(deadline - now)
                        continue
                    late = max(0.0, now - deadline)
                    self.stats.max_late_s = max(self.stats.max_late_s, late)
                    missed = math.floor(late / period)
                    if missed >= 1:
                        self.stats.overruns += 1
                        self.stats.skipped_ticks += missed
                        self.stats.worst_overrun_s = max(self.stats.worst_overrun_s, late)
                        self.log.warning(
                            "overrun: tick %d started %.1f ms late (period %.1f ms); "
                            "skipped %d deadline(s)",
                            k,
                            late * 1000,
                            period * 1000,
                            missed,
                            extra=LogEvent.SHELL_OVERRUN.extra,
                        )
                        k += missed
                    self._tick(now)
                    work = self.now() - now
                    self.stats.tick_s += work
                    if work > self.stats.max_tick_s:
                        self.stats.max_tick_s = work
                    k += 1
                    if max_ticks is not None and self.stats.ticks >= max_ticks:
                        self.stopped_by = "max_ticks"
                        break
                    if until_s is not None and now - start >= until_s:
                        self.stopped_by = "until"
                        break
            except BaseException:
                # A fault in the loop still leaves the vehicle as the stop does.
                self.stopped_by = self.stopped_by or "an error in the loop"
                with contextlib.suppress(Exception):
                    self.shutdown()
                raise
            self.shutdown()
            return EXIT_ABORTED if self.hurried_by is not None else 0

    @contextlib.contextmanager
    def _heap_frozen(self) -> Iterator[None]:
        """Within: start-up's garbage collected once, the rest frozen (``gc_freeze``)."""
        if not self.gc_freeze:
            yield
            return
        gc.collect()  # start-up's garbage, once, before the first deadline
        gc.freeze()  # the rest: out of every collection while the loop runs
        try:
            yield
        finally:
            gc.unfreeze()

    def _tick(self, now: float) -> None:
        self._retry_links(now)
        self._carry_out(self.runtime.tick(now), now)
        self.stats.ticks += 1
        link = self.autopilot
        if link is not None and link.transport is not None and not self._closing:
            self._to_autopilot(link.adapter.poll(now), now)
        for hook in self.on_tick:
            hook(self, now)

    def _wait(self, timeout_s: float) -> None:
        """Wait for input until ``timeout_s`` from now (or a link's retry), handling it."""
        retry = self._next_retry_s()
        if retry is not None:
            timeout_s = max(0.0, min(timeout_s, retry - self.now()))
        ready = self._select(timeout_s)
        self.stats.wakeups += 1
        now = self.now()
        for key, _mask in ready:
            what = key.data
            if what == "wake":
                with contextlib.suppress(OSError):
                    self._wake_r.recv(4096)
            elif what == "autopilot":
                self._from_autopilot(now)
            elif what == "radio":
                self._from_radio(now)
            elif isinstance(what, tuple) and what[0] == "payload":
                self._from_payload(what[1], now)
            elif isinstance(what, tuple) and what[0] == "reader":
                callback = self._readers.get(what[1])
                if callback is not None:
                    callback(now)
            if self._closing:
                return
        # Links without a descriptor (in-memory pipes) are polled at every wake-up.
        if self.autopilot is not None and "autopilot" not in self._registered:
            self._from_autopilot(now)
        if self.radio is not None and "radio" not in self._registered:
            self._from_radio(now)
        for name in self.payloads:
            if f"payload:{name}" not in self._registered:
                self._from_payload(name, now)
        if retry is not None:
            self._retry_links(now)

    def _select(self, timeout_s: float) -> _SelectorEvents:
        if self._precise and timeout_s > 0:
            try:
                return _precise_wait(cast(selectors.EpollSelector, self.selector), timeout_s)
            except ValueError:  # a descriptor above select()'s FD_SETSIZE: epoll alone
                self._precise = False
        return self.selector.select(timeout_s)

    # -- inputs -----------------------------------------------------------------------------

    def _from_autopilot(self, now: float) -> None:
        link = self.autopilot
        if link is None or link.transport is None:
            return
        try:
            data = link.transport.receive()
        except TransportError as exc:
            self._autopilot_failed(now, str(exc))
            return
        if not data:
            return
        for event in link.adapter.receive(data, now):
            if isinstance(event, _RUNTIME_EVENTS):
                self._carry_out(self.runtime.deliver(event, now), now)
        self._to_autopilot(link.adapter.flush(), now)  # what the answers called for

    def _from_radio(self, now: float) -> None:
        link = self.radio
        if link is None or link.radio is None:
            return
        try:
            frames = link.radio.receive()
        except (RadioError, OSError) as exc:
            self._radio_failed(now, str(exc))
            return
        for frame in frames:
            self._carry_out(self.runtime.deliver(PacketReceived(frame.data), now), now)
        if link.radio is not None:
            for event in link.radio.link_events():
                self._radio_link_event(link.radio, event, now)
        if link.radio is not None and link.radio.fileno() is None and "radio" in self._registered:
            self._radio_failed(now, "its descriptor closed")

    def _from_payload(self, name: str, now: float) -> None:
        adapter = self.payloads.get(name)
        if adapter is None:
            return
        for event in adapter.receive():
            self._carry_out(self.runtime.deliver(event, now), now)

    # -- outputs ----------------------------------------------------------------------------

    def _carry_out(self, commands: list[Command], now: float) -> None:
        """Carry out the runtime's commands through :data:`_CARRY_OUT`, one per type.

        Raises:
            UnknownCommandError: A command type this shell has no way to carry out (an
                engine bug, raised rather than dropped in silence).
        """
        for command in commands:
            carry_out = _CARRY_OUT.get(type(command))
            if carry_out is None:
                raise unknown_command(command, "the real-time shell")
            carry_out(self, command, now)

    def _autopilot_command(self, command: Any, now: float) -> None:
        """To the autopilot through its adapter; counted as dropped while it is closed."""
        link = self.autopilot
        if link is None or link.transport is None:
            self.stats.drop(type(command).__name__)
            return
        self._to_autopilot(link.adapter.command(command, now), now)

    def _close_command(self, command: CloseInterfaces, now: float) -> None:
        """Terminate: the loop closes the interfaces once this tick's commands are out."""
        self._closing = True

    def _send_packet(self, command: SendPacket, now: float) -> None:
        link = self.radio
        if link is None or link.radio is None:
            self.stats.drop("SendPacket")
            return
        address: str | None = None
        if command.destination:
            address = self.peer_addresses.get(command.destination, command.radio_address)
        try:
            link.radio.send(command.data, address)
        except RadioError as exc:
            # An address the radio cannot use is a configuration error: counted and logged,
            # never raised into the loop; the packet is lost as on a bad link.
            self.stats.drop("SendPacket")
            self.log.error(
                "radio: cannot send to %s: %s",
                command.destination,
                exc,
                extra=LogEvent.RADIO_FAILED.extra,
            )

    def _payload_command(self, command: PayloadCommand, now: float) -> None:
        adapter = self.payloads.get(command.payload)
        if adapter is None:
            self.stats.drop("PayloadCommand")
            answer = PayloadEvent(
                command.payload, "error", command.request_id, "payload disabled (testing mode)"
            )
            self._carry_out(self.runtime.deliver(answer, now), now)
            return
        adapter.send(command)  # never raises; an undeliverable command is answered with an error

    def _to_autopilot(self, data: bytes, now: float) -> None:
        link = self.autopilot
        if not data or link is None or link.transport is None:
            return
        try:
            link.transport.send(data)
        except TransportError as exc:
            self._autopilot_failed(now, str(exc))

    # -- links ------------------------------------------------------------------------------

    def _register(self, what: str, fd: int | None, data: object) -> None:
        self._unregister(what)
        if fd is None:
            return
        self.selector.register(fd, selectors.EVENT_READ, data)
        self._registered[what] = fd

    def _unregister(self, what: str) -> None:
        fd = self._registered.pop(what, None)
        if fd is not None:
            with contextlib.suppress(KeyError, ValueError, OSError):
                self.selector.unregister(fd)

    def _open_links(self, now: float) -> None:
        for name, adapter in self.payloads.items():
            self._register(f"payload:{name}", adapter.fileno(), ("payload", name))
        radio = self.radio
        if radio is not None:
            if radio.radio is not None:  # opened by the caller, to report its failure at once
                self._register("radio", radio.radio.fileno(), "radio")
            else:
                self._open_radio(now, first=True)
        if self.autopilot is not None:
            self._open_autopilot(now, first=True)

    def _next_retry_s(self) -> float | None:
        due = [
            link.reopen.next_s
            for link in (self.autopilot, self.radio)
            if link is not None and link.reopen.failures and not self._is_open(link)
        ]
        return min(due) if due else None

    @staticmethod
    def _is_open(link: AutopilotLink | RadioLink) -> bool:
        if isinstance(link, AutopilotLink):
            return link.transport is not None
        return link.radio is not None

    def _retry_links(self, now: float) -> None:
        if self._closing:
            return
        link = self.autopilot
        if link is not None and link.transport is None and now >= link.reopen.next_s:
            self._open_autopilot(now, first=False)
        radio = self.radio
        if radio is not None and radio.radio is None and now >= radio.reopen.next_s:
            self._open_radio(now, first=False)

    def _open_autopilot(self, now: float, *, first: bool) -> None:
        link = self.autopilot
        assert link is not None
        try:
            transport = link.open_transport()
        except (TransportError, OSError) as exc:
            self._autopilot_failed(now, str(exc))
            return
        link.transport = transport
        self._register("autopilot", transport.fileno(), "autopilot")
        if link.reopen.failures:
            self.stats.autopilot_reopens += 1
            self.log.warning(
                "autopilot: %s open again after %d failed attempt(s)",
                link.describe,
                link.reopen.failures,
                extra=LogEvent.AUTOPILOT_LINK.extra,
            )
        link.reopen.succeeded()
        if not link.started:
            link.started = True
            self._to_autopilot(link.adapter.start(now), now)
        else:
            self._to_autopilot(link.adapter.poll(now), now)

    def _autopilot_failed(self, now: float, error: str) -> None:
        link = self.autopilot
        assert link is not None
        self._unregister("autopilot")
        if link.transport is not None:
            with contextlib.suppress(TransportError, OSError):
                link.transport.close()
            link.transport = None
        self.stats.autopilot_failures += 1
        wait = link.reopen.failed(now, error)
        self.log.error(
            "autopilot: %s failed: %s; trying again in %.1f s",
            link.describe,
            error,
            wait,
            extra=LogEvent.AUTOPILOT_LINK.extra,
        )

    def _open_radio(self, now: float, *, first: bool) -> None:
        link = self.radio
        assert link is not None
        try:
            radio = link.open_radio()
        except (RadioError, OSError) as exc:
            self._radio_failed(now, str(exc))
            return
        link.radio = radio
        self._register("radio", radio.fileno(), "radio")
        if link.reopen.failures:
            self.stats.radio_reopens += 1
            self.log.warning(
                "radio: %s open again after %d failed attempt(s)",
                link.describe,
                link.reopen.failures,
                extra=LogEvent.RADIO_OPEN.extra,
            )
        link.reopen.succeeded()
        self.log.info(
            "radio: %s open, address %s", radio.name, radio.address, extra=LogEvent.RADIO_OPEN.extra
        )

    def _radio_link_event(self, radio: Radio, event: LinkEvent, now: float) -> None:
        """One line in the interface log for a loss or a return the radio handled itself.

        The radio reconnects on its own (an XBee's supervisor); the shell counts it
        with the reopens it does itself, so the summary's figures hold both.
        """
        # The event's monotonic time in the runtime's time base: how long ago, from now.
        at_s = now - max(0.0, time.monotonic() - event.monotonic_s)
        if event.up:
            self.stats.radio_reopens += 1
            self.log.warning(
                "radio: %s link back at t=%.3f %s",
                radio.name,
                at_s,
                event.detail,
                extra=LogEvent.RADIO_LINK.extra,
            )
        else:
            self.stats.radio_failures += 1
            self.log.error(
                "radio: %s link lost at t=%.3f: %s",
                radio.name,
                at_s,
                event.detail,
                extra=LogEvent.RADIO_LINK.extra,
            )

    def _radio_failed(self, now: float, error: str) -> None:
        link = self.radio
        assert link is not None
        self._unregister("radio")
        if link.radio is not None:
            with contextlib.suppress(RadioError, OSError):
                link.radio.close()
            link.radio = None
        self.stats.radio_failures += 1
        wait = link.reopen.failed(now, error)
        self.log.error(
            "radio: %s failed: %s; trying again in %.1f s",
            link.describe,
            error,
            wait,
            extra=LogEvent.RADIO_FAILED.extra,
        )

    def summary(self) -> str:
        """The loop's figures in one line (for the logs and the end of ``clark run``)."""
        s = self.stats
        return (
            f"{s.ticks} ticks at {self.loop_hz:g} Hz, {s.overruns} overrun(s) "
            f"({s.skipped_ticks} deadline(s) skipped, worst {s.worst_overrun_s * 1000:.1f} ms), "
            f"max lateness {s.max_late_s * 1000:.1f} ms, "
            f"ticks {s.tick_s / max(s.ticks, 1) * 1000:.2f} ms on average, "
            f"longest {s.max_tick_s * 1000:.1f} ms, "
            f"autopilot reopened {s.autopilot_reopens}, radio reopened {s.radio_reopens}"
        )


#: The real-time shell's dispatch: command type -> how it is carried out. Checked against
#: every command type when this module loads, so none can be added without an entry here.
_CARRY_OUT: dict[type, Callable[[RealtimeShell, Any, float], None]] = {
    **dict.fromkeys(AUTOPILOT_COMMANDS, RealtimeShell._autopilot_command),
    SendPacket: RealtimeShell._send_packet,
    PayloadCommand: RealtimeShell._payload_command,
    CloseInterfaces: RealtimeShell._close_command,
}
check_dispatch(_CARRY_OUT, "the real-time shell")
