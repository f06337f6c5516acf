"""Fuzz ClarkLink decode with a million inputs: only ClarkLinkError may come out.

Inputs, from a seeded random generator (the same run every time unless a seed
is given):

* 15 % random bytes of random length (0 to 1500);
* 15 % a valid header followed by a random bundle (half of them signed with the
  key, so that the random bundle reaches the Protocol Buffers parser under
  authentication too);
* 60 % valid packets (keyed and unkeyed, 1 to 8 messages) with 1 to 3 mutations:
  bit flips, truncation, extension, overwritten bytes, a changed counter,
  mission id, sender or flags, and half of the keyed ones re-signed as a key
  holder would;
* 10 % valid packets unchanged.

Every damaged or random input goes to a keyed and an unkeyed receiver that live
for the whole run, so their replay windows are pushed around as an attacker
would push them. Valid packets go to a second pair that sees only genuine
traffic, and must be accepted by the receiver whose key setting matches
(and refused with BadTag by the other). Prints the number of inputs, unexpected
exceptions (must be 0), valid packets refused (must be 0), the outcomes, the
slowest input by wall clock and by CPU time (each re-timed, to tell a slow
input from a pause of the machine; under 10 ms or the run fails) and peak
memory (max RSS, before and after: no growth means nothing accumulates).

Run: python benchmarks/fuzz_link.py [INPUTS] [SEED]
"""

from __future__ import annotations

import collections
import contextlib
import hashlib
import hmac
import random
import resource
import sys
import time
import traceback

from clark_engine.link import (
    ActivateController,
    AgentAttitude,
    AgentStatus,
    AgentType,
    BehaviorState,
    ClarkLinkError,
    Codec,
    Condition,
    Heartbeat,
    Message,
    ModeChangeRequest,
    PictureData,
    Terminate,
)
from clark_engine.link.packet import HEADER_BYTES, TAG_BYTES

MISSION = 7
KEY = bytes(range(32))
SLOW_MS = 10.0


def random_message(rng: random.Random, sender: int) -> Message:
    gps = rng.getrandbits(41)
    kind = rng.randrange(8)
    if kind == 0:
        return Heartbeat(
            sender, gps, MISSION, rng.choice(list(AgentType)), rng.choice(list(Condition))
        )
    if kind == 1:
        return AgentStatus(
            sender,
            gps,
            rng.uniform(-90, 90),
            rng.uniform(-180, 180),
            rng.uniform(-100, 3000),
            rng.uniform(0, 60),
            rng.uniform(-10, 10),
            rng.uniform(0, 359.99),
            rng.randrange(30),
        )
    if kind == 2:
        return PictureData(
            sender, gps, rng.uniform(-90, 90), rng.uniform(-180, 180), 80.0, rng.randrange(9999)
        )
    if kind == 3:
        return ModeChangeRequest(sender, gps, rng.randrange(65536), rng.randrange(30))
    if kind == 4:
        return ActivateController(sender, gps, rng.randrange(65536), rng.random() < 0.5)
    if kind == 5:
        return AgentAttitude(sender, gps, *(rng.uniform(-180, 180) for _ in range(3)))
    if kind == 6:
        return Terminate(sender, gps, 0, "".join(rng.choice("abc é✓") for _ in range(10)))
    return BehaviorState(sender, gps, ("a.b", "c"), "done")


class Source:
    """Makes the inputs: valid packets from a few senders, and damage to them."""

    def __init__(self, rng: random.Random) -> None:
        self.rng = rng
        self.senders = {
            (sender, keyed): Codec(MISSION, sender, KEY if keyed else None)
            for sender in (2, 3, 4)
            for keyed in (False, True)
        }

    def valid(self) -> bytes:
        rng = self.rng
        sender, keyed = rng.choice((2, 3, 4)), rng.random() < 0.5
        messages = [random_message(rng, sender) for _ in range(rng.randint(1, 8))]
        return self.senders[sender, keyed].encode(messages, destination=rng.choice((0, 1)))[0]

    def random_bytes(self) -> bytes:
        return self.rng.randbytes(self.rng.randrange(1501))

    def random_bundle(self) -> bytes:
        rng = self.rng
        signed = rng.random() < 0.5
        header = bytes((1, 1 if signed else 0)) + MISSION.to_bytes(4, "big")
        header += rng.choice((2, 3)).to_bytes(2, "big") + b"\x00\x01" + rng.randbytes(6)
        data = header + rng.randbytes(rng.randrange(300))
        return sign(data) if signed else data

    def mutated(self) -> bytes:
        rng = self.rng
        data = bytearray(self.valid())
        keyed = bool(data[1] & 1)
        for _ in range(rng.randint(1, 3)):
            kind = rng.randrange(9)
            if kind == 0 and data:
                data[rng.randrange(len(data))] ^= 1 << rng.randrange(8)
            elif kind == 1:
                del data[rng.randrange(len(data) + 1) :]
            elif kind == 2:
                data += rng.randbytes(rng.randint(1, 64))
            elif kind == 3 and data:
                at = rng.randrange(len(data))
                data[at : at + 4] = rng.randbytes(rng.randint(0, 8))
            elif len(data) >= HEADER_BYTES:
                field = {4: (10, 6), 5: (2, 4), 6: (6, 2), 7: (1, 1), 8: (0, 1)}[kind]
                at, size = field
                data[at : at + size] = rng.randbytes(size)
        if keyed and len(data) > HEADER_BYTES + TAG_BYTES and rng.random() < 0.5:
            data = bytearray(sign(bytes(data[:-TAG_BYTES])))
        return bytes(data)

    def next(self) -> tuple[str, bytes]:
        pick = self.rng.random()
        if pick < 0.15:
            return "random bytes", self.random_bytes()
        if pick < 0.30:
            return "random bundle", self.random_bundle()
        if pick < 0.90:
            return "mutated", self.mutated()
        return "valid", self.valid()


def sign(body: bytes) -> bytes:
    return body + hmac.new(KEY, body, hashlib.sha256).digest()[:TAG_BYTES]


def retime(data: bytes) -> list[float]:
    """Wall-clock decode times of ``data`` on fresh receivers, sorted: slow inputs stay slow."""
    times = []
    for _ in range(50):
        for receiver in (Codec(MISSION, 1, KEY), Codec(MISSION, 1)):
            start = time.perf_counter()
            with contextlib.suppress(ClarkLinkError):
                receiver.decode(data)
            times.append(time.perf_counter() - start)
    return sorted(times)


def main() -> int:
    inputs = int(sys.argv[1]) if len(sys.argv) > 1 else 1_000_000
    seed = int(sys.argv[2]) if len(sys.argv) > 2 else 20260101
    rng = random.Random(seed)
    source = Source(rng)
    attacked = (Codec(MISSION, 1, KEY), Codec(MISSION, 1))
    clean = (Codec(MISSION, 1, KEY), Codec(MISSION, 1))
    valid_refused = 0
    outcomes: collections.Counter[str] = collections.Counter()
    unexpected: list[str] = []
    # Slowest by wall clock (what a tick would feel, including the machine's own pauses)
    # and by this thread's CPU time (the input's own cost, immune to preemption).
    slowest_wall_s, slowest_wall_input = 0.0, b""
    slowest_cpu_s, slowest_cpu_input = 0.0, b""
    rss_before_kb = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss
    started = time.perf_counter()
    for _ in range(inputs):
        kind, data = source.next()
        for receiver in clean if kind == "valid" else attacked:
            start, start_cpu = time.perf_counter(), time.thread_time()
            try:
                receiver.decode(data)
                outcome = "accepted"
            except ClarkLinkError as exc:
                outcome = type(exc).__name__
            except Exception:
                outcome = "UNEXPECTED"
                if len(unexpected) < 5:
                    unexpected.append(f"{data.hex()}\n{traceback.format_exc()}")
            took, took_cpu = time.perf_counter() - start, time.thread_time() - start_cpu
            if took > slowest_wall_s:
                slowest_wall_s, slowest_wall_input = took, data
            if took_cpu > slowest_cpu_s:
                slowest_cpu_s, slowest_cpu_input = took_cpu, data
            pair = "clean" if kind == "valid" else "attacked"
            setting = "keyed" if receiver.authenticated else "plain"
            outcomes[f"{pair} {setting}: {outcome}"] += 1
            if kind == "valid":
                matches = receiver.authenticated == bool(data[1] & 1)
                valid_refused += outcome != ("accepted" if matches else "BadTag")
        outcomes[f"input: {kind}"] += 1
    elapsed = time.perf_counter() - started
    rss_after_kb = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss

    count_unexpected = sum(v for k, v in outcomes.items() if k.endswith("UNEXPECTED"))
    decodes = sum(v for k, v in outcomes.items() if not k.startswith("input"))
    print(f"inputs: {inputs:,} (each decoded by a keyed and an unkeyed receiver: {decodes:,})")
    print(f"unexpected exceptions: {count_unexpected}")
    print(f"valid packets refused: {valid_refused} of {outcomes['input: valid']:,}")
    worst_retime_s = 0.0
    for label, took, data in (
        ("wall clock", slowest_wall_s, slowest_wall_input),
        ("CPU time", slowest_cpu_s, slowest_cpu_input),
    ):
        retimes = retime(data)
        worst_retime_s = max(worst_retime_s, retimes[-1])
        print(
            f"slowest input by {label}: {took * 1e3:.3f} ms ({len(data)} B); re-timed 100 times "
            f"on fresh receivers: median {retimes[len(retimes) // 2] * 1e3:.3f} ms, "
            f"max {retimes[-1] * 1e3:.3f} ms"
        )
    print(f"mean per decode: {elapsed / decodes * 1e6:.1f} us (input generation included)")
    print(
        f"peak memory (max RSS): {rss_after_kb / 1024:.1f} MiB "
        f"({rss_before_kb / 1024:.1f} MiB before the run)"
    )
    windows = [len(receiver._windows) for receiver in attacked]
    print(f"replay windows held by the attacked receivers: keyed {windows[0]}, plain {windows[1]}")
    print(f"wall time: {elapsed:.0f} s, seed {seed}")
    print("outcomes:")
    for name, number in sorted(outcomes.items()):
        print(f"  {name:32} {number:>9,}")
    for text in unexpected:
        print(text)
    slow = max(slowest_cpu_s, worst_retime_s) * 1e3 >= SLOW_MS
    return 1 if count_unexpected or valid_refused or slow else 0


if __name__ == "__main__":
    sys.exit(main())
