"""XBeeRadio through the real digi-xbee library against emulated 900HP radios."""

from __future__ import annotations

import logging
import selectors
import threading
import time
from collections.abc import Callable, Iterator

import pytest

from clark_engine.io import xbee as xbee_module
from clark_engine.io.radio import RadioError, RadioFrame
from clark_engine.io.xbee import LIBRARY_LOGGER, LibraryLogGate, XBeeRadio
from clark_engine.sim.xbee_emulator import XBeeEmulator

A = "0013A20041000001"
B = "0013A20041000002"
C = "0013A20041000003"
ABSENT = "0013A20041009999"
WAIT_S = 20.0
"""How long a test waits for what must happen (it returns as soon as it does): a bound on a
hang, not a time asserted. A loaded suite took 8 s to reconnect an unplugged radio."""


def wait_for(condition: Callable[[], bool], timeout_s: float = WAIT_S) -> None:
    """Wait until ``condition`` holds, on an event with a time limit (never asserts time)."""
    event = threading.Event()
    deadline = time.monotonic() + timeout_s
    while not condition():
        if time.monotonic() > deadline:
            raise AssertionError("condition not met in time")
        event.wait(0.01)


def collect(radio: XBeeRadio, count: int) -> list[RadioFrame]:
    """Wait on the radio's descriptor, as the shell's selector does, for ``count`` frames."""
    frames: list[RadioFrame] = []
    fd = radio.fileno()
    assert fd is not None
    with selectors.DefaultSelector() as selector:
        selector.register(fd, selectors.EVENT_READ)
        deadline = time.monotonic() + WAIT_S
        while len(frames) < count:
            remaining = deadline - time.monotonic()
            if remaining <= 0:
                raise AssertionError(f"{len(frames)} of {count} frames arrived")
            if selector.select(remaining):
                frames.extend(radio.receive())
    return frames


@pytest.fixture
def emulator() -> Iterator[XBeeEmulator]:
    emu = XBeeEmulator(throughput_bps=None)
    for address, name in ((A, "STATION"), (B, "CUB"), (C, "FOX")):
        emu.add_radio(address, node_id=name)
    emu.start()
    try:
        yield emu
    finally:
        emu.stop()


@pytest.fixture
def make_radio(emulator: XBeeEmulator) -> Iterator[Callable[..., XBeeRadio]]:
    opened: list[XBeeRadio] = []

    def make(address: str, **options: object) -> XBeeRadio:
        options.setdefault("network_id", "5ABC")
        options.setdefault("health_interval_s", 0.05)
        radio = XBeeRadio(emulator.radios[int(address, 16)].port, **options)  # type: ignore[arg-type]
        opened.append(radio)
        radio.open()
        return radio

    try:
        yield make
    finally:
        for radio in opened:
            radio.close()


def test_open_verify_and_read_the_address(make_radio: Callable[..., XBeeRadio]) -> None:
    radio = make_radio(A)
    radio.verify()
    assert radio.address == A
    assert radio.info["network_id"] == "5ABC"
    assert radio.info["api_mode"] == "1"
    assert radio.info["firmware"] == "8074"
    assert radio.info["node_id"] == "STATION"


def test_verify_names_a_wrong_network_id(make_radio: Callable[..., XBeeRadio]) -> None:
    radio = make_radio(A, network_id="7FFF")
    with pytest.raises(RadioError, match=r"ID=5ABC.*expects ID=7FFF"):
        radio.verify()


def test_open_fails_with_a_radio_error_on_a_missing_port() -> None:
    radio = XBeeRadio("/nonexistent/ttyUSB9")
    with pytest.raises(RadioError, match="cannot open"):
        radio.open()
    radio.close()


def test_unicast_reaches_only_its_destination_and_is_confirmed(
    make_radio: Callable[..., XBeeRadio],
) -> None:
    a, b, c = make_radio(A), make_radio(B), make_radio(C)
    a.send(b"to cub", B)
    [frame] = collect(b, 1)
    assert frame == RadioFrame(source=A, data=b"to cub", broadcast=False)
    wait_for(lambda: a.stats.delivered == 1)
    assert a.stats.sent == 1 and not a.stats.send_failures
    assert c.receive() == []


def test_broadcast_reaches_every_other_radio_in_order(
    make_radio: Callable[..., XBeeRadio],
) -> None:
    a, b, c = make_radio(A), make_radio(B), make_radio(C)
    for index in range(20):
        a.send(bytes([index]), None)
    for other in (b, c):
        frames = collect(other, 20)
        assert [f.data[0] for f in frames] == list(range(20))
        assert all(f.broadcast and f.source == A for f in frames)
    assert a.stats.delivered == 0  # broadcasts are never acknowledged


def test_unicast_to_an_absent_address_counts_route_not_found(
    make_radio: Callable[..., XBeeRadio], caplog: pytest.LogCaptureFixture
) -> None:
    a = make_radio(A)
    a.send(b"anyone?", ABSENT)
    wait_for(lambda: a.stats.send_failures.get("route not found") == 1)
    assert "route not found" in caplog.text
    assert a.stats.delivered == 0


def test_loss_fails_unicast_with_no_ack_and_latency_delays_arrival() -> None:
    with XBeeEmulator(loss=1.0, latency_s=0.05, seed=1) as emu:
        emu.add_radio(A)
        emu.add_radio(B)
        a = XBeeRadio(emu.radios[int(A, 16)].port)
        b = XBeeRadio(emu.radios[int(B, 16)].port)
        try:
            a.open()
            b.open()
            a.send(b"lost", B)
            wait_for(lambda: a.stats.send_failures.get("no ack") == 1)
            assert b.receive() == []
            emu.loss = 0.0
            a.send(b"late", B)
            [frame] = collect(b, 1)
            assert frame.data == b"late"
            delivery = emu.deliveries[-1]
            assert delivery.arrival_s - delivery.start_s >= 0.05
        finally:
            a.close()
            b.close()


def test_full_receive_queue_drops_the_oldest_and_counts_it(
    make_radio: Callable[..., XBeeRadio],
) -> None:
    a, b = make_radio(A), make_radio(B, max_pending_frames=4)
    for index in range(10):
        a.send(bytes([index]), B)
    wait_for(lambda: b.frames_arrived == 10)
    frames = b.receive()
    assert [f.data[0] for f in frames] == [6, 7, 8, 9]
    assert b.stats.dropped == {"receive queue": 6}
    assert b.stats.received == 4


def test_the_library_queue_overflow_is_counted(make_radio: Callable[..., XBeeRadio]) -> None:
    a, b = make_radio(A), make_radio(B)
    # Hold our side so the library's 40-frame queue fills and drops the oldest.
    # (Not waiting on a's transmit statuses: b's callbacks, blocked here, hold the
    # library's shared callback pool.)
    with b._rx_lock:
        for index in range(60):
            a.send(bytes([index]), B)
        wait_for(lambda: b._device._packet_listener.get_data_queue().full())
        # The reader has queued 40 and reads the rest already in its pty buffer:
        # give it a moment (a settle, not a timing assertion).
        threading.Event().wait(0.3)
    wait_for(lambda: b.frames_arrived == 60)
    frames = b.receive()
    dropped = b.stats.dropped.get("xbee queue", 0)
    assert dropped > 0
    assert len(frames) + dropped == 60
    assert [f.data[0] for f in frames] == list(range(60 - len(frames), 60))


def test_an_exception_in_our_receive_handling_does_not_close_the_port(
    make_radio: Callable[..., XBeeRadio],
    monkeypatch: pytest.MonkeyPatch,
    caplog: pytest.LogCaptureFixture,
) -> None:
    a, b = make_radio(A), make_radio(B)
    original = XBeeRadio._frame_from_message
    calls = {"n": 0}

    def failing_once(message: object) -> RadioFrame:
        calls["n"] += 1
        if calls["n"] == 1:
            raise RuntimeError("bug in our handling")
        return original(message)

    monkeypatch.setattr(XBeeRadio, "_frame_from_message", staticmethod(failing_once))
    a.send(b"first", B)
    wait_for(lambda: b.stats.dropped.get("receive handler") == 1)
    assert "bug in our handling" in caplog.text
    a.send(b"second", B)
    [frame] = collect(b, 1)
    assert frame.data == b"second"
    assert b.link_up and b.stats.reconnects == 0


def test_serial_error_is_detected_and_the_radio_reconnects(
    emulator: XBeeEmulator, make_radio: Callable[..., XBeeRadio]
) -> None:
    written: list[logging.LogRecord] = []
    handler = logging.Handler()
    handler.emit = written.append  # type: ignore[method-assign]
    logging.getLogger(LIBRARY_LOGGER).addHandler(handler)
    try:
        a, b = make_radio(A), make_radio(B)
        emulated = emulator.radios[int(B, 16)]
        emulated.unplug()
        wait_for(lambda: not b.link_up)
        b.send(b"nobody hears", A)
        assert b.stats.send_failures.get("link down") == 1
        emulated.plug()
        wait_for(lambda: b.link_up)
    finally:
        logging.getLogger(LIBRARY_LOGGER).removeHandler(handler)
    assert b.stats.reconnects == 1
    # The loss and the return, once each, for the shell's interface log.
    [lost, back] = b.link_events()
    assert not lost.up and "serial error" in lost.detail
    assert back.up and "s down" in back.detail and back.monotonic_s >= lost.monotonic_s
    assert b.link_events() == []
    # The library's reader spun on the dead port: one line written at most, the rest
    # counted (none at all when the supervisor saw the path go before the reader spun).
    spun = [r for r in written if r.getMessage().startswith("Serial exception while reading")]
    assert len(spun) <= 1
    assert not spun or "digi-xbee logged" in lost.detail
    assert b.address == B
    a.send(b"welcome back", B)
    [frame] = collect(b, 1)
    assert frame.data == b"welcome back"
    b.send(b"thanks", A)
    assert collect(a, 1)[0].data == b"thanks"


def test_set_apply_and_write_a_parameter(
    emulator: XBeeEmulator, make_radio: Callable[..., XBeeRadio]
) -> None:
    radio = make_radio(A)
    emulated = emulator.radios[int(A, 16)]
    radio.set_parameter("NI", b"HAWK", apply=False)
    assert radio.get_parameter("NI") == b"STATION"
    radio.apply_changes()
    assert radio.get_parameter("NI") == b"HAWK"
    assert emulated.written["NI"] == b"STATION"
    radio.write_changes()
    assert emulated.written["NI"] == b"HAWK"
    radio.set_parameter("PL", b"\x02")
    assert emulated.settings["PL"] == b"\x02"
    with pytest.raises(RadioError, match="cannot set SL"):
        radio.set_parameter("SL", b"\x00")


def test_close_is_idempotent_and_stops_every_thread(
    make_radio: Callable[..., XBeeRadio],
) -> None:
    radio = make_radio(A)
    radio.close()
    radio.close()
    assert radio.fileno() is None
    assert not any(t.name.startswith("xbee-supervisor") for t in threading.enumerate())
    assert xbee_module.BROADCAST == "000000000000FFFF"


def test_the_library_gate_writes_one_line_per_kind_and_counts_the_rest() -> None:
    """digi-xbee's reader logger, on a thread the gate watches, as when a port dies."""
    reader_log = logging.getLogger("digi.xbee.reader")
    written: list[logging.LogRecord] = []
    handler = logging.Handler()
    handler.emit = written.append  # type: ignore[method-assign]
    errors: list[str] = []
    gate = LibraryLogGate(errors.append)

    def spin() -> None:
        for _ in range(1000):
            reader_log.warning("Serial exception while reading: %s", "no data")
        try:
            raise OSError(5, "Input/output error")
        except OSError as exc:
            reader_log.exception(exc)
        reader_log.exception("the same kind again")

    reader = threading.Thread(target=spin)
    gate.watch(reader)
    reader_log.addFilter(gate)
    reader_log.addHandler(handler)
    try:
        reader.start()
        reader.join()
        reader_log.warning("another thread's line passes untouched")
    finally:
        reader_log.removeFilter(gate)
        reader_log.removeHandler(handler)
    assert [r.getMessage() for r in written] == [
        "Serial exception while reading: no data",
        "[Errno 5] Input/output error (OSError)",  # its traceback folded into the line
        "the same kind again",
        "another thread's line passes untouched",
    ]
    assert all(r.exc_info is None for r in written[:-1])
    assert errors == ["Serial exception while reading: no data"]
    counts, shown, error, error_s = gate.take()
    assert sum(counts.values()) == 1002 and shown == 3
    assert error == errors[0] and error_s is not None
