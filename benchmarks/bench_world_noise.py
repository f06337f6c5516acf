"""What a noisy world costs: a 50-agent fleet's dry run with and without GPS error and bursts.

Runs the generated fleet (benchmarks/fleet.py, UDP LAN radios, 10 Hz loops) for a few
simulated seconds in one process, three ways: as it is, with ``sim.radio_bursts`` (a
Gilbert-Elliott chain on each of its 2,450 directed links' 1,225 pairs), and with bursts
plus ``sim.gps_error`` (a walk and glitches on every vehicle). Prints the best and median
wall seconds of several rounds.

Run: python benchmarks/bench_world_noise.py [AGENTS] [SECONDS]   (figures: docs/performance.md)
"""

from __future__ import annotations

import statistics
import sys
import tempfile
import time
from pathlib import Path

from fleet import fleet_mission

from clark_engine.dryrun.engine import DryRun
from clark_engine.validation import validate_file

ROUNDS = 3
WORLDS = {
    "clean": "",
    "bursts": "  radio_bursts: {good_s: 20, bad_s: 2, loss_good: 0.01, loss_bad: 0.9}\n",
    "bursts + GPS error": (
        "  radio_bursts: {good_s: 20, bad_s: 2, loss_good: 0.01, loss_bad: 0.9}\n"
        "  gps_error: {walk_m: 1.5, walk_time_constant_s: 300, common_share: 0.5, "
        "glitch_rate_per_h: 6, glitch_m: 10, glitch_s: 5}\n"
    ),
}


def main() -> None:
    agents = int(sys.argv[1]) if len(sys.argv) > 1 else 50
    until_s = float(sys.argv[2]) if len(sys.argv) > 2 else 10.0
    base = fleet_mission(agents)
    with tempfile.TemporaryDirectory() as folder:
        for name, extra in WORLDS.items():
            assert "\nsim:" not in base
            text = base + ("\nsim:\n" + extra if extra else "")
            path = Path(folder) / f"fleet_{name.replace(' ', '_').replace('+', '')}.yaml"
            path.write_text(text)
            validation = validate_file(path, str(path))
            assert validation.mission is not None, [f.format_text() for f in validation.findings]
            walls = []
            for _ in range(ROUNDS):
                start = time.perf_counter()
                DryRun(validation.mission, path, seed=1, until_s=until_s).run()
                walls.append(time.perf_counter() - start)
            print(
                f"{agents} agents, {until_s:g} s simulated, {name:20s}: "
                f"best {min(walls):.2f} s, median {statistics.median(walls):.2f} s"
            )


if __name__ == "__main__":
    main()
