"""``clark dry-run``: validate, simulate, evaluate the checks, write the report.

This is the command's logic, apart from argument parsing: it turns a mission
file into a verdict. Exit codes: 0 when every check holds, 1 when one fails or
the mission is invalid, 2 for usage errors.
"""

from __future__ import annotations

import re
import shutil
import sys
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any, TextIO

from clark_engine.errors import UsageError
from clark_engine.sim.checks import CheckResult, evaluate
from clark_engine.sim.engine import DryRun, DryRunResult
from clark_engine.sim.report import (
    checks_table,
    plot_inputs,
    plot_timeline,
    plot_tracks,
    write_summary,
)
from clark_engine.validation import validate_file

_FAULT = re.compile(
    r"^(?P<kind>kill|link_drop|station_silent|autopilot_disconnect|corrupt)"
    r"(?::(?P<arg>[^@]+))?@(?P<start>[0-9.]+)(?:-(?P<end>[0-9.]+))?$"
)
FAULT_HELP = (
    "a fault: kill:AGENT@T, link_drop:A,B@T1-T2, station_silent@T1-T2, "
    "autopilot_disconnect:AGENT@T1-T2, corrupt:SHARE@T1-T2 (seconds)"
)


def parse_fault(text: str) -> dict[str, Any]:
    """A command-line fault (``kill:slash_a@30``) in the mission's fault form.

    Raises:
        UsageError: Not one of the forms in :data:`FAULT_HELP`.
    """
    match = _FAULT.match(text.strip())
    if match is None:
        raise UsageError(f"--fault {text!r} is not {FAULT_HELP}")
    kind, arg = match["kind"], match["arg"]
    start = float(match["start"])
    end = float(match["end"]) if match["end"] else None
    try:
        if kind == "kill":
            if not arg or end is not None:
                raise ValueError
            return {"kill": {"agent": arg, "at_s": start}}
        if end is None or end <= start:
            raise ValueError
        window = {"from_s": start, "to_s": end}
        if kind == "link_drop":
            a, b = arg.split(",")
            return {"link_drop": {"between": [a, b], **window}}
        if kind == "station_silent":
            return {"station_silent": window}
        if kind == "autopilot_disconnect":
            return {"autopilot_disconnect": {"agent": arg, **window}}
        return {"corrupt": {"share": float(arg), **window}}
    except (ValueError, TypeError, AttributeError):
        raise UsageError(f"--fault {text!r} is not {FAULT_HELP}") from None


@dataclass(slots=True)
class Outcome:
    """A dry run's verdict."""

    exit_code: int
    results: list[CheckResult]
    result: DryRunResult | None


def _progress(stream: TextIO) -> Any:
    def show(t_s: float, end_s: float) -> None:
        share = t_s / end_s if end_s else 1.0
        bar = "#" * int(share * 30)
        stream.write(f"\r  simulating [{bar:<30}] {t_s:7.1f} / {end_s:g} s")
        stream.flush()

    return show


def run_dry_run(
    mission_path: Path,
    *,
    seed: int | None,
    until_s: float | None,
    report: Path | None,
    speed: float | None,
    faults: Sequence[str] = (),
    out: TextIO = sys.stdout,
    err: TextIO = sys.stderr,
) -> Outcome:
    """Validate the mission, simulate it, evaluate its checks and write the report.

    Raises:
        UsageError: Unreadable mission, bad fault, or a report folder that cannot be made.
    """
    extra = [parse_fault(text) for text in faults]
    validation = validate_file(mission_path, str(mission_path))
    for finding in validation.findings:
        print(finding.format_text(), file=err)
    mission = validation.mission
    if validation.kind != "mission" and validation.ok:
        raise UsageError(f"{mission_path} is a {validation.kind}, not a mission")
    if mission is None:
        print(f"{mission_path}: invalid; nothing simulated", file=err)
        return Outcome(1, [], None)
    for fault in extra:
        ((kind, body),) = fault.items()
        names = [*body.get("between", []), *([body["agent"]] if "agent" in body else [])]
        for name in names:
            if name not in mission.agents:
                raise UsageError(f"--fault {kind}: there is no agent {name!r} in the mission")
    seed = int(seed if seed is not None else mission.sim.get("seed", 0))
    until = float(until_s if until_s is not None else mission.sim.get("duration_s", 300.0))
    log_dir: Path | None = None
    if report is not None:
        try:
            report.mkdir(parents=True, exist_ok=True)
            log_dir = report / "logs"
            if log_dir.exists():
                shutil.rmtree(log_dir)
            log_dir.mkdir()
        except OSError as exc:
            raise UsageError(
                f"cannot write the report to {report}: {exc.strerror or exc}"
            ) from None
    interactive = err.isatty() if hasattr(err, "isatty") else False
    progress = _progress(err) if interactive or until > 60 else None
    print(
        f"dry run of {mission.name}: {len(mission.agents)} agents, {until:g} s, seed {seed}",
        file=err,
    )
    run = DryRun(
        mission,
        mission_path,
        seed=seed,
        until_s=until,
        log_dir=log_dir,
        extra_faults=extra,
        progress=progress,
        speed=speed,
    )
    result = run.run()
    if progress is not None:
        err.write("\n")
    results = evaluate(mission.checks, result.recording, result.configs, mission.origin)
    rate = until / result.wall_s if result.wall_s > 0 else float("inf")
    print(f"simulated {until:g} s in {result.wall_s:.1f} s ({rate:.0f}x real time)", file=err)
    if results:
        out.write(checks_table(results))
    else:
        print("the mission declares no checks", file=out)
    if report is not None:
        _write_report(report, mission.name, seed, until, result, results)
        print(f"report: {report / 'summary.md'}", file=err)
    failed = [r for r in results if not r.passed]
    if failed:
        print(f"{len(failed)} of {len(results)} checks failed", file=err)
    return Outcome(1 if failed else 0, results, result)


def _write_report(
    report: Path,
    mission: str,
    seed: int,
    until_s: float,
    result: DryRunResult,
    results: list[CheckResult],
) -> None:
    from clark_engine.analyze import analyze_folder, format_text

    plots = ["tracks.png"]
    plot_tracks(report / "tracks.png", result.recording, result.configs)
    if plot_inputs(report / "inputs.png", result.recording):
        plots.append("inputs.png")
    plot_timeline(report / "timeline.png", result.recording)
    plots.append("timeline.png")
    analysis = analyze_folder(report / "logs")
    write_summary(
        report / "summary.md",
        mission=mission,
        seed=seed,
        end_s=until_s,
        wall_s=result.wall_s,
        results=results,
        recording=result.recording,
        latency=format_text(analysis),
        plots=plots,
    )
