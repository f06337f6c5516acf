"""The station view's web server: aiohttp on its own thread and event loop.

The station's real-time loop is single-threaded and must never wait for the web
(DESIGN.md, "The runtime loop"), so the server runs apart, on a thread of its own with
its own :mod:`asyncio` loop, and the two meet at two points only:

- **snapshots in** (:meth:`ViewServer.publish`, called on the loop's thread): the newest
  snapshot replaces the previous one in a slot under a lock, its new track points,
  photos and log lines are added to bounded lists, and the server's loop is woken with
  :meth:`asyncio.AbstractEventLoop.call_soon_threadsafe` (once per batch, never once
  per snapshot while a wake-up is pending). Nothing waits.
- **commands out** (the ``on_command`` callback, called on the server's thread): every
  command the page sends is checked here (every string from a browser is hostile:
  bounded, known agents and modes only) and handed on as a
  :class:`~clark_engine.station.view_model.CommandRequest`; :mod:`clark_engine.station.live_view`
  queues it for the loop and wakes the loop through a pipe.

Each WebSocket client has one sender task that sends ``hello``, then the newest state
whenever there is a newer one: a slow client skips the states it had no time for
rather than queueing them (newest wins), and is sent the track points, photos and log
lines it has not had yet (each has a sequence number) from bounded histories
(:data:`MAX_TRACK_POINTS`, :data:`MAX_PHOTOS`, :data:`MAX_LOG_LINES`).

In replay mode (``clark replay``, :mod:`clark_engine.station.replay`) the server is given a
:class:`ReplaySource` instead of snapshots: each client has its own time, which its page
moves with ``seek``, ``play``, ``pause`` and ``speed`` messages (:func:`parse_replay_control`);
its sender sends what the source builds for that time (a ``reset`` when the page jumps,
then ``state`` messages, at the update rate while it plays). Commands are refused.

Security (docs/station-view.md, "Security"):

- It binds 127.0.0.1 by default. A token is required whenever the bind address is not
  loopback: :class:`ViewServer` refuses to start without one (a usage error, exit 2).
- With a token, every request (the page, the static files, the WebSocket) must carry it:
  ``?token=`` once (the page's URL; the server answers with a cookie for this port and
  redirects to the URL without the token), then the cookie, or an ``X-Clark-Token``
  header or ``Authorization: Bearer``. Anything else gets 403. Tokens are compared in
  constant time.
- On a loopback bind the ``Host`` header must name the loopback address and port
  served (``127.0.0.1:P``, ``localhost:P``, ``[::1]:P``): a page of another site whose
  name was made to resolve to 127.0.0.1 (DNS rebinding) is refused.
- The WebSocket's ``Origin``, when a browser sends one, must be this server's own
  (``http://`` + the request's ``Host``), so a page of another site cannot open the
  WebSocket with the operator's cookie (cross-site WebSocket hijacking). Clients that
  are not browsers send no Origin and pass this check (they still need the token).
- The page is served with a strict Content-Security-Policy (its own scripts and styles
  only), ``X-Frame-Options: DENY``, ``nosniff`` and ``Referrer-Policy: no-referrer``.
- Connections are bounded (docs/station-view.md, "Connections and floods"): asyncio
  accepts, :class:`_Admitted` admits each under :class:`ViewLimits` (per address, in
  all: below the file limit, :func:`view_limits`) before aiohttp sees it; a connection
  must pass the checks above within :data:`HEADER_TIMEOUT_S` (until then it may be
  closed to make room for a newer one, oldest first), a served one idle for
  :data:`IDLE_TIMEOUT_S` is closed; floods of errors (accept() out of descriptors,
  aiohttp's bad requests) are one counted line per :data:`LOG_INTERVAL_S`.
"""

from __future__ import annotations

import asyncio
import contextlib
import errno
import hmac
import ipaddress
import itertools
import json
import logging
import math
import resource
import socket
import threading
import time
from collections import OrderedDict, deque
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Final, Protocol
from urllib.parse import quote

from aiohttp import WSMsgType, web
from aiohttp.typedefs import Handler

from clark_engine.errors import UsageError
from clark_engine.station.view_model import (
    ACTIONS,
    MAX_LOG_LINES,
    CommandRequest,
    Json,
    Snapshot,
    agent_names,
    modes_of,
)
from clark_engine.untrusted import printable

STATIC_DIR: Final = Path(__file__).resolve().parent / "static"
"""The page, its script and style, and the vendored Leaflet."""

DEFAULT_PORT: Final = 8080
"""The port a :class:`ViewServer` serves when none is given."""

MAX_TRACK_POINTS: Final = 20_000
"""Track points kept for clients that connect later (all agents together)."""

MAX_PHOTOS: Final = 2_000
"""Photo positions kept for clients that connect later."""

MAX_MESSAGE_BYTES: Final = 16 * 1024
"""Largest WebSocket message accepted from a page; a larger one closes its connection."""

MAX_NAME_CHARS: Final = 64
"""Longest agent or mode name accepted in a command."""

MAX_OPERATOR_CHARS: Final = 40
"""Longest operator name kept (escaped, then cut)."""

MAX_REF_CHARS: Final = 32
"""Longest ``ref`` a page may attach to a command (echoed in the answer)."""

MAX_CLIENTS: Final = 32
"""WebSocket clients served at once; more are closed at once (code 1013)."""

COMMANDS_PER_S: Final = 5.0
"""Sustained commands a client may send; a burst of :data:`COMMAND_BURST` is allowed."""

COMMAND_BURST: Final = 10

MIN_TOKEN_CHARS: Final = 16
"""Shortest token accepted: a token is a secret, not a password to remember."""

MAX_TOKEN_CHARS: Final = 256

TOKEN_HEADER: Final = "X-Clark-Token"

CONTROLS_PER_S: Final = 20.0
"""Sustained replay controls (seek, play, pause, speed) a client may send; bursts of
:data:`CONTROLS_BURST` (a dragged slider sends a few a second)."""

CONTROLS_BURST: Final = 40

REPLAY_ACTIONS: Final = ("seek", "play", "pause", "speed")
"""What a replay's page may send."""

STOP_FLUSH_S: Final = 1.0
"""How long the server, when it stops, gives its clients to receive the last state."""

HEADER_TIMEOUT_S: Final = 10.0
"""A new connection must send a whole request that passes the view's checks (its token,
its Host) within this time, or it is closed: the slowloris guard. A browser sends its
request within milliseconds of connecting."""

IDLE_TIMEOUT_S: Final = 30.0
"""A connection that has been served and then sends no new request for this long is
closed (aiohttp's ``keepalive_timeout``); a WebSocket is not idle (its own heartbeat
closes a dead one)."""

MAX_CONNECTIONS_CEILING: Final = 1024
"""The most connections served at once, however high the file limit: a station view
has a handful of users."""

MAX_PER_ADDRESS_CEILING: Final = 32
"""The most connections one client address (an IPv6 client's /64) holds at once: a
browser opens six per server and a WebSocket; a few tabs fit."""

RESERVED_FILES: Final = 128
"""File descriptors always left to the rest of the engine (logs, radios, serial ports,
the autopilot's link) whatever the view holds: at least this, or a quarter of the
limit."""

LOG_INTERVAL_S: Final = 10.0
"""At most one line per kind of trouble (connections shed, accept failures, errors of
aiohttp or asyncio) per this interval; the others are counted into the next line."""

ACCEPT_RETRY_S: Final = 0.5
"""After accept() fails for want of a file descriptor, how long the view waits before
accepting again (the pending connections wait in the kernel's backlog)."""

LISTEN_BACKLOG: Final = 128

_NO_RESOURCE: Final = frozenset({errno.EMFILE, errno.ENFILE, errno.ENOBUFS, errno.ENOMEM})

_LOG = logging.getLogger(__name__)


@dataclass(frozen=True)
class ViewLimits:
    """How many connections the view holds, and for how long (docs/station-view.md).

    Left as None, the connection caps are derived from the process's file limit by
    :func:`view_limits` when the server starts.
    """

    header_timeout_s: float = HEADER_TIMEOUT_S
    """Time a new connection has to send a request that passes the checks."""
    idle_timeout_s: float = IDLE_TIMEOUT_S
    """Time a served connection may stay silent before it is closed."""
    max_connections: int | None = None
    """Connections held at once, in all."""
    max_per_address: int | None = None
    """Connections held at once from one client address (one IPv6 /64)."""
    log_interval_s: float = LOG_INTERVAL_S
    """At most one line per kind of trouble per this interval."""


def view_limits(limits: ViewLimits, nofile: int | None = None) -> ViewLimits:
    """``limits`` with its connection caps filled in and kept below the file limit.

    ``nofile`` is the process's soft ``RLIMIT_NOFILE`` (read when None). The engine keeps
    ``max(RESERVED_FILES, nofile // 4)`` descriptors for its own files and sockets; of
    the rest, each view connection may take two at once (its socket, and a static file
    while aiohttp sends it), so at most half the rest are connections, and never more
    than :data:`MAX_CONNECTIONS_CEILING`. One address may hold an eighth of them, at
    most :data:`MAX_PER_ADDRESS_CEILING`, at least 2, so that no one address (an
    attacker's) can take every place. Caps given in ``limits`` are kept when below
    these.
    """
    if nofile is None:
        nofile = resource.getrlimit(resource.RLIMIT_NOFILE)[0]
    if nofile == resource.RLIM_INFINITY or nofile <= 0:
        nofile = 65536
    reserve = max(RESERVED_FILES, nofile // 4)
    ceiling = max(4, min(MAX_CONNECTIONS_CEILING, (nofile - reserve) // 2))
    total = min(ceiling, limits.max_connections or ceiling)
    per_address = max(2, min(MAX_PER_ADDRESS_CEILING, total // 8))
    if limits.max_per_address is not None:
        per_address = limits.max_per_address
    per_address = max(1, min(per_address, total))
    return ViewLimits(
        header_timeout_s=limits.header_timeout_s,
        idle_timeout_s=limits.idle_timeout_s,
        max_connections=total,
        max_per_address=per_address,
        log_interval_s=limits.log_interval_s,
    )


def client_key(address: str) -> str:
    """The key a client's connections are counted under, for the per-address cap.

    Its IPv4 address; an IPv6 client's /64 (one host is commonly given a whole /64, so
    counting single IPv6 addresses would give an attacker billions of places); an
    IPv4-mapped IPv6 address as its IPv4 address.
    """
    try:
        ip = ipaddress.ip_address(address.split("%", 1)[0])
    except ValueError:
        return address
    if isinstance(ip, ipaddress.IPv6Address):
        if ip.ipv4_mapped is not None:
            return str(ip.ipv4_mapped)
        if not ip.is_loopback:
            return str(ipaddress.ip_network(f"{ip}/64", strict=False))
    return str(ip)


class _Throttle:
    """Log lines that may come in floods: one per kind per interval, the rest counted.

    ``note`` logs at once when its kind has been quiet for the interval, else counts;
    the count goes out with the next line of that kind (or :meth:`flush`), so a flood of
    a thousand accept failures a second is one line every ``interval_s``.
    """

    def __init__(self, logger: logging.Logger, interval_s: float) -> None:
        self.logger = logger
        self.interval_s = interval_s
        self._last_s: dict[str, float] = {}
        self._counts: dict[str, int] = {}
        self._texts: dict[str, str] = {}
        self.total: dict[str, int] = {}

    def admit(self, kind: str) -> int | None:
        """Count one of ``kind``; the number to report when a line may go out now, or None."""
        self.total[kind] = self.total.get(kind, 0) + 1
        self._counts[kind] = self._counts.get(kind, 0) + 1
        now = time.monotonic()
        last = self._last_s.get(kind)
        if last is not None and now - last < self.interval_s:
            return None
        self._last_s[kind] = now
        return self._counts.pop(kind)

    def remember(self, kind: str, text: str) -> None:
        """The line (a %-format with one ``%d``) :meth:`flush` writes for ``kind``."""
        self._texts[kind] = text

    def note(self, kind: str, text: str, level: int = logging.WARNING) -> None:
        """Log ``text`` (a %-format with one ``%d`` for the count) when its kind may."""
        self._texts[kind] = text
        count = self.admit(kind)
        if count is not None:
            self.logger.log(level, text, count)

    def flush(self) -> None:
        """Log what was counted and not yet reported (when the server stops)."""
        for kind, count in list(self._counts.items()):
            text = self._texts.get(kind)
            if count and text is not None:
                self.logger.warning(text, count)
        self._counts.clear()


class _ThrottledLogger(logging.LoggerAdapter):  # type: ignore[type-arg]
    """aiohttp's server logger, one record per message per interval, counted.

    aiohttp logs each bad request ("Error handling request", with a traceback) and
    each error of its own; from anyone who reaches the port, that is a flood. The first
    of a kind keeps its traceback; later ones go out once per interval as one line with
    their count. Debug records pass (they are off unless asked for).
    """

    def __init__(self, logger: logging.Logger, throttle: _Throttle) -> None:
        super().__init__(logger, {})
        self.throttle = throttle

    def log(self, level: int, msg: object, *args: Any, **kwargs: Any) -> None:
        if level < logging.WARNING:
            self.logger.log(level, msg, *args, **kwargs)
            return
        kind = f"aiohttp:{msg}"
        first = kind not in self.throttle.total
        self.throttle.remember(
            kind, f"station view: %d more of aiohttp's {msg!s}".replace("%s", "...")
        )
        count = self.throttle.admit(kind)
        if count is None:
            return
        if not first:
            kwargs.pop("exc_info", None)
            kwargs.pop("stack_info", None)
            msg = f"{msg} (%d like it in the last {self.throttle.interval_s:g} s)"
            args = (*args, count)
        self.logger.log(level, msg, *args, **kwargs)


def is_loopback_host(host: str) -> bool:
    """True for ``localhost`` and the loopback addresses (127.0.0.0/8, ::1)."""
    if host.lower() == "localhost":
        return True
    try:
        return ipaddress.ip_address(host.strip("[]")).is_loopback
    except ValueError:
        return False


def parse_view_address(text: str) -> tuple[str, int]:
    """``[HOST:]PORT`` (``8080``, ``127.0.0.1:8080``, ``0.0.0.0:8080``, ``[::1]:8080``).

    Raises:
        UsageError: Not of that form, or a port outside 0-65535 (0 picks a free one).
    """
    host, sep, port_text = text.rpartition(":")
    if not sep:
        host, port_text = "127.0.0.1", text
    host = host.strip()
    if host.startswith("[") and host.endswith("]"):
        host = host[1:-1]
    if not host:
        raise UsageError(f"--view {text!r}: give [HOST:]PORT, e.g. 8080 or 127.0.0.1:8080")
    try:
        port = int(port_text)
    except ValueError:
        raise UsageError(
            f"--view {text!r}: the port must be a number (e.g. 8080; 0 picks a free one)"
        ) from None
    if not 0 <= port <= 65535:
        raise UsageError(f"--view {text!r}: the port must be within 0-65535")
    return host, port


def check_token(token: str) -> str:
    """The token, when it is usable: printable ASCII without spaces, 16-256 characters.

    Raises:
        UsageError: It is not.
    """
    if not MIN_TOKEN_CHARS <= len(token) <= MAX_TOKEN_CHARS:
        raise UsageError(
            f"the view token must be {MIN_TOKEN_CHARS}-{MAX_TOKEN_CHARS} characters long "
            "(e.g. from `python -c 'import secrets; print(secrets.token_urlsafe(24))'`)"
        )
    if not all(33 <= ord(c) <= 126 for c in token):
        raise UsageError("the view token must be printable ASCII without spaces")
    return token


@dataclass
class _Bucket:
    """A token bucket: ``rate_per_s`` messages a second, bursts of ``burst``."""

    rate_per_s: float
    burst: float
    tokens: float = -1.0
    refilled_s: float = field(default_factory=time.monotonic)

    def allow(self) -> bool:
        now = time.monotonic()
        if self.tokens < 0:
            self.tokens = self.burst
        self.tokens = min(self.burst, self.tokens + (now - self.refilled_s) * self.rate_per_s)
        self.refilled_s = now
        if self.tokens < 1.0:
            return False
        self.tokens -= 1.0
        return True


@dataclass(eq=False)
class _Client:
    """One WebSocket client: what it has been sent, and its sender's wake-up.

    In replay mode, also its own time (``replay_t``), whether it plays and how fast, and
    the time up to which it has every track point, photo and log line (``sent_t``, None
    before its first reset).
    """

    ws: web.WebSocketResponse
    address: str
    wake: asyncio.Event = field(default_factory=asyncio.Event)
    replies: deque[str] = field(default_factory=lambda: deque(maxlen=64))
    version: int = 0
    track_seq: int = 0
    photo_seq: int = 0
    log_seq: int = 0
    commands: _Bucket = field(default_factory=lambda: _Bucket(COMMANDS_PER_S, COMMAND_BURST))
    controls: _Bucket = field(default_factory=lambda: _Bucket(CONTROLS_PER_S, CONTROLS_BURST))
    replay_t: float = 0.0
    sent_t: float | None = None
    playing: bool = False
    speed: float = 1.0
    moved: bool = True

    def allow_command(self) -> bool:
        """Whether one more command fits this client's rate (:data:`COMMANDS_PER_S`)."""
        return self.commands.allow()


_FULL_RESPONSE: Final = (
    b"HTTP/1.1 503 Service Unavailable\r\nContent-Type: text/plain\r\n"
    b"Content-Length: 47\r\nConnection: close\r\nRetry-After: 5\r\n\r\n"
    b"503: the station view holds all it can; retry\n"
)
"""What a connection the view has no room for is sent before it is closed."""


@dataclass(eq=False)
class _Connection:
    """One TCP connection the view holds, for its caps and its header timeout.

    It is *proven* once a request on it has passed the view's checks (the token when
    there is one, the Host on loopback); until then it may be closed to make room for a
    newer one, oldest first, and is closed when :data:`HEADER_TIMEOUT_S` runs out.
    """

    key: str
    transport: asyncio.BaseTransport
    proven: bool = False
    closed: bool = False
    timer: asyncio.TimerHandle | None = None


class _Admitted(asyncio.Protocol):
    """A connection's protocol: admitted under the view's limits, then aiohttp's.

    asyncio accepts each connection and calls :meth:`connection_made`; there the view
    decides whether it has room (:meth:`ViewServer._admit`). A connection admitted is
    handed to aiohttp's request handler, which sees every call after; one refused is
    sent a 503 and closed, and aiohttp never learns of it.
    """

    def __init__(self, server: ViewServer, handler_factory: Callable[[], asyncio.Protocol]):
        self._server = server
        self._factory = handler_factory
        self._inner: asyncio.Protocol | None = None
        self._connection: _Connection | None = None

    def connection_made(self, transport: asyncio.BaseTransport) -> None:
        self._connection = self._server._admit(transport)
        if self._connection is not None:
            self._inner = self._factory()
            self._inner.connection_made(transport)

    def data_received(self, data: bytes) -> None:
        if self._inner is not None:
            self._inner.data_received(data)

    def eof_received(self) -> bool | None:
        return self._inner.eof_received() if self._inner is not None else None

    def pause_writing(self) -> None:
        if self._inner is not None:
            self._inner.pause_writing()

    def resume_writing(self) -> None:
        if self._inner is not None:
            self._inner.resume_writing()

    def connection_lost(self, exc: Exception | None) -> None:
        if self._connection is not None:
            self._server._release(self._connection)
        if self._inner is not None:
            self._inner.connection_lost(exc)


class ReplaySource(Protocol):
    """What the server needs of a replay (:class:`clark_engine.station.replay.Replay`).

    Attributes:
        start_s: The earliest mission time of the run.
        end_s: The latest.
    """

    start_s: float
    end_s: float

    def clamp(self, t_s: float) -> float:
        """``t_s`` within the run's span."""
        ...

    def frame(self, t_s: float, after_s: float | None) -> list[Json]:
        """The messages that bring a page that has everything up to ``after_s`` to ``t_s``."""
        ...


@dataclass
class _Pending:
    """What the loop published since the server's loop last took it."""

    state: Json | None = None
    track: deque[Json] = field(default_factory=lambda: deque(maxlen=MAX_TRACK_POINTS))
    photos: deque[Json] = field(default_factory=lambda: deque(maxlen=MAX_PHOTOS))
    log: deque[Json] = field(default_factory=lambda: deque(maxlen=MAX_LOG_LINES))


class CommandRejected(ValueError):
    """A message from a page that is not a command the station may send.

    Args:
        reason: Why, in words safe to send back (it quotes nothing the page sent).
        ref: The page's ``ref`` of the message, when it could be read.
    """

    def __init__(self, reason: str, ref: str | int | None = None) -> None:
        super().__init__(reason)
        self.ref = ref


def _json_object(text: str) -> dict[str, Any]:
    """A message from the page as a JSON object, within :data:`MAX_MESSAGE_BYTES`.

    Raises:
        CommandRejected: Too long, not JSON, or not an object.
    """
    if len(text) > MAX_MESSAGE_BYTES:
        raise CommandRejected("message too long")
    try:
        data = json.loads(text)
    except (ValueError, RecursionError):
        raise CommandRejected("not JSON") from None
    if not isinstance(data, dict):
        raise CommandRejected("not a JSON object")
    return data


def _valid_ref(ref: object) -> bool:
    """Whether a message's ``ref`` (echoed to the page) is absent, an int or a short text."""
    return (
        ref is None
        or (isinstance(ref, int) and not isinstance(ref, bool) and abs(ref) < 2**53)
        or (isinstance(ref, str) and len(ref) <= MAX_REF_CHARS and ref.isprintable())
    )


def parse_command(
    text: str, hello: Mapping[str, Any], *, command_id: int, address: str
) -> tuple[CommandRequest, str | int | None]:
    """Check one message from a page; returns the command and the page's ``ref``.

    Everything in it is hostile until checked: it must be a JSON object of at most
    :data:`MAX_MESSAGE_BYTES`, of ``"type": "command"``, with a known action, a target
    that is an agent of the mission or ``"all"``, for ``mode`` a mode of that agent's
    profile, for ``terminate`` ``"confirm": true``; the operator's name is escaped and
    cut to :data:`MAX_OPERATOR_CHARS`.

    Raises:
        CommandRejected: Why it is not accepted (safe to show: it quotes nothing
            longer than the bounds).
    """
    data = _json_object(text)
    ref = data.get("ref")
    if not _valid_ref(ref):
        raise CommandRejected("ref must be a number or a short string")

    def rejected(reason: str) -> CommandRejected:
        return CommandRejected(reason, ref)

    if data.get("type") != "command":
        raise rejected("unknown message type (expected 'command')")
    action = data.get("action")
    if not isinstance(action, str) or action not in ACTIONS:
        raise rejected(f"unknown action; expected one of {', '.join(ACTIONS)}")
    target = data.get("target")
    names = agent_names(hello)
    if not isinstance(target, str) or len(target) > MAX_NAME_CHARS:
        raise rejected("target must be an agent's name or 'all'")
    if target != "all" and target not in names:
        raise rejected(f"no such agent; agents: {', '.join(names)}, all")
    mode = data.get("mode", "")
    if action == "mode":
        if target == "all":
            raise rejected("a mode change names one agent")
        if not isinstance(mode, str) or not mode or len(mode) > MAX_NAME_CHARS:
            raise rejected("mode must be one of the agent's modes")
        if mode not in modes_of(hello).get(target, frozenset()):
            raise rejected(f"{target} has no such mode")
    elif mode not in ("", None):
        raise rejected("mode is only for action 'mode'")
    if action == "terminate" and data.get("confirm") is not True:
        raise rejected('terminate needs "confirm": true')
    operator = data.get("operator", "")
    if operator is None:
        operator = ""
    if not isinstance(operator, str) or len(operator) > 4 * MAX_OPERATOR_CHARS:
        raise rejected("operator must be a short name")
    request = CommandRequest(
        id=command_id,
        action=action,
        target="" if target == "all" else target,
        mode=mode if action == "mode" else "",
        operator=printable(operator.strip(), MAX_OPERATOR_CHARS),
        address=printable(address, 64),
    )
    return request, ref


def parse_replay_control(
    text: str, speeds: tuple[float, ...]
) -> tuple[str, float | None, str | int | None]:
    """Check one message from a replay's page: ``(action, value, ref)``.

    ``{"type": "seek", "t": SECONDS}``, ``{"type": "play"}``, ``{"type": "pause"}``,
    ``{"type": "speed", "speed": X}`` with X one of ``speeds``. A command is refused: a
    replay sends nothing to any vehicle.

    Raises:
        CommandRejected: Why it is not accepted (it quotes nothing the page sent).
    """
    data = _json_object(text)
    ref = data.get("ref")
    if not _valid_ref(ref):
        ref = None
    kind = data.get("type")
    if kind == "command":
        raise CommandRejected("this is a replay of a finished run: it sends no commands", ref)
    if kind not in REPLAY_ACTIONS:
        raise CommandRejected(
            f"unknown message type; expected one of {', '.join(REPLAY_ACTIONS)}", ref
        )
    if kind in ("play", "pause"):
        return kind, None, ref
    key = "t" if kind == "seek" else "speed"
    value = data.get(key)
    if not isinstance(value, int | float) or isinstance(value, bool) or not math.isfinite(value):
        raise CommandRejected(f"{kind} needs a number {key!r}", ref)
    if kind == "speed" and float(value) not in speeds:
        raise CommandRejected(f"speed must be one of {', '.join(f'{x:g}' for x in speeds)}", ref)
    return kind, float(value), ref


def _dumps(message: Json) -> str:
    """A message as compact JSON; a NaN or infinity (JSON has none) becomes null."""
    try:
        return json.dumps(message, separators=(",", ":"), allow_nan=False)
    except ValueError:
        return json.dumps(_finite(message), separators=(",", ":"), allow_nan=False)


class ViewServer:
    """The station view's HTTP and WebSocket server, on a thread of its own.

    Args:
        hello: The ``hello`` message (:func:`~clark_engine.station.view_model.build_hello`); the
            agents and modes a command may name come from it.
        on_command: Called on the server's thread with each checked command; it must
            not block (:class:`~clark_engine.station.live_view.StationViewLink.submit` queues
            it for the loop).
        host: The address to bind (127.0.0.1 by default).
        port: The port (0 picks a free one; :attr:`port` then says which).
        token: The token every request must carry; required when ``host`` is not
            loopback.
        static_dir: The page's folder (the package's by default).
        replay: Serve this finished run instead of snapshots (``clark replay``): each
            client moves through it at its own time, and commands are refused.
        limits: Timeouts and connection caps (:class:`ViewLimits`); caps left out are
            derived from the file limit when the server starts (:func:`view_limits`).

    Raises:
        UsageError: A non-loopback ``host`` without a token, or a token that is too
            short, too long or not printable ASCII.
    """

    def __init__(
        self,
        hello: Json,
        on_command: Callable[[CommandRequest], None],
        *,
        host: str = "127.0.0.1",
        port: int = DEFAULT_PORT,
        token: str | None = None,
        static_dir: Path = STATIC_DIR,
        replay: ReplaySource | None = None,
        limits: ViewLimits | None = None,
    ) -> None:
        loopback = is_loopback_host(host)
        if token is None and not loopback:
            raise UsageError(
                f"the view would be served on {host}, beyond this machine: give a token "
                "(--view-token-file FILE or --view-token TOKEN), or bind 127.0.0.1"
            )
        self.token = check_token(token) if token is not None else None
        self.hello = hello
        self.on_command = on_command
        self.host = host
        self.requested_port = port
        self.port = port
        self.loopback = loopback
        self.static_dir = static_dir
        self.replay = replay
        replay_info = hello.get("replay") or {}
        self._speeds = tuple(float(x) for x in replay_info.get("speeds", (1,)))
        self._replay_period_s = 1.0 / float(hello.get("update_hz") or 5.0)
        self._hello_text = json.dumps(hello, separators=(",", ":"))
        self._lock = threading.Lock()
        self._pending = _Pending()
        self._scheduled = False
        self._loop: asyncio.AbstractEventLoop | None = None
        self._thread: threading.Thread | None = None
        self._ready = threading.Event()
        self._error: BaseException | None = None
        self._stopping: asyncio.Event | None = None
        self._sock: socket.socket | None = None
        self._clients: set[_Client] = set()
        self._ids = itertools.count(1)
        # What clients are sent (touched on the server's loop only).
        self._state: Json | None = None
        self._version = 0
        self._track: deque[Json] = deque(maxlen=MAX_TRACK_POINTS)
        self._photos: deque[Json] = deque(maxlen=MAX_PHOTOS)
        self._log: deque[Json] = deque(maxlen=MAX_LOG_LINES)
        self.limits = limits or ViewLimits()
        """The view's timeouts and caps (the caps filled in by :meth:`start`)."""
        self._throttle = _Throttle(_LOG, self.limits.log_interval_s)
        self._open: dict[asyncio.BaseTransport, _Connection] = {}
        self._unproven: OrderedDict[_Connection, None] = OrderedDict()
        self._unproven_by_key: dict[str, OrderedDict[_Connection, None]] = {}
        self._per_key: dict[str, int] = {}
        self.stats = {
            "connections": 0,
            "refused": 0,
            "commands": 0,
            "rejected": 0,
            "timed_out": 0,
            "shed": 0,
            "full": 0,
            "accept_errors": 0,
        }
        """Counts since the start: WebSocket connections, requests refused (403),
        commands handed on, messages rejected; TCP connections closed for sending no
        valid request in time (``timed_out``), closed to make room for a newer one
        (``shed``), refused because every place was taken by proven ones (``full``),
        and accept() failures for want of a file descriptor (``accept_errors``)."""

    # -- addresses -----------------------------------------------------------------------

    @property
    def open_connections(self) -> int:
        """TCP connections held now (read on the server's thread, or as an estimate)."""
        return len(self._open)

    @property
    def cookie_name(self) -> str:
        """The token's cookie, one per port: a browser sends a host's cookies to all ports."""
        return f"clark_view_{self.port}"

    def _netloc(self, host: str) -> str:
        return f"[{host}]:{self.port}" if ":" in host else f"{host}:{self.port}"

    @property
    def url(self) -> str:
        """The page's address, with the token when there is one (print it for the operator)."""
        host = self.host
        if host in ("0.0.0.0", "::"):
            host = socket.gethostname()
        base = f"http://{self._netloc(host)}/"
        return base + (f"?token={quote(self.token, safe='')}" if self.token else "")

    def _allowed_hosts(self) -> set[str] | None:
        """Host headers accepted; None for any (a token guards a non-loopback bind)."""
        if not self.loopback:
            return None
        names = {self.host, "127.0.0.1", "localhost", "::1"}
        return {self._netloc(name).lower() for name in names}

    # -- life ----------------------------------------------------------------------------

    def start(self, timeout_s: float = 10.0) -> None:
        """Bind, start the server's thread and wait until it serves.

        Raises:
            UsageError: The address cannot be bound (in use, not this machine's).
        """
        try:
            infos = socket.getaddrinfo(
                self.host, self.requested_port, type=socket.SOCK_STREAM, flags=socket.AI_PASSIVE
            )
            family, kind, proto, _, address = infos[0]
            sock = socket.socket(family, kind, proto)
        except OSError as exc:
            raise UsageError(f"--view: cannot use {self.host}: {exc.strerror or exc}") from None
        try:
            sock.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
            sock.bind(address)
            sock.listen(LISTEN_BACKLOG)
            sock.setblocking(False)
        except OSError as exc:
            sock.close()
            raise UsageError(
                f"--view: cannot serve on {self._netloc(self.host)}: {exc.strerror or exc}"
            ) from None
        self._sock = sock
        self.port = int(sock.getsockname()[1])
        self.limits = view_limits(self.limits)
        self._thread = threading.Thread(target=self._main, name="clark-view", daemon=True)
        self._thread.start()
        if not self._ready.wait(timeout_s) or self._error is not None:
            self.stop()
            raise UsageError(f"--view: the server did not start: {self._error}")

    def stop(self, timeout_s: float = 5.0) -> None:
        """Send every client the last state, close them and the server; wait for the thread."""
        loop, stopping = self._loop, self._stopping
        if loop is not None and stopping is not None:
            with contextlib.suppress(RuntimeError):  # its loop already ended
                loop.call_soon_threadsafe(stopping.set)
        if self._thread is not None:
            self._thread.join(timeout_s)
            self._thread = None
        if self._sock is not None:
            self._sock.close()
            self._sock = None

    def _main(self) -> None:
        loop = asyncio.new_event_loop()
        loop.set_exception_handler(self._loop_error)
        self._loop = loop
        try:
            loop.run_until_complete(self._serve())
        except BaseException as exc:  # reported to start(); the station flies on without it
            self._error = exc
            self._ready.set()
            _LOG.error("station view server stopped: %s", exc)
        finally:
            with contextlib.suppress(Exception):
                loop.run_until_complete(loop.shutdown_asyncgens())
            loop.close()

    async def _serve(self) -> None:
        self._stopping = asyncio.Event()
        app = web.Application(middlewares=[self._guard], client_max_size=64 * 1024)
        app.router.add_get("/", self._page)
        app.router.add_get("/ws", self._websocket)
        app.router.add_static("/static/", self.static_dir, follow_symlinks=False)
        limits = self.limits
        runner = web.AppRunner(
            app,
            handle_signals=False,
            access_log=None,
            shutdown_timeout=STOP_FLUSH_S,
            keepalive_timeout=limits.idle_timeout_s,
            lingering_time=min(limits.header_timeout_s, 10.0),
            logger=_ThrottledLogger(logging.getLogger("aiohttp.server"), self._throttle),
        )
        await runner.setup()
        assert self._sock is not None and runner.server is not None
        handlers = runner.server
        # Not a SockSite: each connection goes through _Admitted, which applies the caps.
        listener = await asyncio.get_running_loop().create_server(
            lambda: _Admitted(self, handlers), sock=self._sock, backlog=LISTEN_BACKLOG
        )
        self._ready.set()
        try:
            await self._stopping.wait()
            self._take()
            await self._close_clients()
        finally:
            listener.close()
            await runner.cleanup()
            self._throttle.flush()

    # -- connections: caps, header timeout, errors ---------------------------------------

    def _admit(self, transport: asyncio.BaseTransport) -> _Connection | None:
        """A new connection held under the caps, or None when there is no room for it.

        Room is made by closing the oldest connection that has not proven itself (from
        the same address when that address is at its cap, else from anyone): a flood of
        new connections churns through the unproven places, while a browser, which
        sends its request at once, proves itself long before its turn to go. A
        connection is refused only when every place it could take is proven.
        """
        peer = transport.get_extra_info("peername")
        address = str(peer[0]) if isinstance(peer, tuple) and peer else ""
        key = client_key(address)
        assert self.limits.max_connections is not None and self.limits.max_per_address is not None
        if self._per_key.get(key, 0) >= self.limits.max_per_address:
            victims = self._unproven_by_key.get(key)
            if not victims:
                self._refuse(transport)
                return None
            self._shed(next(iter(victims)))
        if len(self._open) >= self.limits.max_connections:
            if not self._unproven:
                self._refuse(transport)
                return None
            self._shed(next(iter(self._unproven)))
        connection = _Connection(key, transport)
        self._open[transport] = connection
        self._unproven[connection] = None
        self._unproven_by_key.setdefault(key, OrderedDict())[connection] = None
        self._per_key[key] = self._per_key.get(key, 0) + 1
        loop = asyncio.get_running_loop()
        connection.timer = loop.call_later(
            self.limits.header_timeout_s, self._header_timeout, connection
        )
        return connection

    def _unlist(self, connection: _Connection) -> None:
        """Take ``connection`` off the unproven lists."""
        self._unproven.pop(connection, None)
        mine = self._unproven_by_key.get(connection.key)
        if mine is not None:
            mine.pop(connection, None)
            if not mine:
                del self._unproven_by_key[connection.key]
        if connection.timer is not None:
            connection.timer.cancel()
            connection.timer = None

    def _release(self, connection: _Connection) -> None:
        """Forget a connection that closed (or is being closed); idempotent."""
        if connection.closed:
            return
        connection.closed = True
        self._unlist(connection)
        self._open.pop(connection.transport, None)
        left = self._per_key.get(connection.key, 1) - 1
        if left > 0:
            self._per_key[connection.key] = left
        else:
            self._per_key.pop(connection.key, None)

    def _prove(self, transport: asyncio.BaseTransport | None) -> None:
        """A request on this connection passed the checks: it keeps its place."""
        connection = self._open.get(transport) if transport is not None else None
        if connection is not None and not connection.proven:
            connection.proven = True
            self._unlist(connection)

    def _limits_text(self) -> str:
        return (
            f"at most {self.limits.max_per_address} per address and "
            f"{self.limits.max_connections} in all"
        )

    def _shed(self, connection: _Connection) -> None:
        self.stats["shed"] += 1
        self._throttle.note(
            "shed",
            "station view: %d connection(s) closed that had sent no valid request, "
            f"to make room for new ones ({self._limits_text()})",
        )
        self._release(connection)
        connection.transport.abort()  # type: ignore[attr-defined]

    def _refuse(self, transport: asyncio.BaseTransport) -> None:
        self.stats["full"] += 1
        self._throttle.note(
            "full",
            "station view: %d connection(s) refused: every place is held by a served "
            f"client ({self._limits_text()})",
        )
        with contextlib.suppress(Exception):
            transport.write(_FULL_RESPONSE)  # type: ignore[attr-defined]
        transport.close()

    def _header_timeout(self, connection: _Connection) -> None:
        connection.timer = None
        if connection.closed or connection.proven:
            return
        self.stats["timed_out"] += 1
        self._throttle.note(
            "timeout",
            "station view: %d connection(s) closed that sent no valid request within "
            f"{self.limits.header_timeout_s:g} s",
            logging.INFO,
        )
        self._release(connection)
        connection.transport.abort()  # type: ignore[attr-defined]

    def _loop_error(self, loop: asyncio.AbstractEventLoop, context: dict[str, Any]) -> None:
        """The server loop's exception handler: no traceback floods.

        asyncio reports each failed accept() (no file descriptor left: the engine's or
        the view's) with a traceback, once a second while it lasts; here it is one line
        per :data:`LOG_INTERVAL_S` with the count, and the oldest unproven connections
        are closed to give the operator (and the engine) room. Anything else is logged
        in full the first time, then counted.
        """
        exc = context.get("exception")
        if isinstance(exc, OSError) and exc.errno in _NO_RESOURCE:
            self.stats["accept_errors"] += 1
            nofile = resource.getrlimit(resource.RLIMIT_NOFILE)[0]
            self._throttle.note(
                "accept",
                "station view: could not accept connections (%d failures): "
                f"{exc.strerror} "
                f"(file limit {nofile}, {len(self._open)} view connections open); "
                "retrying every second",
            )
            for victim in list(self._unproven)[:8]:
                self._shed(victim)
            return
        if isinstance(exc, (OSError, ValueError)) and "_start_serving" in str(
            context.get("message", "")
        ):
            self._accept_rearm_failed(exc)
            return
        kind = f"loop:{context.get('message')}"
        first = kind not in self._throttle.total
        count = self._throttle.admit(kind)
        if count is None:
            return
        if first:
            loop.default_exception_handler(context)
        else:
            _LOG.error(
                "station view: %s: %s (%d like it in the last %g s)",
                context.get("message"),
                exc,
                count,
                self._throttle.interval_s,
            )

    def _accept_rearm_failed(self, exc: BaseException) -> None:
        """When asyncio's own retry of accept() fails: one line, never a traceback.

        After accept() runs out of file descriptors, asyncio (3.11) stops listening and
        schedules ``_start_serving`` a second later to listen again, once per failed
        accept of that tick. When the view stops within that second, the listening
        socket is closed before the retry runs, and the retry raises on its file
        descriptor (-1). That is the expected end of a flood, not an error: it is noted
        at debug level. While the view serves, a failed retry would mean it no longer
        accepts at all: that is said once a log interval.
        """
        serving = self._stopping is not None and not self._stopping.is_set()
        if not serving:
            _LOG.debug("station view: asyncio's accept retry ran after the view closed: %s", exc)
            return
        self._throttle.note(
            "rearm",
            "station view: could not listen again after running out of files "
            "(%d failures): " + str(exc).replace("%", "%%"),
        )

    async def _close_clients(self) -> None:
        clients = list(self._clients)
        for client in clients:
            client.wake.set()
        await asyncio.sleep(0)
        deadline = time.monotonic() + STOP_FLUSH_S
        while any(c.version < self._version for c in clients if not c.ws.closed):
            if time.monotonic() > deadline:
                break
            await asyncio.sleep(0.02)
        for client in clients:
            with contextlib.suppress(Exception):
                await asyncio.wait_for(
                    client.ws.close(code=1001, message=b"the station stopped"), STOP_FLUSH_S
                )

    # -- snapshots in (any thread) -------------------------------------------------------

    def publish(self, snapshot: Snapshot) -> None:
        """Hand the server the newest snapshot; never blocks (called from the station loop)."""
        with self._lock:
            pending = self._pending
            pending.state = snapshot.state
            pending.track.extend(snapshot.track)
            pending.photos.extend(snapshot.photos)
            pending.log.extend(snapshot.log)
            schedule = not self._scheduled
            self._scheduled = True
        loop = self._loop
        if schedule and loop is not None:
            try:
                loop.call_soon_threadsafe(self._take)
            except RuntimeError:  # the server's loop has ended: nobody to tell
                with self._lock:
                    self._scheduled = False

    def _take(self) -> None:
        """On the server's loop: move what was published to the clients' histories."""
        with self._lock:
            pending, self._pending = self._pending, _Pending()
            self._scheduled = False
        if pending.state is None:
            return
        self._state = pending.state
        self._track.extend(pending.track)
        self._photos.extend(pending.photos)
        self._log.extend(pending.log)
        self._version += 1
        for client in self._clients:
            client.wake.set()

    # -- HTTP ----------------------------------------------------------------------------

    def _supplied_token(self, request: web.Request) -> tuple[str | None, bool]:
        """The token the request carries, and whether it came in the query string."""
        query = request.query.get("token")
        if query is not None:
            return query, True
        header = request.headers.get(TOKEN_HEADER)
        if header is not None:
            return header, False
        authorization = request.headers.get("Authorization", "")
        if authorization.startswith("Bearer "):
            return authorization[len("Bearer ") :], False
        return request.cookies.get(self.cookie_name), False

    def _token_ok(self, supplied: str | None) -> bool:
        if self.token is None:
            return True
        if supplied is None or len(supplied) > MAX_TOKEN_CHARS:
            return False
        return hmac.compare_digest(supplied.encode(), self.token.encode())

    def _forbidden(self, why: str) -> web.Response:
        self.stats["refused"] += 1
        return web.Response(
            status=403,
            text=f"403 Forbidden: {why}\n",
            headers={"Cache-Control": "no-store", "X-Content-Type-Options": "nosniff"},
        )

    @web.middleware
    async def _guard(
        self,
        request: web.Request,
        handler: Handler,
    ) -> web.StreamResponse:
        allowed = self._allowed_hosts()
        if allowed is not None and request.host.lower() not in allowed:
            return self._forbidden("this view answers to its own address only")
        supplied, in_query = self._supplied_token(request)
        if not self._token_ok(supplied):
            return self._forbidden("a valid token is required (the URL clark run printed)")
        self._prove(request.transport)
        upgrade = request.headers.get("Upgrade", "").lower() == "websocket"
        if self.token is not None and in_query and request.method == "GET" and not upgrade:
            # The token moves from the URL to a cookie, and the URL is shown without it.
            query = {k: v for k, v in request.query.items() if k != "token"}
            target = request.rel_url.with_query(query)
            moved = web.Response(
                status=303, headers={"Location": str(target), "Cache-Control": "no-store"}
            )
            moved.set_cookie(
                self.cookie_name, self.token, httponly=True, samesite="Strict", path="/"
            )
            return moved
        response = await handler(request)
        if not response.prepared:
            headers = response.headers
            headers.setdefault("X-Content-Type-Options", "nosniff")
            headers.setdefault("Referrer-Policy", "no-referrer")
            headers.setdefault("X-Frame-Options", "DENY")
            headers.setdefault("Cache-Control", "no-store")
        return response

    async def _page(self, request: web.Request) -> web.StreamResponse:
        host = request.host
        csp = (
            "default-src 'none'; script-src 'self'; style-src 'self'; img-src 'self' data:; "
            f"connect-src 'self' ws://{host} wss://{host}; base-uri 'none'; "
            "form-action 'none'; frame-ancestors 'none'"
        )
        return web.FileResponse(
            self.static_dir / "index.html", headers={"Content-Security-Policy": csp}
        )

    # -- the WebSocket -------------------------------------------------------------------

    def _origin_ok(self, request: web.Request) -> bool:
        origin = request.headers.get("Origin")
        if origin is None:
            return True  # not a browser: the token (when set) is its guard
        return origin.lower() in (
            f"http://{request.host}".lower(),
            f"https://{request.host}".lower(),
        )

    async def _websocket(self, request: web.Request) -> web.StreamResponse:
        if not self._origin_ok(request):
            return self._forbidden("the WebSocket must be opened by this view's own page")
        ws = web.WebSocketResponse(heartbeat=20.0, max_msg_size=MAX_MESSAGE_BYTES, compress=False)
        await ws.prepare(request)
        if len(self._clients) >= MAX_CLIENTS:
            await ws.close(code=1013, message=b"too many clients")
            return ws
        client = _Client(ws, request.remote or "")
        self._clients.add(client)
        self.stats["connections"] += 1
        sender = asyncio.create_task(self._send(client))
        try:
            async for message in ws:
                if message.type == WSMsgType.TEXT:
                    self._received(client, message.data)
                elif message.type == WSMsgType.BINARY:
                    self._reply(client, {"type": "error", "ref": None, "error": "text only"})
                else:
                    break
        finally:
            self._clients.discard(client)
            sender.cancel()
            with contextlib.suppress(asyncio.CancelledError, Exception):
                await sender
        return ws

    def _reply(self, client: _Client, message: Json) -> None:
        client.replies.append(json.dumps(message, separators=(",", ":")))
        client.wake.set()

    def _received(self, client: _Client, text: str) -> None:
        """One message from a page: a checked command handed on, or an error sent back."""
        if self.replay is not None:
            self._replay_control(client, self.replay, text)
            return
        if not client.allow_command():
            self.stats["rejected"] += 1
            self._reply(client, {"type": "error", "ref": None, "error": "too many commands"})
            return
        try:
            request, ref = parse_command(
                text, self.hello, command_id=next(self._ids), address=client.address
            )
        except CommandRejected as exc:
            self.stats["rejected"] += 1
            self._reply(client, {"type": "error", "ref": exc.ref, "error": str(exc)})
            return
        self.stats["commands"] += 1
        try:
            self.on_command(request)
        except Exception as exc:  # the station could not take it (it has stopped)
            self._reply(client, {"type": "error", "ref": ref, "error": f"not sent: {exc}"})
            return
        self._reply(client, {"type": "accepted", "ref": ref, "id": request.id})

    def _replay_control(self, client: _Client, source: ReplaySource, text: str) -> None:
        """A replay page's seek, play, pause or speed, applied to its own time."""
        if not client.controls.allow():
            self.stats["rejected"] += 1
            self._reply(client, {"type": "error", "ref": None, "error": "too many messages"})
            return
        try:
            action, value, _ref = parse_replay_control(text, self._speeds)
        except CommandRejected as exc:
            self.stats["rejected"] += 1
            self._reply(client, {"type": "error", "ref": exc.ref, "error": str(exc)})
            return
        if action == "seek" and value is not None:
            client.replay_t = source.clamp(value)
        elif action == "play":
            if client.replay_t >= source.end_s:
                client.replay_t = source.start_s  # at the end: play from the start
            client.playing = True
        elif action == "pause":
            client.playing = False
        elif action == "speed" and value is not None:
            client.speed = value
        client.moved = True
        client.wake.set()

    async def _send_replay(self, client: _Client, source: ReplaySource) -> None:
        """A replay client's sender: hello, then its time's state whenever it moves.

        While the page plays, its time advances by its speed times the wall-clock time
        elapsed, and a state goes out at the update rate; at the end of the run it stops.
        """
        ws = client.ws
        client.replay_t = source.start_s
        await ws.send_str(self._hello_text)
        last_s = time.monotonic()
        while not ws.closed:
            if not client.moved and not client.replies:
                timeout = self._replay_period_s if client.playing else None
                with contextlib.suppress(TimeoutError):
                    await asyncio.wait_for(client.wake.wait(), timeout)
            client.wake.clear()
            while client.replies and not ws.closed:
                await ws.send_str(client.replies.popleft())
            now_s = time.monotonic()
            if client.playing:
                client.replay_t = min(
                    source.end_s, client.replay_t + client.speed * (now_s - last_s)
                )
                if client.replay_t >= source.end_s:
                    client.playing = False
                client.moved = True
            last_s = now_s
            if not client.moved or ws.closed:
                continue
            client.moved = False
            for message in source.frame(client.replay_t, client.sent_t):
                if message.get("type") == "state":
                    message["replay"] = {
                        **message.get("replay", {}),
                        "playing": client.playing,
                        "speed": client.speed,
                    }
                await ws.send_str(_dumps(message))
            client.sent_t = client.replay_t

    async def _send(self, client: _Client) -> None:
        """The client's one sender: hello, then replies and the newest state as they come."""
        ws = client.ws
        if self.replay is not None:
            # ConnectionError, RuntimeError: the client went away; its handler cleans up.
            with contextlib.suppress(ConnectionError, RuntimeError):
                await self._send_replay(client, self.replay)
            return
        try:
            await ws.send_str(self._hello_text)
            client.wake.set()
            while not ws.closed:
                await client.wake.wait()
                client.wake.clear()
                while client.replies and not ws.closed:
                    await ws.send_str(client.replies.popleft())
                if self._state is not None and client.version < self._version and not ws.closed:
                    client.version = self._version
                    await ws.send_str(self._state_for(client))
        except (ConnectionError, RuntimeError):
            return  # the client went away; its handler cleans up

    def _state_for(self, client: _Client) -> str:
        """The newest state with the track points, photos and log lines the client lacks."""
        assert self._state is not None
        message = dict(self._state)
        message["track"] = _after(self._track, client.track_seq)
        message["photos"] = _after(self._photos, client.photo_seq)
        message["log"] = _after(self._log, client.log_seq)
        if self._track:
            client.track_seq = int(self._track[-1]["seq"])
        if self._photos:
            client.photo_seq = int(self._photos[-1]["seq"])
        if self._log:
            client.log_seq = int(self._log[-1]["seq"])
        return _dumps(message)


def _after(items: deque[Json], seq: int) -> list[Json]:
    """The items with a sequence number above ``seq`` (they are in order), oldest first."""
    out: list[Json] = []
    for item in reversed(items):
        if int(item["seq"]) <= seq:
            break
        out.append(item)
    out.reverse()
    return out


def _finite(value: Any) -> Any:
    """``value`` with every NaN and infinity, however deep, replaced by None."""
    if isinstance(value, float):
        return value if math.isfinite(value) else None
    if isinstance(value, dict):
        return {k: _finite(v) for k, v in value.items()}
    if isinstance(value, list | tuple):
        return [_finite(v) for v in value]
    return value


__all__ = [
    "DEFAULT_PORT",
    "REPLAY_ACTIONS",
    "STATIC_DIR",
    "CommandRejected",
    "ReplaySource",
    "ViewLimits",
    "ViewServer",
    "check_token",
    "client_key",
    "is_loopback_host",
    "parse_command",
    "parse_replay_control",
    "parse_view_address",
    "view_limits",
]
