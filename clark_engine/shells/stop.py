"""The real-time shell's stop: SIGINT and SIGTERM, and the clean stop that keeps the vehicle safe.

A mixin of :class:`~clark_engine.shells.realtime.RealtimeShell` (see its module docstring
for what the stop does and why): the signal handler, and :meth:`ShellStop.shutdown`'s
steps, each guarded so that one failing never skips the next, with the one wait a second
signal cuts short. A mixin, not a helper object the shell owns: the stop carries out the
runtime's terminate sequence through the shell's own routes, reads the autopilot through
its selector and closes every link it registered, so a helper would need all of the
shell's private state; it is kept apart because it is the shell's other mode (after the
loop, nothing read but the autopilot) and holds the safety steps a reviewer reads alone.
"""

from __future__ import annotations

import contextlib
import logging
import selectors
import signal
import socket
import threading
from collections.abc import Callable, Iterator
from types import FrameType
from typing import TYPE_CHECKING, Final

from clark_engine.io.payload import PayloadAdapter
from clark_engine.io.transports import TransportError
from clark_engine.runtime.commands import Command
from clark_engine.runtime.events import CommandRefused
from clark_engine.runtime.log_events import LogEvent
from clark_engine.runtime.runtime import AgentRuntime
from clark_engine.shells.links import AutopilotLink, RadioLink

STOP_CONFIRM_S: Final = 3.0
"""Longest a clean stop waits for the autopilot to answer the terminal mode and the
failsafe switched off: a command's three sends, ``ACK_TIMEOUT_S`` apart. Skipped by a
second signal; what it waits for has been sent at least once by then."""

STOP_ANNOUNCE_S: Final = 0.5
"""After this long without the autopilot's answers, the stop says on the terminal what it
waits for and that Ctrl-C again skips it (a quick answer is not worth a line)."""


class ShellStop:
    """The signals and the clean stop of :class:`~clark_engine.shells.realtime.RealtimeShell`."""

    if TYPE_CHECKING:
        # What the stop uses of the shell it is mixed into.
        runtime: AgentRuntime
        autopilot: AutopilotLink | None
        radio: RadioLink | None
        payloads: dict[str, PayloadAdapter]
        selector: selectors.BaseSelector
        log: logging.Logger
        stopped_by: str | None
        hurried_by: str | None
        skipped: list[str]
        announce: Callable[[str], None] | None
        _readers: dict[int, Callable[[float], None]]
        _registered: dict[str, int]
        _signals: int
        _in_stop: bool
        _closed: bool
        _wake_r: socket.socket
        _wake_w: socket.socket

        def now(self) -> float:
            """As :meth:`RealtimeShell.now`."""

        def stop(self, reason: str = "stop") -> None:
            """As :meth:`RealtimeShell.stop`."""

        def remove_reader(self, fd: int) -> None:
            """As :meth:`RealtimeShell.remove_reader`."""

        def summary(self) -> str:
            """As :meth:`RealtimeShell.summary`."""

        def _carry_out(self, commands: list[Command], now: float) -> None: ...
        def _to_autopilot(self, data: bytes, now: float) -> None: ...
        def _select(self, timeout_s: float) -> list[tuple[selectors.SelectorKey, int]]: ...
        def _autopilot_failed(self, now: float, error: str) -> None: ...
        def _unregister(self, what: str) -> None: ...

    def hurry(self, reason: str = "stop") -> None:
        """Shorten the stop: skip what only waits; safe from signal handlers and threads.

        The parts that keep the vehicle safe still run (:meth:`shutdown`). Before the
        stop began, it also stops the loop.
        """
        if self.hurried_by is None:
            self.hurried_by = reason
        self.stop(reason)

    @contextlib.contextmanager
    def signals(self) -> Iterator[None]:
        """Within the block, SIGINT and SIGTERM stop the loop; a second one shortens the stop.

        A first one that arrives once a stop began by itself (``--until``, a terminate)
        shortens it at once.

        The handler never raises: a signal may land anywhere, in the middle of the
        stop's safety steps too, and an exception there would skip the rest of them
        (the overrides left active, the replay marks unsaved). It only sets flags and
        wakes the loop. Does nothing outside the main thread (handlers belong to it).
        """
        if threading.current_thread() is not threading.main_thread():
            yield
            return
        previous = {sig: signal.getsignal(sig) for sig in (signal.SIGINT, signal.SIGTERM)}

        def handler(signum: int, frame: FrameType | None) -> None:
            self._signals += 1
            name = signal.Signals(signum).name
            if self._signals == 1 and not self._in_stop:
                self.stop(name)
            else:  # a second signal, or a first one once a stop (--until...) began
                self.hurry(name)

        for sig in previous:
            signal.signal(sig, handler)
        try:
            yield
        finally:
            for sig, old in previous.items():
                signal.signal(sig, old if old is not None else signal.SIG_DFL)

    # -- the end ----------------------------------------------------------------------------

    def shutdown(self) -> None:
        """The clean stop; idempotent. A second signal shortens it, never skips its safety.

        In order, each step guarded so that one failing never skips the next:

        1. The RC overrides released and every pending request forgotten (the stick back
           to the pilot at once; nothing the behaviour asked for is sent again).
        2. The runtime's terminate sequence: its primitives stopped, the vehicle to its
           terminal mode, a last heartbeat to the peers.
        3. The failsafe the safety set-up switched on switched off (leaving on purpose).
        4. Waiting for the autopilot to answer 2 and 3 (resent meanwhile), at most
           :data:`STOP_CONFIRM_S`: the only part a second signal skips.
        5. The replay marks saved (the counter store needs nothing: it is written
           before a counter is used).
        6. Every link closed, then the logs flushed and closed.
        """
        if self._closed:
            return
        runtime = self.runtime
        link = self.autopilot
        self._in_stop = True
        self._stop_listening()
        done: list[str] = []
        if not runtime.terminated:
            self._safely("log the loop's figures", self._log_summary)
        self.log.info("stop began (%s)", self.stopped_by or "stop", extra=LogEvent.SHELL_STOP.extra)
        if link is not None and link.transport is not None and not runtime.terminated:
            # (A runtime terminated in the loop already sent its terminal mode: kept.)
            self._safely(
                "release the RC overrides",
                lambda: self._to_autopilot(link.adapter.stop_commanding(self.now()), self.now()),
            )
        if self._safely("run the terminate sequence", self._terminate):
            done.append("terminate sequence run (terminal mode, last heartbeat)")
        if link is not None and link.transport is not None:
            closed = self._safely(
                "close the autopilot's session",
                lambda: self._to_autopilot(link.adapter.close(self.now()), self.now()),
            )
            if closed:
                done.append("RC overrides released")
                names = link.adapter.left_on_purpose
                done.extend([f"failsafe off ({', '.join(names)})"] if names else [])
        self._safely("wait for the autopilot's answers", self._await_answers)
        saved = self._safely("save the replay marks", self._save_replay_marks)
        done.extend(["replay marks saved"] if saved and runtime.codec.authenticated else [])
        if self.hurried_by is not None:
            skipped = "; ".join(self.skipped) or "nothing (nothing was left to wait for)"
            which = "a second " if self._signals > 1 else ""
            line = (
                f"stop shortened by {which}{self.hurried_by}: skipped {skipped}; "
                f"still done: {', '.join([*done, 'links closed'])}"
            )
            self._safely(
                "log the shortened stop",
                lambda: self.log.warning("%s", line, extra=LogEvent.SHELL_STOP.extra),
            )
            self._safely("announce the shortened stop", lambda: self._say(line))
        self._close_all()

    def _log_summary(self) -> None:
        self.runtime.logbook.interface.info(
            "real-time shell: %s", self.summary(), extra=LogEvent.SHELL_SUMMARY.extra
        )

    def _terminate(self) -> None:
        now = self.now()
        reason = f"real-time shell stopping ({self.stopped_by or 'stop'})"
        self._carry_out(self.runtime.terminate(now, reason), now)

    def _safely(self, what: str, step: Callable[[], None]) -> bool:
        """Run one step of the stop; its failure is logged and the stop goes on.

        Returns:
            True when the step ran to its end.
        """
        try:
            self.runtime.note_time(self.now())
            step()
        except Exception as exc:
            with contextlib.suppress(Exception):
                self.log.error("stop: cannot %s: %s", what, exc, extra=LogEvent.SHELL_STOP.extra)
            return False
        return True

    def _say(self, line: str) -> None:
        if self.announce is not None:
            self.announce(line)

    def _stop_listening(self) -> None:
        """Unwatch everything but the autopilot and the wake-up: the stop reads nothing else."""
        for what in list(self._registered):
            if what != "autopilot":
                self._unregister(what)
        for fd in list(self._readers):
            self.remove_reader(fd)

    def _await_answers(self) -> None:
        """Step 4 of :meth:`shutdown`: the autopilot's answers, until a second signal."""
        link = self.autopilot
        if link is None or link.transport is None or not link.adapter.unanswered:
            return
        what = ", ".join(link.adapter.unanswered)
        if self.hurried_by is not None:
            self.skipped.append(f"waiting for the autopilot to answer {what}")
            return
        begin = self.now()
        deadline = begin + STOP_CONFIRM_S
        self.log.info(
            "stop: waiting up to %g s for the autopilot to answer %s",
            STOP_CONFIRM_S,
            what,
            extra=LogEvent.SHELL_STOP.extra,
        )
        announced = False
        while True:
            now = self.now()
            self.runtime.note_time(now)
            if link.transport is None:  # failed while waiting (logged): nobody to wait for
                return
            left = link.adapter.unanswered
            if not left:
                self.log.info(
                    "stop: the autopilot answered in %.3f s",
                    now - begin,
                    extra=LogEvent.SHELL_STOP.extra,
                )
                return
            if not announced and now - begin >= STOP_ANNOUNCE_S:
                announced = True  # a person waiting longer than a blink is told why
                self._say(
                    f"stopping: waiting up to {STOP_CONFIRM_S:g} s for the autopilot to answer "
                    f"{', '.join(left)}; Ctrl-C again skips the wait"
                )
            if self.hurried_by is not None:
                self.skipped.append(f"waiting for the autopilot to answer {', '.join(left)}")
                return
            if now >= deadline:
                self.log.warning(
                    "stop: no answer from the autopilot to %s within %g s",
                    ", ".join(left),
                    STOP_CONFIRM_S,
                    extra=LogEvent.SHELL_STOP.extra,
                )
                return
            wake = deadline if announced else min(deadline, begin + STOP_ANNOUNCE_S)
            self._listen_to_autopilot(min(wake - now, 0.1))

    def _listen_to_autopilot(self, timeout_s: float) -> None:
        """Wait for the autopilot's bytes (or a signal) and hear its answers; resend due."""
        link = self.autopilot
        assert link is not None
        ready = self._select(timeout_s)
        now = self.now()
        for key, _mask in ready:
            if key.data == "wake":
                with contextlib.suppress(OSError):
                    self._wake_r.recv(4096)
        if link.transport is None:
            return
        try:
            data = link.transport.receive()
        except TransportError as exc:
            self._autopilot_failed(now, str(exc))
            return
        for event in link.adapter.receive(data, now) if data else []:
            if isinstance(event, CommandRefused):
                self.log.warning(
                    "stop: the autopilot refused %s: %s",
                    event.request,
                    event.result,
                    extra=LogEvent.SHELL_STOP.extra,
                )
        self._to_autopilot(link.adapter.flush(), now)
        self._to_autopilot(link.adapter.poll(now), now)

    def _save_replay_marks(self) -> None:
        self.runtime.codec.save_replay_marks()
        if self.runtime.codec.authenticated:
            self.log.info("stop: replay marks saved", extra=LogEvent.SHELL_STOP.extra)

    def _close_all(self) -> None:
        """Every link closed (each failure logged, never stopping the rest), then the logs."""
        if self._closed:
            return
        self._closed = True
        closed: list[str] = []
        link = self.autopilot
        if link is not None and link.transport is not None:
            self._safely("close the autopilot link", link.transport.close)
            link.transport = None
            closed.append("autopilot")
        radio = self.radio
        if radio is not None and radio.radio is not None:
            self._safely("close the radio", radio.radio.close)
            radio.radio = None
            closed.append("radio")
        for name, adapter in self.payloads.items():
            self._safely(f"close the payload {name}", adapter.close)
            closed.append(f"payload {name}")
        for what in list(self._registered):
            self._unregister(what)
        for fd in list(self._readers):
            self.remove_reader(fd)
        with contextlib.suppress(KeyError, ValueError):
            self.selector.unregister(self._wake_r)
        self._safely("close the selector", self.selector.close)
        self._wake_r.close()
        self._wake_w.close()
        self._safely(
            "log the links closed",
            lambda: self.log.info(
                "stop: links closed (%s)",
                ", ".join(closed) or "none open",
                extra=LogEvent.SHELL_STOP.extra,
            ),
        )
        self._safely("close the logs", self.runtime.logbook.close)
