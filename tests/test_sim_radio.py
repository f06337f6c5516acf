"""The simulated radio mesh: serialisation, loss, range, faults, corruption, determinism."""

from __future__ import annotations

import math
import random
from collections.abc import Mapping
from pathlib import Path
from typing import Any

import pytest
import yaml

from clark_engine.sim.radio import (
    DEFAULT_LATENCY_S,
    MAX_FLIPPED_BYTES,
    Delivery,
    RadioMesh,
    RadioSettings,
    loss_probability,
)

ROOT = Path(__file__).resolve().parent.parent
XBEE: dict[str, Any] = yaml.safe_load(
    (ROOT / "hardware_profiles" / "radios" / "xbee_pro_900hp.yaml").read_text()
)
UDP: dict[str, Any] = yaml.safe_load(
    (ROOT / "hardware_profiles" / "radios" / "udp_lan.yaml").read_text()
)
RANGE_M = 1609.344


def mesh(
    names: tuple[str, ...] = ("a", "b", "c"),
    profile: Mapping[str, Any] = XBEE,
    seed: int = 1,
    **settings: Any,
) -> RadioMesh:
    radio = RadioMesh(random.Random(seed), **settings)
    for agent_id, name in enumerate(names, start=1):
        radio.add_agent(name, agent_id, profile)
    return radio


def binomial_ok(count: int, trials: int, p: float, sigmas: float = 5.0) -> bool:
    return abs(count - trials * p) <= sigmas * math.sqrt(trials * p * (1 - p)) + 1


# -- profiles ---------------------------------------------------------------


def test_settings_come_from_the_shipped_profiles() -> None:
    xbee = RadioSettings.from_profile(XBEE)
    assert (xbee.throughput_bps, xbee.max_packet_bytes, xbee.frame_overhead_bytes) == (
        33000.0,
        256,
        18,
    )
    assert xbee.range_m == pytest.approx(RANGE_M)
    assert RadioSettings.from_profile(UDP).range_m is None
    assert xbee.air_time_s(100) == pytest.approx(118 * 8 / 33000)


@pytest.mark.parametrize(
    ("field", "value"),
    [("throughput_bps", 0), ("throughput_bps", None), ("max_packet_bytes", 2.5), ("range_m", -1)],
)
def test_bad_profile_fields_are_named(field: str, value: Any) -> None:
    with pytest.raises(ValueError, match=field):
        RadioSettings.from_profile({**XBEE, field: value})


def test_duplicate_agents_and_unknown_names_are_refused() -> None:
    radio = mesh()
    with pytest.raises(ValueError, match="already"):
        radio.add_agent("a", 9, XBEE)
    with pytest.raises(ValueError, match="id 1"):
        radio.add_agent("z", 1, XBEE)
    with pytest.raises(ValueError, match="'nobody' is not on the mesh"):
        radio.send("a", b"x", "nobody", 0.0)
    with pytest.raises(ValueError, match="itself"):
        radio.send("a", b"x", "a", 0.0)


def test_time_never_goes_back() -> None:
    radio = mesh()
    radio.send("a", b"x", "b", 1.0)
    with pytest.raises(ValueError, match="time went back"):
        radio.send("a", b"x", "b", 0.5)
    radio.deliveries_until(2.0)
    with pytest.raises(ValueError, match=r"time went back: a packet sent at 1\.5 s"):
        radio.send("a", b"x", "b", 1.5)


def test_a_late_send_is_fine_when_it_cannot_arrive_in_the_past() -> None:
    """Only an arrival in the past is refused: the least time to arrive is latency plus framing."""
    radio = mesh(latency_s=0.005)
    lookahead_s = radio.latency_s + radio.air_time_s("a", 0)
    assert lookahead_s == pytest.approx(0.005 + 18 * 8 / 33000)
    radio.deliveries_until(1.0)
    radio.send("a", b"", "b", 1.0 - lookahead_s + 1e-9)  # arrives at 1.0 at the earliest
    assert [d.receiver for d in radio.deliveries_until(1.1)] == ["b"]
    late = mesh(latency_s=0.005)
    late.deliveries_until(1.0)
    with pytest.raises(ValueError, match="would arrive"):
        late.send("a", b"", "b", 1.0 - lookahead_s - 1e-6)


# -- serialisation ------------------------------------------------------------


def test_back_to_back_packets_are_spaced_by_their_air_time() -> None:
    radio = mesh(("a", "b"))
    packet = bytes(100)
    for _ in range(5):
        radio.send("a", packet, "b", 0.0)
    air_s = (100 + 18) * 8 / 33000
    times = [d.at_s for d in radio.deliveries_until(10.0)]
    assert times == pytest.approx([(i + 1) * air_s + DEFAULT_LATENCY_S for i in range(5)])
    queue = radio.queue_stats()
    assert queue.transmissions == 5
    assert queue.max_queue_s == pytest.approx(4 * air_s)
    assert queue.mean_queue_s == pytest.approx(2 * air_s)


def test_one_channel_is_shared_by_every_sender() -> None:
    radio = mesh(("a", "b", "c"))
    radio.send("a", bytes(50), "c", 0.0)
    radio.send("b", bytes(50), "c", 0.0)
    first, second = radio.deliveries_until(1.0)
    assert (first.sender, second.sender) == ("a", "b")
    assert second.at_s - first.at_s == pytest.approx(68 * 8 / 33000)
    assert radio.queue_stats("b").max_queue_s == pytest.approx(68 * 8 / 33000)
    assert radio.queue_stats("a").max_queue_s == 0.0


def test_an_idle_channel_adds_no_queueing() -> None:
    radio = mesh(("a", "b"), latency_s=0.01)
    radio.send("a", bytes(10), "b", 0.0)
    radio.send("a", bytes(10), "b", 5.0)
    times = [d.at_s for d in radio.deliveries_until(10.0)]
    air_s = 28 * 8 / 33000
    assert times == pytest.approx([air_s + 0.01, 5.0 + air_s + 0.01])
    assert radio.queue_stats().max_queue_s == 0.0


def test_an_overloaded_33_kbps_mesh_carries_33_kbps_and_queues_the_rest() -> None:
    """Offer about 66 kbit/s for 10 s: 33 kbit/s gets through, the rest waits."""
    radio = mesh(("a", "b", "c"))
    packet = bytes(238)  # 256 bytes with the XBee frame: 2048 bits on air
    offered_bits = 0
    for tick in range(100):  # 10 Hz for 10 s, two senders
        now_s = tick / 10
        for sender in ("a", "b"):
            for _ in range(2):
                radio.send(sender, packet, "c", now_s)
                offered_bits += 2048
    assert offered_bits / 10 == pytest.approx(81920)
    arrived = radio.deliveries_until(10.0)
    carried_bps = len(arrived) * 2048 / 10
    assert carried_bps == pytest.approx(33000, rel=0.01)
    assert radio.in_flight == 400 - len(arrived)
    assert radio.queue_stats().max_queue_s > 5.0
    radio.deliveries_until(1000.0)
    assert radio.in_flight == 0
    assert radio.queue_stats().air_s == pytest.approx(400 * 2048 / 33000)


def test_a_bounded_queue_drops_what_would_wait_too_long() -> None:
    radio = mesh(("a", "b"), max_queue_s=0.1)
    air_s = (238 + 18) * 8 / 33000  # 62 ms
    for _ in range(4):
        radio.send("a", bytes(238), "b", 0.0)
    delivered = radio.deliveries_until(1.0)
    assert len(delivered) == 2  # waits 0 and 62 ms; 124 ms and 186 ms are too long
    assert air_s < 0.1 < 2 * air_s
    stats = radio.link_stats("a", "b")
    assert (stats.sent, stats.delivered, stats.dropped_queue) == (4, 2, 2)


def test_next_event_is_the_next_arrival() -> None:
    radio = mesh(("a", "b"))
    assert radio.next_event_s() is None
    radio.send("a", bytes(10), "b", 2.0)
    expected_s = 2.0 + 28 * 8 / 33000 + DEFAULT_LATENCY_S
    assert radio.next_event_s() == pytest.approx(expected_s)
    assert radio.deliveries_until(expected_s - 1e-9) == []
    assert len(radio.deliveries_until(expected_s)) == 1
    assert radio.next_event_s() is None


# -- loss -------------------------------------------------------------------


def test_random_loss_follows_the_rate() -> None:
    radio = mesh(("a", "b"), loss_rate=0.2, seed=7)
    trials = 2000
    for i in range(trials):
        radio.send("a", b"ping", "b", float(i))
    delivered = radio.deliveries_until(math.inf)
    stats = radio.link_stats("a", "b")
    assert stats.sent == trials
    assert stats.delivered == len(delivered)
    assert stats.lost_random + stats.delivered == trials
    assert binomial_ok(stats.lost_random, trials, 0.2)
    assert stats.lost_range == stats.lost_fault == 0


def test_loss_law_is_smooth_from_range_to_the_fade_end() -> None:
    assert loss_probability(100.0, None, 0.1, 2.0) == 0.1
    assert loss_probability(1000.0, 1000.0, 0.1, 2.0) == 0.1
    assert loss_probability(1500.0, 1000.0, 0.1, 2.0) == pytest.approx(0.55)
    assert loss_probability(2000.0, 1000.0, 0.1, 2.0) == 1.0
    assert loss_probability(9000.0, 1000.0, 0.0, 3.0) == 1.0
    grid = [loss_probability(1000.0 + i, 1000.0, 0.05, 2.0) for i in range(0, 1001, 10)]
    assert grid == sorted(grid)
    # zero slope at both ends: the first and last steps are tiny next to the middle one
    middle_step = grid[51] - grid[50]
    assert grid[1] - grid[0] < 0.1 * middle_step
    assert grid[-1] - grid[-2] < 0.1 * middle_step


def test_range_loss_grows_beyond_range_and_takes_all_far_beyond() -> None:
    def lost_share(distance_m: float) -> float:
        radio = mesh(("a", "b"), seed=3)
        positions = {"a": (0.0, 0.0, 0.0), "b": (distance_m, 0.0, 0.0)}
        for i in range(1000):
            radio.send("a", b"x", "b", float(i), positions)
        radio.deliveries_until(math.inf)
        stats = radio.link_stats("a", "b")
        assert stats.lost_random == 0
        return stats.lost_range / stats.sent

    assert lost_share(0.9 * RANGE_M) == 0.0
    near = lost_share(1.25 * RANGE_M)
    middle = lost_share(1.5 * RANGE_M)
    assert binomial_ok(round(near * 1000), 1000, 0.15625)
    assert binomial_ok(round(middle * 1000), 1000, 0.5)
    assert lost_share(2.0 * RANGE_M) == 1.0


def test_range_is_three_dimensional_and_set_by_the_weaker_radio() -> None:
    radio = RadioMesh(random.Random(0))
    radio.add_agent("station", 1, UDP)  # no range of its own
    radio.add_agent("plane", 2, {**XBEE, "range_m": 100.0})
    positions = {"station": (0.0, 0.0, 0.0), "plane": (0.0, 0.0, 250.0)}
    for i in range(50):
        radio.send("station", b"x", "plane", float(i), positions)
        radio.send("plane", b"y", "station", float(i), positions)
    assert radio.deliveries_until(math.inf) == []
    assert radio.link_stats("station", "plane").lost_range == 50
    assert radio.link_stats("plane", "station").lost_range == 50


def test_agents_without_a_position_are_in_range() -> None:
    radio = mesh(("a", "b"))
    radio.send("a", b"x", "b", 0.0, {"a": (1e9, 0.0, 0.0)})
    assert len(radio.deliveries_until(1.0)) == 1


# -- faults -----------------------------------------------------------------


def test_a_dropped_link_loses_both_directions_in_its_window_only() -> None:
    radio = mesh(("a", "b", "c"))
    radio.drop_link("b", "a", 10.0, 20.0)
    for t_s in (5.0, 15.0, 25.0):
        radio.send("a", b"1", "b", t_s)
        radio.send("b", b"2", "a", t_s)
        radio.send("a", b"3", "c", t_s)
    arrived = [(d.sender, d.receiver, round(d.sent_s)) for d in radio.deliveries_until(99.0)]
    assert ("a", "b", 15) not in arrived
    assert ("b", "a", 15) not in arrived
    assert ("a", "c", 15) in arrived
    assert len(arrived) == 7
    assert radio.link_stats("a", "b").lost_fault == radio.link_stats("b", "a").lost_fault == 1


def test_a_fault_injected_while_a_packet_is_in_flight_applies_on_arrival() -> None:
    radio = mesh(("a", "b"))
    radio.send("a", bytes(200), "b", 0.0)
    radio.drop_link("a", "b", 0.01)
    assert radio.deliveries_until(1.0) == []
    assert radio.link_stats("a", "b").lost_fault == 1


def test_a_silenced_agent_neither_sends_nor_receives() -> None:
    radio = mesh(("a", "b", "c"))
    radio.silence("b", 10.0)  # b dies at 10 s
    radio.send("b", b"before", "", 5.0)
    radio.send("b", b"after", "", 15.0)
    radio.send("a", b"to b", "b", 15.0)
    radio.send("a", b"all", "", 16.0)
    arrived = [(d.sender, d.receiver, d.packet) for d in radio.deliveries_until(99.0)]
    assert arrived == [
        ("b", "a", b"before"),
        ("b", "c", b"before"),
        ("a", "c", b"all"),
    ]
    assert radio.link_stats("b", "a").lost_fault == 1
    assert radio.link_stats("a", "b").lost_fault == 2
    # a silenced sender's packets never took the air
    assert radio.queue_stats("b").transmissions == 1


def test_silence_can_end() -> None:
    radio = mesh(("a", "b"))
    radio.silence("a", 0.0, 1.0)
    radio.send("a", b"x", "b", 0.5)
    radio.send("a", b"y", "b", 1.0)
    assert [d.packet for d in radio.deliveries_until(9.0)] == [b"y"]


def test_fault_windows_are_checked() -> None:
    radio = mesh()
    with pytest.raises(ValueError, match="from_s <= to_s"):
        radio.silence("a", 5.0, 1.0)
    with pytest.raises(ValueError, match="two agents"):
        radio.drop_link("a", "a", 0.0)
    with pytest.raises(ValueError, match="within 0"):
        radio.corrupt(1.5)


def test_corruption_flips_bytes_in_its_share_only() -> None:
    radio = mesh(("a", "b"), seed=11)
    radio.corrupt(0.3, 0.0, 1000.0)
    packet = bytes(range(64))
    trials = 2000
    for i in range(trials):
        radio.send("a", packet, "b", float(i))  # the last 1000 fall outside the window
    delivered = radio.deliveries_until(math.inf)
    assert len(delivered) == trials
    changed = [d for d in delivered if d.packet != packet]
    assert all(d.corrupted for d in changed)
    assert all(d.sent_s < 1000.0 for d in changed)
    assert len(changed) == radio.link_stats("a", "b").corrupted
    assert binomial_ok(len(changed), 1000, 0.3)
    for d in changed:
        assert len(d.packet) == len(packet)
        assert 1 <= sum(x != y for x, y in zip(d.packet, packet, strict=True)) <= MAX_FLIPPED_BYTES


def test_oversize_packets_are_refused_and_never_take_the_air() -> None:
    radio = mesh(("a", "b", "c"))
    radio.send("a", bytes(257), "", 0.0)
    radio.send("a", bytes(256), "b", 0.0)
    delivered = radio.deliveries_until(1.0)
    assert [len(d.packet) for d in delivered] == [256]
    assert delivered[0].at_s == pytest.approx(274 * 8 / 33000 + DEFAULT_LATENCY_S)
    assert radio.link_stats("a", "b").refused_oversize == 1
    assert radio.link_stats("a", "c").refused_oversize == 1
    assert radio.totals().sent == 3


# -- broadcast and ordering ----------------------------------------------------


def test_broadcast_receivers_draw_their_loss_independently() -> None:
    names = ("s", "r1", "r2", "r3")
    radio = mesh(names, loss_rate=0.5, seed=5)
    trials = 2000
    for i in range(trials):
        radio.send("s", bytes([i % 256]), "", float(i))
    got: dict[str, set[int]] = {name: set() for name in names[1:]}
    for d in radio.deliveries_until(math.inf):
        got[d.receiver].add(round(d.sent_s))
    for name in names[1:]:
        assert binomial_ok(len(got[name]), trials, 0.5)
    # independent: each pair both receives about a quarter of the packets
    for a, b in (("r1", "r2"), ("r1", "r3"), ("r2", "r3")):
        assert binomial_ok(len(got[a] & got[b]), trials, 0.25)
    assert radio.queue_stats().transmissions == trials  # one transmission per broadcast


def test_a_broadcast_reaches_every_other_agent_at_once_in_name_order() -> None:
    radio = mesh(("m", "c", "x", "a"))
    radio.send("m", b"hello", "", 0.0)
    delivered = radio.deliveries_until(1.0)
    assert [d.receiver for d in delivered] == ["a", "c", "x"]
    assert len({d.at_s for d in delivered}) == 1


def test_equal_times_come_out_by_sender_receiver_then_sequence() -> None:
    radio = RadioMesh(random.Random(0), latency_s=0.01)
    for agent_id, name in enumerate(("a", "b", "c"), start=1):
        radio.add_agent(name, agent_id, {**XBEE, "frame_overhead_bytes": 0})
    # empty packets without framing take no air time: all arrive at 0.01 s
    radio.send("c", b"", "b", 0.0)
    radio.send("b", b"", "", 0.0)
    radio.send("c", b"", "a", 0.0)
    radio.send("c", b"", "a", 0.0)
    delivered = radio.deliveries_until(1.0)
    assert {d.at_s for d in delivered} == {0.01}
    assert [(d.sender, d.receiver, d.sequence) for d in delivered] == [
        ("b", "a", 1),
        ("b", "c", 1),
        ("c", "a", 2),
        ("c", "a", 3),
        ("c", "b", 0),
    ]


# -- determinism ------------------------------------------------------------


def run(seed: int) -> list[Delivery]:
    radio = mesh(("a", "b", "c", "d"), seed=seed, loss_rate=0.2)
    radio.corrupt(0.2)
    radio.drop_link("a", "d", 3.0, 6.0)
    out: list[Delivery] = []
    for tick in range(100):
        now_s = tick / 10
        positions = {n: (tick * 30.0 * i, 0.0, 0.0) for i, n in enumerate("abcd")}
        for sender in "abcd":
            radio.send(sender, f"{sender}{tick}".encode() * 5, "", now_s, positions)
        out.extend(radio.deliveries_until(now_s))
    out.extend(radio.deliveries_until(math.inf))
    return out


def test_same_seed_same_deliveries_different_seed_different() -> None:
    first, again, other = run(42), run(42), run(43)
    assert first == again
    assert first != other
    assert [d.at_s for d in first] == sorted(d.at_s for d in first)


def test_a_fault_changes_only_the_packets_it_touches() -> None:
    def deliveries(with_fault: bool) -> list[Delivery]:
        radio = mesh(("a", "b", "c"), seed=9, loss_rate=0.3)
        if with_fault:
            radio.drop_link("a", "b", 0.0)
        for i in range(200):
            radio.send("a", b"x", "", float(i))
        return radio.deliveries_until(math.inf)

    plain = deliveries(False)
    faulted = deliveries(True)
    assert faulted == [d for d in plain if d.receiver != "b"]


def test_a_packets_fate_hangs_on_the_packet_not_on_the_traffic_around_it() -> None:
    """The same packet is lost or corrupted alike however much else the mesh carries.

    A mission flown on the simulated autopilot and on ArduPilot SITL sends the same
    periodic packets at the same tick times, but not the same packets in between (a state
    change a tick later, a peer's report missing while its autopilot boots). The loss and
    corruption of a packet must hang on that packet (sender, destination, receiver, send
    time, its place among that sender's sends to that destination at that time), or the
    two runs corrupt different heartbeats and a peer is lost in one and not the other
    (fault_lost_peer.yaml: Slash B lost its leader 9 s early in the simulated run only).
    """

    def fates(busy: bool) -> dict[tuple[str, str, int], bytes | None]:
        radio = mesh(("a", "b", "c"), seed=7, loss_rate=0.2)
        radio.corrupt(0.3)
        sent: list[tuple[str, str, int]] = []
        for k in range(400):
            now_s = k / 10
            if busy and k % 3 == 0:
                radio.send("c", b"noise" * 8, "", now_s)  # another sender, interleaved
            if busy and k % 5 == 0:
                radio.send("a", b"extra", "c", now_s)  # the same sender, elsewhere
            if busy and k % 7 == 0:
                continue  # a packet this run does not send at all
            radio.send("a", k.to_bytes(2, "big") * 20, "", now_s)
            sent += [("a", "b", k), ("a", "c", k)]
        got: dict[tuple[str, str, int], bytes | None] = dict.fromkeys(sent)
        for d in radio.deliveries_until(math.inf):
            key = (d.sender, d.receiver, round(d.sent_s * 10))
            if key in got and len(d.packet) == 40:  # not the extra packet to c
                got[key] = d.packet
        return got

    quiet, busy = fates(False), fates(True)
    common = busy.keys() & quiet.keys()
    assert len(common) > 400
    assert {k: busy[k] for k in common} == {k: quiet[k] for k in common}
    lost = sum(quiet[k] is None for k in common)
    corrupted = sum(quiet[k] not in (None, k[2].to_bytes(2, "big") * 20) for k in common)
    assert lost > 0 and corrupted > 0
