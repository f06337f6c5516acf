"""A receiver restarted after a crash rejoins its senders at once (issue 18, item 1).

Before: the replay store reserved 64 counters of each sender per write, so a vehicle
killed and restarted beside a station sending once a second refused the station's next
54 genuine packets, its ``mcs_lost`` failsafe fired 4 s after the restart, and it was out
of the mission for good. Now the store reserves what each sender sends in a fraction of
a second (down to the exact mark for a slow sender): after a crash an agent accepts a
genuine sender's next packet within 2 s, whatever its rate, and still never a packet it
accepted before the crash.

Everything here runs on virtual clocks (the codec's is injected, the runtime's is the
time its events carry): no test sleeps or measures the wall clock.
"""

from __future__ import annotations

import contextlib
import random
from collections.abc import Iterator
from pathlib import Path

import pytest
from test_runtime import GPS0, READY, ROOT, config_of, vehicle

from clark_engine.link.auth import ReplayStore, generate_key_file, load_key
from clark_engine.link.codec import Codec
from clark_engine.link.errors import ReplayedPacket
from clark_engine.link.messages import AgentType, Heartbeat, ModeChangeRequest
from clark_engine.runtime.events import AutopilotHeartbeat, PacketReceived
from clark_engine.runtime.runtime import AgentRuntime

MISSION = 521
KEY = bytes(range(32))


# -- end to end: a keyed vehicle killed and restarted beside a live 1 Hz station ----------


def _keyed_slash_b(tmp_path: Path) -> tuple[object, bytes]:
    text = (
        (ROOT / "missions" / "cooperative_follow.yaml")
        .read_text(encoding="utf-8")
        .replace("  loop_hz: 10\n", "  loop_hz: 10\n  key_file: coop.key\n", 1)
    )
    generate_key_file(tmp_path / "coop.key")
    key = load_key(tmp_path / "coop.key")
    return config_of("cooperative_follow.yaml", "slash_b", text, tmp_path), key


def _mission_log(runtime: AgentRuntime) -> str:
    return runtime.logbook.streams.mission.getvalue()  # type: ignore[attr-defined]


@pytest.mark.parametrize("crash_s", [40.05, 40.5, 40.95])
def test_a_keyed_vehicle_killed_beside_a_1hz_station_rejoins_within_2_s(
    tmp_path: Path, crash_s: float
) -> None:
    """Slash B runs 40 s with the station heard once a second, is killed (its runtime
    dropped, nothing saved: what kill -9 leaves), and a new process starts 0.2 s later
    on the same replay store. The station's next genuine packet is accepted within 2 s
    of the restart, its station-loss failsafe never fires, and the station's packets
    from before the crash, played back, are all refused."""
    config, key = _keyed_slash_b(tmp_path)
    store = tmp_path / "slash_b.replay"
    station = Codec(MISSION, 1, key)
    sent: list[tuple[float, bytes]] = []

    def beat(t: float) -> PacketReceived:
        (data,) = station.encode([Heartbeat(1, GPS0 + round(t * 1000), MISSION, AgentType.MCS)], 0)
        sent.append((t, data))
        return PacketReceived(data)

    def boot() -> AgentRuntime:
        return AgentRuntime(config, key=key, replay_store=ReplayStore(store))  # type: ignore[arg-type]

    def tick(runtime: AgentRuntime, t: float, *events: object) -> None:
        runtime.deliver(READY, t)
        runtime.deliver(vehicle(t), t)
        runtime.deliver(AutopilotHeartbeat("HOLD", 4, True), t)
        for event in events:
            runtime.deliver(event, t)  # type: ignore[arg-type]
        runtime.tick(t)

    def ticks(start_s: float, end_s: float) -> Iterator[tuple[float, bool]]:
        """Every 0.1 s from ``start_s``; True where the station sends (each whole second)."""
        k = round(start_s * 10)
        while k / 10 < end_s:
            yield k / 10, k % 10 == 0
            k += 1

    first = boot()
    for t, beats in ticks(0.0, crash_s):
        tick(first, t, *([beat(t)] if beats else []))
    assert first.failsafe is None
    before = [data for _, data in sent]
    del first  # kill -9: no clean stop, no save_replay_marks()

    restart_s = round(crash_s + 0.2, 1)
    again = boot()
    accepted_s: float | None = None
    for t, beats in ticks(restart_s, restart_s + 15.0):
        tick(again, t, *([beat(t)] if beats else []))
        if accepted_s is None and again.fleet.record(1) is not None:
            accepted_s = t
    assert accepted_s is not None and accepted_s - restart_s <= 2.0, (restart_s, accepted_s)
    assert again.failsafe is None
    assert "mcs_lost" not in _mission_log(again)
    # And what it accepted before the crash is still refused, played back in order.
    probe = Codec(MISSION, 2, key, replay_store=ReplayStore(store))
    for data in before:
        with pytest.raises(ReplayedPacket):
            probe.decode(data)


# -- the store: nothing accepted before a crash is accepted after it, at any rate --------


class Clock:
    """A virtual clock for a codec: tests move it by hand."""

    def __init__(self, now_s: float = 0.0) -> None:
        self.now_s = now_s

    def __call__(self) -> float:
        return self.now_s


def _packet(sender: Codec, t: float) -> bytes:
    (data,) = sender.encode([ModeChangeRequest(sender.agent_id, GPS0 + round(t * 1000), 2, 4)], 2)
    return data


def _schedule(rng: random.Random, rate_hz: float, start_s: float, end_s: float) -> list[float]:
    """Send times at ``rate_hz`` with 20 % jitter, and now and then a burst of 4 (a split
    bundle sent at once)."""
    times: list[float] = []
    t = start_s
    while t < end_s:
        times += [t] * (4 if rng.random() < 0.05 else 1)
        t += (1.0 / rate_hz) * rng.uniform(0.8, 1.2)
    return times


@pytest.mark.parametrize("rate_hz", [0.2, 1.0, 2.0, 10.0, 100.0, 400.0])
@pytest.mark.parametrize("seed", [1, 2, 3])
def test_after_a_crash_nothing_accepted_before_is_accepted_and_the_sender_rejoins(
    tmp_path: Path, rate_hz: float, seed: int
) -> None:
    """A sender at ``rate_hz`` (jittered, with bursts), a receiver that crashes at a random
    moment and restarts on the same store after a random delay: every packet it accepted
    before is refused after, in order and shuffled; the sender's genuine packets are
    accepted again within 2 s of the restart (or its very next one, when it sends less
    often than that)."""
    rng = random.Random(seed)
    path = tmp_path / "cub.replay"
    sender = Codec(MISSION, 1, KEY)
    clock = Clock()
    receiver = Codec(MISSION, 2, KEY, replay_store=ReplayStore(path), clock=clock)
    crash_s = rng.uniform(20.0, 30.0)
    accepted: list[bytes] = []
    for t in _schedule(rng, rate_hz, 0.0, crash_s):
        clock.now_s = t
        data = _packet(sender, t)
        receiver.decode(data)  # a genuine, fresh packet: never refused while running
        accepted.append(data)
    # The crash: the receiver's memory is gone; packets sent while it is down are lost.
    restart_s = crash_s + rng.uniform(0.0, 1.5)
    down = [t for t in _schedule(rng, rate_hz, crash_s, restart_s)]
    for t in down:
        _packet(sender, t)  # sent, never received
    clock = Clock(restart_s)
    again = Codec(MISSION, 2, KEY, replay_store=ReplayStore(path), clock=clock)
    for data in accepted + rng.sample(accepted, len(accepted)):
        with pytest.raises(ReplayedPacket):
            again.decode(data)
    first_accepted_s: float | None = None
    period_s = 1.0 / rate_hz * 1.2
    for t in _schedule(rng, rate_hz, restart_s, restart_s + 2.0 + period_s):
        clock.now_s = t
        try:
            again.decode(_packet(sender, t))
        except ReplayedPacket:
            assert first_accepted_s is None, "a genuine packet refused after one was accepted"
            continue
        if first_accepted_s is None:
            first_accepted_s = t
    assert first_accepted_s is not None
    assert first_accepted_s - restart_s <= max(2.0, period_s), (restart_s, first_accepted_s)


def test_a_sender_that_slows_down_is_not_refused_for_long_after_a_crash(tmp_path: Path) -> None:
    """Reservations follow the sender's rate down: 50 Hz for 10 s, then 1 Hz for 10 s,
    then a crash; the next 1 Hz packet after the restart is accepted."""
    path = tmp_path / "cub.replay"
    sender = Codec(MISSION, 1, KEY)
    clock = Clock()
    receiver = Codec(MISSION, 2, KEY, replay_store=ReplayStore(path), clock=clock)
    times = [k / 50 for k in range(500)] + [10.0 + k for k in range(10)]
    for t in times:
        clock.now_s = t
        receiver.decode(_packet(sender, t))
    clock = Clock(19.5)
    again = Codec(MISSION, 2, KEY, replay_store=ReplayStore(path), clock=clock)
    clock.now_s = 20.0
    assert again.decode(_packet(sender, 20.0)).counter == 511


class CountingStore(ReplayStore):
    """A replay store that counts its durable (fsynced) and live writes."""

    def __init__(self, path: Path, **options: object) -> None:
        super().__init__(path, **options)  # type: ignore[arg-type]
        self.durable_writes = 0
        self.live_writes = 0

    def write_durable(self, marks: dict[int, int]) -> None:
        self.durable_writes += 1
        super().write_durable(marks)

    def write_live(self, marks: dict[int, int]) -> None:
        self.live_writes += 1
        super().write_live(marks)


@pytest.mark.parametrize(
    ("rates_hz", "most_durable_per_s", "most_live_per_s"),
    [
        ((100.0,) * 3, 0.5, 3.0),  # fast senders: a write renews all, twice a second
        ((1.0,) * 50, 0.5, 60.0),  # 50 slow senders: exact live marks, a rename a packet
    ],
)
def test_fsyncs_stay_rare_at_any_rate(
    tmp_path: Path, rates_hz: tuple[float, ...], most_durable_per_s: float, most_live_per_s: float
) -> None:
    """Whatever the senders' rates, the fsynced marks are written every few seconds, not
    per packet; the live marks (no fsync) per packet only of senders slower than 2 Hz."""
    rng = random.Random(18)
    store = CountingStore(tmp_path / "cub.replay", boot_id="boot-1")
    clock = Clock()
    codec = Codec(MISSION, 100, KEY, replay_store=store, clock=clock)
    senders = [Codec(MISSION, agent + 1, KEY) for agent in range(len(rates_hz))]
    traffic = sorted(
        (t, n)
        for n, rate in enumerate(rates_hz)
        for t in _schedule(rng, rate, rng.uniform(0.0, 1.0 / rate), 30.0)
    )
    for t, n in traffic:
        clock.now_s = t
        codec.decode(_packet(senders[n], t))
    warm_up = 2 * len(rates_hz) + 2  # each sender's first two packets: its pace unknown
    assert store.durable_writes <= 30.0 * most_durable_per_s + warm_up
    assert store.live_writes <= min(30.0 * most_live_per_s + warm_up, len(traffic))


def test_after_the_computer_restarts_the_durable_marks_hold(tmp_path: Path) -> None:
    """Another boot id: the live marks (not fsynced) are not trusted, the durable ones
    are; nothing accepted before is accepted after, and the sender is heard again after
    at most about durable_reserve_s of its traffic."""
    path = tmp_path / "cub.replay"
    sender = Codec(MISSION, 1, KEY)
    clock = Clock()
    receiver = Codec(MISSION, 2, KEY, replay_store=ReplayStore(path, boot_id="boot-1"), clock=clock)
    accepted = []
    for k in range(300):  # 30 s at 10 Hz
        clock.now_s = k / 10
        accepted.append(data := _packet(sender, clock.now_s))
        receiver.decode(data)
    clock = Clock(30.0)
    store = ReplayStore(path, boot_id="boot-2")
    again = Codec(MISSION, 2, KEY, replay_store=store, clock=clock)
    assert store.live_marks is None
    for data in accepted:
        with pytest.raises(ReplayedPacket):
            again.decode(data)
    first = None
    for k in range(300, 400):
        clock.now_s = k / 10
        try:
            again.decode(_packet(sender, clock.now_s))
        except ReplayedPacket:
            continue
        first = first if first is not None else clock.now_s
    assert first is not None and first - 30.0 <= store.durable_reserve_s + 0.2


@pytest.mark.parametrize("live_file", ["missing", "damaged", "another mission"])
def test_a_lost_or_damaged_live_file_falls_back_to_the_durable_marks(
    tmp_path: Path, live_file: str
) -> None:
    path = tmp_path / "cub.replay"
    sender = Codec(MISSION, 1, KEY)
    clock = Clock()
    receiver = Codec(MISSION, 2, KEY, replay_store=ReplayStore(path, boot_id="b"), clock=clock)
    accepted = []
    for k in range(50):
        clock.now_s = k / 10
        accepted.append(data := _packet(sender, clock.now_s))
        receiver.decode(data)
    live = path.with_name("cub.replay.live")
    if live_file == "missing":
        live.unlink()
    elif live_file == "damaged":
        live.write_bytes(b"clarklink-replay-live 1 garbage\n")
    else:
        text = live.read_text(encoding="ascii")
        live.write_text(text.replace(f"replay-live 1 {MISSION} ", "replay-live 1 99 "), "ascii")
    again = Codec(MISSION, 2, KEY, replay_store=ReplayStore(path, boot_id="b"), clock=Clock(9.0))
    for data in accepted:
        with pytest.raises(ReplayedPacket):
            again.decode(data)


def test_without_a_boot_id_the_durable_marks_reserve_half_a_second(tmp_path: Path) -> None:
    """Where the kernel has no boot id (not Linux) there is no live file: the durable
    marks reserve what a live file would, at an fsync per write, and a 1 Hz sender is
    still heard again at its next packet after a crash."""
    path = tmp_path / "cub.replay"
    store = ReplayStore(path, boot_id=None)
    assert not store.live and store.durable_reserve_s == store.reserve_s
    sender = Codec(MISSION, 1, KEY)
    clock = Clock()
    receiver = Codec(MISSION, 2, KEY, replay_store=store, clock=clock)
    for k in range(20):
        clock.now_s = float(k)
        receiver.decode(_packet(sender, clock.now_s))
    assert not path.with_name("cub.replay.live").exists()
    again = Codec(MISSION, 2, KEY, replay_store=ReplayStore(path, boot_id=None), clock=clock)
    clock.now_s = 20.0
    assert again.decode(_packet(sender, 20.0)).counter == 21


def test_live_marks_are_not_trusted_beside_a_durable_file_rewritten_without_them(
    tmp_path: Path,
) -> None:
    """A live file names the durable file it was written with. If something rewrote the
    durable file without updating the live one (a run without a boot id, an engine from
    before live marks), the live marks may lag behind what was accepted: ignored."""
    path = tmp_path / "cub.replay"
    sender = Codec(MISSION, 1, KEY)
    accepted = []

    def receive(store: ReplayStore, times_s: range) -> None:
        clock = Clock()
        codec = Codec(MISSION, 2, KEY, replay_store=store, clock=clock)
        for k in times_s:
            clock.now_s = k / 10
            data = _packet(sender, clock.now_s)
            with contextlib.suppress(ReplayedPacket):  # after a restart: until past the marks
                codec.decode(data)
                accepted.append(data)

    receive(ReplayStore(path, boot_id="b"), range(50))
    live = path.with_name("cub.replay.live").read_bytes()
    receive(ReplayStore(path, boot_id=None), range(50, 300))  # the live file not touched
    assert len(accepted) > 100
    assert path.with_name("cub.replay.live").read_bytes() == live
    store = ReplayStore(path, boot_id="b")
    again = Codec(MISSION, 2, KEY, replay_store=store, clock=Clock(20.0))
    assert store.live_marks is None
    for data in accepted:
        with pytest.raises(ReplayedPacket):
            again.decode(data)


def test_a_sender_gone_slow_has_its_live_marks_trimmed_before_its_next_packet(
    tmp_path: Path,
) -> None:
    """100 packets a second for 10 s, then silence: a trim a second later (the runtime
    calls it every tick) cuts the reservation made at the old pace, so a crash then
    does not refuse the sender's next packets for minutes at its new pace."""
    path = tmp_path / "cub.replay"
    sender = Codec(MISSION, 1, KEY)
    clock = Clock()
    receiver = Codec(MISSION, 2, KEY, replay_store=ReplayStore(path, boot_id="b"), clock=clock)
    for k in range(1000):
        clock.now_s = k / 100
        receiver.decode(_packet(sender, clock.now_s))
    assert not receiver.trim_replay_marks(10.0)  # at its pace: nothing to trim
    assert receiver.trim_replay_marks(11.0)
    assert not receiver.trim_replay_marks(11.1)  # once
    again = Codec(MISSION, 2, KEY, replay_store=ReplayStore(path, boot_id="b"), clock=Clock(12))
    assert again.decode(_packet(sender, 15.0)).counter == 1001  # its next packet, 0.2 Hz on


def test_the_runtime_trims_the_replay_marks_every_tick(tmp_path: Path) -> None:
    config, key = _keyed_slash_b(tmp_path)
    runtime = AgentRuntime(
        config,  # type: ignore[arg-type]
        key=key,
        replay_store=ReplayStore(tmp_path / "b.replay", boot_id="b"),
    )
    station = Codec(MISSION, 1, key)
    for k in range(200):  # 20 packets a second for 10 s
        t = k / 20
        (data,) = station.encode([Heartbeat(1, GPS0 + k * 50, MISSION, AgentType.MCS)], 0)
        runtime.deliver(PacketReceived(data), t)
    live = (tmp_path / "b.replay.live").read_text(encoding="ascii")
    runtime.tick(11.0)  # the station gone quiet for a second
    assert (tmp_path / "b.replay.live").read_text(encoding="ascii") != live
    assert (tmp_path / "b.replay.live").read_text(encoding="ascii").endswith("\n1 200\n")
