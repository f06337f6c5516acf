r"""Payload adapters: a payload's ASCII lines in, typed payload events out, and back.

The thesis's camera was a Raspberry Pi that connected to the mission computer
over TCP and spoke ASCII strings, the mission computer serving (4.1.4); its
payload interface also came in a UDP flavour (5.2). These adapters are that
interface for the runtime: :meth:`PayloadAdapter.send` takes a
:class:`~clark_engine.runtime.commands.PayloadCommand` and
:meth:`PayloadAdapter.receive` returns
:class:`~clark_engine.runtime.events.PayloadEvent` s, the same types the dry
run's :class:`~clark_engine.sim.camera.SimCamera` speaks, so the runtime cannot
tell a real camera from the simulated one.

The line protocol (docs/payloads.md): ASCII lines ending in ``\n`` (a ``\r``
before it is ignored), at most :data:`MAX_LINE_BYTES` bytes, words separated
by spaces.

To the payload::

    CAPTURE <seq>                         take one picture; seq is the request id

From the payload::

    READY                                 the payload is up (sent on connecting)
    PHOTO <seq> <gps_time_ms> [<file>]    picture <seq> saved      -> captured
    REFUSED <seq> [<text>]                too soon / busy          -> refused
    ERROR <seq> <text>                    request <seq> failed     -> error
    ERROR <text>                          payload-wide failure     -> error, request 0

``seq`` is a decimal request id (the runtime's start at 1, so 0 never answers
a request); ``gps_time_ms`` is decimal milliseconds; ``file`` is 1-64 of
``A-Z a-z 0-9 . _ -``. The event's ``detail`` is the file name for PHOTO and the
text for REFUSED and ERROR. An empty line is a keep-alive and ignored.

Every line from the payload is hostile: a line too long, not printable ASCII,
with an unknown verb or malformed arguments is dropped and counted in
``stats.dropped`` (``too long``, ``not ascii``, ``unknown``, ``malformed``),
never raised into the loop. A command the adapter cannot deliver (no payload
connected, socket buffer full) or does not know (an action other than
``capture``) is counted in ``stats.send_failures`` and answered at once with an
``error`` event for its request, as :class:`~clark_engine.sim.camera.SimCamera`
answers an unsupported action, so the runtime's bookkeeping never waits for an
answer that cannot come.

Adapters:

- :class:`TcpPayloadServer`: listens; the payload connects. One payload
  connection at a time: a new connection replaces the old one (counted in
  ``stats.reconnects``). Non-blocking; :meth:`TcpPayloadServer.fileno` is one
  descriptor (an internal epoll/kqueue selector over the listening and the
  connected sockets) that becomes readable when either has something.
- :class:`UdpPayload`: listens for datagrams, each holding one or more lines;
  commands go to the payload's fixed ``remote`` address when given, otherwise
  to the address it last heard from (a new address counts as a reconnect).
"""

from __future__ import annotations

import collections
import contextlib
import re
import selectors
import socket
from abc import ABC, abstractmethod
from collections.abc import Mapping
from dataclasses import dataclass, field
from types import TracebackType
from typing import Any, Final

from clark_engine.errors import ClarkError
from clark_engine.io.transports import TransportError, parse_address
from clark_engine.runtime.commands import PayloadCommand
from clark_engine.runtime.events import PayloadEvent

MAX_LINE_BYTES: Final = 256
"""Longest line accepted, without its ``\\n``; longer ones are dropped whole."""

MAX_PENDING_EVENTS: Final = 256
"""Events held for the loop before the oldest is dropped (counted)."""

MAX_OUTBOX_BYTES: Final = 4096
"""Bytes of commands waiting for a slow payload to read before commands fail."""

RECEIVE_CHUNK_BYTES: Final = 4096
"""Largest read per system call."""

MAX_READS_PER_RECEIVE: Final = 64
"""System calls per :meth:`PayloadAdapter.receive`, so a flooding payload cannot starve the loop."""

MAX_SEQ: Final = 2**63 - 1
"""Largest request id accepted."""

_NUMBER = re.compile(r"[0-9]{1,19}")
_FILE_NAME = re.compile(r"[A-Za-z0-9._-]{1,64}")


class PayloadError(ClarkError):
    """A payload adapter cannot be opened (bad address, port in use, unknown connection)."""


@dataclass(slots=True)
class PayloadStats:
    """What a payload adapter counted since it was opened.

    Attributes:
        lines: Lines from the payload understood (READY included).
        events: Events handed to the loop.
        ready: READY lines heard.
        commands_sent: Commands written to the payload.
        send_failures: Commands not delivered, per reason (``not connected``...).
        dropped: Lines or events lost, per reason (``malformed``, ``receive queue``...).
        connections: Payload connections accepted (TCP) or payload addresses heard (UDP).
        reconnects: Connections after the first (a new one replaced the old).
        disconnects: Connections the payload closed or that failed.
    """

    lines: int = 0
    events: int = 0
    ready: int = 0
    commands_sent: int = 0
    send_failures: dict[str, int] = field(default_factory=dict)
    dropped: dict[str, int] = field(default_factory=dict)
    connections: int = 0
    reconnects: int = 0
    disconnects: int = 0

    def fail(self, reason: str) -> None:
        """Count one undelivered command under ``reason``."""
        self.send_failures[reason] = self.send_failures.get(reason, 0) + 1

    def drop(self, reason: str) -> None:
        """Count one line or event lost for ``reason``."""
        self.dropped[reason] = self.dropped.get(reason, 0) + 1


@dataclass(frozen=True, slots=True)
class PayloadLine:
    """One line from the payload, parsed.

    Attributes:
        verb: ``READY``, ``PHOTO``, ``REFUSED`` or ``ERROR``.
        seq: The request it answers; 0 for READY and a payload-wide ERROR.
        gps_time_ms: PHOTO's capture time, 0 otherwise.
        detail: PHOTO's file name, or REFUSED's and ERROR's text.
    """

    verb: str
    seq: int = 0
    gps_time_ms: int = 0
    detail: str = ""


def _number(word: str) -> int | None:
    if not _NUMBER.fullmatch(word):
        return None
    value = int(word)
    return value if value <= MAX_SEQ else None


def parse_line(line: bytes) -> PayloadLine | str:
    r"""Parse one line (without its ``\n``) from the payload.

    Returns:
        The parsed line, or the reason it is dropped: ``too long``, ``not ascii``,
        ``unknown`` (verb) or ``malformed`` (arguments).
    """
    if line.endswith(b"\r"):
        line = line[:-1]
    if len(line) > MAX_LINE_BYTES:
        return "too long"
    if any(byte < 0x20 or byte > 0x7E for byte in line):
        return "not ascii"
    verb, _, rest = line.decode("ascii").partition(" ")
    words = rest.split()
    if verb == "READY":
        return PayloadLine("READY") if not words else "malformed"
    if verb == "PHOTO":
        if len(words) not in (2, 3):
            return "malformed"
        seq, gps_time_ms = _number(words[0]), _number(words[1])
        name = words[2] if len(words) == 3 else ""
        if seq is None or gps_time_ms is None or (name and not _FILE_NAME.fullmatch(name)):
            return "malformed"
        return PayloadLine("PHOTO", seq, gps_time_ms, name)
    if verb == "REFUSED":
        seq = _number(words[0]) if words else None
        if seq is None:
            return "malformed"
        return PayloadLine("REFUSED", seq, detail=" ".join(words[1:]))
    if verb == "ERROR":
        if not words:
            return "malformed"
        seq = _number(words[0])
        if seq is not None and len(words) > 1:
            return PayloadLine("ERROR", seq, detail=" ".join(words[1:]))
        return PayloadLine("ERROR", 0, detail=" ".join(words))
    return "unknown"


def format_command(command: PayloadCommand) -> bytes | None:
    """The line for ``command``, or None for an action the protocol has no line for."""
    if command.action != "capture" or not 0 <= command.request_id <= MAX_SEQ:
        return None
    return f"CAPTURE {command.request_id}\n".encode("ascii")


_KINDS: Final = {"PHOTO": "captured", "REFUSED": "refused", "ERROR": "error"}


class LineSplitter:
    r"""Bytes of a stream in, whole lines out; a line longer than the bound is dropped.

    Args:
        max_line_bytes: Longest line kept (a ``\r`` before the ``\n`` not counted).
    """

    def __init__(self, max_line_bytes: int = MAX_LINE_BYTES) -> None:
        self.max_line_bytes = max_line_bytes
        self._buffer = bytearray()
        self._discarding = False

    def feed(self, data: bytes) -> tuple[list[bytes], int]:
        """Add ``data``; returns the lines it completed and how many overlong ones were dropped."""
        lines: list[bytes] = []
        dropped = 0
        start = 0
        while True:
            end = data.find(b"\n", start)
            if end < 0:
                break
            if self._discarding:
                self._discarding = False
            else:
                self._buffer += data[start:end]
                line = bytes(self._buffer)
                if len(line.removesuffix(b"\r")) > self.max_line_bytes:
                    dropped += 1
                else:
                    lines.append(line)
            self._buffer.clear()
            start = end + 1
        if not self._discarding:
            self._buffer += data[start:]
            if len(self._buffer) > self.max_line_bytes + 1:
                self._buffer.clear()
                self._discarding = True  # drop the rest of this line when it ends
                dropped += 1
        return lines, dropped

    def reset(self) -> None:
        """Forget a partial line (the connection it came on is gone)."""
        self._buffer.clear()
        self._discarding = False


class PayloadAdapter(ABC):
    """One payload's link; typed commands in, typed events out. Never blocks, never raises.

    Args:
        name: The payload's name on this agent (``camera``); every event carries it.
        max_pending_events: Events held for the loop before the oldest is dropped.
    """

    def __init__(self, name: str, *, max_pending_events: int = MAX_PENDING_EVENTS) -> None:
        if not name:
            raise ValueError("payload name must not be empty")
        self.payload = name
        self.stats = PayloadStats()
        self.max_pending_events = max_pending_events
        self._events: collections.deque[PayloadEvent] = collections.deque()

    name: str
    """The link in words, for errors and logs (``payload camera tcp 0.0.0.0:5005``)."""

    @property
    @abstractmethod
    def address(self) -> str:
        """Where the adapter listens, ``host:port`` (the real port once open)."""

    @property
    @abstractmethod
    def connected(self) -> bool:
        """Whether a payload is connected (TCP) or has been heard (UDP)."""

    @abstractmethod
    def open(self) -> None:
        """Start listening; raises :class:`PayloadError`."""

    @abstractmethod
    def _write(self, line: bytes) -> str | None:
        """Write one command line; returns None, or why it was not delivered."""

    @abstractmethod
    def _read(self) -> None:
        """Read what has arrived and hand lines to :meth:`_handle_lines`."""

    @abstractmethod
    def fileno(self) -> int | None:
        """A descriptor readable while something waits, for the shell's selector; or None."""

    @abstractmethod
    def close(self) -> None:
        """Stop listening and drop the payload's connection; calling it again does nothing."""

    def send(self, command: PayloadCommand) -> None:
        """Send ``command`` to the payload; never blocks or raises.

        A command for another payload is a programming error (ValueError). One that
        cannot be delivered or has no line in the protocol is counted and answered
        with an ``error`` event at once.
        """
        if command.payload != self.payload:
            raise ValueError(f"command for payload {command.payload!r} sent to {self.payload!r}")
        line = format_command(command)
        if line is None:
            self._refuse(command, "unsupported action", f"unsupported action {command.action!r}")
            return
        why = self._write(line)
        if why is not None:
            self._refuse(command, why, f"{why}: {self.name}")
            return
        self.stats.commands_sent += 1

    def receive(self) -> list[PayloadEvent]:
        """The events that arrived since the last call, oldest first; never blocks."""
        self._read()
        events = list(self._events)
        self._events.clear()
        self.stats.events += len(events)
        return events

    def _refuse(self, command: PayloadCommand, reason: str, detail: str) -> None:
        self.stats.fail(reason)
        self._push(PayloadEvent(self.payload, "error", command.request_id, detail))

    def _push(self, event: PayloadEvent) -> None:
        if len(self._events) >= self.max_pending_events:
            self._events.popleft()
            self.stats.drop("receive queue")
        self._events.append(event)

    def _handle_lines(self, lines: list[bytes]) -> None:
        for raw in lines:
            if not raw.removesuffix(b"\r"):
                continue  # keep-alive
            parsed = parse_line(raw)
            if isinstance(parsed, str):
                self.stats.drop(parsed)
                continue
            self.stats.lines += 1
            if parsed.verb == "READY":
                self.stats.ready += 1
                continue
            self._push(PayloadEvent(self.payload, _KINDS[parsed.verb], parsed.seq, parsed.detail))

    def __enter__(self) -> PayloadAdapter:
        return self

    def __exit__(
        self,
        exc_type: type[BaseException] | None,
        exc: BaseException | None,
        traceback: TracebackType | None,
    ) -> None:
        self.close()


def _bind_address(address: str) -> tuple[str, int]:
    try:
        return parse_address(address)
    except TransportError as exc:
        raise PayloadError(f"payload: {exc}") from None


class TcpPayloadServer(PayloadAdapter):
    """The mission computer's TCP server; the payload connects (thesis 4.1.4).

    Args:
        name: The payload's name on this agent.
        address: Where to listen, ``host:port`` (``0.0.0.0:5005``; port 0 picks a free one).

    Raises:
        PayloadError: The address is not ``host:port``.
    """

    def __init__(
        self, name: str, address: str, *, max_pending_events: int = MAX_PENDING_EVENTS
    ) -> None:
        super().__init__(name, max_pending_events=max_pending_events)
        self._bind = _bind_address(address)
        self._address = address
        self.name = f"payload {name} tcp {address}"
        self._listener: socket.socket | None = None
        self._conn: socket.socket | None = None
        self._selector: selectors.DefaultSelector | None = None
        self._splitter = LineSplitter()
        self._outbox = bytearray()

    @property
    def address(self) -> str:
        """Where the server listens (the real port once open)."""
        return self._address

    @property
    def connected(self) -> bool:
        """Whether a payload is connected now."""
        return self._conn is not None

    def open(self) -> None:
        """Listen (non-blocking, SO_REUSEADDR so a restart can take the port again).

        Raises:
            PayloadError: The port cannot be bound.
        """
        if self._listener is not None:
            return
        listener = socket.socket(socket.AF_INET, socket.SOCK_STREAM)
        try:
            listener.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
            listener.bind(self._bind)
            listener.listen(4)
            listener.setblocking(False)
        except OSError as exc:
            listener.close()
            raise PayloadError(
                f"{self.name}: cannot listen there ({exc.strerror or exc}); "
                "is another program using this port?"
            ) from None
        host, port = listener.getsockname()[:2]
        self._address = f"{host}:{port}"
        self.name = f"payload {self.payload} tcp {self._address}"
        self._selector = selectors.DefaultSelector()
        self._selector.register(listener, selectors.EVENT_READ)
        self._listener = listener

    def fileno(self) -> int | None:
        """One descriptor readable when a payload connects or sends (None when closed)."""
        return None if self._selector is None else self._selector.fileno()

    def _drop_connection(self) -> None:
        conn, self._conn = self._conn, None
        if conn is None:
            return
        if self._selector is not None:
            with contextlib.suppress(KeyError, ValueError):
                self._selector.unregister(conn)
        with contextlib.suppress(OSError):
            conn.shutdown(socket.SHUT_RDWR)
        conn.close()
        self._splitter.reset()
        self._outbox.clear()

    def _accept(self) -> None:
        listener = self._listener
        if listener is None:
            return
        while True:
            try:
                conn, _peer = listener.accept()
            except (BlockingIOError, InterruptedError):
                return
            except OSError:
                self.stats.drop("accept failed")
                return
            self._drop_connection()  # one payload at a time: the newest wins
            if self.stats.connections:
                self.stats.reconnects += 1
            conn.setblocking(False)
            with contextlib.suppress(OSError):
                conn.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)
            self._conn = conn
            self.stats.connections += 1
            if self._selector is not None:
                self._selector.register(conn, selectors.EVENT_READ)

    def _read(self) -> None:
        self._accept()
        conn = self._conn
        if conn is None:
            return
        self._flush()
        for _ in range(MAX_READS_PER_RECEIVE):
            try:
                data = conn.recv(RECEIVE_CHUNK_BYTES)
            except (BlockingIOError, InterruptedError):
                return
            except OSError:
                data = b""
            if not data:
                self.stats.disconnects += 1
                self._drop_connection()
                return
            lines, too_long = self._splitter.feed(data)
            for _ in range(too_long):
                self.stats.drop("too long")
            self._handle_lines(lines)

    def _flush(self) -> str | None:
        conn = self._conn
        if conn is None:
            return "not connected"
        while self._outbox:
            try:
                written = conn.send(self._outbox)
            except (BlockingIOError, InterruptedError):
                return None
            except OSError:
                self.stats.disconnects += 1
                self._drop_connection()
                return "not connected"
            del self._outbox[:written]
        return None

    def _write(self, line: bytes) -> str | None:
        self._accept()
        if self._conn is None:
            return "not connected"
        if len(self._outbox) + len(line) > MAX_OUTBOX_BYTES:
            return "buffer full"
        self._outbox += line
        return self._flush()

    def close(self) -> None:
        """Close the connection and stop listening."""
        self._drop_connection()
        listener, self._listener = self._listener, None
        selector, self._selector = self._selector, None
        if selector is not None:
            selector.close()
        if listener is not None:
            listener.close()


class UdpPayload(PayloadAdapter):
    r"""The line protocol over UDP datagrams (the thesis's UDP payload interface).

    Each datagram holds one or more lines (the last ``\n`` optional); a datagram
    longer than a line's bound with no line end is dropped as ``too long``.

    Args:
        name: The payload's name on this agent.
        address: Where to listen, ``host:port`` (port 0 picks a free one).
        remote: The payload's fixed ``host:port``; None: reply to whoever spoke last.

    Raises:
        PayloadError: An address is not ``host:port``.
    """

    def __init__(
        self,
        name: str,
        address: str,
        *,
        remote: str | None = None,
        max_pending_events: int = MAX_PENDING_EVENTS,
    ) -> None:
        super().__init__(name, max_pending_events=max_pending_events)
        self._bind = _bind_address(address)
        self._remote = _bind_address(remote) if remote is not None else None
        self._peer: tuple[str, int] | None = self._remote
        self._address = address
        self.name = f"payload {name} udp {address}"
        self._sock: socket.socket | None = None

    @property
    def address(self) -> str:
        """Where the adapter listens (the real port once open)."""
        return self._address

    @property
    def connected(self) -> bool:
        """Whether commands have somewhere to go (a fixed remote, or a payload heard)."""
        return self._peer is not None

    def open(self) -> None:
        """Bind the socket (non-blocking).

        Raises:
            PayloadError: The port cannot be bound.
        """
        if self._sock is not None:
            return
        sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        try:
            sock.bind(self._bind)
            sock.setblocking(False)
        except OSError as exc:
            sock.close()
            raise PayloadError(
                f"{self.name}: cannot listen there ({exc.strerror or exc})"
            ) from None
        host, port = sock.getsockname()[:2]
        self._address = f"{host}:{port}"
        self.name = f"payload {self.payload} udp {self._address}"
        self._sock = sock

    def fileno(self) -> int | None:
        """The socket's descriptor; None when closed."""
        return None if self._sock is None else self._sock.fileno()

    def _read(self) -> None:
        sock = self._sock
        if sock is None:
            return
        for _ in range(MAX_READS_PER_RECEIVE):
            try:
                data, sender = sock.recvfrom(RECEIVE_CHUNK_BYTES)
            except (BlockingIOError, InterruptedError):
                return
            except ConnectionRefusedError:
                continue  # an ICMP error for an earlier command: UDP carries on
            except OSError:
                self.stats.drop("socket error")
                return
            source = (str(sender[0]), int(sender[1]))
            if self._remote is None and source != self._peer:
                if self._peer is not None:
                    self.stats.reconnects += 1
                self._peer = source
                self.stats.connections += 1
            splitter = LineSplitter()
            lines, too_long = splitter.feed(data if data.endswith(b"\n") else data + b"\n")
            for _ in range(too_long):
                self.stats.drop("too long")
            self._handle_lines(lines)

    def _write(self, line: bytes) -> str | None:
        sock, peer = self._sock, self._peer
        if sock is None or peer is None:
            return "not connected"
        try:
            sock.sendto(line, peer)
        except BlockingIOError:
            return "buffer full"
        except OSError:
            return "unreachable"
        return None

    def close(self) -> None:
        """Close the socket."""
        sock, self._sock = self._sock, None
        if sock is not None:
            sock.close()


def open_payload(name: str, profile: Mapping[str, Any]) -> PayloadAdapter:
    """The adapter a payload profile's ``connection`` describes, opened.

    - ``{kind: tcp, role: server, address}`` -> :class:`TcpPayloadServer` listening there.
    - ``{kind: udp, address[, remote]}`` -> :class:`UdpPayload`.

    Raises:
        PayloadError: Another kind or role, a missing address, or the port cannot be bound.
    """
    connection = profile.get("connection") or {}
    kind, address = connection.get("kind"), connection.get("address")
    if not address:
        raise PayloadError(f"payload {name}: connection without an address (host:port)")
    adapter: PayloadAdapter
    if kind == "tcp":
        if connection.get("role", "server") != "server":
            raise PayloadError(
                f"payload {name}: the mission computer is the TCP server (role: server); "
                "a payload that serves is not supported"
            )
        adapter = TcpPayloadServer(name, str(address))
    elif kind == "udp":
        remote = connection.get("remote")
        adapter = UdpPayload(name, str(address), remote=str(remote) if remote else None)
    else:
        raise PayloadError(f"payload {name}: unknown connection kind {kind!r}; use tcp or udp")
    adapter.open()
    return adapter
