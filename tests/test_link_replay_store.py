"""Replay protection across a receiver's restart (issue 10, item 1): the ReplayStore."""

from __future__ import annotations

import contextlib
from pathlib import Path

import pytest

from clark_engine.link.auth import ReplayStore
from clark_engine.link.codec import Codec
from clark_engine.link.errors import ReplayedPacket, ReplayStoreError
from clark_engine.link.messages import ModeChangeRequest, Terminate

MISSION = 7
KEY = bytes(range(32))
GPS_MS = 1_400_000_000_000


def station(key: bytes = KEY) -> Codec:
    return Codec(MISSION, 1, key)


def commands(sender: Codec, n: int) -> list[bytes]:
    """``n`` packets of commands from the station to agent 2, one each."""
    out: list[bytes] = []
    for i in range(n):
        message = (
            ModeChangeRequest(1, GPS_MS + i, target_id=2, mode=i)
            if i % 2
            else Terminate(1, GPS_MS + i, target_id=2, reason="operator")
        )
        out += sender.encode([message], destination=2)
    return out


class Clock:
    """A virtual clock for the receiving codec (its replay reservations follow it)."""

    def __init__(self) -> None:
        self.now_s = 0.0

    def __call__(self) -> float:
        return self.now_s


def receiver(path: Path, key: bytes = KEY, clock: Clock | None = None) -> Codec:
    return Codec(MISSION, 2, key, replay_store=ReplayStore(path), clock=clock or Clock())


def test_a_restarted_receiver_refuses_every_packet_it_accepted(tmp_path: Path) -> None:
    store = tmp_path / "cub.replay"
    recorded = commands(station_codec := station(), 150)
    clock = Clock()
    first = receiver(store, clock=clock)
    for k, data in enumerate(recorded):  # at 100 packets a second
        clock.now_s = k / 100
        first.decode(data)
    # A crash: nothing saved on the way out. The recordings played back, in order.
    clock = Clock()
    again = receiver(store, clock=clock)
    for data in recorded:
        with pytest.raises(ReplayedPacket):
            again.decode(data)
    # The station's later packets get through, after at most half a second of them (the
    # reservation: 50 at 100 packets a second) refused.
    later = commands(station_codec, 60)
    accepted = []
    for k, data in enumerate(later):
        clock.now_s = k / 100
        with contextlib.suppress(ReplayedPacket):
            accepted.append(again.decode(data).counter)
    assert accepted == list(range(accepted[0], 150 + 61)) and accepted[0] <= 150 + 51


def test_after_a_clean_stop_the_next_genuine_packet_is_accepted(tmp_path: Path) -> None:
    store = tmp_path / "cub.replay"
    recorded = commands(station_codec := station(), 10)
    first = receiver(store)
    for data in recorded:
        first.decode(data)
    first.save_replay_marks()
    again = receiver(store)
    for data in recorded:
        with pytest.raises(ReplayedPacket):
            again.decode(data)
    assert again.decode(commands(station_codec, 1)[0]).counter == 11


def test_durable_marks_are_written_every_few_seconds_not_per_packet(tmp_path: Path) -> None:
    store = ReplayStore(tmp_path / "cub.replay")
    writes: list[dict[int, int]] = []
    real = store.write_durable

    def counting(marks: dict[int, int]) -> None:
        writes.append(dict(marks))
        real(marks)

    store.write_durable = counting  # type: ignore[method-assign]
    clock = Clock()
    codec = Codec(MISSION, 2, KEY, replay_store=store, clock=clock)
    senders = [Codec(MISSION, agent, KEY) for agent in (1, 3, 4)]
    for k in range(640):  # 6.4 s at 100 packets a second from each
        clock.now_s = k / 100
        for sender in senders:
            codec.decode(commands_from(sender))
    # the fsynced writes: one every 5 s or so (each renews every sender), and two more
    # per sender to learn its pace
    assert len(writes) <= 6.4 / 5 + 2 + 2 * 3


def commands_from(sender: Codec) -> bytes:
    return sender.encode([ModeChangeRequest(sender.agent_id, GPS_MS, 2, 4)], destination=2)[0]


def test_marks_of_another_key_are_not_applied(tmp_path: Path) -> None:
    store = tmp_path / "cub.replay"
    first = receiver(store)
    for data in commands(station(), 5):
        first.decode(data)
    first.save_replay_marks()
    other_key = bytes(range(1, 33))
    again = receiver(store, key=other_key)
    assert again.decode(commands(station(other_key), 1)[0]).counter == 1


@pytest.mark.parametrize(
    "content",
    [b"garbage\n", b"", b"\xff" * 50, b"clarklink-replay 1\n1 99999999999999999999\n"],
)
def test_a_damaged_store_stops_the_receiver(tmp_path: Path, content: bytes) -> None:
    store = tmp_path / "cub.replay"
    store.write_bytes(content)
    with pytest.raises(ReplayStoreError, match="damaged") as caught:
        receiver(store)
    assert "ff" not in str(caught.value) and "9999" not in str(caught.value)


def test_unauthenticated_codec_keeps_no_marks(tmp_path: Path) -> None:
    path = tmp_path / "cub.replay"
    codec = Codec(MISSION, 2, None, replay_store=ReplayStore(path))
    codec.decode(Codec(MISSION, 1).encode([ModeChangeRequest(1, GPS_MS, 2, 4)], 2)[0])
    codec.save_replay_marks()
    assert not path.exists()
