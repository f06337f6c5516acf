"""How fast `clark dry-run` simulates, and how much memory it takes.

For every example mission (its declared duration) and for generated fleets of 10 and
50 agents at a 10 Hz loop (60 simulated seconds, the shipped platforms' behaviours,
UDP radios: an XBee mesh cannot carry 50 agents' telemetry), one dry run each in a
fresh process, so that peak memory is that run's alone. Printed per run: agents,
simulated seconds, wall seconds of the simulation loop (validation, compilation and
report excluded), the speed-up (simulated seconds per wall second; the issue's target
is 10x for 50 agents at 10 Hz), agent ticks per wall second, and the process's peak
resident memory (of the process that gathers the run: a split run's other processes
each hold their share).

The fleets run twice: in one process and split across the usable cores
(``--workers``, :mod:`clark_engine.sim.parallel`), whose logs are the same byte for
byte. The 50-agent fleet runs again writing every agent's logs and CSV files, as
``--report`` does (``logs``): each agent's fleet CSV has a row per agent per tick.
The examples run as ``clark dry-run`` runs them by default (one process: they have
too few agents to gain from splitting).

Run: python benchmarks/bench_sim.py [--quick] [--repeat N]
(--quick: the 50-agent fleet for 20 s only. --repeat N: only the 50-agent fleet, N times
in one process and N times split, alternating, with each run's figures and the medians:
on a shared machine wall times move by tens of per cent from one minute to the next.)
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


def one(
    mission: Path, until_s: float | None, workers: int | None, report: bool
) -> dict[str, float]:
    """Dry-run ``mission`` in this process (split when ``workers`` > 1); the figures.

    With ``report``, every agent's logs and CSV files are written (into a temporary
    folder) as ``--report`` writes them; the plots, drawn after the loop, are not timed.
    """
    from clark_engine.sim.dryrun import run_dry_run

    with tempfile.TemporaryDirectory() as tmp:
        outcome = run_dry_run(
            mission,
            seed=None,
            until_s=until_s,
            report=Path(tmp) / "report" if report else None,
            speed=None,
            workers=workers,
            out=io.StringIO(),
            err=io.StringIO(),
        )
    result = outcome.result
    if result is None:
        raise SystemExit(f"{mission}: invalid mission")
    ticks = sum(result.ticks.values())
    return {
        "agents": len(result.ticks),
        "workers": float(result.workers),
        "sim_s": result.recording.end_s,
        "wall_s": result.wall_s,
        "ticks": float(ticks),
        "passed": float(outcome.exit_code == 0),
        # Linux reports ru_maxrss in KiB.
        "peak_mib": resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024,
    }


def measure(
    mission: Path, until_s: float | None, workers: int | None, report: bool = False
) -> dict[str, float]:
    """Run :func:`one` in a fresh interpreter, for a clean peak-memory figure."""
    args = [sys.executable, __file__, "--one", str(mission), str(until_s), str(workers)]
    if report:
        args.append("--report")
    done = subprocess.run(args, capture_output=True, text=True, check=False, cwd=ROOT)
    if done.returncode != 0:
        raise SystemExit(done.stderr)
    figures: dict[str, float] = json.loads(done.stdout)
    return figures


def repeat(times: int) -> None:
    """The 50-agent fleet ``times`` times alone and split, alternating; medians at the end."""
    sys.path.insert(0, str(Path(__file__).resolve().parent))
    from fleet import fleet_mission

    from clark_engine.sim.parallel import usable_cores

    cores = usable_cores()
    speeds: dict[int, list[float]] = {1: [], cores: []}
    with tempfile.TemporaryDirectory() as tmp:
        path = Path(tmp) / "fleet_50.yaml"
        path.write_text(fleet_mission(50, loop_hz=10), encoding="utf-8")
        for run in range(times):
            for workers in speeds:
                f = measure(path, FLEET_SECONDS, workers)
                speeds[workers].append(f["sim_s"] / f["wall_s"])
                print(
                    f"run {run + 1}: 50 agents, {workers} process(es): "
                    f"wall {f['wall_s']:.2f} s, {speeds[workers][-1]:.1f}x",
                    flush=True,
                )
    for workers, values in speeds.items():
        print(
            f"{workers} process(es): median {statistics.median(values):.1f}x "
            f"(min {min(values):.1f}x, max {max(values):.1f}x, {len(values)} runs)"
        )


def main() -> None:
    sys.path.insert(0, str(Path(__file__).resolve().parent))
    from fleet import fleet_mission

    quick = "--quick" in sys.argv
    from clark_engine.sim.parallel import usable_cores

    cores = usable_cores()
    cases: list[tuple[str, Path, float | None, int | None, bool]] = [
        (path.stem, path, None, None, False) for path in sorted((ROOT / "missions").glob("*.yaml"))
    ]
    with tempfile.TemporaryDirectory() as tmp:
        for size in (10, 50):
            path = Path(tmp) / f"fleet_{size}.yaml"
            path.write_text(fleet_mission(size, loop_hz=10), encoding="utf-8")
            seconds = 20.0 if quick and size == 50 else FLEET_SECONDS
            label = f"generated fleet, {size} agents, 10 Hz"
            for report in (False, True) if size == 50 else (False,):
                tag = f"{label}{', logs' if report else ''}"
                cases.append((tag, path, seconds, 1, report))
                if cores > 1:
                    cases.append((tag, path, seconds, cores, report))
        print(
            f"{'mission':<40} {'agents':>6} {'procs':>5} {'sim s':>7} {'wall s':>7} "
            f"{'speed-up':>9} {'ticks/s':>9} {'peak MiB':>9}"
        )
        for label, path, until, workers, report in cases:
            f = measure(path, until, workers, report)
            speed = f["sim_s"] / f["wall_s"] if f["wall_s"] else float("inf")
            ticks = f["ticks"] / f["wall_s"] if f["wall_s"] else 0.0
            print(
                f"{label:<40} {f['agents']:>6.0f} {f['workers']:>5.0f} {f['sim_s']:>7.0f} "
                f"{f['wall_s']:>7.2f} "
                f"{speed:>8.1f}x {ticks:>9.0f} {f['peak_mib']:>9.0f}"
            )


if __name__ == "__main__":
    if len(sys.argv) >= 3 and sys.argv[1] == "--one":
        # --one MISSION [UNTIL|None [WORKERS|None]] [--report]: one run here, as JSON.
        sys.path.insert(0, str(ROOT))
        given = [*(a for a in sys.argv[3:] if a != "--report"), "None", "None"]
        until = None if given[0] == "None" else float(given[0])
        workers = None if given[1] == "None" else int(given[1])
        figures = one(Path(sys.argv[2]), until, workers, "--report" in sys.argv)
        print(json.dumps(figures))
    elif "--repeat" in sys.argv:
        repeat(int(sys.argv[sys.argv.index("--repeat") + 1]))
    else:
        main()
