"""Measure the replay store: its writes (each an fsync), and what a crash costs a receiver.

A receiver with a replay store writes its marks before it accepts a packet above them
(clark_engine/link/auth.py, ReplayStore). This script feeds real codecs the traffic of a
few fleets on a virtual clock (seeded, every interval jittered by up to 20 %), with the
store on a real disk, and prints per fleet and per policy:

* writes per second of traffic, and what one write took (median, p99, max; the
  rename, the file's fsync and the folder's fsync, timed on this disk);
* decode time per packet, writes included, against the same codec without a store;
* after a crash at any of 200 moments (the marks last written before it, a restart at
  once: the worst case), the longest from the restart to a sender's first accepted
  packet (its own interval included: a 0.2 Hz sender's next packet may be 6 s away),
  and the most of its genuine packets refused.

Policies: ``time`` is the store as shipped (each write reserves what a sender sends in
``reserve_s`` = 0.5 s at its slowest recent interval); ``64 counters`` emulates the
store before issue 18 (a block of 64 per sender, whatever its rate: ``block_size=64``
with a 60 s reservation, so that every sender faster than 1 Hz reserves the whole block).

Run: python benchmarks/bench_replay_store.py [--dir FOLDER] [--seconds 60]
(``--dir`` on the mission computer's own storage, an SD card say, to measure there.)
"""

from __future__ import annotations

import argparse
import bisect
import heapq
import random
import statistics
import tempfile
import time
from dataclasses import dataclass
from pathlib import Path

from clark_engine.link.auth import ReplayStore
from clark_engine.link.codec import Codec
from clark_engine.link.messages import AgentType, Heartbeat

MISSION = 7
KEY = bytes(range(32))
GPS_MS = 1_400_000_000_000


@dataclass(frozen=True)
class Fleet:
    """What one receiver hears: one rate per sender (packets a second)."""

    name: str
    rates_hz: tuple[float, ...]


FLEETS = (
    Fleet("vehicle: station 1 Hz, peer 2 Hz", (1.0, 2.0)),
    Fleet("station: 4 vehicles at 2 Hz", (2.0,) * 4),
    Fleet("station: 10 vehicles at 10 Hz", (10.0,) * 10),
    Fleet("vehicle: 50 agents at 1 Hz", (1.0,) * 50),
    Fleet("one sender at 0.2 Hz", (0.2,)),
    Fleet("one sender at 100 Hz", (100.0,)),
)
POLICIES: dict[str, dict[str, object]] = {
    "live + durable": {},
    "durable only (no boot id)": {"boot_id": None},
    "64 counters (before)": {"boot_id": None, "block_size": 64, "reserve_s": 60.0},
}


class Clock:
    """The receiving codec's virtual clock."""

    def __init__(self) -> None:
        self.now_s = 0.0

    def __call__(self) -> float:
        return self.now_s


class TimedStore(ReplayStore):
    """A replay store that times its writes and keeps the marks of each, with its time."""

    def __init__(self, path: Path, clock: Clock, **options: object) -> None:
        super().__init__(path, **options)  # type: ignore[arg-type]
        self.clock = clock
        self.durable_s: list[float] = []
        self.live_s: list[float] = []
        self.durable_history: list[tuple[float, dict[int, int]]] = []
        self.live_history: list[tuple[float, dict[int, int]]] = []

    def write_durable(self, marks: dict[int, int]) -> None:
        start = time.perf_counter()
        super().write_durable(marks)
        self.durable_s.append(time.perf_counter() - start)
        self.durable_history.append((self.clock.now_s, dict(marks)))

    def write_live(self, marks: dict[int, int]) -> None:
        if not self.live:
            return
        start = time.perf_counter()
        super().write_live(marks)
        self.live_s.append(time.perf_counter() - start)
        self.live_history.append((self.clock.now_s, dict(marks)))


def marks_at(history: list[tuple[float, dict[int, int]]], at_s: float) -> dict[int, int] | None:
    """The marks on disk at ``at_s``: those of the last write before it (None: no file)."""
    index = bisect.bisect_right([t for t, _ in history], at_s) - 1
    return history[index][1] if index >= 0 else None


def ms(values: list[float]) -> str:
    """Median / p99 / max of write times in ms; "-" without writes."""
    if not values:
        return "-"
    ordered = sorted(values)
    p99 = ordered[int(0.99 * (len(ordered) - 1))]
    return f"{statistics.median(values) * 1000:.2f} / {p99 * 1000:.2f} / {ordered[-1] * 1000:.2f}"


def schedule(rates_hz: tuple[float, ...], seconds: float, seed: int) -> list[tuple[float, int]]:
    """(send time, sender id) of every packet, in time order; senders are 1, 2, ..."""
    rng = random.Random(seed)
    streams = []
    for index, rate in enumerate(rates_hz):
        times = []
        t = rng.uniform(0.0, 1.0 / rate)
        while t < seconds:
            times.append((t, index + 1))
            t += rng.uniform(0.8, 1.2) / rate
        streams.append(times)
    return list(heapq.merge(*streams))


def run(fleet: Fleet, policy: dict[str, float], folder: Path, seconds: float) -> dict[str, float]:
    """One fleet under one policy: the figures the module docstring lists."""
    packets = schedule(fleet.rates_hz, seconds, seed=18)
    senders = {i + 1: Codec(MISSION, i + 1, KEY) for i in range(len(fleet.rates_hz))}
    sent: dict[int, list[tuple[float, int]]] = {s: [] for s in senders}
    data = []
    for t, sender in packets:
        codec = senders[sender]
        counter = codec.next_counter
        beat = Heartbeat(sender, GPS_MS + round(t * 1000), MISSION, AgentType.VEHICLE)
        data.append(codec.encode([beat], 0)[0])
        sent[sender].append((t, counter))
    clock = Clock()
    path = folder / "bench.replay"
    path.unlink(missing_ok=True)
    path.with_name(path.name + ".live").unlink(missing_ok=True)
    store = TimedStore(path, clock, **policy)
    receiver = Codec(MISSION, 100, KEY, replay_store=store, clock=clock)
    start = time.perf_counter()
    for (t, _), raw in zip(packets, data, strict=True):
        clock.now_s = t
        receiver.decode(raw)
    with_store_s = time.perf_counter() - start
    bare = Codec(MISSION, 100, KEY)
    start = time.perf_counter()
    for raw in data:
        bare.decode(raw)
    bare_s = time.perf_counter() - start
    # Crashes at 200 moments spread over the run (after the first 5 s), a restart at once:
    # of the process (the lower of the live and durable marks), of the computer (durable).
    worst = {"process": [0.0, 0], "computer": [0.0, 0]}
    rng = random.Random(1)
    for _ in range(200):
        crash_s = rng.uniform(5.0, seconds - 15.0)
        durable = marks_at(store.durable_history, crash_s) or {}
        live = marks_at(store.live_history, crash_s)
        process = dict(durable)
        for sender, mark in (live or {}).items():
            process[sender] = min(mark, process.get(sender, mark))
        for kind, marks in (("process", process), ("computer", durable)):
            for sender, stream in sent.items():
                mark = marks.get(sender, 0)
                after = [(t, c) for t, c in stream if t >= crash_s]
                refused = sum(1 for _, c in after if c <= mark)
                accepted = next((t for t, c in after if c > mark), None)
                if accepted is None:
                    continue
                worst[kind][0] = max(worst[kind][0], accepted - crash_s)
                worst[kind][1] = max(worst[kind][1], refused)
    n = len(packets)
    return {
        "packets_per_s": n / seconds,
        "durable_per_s": len(store.durable_s) / seconds,
        "live_per_s": len(store.live_s) / seconds,
        "durable_ms": ms(store.durable_s),
        "live_ms": ms(store.live_s),
        "write_share": (sum(store.durable_s) + sum(store.live_s)) / seconds,
        "decode_us": with_store_s / n * 1e6,
        "bare_decode_us": bare_s / n * 1e6,
        "process_wait_s": worst["process"][0],
        "process_refused": worst["process"][1],
        "computer_wait_s": worst["computer"][0],
        "computer_refused": worst["computer"][1],
    }


def main() -> None:
    """Print one table row per fleet and policy."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--dir", type=Path, help="where the store goes (a temporary folder)")
    parser.add_argument("--seconds", type=float, default=60.0, help="traffic simulated per run")
    options = parser.parse_args()
    with tempfile.TemporaryDirectory(dir=options.dir) as folder:
        print(f"store in {folder}, {options.seconds:.0f} s of traffic per row")
        print(
            "| receiver hears | policy | packets/s | fsynced writes/s (ms p50 / p99 / max) "
            "| live writes/s (ms p50 / p99 / max) | time in writes | decode us (no store) "
            "| process crash: first accepted within s (most refused) "
            "| computer restart: within s (most refused) |"
        )
        print("|---|---|---|---|---|---|---|---|---|")
        for fleet in FLEETS:
            for name, policy in POLICIES.items():
                f = run(fleet, policy, Path(folder), options.seconds)
                print(
                    f"| {fleet.name} | {name} | {f['packets_per_s']:.1f} "
                    f"| {f['durable_per_s']:.2f} ({f['durable_ms']}) "
                    f"| {f['live_per_s']:.2f} ({f['live_ms']}) "
                    f"| {f['write_share']:.1%} "
                    f"| {f['decode_us']:.0f} ({f['bare_decode_us']:.0f}) "
                    f"| {f['process_wait_s']:.2f} ({f['process_refused']}) "
                    f"| {f['computer_wait_s']:.2f} ({f['computer_refused']}) |"
                )


if __name__ == "__main__":
    main()
