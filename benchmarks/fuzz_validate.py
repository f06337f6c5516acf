"""Fuzz missions through validate, compile and a short dry run, far beyond the suite's run.

Mutated example missions, half with their structure damaged (keys dropped, values of the
wrong type, states rewired: tests/test_fuzz_validate.py) and half with numbers and
strings pushed to extremes (0, -1, 4294967295, 10**400, 1.797e308, nan, 6,000-character
paths: tests/test_number_ranges.py). Each is validated as `clark validate` does; one
that validates is compiled and dry-run in-process for a few simulated seconds. Nothing
may raise: every exception is counted as a crash, by stage and place, and the first
mission of each kind of crash is written out for reproduction.

Run:
    python benchmarks/fuzz_validate.py [MISSIONS] [--until S] [--validate-only] [--save DIR]

Prints the missions tried, how many were invalid, valid and dry-run (with their exit
codes), the crashes (must be 0) and the time taken. Fresh randomness each run.
"""

from __future__ import annotations

import argparse
import collections
import io
import sys
import tempfile
import time
import traceback
from pathlib import Path

from hypothesis import HealthCheck, Phase, given, settings
from hypothesis import strategies as st

sys.path.insert(0, str(Path(__file__).resolve().parent.parent / "tests"))
import test_fuzz_validate as structure
import test_number_ranges as extremes

from clark_engine.dryrun.command import run_dry_run
from clark_engine.mission.compiler import compile_mission
from clark_engine.validation import validate_file


def _where(exc: BaseException) -> str:
    """file:line of the innermost frame, for grouping crashes."""
    frames = traceback.extract_tb(exc.__traceback__)
    if not frames:
        return "?"
    last = frames[-1]
    return f"{Path(last.filename).name}:{last.lineno}"


def run_one(text: str, until_s: float, dry_run: bool) -> tuple[str, int | None]:
    """Validate, compile and dry-run one mission text: (stage reached, dry-run exit code).

    Raises whatever the engine raises, with ``stage`` set on it for the report.
    """
    with tempfile.TemporaryDirectory() as tmp:
        path = Path(tmp) / "fuzz.yaml"
        path.write_text(text, encoding="utf-8")
        stage = "validate"
        try:
            result = validate_file(path, "fuzz.yaml")
            if result.mission is None:
                return "invalid", None
            stage = "compile"
            compile_mission(result.mission)
            if not dry_run:
                return "valid", None
            stage = "dry-run"
            outcome = run_dry_run(
                path,
                seed=0,
                until_s=until_s,
                report=None,
                speed=None,
                out=io.StringIO(),
                err=io.StringIO(),
                quiet=True,
            )
            return "ran", outcome.exit_code
        except Exception as exc:
            exc.add_note(f"stage: {stage}")
            exc.stage = stage  # type: ignore[attr-defined]
            raise


def main() -> int:
    """Run the fuzz and print its counts; exit 1 when anything crashed."""
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("missions", nargs="?", type=int, default=2000)
    parser.add_argument("--until", type=float, default=3.0, help="simulated seconds per run")
    parser.add_argument("--validate-only", action="store_true", help="no compile, no dry run")
    parser.add_argument("--save", type=Path, help="folder for the first mission of each crash")
    args = parser.parse_args()
    counts: collections.Counter[str] = collections.Counter()
    exits: collections.Counter[int | None] = collections.Counter()
    crashes: collections.Counter[tuple[str, str, str]] = collections.Counter()
    slowest = [0.0, ""]
    start = time.perf_counter()

    @settings(
        max_examples=args.missions,
        deadline=None,
        database=None,
        phases=[Phase.generate],
        suppress_health_check=list(HealthCheck),
    )
    @given(
        st.one_of(
            structure.mutated(),
            extremes.extreme_missions().map(lambda case: case[1]),
        )
    )
    def fuzz(text: str) -> None:
        began = time.perf_counter()
        counts["tried"] += 1
        try:
            stage, code = run_one(text, args.until, not args.validate_only)
        except Exception as exc:
            key = (getattr(exc, "stage", "?"), type(exc).__name__, _where(exc))
            if not crashes[key] and args.save is not None:
                args.save.mkdir(parents=True, exist_ok=True)
                name = f"crash_{len(crashes)}_{key[0]}_{key[1]}.yaml"
                (args.save / name).write_text(text, encoding="utf-8")
            if not crashes[key]:
                print(f"crash: {key} {str(exc)[:160]}", file=sys.stderr, flush=True)
            crashes[key] += 1
            return
        counts[stage] += 1
        if stage == "ran":
            exits[code] += 1
        took = time.perf_counter() - began
        if took > slowest[0]:
            slowest[0], slowest[1] = took, stage
        if counts["tried"] % 500 == 0:
            print(
                f"  {counts['tried']} missions: {counts['invalid']} invalid, "
                f"{counts['valid'] + counts['ran']} valid, {counts['ran']} dry-run, "
                f"{sum(crashes.values())} crashes, {time.perf_counter() - start:.0f} s",
                flush=True,
            )

    try:
        fuzz()
    except KeyboardInterrupt:  # Ctrl-C (or kill -INT): the counts so far
        print("interrupted; the counts so far:")
    elapsed = time.perf_counter() - start
    valid = counts["valid"] + counts["ran"]
    print(
        f"missions: {counts['tried']}, invalid (findings, no crash): {counts['invalid']}, "
        f"valid: {valid} (compiled: {valid}"
        + (
            ""
            if args.validate_only
            else f", dry-run --until {args.until:g}: {counts['ran']}, exit codes "
            + ", ".join(f"{k}: {v}" for k, v in sorted(exits.items(), key=str))
        )
        + ")"
    )
    print(f"crashes (tracebacks): {sum(crashes.values())}")
    for (stage, kind, where), n in crashes.most_common():
        print(f"  {n} x {kind} in {stage} at {where}")
    print(
        f"time: {elapsed:.0f} s ({elapsed / max(counts['tried'], 1) * 1e3:.0f} ms a mission), "
        f"slowest: {slowest[0] * 1e3:.0f} ms ({slowest[1]})"
    )
    return 1 if crashes else 0


if __name__ == "__main__":
    sys.exit(main())
