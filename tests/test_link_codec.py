"""ClarkLink packets: golden bytes, bundling and splitting, every error, replay, counters."""

from __future__ import annotations

import array
import hashlib
import hmac
import struct
from pathlib import Path

import pytest
from test_link_wire import GPS_MS, SAMPLES, lfield, status, vfield

from clark_engine.errors import ClarkError
from clark_engine.link import (
    AgentStatus,
    AgentType,
    BadTag,
    BadVersion,
    BehaviorState,
    ClarkLinkError,
    Codec,
    CounterStore,
    CounterStoreError,
    ForeignMission,
    Heartbeat,
    MalformedPacket,
    OversizePacket,
    Packet,
    ReplayedPacket,
    Terminate,
    TruncatedPacket,
)
from clark_engine.link.packet import HEADER_BYTES, MAX_COUNTER, TAG_BYTES
from clark_engine.link.wire import encoded_size

KEY = bytes(range(32))
OTHER_KEY = bytes(range(1, 33))
MISSION = 7

HEARTBEAT = Heartbeat(
    agent_id=2, gps_time_ms=1_400_000_000_000, mission_id=7, agent_type=AgentType.VEHICLE
)
STATUS = AgentStatus(
    agent_id=2,
    gps_time_ms=1_400_000_000_100,
    lat_deg=30.6319,
    lon_deg=-96.4826,
    alt_m=121.5,
    ground_speed_m_s=17.25,
    climb_rate_m_s=-1.5,
    heading_deg=271.3,
    mode=10,
)

# ------------------------------------------------------------------ golden bytes
# Header: version 1 | flags | mission 7 | sender 2 | destination 1 | counter 1 (48 bits).
GOLDEN_HEADER_PLAIN = "01000000000700020001000000000001"
GOLDEN_HEADER_KEYED = "01010000000700020001000000000001"
# Bundle field 1 (heartbeat), 17 bytes: agent 2, gps time, mission 7, VEHICLE, OK, version 7.
GOLDEN_HEARTBEAT = "0a1108021080e082b4df281807200128013807"
# Bundle field 2 (agent_status), 35 bytes: agent 2, gps time, lat 306319000 (sfixed32 LE),
# lon -964826000, alt 121500 mm (zigzag), 1725 cm/s, -150 cm/s (zigzag), 27130 cdeg, mode 10.
GOLDEN_STATUS = "1223080210e4e082b4df281d980e42122570ec7dc628b8ea0e30bd0d38ab0240fad301480a"
# HMAC-SHA256 over header and bundle under KEY = bytes(range(32)), first 12 bytes.
GOLDEN_TAG = "19f634df72ad0dc8c60eb4da"


def test_golden_bytes_without_a_key() -> None:
    (packet,) = Codec(MISSION, 2).encode([STATUS, HEARTBEAT], destination=1)
    assert packet.hex() == GOLDEN_HEADER_PLAIN + GOLDEN_HEARTBEAT + GOLDEN_STATUS
    assert len(packet) == 72


def test_golden_bytes_with_a_key() -> None:
    (packet,) = Codec(MISSION, 2, KEY).encode([STATUS, HEARTBEAT], destination=1)
    assert packet.hex() == GOLDEN_HEADER_KEYED + GOLDEN_HEARTBEAT + GOLDEN_STATUS + GOLDEN_TAG
    body = packet[:-TAG_BYTES]
    assert hmac.new(KEY, body, hashlib.sha256).digest()[:12].hex() == GOLDEN_TAG


@pytest.mark.parametrize("key", [None, KEY])
def test_golden_bytes_decode_to_what_was_sent(key: bytes | None) -> None:
    tag = GOLDEN_TAG if key else ""
    head = GOLDEN_HEADER_KEYED if key else GOLDEN_HEADER_PLAIN
    data = bytes.fromhex(head + GOLDEN_HEARTBEAT + GOLDEN_STATUS + tag)
    packet = Codec(MISSION, 1, key).decode(data)
    assert packet == Packet(
        mission_id=7,
        sender_id=2,
        destination_id=1,
        counter=1,
        authenticated=key is not None,
        messages=(HEARTBEAT, STATUS),
        size_bytes=len(data),
    )


def test_the_counter_fills_48_bits_big_endian(tmp_path: Path) -> None:
    store = CounterStore(tmp_path / "counter")
    (tmp_path / "counter").write_text(f"{0x0123456789AA - 1}\n")
    (packet,) = Codec(0x0A0B0C0D, 0x0102, counter_store=store).encode(
        [Terminate(0x0102, 5)], destination=0xFFFF
    )
    assert packet[:HEADER_BYTES].hex() == "01000a0b0c0d0102ffff0123456789aa"


# ------------------------------------------------------------------ bundling and splitting


@pytest.mark.parametrize("key", [None, KEY])
def test_every_message_due_goes_in_one_packet_when_it_fits(key: bytes | None) -> None:
    packets = Codec(MISSION, 2, key).encode(SAMPLES, destination=0)
    assert len(packets) == 1
    got = Codec(MISSION, 1, key).decode(packets[0])
    assert got.messages == SAMPLES  # SAMPLES is already in bundle order
    expected = HEADER_BYTES + sum(encoded_size(m) for m in SAMPLES) + (TAG_BYTES if key else 0)
    assert got.size_bytes == len(packets[0]) == expected


def states(count: int, label: str = "s") -> list[BehaviorState]:
    return [BehaviorState(2, GPS_MS + i, (f"{label}{i:03d}",), "tick") for i in range(count)]


@pytest.mark.parametrize("key", [None, KEY])
def test_a_bundle_too_big_for_one_packet_splits_by_whole_messages_in_order(
    key: bytes | None,
) -> None:
    messages = [*states(12), HEARTBEAT, status(mode=1), status(mode=2)]
    limit = 120
    sender, receiver = Codec(MISSION, 2, key), Codec(MISSION, 1, key)
    packets = sender.encode(messages, destination=3, max_packet_bytes=limit)
    assert len(packets) > 1
    decoded = [receiver.decode(p) for p in packets]
    assert all(len(p) <= limit for p in packets)
    assert [p.counter for p in decoded] == list(range(1, len(packets) + 1))
    assert [m for p in decoded for m in p.messages] == [
        HEARTBEAT,
        status(mode=1),
        status(mode=2),
        *states(12),
    ]
    # Greedy: no packet had room for the first message of the next one.
    for packet, following in zip(packets, decoded[1:], strict=False):
        assert len(packet) + encoded_size(following.messages[0]) > limit


def test_a_message_exactly_filling_a_packet_fits() -> None:
    one = Terminate(2, GPS_MS, reason="x" * 50)
    limit = HEADER_BYTES + encoded_size(one) + TAG_BYTES
    (packet,) = Codec(MISSION, 2, KEY).encode([one], 0, max_packet_bytes=limit)
    assert len(packet) == limit
    with pytest.raises(OversizePacket):
        Codec(MISSION, 2, KEY).encode([one], 0, max_packet_bytes=limit - 1)


def test_a_single_message_that_fits_no_packet_raises_and_spends_no_counter() -> None:
    codec = Codec(MISSION, 2, KEY, max_packet_bytes=200)
    huge = Terminate(2, GPS_MS, reason="x" * 300)
    with pytest.raises(OversizePacket, match="terminate message encodes to") as caught:
        codec.encode([HEARTBEAT, huge], destination=0)
    assert caught.value.sender_id == 2
    assert caught.value.mission_id == MISSION
    assert codec.next_counter == 1
    assert len(codec.encode([HEARTBEAT], destination=0)) == 1


def test_nothing_due_sends_nothing() -> None:
    codec = Codec(MISSION, 2)
    assert codec.encode([], destination=0) == []
    assert codec.next_counter == 1


def test_encode_refuses_messages_that_are_not_this_agent_s() -> None:
    codec = Codec(MISSION, 3)
    with pytest.raises(ValueError, match="agent_id 2"):
        codec.encode([STATUS], destination=0)
    with pytest.raises(ValueError, match="mission_id 8"):
        Codec(MISSION, 2).encode([Heartbeat(2, 0, 8, AgentType.MCS)], destination=0)
    with pytest.raises(ValueError, match="destination"):
        Codec(MISSION, 2).encode([STATUS], destination=65536)
    assert codec.next_counter == 1


@pytest.mark.parametrize(
    ("mission_id", "agent_id", "key", "limit"),
    [
        (0, 1, None, 1400),
        (1 << 32, 1, None, 1400),
        (1, 0, None, 1400),
        (1, 65536, None, 1400),
        (1, 1, b"short", 1400),
        (1, 1, None, 20),
    ],
)
def test_the_codec_refuses_impossible_settings(
    mission_id: int, agent_id: int, key: bytes | None, limit: int
) -> None:
    with pytest.raises(ValueError):
        Codec(mission_id, agent_id, key, max_packet_bytes=limit)


# ------------------------------------------------------------------ decode: every error


def plain(**header: int) -> bytes:
    """An unauthenticated Agent Status packet from agent 2, with header fields overwritten."""
    packet = bytearray(Codec(MISSION, 2).encode([status()], 0)[0])
    fields = {"version": 0, "flags": 1, "mission": 2, "sender": 6, "counter": 10}
    for name, value in header.items():
        at = fields[name]
        if name == "mission":
            packet[at : at + 4] = struct.pack(">I", value)
        elif name == "sender":
            packet[at : at + 2] = struct.pack(">H", value)
        elif name == "counter":
            packet[at : at + 6] = value.to_bytes(6, "big")
        else:
            packet[at] = value
    return bytes(packet)


def keyed(messages: list[object] | None = None, key: bytes = KEY, sender: int = 2) -> bytes:
    return Codec(MISSION, sender, key).encode(messages or [status(agent_id=sender)], 0)[0]  # type: ignore[arg-type]


def retag(body: bytes, key: bytes = KEY) -> bytes:
    """Sign arbitrary bytes as header+bundle, as only a key holder could."""
    return body + hmac.new(key, body, hashlib.sha256).digest()[:TAG_BYTES]


@pytest.mark.parametrize(
    ("key", "data", "error", "claims"),
    [
        (None, b"\x01" * 1401, OversizePacket, True),
        (None, b"", TruncatedPacket, False),
        (None, b"\x01" * 15, TruncatedPacket, False),
        (
            KEY,
            plain()[:HEADER_BYTES].replace(b"\x01\x00", b"\x01\x01", 1) + b"x" * 11,
            TruncatedPacket,
            True,
        ),
        (None, plain(version=2), BadVersion, True),
        (None, plain(flags=0x02), MalformedPacket, True),
        (None, plain(sender=0), MalformedPacket, True),
        (None, plain(mission=8), ForeignMission, True),
        (KEY, plain(), BadTag, True),  # unauthenticated where a key is set
        (None, keyed(), BadTag, True),  # authenticated where none is
        (KEY, keyed(key=OTHER_KEY), BadTag, True),  # another key
        (KEY, keyed()[:-1] + bytes([keyed()[-1] ^ 1]), BadTag, True),  # a flipped tag bit
        (
            KEY,
            retag(plain()[:HEADER_BYTES].replace(b"\x01\x00", b"\x01\x01", 1) + b"\xff"),
            MalformedPacket,
            True,
        ),
        (None, plain()[:HEADER_BYTES], MalformedPacket, True),  # empty bundle
        (None, plain(sender=3), MalformedPacket, True),  # status from 2 in a packet from 3
    ],
)
def test_every_error_class_is_reachable(
    key: bytes | None, data: bytes, error: type[ClarkLinkError], claims: bool
) -> None:
    codec = Codec(MISSION, 1, key)
    with pytest.raises(error) as caught:
        codec.decode(data)
    assert type(caught.value) is error
    assert isinstance(caught.value, ClarkError)
    if claims:
        assert caught.value.sender_id is not None
        assert caught.value.mission_id is not None
    else:
        assert caught.value.sender_id is None


def test_a_heartbeat_claiming_another_mission_is_malformed() -> None:
    body = plain()[:HEADER_BYTES] + lfield(
        1, vfield(1, 2) + vfield(3, 8) + vfield(4, 1) + vfield(5, 1)
    )
    with pytest.raises(MalformedPacket, match="heartbeat claims mission 8"):
        Codec(MISSION, 1).decode(body)


def test_a_replayed_packet_is_refused() -> None:
    codec = Codec(MISSION, 1)
    packet = plain()
    codec.decode(packet)
    with pytest.raises(ReplayedPacket) as caught:
        codec.decode(packet)
    assert caught.value.sender_id == 2


def test_checks_run_in_the_documented_order() -> None:
    codec = Codec(MISSION, 1, KEY, max_packet_bytes=100)
    # Oversize beats everything: a huge packet of a foreign mission with a bad version.
    with pytest.raises(OversizePacket):
        codec.decode(plain(version=9, mission=8) + b"\x00" * 100)
    # Version before flags and mission; flags before mission; mission before tag.
    with pytest.raises(BadVersion):
        codec.decode(plain(version=9, flags=0xF0, mission=8))
    with pytest.raises(MalformedPacket, match="flags"):
        codec.decode(plain(flags=0xF0, mission=8))
    with pytest.raises(ForeignMission):
        codec.decode(plain(mission=8))  # also unauthenticated
    # Tag before bundle: garbage that is not signed is a bad tag, not a malformed packet.
    with pytest.raises(BadTag):
        codec.decode(plain(flags=1)[:HEADER_BYTES] + b"\xff" * 20)


@pytest.mark.parametrize("kind", ["bytes", "bytearray", "memoryview", "int-view", "strided"])
def test_decode_takes_any_byte_string(kind: str) -> None:
    packet = keyed()
    data: bytes | bytearray | memoryview
    if kind == "bytes":
        data = packet
    elif kind == "bytearray":
        data = bytearray(packet)
    elif kind == "memoryview":
        data = memoryview(packet)
    elif kind == "int-view":
        data = memoryview(array.array("B", packet)).cast("B").cast("c")
    else:
        doubled = bytes(b for byte in packet for b in (byte, 0))
        data = memoryview(doubled)[::2]
    assert Codec(MISSION, 1, KEY).decode(data).messages == (status(),)


def test_decode_of_something_not_bytes_is_a_caller_s_bug() -> None:
    with pytest.raises(TypeError):
        Codec(MISSION, 1).decode("hello")  # type: ignore[arg-type]


# ------------------------------------------------------------------ replay window


def from_counter(sender: Codec, counter: int) -> bytes:
    sender._next_counter = counter  # tests place a packet at a chosen counter
    return sender.encode([Terminate(sender.agent_id, counter)], destination=0)[0]


def test_replay_window_accepts_out_of_order_within_64_and_refuses_the_rest() -> None:
    sender, receiver = Codec(MISSION, 2, KEY), Codec(MISSION, 1, KEY)
    packets = {n: from_counter(sender, n) for n in (1, 2, 3, 40, 100, 101, 36, 37, 38)}
    assert receiver.decode(packets[100]).counter == 100
    assert receiver.decode(packets[40]).counter == 40  # 60 behind: inside the window
    assert receiver.decode(packets[101]).counter == 101
    assert receiver.decode(packets[38]).counter == 38  # 63 behind 101: the oldest still fresh
    with pytest.raises(ReplayedPacket):
        receiver.decode(packets[37])  # 64 behind: too old
    with pytest.raises(ReplayedPacket):
        receiver.decode(packets[40])  # duplicate inside the window
    with pytest.raises(ReplayedPacket):
        receiver.decode(packets[101])  # duplicate of the highest
    with pytest.raises(ReplayedPacket):
        receiver.decode(packets[3])  # long gone


def test_replay_window_slides_with_the_highest_counter() -> None:
    sender, receiver = Codec(MISSION, 2, KEY), Codec(MISSION, 1, KEY)
    early = from_counter(sender, 10)
    for n in range(1, 74):
        if n != 10:
            receiver.decode(from_counter(sender, n))
    assert receiver.decode(early).counter == 10  # 63 behind 73
    late = from_counter(sender, 9)
    with pytest.raises(ReplayedPacket):
        receiver.decode(late)
    # A jump far ahead clears the window, and what is just behind the jump is fresh.
    receiver.decode(from_counter(sender, 1_000_000))
    assert receiver.decode(from_counter(sender, 999_999)).counter == 999_999


def test_without_a_key_the_window_only_drops_duplicates() -> None:
    """A garbled counter far ahead must not lock the sender out (found in a dry run).

    Without a tag a counter proves nothing, so an unauthenticated packet older than
    the window restarts it instead of being refused; duplicates are still dropped.
    """
    sender, receiver = Codec(MISSION, 2), Codec(MISSION, 1)
    for n in range(1, 6):
        receiver.decode(from_counter(sender, n))
    garbled = bytearray(from_counter(sender, 6))
    garbled[10] ^= 0x40  # the counter's top byte flipped on the way: 2**46 + 6
    assert receiver.decode(bytes(garbled)).counter == (0x40 << 40) + 6
    assert receiver.decode(from_counter(sender, 7)).counter == 7, "not locked out"
    assert receiver.decode(from_counter(sender, 8)).counter == 8
    with pytest.raises(ReplayedPacket):
        receiver.decode(from_counter(sender, 8))  # a duplicate is still a duplicate


def test_with_a_key_an_old_counter_is_still_a_replay() -> None:
    sender, receiver = Codec(MISSION, 2, KEY), Codec(MISSION, 1, KEY)
    receiver.decode(from_counter(sender, 1_000))
    with pytest.raises(ReplayedPacket, match="older than the window"):
        receiver.decode(from_counter(sender, 7))


def test_each_sender_has_its_own_window() -> None:
    receiver = Codec(MISSION, 1)
    receiver.decode(from_counter(Codec(MISSION, 2), 5))
    assert receiver.decode(from_counter(Codec(MISSION, 3), 5)).sender_id == 3


def test_a_forged_packet_changes_no_state() -> None:
    sender, receiver = Codec(MISSION, 2, KEY), Codec(MISSION, 1, KEY)
    genuine = from_counter(sender, 1)
    forged = bytearray(from_counter(Codec(MISSION, 2, OTHER_KEY), 1_000_000))
    with pytest.raises(BadTag):
        receiver.decode(bytes(forged))
    # A genuine packet whose counter was raised in flight fails its tag too.
    raised = bytearray(from_counter(sender, 5))
    raised[10:16] = (10**9).to_bytes(6, "big")
    with pytest.raises(BadTag):
        receiver.decode(bytes(raised))
    # A signed but malformed bundle with a high counter is refused before the window moves.
    signed_garbage = retag(from_counter(sender, 10**6)[:HEADER_BYTES] + b"\xff")
    with pytest.raises(MalformedPacket):
        receiver.decode(signed_garbage)
    assert receiver.decode(genuine).counter == 1


def test_a_foreign_or_malformed_packet_does_not_move_the_window() -> None:
    receiver = Codec(MISSION, 1)
    with pytest.raises(ForeignMission):
        receiver.decode(plain(mission=8, counter=500))
    with pytest.raises(MalformedPacket):
        receiver.decode(plain(sender=3, counter=500))
    assert receiver.decode(plain(counter=1)).counter == 1


# ------------------------------------------------------------------ counters across restarts


def test_a_restarted_agent_never_reuses_a_counter(tmp_path: Path) -> None:
    path = tmp_path / "cub.counter"
    used: list[int] = []
    receiver = Codec(MISSION, 1, KEY)
    for _restart in range(3):
        sender = Codec(MISSION, 2, KEY, counter_store=CounterStore(path, block_size=4))
        for _tick in range(6):
            for packet in sender.encode([HEARTBEAT], destination=0):
                used.append(receiver.decode(packet).counter)  # the peer accepts every one
    assert len(used) == len(set(used)) == 18
    assert used == sorted(used)


def test_counters_are_reserved_on_disk_before_use(tmp_path: Path) -> None:
    path = tmp_path / "cub.counter"
    sender = Codec(MISSION, 2, counter_store=CounterStore(path, block_size=4))
    assert not path.exists()  # nothing reserved until something is sent
    for expected_mark in (4, 4, 4, 4, 8):
        (packet,) = sender.encode([HEARTBEAT], destination=0)
        counter = int.from_bytes(packet[10:16], "big")
        assert counter <= int(path.read_text()) == expected_mark
    assert sorted(p.name for p in tmp_path.iterdir()) == ["cub.counter"]  # no temporary left


def test_the_default_block_is_large_and_the_store_resumes_above_its_mark(tmp_path: Path) -> None:
    path = tmp_path / "counter"
    path.write_text("41\n")
    sender = Codec(MISSION, 2, counter_store=CounterStore(path))
    assert sender.next_counter == 42
    sender.encode([HEARTBEAT], destination=0)
    assert int(path.read_text()) == 42 + 65_536 - 1


def test_a_store_that_cannot_be_written_stops_sending(tmp_path: Path) -> None:
    sender = Codec(MISSION, 2, counter_store=CounterStore(tmp_path / "missing" / "counter"))
    with pytest.raises(CounterStoreError, match="cannot write"):
        sender.encode([HEARTBEAT], destination=0)


@pytest.mark.parametrize("content", ["", "twelve\n", "-4\n", "1e5\n", f"{MAX_COUNTER + 1}\n"])
def test_a_damaged_store_refuses_to_start(tmp_path: Path, content: str) -> None:
    path = tmp_path / "counter"
    path.write_text(content)
    with pytest.raises(CounterStoreError, match="damaged") as caught:
        Codec(MISSION, 2, counter_store=CounterStore(path))
    assert caught.value.file == str(path)


def test_the_counter_stops_at_48_bits(tmp_path: Path) -> None:
    path = tmp_path / "counter"
    path.write_text(f"{MAX_COUNTER - 1}\n")
    sender = Codec(MISSION, 2, counter_store=CounterStore(path))
    (last,) = sender.encode([HEARTBEAT], destination=0)
    assert last[10:16] == b"\xff" * 6
    with pytest.raises(CounterStoreError, match="exhausted"):
        sender.encode([HEARTBEAT], destination=0)


# ------------------------------------------------------------------ the key stays secret


def test_the_codec_repr_never_shows_the_key() -> None:
    codec = Codec(MISSION, 2, KEY)
    text = repr(codec) + str(codec)
    assert KEY.hex() not in text
    assert repr(KEY) not in text
    assert "authenticated=True" in text
    assert KEY.hex() not in repr(codec._tagger)


def test_no_error_message_carries_the_key_or_the_expected_tag() -> None:
    codec = Codec(MISSION, 1, KEY)
    bad = keyed(key=OTHER_KEY)
    with pytest.raises(BadTag) as caught:
        codec.decode(bad)
    expected = hmac.new(KEY, bad[:-TAG_BYTES], hashlib.sha256).digest()[:TAG_BYTES]
    message = str(caught.value)
    for secret in (KEY.hex(), expected.hex(), repr(KEY), repr(expected)):
        assert secret not in message
