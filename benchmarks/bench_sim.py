"""How fast `clark dry-run` simulates, and how much memory it takes.

For every example mission (its declared duration) and for generated fleets of 10 and
50 agents at a 10 Hz loop (60 simulated seconds, the shipped platforms' behaviours,
UDP radios: an XBee mesh cannot carry 50 agents' telemetry), one dry run each in a
fresh process, so that peak memory is that run's alone. Printed per run: agents,
simulated seconds, wall seconds of the simulation loop (validation, compilation and
report excluded), the speed-up (simulated seconds per wall second; the issue's target
is 10x for 50 agents at 10 Hz), agent ticks per wall second, and the process's peak
resident memory.

Run: python benchmarks/bench_sim.py [--quick]
(--quick: the 50-agent fleet for 20 s only.)
"""

from __future__ import annotations

import io
import json
import resource
import subprocess
import sys
import tempfile
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
FLEET_SECONDS = 60.0


def one(mission: Path, until_s: float | None) -> dict[str, float]:
    """Dry-run ``mission`` in this process; the figures as a dict."""
    from clark_engine.sim.dryrun import run_dry_run

    outcome = run_dry_run(
        mission,
        seed=None,
        until_s=until_s,
        report=None,
        speed=None,
        out=io.StringIO(),
        err=io.StringIO(),
    )
    result = outcome.result
    if result is None:
        raise SystemExit(f"{mission}: invalid mission")
    ticks = sum(agent.ticks for agent in result.agents.values())
    return {
        "agents": len(result.configs),
        "sim_s": result.recording.end_s,
        "wall_s": result.wall_s,
        "ticks": float(ticks),
        "passed": float(outcome.exit_code == 0),
        # Linux reports ru_maxrss in KiB.
        "peak_mib": resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024,
    }


def measure(mission: Path, until_s: float | None) -> dict[str, float]:
    """Run :func:`one` in a fresh interpreter, for a clean peak-memory figure."""
    args = [sys.executable, __file__, "--one", str(mission)]
    if until_s is not None:
        args.append(str(until_s))
    done = subprocess.run(args, capture_output=True, text=True, check=False, cwd=ROOT)
    if done.returncode != 0:
        raise SystemExit(done.stderr)
    figures: dict[str, float] = json.loads(done.stdout)
    return figures


def main() -> None:
    sys.path.insert(0, str(Path(__file__).resolve().parent))
    from fleet import fleet_mission

    quick = "--quick" in sys.argv
    cases: list[tuple[str, Path, float | None]] = [
        (path.stem, path, None) for path in sorted((ROOT / "missions").glob("*.yaml"))
    ]
    with tempfile.TemporaryDirectory() as tmp:
        for size in (10, 50):
            path = Path(tmp) / f"fleet_{size}.yaml"
            path.write_text(fleet_mission(size, loop_hz=10), encoding="utf-8")
            seconds = 20.0 if quick and size == 50 else FLEET_SECONDS
            cases.append((f"generated fleet, {size} agents, 10 Hz", path, seconds))
        print(
            f"{'mission':<38} {'agents':>6} {'sim s':>7} {'wall s':>7} {'speed-up':>9} "
            f"{'ticks/s':>9} {'peak MiB':>9}"
        )
        for label, path, until in cases:
            f = measure(path, until)
            speed = f["sim_s"] / f["wall_s"] if f["wall_s"] else float("inf")
            ticks = f["ticks"] / f["wall_s"] if f["wall_s"] else 0.0
            print(
                f"{label:<38} {f['agents']:>6.0f} {f['sim_s']:>7.0f} {f['wall_s']:>7.2f} "
                f"{speed:>8.1f}x {ticks:>9.0f} {f['peak_mib']:>9.0f}"
            )


if __name__ == "__main__":
    if len(sys.argv) >= 3 and sys.argv[1] == "--one":
        sys.path.insert(0, str(ROOT))
        until = float(sys.argv[3]) if len(sys.argv) > 3 else None
        print(json.dumps(one(Path(sys.argv[2]), until)))
    else:
        main()
