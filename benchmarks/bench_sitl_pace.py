"""Does the engine keep ArduPilot SITL's pace? How far behind SITL's clock a SITL run falls.

SITL runs on its own clock and cannot be paused; the engine must keep up with it, or it
hears SITL late and its heartbeats and commands reach SITL late (issue 19: during
supercub_sysid's sine sweep the run fell 56-289 s behind, and ArduPlane's ground-station
failsafe flew RTL in such runs). For each mission and speed-up, one ``clark dry-run
--autopilot sitl`` in this process; printed per SITL vehicle: the most SITL's clock was
past the run's time (and when), the longest silence of the engine's link to the
autopilot (SITL's clock), the run's wall time, and the mission's signal and failsafe
checks on SITL, and the speed-ups the run set SITL to (slowed when it fell behind, sped up
again once it kept up)
(:mod:`clark_engine.dryrun.sitl_pace`). The machine's load average is printed with each run:
the figures depend on it. ``--busy N`` keeps N processes spinning meanwhile, as a loaded
machine (a test suite beside the run) would; ``--runs K`` flies each mission K times.

Needs SITL: ``--sitl PATH`` or ``$CLARK_SITL``.

Run: python benchmarks/bench_sitl_pace.py [--sitl PATH] [--speedup X]... [--busy N]
     [--runs K] [MISSION...]
(default: missions/supercub_sysid.yaml at 5 and 10)
"""

from __future__ import annotations

import argparse
import io
import multiprocessing
import os
import sys
import time
from pathlib import Path
from typing import TYPE_CHECKING

if TYPE_CHECKING:
    from clark_engine.sitl.launcher import SitlInstall

ROOT = Path(__file__).resolve().parent.parent


def _spin() -> None:
    """A busy process: another job on the machine, for as long as the benchmark runs."""
    while True:
        pass


def main() -> int:
    from clark_engine.errors import ClarkError
    from clark_engine.sitl.launcher import SitlInstall

    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--sitl", help="the SITL folder ($CLARK_SITL by default)")
    parser.add_argument(
        "--speedup", type=float, action="append", help="SITL's speed-up (repeat it: 5 and 10)"
    )
    parser.add_argument("--busy", type=int, default=0, help="processes spinning meanwhile")
    parser.add_argument("--runs", type=int, default=1, help="runs of each mission")
    parser.add_argument("missions", nargs="*", type=Path)
    args = parser.parse_args()
    try:
        install = SitlInstall.find(args.sitl)
    except ClarkError as exc:
        print(f"bench_sitl_pace: {exc}", file=sys.stderr)
        return 2
    missions = args.missions or [ROOT / "missions" / "supercub_sysid.yaml"]
    speedups = args.speedup or [5.0, 10.0]
    print(f"ArduPilot SITL from {install.folder}")
    print(
        f"{'mission':<26} {'x':>4} {'vehicle':<8} {'behind s':>8} {'at s':>6} {'silent s':>8} "
        f"{'wall s':>7} {'load':>5} {'speed-ups':>22}  checks on SITL"
    )
    busy = [multiprocessing.Process(target=_spin, daemon=True) for _ in range(args.busy)]
    for process in busy:
        process.start()
    try:
        for path in missions:
            for speedup in speedups:
                for _ in range(args.runs):
                    _fly(path, speedup, install)
    finally:
        for process in busy:
            process.terminate()
    return 0


def _fly(path: Path, speedup: float, install: SitlInstall) -> None:
    """One run of ``path`` on SITL at ``speedup``: a line per SITL vehicle."""
    from clark_engine.dryrun.command import run_dry_run

    started = time.perf_counter()
    outcome = run_dry_run(
        path,
        seed=None,
        until_s=None,
        report=None,
        speed=None,
        sitl=install,
        sitl_speedup=speedup,
        out=io.StringIO(),
        err=io.StringIO(),
        quiet=True,
    )
    total_s = time.perf_counter() - started
    result = outcome.result
    if result is None:
        print(f"{path.stem}: the run failed (exit {outcome.exit_code})", file=sys.stderr)
        return
    checks = "; ".join(
        f"{r.name}: {'pass' if r.passed else 'FAIL'}"
        for r in outcome.results[:-1]
        if "failsafe" in r.name or "shape" in r.name or "law" in r.name
    )
    load = os.getloadavg()[0]
    for name, pace in result.recording.pace.items():
        changes = ", ".join(f"{x:.1f}" for _, x in pace.speedups) or "-"
        print(
            f"{path.stem:<26} {speedup:>4g} {name:<8} {pace.behind_s:>8.2f} "
            f"{pace.behind_at_s:>6.1f} {pace.silent_s:>8.2f} {result.wall_s:>7.1f} "
            f"{load:>5.1f} {changes:>22}  {checks}   ({total_s:.0f} s in all)"
        )


if __name__ == "__main__":
    sys.exit(main())
