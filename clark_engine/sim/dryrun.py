"""``clark dry-run``: validate, simulate, evaluate the checks, write the report.

This is the command's logic, apart from argument parsing: it turns a mission
file into a verdict. Exit codes: 0 when every check holds, 1 when one fails or
the mission is invalid, 2 for usage errors.
"""

from __future__ import annotations

import re
import shutil
import sys
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any, TextIO

from clark_engine.errors import UsageError
from clark_engine.mission.model import Mission
from clark_engine.sim.checks import CheckResult, evaluate
from clark_engine.sim.engine import DryRun, DryRunResult
from clark_engine.sim.parallel import choose_workers, run_split
from clark_engine.sim.realtime import (
    DEFAULT_HOST,
    MavlinkBridge,
    stop_on_interrupt,
    vehicle_names,
)
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
    realtime_base_port: int | None = None,
    realtime_host: str = DEFAULT_HOST,
    workers: int | None = None,
    out: TextIO | None = None,
    err: TextIO | None = None,
) -> Outcome:
    """Validate the mission, simulate it, evaluate its checks and write the report.

    Args:
        mission_path: The mission file.
        seed: Seeds every random draw; the mission's ``sim.seed`` when None.
        until_s: Simulated seconds to run; the mission's ``sim.duration_s`` when None.
        report: Folder for logs, CSV, plots and ``summary.md``; none written when None.
        speed: Simulated seconds per wall-clock second; as fast as possible when None.
        faults: Command-line faults (:data:`FAULT_HELP`).
        realtime_base_port: Real time with a ground station: run at wall-clock speed
            (``speed`` is ignored) with vehicle k's simulated autopilot on UDP port
            BASE + k (:mod:`clark_engine.sim.realtime`); Ctrl-C ends the run early
            and the report is still written. Off when None.
        realtime_host: The address those ports are bound to (loopback by default).
        workers: Split the agents across this many processes (:mod:`clark_engine.sim.parallel`:
            the same results, sooner); automatic when None. Paced and real-time runs
            stay in one process.
        out: Where the checks table goes; ``sys.stdout`` (as it is at the call) when None.
        err: Where progress and diagnostics go; ``sys.stderr`` when None.

    Raises:
        UsageError: Unreadable mission, bad fault, a report folder that cannot be made,
            or (in real time) no vehicle or a port that cannot be bound.
    """
    out = sys.stdout if out is None else out
    err = sys.stderr if err is None else err
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
    # Real time: bind the ports first, so a port in use is reported before anything is written.
    bridge = (
        MavlinkBridge(vehicle_names(mission), realtime_base_port, host=realtime_host)
        if realtime_base_port is not None
        else None
    )
    try:
        result = _simulate(
            mission, mission_path, seed, until, report, speed, extra, bridge, workers, err
        )
    finally:
        if bridge is not None:
            bridge.close()
    stopped_at_s = bridge.stopped_at_s if bridge is not None else None
    if stopped_at_s is not None:
        print(f"stopped at {stopped_at_s:.1f} s of {until:g} s (Ctrl-C)", file=err)
    until = min(until, result.recording.end_s)  # earlier when Ctrl-C ended a real-time run
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


def _simulate(
    mission: Mission,
    mission_path: Path,
    seed: int,
    until_s: float,
    report: Path | None,
    speed: float | None,
    faults: Sequence[Mapping[str, Any]],
    bridge: MavlinkBridge | None,
    workers: int | None,
    err: TextIO,
) -> DryRunResult:
    """Make the report's log folder and run the simulation (in real time with a bridge).

    Raises:
        UsageError: The report folder cannot be made.
    """
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
    progress = _progress(err) if interactive or until_s > 60 else None
    paced = bridge is not None or speed is not None
    processes = 1 if paced else choose_workers(workers, mission)
    if workers is not None and workers > 1 and processes == 1:
        why = (
            "a paced or real-time run follows the wall clock"
            if paced
            else "processes cannot be forked here, or the radio's lookahead (latency plus "
            "framing air time) is under 1 ms"
        )
        print(f"  note: --workers {workers} ignored: {why}; the run stays in one process", file=err)
    split = f", {processes} processes" if processes > 1 else ""
    print(
        f"dry run of {mission.name}: {len(mission.agents)} agents, {until_s:g} s, "
        f"seed {seed}{split}",
        file=err,
    )
    if processes > 1:
        result = run_split(
            mission,
            mission_path,
            workers=processes,
            seed=seed,
            until_s=until_s,
            log_dir=log_dir,
            extra_faults=faults,
            progress=progress,
        )
        if progress is not None:
            err.write("\n")
        return result
    run = DryRun(
        mission,
        mission_path,
        seed=seed,
        until_s=until_s,
        log_dir=log_dir,
        extra_faults=faults,
        progress=progress,
        speed=1.0 if bridge is not None else speed,
    )
    if bridge is None:
        result = run.run()
    else:
        # Wall-clock speed, each vehicle on its port; the ports were opened before the
        # clock starts, so a station may connect first. Ctrl-C ends the run early.
        bridge.attach(run)
        for endpoint in bridge.endpoints:
            print(
                f"  {endpoint.agent}: MAVLink on udp {endpoint.address} (system id "
                f"{endpoint.system_id}); e.g. mavproxy.py --master=udpout:{endpoint.address}",
                file=err,
            )
        shared = len({e.system_id for e in bridge.endpoints}) < len(bridge.endpoints)
        if shared:
            print(
                "  note: vehicles share a system id, so a station connected to several of them "
                "takes them for one; give each its own (hardware: {autopilot: {mavlink: "
                "{system_id: N}}}) to watch them together",
                file=err,
            )
        with stop_on_interrupt(bridge.stop):
            print("real time: Ctrl-C ends the run early (the report is still written)", file=err)
            result = run.run()
    if progress is not None:
        err.write("\n")
    return result


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
