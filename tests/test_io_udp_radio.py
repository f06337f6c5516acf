"""The UDP radio: unicast, broadcast to peers, bounds and counts, on loopback."""

from __future__ import annotations

import os
import selectors
import socket
import sys
from collections.abc import Iterator

import pytest

from clark_engine.io.radio import RadioError, RadioFrame
from clark_engine.io.udp_radio import UdpRadio

WAIT_S = 5.0


def _wait_frames(radio: UdpRadio, count: int) -> list[RadioFrame]:
    """Frames until ``count`` have arrived, waiting on the descriptor (bounded)."""
    frames: list[RadioFrame] = []
    fd = radio.fileno()
    assert fd is not None
    with selectors.DefaultSelector() as selector:
        selector.register(fd, selectors.EVENT_READ)
        while len(frames) < count:
            if not selector.select(WAIT_S):
                break
            frames += radio.receive()
    return frames


@pytest.fixture
def fleet() -> Iterator[list[UdpRadio]]:
    """Three radios on loopback with ephemeral ports, each knowing the other two."""
    radios = [UdpRadio("127.0.0.1:0") for _ in range(3)]
    try:
        for radio in radios:
            radio.open()
        addresses = [r.address for r in radios]
        for radio in radios:
            radio.set_peers(addresses)  # its own address among them is skipped
            radio.verify()
        yield radios
    finally:
        for radio in radios:
            radio.close()


def test_address_gets_the_real_port() -> None:
    with UdpRadio("127.0.0.1:0") as radio:
        assert isinstance(radio, UdpRadio)
        radio.open()
        host, _, port = radio.address.rpartition(":")
        assert host == "127.0.0.1" and int(port) > 0
        assert radio.name == f"udp {radio.address}"


def test_unicast_reaches_only_its_destination(fleet: list[UdpRadio]) -> None:
    a, b, c = fleet
    a.send(b"to b", b.address)
    frames = _wait_frames(b, 1)
    assert frames == [RadioFrame(a.address, b"to b")]
    assert c.receive() == [] and a.receive() == []
    assert a.stats.sent == 1 and not a.stats.send_failures
    assert b.stats.received == 1 and b.unknown_source_frames == 0


def test_broadcast_reaches_every_peer_but_not_itself(fleet: list[UdpRadio]) -> None:
    a, b, c = fleet
    a.send(b"all", None)
    assert _wait_frames(b, 1) == [RadioFrame(a.address, b"all")]
    assert _wait_frames(c, 1) == [RadioFrame(a.address, b"all")]
    assert a.receive() == []
    assert a.stats.sent == 1


def test_frames_arrive_in_order_one_per_datagram(fleet: list[UdpRadio]) -> None:
    a, b, _ = fleet
    for i in range(10):
        a.send(bytes([i]) * (i + 1), b.address)
    frames = _wait_frames(b, 10)
    assert [f.data for f in frames] == [bytes([i]) * (i + 1) for i in range(10)]


def test_oversize_send_is_counted_not_raised() -> None:
    with UdpRadio("127.0.0.1:0", max_packet_bytes=8) as a, UdpRadio("127.0.0.1:0") as b:
        a.open()
        b.open()
        a.send(b"123456789", b.address)
        a.send(b"12345678", b.address)
        assert a.stats.send_failures == {"oversize": 1}
        assert a.stats.sent == 1
        assert [f.data for f in _wait_frames(b, 1)] == [b"12345678"]


def test_full_queue_drops_oldest_and_counts(fleet: list[UdpRadio]) -> None:
    a, _, _ = fleet
    with UdpRadio("127.0.0.1:0", max_pending_frames=4) as small:
        small.open()
        for i in range(7):
            a.send(bytes([i]), small.address)
        fd = small.fileno()
        assert fd is not None
        with selectors.DefaultSelector() as selector:
            selector.register(fd, selectors.EVENT_READ)
            assert selector.select(WAIT_S)
        frames = small.receive()
        # Loopback delivers each datagram as sendto returns: all 7 are waiting.
        assert [f.data for f in frames] == [bytes([i]) for i in range(3, 7)]
        assert small.stats.dropped == {"receive queue": 3}
        assert small.stats.received == 4


def test_unknown_source_is_handed_up_and_counted(fleet: list[UdpRadio]) -> None:
    _, b, _ = fleet
    with UdpRadio("127.0.0.1:0") as stranger:
        stranger.open()
        stranger.send(b"who?", b.address)
        assert [f.data for f in _wait_frames(b, 1)] == [b"who?"]
        assert b.unknown_source_frames == 1


def test_failures_are_counted_never_raised() -> None:
    radio = UdpRadio("127.0.0.1:0")
    radio.send(b"x", None)  # not open
    radio.open()
    radio.send(b"x", None)  # nobody to broadcast to
    radio.send(b"x", "not an address")
    radio.close()
    radio.close()  # idempotent
    assert radio.stats.send_failures == {"closed": 1, "no peers": 1, "bad address": 1}
    assert radio.fileno() is None and radio.receive() == []
    with pytest.raises(RadioError, match="not open"):
        radio.verify()


def test_bad_addresses_and_busy_port_raise_radio_error() -> None:
    with pytest.raises(RadioError, match="host:port"):
        UdpRadio("nowhere")
    with pytest.raises(RadioError, match="host:port"):
        UdpRadio("127.0.0.1:0", peers=["127.0.0.1"])
    with UdpRadio("127.0.0.1:0") as first:
        first.open()
        second = UdpRadio(first.address)
        with pytest.raises(RadioError, match="cannot listen"):
            second.open()
        assert second.fileno() is None


def test_from_profile_uses_port_broadcast_and_packet_limit() -> None:
    profile = {
        "connection": {"kind": "udp", "port": 14600, "broadcast": "127.255.255.255"},
        "max_packet_bytes": 1400,
    }
    radio = UdpRadio.from_profile(profile, "127.0.0.1:0", peers=["127.0.0.1:15002"])
    assert radio.max_packet_bytes == 1400
    assert radio.address == "127.0.0.1:0"
    assert radio._broadcast_text == "127.255.255.255:14600"
    default = UdpRadio.from_profile(profile)
    assert default.address == "0.0.0.0:14600"


def test_own_address_among_peers_is_skipped() -> None:
    with UdpRadio("127.0.0.1:0") as probe:
        probe.open()
        address = probe.address
    with UdpRadio(address, peers=[address, "127.0.0.1:9"]) as radio:
        radio.open()
        assert radio.peers == ("127.0.0.1:9",)


def test_host_names_resolve_at_open_never_in_the_loop(fleet: list[UdpRadio]) -> None:
    a, b, _ = fleet
    by_name = "localhost:" + b.address.rpartition(":")[2]
    a.set_peers([by_name])
    a.send(b"named", by_name)
    assert [f.data for f in _wait_frames(b, 1)] == [b"named"]
    a.send(b"x", "some-host.invalid:14600")  # not a peer: no DNS lookup in the loop
    assert a.stats.send_failures == {"bad address": 1}


@pytest.mark.skipif(not sys.platform.startswith("linux"), reason="SO_RXQ_OVFL is Linux's")
def test_datagrams_the_kernel_dropped_are_counted() -> None:
    """A flood that overfills the socket's buffer before the loop reads: the kernel's
    drops are counted, so every datagram sent is either received or counted lost."""
    with UdpRadio("127.0.0.1:0", max_pending_frames=100_000) as radio:
        radio.open()
        fd = radio.fileno()
        assert fd is not None
        # The same socket, its buffer made as small as the kernel allows (about 2 KiB).
        view = socket.socket(fileno=os.dup(fd))
        view.setsockopt(socket.SOL_SOCKET, socket.SO_RCVBUF, 1)
        view.close()
        sent = 2000
        port = int(radio.address.split(":")[1])
        frames: list[RadioFrame] = []
        with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as flood:
            for i in range(sent):
                flood.sendto(i.to_bytes(4, "big"), ("127.0.0.1", port))
            while batch := radio.receive():
                frames += batch
            # The kernel hands its count with a datagram queued after the drops: the next.
            flood.sendto(b"next", ("127.0.0.1", port))
            frames += _wait_frames(radio, 1)
        kernel = radio.stats.dropped.get("kernel", 0)
        assert kernel > 0, "the buffer overflowed, and the drops are counted"
        assert len(frames) + kernel == sent + 1
