"""Campaign throughput: runs per minute on one core and on all, Dask's overhead, one big run.

Prints, for ``missions/cooperative_follow.yaml`` on the simulated autopilot:

1. runs per minute with ``--workers 1`` (in this process) and with every usable core
   (the local process pool);
2. the same campaign through a Dask cluster on this machine (a ``LocalCluster`` of one
   single-threaded worker process per core, on loopback), against the local pool;
3. one large run (``benchmarks/fleet.py 50``) in one process, alone and while another
   core is busy with independent runs (a campaign of cooperative_follow in a second
   process, as a campaign would keep it): its real-time factor, from the dry run's own
   "simulated S s in W s" line (the loop alone, not start-up or the report). The dry
   run's own process split, which this once compared, was removed (issue 19:
   docs/performance.md, "The dry run's split removed").

Every figure is a wall time on this machine with whatever else runs on it: the load
average is printed beside them. Run: python benchmarks/bench_campaign.py [--runs N]
"""

from __future__ import annotations

import argparse
import os
import re
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from clark_engine.campaign.pool import (
    Backend,
    DaskCluster,
    InProcess,
    LocalPool,
    fly_all,
    usable_cores,
)
from clark_engine.campaign.runs import RunSpec, mission_sha256, run_seed

ROOT = Path(__file__).resolve().parent.parent
FOLLOW = ROOT / "missions" / "cooperative_follow.yaml"


def load() -> str:
    """The 1-minute load average, for the record."""
    return f"{os.getloadavg()[0]:.1f}"


def campaign(runs: int, backend: Backend, slots: int) -> str:
    """Fly ``runs`` runs of cooperative_follow on ``backend``; its figures as text.

    Besides runs per minute: the time each run took in its worker (its own wall time),
    and the overhead per run, ``(wall x slots - sum of run times) / runs``: what the
    backend adds (sending, scheduling, results coming back, workers left idle), which a
    loaded machine slows less than it slows the runs.
    """
    digest = mission_sha256(FOLLOW)
    specs = [RunSpec(i, run_seed(1, i), str(FOLLOW), digest) for i in range(runs)]
    start = time.perf_counter()
    flown = fly_all(specs, backend, retries=0)
    wall = time.perf_counter() - start
    inside = sum(r.wall_s for r in flown.results)
    cpu = sum(r.cpu_s for r in flown.results)
    overhead_ms = (wall * slots - inside) / runs * 1000
    return (
        f"{runs / wall * 60:.1f} runs/min ({wall:.1f} s for {runs} runs; a run "
        f"{inside / runs:.2f} s in its worker, {cpu / runs:.2f} s of CPU; overhead "
        f"{overhead_ms:.0f} ms per run)"
    )


def fleet_run(mission: Path, until_s: float) -> tuple[float, float]:
    """One dry run of the fleet: (wall seconds of its loop, real-time factor)."""
    done = subprocess.run(
        [sys.executable, "-m", "clark_engine", "dry-run", str(mission), "--until", f"{until_s:g}",
         "-q"],
        cwd=ROOT, capture_output=True, text=True, check=False,
    )  # fmt: skip
    found = re.search(r"simulated ([0-9.]+) s in ([0-9.]+) s", done.stderr)
    if found is None:
        raise SystemExit(f"the fleet's dry run said nothing of its speed:\n{done.stderr}")
    simulated_s, wall_s = float(found[1]), float(found[2])
    return wall_s, simulated_s / wall_s


def main() -> None:
    """Measure and print every figure."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--runs", type=int, default=20, help="runs per campaign (20)")
    parser.add_argument("--skip-dask", action="store_true")
    parser.add_argument("--skip-fleet", action="store_true")
    parser.add_argument("--skip-pool", action="store_true")
    parser.add_argument("--fleet-until", type=float, default=20.0, help="fleet run's s (20)")
    parser.add_argument("--repeat", type=int, default=2, help="fleet runs, alone and busy (2)")
    args = parser.parse_args()
    cores = usable_cores()
    runs = args.runs
    print(f"cooperative_follow, {runs} runs, {cores} usable cores")
    import clark_engine.dryrun.command  # noqa: F401  (before the pool forks)

    if not args.skip_pool:
        print(f"  1 worker (this process): {campaign(runs, InProcess(), 1)}; load {load()}")
        pool = campaign(runs, LocalPool(cores), cores)
        print(f"  {cores} workers (local pool): {pool}; load {load()}")
    if not args.skip_dask:
        import distributed

        start = time.perf_counter()
        with distributed.LocalCluster(
            n_workers=cores,
            threads_per_worker=1,
            processes=True,
            host="127.0.0.1",
            scheduler_port=0,
            dashboard_address=None,
            # The scheduler's HTTP server (metrics, health) on a free port: by default it
            # binds Dask's well-known 8787 even without a dashboard, and warns when a
            # user's own cluster holds it.
            scheduler_kwargs={"dashboard": False, "dashboard_address": "127.0.0.1:0"},
        ) as cluster:
            up = time.perf_counter() - start
            text = campaign(runs, DaskCluster(cluster.scheduler_address, sitl=False), cores)
        print(
            f"  Dask LocalCluster, {cores} workers x 1 thread: {text} (cluster start "
            f"{up:.1f} s, not counted); load {load()}"
        )
    if args.skip_fleet:
        return
    with tempfile.TemporaryDirectory() as folder:
        mission = Path(folder) / "fleet-50.yaml"
        text = subprocess.run(
            [sys.executable, str(ROOT / "benchmarks" / "fleet.py"), "50"],
            capture_output=True, text=True, check=True,
        ).stdout  # fmt: skip
        mission.write_text(text)
        until = args.fleet_until
        print(f"fleet of 50 at 10 Hz, one {until:g} s run in one process:")
        for _ in range(args.repeat):
            seconds, factor = fleet_run(mission, until)
            print(f"  alone: {seconds:.1f} s, {factor:.1f}x real time; load {load()}")
        busy = subprocess.Popen(
            [sys.executable, "-m", "clark_engine", "campaign", str(FOLLOW), "--runs",
             "100000", "--workers", "1", "-q"],
            cwd=ROOT, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL,
        )  # fmt: skip
        try:
            time.sleep(3)
            for _ in range(args.repeat):
                seconds, factor = fleet_run(mission, until)
                print(
                    f"  beside a 1-worker campaign: {seconds:.1f} s, {factor:.1f}x real time; "
                    f"load {load()}"
                )
        finally:
            busy.terminate()
            busy.wait()


if __name__ == "__main__":
    main()
