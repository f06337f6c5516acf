"""The connections the station view holds: its caps, its header timeout, who is shed.

Separate from the server because bounding connections is a concern of its own
(docs/station-view.md, "Connections and floods"), below HTTP: asyncio accepts,
:class:`Admitted` admits each under :class:`ViewLimits` (per address, in all: below the
file limit, :func:`view_limits`) before aiohttp sees it; a connection must pass the
view's checks within :data:`HEADER_TIMEOUT_S` (until then it may be closed to make room
for a newer one, oldest first), a served one idle for :data:`IDLE_TIMEOUT_S` is closed.
:class:`ConnectionCaps` keeps the books; the server owns one and proves a connection
when a request on it passes the checks.
"""

from __future__ import annotations

import asyncio
import contextlib
import ipaddress
import logging
import resource
from collections import OrderedDict
from collections.abc import Callable
from dataclasses import dataclass
from typing import Final

from clark_engine.station.log_throttle import Throttle

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


FULL_RESPONSE: Final = (
    b"HTTP/1.1 503 Service Unavailable\r\nContent-Type: text/plain\r\n"
    b"Content-Length: 47\r\nConnection: close\r\nRetry-After: 5\r\n\r\n"
    b"503: the station view holds all it can; retry\n"
)
"""What a connection the view has no room for is sent before it is closed."""


@dataclass(eq=False)
class Connection:
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


class ConnectionCaps:
    """The connections the view holds now, under its :class:`ViewLimits`.

    Owned by :class:`~clark_engine.station.server.ViewServer` (a helper it holds rather
    than a part of it: the caps know sockets, never HTTP). Touched on the server's loop
    only. Its counts go into the server's ``stats`` and its lines through the server's
    :class:`~clark_engine.station.log_throttle.Throttle`.

    Args:
        limits: The caps (filled in: :func:`view_limits`) and the header timeout.
        stats: The server's counts (``timed_out``, ``shed``, ``full`` are kept here).
        throttle: Where its lines go, one per kind per interval.
    """

    def __init__(self, limits: ViewLimits, stats: dict[str, int], throttle: Throttle) -> None:
        self.limits = limits
        self.stats = stats
        self.throttle = throttle
        self.open: dict[asyncio.BaseTransport, Connection] = {}
        """Every connection held, by its transport."""
        self.unproven: OrderedDict[Connection, None] = OrderedDict()
        """The connections no request has proven yet, oldest first."""
        self._unproven_by_key: dict[str, OrderedDict[Connection, None]] = {}
        self._per_key: dict[str, int] = {}

    def admit(self, transport: asyncio.BaseTransport) -> Connection | None:
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
            self.shed(next(iter(victims)))
        if len(self.open) >= self.limits.max_connections:
            if not self.unproven:
                self._refuse(transport)
                return None
            self.shed(next(iter(self.unproven)))
        connection = Connection(key, transport)
        self.open[transport] = connection
        self.unproven[connection] = None
        self._unproven_by_key.setdefault(key, OrderedDict())[connection] = None
        self._per_key[key] = self._per_key.get(key, 0) + 1
        loop = asyncio.get_running_loop()
        connection.timer = loop.call_later(
            self.limits.header_timeout_s, self._header_timeout, connection
        )
        return connection

    def _unlist(self, connection: Connection) -> None:
        """Take ``connection`` off the unproven lists."""
        self.unproven.pop(connection, None)
        mine = self._unproven_by_key.get(connection.key)
        if mine is not None:
            mine.pop(connection, None)
            if not mine:
                del self._unproven_by_key[connection.key]
        if connection.timer is not None:
            connection.timer.cancel()
            connection.timer = None

    def release(self, connection: Connection) -> None:
        """Forget a connection that closed (or is being closed); idempotent."""
        if connection.closed:
            return
        connection.closed = True
        self._unlist(connection)
        self.open.pop(connection.transport, None)
        left = self._per_key.get(connection.key, 1) - 1
        if left > 0:
            self._per_key[connection.key] = left
        else:
            self._per_key.pop(connection.key, None)

    def prove(self, transport: asyncio.BaseTransport | None) -> None:
        """A request on this connection passed the checks: it keeps its place."""
        connection = self.open.get(transport) if transport is not None else None
        if connection is not None and not connection.proven:
            connection.proven = True
            self._unlist(connection)

    def _limits_text(self) -> str:
        return (
            f"at most {self.limits.max_per_address} per address and "
            f"{self.limits.max_connections} in all"
        )

    def shed(self, connection: Connection) -> None:
        """Close an unproven connection to make room for a newer one."""
        self.stats["shed"] += 1
        self.throttle.note(
            "shed",
            "station view: %d connection(s) closed that had sent no valid request, "
            f"to make room for new ones ({self._limits_text()})",
        )
        self.release(connection)
        connection.transport.abort()  # type: ignore[attr-defined]

    def _refuse(self, transport: asyncio.BaseTransport) -> None:
        self.stats["full"] += 1
        self.throttle.note(
            "full",
            "station view: %d connection(s) refused: every place is held by a served "
            f"client ({self._limits_text()})",
        )
        with contextlib.suppress(Exception):
            transport.write(FULL_RESPONSE)  # type: ignore[attr-defined]
        transport.close()

    def _header_timeout(self, connection: Connection) -> None:
        connection.timer = None
        if connection.closed or connection.proven:
            return
        self.stats["timed_out"] += 1
        self.throttle.note(
            "timeout",
            "station view: %d connection(s) closed that sent no valid request within "
            f"{self.limits.header_timeout_s:g} s",
            logging.INFO,
        )
        self.release(connection)
        connection.transport.abort()  # type: ignore[attr-defined]


class Admitted(asyncio.Protocol):
    """A connection's protocol: admitted under the view's limits, then aiohttp's.

    asyncio accepts each connection and calls :meth:`connection_made`; there the view
    decides whether it has room (:meth:`ConnectionCaps.admit`). A connection admitted is
    handed to aiohttp's request handler, which sees every call after; one refused is
    sent a 503 and closed, and aiohttp never learns of it.
    """

    def __init__(
        self, caps: ConnectionCaps, handler_factory: Callable[[], asyncio.Protocol]
    ) -> None:
        self._caps = caps
        self._factory = handler_factory
        self._inner: asyncio.Protocol | None = None
        self._connection: Connection | None = None

    def connection_made(self, transport: asyncio.BaseTransport) -> None:
        """Admit the connection under the caps, and hand it to aiohttp if it has room."""
        self._connection = self._caps.admit(transport)
        if self._connection is not None:
            self._inner = self._factory()
            self._inner.connection_made(transport)

    def data_received(self, data: bytes) -> None:
        """Pass the bytes to aiohttp."""
        if self._inner is not None:
            self._inner.data_received(data)

    def eof_received(self) -> bool | None:
        """Pass the end of the stream to aiohttp."""
        return self._inner.eof_received() if self._inner is not None else None

    def pause_writing(self) -> None:
        """Pass the transport's back-pressure to aiohttp."""
        if self._inner is not None:
            self._inner.pause_writing()

    def resume_writing(self) -> None:
        """Pass the transport's back-pressure to aiohttp."""
        if self._inner is not None:
            self._inner.resume_writing()

    def connection_lost(self, exc: Exception | None) -> None:
        """Give the connection's place back, and tell aiohttp."""
        if self._connection is not None:
            self._caps.release(self._connection)
        if self._inner is not None:
            self._inner.connection_lost(exc)


__all__ = [
    "HEADER_TIMEOUT_S",
    "IDLE_TIMEOUT_S",
    "LOG_INTERVAL_S",
    "Admitted",
    "Connection",
    "ConnectionCaps",
    "ViewLimits",
    "client_key",
    "view_limits",
]
