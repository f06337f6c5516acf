"""``clark payload-sim camera``: the thesis's Raspberry Pi camera, played against a real adapter.

The thesis's camera was a Raspberry Pi that connected to the mission computer's
TCP server and answered in ASCII strings (4.1.4). This program is that camera
for rehearsals and bench tests of :mod:`clark_engine.io.payload`, speaking the
line protocol of docs/payloads.md:

- Connects to ``HOST:PORT`` (TCP, or UDP datagrams with ``--udp``) and says
  ``READY``; over UDP it repeats ``READY`` every :data:`UDP_KEEPALIVE_S` so an
  adapter started later learns where it is.
- Answers ``CAPTURE <seq>`` with ``PHOTO <seq> <gps_time_ms> IMG_0001.jpg``
  ``--capture-delay-s`` later (files numbered in the order saved). The Pi has
  no GPS receiver: ``gps_time_ms`` is its clock in milliseconds since the Unix
  epoch, standing in for GPS time. Any other line is answered
  ``ERROR unknown command``.
- When the server goes away (or is not up yet) it tries again every
  ``--retry-s`` seconds; captures in progress are forgotten with the connection.
- Ctrl-C (or SIGTERM) stops it with exit code 0; a bad address is a usage
  error (exit 2, no traceback).

Single-threaded around ``selectors``, as the engine is: it never sleeps past a
capture that is due.
"""

from __future__ import annotations

import contextlib
import heapq
import math
import selectors
import signal
import socket
import sys
import time
from types import FrameType
from typing import TextIO

from clark_engine.errors import UsageError
from clark_engine.io.payload import MAX_LINE_BYTES, LineSplitter
from clark_engine.io.transports import TransportError, parse_address

UDP_KEEPALIVE_S = 1.0
"""Seconds between READY datagrams over UDP."""

CONNECT_TIMEOUT_S = 2.0
"""Longest wait for one TCP connection attempt."""


class _Disconnected(Exception):
    """The server closed the connection or the socket failed."""


def _seconds(name: str, value: float, *, positive: bool = False) -> float:
    if not math.isfinite(value) or value < 0 or (positive and value == 0):
        bound = "> 0" if positive else ">= 0"
        raise UsageError(f"{name} must be a number of seconds {bound}, not {value!r}")
    return value


def _resolve(address: str) -> tuple[str, int]:
    try:
        host, port = parse_address(address)
    except TransportError as exc:
        raise UsageError(f"--connect: {exc}") from None
    if port == 0:
        raise UsageError("--connect: port 0 is not a server's port; give the adapter's port")
    try:
        infos = socket.getaddrinfo(host, port, socket.AF_INET)
    except OSError as exc:
        raise UsageError(f"--connect: cannot resolve {host!r} ({exc})") from None
    ip, resolved_port = infos[0][4][:2]
    return str(ip), int(resolved_port)


class _Camera:
    """The camera's state across connections: pending captures and the image counter."""

    def __init__(self, capture_delay_s: float, out: TextIO) -> None:
        self.capture_delay_s = capture_delay_s
        self.out = out
        self.images = 0
        self.pending: list[tuple[float, int]] = []

    def say(self, text: str) -> None:
        print(f"payload-sim camera: {text}", file=self.out, flush=True)

    def answer(self, line: bytes) -> bytes | None:
        """Serve one line from the server; returns a reply to send now, if any."""
        words = line.removesuffix(b"\r").split()
        if not words:
            return None
        if len(words) == 2 and words[0] == b"CAPTURE" and words[1].isdigit():
            seq = int(words[1])
            heapq.heappush(self.pending, (time.monotonic() + self.capture_delay_s, seq))
            return None
        return b"ERROR unknown command\n"

    def due(self) -> list[bytes]:
        """PHOTO lines for the captures finished by now."""
        lines: list[bytes] = []
        now = time.monotonic()
        while self.pending and self.pending[0][0] <= now:
            _, seq = heapq.heappop(self.pending)
            self.images += 1
            gps_time_ms = int(time.time() * 1000)
            name = f"IMG_{self.images:04d}.jpg"
            lines.append(f"PHOTO {seq} {gps_time_ms} {name}\n".encode("ascii"))
            self.say(f"captured {seq} as {name}")
        return lines

    def wait_s(self, limit_s: float) -> float:
        if not self.pending:
            return limit_s
        return max(0.0, min(limit_s, self.pending[0][0] - time.monotonic()))


def _serve_tcp(sock: socket.socket, camera: _Camera) -> None:
    """Serve one TCP connection until it ends (raises :class:`_Disconnected`)."""
    splitter = LineSplitter(MAX_LINE_BYTES)
    _send_all(sock, b"READY\n")
    with selectors.DefaultSelector() as selector:
        selector.register(sock, selectors.EVENT_READ)
        while True:
            if selector.select(camera.wait_s(1.0)):
                try:
                    data = sock.recv(4096)
                except (BlockingIOError, InterruptedError):
                    data = None
                except OSError as exc:
                    raise _Disconnected(exc.strerror or str(exc)) from None
                if data == b"":
                    raise _Disconnected("the server closed the connection")
                if data:
                    lines, _too_long = splitter.feed(data)
                    for line in lines:
                        reply = camera.answer(line)
                        if reply:
                            _send_all(sock, reply)
            for line in camera.due():
                _send_all(sock, line)


def _send_all(sock: socket.socket, data: bytes) -> None:
    try:
        sock.sendall(data)
    except OSError as exc:
        raise _Disconnected(exc.strerror or str(exc)) from None


def _run_tcp(server: tuple[str, int], camera: _Camera, retry_s: float) -> None:
    where = f"{server[0]}:{server[1]}"
    waiting_said = False
    while True:
        try:
            sock = socket.create_connection(server, timeout=CONNECT_TIMEOUT_S)
        except OSError as exc:
            if not waiting_said:
                camera.say(f"cannot connect to {where} ({exc.strerror or exc}); retrying")
                waiting_said = True
            time.sleep(retry_s)
            continue
        waiting_said = False
        with sock:
            sock.settimeout(CONNECT_TIMEOUT_S)  # sendall may wait this long for a full buffer
            camera.say(f"connected to {where}")
            try:
                _serve_tcp(sock, camera)
            except _Disconnected as exc:
                camera.say(f"disconnected ({exc}); reconnecting")
                camera.pending.clear()
        time.sleep(retry_s)


def _run_udp(server: tuple[str, int], camera: _Camera) -> None:
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as sock:
        sock.connect(server)
        sock.setblocking(False)
        camera.say(f"sending to udp {server[0]}:{server[1]}")
        next_ready = time.monotonic()
        with selectors.DefaultSelector() as selector:
            selector.register(sock, selectors.EVENT_READ)
            while True:
                replies: list[bytes] = []
                if time.monotonic() >= next_ready:
                    replies.append(b"READY\n")
                    next_ready = time.monotonic() + UDP_KEEPALIVE_S
                wait_s = camera.wait_s(max(0.0, next_ready - time.monotonic()))
                if not replies and selector.select(wait_s):
                    for _ in range(64):
                        try:
                            data = sock.recv(65536)
                        except (BlockingIOError, InterruptedError):
                            break
                        except OSError:
                            break  # ICMP unreachable: nobody listens yet; READY repeats
                        lines, _too_long = LineSplitter(MAX_LINE_BYTES).feed(
                            data if data.endswith(b"\n") else data + b"\n"
                        )
                        for line in lines:
                            reply = camera.answer(line)
                            if reply:
                                replies.append(reply)
                replies += camera.due()
                for reply in replies:
                    with contextlib.suppress(OSError):
                        sock.send(reply)


def _stop(signum: int, frame: FrameType | None) -> None:
    raise KeyboardInterrupt


def run_camera(
    connect: str,
    *,
    udp: bool = False,
    capture_delay_s: float = 0.8,
    retry_s: float = 1.0,
    out: TextIO | None = None,
) -> int:
    """Play the camera against the adapter at ``connect`` until Ctrl-C; returns the exit code.

    Args:
        connect: The mission computer's adapter, ``host:port``.
        udp: Datagrams instead of a TCP connection.
        capture_delay_s: Time from CAPTURE to PHOTO.
        retry_s: Time between connection attempts.
        out: Where progress lines go (stdout by default).

    Raises:
        UsageError: A bad address or delay (exit 2).
    """
    _seconds("--capture-delay-s", capture_delay_s)
    _seconds("--retry-s", retry_s, positive=True)
    server = _resolve(connect)
    camera = _Camera(capture_delay_s, out if out is not None else sys.stdout)
    previous = signal.signal(signal.SIGTERM, _stop)
    try:
        if udp:
            _run_udp(server, camera)
        else:
            _run_tcp(server, camera, retry_s)
    except KeyboardInterrupt:
        camera.say(f"stopped after {camera.images} pictures")
        return 0
    except OSError as exc:
        raise UsageError(f"{connect}: {exc.strerror or exc}") from None
    finally:
        signal.signal(signal.SIGTERM, previous)
    return 0  # pragma: no cover - the loops end only by Ctrl-C
