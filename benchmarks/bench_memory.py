"""How the memory of a long dry run grows with its simulated length.

Runs ``clark dry-run`` of one example mission whose behaviour keeps running
(``cooperative_follow``: Slash A drives its loop for as long as the run lasts) for
several simulated lengths, each in a fresh process, and prints the process's peak
resident memory (``resource.getrusage``), the samples the recording holds in memory,
and the growth per simulated hour over the shortest run. A dry run whose memory is
constant in its length shows the same peak for every length.

Run: python benchmarks/bench_memory.py [--hours 0.25,1,4] [--mission PATH] [--report]
(--report: write the report folder too, logs, CSV files and plots, into a temporary
folder, as ``clark dry-run --report`` does.)
"""

from __future__ import annotations

import argparse
import json
import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
DEFAULT_MISSION = ROOT / "missions" / "cooperative_follow.yaml"

_CHILD = r"""
import io, json, resource, sys, tempfile
from pathlib import Path
from clark_engine.dryrun import engine

held = {}
original_run = engine.DryRun.run

def run(self):
    result = original_run(self)
    rec = result.recording
    held["track_points"] = sum(len(t.times_s) for t in rec.tracks.values())
    held["state_entries"] = sum(len(s) for s in rec.states.values())
    held["signal_samples"] = sum(len(s) for s in rec.signals.values())
    return result

engine.DryRun.run = run
from clark_engine.dryrun.command import run_dry_run

mission, until_s, report = Path(sys.argv[1]), float(sys.argv[2]), sys.argv[3] == "1"
with tempfile.TemporaryDirectory() as tmp:
    out = io.StringIO()
    run_dry_run(
        mission, seed=None, until_s=until_s, report=Path(tmp) / "r" if report else None,
        speed=None, out=out, err=io.StringIO(),
    )
held["peak_rss_mb"] = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024
held["checks"] = out.getvalue()
print(json.dumps(held))
"""


def one(mission: Path, hours: float, report: bool) -> dict[str, object]:
    """Dry-run ``mission`` for ``hours`` simulated hours in a fresh process; its figures."""
    done = subprocess.run(
        [sys.executable, "-c", _CHILD, str(mission), str(hours * 3600.0), "1" if report else "0"],
        capture_output=True,
        text=True,
        check=True,
        cwd=ROOT,
    )
    figures: dict[str, object] = json.loads(done.stdout.strip().splitlines()[-1])
    return figures


def main() -> None:
    """Print peak memory per run length and the growth per simulated hour."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--hours", default="0.25,1,4", help="simulated hours, comma-separated")
    parser.add_argument("--mission", type=Path, default=DEFAULT_MISSION)
    parser.add_argument("--report", action="store_true", help="write the report folder too")
    args = parser.parse_args()
    lengths = [float(h) for h in args.hours.split(",")]
    print(f"mission: {args.mission.name}{' (with --report)' if args.report else ''}")
    print("| simulated h | peak RSS MB | track points | state entries | signal samples |")
    print("|---|---|---|---|---|")
    rows = []
    for hours in lengths:
        figures = one(args.mission, hours, args.report)
        rows.append((hours, figures))
        print(
            f"| {hours:g} | {figures['peak_rss_mb']:.1f} | {figures['track_points']} "
            f"| {figures['state_entries']} | {figures['signal_samples']} |",
            flush=True,
        )
    (first_h, first), (last_h, last) = rows[0], rows[-1]
    if last_h > first_h:
        growth = (float(last["peak_rss_mb"]) - float(first["peak_rss_mb"])) / (last_h - first_h)  # type: ignore[arg-type]
        print(f"growth: {growth:.1f} MB per simulated hour ({first_h:g} h to {last_h:g} h)")


if __name__ == "__main__":
    main()
