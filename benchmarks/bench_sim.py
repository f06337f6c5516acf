"""How fast `clark dry-run` simulates, and how much memory it takes.

For every example mission (its declared duration) and for generated fleets of 10 and
50 agents at a 10 Hz loop (60 simulated seconds, the shipped platforms' behaviours,
UDP radios: an XBee mesh cannot carry 50 agents' telemetry), one dry run each in a
fresh process, so that peak memory is that run's alone. Printed per run: agents,
simulated seconds, wall seconds of the simulation loop (validation, compilation and
report excluded), the speed-up (simulated seconds per wall second; the issue's target
is 10x for 50 agents at 10 Hz), agent ticks per wall second, and the process's peak
resident memory.

Every run is one process, as ``clark dry-run`` runs it (the dry run's own process
split was removed in issue 19: docs/performance.md). The 50-agent fleet runs again
writing every agent's logs and CSV files, as ``--report`` does (``logs``): each agent's
fleet CSV has a row per agent per tick.

Run: python benchmarks/bench_sim.py [--quick] [--repeat N]
(--quick: the 50-agent fleet for 20 s only. --repeat N: only the 50-agent fleet, N
times, with each run's figures and the median: on a shared machine wall times move by
tens of per cent from one minute to the next.)
"""

from __future__ import annotations

import io
import json
import resource
import statistics
import subprocess
import sys
import tempfile
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
FLEET_SECONDS = 60.0


def one(mission: Path, until_s: float | None, report: bool) -> dict[str, float]:
    """Dry-run ``mission`` in this process; the figures.

    With ``report``, every agent's logs and CSV files are written (into a temporary
    folder) as ``--report`` writes them; the plots, drawn after the loop, are not timed.
    """
    from clark_engine.dryrun.command import run_dry_run

    with tempfile.TemporaryDirectory() as tmp:
        outcome = run_dry_run(
            mission,
            seed=None,
            until_s=until_s,
            report=Path(tmp) / "report" if report else None,
            speed=None,
            out=io.StringIO(),
            err=io.StringIO(),
        )
    result = outcome.result
    if result is None:
        raise SystemExit(f"{mission}: invalid mission")
    ticks = sum(result.ticks.values())
    return {
        "agents": len(result.ticks),
        "sim_s": result.recording.end_s,
        "wall_s": result.wall_s,
        "ticks": float(ticks),
        "passed": float(outcome.exit_code == 0),
        # Linux reports ru_maxrss in KiB.
        "peak_mib": resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024,
    }


def measure(mission: Path, until_s: float | None, report: bool = False) -> dict[str, float]:
    """Run :func:`one` in a fresh interpreter, for a clean peak-memory figure."""
    args = [sys.executable, __file__, "--one", str(mission), str(until_s)]
    if report:
        args.append("--report")
    done = subprocess.run(args, capture_output=True, text=True, check=False, cwd=ROOT)
    if done.returncode != 0:
        raise SystemExit(done.stderr)
    figures: dict[str, float] = json.loads(done.stdout)
    return figures


def repeat(times: int) -> None:
    """The 50-agent fleet ``times`` times, each in a fresh process; the median at the end."""
    sys.path.insert(0, str(Path(__file__).resolve().parent))
    from fleet import fleet_mission

    speeds: list[float] = []
    with tempfile.TemporaryDirectory() as tmp:
        path = Path(tmp) / "fleet_50.yaml"
        path.write_text(fleet_mission(50, loop_hz=10), encoding="utf-8")
        for run in range(times):
            f = measure(path, FLEET_SECONDS)
            speeds.append(f["sim_s"] / f["wall_s"])
            print(
                f"run {run + 1}: 50 agents: wall {f['wall_s']:.2f} s, {speeds[-1]:.1f}x",
                flush=True,
            )
    print(
        f"median {statistics.median(speeds):.1f}x "
        f"(min {min(speeds):.1f}x, max {max(speeds):.1f}x, {len(speeds)} runs)"
    )


def main() -> None:
    sys.path.insert(0, str(Path(__file__).resolve().parent))
    from fleet import fleet_mission

    quick = "--quick" in sys.argv
    cases: list[tuple[str, Path, float | None, bool]] = [
        (path.stem, path, None, False) for path in sorted((ROOT / "missions").glob("*.yaml"))
    ]
    with tempfile.TemporaryDirectory() as tmp:
        for size in (10, 50):
            path = Path(tmp) / f"fleet_{size}.yaml"
            path.write_text(fleet_mission(size, loop_hz=10), encoding="utf-8")
            seconds = 20.0 if quick and size == 50 else FLEET_SECONDS
            label = f"generated fleet, {size} agents, 10 Hz"
            for report in (False, True) if size == 50 else (False,):
                tag = f"{label}{', logs' if report else ''}"
                cases.append((tag, path, seconds, report))
        print(
            f"{'mission':<40} {'agents':>6} {'sim s':>7} {'wall s':>7} "
            f"{'speed-up':>9} {'ticks/s':>9} {'peak MiB':>9}"
        )
        for label, path, until, report in cases:
            f = measure(path, until, report)
            speed = f["sim_s"] / f["wall_s"] if f["wall_s"] else float("inf")
            ticks = f["ticks"] / f["wall_s"] if f["wall_s"] else 0.0
            print(
                f"{label:<40} {f['agents']:>6.0f} {f['sim_s']:>7.0f} "
                f"{f['wall_s']:>7.2f} "
                f"{speed:>8.1f}x {ticks:>9.0f} {f['peak_mib']:>9.0f}"
            )


if __name__ == "__main__":
    if len(sys.argv) >= 3 and sys.argv[1] == "--one":
        # --one MISSION [UNTIL|None] [--report]: one run here, as JSON.
        sys.path.insert(0, str(ROOT))
        given = [*(a for a in sys.argv[3:] if a != "--report"), "None"]
        until = None if given[0] == "None" else float(given[0])
        figures = one(Path(sys.argv[2]), until, "--report" in sys.argv)
        print(json.dumps(figures))
    elif "--repeat" in sys.argv:
        repeat(int(sys.argv[sys.argv.index("--repeat") + 1]))
    else:
        main()
