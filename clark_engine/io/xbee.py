"""The XBee DigiMesh radio: ClarkLink packets over XBee-PRO 900HP modules, through digi-xbee.

:class:`XBeeRadio` implements :class:`~clark_engine.io.radio.Radio` on a
``DigiMeshDevice`` in API mode 1 (thesis 3.2.1-3.2.7, 4.1.2). The loop never
waits on the radio:

- **Sending** builds a transmit request (``0x10``) with a frame id of its own
  and hands it to the library without waiting (``send_packet(sync=False)``).
  The transmit status (``0x8B``) that answers it arrives later on the library's
  thread and is matched by frame id: SUCCESS counts ``delivered``; anything else
  (``route not found``, ``no ack``...) counts under that reason in
  ``stats.send_failures`` and is logged. A frame id reused before its status
  came back counts as ``no status``.
- **Receiving** goes through the library's data-received callback. digi-xbee
  runs its callbacks on a pool of up to 50 threads, so two callbacks can run
  in any order; the callback therefore only signals, and the frames are taken,
  in order and under one lock, from the library's own receive queue into a
  bounded queue of ours, which :meth:`XBeeRadio.receive` drains. A byte on a
  pipe (:meth:`XBeeRadio.fileno`) wakes the shell's selector; the flag that
  guards it is set and cleared under the same lock as the queue, so no frame
  is ever left waiting without the pipe readable.
- **The library's traps.** Its receive queue (40 frames) silently drops the
  oldest when full: every callback corresponds to one frame the library
  queued, so frames called back minus frames taken is the count it dropped,
  kept in ``stats.dropped["xbee queue"]``. Our own queue, when the loop falls
  behind, drops the oldest too, counted as ``receive queue``. An exception in
  our handling never reaches the library (caught, logged, counted as
  ``receive handler``). A serial error (the dongle pulled out) either kills the
  library's reader thread or leaves it spinning on "device reports readiness to
  read but returned no data", logging a warning per turn (digi-xbee 1.5 goes
  round its loop again on that error, tens of thousands of times a second); a
  supervisor thread notices (the reader reported a serial error, stopped, the
  port closed, or the port's path no longer leads to the device we hold),
  closes the device, which stops the reader, and opens it again every
  ``health_interval_s`` until the radio answers, counting ``stats.reconnects``.
  Meanwhile sends count as ``link down``; the loop never blocks. Each loss and
  each return is queued as a :class:`~clark_engine.io.radio.LinkEvent`
  (:meth:`XBeeRadio.link_events`, with the wake-up pipe made readable) for the
  shell to write once in the interface log with its time.
- **The library's log is contained.** What digi-xbee logs on this radio's
  reader thread goes through a filter of ours (:class:`LibraryLogGate`): the
  first line of each kind per connection is written (without its traceback),
  the rest are counted, in ``stats.library_lines`` and in the loss's line of
  the interface log, and the first serial error wakes the supervisor at once
  rather than at its next check.

Changing parameters (:meth:`XBeeRadio.set_parameter`, :meth:`apply_changes`,
:meth:`write_changes`), reading them and :meth:`verify` are synchronous AT
exchanges: for start-up and ``clark check radio``, not for inside the loop.
"""

from __future__ import annotations

import contextlib
import logging
import os
import threading
import time
from collections import Counter, deque
from collections.abc import Callable
from typing import Any, Final

from digi.xbee.devices import DigiMeshDevice
from digi.xbee.exception import XBeeException
from digi.xbee.models.address import (
    XBee16BitAddress,
    XBee64BitAddress,
)
from digi.xbee.models.mode import OperatingMode
from digi.xbee.models.protocol import XBeeProtocol
from digi.xbee.models.status import TransmitStatus
from digi.xbee.packets.aft import ApiFrameType
from digi.xbee.packets.common import TransmitPacket
from serial import SerialException

from clark_engine.io.radio import (
    MAX_PENDING_FRAMES,
    LinkEvent,
    Radio,
    RadioError,
    RadioFrame,
    RadioStats,
)

log = logging.getLogger(__name__)

BROADCAST: Final = "000000000000FFFF"
"""The 64-bit broadcast address."""

FAILURE_REASONS: Final[dict[int, str]] = {
    0x01: "no ack",
    0x02: "cca failure",
    0x03: "purged",
    0x21: "network ack failure",
    0x22: "not joined",
    0x25: "route not found",
    0x74: "payload too large",
}
"""Transmit status codes as :attr:`RadioStats.send_failures` names them."""

_DEVICE_ERRORS: Final = (XBeeException, SerialException, OSError, ValueError)

LIBRARY_LOGGER: Final = "digi.xbee"
"""The root of digi-xbee's loggers (one per module: ``digi.xbee.reader``...)."""

LIBRARY_KINDS_SHOWN: Final = 4
"""Kinds of library line written per connection; every further line is only counted."""

MAX_LIBRARY_KINDS: Final = 32
"""Kinds of library line counted apart per connection; the rest are counted together."""

MAX_LINK_EVENTS: Final = 64
"""Link events held for the shell before the oldest is dropped (a flapping port)."""

_SERIAL_ERROR: Final = "Serial exception while reading"
"""How digi-xbee's reader starts the warning it logs, and loops on, for a dead port."""


class LibraryLogGate(logging.Filter):
    """Judges what digi-xbee logs on one radio's reader thread: a few lines, the rest counted.

    A logger's filters run on the thread that logs, for records logged on that
    logger itself (not for its children's), so one gate is added to each of
    digi-xbee's loggers and judges only the records of the reader thread it
    watches (:attr:`reader`); records of other threads, and of other radios'
    readers, pass untouched. Of this reader's records, the first of each kind
    (logger, level and message template) is written, its traceback folded into
    one line, up to :data:`LIBRARY_KINDS_SHOWN` kinds; the rest are counted per
    kind. The first "Serial exception while reading" calls ``on_serial_error``.

    Args:
        on_serial_error: Called (on the reader's thread, once per connection)
            with the error's text when the reader reports a serial error.
    """

    def __init__(self, on_serial_error: Callable[[str], None]) -> None:
        super().__init__()
        self.on_serial_error = on_serial_error
        self.reader: threading.Thread | None = None
        """The reader thread watched (None: no record is judged)."""
        self.counts: Counter[str] = Counter()
        """Records of the reader since :meth:`watch` or :meth:`take`, per kind."""
        self.shown = 0
        """Of them, the ones written."""
        self.serial_error: str | None = None
        """The first serial error the reader reported since :meth:`watch` or :meth:`take`."""
        self.serial_error_s: float | None = None
        """When (:func:`time.monotonic`)."""
        self._lock = threading.Lock()

    def watch(self, reader: threading.Thread | None) -> None:
        """Judge the records of ``reader`` from now on, with fresh counts."""
        with self._lock:
            self.reader = reader
            self.counts = Counter()
            self.shown = 0
            self.serial_error = None
            self.serial_error_s = None

    def take(self) -> tuple[Counter[str], int, str | None, float | None]:
        """The counts, lines shown and first serial error (and its time), then reset."""
        with self._lock:
            taken = (self.counts, self.shown, self.serial_error, self.serial_error_s)
            self.counts = Counter()
            self.shown = 0
            self.serial_error = None
            self.serial_error_s = None
        return taken

    def filter(self, record: logging.LogRecord) -> bool:
        """True to write ``record``; False to count it only."""
        reader = self.reader
        if reader is None or threading.current_thread() is not reader:
            return True
        kind = f"{record.name} {record.levelname} {record.msg}"[:160]
        first_error: str | None = None
        with self._lock:
            if kind not in self.counts and len(self.counts) >= MAX_LIBRARY_KINDS:
                kind = "other kinds"  # a message that differs each time stays bounded
            seen = self.counts[kind]
            self.counts[kind] = seen + 1
            if self.serial_error is None and str(record.msg).startswith(_SERIAL_ERROR):
                first_error = self.serial_error = _library_text(record)
                self.serial_error_s = time.monotonic()
            show = seen == 0 and self.shown < LIBRARY_KINDS_SHOWN
            if show:
                self.shown += 1
        if first_error is not None:
            self.on_serial_error(first_error)
        if show and record.exc_info:
            # One line, not a traceback: the exception's type and text stay.
            exc = record.exc_info[1]
            text = _library_text(record)
            record.msg = text if exc is None else f"{text} ({type(exc).__name__})"
            record.args = ()
            record.exc_info = None
            record.exc_text = None
        return show


def _library_text(record: logging.LogRecord) -> str:
    """A library record's message, formatted, on one line; never raises."""
    try:
        text = record.getMessage()
    except Exception:  # a library's bad format arguments must not reach the reader
        text = str(record.msg)
    return " ".join(text.split())[:300]


def _library_loggers() -> list[logging.Logger]:
    """digi-xbee's loggers that exist (one per imported module, and their root)."""
    names = [
        name
        for name in list(logging.root.manager.loggerDict)
        if name == LIBRARY_LOGGER or name.startswith(LIBRARY_LOGGER + ".")
    ]
    return [logging.getLogger(name) for name in sorted({LIBRARY_LOGGER, *names})]


def _kinds(counts: Counter[str]) -> str:
    """The commonest kinds of library line, counted, for one log line."""
    shown = [f'{n} x "{kind}"' for kind, n in counts.most_common(3)]
    if len(counts) > 3:
        shown.append(f"{len(counts) - 3} other kind(s)")
    return ", ".join(shown)


def _hex(value: bytes | bytearray) -> str:
    return bytes(value).hex().upper()


class XBeeRadio(Radio):
    """An XBee DigiMesh radio on a serial port, in API mode.

    Args:
        port: The serial device (``/dev/ttyUSB0``, ``/dev/serial/by-id/...``).
        baud_bps: The module's serial rate (BD; 115200 is BD=7).
        network_id: The DigiMesh network id the profile expects (ID, hex), or None.
        api_mode: The API mode the profile expects (AP): 1, without escapes.
        max_pending_frames: Frames held for the loop before dropping the oldest.
        health_interval_s: How often the supervisor checks the link and retries.
        sync_timeout_s: Time limit of the library's synchronous AT exchanges.
    """

    def __init__(
        self,
        port: str,
        *,
        baud_bps: int = 115200,
        network_id: str | None = None,
        api_mode: int = 1,
        max_pending_frames: int = MAX_PENDING_FRAMES,
        health_interval_s: float = 0.5,
        sync_timeout_s: float = 2.0,
    ) -> None:
        self.name = f"xbee {port}"
        self.stats = RadioStats()
        self.port = port
        self.baud_bps = baud_bps
        self.network_id = network_id
        self.api_mode = api_mode
        self.max_pending_frames = max_pending_frames
        self.health_interval_s = health_interval_s
        self.sync_timeout_s = sync_timeout_s
        self.info: dict[str, str] = {}
        """What :meth:`verify` read: hardware, firmware, node id, network id, API mode."""
        self._address: str | None = None
        self._device: Any = None
        self._generation = 0
        self._link_up = False
        self._closed = True
        self._frames: deque[RadioFrame] = deque()
        self._rx_lock = threading.Lock()
        self._signalled = False
        self._called_back = 0
        self._taken = 0
        self._library_dropped = 0
        self._arrived = 0
        self._tx_lock = threading.Lock()
        self._pending: dict[int, str | None] = {}
        self._device_lock = threading.Lock()
        self._wake_r = -1
        self._wake_w = -1
        self._stop = threading.Event()
        self._poke = threading.Event()
        self._supervisor: threading.Thread | None = None
        self._events: deque[LinkEvent] = deque()
        self._down_since_s: float | None = None
        self._attempts = 0
        self._gate = LibraryLogGate(self._on_serial_error)
        self._gated: list[logging.Logger] = []

    # --- the Radio interface ------------------------------------------------------

    @property
    def address(self) -> str:
        """The transceiver's 64-bit address (SH and SL), 16 hex digits, read on open."""
        if self._address is None:
            raise RadioError(f"{self.name}: not open; its address is read when it opens")
        return self._address

    @property
    def link_up(self) -> bool:
        """Whether the device is open and answering (False while it reconnects)."""
        return self._link_up

    @property
    def frames_arrived(self) -> int:
        """Frames the library called back with since open, across reconnects."""
        return self._arrived

    def open(self) -> None:
        """Open the port, read the transceiver's address and start the supervisor."""
        if not self._closed:
            raise RadioError(f"{self.name}: already open")
        self._wake_r, self._wake_w = os.pipe()
        os.set_blocking(self._wake_r, False)
        os.set_blocking(self._wake_w, False)
        self._closed = False
        self._stop.clear()
        self._poke.clear()
        self._gated = _library_loggers()
        for logger in self._gated:
            logger.addFilter(self._gate)
        try:
            self._connect()
        except RadioError:
            self.close()
            raise
        self._supervisor = threading.Thread(
            target=self._supervise, name=f"xbee-supervisor {self.port}", daemon=True
        )
        self._supervisor.start()

    def verify(self) -> None:
        """Read HV, VR, AP, ID and NI and check them against the profile (3.2.6).

        Raises:
            RadioError: The radio does not answer, or answers other settings than
                the profile's, naming what to change.
        """
        device = self._require_device()
        try:
            hardware = _hex(device.get_parameter("HV"))
            firmware = _hex(device.get_parameter("VR"))
            api_mode = int.from_bytes(device.get_parameter("AP"), "big")
            network = _hex(device.get_parameter("ID"))
            node_id = bytes(device.get_parameter("NI")).decode("ascii", "replace")
        except _DEVICE_ERRORS as exc:
            raise RadioError(f"{self.name}: does not answer AT commands ({exc})") from exc
        self.info = {
            "hardware": hardware,
            "firmware": firmware,
            "api_mode": str(api_mode),
            "network_id": network,
            "node_id": node_id,
            "address": self.address,
        }
        problems = []
        if device.get_protocol() != XBeeProtocol.DIGI_MESH:
            problems.append(f"firmware {firmware} is not DigiMesh; load the DigiMesh firmware")
        if api_mode != self.api_mode:
            problems.append(
                f"API mode is AP={api_mode}, the profile expects AP={self.api_mode};"
                f" set AP={self.api_mode} and write (WR)"
            )
        if self.network_id is not None and network.lstrip("0") != self.network_id.upper().lstrip(
            "0"
        ):
            problems.append(
                f"network id is ID={network}, the profile expects ID={self.network_id};"
                f" set ID={self.network_id} and write (WR)"
            )
        if problems:
            raise RadioError(f"{self.name}: " + "; ".join(problems))

    def send(self, data: bytes, destination: str | None) -> None:
        """Queue ``data`` to a 64-bit address (16 hex digits) or to all (None); never blocks.

        Raises:
            RadioError: ``destination`` is not a 64-bit address (a configuration error).
        """
        target = BROADCAST if destination is None else destination
        try:
            address = XBee64BitAddress.from_hex_string(target)
        except ValueError as exc:
            raise RadioError(f"{self.name}: {target!r} is not a 64-bit XBee address") from exc
        self.stats.sent += 1
        device = self._device
        if device is None or not self._link_up:
            self.stats.fail("link down")
            return
        try:
            frame_id = device.get_next_frame_id()
            packet = TransmitPacket(
                frame_id, address, XBee16BitAddress.UNKNOWN_ADDRESS, 0, 0, rf_data=bytes(data)
            )
            with self._tx_lock:
                if frame_id in self._pending:
                    self.stats.fail("no status")
                self._pending[frame_id] = destination
            device.send_packet(packet, sync=False)
        except _DEVICE_ERRORS as exc:
            with self._tx_lock:
                self._pending.pop(frame_id, None)
            self.stats.fail("serial error")
            log.warning("%s: send failed: %s", self.name, exc)

    def receive(self) -> list[RadioFrame]:
        """The frames that arrived since the last call, oldest first; never blocks."""
        if self._wake_r >= 0:
            with contextlib.suppress(BlockingIOError):
                os.read(self._wake_r, 4096)
        with self._rx_lock:
            frames = list(self._frames)
            self._frames.clear()
            self._signalled = False
        self.stats.received += len(frames)
        return frames

    def fileno(self) -> int | None:
        """The read end of the wake-up pipe: readable while frames or link events wait."""
        return self._wake_r if self._wake_r >= 0 else None

    def link_events(self) -> list[LinkEvent]:
        """The link's losses and returns since the last call, oldest first; never blocks."""
        with self._rx_lock:
            events = list(self._events)
            self._events.clear()
        return events

    def close(self) -> None:
        """Stop the supervisor, close the device and the pipe; idempotent (3.2.7)."""
        if self._closed:
            return
        self._closed = True
        self._stop.set()
        self._poke.set()
        if self._supervisor is not None:
            self._supervisor.join()
            self._supervisor = None
        self._disconnect()
        counts, shown, _error, _error_s = self._gate.take()
        self._count_library_lines(counts, shown)
        for logger in self._gated:
            logger.removeFilter(self._gate)
        self._gated = []
        for fd in (self._wake_r, self._wake_w):
            if fd >= 0:
                os.close(fd)
        self._wake_r = self._wake_w = -1

    # --- parameters (3.2.5) ---------------------------------------------------------

    def get_parameter(self, command: str) -> bytes:
        """Read one AT setting (``"ID"``, ``"NI"``...) as the module returns it."""
        device = self._require_device()
        try:
            return bytes(device.get_parameter(command))
        except _DEVICE_ERRORS as exc:
            raise RadioError(f"{self.name}: cannot read {command}: {exc}") from exc

    def set_parameter(self, command: str, value: bytes, *, apply: bool = True) -> None:
        """Set one AT setting; with ``apply`` False it waits for :meth:`apply_changes`."""
        device = self._require_device()
        try:
            device.set_parameter(command, bytearray(value), apply=apply)
        except _DEVICE_ERRORS as exc:
            raise RadioError(f"{self.name}: cannot set {command}: {exc}") from exc

    def apply_changes(self) -> None:
        """Apply the settings queued with ``apply=False`` (AC)."""
        device = self._require_device()
        try:
            device.apply_changes()
        except _DEVICE_ERRORS as exc:
            raise RadioError(f"{self.name}: cannot apply changes: {exc}") from exc

    def write_changes(self) -> None:
        """Write the settings in force to the module's flash (WR), to survive a power cycle."""
        device = self._require_device()
        try:
            device.write_changes()
        except _DEVICE_ERRORS as exc:
            raise RadioError(f"{self.name}: cannot write changes: {exc}") from exc

    # --- the device and its callbacks --------------------------------------------

    def _require_device(self) -> Any:
        device = self._device
        if device is None or not self._link_up:
            raise RadioError(f"{self.name}: not connected")
        return device

    def _connect(self) -> None:
        """Open a fresh device and hook our callbacks to it; raises RadioError."""
        device = DigiMeshDevice(self.port, self.baud_bps)
        device.set_sync_ops_timeout(self.sync_timeout_s)
        try:
            device.open()
        except _DEVICE_ERRORS as exc:
            with contextlib.suppress(*_DEVICE_ERRORS):
                device.close()
            raise RadioError(
                f"{self.name}: cannot open the radio at {self.baud_bps} baud ({exc});"
                " check the port, the baud rate (BD) and that the module is in API mode (AP=1)"
            ) from exc
        if device.operating_mode != OperatingMode.API_MODE:
            device.close()
            raise RadioError(
                f"{self.name}: the module is in {device.operating_mode}, set AP={self.api_mode}"
            )
        address = str(device.get_64bit_addr()).upper()
        if self._address is not None and address != self._address:
            device.close()
            raise RadioError(
                f"{self.name}: another radio ({address}) answers where {self._address} was"
            )
        with self._rx_lock:
            self._generation += 1
            generation = self._generation
            self._called_back = 0
            self._taken = 0
            self._library_dropped = 0
        self._gate.watch(getattr(device, "_packet_listener", None))  # no accessor either
        device.add_data_received_callback(self._make_data_callback(device, generation))
        device.add_packet_received_callback(self._make_packet_callback(generation))
        with self._device_lock:
            self._device = device
            self._address = address
            self._link_up = True

    def _disconnect(self) -> None:
        with self._device_lock:
            device, self._device = self._device, None
            self._link_up = False
        if device is not None:
            with contextlib.suppress(*_DEVICE_ERRORS):
                device.close()
        with self._tx_lock:
            lost = len(self._pending)
            self._pending.clear()
        for _ in range(lost):
            self.stats.fail("no status")

    def _make_data_callback(self, device: Any, generation: int) -> Callable[[Any], None]:
        def on_data(_message: Any) -> None:
            # Runs on the library's callback pool: nothing may escape from here.
            try:
                self._take_frames(device, generation)
            except Exception:
                log.exception("%s: error while taking a received frame", self.name)
                self.stats.drop("receive handler")

        return on_data

    def _make_packet_callback(self, generation: int) -> Callable[[Any], None]:
        def on_packet(packet: Any) -> None:
            try:
                if packet.get_frame_type() == ApiFrameType.TRANSMIT_STATUS:
                    self._transmit_status(packet.frame_id, packet.transmit_status)
            except Exception:
                log.exception("%s: error while reading a transmit status", self.name)
                self.stats.fail("status handler")

        return on_packet

    def _take_frames(self, device: Any, generation: int) -> None:
        with self._rx_lock:
            if generation != self._generation:
                return
            self._called_back += 1
            self._arrived += 1
            while (message := device.read_data()) is not None:
                self._taken += 1
                frame = self._frame_from_message(message)
                if len(self._frames) >= self.max_pending_frames:
                    self._frames.popleft()
                    self.stats.drop("receive queue")
                self._frames.append(frame)
            # Each callback stands for one frame the library queued; those neither
            # taken now nor before were dropped by its full queue.
            missing = self._called_back - self._taken
            if missing > self._library_dropped:
                self.stats.drop("xbee queue", missing - self._library_dropped)
                self._library_dropped = missing
            if self._frames and not self._signalled:
                self._signalled = True
                with contextlib.suppress(BlockingIOError):
                    os.write(self._wake_w, b"\x01")

    @staticmethod
    def _frame_from_message(message: Any) -> RadioFrame:
        remote = message.remote_device
        source = str(remote.get_64bit_addr()).upper() if remote is not None else ""
        return RadioFrame(
            source=source, data=bytes(message.data), broadcast=bool(message.is_broadcast)
        )

    def _transmit_status(self, frame_id: int, status: Any) -> None:
        with self._tx_lock:
            if frame_id not in self._pending:
                return
            destination = self._pending.pop(frame_id)
        if status == TransmitStatus.SUCCESS:
            if destination is not None:
                self.stats.delivered += 1
            return
        reason = FAILURE_REASONS.get(status.code, str(status.description).lower())
        log.warning(
            "%s: packet to %s not delivered: %s",
            self.name,
            destination or "every radio",
            reason,
        )
        self.stats.fail(reason)

    # --- supervision ------------------------------------------------------------------

    def _on_serial_error(self, _error: str) -> None:
        """The reader reported a serial error (on its thread): check the link now."""
        self._poke.set()

    def _trouble(self) -> str | None:
        """Why the link is down, in words; None while it is healthy."""
        device = self._device
        if device is None:
            return "the device is gone"
        error = self._gate.serial_error
        if error is not None:
            return f"the reader reported a serial error: {error}"
        try:
            if not device.is_open() or not device.serial_port.is_interface_open:
                return "the port closed"
            listener = device._packet_listener  # the library exposes no accessor
            if listener is None or not listener.is_running():
                return "the library's reader stopped"
            # A pulled dongle takes its device node with it (and pty emulation its
            # link); the library's reader may keep spinning on the dead descriptor.
            if os.stat(self.port).st_rdev != os.fstat(device.serial_port.fileno()).st_rdev:
                return "the port's path leads to another device"
        except FileNotFoundError:
            return "the port's path is gone"
        except (OSError, ValueError, AttributeError, SerialException) as exc:
            return f"the port cannot be checked ({exc})"
        return None

    def _count_library_lines(self, counts: Counter[str], shown: int) -> int:
        """Add the library's lines that were counted, not written; return all it logged."""
        logged = sum(counts.values())
        self.stats.library_lines += logged - shown
        return logged

    def _queue_event(self, event: LinkEvent) -> None:
        """Hold ``event`` for :meth:`link_events` and make the wake-up pipe readable."""
        with self._rx_lock:
            if len(self._events) >= MAX_LINK_EVENTS:
                self._events.popleft()
            self._events.append(event)
            if not self._signalled and self._wake_w >= 0:
                self._signalled = True
                with contextlib.suppress(BlockingIOError):
                    os.write(self._wake_w, b"\x01")

    def _lost(self, trouble: str) -> None:
        """Close the device (which stops its reader), then tell the shell once."""
        self._disconnect()
        counts, shown, _error, error_s = self._gate.take()
        logged = self._count_library_lines(counts, shown)
        at_s = error_s if error_s is not None else time.monotonic()
        detail = f"{trouble}; reconnecting every {self.health_interval_s:g} s, sends dropped"
        if logged:
            detail += (
                f"; digi-xbee logged {logged} line(s) on its reader, {shown} written,"
                f" the rest counted: {_kinds(counts)}"
            )
        self._down_since_s = at_s
        self._attempts = 0
        log.warning("%s: serial link lost (%s); reconnecting", self.name, trouble)
        self._queue_event(LinkEvent(up=False, monotonic_s=at_s, detail=detail))

    def _back(self) -> None:
        now_s = time.monotonic()
        down_s = now_s - (self._down_since_s if self._down_since_s is not None else now_s)
        self.stats.reconnects += 1
        log.warning("%s: reconnected after %.1f s", self.name, down_s)
        self._queue_event(
            LinkEvent(
                up=True,
                monotonic_s=now_s,
                detail=f"after {down_s:.1f} s down, {self._attempts} attempt(s)",
            )
        )
        self._down_since_s = None

    def _supervise(self) -> None:
        while True:
            self._poke.wait(self.health_interval_s)
            self._poke.clear()
            if self._stop.is_set():
                return
            try:
                if self._link_up:
                    trouble = self._trouble()
                    if trouble is None:
                        continue
                    self._lost(trouble)
                if self._stop.is_set():
                    return
                self._attempts += 1
                try:
                    self._connect()
                except RadioError as exc:
                    log.debug("%s: not back yet: %s", self.name, exc)
                    continue
                self._back()
            except Exception:
                log.exception("%s: supervisor error", self.name)
