"""Every example mission on ArduPilot SITL: how long it takes, and how close the simulation is.

For each mission in ``missions/``, one ``clark dry-run --autopilot sitl`` (in this
process, as the command runs it): the mission on the simulated autopilot, then on one
ArduPilot SITL process per vehicle at the given speed-up. Printed per mission: the
firmwares flown, simulated seconds, wall seconds of the SITL run (SITL sets the pace:
about the mission's duration over the speed-up, plus the pre-flight of aircraft handed
over in flight), its own checks passed, and the comparison of the two runs
(:mod:`clark_engine.dryrun.timeline`): states compared, its verdict, and the worst time
(against what its leg allowed), position, altitude and check figure; what failed.

Needs SITL: ``--sitl PATH`` or ``$CLARK_SITL`` (the folder with the ``sitl`` launcher).

Run: python benchmarks/bench_sitl.py [--sitl PATH] [--speedup X] [MISSION...]
"""

from __future__ import annotations

import argparse
import io
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent


def main() -> int:
    from clark_engine.dryrun.command import DEFAULT_SITL_SPEEDUP, run_dry_run
    from clark_engine.errors import ClarkError
    from clark_engine.sitl.launcher import SitlInstall
    from clark_engine.validation import validate_file

    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--sitl", help="the SITL folder ($CLARK_SITL by default)")
    parser.add_argument("--speedup", type=float, default=DEFAULT_SITL_SPEEDUP)
    parser.add_argument("--tables", action="store_true", help="print each comparison's tables")
    parser.add_argument("missions", nargs="*", type=Path)
    args = parser.parse_args()
    try:
        install = SitlInstall.find(args.sitl)
    except ClarkError as exc:
        print(f"bench_sitl: {exc}", file=sys.stderr)
        return 2
    missions = args.missions or sorted((ROOT / "missions").glob("*.yaml"))
    print(f"ArduPilot SITL from {install.folder}, speed-up {args.speedup:g}")
    header = (
        f"{'mission':<28} {'firmwares':<24} {'sim s':>6} {'wall s':>7} {'checks':>7} "
        f"{'states':>6} {'comparison':>10}"
    )
    print(header)
    failures = 0
    for path in missions:
        mission = validate_file(path, str(path)).mission
        if mission is None:
            print(f"{path}: invalid", file=sys.stderr)
            failures += 1
            continue
        firmwares = sorted(
            {
                str(agent.hardware.parts["autopilot"]["firmware"])
                for agent in mission.agents.values()
                if agent.is_vehicle
            }
        )
        started = time.perf_counter()
        outcome = run_dry_run(
            path,
            seed=None,
            until_s=None,
            report=None,
            speed=None,
            sitl=install,
            sitl_speedup=args.speedup,
            out=io.StringIO(),
            err=io.StringIO(),
        )
        total_s = time.perf_counter() - started
        result, comparison = outcome.result, outcome.comparison
        assert result is not None and comparison is not None
        passed = sum(r.passed for r in outcome.results[:-1])
        print(
            f"{path.stem:<28} {','.join(firmwares):<24} {result.recording.end_s:>6.0f} "
            f"{result.wall_s:>7.1f} {passed:>3}/{len(outcome.results) - 1:<3} "
            f"{len(comparison.states):>6} {'pass' if comparison.holds else 'FAIL':>10}"
            + ("" if outcome.exit_code == 0 else "   (exit 1)")
            + f"   ({total_s:.1f} s in all)"
        )
        print(f"    worst: {'; '.join(comparison.worst())}")
        if not comparison.holds:
            print(f"    failed: {comparison.check().observed}")
        if args.tables:
            print(comparison.table())
        failures += outcome.exit_code != 0
    return 1 if failures else 0


if __name__ == "__main__":
    sys.exit(main())
