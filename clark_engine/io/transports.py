"""Byte transports: how an adapter's bytes reach a device, and the device's reach it.

The adapters (:mod:`clark_engine.io.autopilot`) are pure and speak bytes; a
:class:`Transport` moves those bytes over one link. Every transport has the same
small interface so the real-time shell can wait on any of them with
``selectors`` and the simulator can swap a real link for an in-memory one:

- ``send(data) -> int``: write all of ``data`` (bytes written; 0 when a UDP
  listener has no peer yet, since UDP may drop and MAVLink retries).
- ``receive() -> bytes``: whatever has arrived, ``b""`` if nothing; never blocks.
- ``fileno() -> int | None``: the descriptor to wait on, None for in-memory pipes.
- ``close()``: release the device; idempotent.

Failures of the link itself (a device unplugged, a TCP peer gone) raise
:class:`TransportError`, which names the link; the shell reports it and the
adapter's ``lost`` takes it from there. Implementations: :class:`MemoryPipe`
(deterministic, for the dry run and tests), :class:`UdpTransport`,
:class:`TcpTransport` (client) and :class:`SerialTransport` (POSIX termios; a
pseudo-terminal stands in for hardware in tests). :func:`open_transport` builds
one from a hardware profile's ``connection`` mapping.
"""

from __future__ import annotations

import contextlib
import errno
import os
import select
import socket
import termios
from abc import ABC, abstractmethod
from collections.abc import Mapping
from types import TracebackType
from typing import Any, Final

from clark_engine.errors import ClarkError

RECEIVE_CHUNK_BYTES: Final = 65536
"""Largest read per system call (the largest UDP datagram)."""

MAX_RECEIVE_BYTES: Final = 1 << 20
"""Most bytes one ``receive`` returns, so a flooding link cannot starve the loop."""

SEND_TIMEOUT_S: Final = 1.0
"""How long a send may wait for a full stream buffer before the link counts as failed."""

MAX_UDP_PEERS: Final = 8
"""Peers a UDP listener answers at once (a MAVLink router's job beyond that)."""


class TransportError(ClarkError):
    """The link failed: the device is gone, the peer closed, or it cannot be opened."""


class Transport(ABC):
    """One bidirectional byte link; see the module docstring for the contract."""

    name: str
    """The link in words, for errors and logs (``udp 127.0.0.1:14550``)."""

    @abstractmethod
    def send(self, data: bytes) -> int:
        """Write ``data``; returns the number of bytes written (0 when there is no peer)."""

    @abstractmethod
    def receive(self) -> bytes:
        """Everything that has arrived since the last call; ``b""`` if nothing. Never blocks."""

    @abstractmethod
    def fileno(self) -> int | None:
        """The file descriptor to wait on for incoming bytes; None when there is none."""

    @abstractmethod
    def close(self) -> None:
        """Release the link (thesis 4.3.6); calling it again does nothing."""

    def __enter__(self) -> Transport:
        return self

    def __exit__(
        self,
        exc_type: type[BaseException] | None,
        exc: BaseException | None,
        tb: TracebackType | None,
    ) -> None:
        self.close()


class MemoryPipe(Transport):
    """One end of an in-memory byte pipe: deterministic, no threads, no descriptors.

    What one end sends, the other receives at its next :meth:`receive`, whole and
    in order. Build a connected pair with :meth:`pair`.
    """

    def __init__(self, name: str = "memory") -> None:
        self.name = name
        self._inbox = bytearray()
        self._peer: MemoryPipe | None = None
        self._closed = False

    @classmethod
    def pair(cls, name: str = "memory") -> tuple[MemoryPipe, MemoryPipe]:
        """Two connected ends ``(a, b)``: ``a.send`` reaches ``b.receive`` and back."""
        a, b = cls(f"{name} a"), cls(f"{name} b")
        a._peer, b._peer = b, a
        return a, b

    def send(self, data: bytes) -> int:
        """Hand ``data`` to the other end."""
        if self._closed:
            raise TransportError(f"{self.name}: send on a closed pipe")
        peer = self._peer
        if peer is None or peer._closed:
            raise TransportError(f"{self.name}: the other end is closed")
        peer._inbox += data
        return len(data)

    def receive(self) -> bytes:
        """What the other end has sent since the last call."""
        if self._closed:
            raise TransportError(f"{self.name}: receive on a closed pipe")
        data, self._inbox = bytes(self._inbox), bytearray()
        return data

    def fileno(self) -> int | None:
        """None: no descriptor; the simulator polls pipes on its own clock."""
        return None

    def close(self) -> None:
        """Close this end; the other end's sends fail from now on."""
        self._closed = True
        self._inbox = bytearray()


def parse_address(address: str) -> tuple[str, int]:
    """``host:port`` as a socket address.

    Raises:
        TransportError: Not ``host:port`` with a port 0-65535.
    """
    host, sep, port = address.rpartition(":")
    if not sep or not host or not port.isdigit() or int(port) > 65535:
        raise TransportError(f"{address!r} is not host:port (e.g. 127.0.0.1:14550)")
    return host, int(port)


class UdpTransport(Transport):
    """MAVLink over UDP, as SITL, MAVProxy and mavlink-router speak it.

    Two roles, as in pymavlink's ``udpin``/``udpout``:

    - Listener (``bind`` only): waits on a local address, the profile's
      ``connection.address``, where the autopilot (or a router) sends its
      stream; replies go to every peer heard so far (up to
      :data:`MAX_UDP_PEERS`, newest kept), so one simulated vehicle can serve
      the engine and a ground station at once. Until a peer is heard, ``send``
      drops the data and returns 0.
    - Sender (``remote``, optionally ``bind``): sends to one fixed address and
      receives whatever comes back to its own port.

    Datagrams are concatenated on ``receive``: MAVLink frames delimit themselves.

    Args:
        bind: Local address to listen on; port 0 picks a free one (see :attr:`address`).
        remote: Fixed destination; None for a listener.

    Raises:
        TransportError: The address cannot be bound.
    """

    def __init__(
        self, *, bind: tuple[str, int] | None = None, remote: tuple[str, int] | None = None
    ) -> None:
        if bind is None and remote is None:
            raise ValueError("a UDP transport needs a bind address, a remote address, or both")
        self.remote = remote
        self._peers: list[tuple[str, int]] = []
        self._sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        try:
            self._sock.bind(bind if bind is not None else ("0.0.0.0", 0))
        except OSError as exc:
            self._sock.close()
            where = f"{bind[0]}:{bind[1]}" if bind is not None else "0.0.0.0:0"
            raise TransportError(f"udp {where}: cannot listen there ({exc.strerror})") from None
        host, port = self._sock.getsockname()[:2]
        self.address: tuple[str, int] = (host, port)
        """The bound local address (with the real port when 0 was asked)."""
        self.name = f"udp {remote[0]}:{remote[1]}" if remote else f"udp listen {host}:{port}"

    @property
    def peers(self) -> tuple[tuple[str, int], ...]:
        """Addresses a listener has heard from, oldest first."""
        return tuple(self._peers)

    def send(self, data: bytes) -> int:
        """One datagram to the remote, or to every peer a listener has heard."""
        if not data:
            return 0
        targets = [self.remote] if self.remote is not None else self._peers
        sent = 0
        for target in targets:
            try:
                sent = max(sent, self._sock.sendto(data, target))
            except (BlockingIOError, ConnectionRefusedError):
                pass  # UDP may drop; the protocols above retry
            except OSError as exc:
                raise TransportError(f"{self.name}: send failed ({exc.strerror})") from None
        return sent

    def receive(self) -> bytes:
        """Every datagram waiting, concatenated; remembers who sent them."""
        chunks: list[bytes] = []
        size = 0
        while size < MAX_RECEIVE_BYTES:
            try:
                data, sender = self._sock.recvfrom(RECEIVE_CHUNK_BYTES, socket.MSG_DONTWAIT)
            except (BlockingIOError, InterruptedError):
                break
            except ConnectionRefusedError:
                continue  # an ICMP error for an earlier send: UDP carries on
            except OSError as exc:
                raise TransportError(f"{self.name}: receive failed ({exc.strerror})") from None
            peer = (str(sender[0]), int(sender[1]))
            if self.remote is None and peer not in self._peers:
                self._peers.append(peer)
                del self._peers[:-MAX_UDP_PEERS]
            chunks.append(data)
            size += len(data)
        return b"".join(chunks)

    def fileno(self) -> int:
        """The socket's descriptor."""
        return self._sock.fileno()

    def close(self) -> None:
        """Close the socket."""
        self._sock.close()


class TcpTransport(Transport):
    """MAVLink over a TCP connection to a server (SITL's port 5760, a router, a bridge).

    Connects at construction, waiting at most ``connect_timeout_s``. Sends may
    wait up to :data:`SEND_TIMEOUT_S` for a full buffer; receives never wait.

    Raises:
        TransportError: The server cannot be reached.
    """

    def __init__(self, address: tuple[str, int], *, connect_timeout_s: float = 5.0) -> None:
        self.name = f"tcp {address[0]}:{address[1]}"
        try:
            self._sock = socket.create_connection(address, timeout=connect_timeout_s)
        except OSError as exc:
            why = exc.strerror or str(exc)
            raise TransportError(f"{self.name}: cannot connect ({why})") from None
        self._sock.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)
        # Non-blocking: a socket timeout would make even a MSG_DONTWAIT receive wait.
        self._sock.setblocking(False)
        self._closed = False

    def send(self, data: bytes) -> int:
        """Write all of ``data``, waiting at most :data:`SEND_TIMEOUT_S` for a full buffer."""
        view = memoryview(data)
        while view:
            try:
                written = self._sock.send(view)
            except BlockingIOError:
                _ready, writable, _ = select.select([], [self._sock], [], SEND_TIMEOUT_S)
                if not writable:
                    raise TransportError(f"{self.name}: the server does not read") from None
                continue
            except OSError as exc:
                raise TransportError(f"{self.name}: send failed ({exc.strerror})") from None
            view = view[written:]
        return len(data)

    def receive(self) -> bytes:
        """What has arrived.

        Raises:
            TransportError: The server closed the connection.
        """
        chunks: list[bytes] = []
        size = 0
        while size < MAX_RECEIVE_BYTES:
            try:
                data = self._sock.recv(RECEIVE_CHUNK_BYTES)
            except (BlockingIOError, InterruptedError):
                break
            except OSError as exc:
                raise TransportError(f"{self.name}: receive failed ({exc.strerror})") from None
            if not data:
                if chunks:
                    break  # hand over what came before the end; the next call reports it
                raise TransportError(f"{self.name}: the server closed the connection")
            chunks.append(data)
            size += len(data)
        return b"".join(chunks)

    def fileno(self) -> int:
        """The socket's descriptor."""
        return self._sock.fileno()

    def close(self) -> None:
        """Close the connection."""
        if not self._closed:
            self._closed = True
            with contextlib.suppress(OSError):
                self._sock.shutdown(socket.SHUT_RDWR)
            self._sock.close()


def _baud_constant(baud_bps: int) -> int:
    constant = getattr(termios, f"B{baud_bps}", None)
    if not isinstance(constant, int):
        raise TransportError(
            f"{baud_bps} bit/s is not a standard serial rate on this system; "
            "use 57600, 115200, 230400, 460800 or 921600"
        )
    return constant


class SerialTransport(Transport):
    """MAVLink over a serial line (a Pixhawk's USB port, a telemetry UART).

    Opens the device with ``os.open`` and sets it raw, 8 data bits, no parity, one
    stop bit, no flow control, at ``baud_bps``, with POSIX termios: the standard
    library, so no extra dependency and nothing untyped (USB CDC devices such as
    /dev/ttyACM0 ignore the rate; UARTs need it to match the autopilot's
    SERIALn_BAUD). POSIX only, like the mission computers the engine flies on.

    Args:
        device: The device path (``/dev/ttyACM0``).
        baud_bps: Line rate; one of the system's standard rates.

    Raises:
        TransportError: The device cannot be opened or configured.
    """

    def __init__(self, device: str, baud_bps: int = 115200) -> None:
        self.name = f"serial {device}"
        speed = _baud_constant(baud_bps)
        try:
            self._fd: int | None = os.open(device, os.O_RDWR | os.O_NOCTTY | os.O_NONBLOCK)
        except OSError as exc:
            raise TransportError(f"{self.name}: cannot open it ({exc.strerror})") from None
        try:
            attrs = termios.tcgetattr(self._fd)
            iflag, oflag, cflag, lflag, _ispeed, _ospeed, cc = attrs
            # cfmakeraw: no input translation, no output processing, no echo, no signals.
            iflag &= ~(
                termios.IGNBRK
                | termios.BRKINT
                | termios.PARMRK
                | termios.ISTRIP
                | termios.INLCR
                | termios.IGNCR
                | termios.ICRNL
                | termios.IXON
                | termios.IXOFF
                | termios.IXANY
            )
            oflag &= ~termios.OPOST
            lflag &= ~(
                termios.ECHO | termios.ECHONL | termios.ICANON | termios.ISIG | termios.IEXTEN
            )
            cflag &= ~(termios.CSIZE | termios.PARENB | termios.CSTOPB | termios.CRTSCTS)
            cflag |= termios.CS8 | termios.CLOCAL | termios.CREAD
            cc = list(cc)
            cc[termios.VMIN] = 0
            cc[termios.VTIME] = 0
            termios.tcsetattr(
                self._fd, termios.TCSANOW, [iflag, oflag, cflag, lflag, speed, speed, cc]
            )
        except (termios.error, OSError) as exc:
            os.close(self._fd)
            self._fd = None
            raise TransportError(f"{self.name}: not a serial line ({exc})") from None

    def _descriptor(self) -> int:
        if self._fd is None:
            raise TransportError(f"{self.name}: closed")
        return self._fd

    def send(self, data: bytes) -> int:
        """Write all of ``data``, waiting at most :data:`SEND_TIMEOUT_S` for a full buffer."""
        fd = self._descriptor()
        view = memoryview(data)
        while view:
            try:
                written = os.write(fd, view)
            except BlockingIOError:
                _ready, writable, _ = select.select([], [fd], [], SEND_TIMEOUT_S)
                if not writable:
                    raise TransportError(f"{self.name}: the line does not drain") from None
                continue
            except OSError as exc:
                raise TransportError(f"{self.name}: write failed ({exc.strerror})") from None
            view = view[written:]
        return len(data)

    def receive(self) -> bytes:
        """What has arrived.

        Raises:
            TransportError: The device went away (unplugged, or the other end of a
                pseudo-terminal closed).
        """
        fd = self._descriptor()
        chunks: list[bytes] = []
        size = 0
        while size < MAX_RECEIVE_BYTES:
            try:
                data = os.read(fd, RECEIVE_CHUNK_BYTES)
            except BlockingIOError:
                break
            except OSError as exc:
                if exc.errno == errno.EINTR:
                    continue
                raise TransportError(f"{self.name}: read failed ({exc.strerror})") from None
            if not data:
                break  # no data on a non-blocking tty
            chunks.append(data)
            size += len(data)
        return b"".join(chunks)

    def fileno(self) -> int:
        """The device's descriptor."""
        return self._descriptor()

    def close(self) -> None:
        """Close the device."""
        if self._fd is not None:
            fd, self._fd = self._fd, None
            os.close(fd)


def open_transport(connection: Mapping[str, Any]) -> Transport:
    """Open the link a hardware profile's ``connection`` describes.

    - ``{kind: serial, device, baud_bps}`` -> :class:`SerialTransport`.
    - ``{kind: udp, address: host:port}`` -> :class:`UdpTransport` listening on the
      address (where SITL or a router sends the stream), as the schema describes it.
    - ``{kind: tcp, address: host:port}`` -> :class:`TcpTransport` connected to it.

    Raises:
        TransportError: Unknown kind, bad address, or the link cannot be opened.
    """
    kind = connection.get("kind")
    if kind == "serial":
        device = connection.get("device")
        if not device:
            raise TransportError("serial connection without a device (e.g. /dev/ttyACM0)")
        return SerialTransport(str(device), int(connection.get("baud_bps", 115200)))
    if kind in ("udp", "tcp"):
        address = connection.get("address")
        if not address:
            raise TransportError(f"{kind} connection without an address (host:port)")
        where = parse_address(str(address))
        return UdpTransport(bind=where) if kind == "udp" else TcpTransport(where)
    raise TransportError(f"unknown connection kind {kind!r}; use serial, udp or tcp")
