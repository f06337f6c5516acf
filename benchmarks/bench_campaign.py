"""Campaign throughput: runs per minute on one core and on all, Dask's overhead, the split.

Prints, for ``missions/cooperative_follow.yaml`` on the simulated autopilot:

1. runs per minute with ``--workers 1`` (in this process) and with every usable core
   (the local process pool);
2. the same campaign through a Dask cluster on this machine (a ``LocalCluster`` of one
   single-threaded worker process per core, on loopback), against the local pool;
3. whether the dry run's own process split (``clark dry-run --workers 2``,
   :mod:`clark_engine.sim.parallel`) beats one process for one large run
   (``benchmarks/fleet.py 50``, 60 s) while the other core is busy with independent
   runs (a campaign of cooperative_follow in a second process, as a campaign would
   keep it), and alone.

Every figure is a wall time on this machine with whatever else runs on it: the load
average is printed beside them. Run: python benchmarks/bench_campaign.py [--runs N]
"""

from __future__ import annotations

import argparse
import io
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from clark_engine.campaign.command import CampaignOptions, run_campaign
from clark_engine.campaign.pool import usable_cores

ROOT = Path(__file__).resolve().parent.parent
FOLLOW = ROOT / "missions" / "cooperative_follow.yaml"


def load() -> str:
    """The 1-minute load average, for the record."""
    return f"{os.getloadavg()[0]:.1f}"


def campaign_s(runs: int, **options: object) -> float:
    """Wall seconds of a campaign of ``runs`` runs (quiet, nothing written)."""
    start = time.perf_counter()
    run_campaign(
        FOLLOW,
        CampaignOptions(runs=runs, quiet=True, **options),  # type: ignore[arg-type]
        out=io.StringIO(),
        err=io.StringIO(),
    )
    return time.perf_counter() - start


def per_minute(runs: int, seconds: float) -> str:
    return f"{runs / seconds * 60:.1f} runs/min ({seconds:.1f} s for {runs} runs)"


def fleet_run_s(mission: Path, workers: int) -> float:
    """Wall seconds of one 60 s dry run of the fleet with ``workers`` processes."""
    start = time.perf_counter()
    subprocess.run(
        [sys.executable, "-m", "clark_engine", "dry-run", str(mission), "--until", "60",
         "--workers", str(workers), "-q"],
        cwd=ROOT, capture_output=True, check=False,
    )  # fmt: skip
    return time.perf_counter() - start


def main() -> None:
    """Measure and print every figure."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--runs", type=int, default=20, help="runs per campaign (20)")
    parser.add_argument("--skip-dask", action="store_true")
    parser.add_argument("--skip-split", action="store_true")
    args = parser.parse_args()
    cores = usable_cores()
    runs = args.runs
    print(f"cooperative_follow, {runs} runs, {cores} usable cores")
    one = campaign_s(runs, workers=1)
    print(f"  1 worker (this process): {per_minute(runs, one)}; load {load()}")
    many = campaign_s(runs, workers=cores)
    print(f"  {cores} workers (local pool): {per_minute(runs, many)}; load {load()}")
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
        ) as cluster:
            up = time.perf_counter() - start
            dask = campaign_s(runs, scheduler=cluster.scheduler_address)
        print(
            f"  Dask LocalCluster, {cores} workers x 1 thread: {per_minute(runs, dask)} "
            f"(cluster start {up:.1f} s, not counted); against the pool: "
            f"{(dask - many) / runs * 1000:+.0f} ms per run; load {load()}"
        )
    if args.skip_split:
        return
    with tempfile.TemporaryDirectory() as folder:
        mission = Path(folder) / "fleet-50.yaml"
        text = subprocess.run(
            [sys.executable, str(ROOT / "benchmarks" / "fleet.py"), "50"],
            capture_output=True, text=True, check=True,
        ).stdout  # fmt: skip
        mission.write_text(text)
        print("fleet of 50, one 60 s run:")
        for workers in (1, 2):
            print(f"  alone, --workers {workers}: {fleet_run_s(mission, workers):.1f} s; "
                  f"load {load()}")  # fmt: skip
        busy = subprocess.Popen(
            [sys.executable, "-m", "clark_engine", "campaign", str(FOLLOW), "--runs",
             "100000", "--workers", "1", "-q"],
            cwd=ROOT, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL,
        )  # fmt: skip
        try:
            time.sleep(3)
            for workers in (1, 2):
                print(
                    f"  beside a 1-worker campaign, --workers {workers}: "
                    f"{fleet_run_s(mission, workers):.1f} s; load {load()}"
                )
        finally:
            busy.terminate()
            busy.wait()


if __name__ == "__main__":
    main()
