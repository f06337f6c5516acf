"""`make demo`: the engine's main job on the shipped examples.

Every example mission is checked before flight and compiled into one config per
agent under demo-output/; then the thesis's cooperation test (5.2.1) is dry-run:
every agent's real runtime against a simulated fleet, its checks evaluated and a
report (summary, plots, logs) written under demo-output/dry-run/.
"""

from __future__ import annotations

import sys
import time
from pathlib import Path

from clark_engine.data import data_dir
from clark_engine.dryrun.command import run_dry_run
from clark_engine.mission.compiler import compile_mission, write_configs
from clark_engine.mission.validate import display_path
from clark_engine.validation import validate_file

OUTPUT = Path("demo-output")
DRY_RUN = "cooperative_follow.yaml"


def main() -> int:
    missions = sorted(data_dir("missions").glob("*.yaml"))
    print(f"Clark Engine demo: validating and compiling {len(missions)} example missions\n")
    print(f"{'mission':<34} {'agents':>6} {'warnings':>8} {'ms':>6}  result")
    failed = 0
    seen_codes: set[str] = set()
    for path in missions:
        start = time.perf_counter()
        result = validate_file(path, display_path(path))
        if result.mission is None:
            failed += 1
            print(f"{path.name:<34} {'-':>6} {'-':>8} {'-':>6}  INVALID")
            for finding in result.findings:
                print("    " + finding.format_text())
            continue
        files = compile_mission(result.mission)
        target = write_configs(files, OUTPUT, result.mission.name)
        elapsed_ms = (time.perf_counter() - start) * 1000
        warnings = len(result.findings)
        codes = sorted({f.code for f in result.findings})
        seen_codes.update(codes)
        print(
            f"{path.name:<34} {len(files):>6} {warnings:>8} {elapsed_ms:>6.0f}  "
            f"compiled to {target}/" + (f"  ({', '.join(codes)})" if codes else "")
        )
    print()
    if failed:
        print(f"{failed} example mission(s) are invalid; see the findings above.")
        return 1
    print(f"All example missions are valid. Compiled configs are in {OUTPUT.resolve()}/")
    if seen_codes & {"W-NO-KEY"}:
        print(
            "W-NO-KEY: the thesis flew without authentication, and so do these examples;"
            " `clark keygen` and mission.key_file add it."
        )
    return dry_run(data_dir("missions") / DRY_RUN)


def dry_run(path: Path) -> int:
    """Dry-run one example with a report, and say where the report is."""
    report = OUTPUT / "dry-run" / path.stem
    print(f"\nDry run of {path.name}: every agent's runtime against a simulated fleet\n")
    outcome = run_dry_run(path, seed=None, until_s=None, report=report, speed=None, err=sys.stdout)
    print()
    if outcome.exit_code != 0:
        print("The dry run failed (a check, or its safety judgement); see the tables above.")
        return outcome.exit_code
    summary = (report / "summary.md").resolve()
    print(f"All checks passed, no vehicle left its envelope. Open {summary}")
    print("Try: .venv/bin/clark dry-run missions/fault_station_loss.yaml --report out/")
    print("     .venv/bin/clark explain missions/supercub_sysid.yaml --agent cub")
    return 0


if __name__ == "__main__":
    sys.exit(main())
