"""The station view wired to the loop that runs the station (``clark run --view``, a rehearsal).

The loop is single-threaded and never waits for the web; the server
(:class:`~clark_engine.station.server.ViewServer`) runs on its own thread. They meet here,
through a small host interface (:class:`ViewHost`: ``runtime``, ``period_s``,
``on_tick``, ``add_reader``, ``remove_reader``, ``deliver``). ``clark run``'s
:class:`~clark_engine.shells.realtime.RealtimeShell` is such a host as it is; a
rehearsal's is the dry run's station agent (:mod:`clark_engine.station.rehearsal_view`).

- :class:`CommandInbox`: the server's thread puts each checked command in a bounded
  queue and writes one byte to a pipe; the host watches the pipe's read end
  (``add_reader``: a real-time shell wakes at once, a rehearsal looks at every tick of
  the station), drains the queue and carries each command out with ``deliver`` on its
  own thread.
- :class:`StationViewLink`: after every tick (``on_tick``) the view takes what arrived
  (track points, photos, answers to commands); at the view's update rate (and at once
  after a command) it builds a snapshot and publishes it to the server, which never
  blocks the loop (newest wins).

:func:`view_settings` reads ``clark run``'s ``--view`` options (usage errors before
anything opens; :func:`settings_from_options` is the part a rehearsal shares),
:func:`fleet_configs` finds every agent's config for the plan, and :func:`open_view`
starts the server before the agent's links open, so a port in use ends the run before
the radio is touched.
"""

from __future__ import annotations

import contextlib
import math
import os
import queue
from collections.abc import Callable, Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Final, Protocol

from clark_engine.errors import ClarkError, UsageError
from clark_engine.runtime.config import AgentConfig, load_config
from clark_engine.runtime.events import StationCommand
from clark_engine.runtime.log_events import LogEvent
from clark_engine.runtime.runtime import AgentRuntime
from clark_engine.station.access import check_token, is_loopback_host, parse_view_address
from clark_engine.station.server import ViewServer
from clark_engine.station.view_commands import CommandRequest
from clark_engine.station.view_hello import build_hello
from clark_engine.station.view_log import MissionLogBuffer
from clark_engine.station.view_model import StationView
from clark_engine.station.view_protocol import Json

DEFAULT_UPDATE_HZ: Final = 5.0
"""How often the page is sent the state, unless ``--view-hz`` says otherwise."""

MAX_WAITING_COMMANDS: Final = 64
"""Commands waiting for the loop at most; more are refused (the station is busy)."""


@dataclass(frozen=True, slots=True)
class ViewSettings:
    """Where and how the station view is served.

    Attributes:
        host: The bind address.
        port: The port (0: a free one).
        token: The token every request must carry, or None (loopback only).
        update_hz: State updates per second (at most the loop's rate).
    """

    host: str
    port: int
    token: str | None
    update_hz: float


def load_token(path_text: str) -> str:
    """The token in a file: its first line, without surrounding whitespace.

    Raises:
        UsageError: The file cannot be read, or holds no usable token.
    """
    path = Path(path_text)
    try:
        text = path.read_text(encoding="utf-8")
    except (OSError, UnicodeDecodeError) as exc:
        reason = exc.strerror if isinstance(exc, OSError) and exc.strerror else exc
        raise UsageError(f"--view-token-file {path_text}: cannot read it ({reason})") from None
    lines = text.strip().splitlines()
    if not lines or not lines[0].strip():
        raise UsageError(f"--view-token-file {path_text}: the file is empty")
    return check_token(lines[0].strip())


def view_settings(
    view: str | None,
    token: str | None,
    token_file: str | None,
    update_hz: float | None,
    config: AgentConfig,
) -> ViewSettings | None:
    """``clark run``'s ``--view`` options checked; None when the view is not asked for.

    Raises:
        UsageError: The agent is not a station; a token option without ``--view``; both
            token options; a bad address or token; a non-loopback address without a
            token.
    """
    if view is None:
        if token is not None or token_file is not None or update_hz is not None:
            raise UsageError("--view-token, --view-token-file and --view-hz go with --view")
        return None
    if config.role != "mcs":
        raise UsageError(
            f"--view serves the station's view; {config.agent} is a vehicle: "
            "give --view to the station's clark run (role mcs)"
        )
    return settings_from_options(view, token, token_file, update_hz)


def settings_from_options(
    view: str, token: str | None, token_file: str | None, update_hz: float | None
) -> ViewSettings:
    """The view's address, token and rate checked, wherever the station runs.

    The rules every command that serves the view shares (``clark run --view``,
    ``clark dry-run --station``): one token option at most, a valid address, and a
    token whenever the address is not loopback (the view commands vehicles).

    Raises:
        UsageError: Both token options; a bad address or token; a non-loopback address
            without a token.
    """
    if token is not None and token_file is not None:
        raise UsageError("give --view-token or --view-token-file, not both")
    host, port = parse_view_address(view)
    secret = load_token(token_file) if token_file is not None else None
    if token is not None:
        secret = check_token(token)
    if secret is None and not is_loopback_host(host):
        raise UsageError(
            f"--view {view}: serving beyond this machine needs a token: add "
            "--view-token-file FILE (or --view-token TOKEN), or bind 127.0.0.1"
        )
    return ViewSettings(host, port, secret, update_hz or DEFAULT_UPDATE_HZ)


def fleet_configs(path_text: str, station: AgentConfig) -> tuple[dict[str, AgentConfig], str]:
    """Every agent's compiled config (for the airframes and the plan), and where from.

    From a mission file, each agent is compiled from it. From a station's compiled
    ``.json``, the peers' configs are the ``<peer>.json`` files beside it (where
    ``clark compile`` writes them) that belong to the same mission; those missing are
    named in the returned words and their plans are left out.
    """
    path = Path(path_text)
    if path.suffix != ".json":
        from clark_engine.mission.compiler import agent_config
        from clark_engine.runtime.config import config_from_dict
        from clark_engine.validation import validate_file

        mission = validate_file(path, path_text).mission
        if mission is None:  # load_agent validated it already; this is not expected
            return {}, ""
        configs = {
            name: config_from_dict(agent_config(mission, agent))
            for name, agent in mission.agents.items()
        }
        return configs, f"the mission {path.name}"
    configs = {station.agent: station}
    missing: list[str] = []
    for peer in station.peers:
        beside = path.parent / f"{peer.name}.json"
        try:
            config = load_config(beside)
        except ClarkError:
            missing.append(peer.name)
            continue
        if (config.mission_id, config.mission_name, config.agent) != (
            station.mission_id,
            station.mission_name,
            peer.name,
        ):
            missing.append(peer.name)
            continue
        configs[peer.name] = config
    source = f"the compiled configs beside {path.name}"
    if missing:
        source += f" (none for {', '.join(missing)})"
    return configs, source


class CommandInbox:
    """Commands from the server's thread to the station's loop: a queue and a wake-up pipe.

    Args:
        max_waiting: Commands that may wait for the loop; more are refused.
    """

    def __init__(self, max_waiting: int = MAX_WAITING_COMMANDS) -> None:
        self._queue: queue.Queue[CommandRequest] = queue.Queue(maxsize=max_waiting)
        self._read_fd, self._write_fd = os.pipe()
        os.set_blocking(self._read_fd, False)
        os.set_blocking(self._write_fd, False)
        self.closed = False

    def fileno(self) -> int:
        """The pipe's read end: readable when a command waits."""
        return self._read_fd

    def submit(self, request: CommandRequest) -> None:
        """Queue one command and wake the loop (any thread; never blocks).

        Raises:
            RuntimeError: The station has stopped, or too many commands wait.
        """
        if self.closed:
            raise RuntimeError("the station has stopped")
        try:
            self._queue.put_nowait(request)
        except queue.Full:
            raise RuntimeError("the station is busy; try again") from None
        with contextlib.suppress(BlockingIOError, OSError):  # a full pipe is awake already
            os.write(self._write_fd, b"\0")

    def drain(self) -> list[CommandRequest]:
        """Every command waiting, oldest first (the loop's thread)."""
        with contextlib.suppress(BlockingIOError, OSError):
            while os.read(self._read_fd, 4096):
                pass
        out: list[CommandRequest] = []
        while True:
            try:
                out.append(self._queue.get_nowait())
            except queue.Empty:
                return out

    def close(self) -> None:
        """Refuse further commands and close the pipe. Idempotent."""
        if self.closed:
            return
        self.closed = True
        for fd in (self._read_fd, self._write_fd):
            with contextlib.suppress(OSError):
                os.close(fd)


class ViewHost(Protocol):
    """What the view needs of the loop that runs the station, whichever loop it is.

    ``clark run``'s :class:`~clark_engine.shells.realtime.RealtimeShell` is one as it
    is; a rehearsal's is :class:`~clark_engine.station.rehearsal_view.RehearsalHost`, over the
    dry run's station agent. Everything is called on the loop's own thread.
    """

    @property
    def runtime(self) -> AgentRuntime:
        """The station's runtime: its fleet table, its clock, its logbook."""
        ...

    @property
    def period_s(self) -> float:
        """The station's loop period: the view updates at most once per tick."""
        ...

    @property
    def on_tick(self) -> list[Callable[[Any, float], None]]:
        """Hooks called after every tick of the station with (the host, the time)."""
        ...

    def add_reader(self, fd: int, callback: Callable[[float], None]) -> None:
        """Call ``callback(now_s)`` on the loop's thread when ``fd`` may be readable.

        A host may wake on it (a real-time shell's selector) or call ``callback`` at
        every tick (a rehearsal): the callback reads without blocking either way.
        """
        ...

    def remove_reader(self, fd: int) -> None:
        """Stop watching ``fd``."""
        ...

    def deliver(self, event: StationCommand, now_s: float) -> None:
        """Hand an operator's command to the station's runtime and carry out its answer."""
        ...


class StationViewLink:
    """The station's view fed from its loop and handed to the server.

    Args:
        host: The loop that runs the station (:class:`ViewHost`).
        view: The view's model over ``host.runtime``.
        server: The server (started or not); snapshots go to it.
        inbox: Where the server puts the page's commands.
        update_hz: Snapshots per second (one per tick at most).
    """

    def __init__(
        self,
        host: ViewHost,
        view: StationView,
        server: ViewServer,
        inbox: CommandInbox,
        *,
        update_hz: float = DEFAULT_UPDATE_HZ,
    ) -> None:
        if not update_hz > 0:
            raise ValueError(f"update_hz must be above 0, not {update_hz}")
        self.host = host
        self.view = view
        self.server = server
        self.inbox = inbox
        self.period_s = 1.0 / update_hz
        self.errors = 0
        """Exceptions caught in the view's hooks (logged once each kind; the loop goes on)."""
        self._next_s = -math.inf
        self._reported: set[str] = set()
        self._closed = False
        host.add_reader(inbox.fileno(), self._commands)
        host.on_tick.append(self._on_tick)

    def _failed(self, where: str, exc: Exception) -> None:
        """A fault of the view must never stop the station: count it, log it once."""
        self.errors += 1
        kind = f"{where}:{type(exc).__name__}"
        logbook = self.host.runtime.logbook
        if kind not in self._reported and not logbook.closed:
            self._reported.add(kind)
            logbook.interface.error(
                "station view: %s failed: %r", where, exc, extra=LogEvent.VIEW_FAILED.extra
            )

    def _on_tick(self, host: object, now_s: float) -> None:
        try:
            self.view.observe(now_s)
            # Due within half a tick: ticks and updates keep step despite the loop's jitter
            # (5 Hz on a 10 Hz loop is every other tick, not every third).
            if now_s >= self._next_s - 0.5 * self.host.period_s:
                behind = now_s - self._next_s >= self.period_s
                self._next_s = (now_s if behind else self._next_s) + self.period_s
                self.server.publish(self.view.snapshot(now_s))
        except Exception as exc:
            self._failed("update", exc)

    def _commands(self, now_s: float) -> None:
        """The pipe may be readable: carry out every command waiting, then publish at once."""
        requests = self.inbox.drain()
        if not requests:
            return
        for request in requests:
            try:
                self.view.execute(request, lambda c: self.host.deliver(c, now_s), now_s)
            except Exception as exc:
                self._failed("command", exc)
        self.publish(now_s)

    def publish(self, now_s: float) -> None:
        """Send a snapshot now, whatever the rate."""
        try:
            self.server.publish(self.view.snapshot(now_s))
        except Exception as exc:
            self._failed("update", exc)

    def close(self, now_s: float) -> None:
        """The last snapshot published; stop taking commands. Idempotent."""
        if self._closed:
            return
        self._closed = True
        self.publish(now_s)
        with contextlib.suppress(Exception):
            self.host.remove_reader(self.inbox.fileno())
        with contextlib.suppress(ValueError):
            self.host.on_tick.remove(self._on_tick)
        self.inbox.close()
        if self.view.log is not None:
            self.view.log.detach()


@dataclass
class OpenView:
    """A started server and what the link needs once the station's loop exists."""

    server: ViewServer
    inbox: CommandInbox
    hello: Json
    settings: ViewSettings

    def attach(self, host: ViewHost) -> StationViewLink:
        """Feed the server from ``host``: its mission log, its ticks, its commands."""
        log = MissionLogBuffer()
        log.attach(host.runtime.logbook.mission)
        view = StationView(host.runtime, self.hello, log=log)
        return StationViewLink(
            host, view, self.server, self.inbox, update_hz=self.settings.update_hz
        )

    def stop(self) -> None:
        """Stop the server (its clients are sent the last state) and the inbox."""
        self.inbox.close()
        self.server.stop()


def open_view(
    settings: ViewSettings,
    station: AgentConfig,
    fleet: Mapping[str, AgentConfig],
    plan_source: str,
) -> OpenView:
    """Start the server (it serves the page and hello at once; state once the loop runs).

    Raises:
        UsageError: The address cannot be served (a port in use...).
    """
    hello = build_hello(station, fleet, plan_source=plan_source, update_hz=settings.update_hz)
    inbox = CommandInbox()
    server = ViewServer(
        hello, inbox.submit, host=settings.host, port=settings.port, token=settings.token
    )
    try:
        server.start()
    except BaseException:
        inbox.close()
        raise
    return OpenView(server, inbox, hello, settings)


__all__ = [
    "DEFAULT_UPDATE_HZ",
    "CommandInbox",
    "OpenView",
    "StationViewLink",
    "ViewHost",
    "ViewSettings",
    "fleet_configs",
    "load_token",
    "open_view",
    "settings_from_options",
    "view_settings",
]
