"""What a packet's own fate costs: the radio mesh alone, per packet and receiver.

The mesh (``clark_engine/sim/radio.py``) decides a packet's loss and corruption from a
keyed hash of the packet's identity, computed only when the packet can be lost or is sent
into a corruption window. This sends broadcasts from 10 agents (9 receivers each) at
10 Hz for a few simulated seconds and takes every delivery, four ways: a clean mesh, 5 %
random loss, 20 % corruption, and both. Prints the CPU microseconds per packet and receiver
(process time, so that other work on a shared machine weighs less), best and median of
several rounds.

``--module PATH`` measures another copy of radio.py instead (it imports nothing but the
standard library), e.g. the previous commit's, to compare:

    git show HEAD~1:clark_engine/sim/radio.py > /tmp/radio_old.py
    python benchmarks/bench_radio_fate.py --module /tmp/radio_old.py

Run: python benchmarks/bench_radio_fate.py [--module PATH] [--seconds S]
(figures: docs/performance.md)
"""

from __future__ import annotations

import argparse
import importlib.util
import math
import random
import statistics
import sys
import time
from pathlib import Path
from types import ModuleType
from typing import Any

ROUNDS = 5
AGENTS = 10
RATE_HZ = 10
PROFILE = {"throughput_bps": 1e9, "max_packet_bytes": 1400, "frame_overhead_bytes": 0}
WORLDS: dict[str, dict[str, float]] = {
    "clean": {},
    "loss 5 %": {"loss": 0.05},
    "corrupt 20 %": {"corrupt": 0.2},
    "loss 5 % + corrupt 20 %": {"loss": 0.05, "corrupt": 0.2},
}


def load(path: Path | None) -> ModuleType:
    """The radio module to measure: this tree's, or a copy of radio.py at ``path``."""
    if path is None:
        from clark_engine.sim import radio

        return radio
    spec = importlib.util.spec_from_file_location("radio_under_test", path)
    assert spec is not None and spec.loader is not None
    module = importlib.util.module_from_spec(spec)
    sys.modules[spec.name] = module  # its dataclasses look their module up
    spec.loader.exec_module(module)
    return module


def one_round(radio: Any, world: dict[str, float], seconds: float) -> tuple[float, int]:
    """CPU seconds for one run of the world, and the packet-receiver pairs it carried."""
    mesh = radio.RadioMesh(random.Random("1:radio"), loss_rate=world.get("loss", 0.0))
    names = [f"agent{i:02d}" for i in range(AGENTS)]
    for i, name in enumerate(names):
        mesh.add_agent(name, i + 1, PROFILE)
    if "corrupt" in world:
        mesh.corrupt(world["corrupt"])
    packet = bytes(range(80))
    ticks = int(seconds * RATE_HZ)
    start = time.process_time()
    for tick in range(ticks):
        now_s = tick / RATE_HZ
        for name in names:
            mesh.send(name, packet, "", now_s)
        mesh.deliveries_until(now_s)
    mesh.deliveries_until(math.inf)
    return time.process_time() - start, ticks * AGENTS * (AGENTS - 1)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--module", type=Path, help="a radio.py to measure instead")
    parser.add_argument("--seconds", type=float, default=200.0, help="simulated seconds")
    args = parser.parse_args()
    radio = load(args.module)
    print(
        f"{args.module or 'clark_engine.sim.radio'}: {AGENTS} agents broadcasting at {RATE_HZ} Hz"
    )
    for name, world in WORLDS.items():
        per_us = []
        for _ in range(ROUNDS):
            cpu_s, pairs = one_round(radio, world, args.seconds)
            per_us.append(cpu_s / pairs * 1e6)
        print(
            f"{name:24s}: {pairs} packet-receivers a round, "
            f"best {min(per_us):.2f} us, median {statistics.median(per_us):.2f} us"
        )


if __name__ == "__main__":
    main()
