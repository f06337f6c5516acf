"""A radio made of UDP datagrams: rehearsals on one machine, on a LAN, or across computers.

:class:`UdpRadio` has the :class:`~clark_engine.io.radio.Radio` interface of the
XBee radio, so the real-time shell cannot tell them apart. One ClarkLink packet
is one datagram, sent as it is (no extra header), so any tool that speaks
ClarkLink over UDP (a ground station, a packet capture) reads it directly.

Addresses are ``host:port``, as ``hardware_profiles/radios/udp_lan.yaml``'s
``address_pattern`` writes them (IPv4; host names resolve when the radio opens).

- Unicast (``send(data, "10.0.0.12:14600")``): one datagram to that address.
- Broadcast (``send(data, None)``): one datagram to every known peer, the
  addresses given at construction (the other agents' radio addresses from the
  mission), and, when the profile gives one, to its ``connection.broadcast``
  address as well. Sending to the known peers rather than relying on a
  broadcast address is deliberate: loopback broadcast does not work alike on
  every platform, and a list of peers works unchanged whether the agents share
  one computer (``127.0.0.1:15001``, ``127.0.0.1:15002``...) or are spread over
  several (``192.168.1.10:14600``, ``192.168.1.11:14600``...): a fleet over
  several computers is just UDP between them.
- Receive: the socket is non-blocking and :meth:`UdpRadio.fileno` is its
  descriptor, for the shell's selector. :meth:`UdpRadio.receive` reads what the
  kernel holds (at most :data:`READ_BUDGET_FACTOR` times the queue bound per
  call, so a flood cannot starve the loop) into a bounded queue that drops the
  oldest frame when full, counted in ``stats.dropped["receive queue"]``. Datagrams the
  kernel itself dropped because the socket's buffer was full (the loop fell behind a
  flood) are counted in ``stats.dropped["kernel"]``, from the count Linux hands with
  the next datagram queued after them (``SO_RXQ_OVFL``); where the platform has none
  they go uncounted.
  Datagrams from addresses that are not known peers are still handed up (the
  codec's authentication decides, never the source address) but counted in
  :attr:`UdpRadio.unknown_source_frames`. UDP cannot tell a broadcast datagram
  from a unicast one here, so :attr:`RadioFrame.broadcast` is always False.
- Send failures are counted in ``stats.send_failures``, never raised: a packet
  longer than ``max_packet_bytes`` (``oversize``, not sent at all), a full
  socket buffer (``buffer full``), an ICMP port-unreachable from an earlier
  datagram (``unreachable``), any other socket error (``socket error``), a
  broadcast with nobody to send to (``no peers``) and a send on a closed radio
  (``closed``).

Reuse: :func:`clark_engine.io.transports.parse_address` checks the addresses.
:class:`~clark_engine.io.transports.UdpTransport` itself does not fit: it
concatenates datagrams (MAVLink frames delimit themselves; ClarkLink packets on a
radio must arrive one by one, with their sender).
"""

from __future__ import annotations

import collections
import socket
import sys
from collections.abc import Iterable, Mapping
from typing import Any, Final

from clark_engine.io.radio import MAX_PENDING_FRAMES, Radio, RadioError, RadioFrame, RadioStats
from clark_engine.io.transports import TransportError, parse_address

DEFAULT_MAX_PACKET_BYTES: Final = 1400
"""Largest packet sent, as udp_lan.yaml's ``max_packet_bytes`` (one unfragmented datagram)."""

RECEIVE_BUFFER_BYTES: Final = 65536
"""Largest datagram read (the largest UDP datagram); longer ones the kernel truncates."""

READ_BUDGET_FACTOR: Final = 4
"""Datagrams read per :meth:`UdpRadio.receive`, as a multiple of the queue bound."""


SO_RXQ_OVFL: Final = getattr(socket, "SO_RXQ_OVFL", 40)
"""Linux's socket option (asm-generic/socket.h: 40) that hands, with every datagram read,
how many the kernel has dropped on this socket since it opened (a full buffer)."""

_DROPS_CMSG_BYTES: Final = socket.CMSG_SPACE(4)
"""Room for that count: one unsigned 32-bit integer of ancillary data."""

MAX_RESOLVED: Final = 256
"""Destination addresses remembered once resolved (peers' are resolved at open)."""


def _resolve(address: str, *, numeric_only: bool = False) -> tuple[str, int]:
    """``host:port`` as an IPv4 socket address, the host name resolved.

    Args:
        address: ``host:port``.
        numeric_only: Accept only an IP address, never asking DNS (which may block).

    Raises:
        RadioError: Not ``host:port``, or the host name does not resolve.
    """
    try:
        host, port = parse_address(address)
    except TransportError as exc:
        raise RadioError(f"udp radio: {exc}") from None
    flags = socket.AI_NUMERICHOST if numeric_only else 0
    try:
        infos = socket.getaddrinfo(host, port, socket.AF_INET, socket.SOCK_DGRAM, 0, flags)
    except OSError as exc:
        raise RadioError(f"udp radio: cannot resolve {address!r} ({exc})") from None
    ip, resolved_port = infos[0][4][:2]
    return str(ip), int(resolved_port)


class UdpRadio(Radio):
    """One agent's radio over UDP; see the module docstring.

    Args:
        address: Where this radio listens, ``host:port`` (``127.0.0.1:15001``;
            ``0.0.0.0:14600`` on a LAN; port 0 picks a free one, see :attr:`address`).
        peers: The other radios' addresses, the broadcast targets. This radio's own
            address among them is skipped.
        broadcast_address: An extra ``host:port`` every broadcast also goes to (the
            profile's ``connection.broadcast`` with its ``connection.port``); None: peers only.
        max_packet_bytes: Longest packet sent; longer ones are counted ``oversize``.
        max_pending_frames: Frames held for the loop before the oldest is dropped.

    Raises:
        RadioError: An address is not ``host:port``.
        ValueError: A bound below 1.
    """

    def __init__(
        self,
        address: str,
        *,
        peers: Iterable[str] = (),
        broadcast_address: str | None = None,
        max_packet_bytes: int = DEFAULT_MAX_PACKET_BYTES,
        max_pending_frames: int = MAX_PENDING_FRAMES,
    ) -> None:
        if max_packet_bytes < 1 or max_pending_frames < 1:
            raise ValueError("max_packet_bytes and max_pending_frames must be at least 1")
        for text in (address, *peers, *([broadcast_address] if broadcast_address else [])):
            try:
                parse_address(text)
            except TransportError as exc:
                raise RadioError(f"udp radio: {exc}") from None
        self._bind_text = address
        self._peer_texts = tuple(peers)
        self._broadcast_text = broadcast_address
        self.max_packet_bytes = max_packet_bytes
        self.max_pending_frames = max_pending_frames
        self.name = f"udp {address}"
        self.stats = RadioStats()
        self.unknown_source_frames = 0
        self._kernel_drops = 0  # the kernel's running count, as last read (SO_RXQ_OVFL)
        self._counts_kernel_drops = False
        """Frames handed up whose sender is not a known peer (possibly hostile; still handed up)."""
        self._sock: socket.socket | None = None
        self._address = address
        self._own: tuple[str, int] | None = None
        self._peers: list[tuple[str, int]] = []
        self._known: set[tuple[str, int]] = set()
        self._broadcast: tuple[str, int] | None = None
        self._resolved: dict[str, tuple[str, int]] = {}
        self._queue: collections.deque[RadioFrame] = collections.deque()

    @classmethod
    def from_profile(
        cls, profile: Mapping[str, Any], address: str | None = None, peers: Iterable[str] = ()
    ) -> UdpRadio:
        """A radio as a composed ``udp`` radio profile describes it.

        Args:
            profile: The radio profile (``connection.port``, ``connection.broadcast``,
                ``max_packet_bytes``).
            address: This agent's radio address from the mission; ``0.0.0.0:<port>``
                (every interface, the profile's port) when None.
            peers: The other agents' radio addresses.
        """
        connection = profile.get("connection") or {}
        port = int(connection.get("port", 0))
        broadcast = connection.get("broadcast")
        return cls(
            address if address is not None else f"0.0.0.0:{port}",
            peers=peers,
            broadcast_address=f"{broadcast}:{port}" if broadcast and port else None,
            max_packet_bytes=int(profile.get("max_packet_bytes", DEFAULT_MAX_PACKET_BYTES)),
        )

    @property
    def address(self) -> str:
        """This radio's ``host:port``; after :meth:`open`, with the real port if 0 was asked."""
        return self._address

    @property
    def is_open(self) -> bool:
        """Whether the socket is open."""
        return self._sock is not None

    def open(self) -> None:
        """Bind the socket and resolve the peers' addresses (thesis 3.2.1).

        Raises:
            RadioError: An address does not resolve or the port cannot be bound.
        """
        if self._sock is not None:
            return
        bind = _resolve(self._bind_text)
        peers = [_resolve(text) for text in self._peer_texts]
        broadcast = _resolve(self._broadcast_text) if self._broadcast_text else None
        sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        try:
            sock.setblocking(False)
            if broadcast is not None:
                sock.setsockopt(socket.SOL_SOCKET, socket.SO_BROADCAST, 1)
            sock.bind(bind)
            self._counts_kernel_drops = _count_kernel_drops(sock)
        except OSError as exc:
            sock.close()
            raise RadioError(
                f"{self.name}: cannot listen there ({exc.strerror or exc}); "
                "is another agent already using this port?"
            ) from None
        host, port = sock.getsockname()[:2]
        self._own = (str(host), int(port))
        shown_host = self._bind_text.rpartition(":")[0]
        self._address = f"{shown_host}:{port}"
        self.name = f"udp {self._address}"
        self._peers = [peer for peer in dict.fromkeys(peers) if not self._is_self(peer)]
        self._known = set(self._peers)
        self._resolved = dict(zip(self._peer_texts, peers, strict=True))
        self._broadcast = broadcast
        self._sock = sock

    def _is_self(self, peer: tuple[str, int]) -> bool:
        own = self._own
        if own is None or peer[1] != own[1]:
            return False
        return own[0] in ("0.0.0.0", peer[0]) and (own[0] != "0.0.0.0" or _is_local(peer[0]))

    def verify(self) -> None:
        """Check the socket is open and bound (UDP has no device to ask).

        Raises:
            RadioError: The radio is not open.
        """
        if self._sock is None:
            raise RadioError(f"{self.name}: not open; call open() first")
        try:
            self._sock.getsockname()
        except OSError as exc:
            raise RadioError(f"{self.name}: the socket failed ({exc.strerror or exc})") from None

    def set_peers(self, peers: Iterable[str]) -> None:
        """Replace the known peers (addresses learnt after the radio opened, ephemeral ports).

        Raises:
            RadioError: An address is not ``host:port`` or does not resolve.
        """
        texts = tuple(peers)
        resolved = [_resolve(text) for text in texts]
        self._peer_texts = texts
        self._resolved = dict(zip(texts, resolved, strict=True))
        if self._sock is not None:
            self._peers = [peer for peer in dict.fromkeys(resolved) if not self._is_self(peer)]
            self._known = set(self._peers)

    @property
    def peers(self) -> tuple[str, ...]:
        """The known peers' resolved addresses, ``host:port`` (after :meth:`open`)."""
        return tuple(f"{host}:{port}" for host, port in self._peers)

    def send(self, data: bytes, destination: str | None) -> None:
        """One datagram to ``destination`` (``host:port``), or to every peer when None.

        Never raises for the medium's failures and never blocks; they are counted in
        :attr:`stats` (see the module docstring). A destination that is not
        ``host:port`` is counted ``bad address``; so is a host name that is not a
        known peer's (names resolve when the radio opens, never in the loop).
        """
        sock = self._sock
        if sock is None:
            self.stats.fail("closed")
            return
        if len(data) > self.max_packet_bytes:
            self.stats.fail("oversize")
            return
        if destination is None:
            targets = list(self._peers)
            if self._broadcast is not None:
                targets.append(self._broadcast)
            if not targets:
                self.stats.fail("no peers")
                return
        else:
            target = self._resolved.get(destination)
            if target is None:
                try:
                    target = _resolve(destination, numeric_only=True)  # never DNS in the loop
                except RadioError:
                    self.stats.fail("bad address")
                    return
                if len(self._resolved) < MAX_RESOLVED:
                    self._resolved[destination] = target
            targets = [target]
        self.stats.sent += 1
        for target in targets:
            try:
                sock.sendto(data, target)
            except BlockingIOError:
                self.stats.fail("buffer full")
            except ConnectionRefusedError:
                self.stats.fail("unreachable")  # an ICMP error for an earlier datagram
            except OSError:
                self.stats.fail("socket error")

    def receive(self) -> list[RadioFrame]:
        """Every frame that arrived since the last call, oldest first; never blocks."""
        sock = self._sock
        if sock is None:
            return []
        queue = self._queue
        counts = self._counts_kernel_drops
        for _ in range(self.max_pending_frames * READ_BUDGET_FACTOR):
            try:
                if counts:
                    data, ancillary, _flags, sender = sock.recvmsg(
                        RECEIVE_BUFFER_BYTES, _DROPS_CMSG_BYTES
                    )
                    self._note_kernel_drops(ancillary)
                else:
                    data, sender = sock.recvfrom(RECEIVE_BUFFER_BYTES)
            except (BlockingIOError, InterruptedError):
                break
            except ConnectionRefusedError:
                continue  # an ICMP error for an earlier send: UDP carries on
            except OSError:
                self.stats.drop("socket error")
                break
            source = (str(sender[0]), int(sender[1]))
            if source not in self._known:
                self.unknown_source_frames += 1
            if len(queue) >= self.max_pending_frames:
                queue.popleft()
                self.stats.drop("receive queue")
            queue.append(RadioFrame(f"{source[0]}:{source[1]}", data))
        frames = list(queue)
        queue.clear()
        self.stats.received += len(frames)
        return frames

    def _note_kernel_drops(self, ancillary: list[tuple[int, int, bytes]]) -> None:
        """Count what the kernel dropped since the last count it handed.

        Its count only grows (wrapping at 2^32) and comes with a datagram queued after
        the drops, so a flood's losses are counted when the next datagram is read.
        """
        for level, kind, data in ancillary:
            if level == socket.SOL_SOCKET and kind == SO_RXQ_OVFL and len(data) >= 4:
                total = int.from_bytes(data[:4], sys.byteorder)
                dropped = (total - self._kernel_drops) % (1 << 32)
                self._kernel_drops = total
                if dropped:
                    self.stats.drop("kernel", dropped)

    def fileno(self) -> int | None:
        """The socket's descriptor, readable while datagrams wait; None when closed."""
        return None if self._sock is None else self._sock.fileno()

    def close(self) -> None:
        """Close the socket (thesis 3.2.2); calling it again does nothing."""
        sock, self._sock = self._sock, None
        if sock is not None:
            sock.close()
        self._queue.clear()


def _count_kernel_drops(sock: socket.socket) -> bool:
    """Ask the kernel for its drop count with every datagram; False where it cannot."""
    if not sys.platform.startswith("linux"):
        return False
    try:
        sock.setsockopt(socket.SOL_SOCKET, SO_RXQ_OVFL, 1)
    except OSError:
        return False
    return True


def _is_local(host: str) -> bool:
    return host.startswith("127.") or host == "0.0.0.0"
