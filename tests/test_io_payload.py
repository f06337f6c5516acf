"""Payload adapters: the line protocol, hostile lines, TCP reconnects, UDP, on loopback."""

from __future__ import annotations

import selectors
import socket
from collections.abc import Callable, Iterator

import pytest

from clark_engine.io.payload import (
    MAX_LINE_BYTES,
    LineSplitter,
    PayloadAdapter,
    PayloadError,
    PayloadLine,
    TcpPayloadServer,
    UdpPayload,
    format_command,
    open_payload,
    parse_line,
)
from clark_engine.runtime.commands import PayloadCommand
from clark_engine.runtime.events import PayloadEvent

WAIT_S = 5.0


def _wait(
    adapter: PayloadAdapter, until: Callable[[list[PayloadEvent]], bool]
) -> list[PayloadEvent]:
    """Events until ``until(events)`` holds, waiting on the adapter's descriptor (bounded)."""
    events: list[PayloadEvent] = []
    fd = adapter.fileno()
    assert fd is not None
    with selectors.DefaultSelector() as selector:
        selector.register(fd, selectors.EVENT_READ)
        events += adapter.receive()
        while not until(events):
            if not selector.select(WAIT_S):
                break
            events += adapter.receive()
    return events


def _port(address: str) -> int:
    return int(address.rpartition(":")[2])


@pytest.fixture
def server() -> Iterator[TcpPayloadServer]:
    with TcpPayloadServer("camera", "127.0.0.1:0") as adapter:
        assert isinstance(adapter, TcpPayloadServer)
        adapter.open()
        yield adapter


def _connect(server: TcpPayloadServer) -> socket.socket:
    sock = socket.create_connection(("127.0.0.1", _port(server.address)), timeout=WAIT_S)
    _wait(server, lambda _e: server.connected)
    return sock


@pytest.mark.parametrize(
    ("line", "parsed"),
    [
        (b"READY", PayloadLine("READY")),
        (b"PHOTO 3 1234567 IMG_0001.jpg", PayloadLine("PHOTO", 3, 1234567, "IMG_0001.jpg")),
        (b"PHOTO 3 1234567\r", PayloadLine("PHOTO", 3, 1234567)),
        (b"REFUSED 4 too soon", PayloadLine("REFUSED", 4, detail="too soon")),
        (b"ERROR 5 lens cap on", PayloadLine("ERROR", 5, detail="lens cap on")),
        (b"ERROR disk full", PayloadLine("ERROR", 0, detail="disk full")),
        (b"PHOTO x 1", "malformed"),
        (b"PHOTO 1", "malformed"),
        (b"PHOTO 1 2 ../etc/passwd", "malformed"),
        (b"PHOTO 99999999999999999999 1", "malformed"),
        (b"READY now", "malformed"),
        (b"ERROR", "malformed"),
        (b"photo 1 2", "unknown"),
        (b"SELFDESTRUCT", "unknown"),
        (b"PHOTO 1 2 \xff", "not ascii"),
        (b"READY\x00", "not ascii"),
        (b"A" * (MAX_LINE_BYTES + 1), "too long"),
    ],
)
def test_parse_line(line: bytes, parsed: PayloadLine | str) -> None:
    assert parse_line(line) == parsed


def test_commands_as_lines() -> None:
    assert format_command(PayloadCommand("camera", "capture", 7)) == b"CAPTURE 7\n"
    assert format_command(PayloadCommand("camera", "zoom", 7)) is None


def test_splitter_drops_an_overlong_line_whole_and_resynchronises() -> None:
    splitter = LineSplitter(8)
    lines, dropped = splitter.feed(b"READY\nAAAAAAAAAAAA")
    assert (lines, dropped) == ([b"READY"], 1)
    lines, dropped = splitter.feed(b"AAAA\nPHOTO\nRE")
    assert (lines, dropped) == ([b"PHOTO"], 0)
    assert splitter.feed(b"ADY\r\n") == ([b"READY\r"], 0)


def test_tcp_photo_events_for_capture_commands(server: TcpPayloadServer) -> None:
    with _connect(server) as payload:
        server.send(PayloadCommand("camera", "capture", 1))
        assert payload.recv(64) == b"CAPTURE 1\n"
        payload.sendall(b"READY\nPHOTO 1 1700000000000 IMG_0001.jpg\r\nREFUSED 2 too soon\n")
        events = _wait(server, lambda e: len(e) >= 2)
    assert events == [
        PayloadEvent("camera", "captured", 1, "IMG_0001.jpg"),
        PayloadEvent("camera", "refused", 2, "too soon"),
    ]
    assert server.stats.ready == 1 and server.stats.lines == 3
    assert server.stats.commands_sent == 1 and server.stats.events == 2


def test_tcp_hostile_lines_are_counted_and_dropped(server: TcpPayloadServer) -> None:
    with _connect(server) as payload:
        payload.sendall(
            b"PHOTO one 2\n"  # malformed
            b"LAUNCH 1\n"  # unknown
            + b"X"
            * (MAX_LINE_BYTES * 3)  # too long, across several reads
            + b"\n\xfe\xff\n"  # not ascii
            b"\n"  # keep-alive
            b"ERROR 9 jammed\n"
        )
        events = _wait(server, lambda e: len(e) >= 1)
    assert events == [PayloadEvent("camera", "error", 9, "jammed")]
    assert server.stats.dropped == {"malformed": 1, "unknown": 1, "too long": 1, "not ascii": 1}


def test_tcp_new_connection_replaces_the_old_and_counts(server: TcpPayloadServer) -> None:
    with _connect(server) as first:
        assert server.stats.connections == 1 and server.stats.reconnects == 0
        with socket.create_connection(("127.0.0.1", _port(server.address)), WAIT_S) as second:
            _wait(server, lambda _e: server.stats.connections == 2)
            assert server.stats.reconnects == 1
            assert first.recv(16) == b""  # the old one was closed
            server.send(PayloadCommand("camera", "capture", 4))
            assert second.recv(64) == b"CAPTURE 4\n"
            second.sendall(b"PHOTO 4 5\n")
            assert _wait(server, lambda e: bool(e)) == [PayloadEvent("camera", "captured", 4)]


def test_tcp_payload_gone_then_back(server: TcpPayloadServer) -> None:
    with _connect(server):
        pass
    _wait(server, lambda _e: not server.connected)
    assert server.stats.disconnects == 1
    server.send(PayloadCommand("camera", "capture", 2))
    assert server.receive() == [PayloadEvent("camera", "error", 2, f"not connected: {server.name}")]
    assert server.stats.send_failures == {"not connected": 1}
    with _connect(server) as again:
        assert server.stats.reconnects == 1
        server.send(PayloadCommand("camera", "capture", 3))
        assert again.recv(64) == b"CAPTURE 3\n"


def test_unsupported_action_is_answered_with_an_error(server: TcpPayloadServer) -> None:
    server.send(PayloadCommand("camera", "zoom", 6))
    assert server.receive() == [PayloadEvent("camera", "error", 6, "unsupported action 'zoom'")]
    with pytest.raises(ValueError, match="lidar"):
        server.send(PayloadCommand("lidar", "capture", 1))


def test_event_queue_is_bounded() -> None:
    with TcpPayloadServer("camera", "127.0.0.1:0", max_pending_events=2) as adapter:
        adapter.open()
        for request_id in range(5):
            adapter.send(PayloadCommand("camera", "capture", request_id))
        assert [e.request_id for e in adapter.receive()] == [3, 4]
        assert adapter.stats.dropped == {"receive queue": 3}


def test_udp_adapter_learns_the_payload_and_replies() -> None:
    with (
        UdpPayload("camera", "127.0.0.1:0") as adapter,
        socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as payload,
    ):
        adapter.open()
        payload.bind(("127.0.0.1", 0))
        payload.settimeout(WAIT_S)
        assert not adapter.connected
        payload.sendto(b"READY", ("127.0.0.1", _port(adapter.address)))
        _wait(adapter, lambda _e: adapter.connected)
        adapter.send(PayloadCommand("camera", "capture", 1))
        assert payload.recv(64) == b"CAPTURE 1\n"
        payload.sendto(b"PHOTO 1 2 a.jpg\nBOGUS\n", ("127.0.0.1", _port(adapter.address)))
        payload.sendto(b"Z" * 2000, ("127.0.0.1", _port(adapter.address)))
        payload.sendto(b"ERROR 1 late", ("127.0.0.1", _port(adapter.address)))
        events = _wait(adapter, lambda e: len(e) >= 2)
    assert events == [
        PayloadEvent("camera", "captured", 1, "a.jpg"),
        PayloadEvent("camera", "error", 1, "late"),
    ]
    assert adapter.stats.dropped == {"unknown": 1, "too long": 1}


def test_open_payload_from_profile_and_its_errors() -> None:
    profile = {"connection": {"kind": "tcp", "role": "server", "address": "127.0.0.1:0"}}
    with open_payload("camera", profile) as adapter:
        assert isinstance(adapter, TcpPayloadServer) and adapter.fileno() is not None
        with pytest.raises(PayloadError, match="cannot listen"):
            TcpPayloadServer("camera", adapter.address).open()
    with open_payload("camera", {"connection": {"kind": "udp", "address": "127.0.0.1:0"}}) as udp:
        assert isinstance(udp, UdpPayload)
    with pytest.raises(PayloadError, match="role: server"):
        open_payload("camera", {"connection": {"kind": "tcp", "role": "client", "address": "a:1"}})
    with pytest.raises(PayloadError, match="unknown connection kind"):
        open_payload("camera", {"connection": {"kind": "serial", "address": "a:1"}})
    with pytest.raises(PayloadError, match="host:port"):
        TcpPayloadServer("camera", "5005")
    closed = TcpPayloadServer("camera", "127.0.0.1:0")
    closed.close()
    assert closed.fileno() is None and closed.receive() == []
