"""What the dry run's safety judgement costs, on a long run of a 10-vehicle fleet.

Every dry run ends with the safety judgement (:mod:`clark_engine.expectations.safety`): one pass
over every vehicle's track, read back from disk sample by sample, with each vehicle's
ceiling, floor, fence margin and each pair's distance. This dry-runs the generated
fleet (``benchmarks/fleet.py``: a station and 10 vehicles of the shipped platforms, 10 Hz)
for ``--until`` simulated seconds (an hour by default), in one process, then times the
judgement on its recording: with the fleet's default fences (a circle around each
home), and again with a declared fence of a 12-corner polygon and two exclusion zones
(the costliest margins). It prints the run's wall time beside the judgement's.

Run: python benchmarks/bench_safety.py [--until 3600] [--agents 11]
"""

from __future__ import annotations

import argparse
import dataclasses
import io
import math
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(Path(__file__).resolve().parent))

#: A declared fence around the fleet's field (the generated fleet spreads over a 400 m
#: square and its surveys fly 200 m north): a 12-corner polygon and two exclusions.
POLYGON_FENCE = (
    "envelope:\n"
    "  geofence:\n"
    "    include:\n"
    "      - polygon: ["
    + ", ".join(
        f"[{900 * math.cos(2 * math.pi * k / 12) + 200:.1f}, "
        f"{900 * math.sin(2 * math.pi * k / 12) + 200:.1f}]"
        for k in range(12)
    )
    + "]\n"
    "    exclude:\n"
    "      - {circle: {center: [-500, -500], radius_m: 30}}\n"
    "      - {polygon: [[800, -400], [850, -400], [850, -350], [800, -350]]}\n"
)


def judge_time(recording: object, configs: object, rounds: int = 3) -> tuple[float, int]:
    """Best wall time of ``rounds`` judgements, and the breaches found."""
    from clark_engine.expectations.safety import judge

    best = math.inf
    breaches = 0
    for _ in range(rounds):
        started = time.perf_counter()
        verdict = judge(recording, configs)  # type: ignore[arg-type]
        best = min(best, time.perf_counter() - started)
        breaches = len(verdict.breaches)
    return best, breaches


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n", 1)[0])
    parser.add_argument("--until", type=float, default=3600.0, help="simulated seconds")
    parser.add_argument("--agents", type=int, default=11, help="agents, the station included")
    args = parser.parse_args()
    from fleet import fleet_mission

    from clark_engine.dryrun.engine import DryRun
    from clark_engine.mission.compiler import agent_config
    from clark_engine.runtime.config import config_from_dict
    from clark_engine.validation import validate_file

    with tempfile.TemporaryDirectory() as tmp:
        path = Path(tmp) / "fleet.yaml"
        text = fleet_mission(args.agents, loop_hz=10)
        path.write_text(text, encoding="utf-8")
        mission = validate_file(path, str(path)).mission
        assert mission is not None
        run = DryRun(mission, path, seed=1, until_s=args.until)
        started = time.perf_counter()
        result = run.run()
        run_s = time.perf_counter() - started
        recording, configs = result.recording, result.configs
        vehicles = len(recording.tracks)
        samples = sum(track.count for track in recording.tracks.values())
        default_s, default_breaches = judge_time(recording, configs)
        # The same recording against the declared polygon fence.
        fenced_path = Path(tmp) / "fenced.yaml"
        fenced_path.write_text(text.replace("agents:\n", POLYGON_FENCE + "agents:\n", 1))
        fenced = validate_file(fenced_path, str(fenced_path)).mission
        assert fenced is not None, "the fenced fleet is invalid"
        fenced_configs = {
            name: dataclasses.replace(
                configs[name],
                envelope=config_from_dict(agent_config(fenced, agent)).envelope,
            )
            for name, agent in fenced.agents.items()
        }
        polygon_s, polygon_breaches = judge_time(recording, fenced_configs)
    out = io.StringIO()
    pairs = vehicles * (vehicles - 1) // 2
    print(
        f"fleet of {args.agents} agents ({vehicles} vehicles, {pairs} pairs), "
        f"{args.until:g} simulated s, {samples} track samples",
        file=out,
    )
    print(f"dry run (simulation loop)            {run_s:8.2f} s", file=out)
    print(
        f"safety judgement, default fences     {default_s:8.3f} s "
        f"({100 * default_s / run_s:.1f} % of the run; {default_breaches} breaches)",
        file=out,
    )
    print(
        f"safety judgement, 12-corner polygon  {polygon_s:8.3f} s "
        f"({100 * polygon_s / run_s:.1f} % of the run; {polygon_breaches} breaches)",
        file=out,
    )
    sys.stdout.write(out.getvalue())


if __name__ == "__main__":
    main()
