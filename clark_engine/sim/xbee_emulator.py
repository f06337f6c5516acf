"""An emulated network of XBee-PRO 900HP radios in DigiMesh, for tests and rehearsals.

Each :class:`EmulatedRadio` sits on a pseudo-terminal: the adapter
(:class:`clark_engine.io.xbee.XBeeRadio`, through digi-xbee and pyserial) opens
the radio's :attr:`~EmulatedRadio.port` exactly as it would open
``/dev/ttyUSB0``. The port is a symbolic link to the pty's slave, like the
``/dev/serial/by-id`` links udev makes, so a radio that is unplugged
(:meth:`EmulatedRadio.unplug`) and plugged back (:meth:`EmulatedRadio.plug`)
keeps its path while the device behind it changes.

The emulator speaks the API frames of API mode 1 (no escapes, AP=1):

- ``0x08`` AT command and ``0x09`` queued AT command, answered by ``0x88``
  AT command responses. Reads return the values a 900HP running DigiMesh
  firmware 8074 reports (HV 0x2342, VR 0x8074, AP 1, CE 0, the thesis's
  appendix B settings); ``SS`` is refused (invalid command) as on the 900HP,
  which digi-xbee expects while it works out the role on open. A write through
  ``0x08`` takes effect at once, one through ``0x09`` waits for ``AC``; ``WR``
  copies the settings to :attr:`EmulatedRadio.written` (the module's flash).
- ``0x10`` transmit request, acknowledged by a ``0x8B`` transmit status and
  delivered to the addressed radio (or every other radio, for the broadcast
  address ``000000000000FFFF``) as a ``0x90`` receive packet.

The medium is modelled as the thesis measured it (5.1.3): ONE channel shared
by the whole network at ``throughput_bps`` (33 kbit/s, the profile's figure),
so a frame occupies the air for ``(len(data) + frame_overhead_bytes) * 8 /
throughput_bps`` seconds once the channel is free, then arrives ``latency_s``
later. Loss is drawn from a seeded :class:`random.Random`: a lost unicast is
reported to its sender as ``0x01`` MAC ACK failure (the module's retries all
failed); a lost broadcast is simply not heard by that receiver (broadcasts are
never acknowledged). A unicast to an address no radio has is reported as
``0x25`` route not found, after the route discovery time ``route_timeout_s``.
A payload over ``NP`` (256 bytes) is refused with ``0x74`` payload too large.

Everything runs on one background thread (:meth:`XBeeEmulator.start`,
:meth:`XBeeEmulator.stop`), around a selector over the pty masters and a
wake-up pipe; the emulator is also a context manager.
"""

from __future__ import annotations

import contextlib
import heapq
import os
import random
import selectors
import shutil
import tempfile
import threading
import time
import tty
from dataclasses import dataclass, field
from types import TracebackType
from typing import Final

BROADCAST_ADDRESS: Final = 0x000000000000FFFF
"""The 64-bit broadcast address of a transmit request."""

START_DELIMITER: Final = 0x7E

FRAME_AT_COMMAND: Final = 0x08
FRAME_AT_COMMAND_QUEUED: Final = 0x09
FRAME_TRANSMIT_REQUEST: Final = 0x10
FRAME_AT_RESPONSE: Final = 0x88
FRAME_TRANSMIT_STATUS: Final = 0x8B
FRAME_RECEIVE_PACKET: Final = 0x90

AT_OK: Final = 0x00
AT_ERROR: Final = 0x01
AT_INVALID_COMMAND: Final = 0x02
AT_INVALID_PARAMETER: Final = 0x03

STATUS_SUCCESS: Final = 0x00
STATUS_MAC_ACK_FAILURE: Final = 0x01
STATUS_ROUTE_NOT_FOUND: Final = 0x25
STATUS_PAYLOAD_TOO_LARGE: Final = 0x74

RECEIVE_OPTIONS_UNICAST: Final = 0xC1
"""DigiMesh delivery, acknowledged (bit 0)."""
RECEIVE_OPTIONS_BROADCAST: Final = 0xC2
"""DigiMesh delivery, broadcast (bit 1)."""

DISCOVERY_NONE: Final = 0x00
DISCOVERY_ROUTE: Final = 0x02

THROUGHPUT_BPS: Final = 33_000
"""The 900HP's measured throughput at 115200 baud (thesis 5.1.3; the profile's figure)."""
FRAME_OVERHEAD_BYTES: Final = 18
"""API transmit request framing around the data (the profile's ``frame_overhead_bytes``)."""
MAX_PAYLOAD_BYTES: Final = 256
"""NP: the largest RF payload without encryption."""


def default_settings(address: int, node_id: str) -> dict[str, bytes]:
    """The AT settings a 900HP in DigiMesh reports, configured as thesis appendix B.

    Args:
        address: The radio's 64-bit address (its serial number, SH and SL).
        node_id: The node identifier (NI).

    Returns:
        Each two-letter command with its value as the module returns it.
    """
    return {
        "HV": bytes.fromhex("2342"),
        "VR": bytes.fromhex("8074"),
        "AP": b"\x01",
        "BD": b"\x07",
        "SH": (address >> 32).to_bytes(4, "big"),
        "SL": (address & 0xFFFFFFFF).to_bytes(4, "big"),
        "MY": bytes.fromhex("FFFE"),
        "NI": node_id.encode("ascii"),
        "CE": b"\x00",
        "ID": bytes.fromhex("5ABC"),
        "HP": b"\x00",
        "CM": bytes.fromhex("00FFFFFFFFFFFF7FFF"),
        "MT": b"\x03",
        "PL": b"\x04",
        "RR": b"\x0a",
        "NH": b"\x07",
        "MR": b"\x01",
        "NN": b"\x03",
        "BH": b"\x00",
        "DH": b"\x00\x00\x00\x00",
        "DL": bytes.fromhex("0000FFFF"),
        "TO": b"\xc0",
        "NP": MAX_PAYLOAD_BYTES.to_bytes(2, "big"),
        "EE": b"\x00",
        "NO": b"\x00",
        "NT": b"\x82",
    }


ACTIONS: Final = frozenset({"AC", "WR", "RE", "FR"})
"""Commands that act rather than read or write a setting."""


def encode_frame(payload: bytes) -> bytes:
    """Frame ``payload`` (frame type first) as API mode 1: delimiter, length, checksum."""
    checksum = 0xFF - (sum(payload) & 0xFF)
    return bytes([START_DELIMITER]) + len(payload).to_bytes(2, "big") + payload + bytes([checksum])


def decode_frames(buffer: bytearray) -> list[bytes]:
    """Take every complete, well-formed frame's payload off the front of ``buffer``.

    Bytes before a start delimiter and frames with a wrong checksum are dropped, as
    the module does; an incomplete frame stays in ``buffer`` for the next read.
    """
    frames: list[bytes] = []
    while True:
        start = buffer.find(START_DELIMITER)
        if start < 0:
            buffer.clear()
            return frames
        del buffer[:start]
        if len(buffer) < 3:
            return frames
        length = int.from_bytes(buffer[1:3], "big")
        if len(buffer) < length + 4:
            return frames
        payload = bytes(buffer[3 : 3 + length])
        checksum = buffer[3 + length]
        del buffer[: length + 4]
        if (sum(payload) + checksum) & 0xFF == 0xFF and payload:
            frames.append(payload)


@dataclass
class EmulatedRadio:
    """One emulated 900HP on a pseudo-terminal.

    Attributes:
        address: Its 64-bit address (SH and SL).
        port: The path the adapter opens (a link to the pty's slave).
        settings: The settings in force (what reads return).
        written: The settings last written to flash by ``WR``.
        received_frames: API frames (payloads) the radio took from its serial line.
    """

    address: int
    port: str
    settings: dict[str, bytes]
    written: dict[str, bytes] = field(default_factory=dict)
    queued: dict[str, bytes] = field(default_factory=dict)
    received_frames: list[bytes] = field(default_factory=list)
    master_fd: int | None = None
    slave_fd: int | None = None
    inbound: bytearray = field(default_factory=bytearray)
    outbound: bytearray = field(default_factory=bytearray)
    emulator: XBeeEmulator | None = None

    @property
    def address_hex(self) -> str:
        """The address as the hardware profile writes it: 16 hexadecimal digits."""
        return f"{self.address:016X}"

    @property
    def plugged(self) -> bool:
        """Whether the radio has a live serial line."""
        return self.master_fd is not None

    def unplug(self) -> None:
        """Close the pty master: the adapter's serial line fails, as a pulled USB cable."""
        assert self.emulator is not None
        self.emulator._call(self._unplug)

    def plug(self) -> None:
        """Give the radio a new pty behind the same :attr:`port`, as a cable plugged back."""
        assert self.emulator is not None
        self.emulator._call(self._plug)

    def _plug(self) -> None:
        master, slave = os.openpty()
        tty.setraw(slave)
        os.set_blocking(master, False)
        self.master_fd, self.slave_fd = master, slave
        self.inbound.clear()
        self.outbound.clear()
        link = self.port + ".new"
        os.symlink(os.ttyname(slave), link)
        os.replace(link, self.port)

    def _unplug(self) -> None:
        if self.emulator is not None and self.master_fd is not None:
            self.emulator._unregister(self.master_fd)
        for fd in (self.master_fd, self.slave_fd):
            if fd is not None:
                os.close(fd)
        self.master_fd = self.slave_fd = None
        self.outbound.clear()


@dataclass(frozen=True)
class Delivery:
    """One transmission as the emulator scheduled it.

    Attributes:
        source: The sender's address.
        destination: The addressed radio, or :data:`BROADCAST_ADDRESS`.
        size_bytes: The data's length.
        sent_s: When the request reached the sender (monotonic seconds).
        start_s: When the frame took the air (after the channel was free).
        arrival_s: When receivers get it: start + air time + latency.
        lost_to: The receivers that lost it.
    """

    source: int
    destination: int
    size_bytes: int
    sent_s: float
    start_s: float
    arrival_s: float
    lost_to: tuple[int, ...]


@dataclass(order=True)
class _Event:
    due_s: float
    seq: int
    radio: EmulatedRadio = field(compare=False)
    frame: bytes = field(compare=False)


class XBeeEmulator:
    """Several emulated 900HP radios sharing one DigiMesh channel.

    Args:
        loss: Probability that a frame is lost on its way to one receiver.
        latency_s: Time from a frame's last bit on the air to its arrival.
        throughput_bps: The shared channel's throughput (None: instantaneous).
        frame_overhead_bytes: Bytes counted on the air around each frame's data.
        route_timeout_s: How long a unicast to an absent address takes to fail.
        seed: Seed of the loss draws.
    """

    def __init__(
        self,
        *,
        loss: float = 0.0,
        latency_s: float = 0.0,
        throughput_bps: float | None = THROUGHPUT_BPS,
        frame_overhead_bytes: int = FRAME_OVERHEAD_BYTES,
        route_timeout_s: float = 0.05,
        seed: int = 0,
    ) -> None:
        if not 0.0 <= loss <= 1.0:
            raise ValueError(f"loss {loss} is not a probability")
        self.loss = loss
        self.latency_s = latency_s
        self.throughput_bps = throughput_bps
        self.frame_overhead_bytes = frame_overhead_bytes
        self.route_timeout_s = route_timeout_s
        self.radios: dict[int, EmulatedRadio] = {}
        self._random = random.Random(seed)
        self._directory = tempfile.mkdtemp(prefix="clark-xbee-")
        self._selector = selectors.DefaultSelector()
        self._wake_r, self._wake_w = os.pipe()
        os.set_blocking(self._wake_r, False)
        os.set_blocking(self._wake_w, False)
        self._selector.register(self._wake_r, selectors.EVENT_READ)
        self._lock = threading.Lock()
        self._calls: list[tuple[object, threading.Event]] = []
        self._events: list[_Event] = []
        self._seq = 0
        self._channel_free_s = 0.0
        self._registered: dict[int, int] = {}
        self.deliveries: list[Delivery] = []
        """Every frame put on the air, with when it left and when it arrives (for tests)."""
        self._thread: threading.Thread | None = None
        self._stopping = False
        self._closed = False

    # --- building the network -------------------------------------------------

    def add_radio(self, address: int | str, node_id: str = " ") -> EmulatedRadio:
        """Add a radio with a 64-bit ``address`` (int or 16 hex digits); returns it.

        Call before :meth:`start`, or while running (the thread picks it up).
        """
        value = int(address, 16) if isinstance(address, str) else address
        if value in self.radios or value == BROADCAST_ADDRESS:
            raise ValueError(f"address {value:016X} is taken")
        port = os.path.join(self._directory, f"xbee-{value:016X}")
        radio = EmulatedRadio(
            address=value,
            port=port,
            settings=default_settings(value, node_id),
            emulator=self,
        )
        radio.written = dict(radio.settings)
        self.radios[value] = radio
        self._call(radio._plug)
        return radio

    # --- lifecycle -------------------------------------------------------------

    def start(self) -> XBeeEmulator:
        """Start the background thread; returns the emulator."""
        if self._thread is not None:
            raise RuntimeError("emulator already started")
        self._thread = threading.Thread(target=self._run, name="xbee-emulator", daemon=True)
        self._thread.start()
        return self

    def stop(self) -> None:
        """Stop the thread, close every pty and remove the ports; idempotent."""
        if self._closed:
            return
        self._stopping = True
        self._poke()
        if self._thread is not None:
            self._thread.join()
        self._closed = True
        for radio in self.radios.values():
            radio._unplug()
        self._selector.close()
        os.close(self._wake_r)
        os.close(self._wake_w)
        shutil.rmtree(self._directory, ignore_errors=True)

    def __enter__(self) -> XBeeEmulator:
        if self._thread is None:
            self.start()
        return self

    def __exit__(
        self,
        exc_type: type[BaseException] | None,
        exc: BaseException | None,
        traceback: TracebackType | None,
    ) -> None:
        self.stop()

    # --- thread plumbing --------------------------------------------------------

    def _poke(self) -> None:
        with contextlib.suppress(BlockingIOError):
            os.write(self._wake_w, b"\x00")

    def _call(self, function: object) -> None:
        """Run ``function`` on the emulator's thread (at once when not running)."""
        assert callable(function)
        if self._thread is None or not self._thread.is_alive():
            function()
            return
        done = threading.Event()
        with self._lock:
            self._calls.append((function, done))
        self._poke()
        done.wait()

    def _run(self) -> None:
        while not self._stopping:
            self._sync_registrations()
            timeout = None
            if self._events:
                timeout = max(0.0, self._events[0].due_s - time.monotonic())
            for key, mask in self._selector.select(timeout):
                fd = key.fd
                if fd == self._wake_r:
                    with contextlib.suppress(BlockingIOError):
                        os.read(self._wake_r, 4096)
                    continue
                radio = key.data
                assert isinstance(radio, EmulatedRadio)
                if radio.master_fd != fd:
                    continue
                if mask & selectors.EVENT_READ:
                    self._read(radio)
                if mask & selectors.EVENT_WRITE and radio.master_fd is not None:
                    self._flush(radio)
            with self._lock:
                calls, self._calls = self._calls, []
            for function, done in calls:
                assert callable(function)
                try:
                    function()
                finally:
                    done.set()
            self._deliver_due()

    def _unregister(self, fd: int) -> None:
        if self._registered.pop(fd, None) is not None:
            with contextlib.suppress(KeyError, ValueError):
                self._selector.unregister(fd)

    def _sync_registrations(self) -> None:
        wanted: dict[int, tuple[EmulatedRadio, int]] = {}
        for radio in self.radios.values():
            if radio.master_fd is not None:
                mask = selectors.EVENT_READ | (selectors.EVENT_WRITE if radio.outbound else 0)
                wanted[radio.master_fd] = (radio, mask)
        for fd in list(self._registered):
            if fd not in wanted:
                with contextlib.suppress(KeyError, ValueError):
                    self._selector.unregister(fd)
                del self._registered[fd]
        for fd, (radio, mask) in wanted.items():
            if fd not in self._registered:
                self._selector.register(fd, mask, radio)
            elif self._registered[fd] != mask:
                self._selector.modify(fd, mask, radio)
            self._registered[fd] = mask

    def _read(self, radio: EmulatedRadio) -> None:
        assert radio.master_fd is not None
        try:
            chunk = os.read(radio.master_fd, 4096)
        except (BlockingIOError, InterruptedError):
            return
        except OSError:
            # EIO: nobody holds the slave; the radio waits for the port to open again.
            return
        radio.inbound += chunk
        for payload in decode_frames(radio.inbound):
            radio.received_frames.append(payload)
            self._handle(radio, payload)

    def _flush(self, radio: EmulatedRadio) -> None:
        assert radio.master_fd is not None
        try:
            written = os.write(radio.master_fd, radio.outbound)
        except (BlockingIOError, InterruptedError):
            return
        except OSError:
            radio.outbound.clear()
            return
        del radio.outbound[:written]

    def _emit(self, radio: EmulatedRadio, payload: bytes) -> None:
        if radio.master_fd is None:
            return
        radio.outbound += encode_frame(payload)
        self._flush(radio)

    def _schedule(self, due_s: float, radio: EmulatedRadio, payload: bytes) -> None:
        self._seq += 1
        heapq.heappush(self._events, _Event(due_s, self._seq, radio, payload))

    def _deliver_due(self) -> None:
        now = time.monotonic()
        while self._events and self._events[0].due_s <= now:
            event = heapq.heappop(self._events)
            self._emit(event.radio, event.frame)

    # --- the module's behaviour --------------------------------------------------

    def _handle(self, radio: EmulatedRadio, payload: bytes) -> None:
        frame_type = payload[0]
        if frame_type in (FRAME_AT_COMMAND, FRAME_AT_COMMAND_QUEUED) and len(payload) >= 4:
            self._at_command(radio, payload, queued=frame_type == FRAME_AT_COMMAND_QUEUED)
        elif frame_type == FRAME_TRANSMIT_REQUEST and len(payload) >= 14:
            self._transmit(radio, payload)

    def _at_command(self, radio: EmulatedRadio, payload: bytes, *, queued: bool) -> None:
        frame_id = payload[1]
        command = payload[2:4].decode("ascii", errors="replace").upper()
        value = payload[4:]
        status = AT_OK
        answer = b""
        if command == "AC":
            radio.settings.update(radio.queued)
            radio.queued.clear()
        elif command == "WR":
            radio.settings.update(radio.queued)
            radio.queued.clear()
            radio.written = dict(radio.settings)
        elif command in ("RE", "FR"):
            pass
        elif command not in radio.settings:
            status = AT_INVALID_COMMAND
        elif not value:
            answer = radio.settings[command]
        elif command in ("HV", "VR", "SH", "SL", "MY", "NP"):
            status = AT_INVALID_PARAMETER
        elif queued:
            radio.queued[command] = bytes(value)
        else:
            radio.settings[command] = bytes(value)
        if frame_id:
            self._emit(
                radio,
                bytes([FRAME_AT_RESPONSE, frame_id]) + payload[2:4] + bytes([status]) + answer,
            )

    def _transmit(self, radio: EmulatedRadio, payload: bytes) -> None:
        frame_id = payload[1]
        destination = int.from_bytes(payload[2:10], "big")
        data = payload[14:]
        now = time.monotonic()
        if len(data) > MAX_PAYLOAD_BYTES:
            self._status(radio, frame_id, STATUS_PAYLOAD_TOO_LARGE, now)
            return
        broadcast = destination == BROADCAST_ADDRESS
        target = self.radios.get(destination)
        if not broadcast and (target is None or target is radio):
            self._status(radio, frame_id, STATUS_ROUTE_NOT_FOUND, now + self.route_timeout_s)
            return
        start = max(now, self._channel_free_s)
        airtime = 0.0
        if self.throughput_bps:
            airtime = (len(data) + self.frame_overhead_bytes) * 8 / self.throughput_bps
        self._channel_free_s = start + airtime
        arrival = start + airtime + self.latency_s
        source = radio.address.to_bytes(8, "big")
        lost: list[int] = []
        if broadcast:
            for other in self.radios.values():
                if other is radio:
                    continue
                if self._lost():
                    lost.append(other.address)
                    continue
                self._schedule(arrival, other, self._receive_packet(source, data, broadcast=True))
            self._status(radio, frame_id, STATUS_SUCCESS, start + airtime)
        else:
            assert target is not None
            if self._lost():
                lost.append(target.address)
                self._status(radio, frame_id, STATUS_MAC_ACK_FAILURE, arrival)
            else:
                packet = self._receive_packet(source, data, broadcast=False)
                self._schedule(arrival, target, packet)
                self._status(radio, frame_id, STATUS_SUCCESS, arrival)
        self.deliveries.append(
            Delivery(radio.address, destination, len(data), now, start, arrival, tuple(lost))
        )

    def _lost(self) -> bool:
        return self.loss > 0.0 and self._random.random() < self.loss

    @staticmethod
    def _receive_packet(source: bytes, data: bytes, *, broadcast: bool) -> bytes:
        options = RECEIVE_OPTIONS_BROADCAST if broadcast else RECEIVE_OPTIONS_UNICAST
        return bytes([FRAME_RECEIVE_PACKET]) + source + b"\xff\xfe" + bytes([options]) + data

    def _status(self, radio: EmulatedRadio, frame_id: int, status: int, due_s: float) -> None:
        if not frame_id:
            return
        discovery = DISCOVERY_ROUTE if status == STATUS_ROUTE_NOT_FOUND else DISCOVERY_NONE
        frame = bytes([FRAME_TRANSMIT_STATUS, frame_id, 0xFF, 0xFE, 0, status, discovery])
        self._schedule(due_s, radio, frame)
