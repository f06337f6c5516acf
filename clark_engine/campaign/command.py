"""``clark campaign``: validate once, fly N runs, write the table and the report.

Exit codes: 0 every declared minimum pass rate is met (or none is declared); 1 a
declared minimum is not met, or the mission is invalid (nothing flown); 2 a usage or
I/O error, or no run could give a verdict (every one failed for want of
infrastructure). Ctrl-C stops the workers and writes nothing.
"""

from __future__ import annotations

import csv
import importlib
import io
import sys
import time
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Final, TextIO

from clark_engine.campaign.pool import backend_for, fly_all
from clark_engine.campaign.report import (
    CampaignSummary,
    factors,
    figure_spreads,
    plot_factor,
    plot_name,
    rates,
    reproduce_command,
)
from clark_engine.campaign.runs import (
    FIGURE_KINDS,
    RunResult,
    RunSpec,
    SitlSpec,
    mission_sha256,
    run_seed,
    unpack,
)
from clark_engine.dryrun.report import REPORT_MARKER, ReportFolder, vary_value_text
from clark_engine.errors import ClarkError, UsageError
from clark_engine.mission.model import Mission

DEFAULT_RUNS: Final = 100
"""Runs when neither ``--runs`` nor the mission's ``campaign.runs`` says."""

DEFAULT_RETRIES: Final = 2
"""Retries of a run whose infrastructure failed."""

DEFAULT_SITL_PER_WORKER: Final = 2
"""SITL stacks a local campaign flies at once when ``--sitl-per-worker`` is not given."""

DEFAULT_SITL_RUN_TIMEOUT_S: Final = 1800.0
"""A SITL run's wall-clock limit when ``--run-timeout-s`` is not given (a 3-minute
mission takes about 20 s at 10x; half an hour means it hangs)."""

COMPARISON_CHECK: Final = "the same mission on ArduPilot SITL"
"""The comparison row a SITL run adds to its checks (:mod:`clark_engine.dryrun.timeline`)."""


@dataclass(frozen=True, slots=True)
class CampaignOptions:
    """The command's options, checked (see ``clark campaign --help``).

    Attributes:
        runs: Runs (``--runs``); the mission's ``campaign.runs`` (else 100) when None.
        seed: The campaign seed; the mission's ``campaign.seed``, else ``sim.seed``.
        until_s: Simulated seconds of each run; the mission's when None.
        faults: ``--fault`` texts, given to every run.
        vary: ``--vary PATH=VALUE`` texts, fixed for every run.
        workers: Local processes (1: in this process); every usable core when None.
        scheduler: A Dask scheduler's address; local when None.
        sitl: ``--sitl PATH`` resolved (with ``--autopilot sitl``); None: simulated.
        sitl_speedup: SITL's speed-up.
        sitl_per_worker: SITL stacks at once per worker (locally: the pool's size).
        run_timeout_s: A run's wall-clock limit; runs given one are flown isolated.
        retries: Retries of an infrastructure failure.
        report: ``--report DIR``.
        failure_reports: Each failing run's dry-run report under ``DIR/runs/<i>/``.
        min_pass_rate: ``--min-pass-rate``; the mission's ``campaign.min_pass_rate``.
        quiet: Hide warnings and progress.
    """

    runs: int | None = None
    seed: int | None = None
    until_s: float | None = None
    faults: tuple[str, ...] = ()
    vary: tuple[str, ...] = ()
    workers: int | None = None
    scheduler: str | None = None
    sitl: Any = None
    sitl_speedup: float = 10.0
    sitl_per_worker: int = DEFAULT_SITL_PER_WORKER
    run_timeout_s: float | None = None
    retries: int = DEFAULT_RETRIES
    report: Path | None = None
    failure_reports: bool = False
    min_pass_rate: float | None = None
    quiet: bool = False


class Progress:
    """Runs done on standard error, as they finish.

    On a terminal a line redrawn in place; elsewhere (a CI log) a plain line about every
    :attr:`EVERY_S` seconds and at the end.
    """

    EVERY_S: Final = 10.0

    def __init__(self, stream: TextIO) -> None:
        self.stream = stream
        self.terminal = stream.isatty() if hasattr(stream, "isatty") else False
        self.last = time.monotonic()
        self.shown = False

    def __call__(self, done: int, total: int, failed: int, infra: int) -> None:
        """Runs done of ``total``, failed so far, infrastructure failures so far."""
        text = f"runs {done} / {total} done, {failed} failed"
        if infra:
            text += f", {infra} infrastructure failures (retried)"
        now = time.monotonic()
        if self.terminal:
            self.stream.write(f"\r  {text}   ")
            self.shown = True
        elif done == total or now - self.last >= self.EVERY_S:
            self.stream.write(f"  {text}\n")
            self.last = now
        self.stream.flush()

    def finish(self) -> None:
        """End the redrawn line (also on Ctrl-C), so what follows starts on its own."""
        if self.shown:
            self.stream.write("\n")
            self.stream.flush()
            self.shown = False


def check_labels(mission: Mission) -> list[str]:
    """Every row name a run's checks table may have.

    The mission's checks (named as :mod:`clark_engine.expectations.evaluate` names them), the SITL
    comparison, and the safety judgement's rows.
    """
    names = []
    for index, check in enumerate(mission.checks):
        kind = next((k for k in check if k not in ("name", "by_s")), "check")
        names.append(str(check.get("name") or f"check {index + 1}: {kind}"))
    names.append(COMPARISON_CHECK)
    vehicles = [name for name, agent in mission.agents.items() if agent.is_vehicle]
    names += [f"safety: {v}" for v in vehicles]
    names += [f"safety: {a} - {b}" for i, a in enumerate(vehicles) for b in vehicles[i + 1 :]]
    return names


def _check_minimums(mission: Mission) -> dict[str, float]:
    """``campaign.min_pass_rates``, each naming a row of the table.

    Raises:
        ClarkError: A name that is no check of the mission (file:line, exit 1).
    """
    declared: Mapping[str, Any] = mission.campaign.get("min_pass_rates") or {}
    known = check_labels(mission)
    for name in declared:
        if name not in known:
            where = mission.campaign_locations.get(f"min_pass_rates.{name}")
            prefix = f"{where.prefix()}: " if where is not None else f"{mission.file}: "
            raise ClarkError(
                f"{prefix}campaign.min_pass_rates: no check is named {name!r}; the mission's "
                f"rows are: {', '.join(repr(k) for k in known)}"
            )
    return {str(k): float(v) for k, v in declared.items()}


def _check_vary(mission: Mission, vary: Sequence[str]) -> None:
    """Refuse a ``--vary`` no run could take, before any run (exit 2)."""
    if not vary:
        return
    try:
        # Imported by name: the world's variations may be newer than this engine.
        variation: Any = importlib.import_module("clark_engine.mission.variation")
    except ImportError:
        raise UsageError(
            "--vary: this engine's dry run draws no varied values (it predates them)"
        ) from None
    try:
        variation.parse_vary(vary, variation.mission_varied_fields(mission))
    except variation.VaryError as exc:
        raise UsageError(str(exc)) from None


def _check_faults(mission: Mission, faults: Sequence[str]) -> None:
    """Refuse a malformed ``--fault`` or one naming an unknown agent (exit 2)."""
    from clark_engine.dryrun.command import parse_fault

    for text in faults:
        ((kind, body),) = parse_fault(text).items()
        names = [*body.get("between", []), *([body["agent"]] if "agent" in body else [])]
        for name in names:
            if name not in mission.agents:
                raise UsageError(f"--fault {kind}: there is no agent {name!r} in the mission")


def run_campaign(
    mission_path: Path,
    options: CampaignOptions,
    *,
    out: TextIO | None = None,
    err: TextIO | None = None,
    command_line: Sequence[str] | None = None,
) -> int:
    """Validate the mission, fly its runs, print the table and write the report.

    Returns:
        The exit code (see the module).

    Raises:
        UsageError: Unreadable mission, a bad option, a report folder it may not
            replace, no Dask scheduler at the address.
        ClarkError: ``campaign.min_pass_rates`` names no check (exit 1).
        KeyboardInterrupt: Ctrl-C; the workers are stopped and nothing is written.
    """
    from clark_engine.validation import mission_to_fly

    out = sys.stdout if out is None else out
    err = sys.stderr if err is None else err
    mission = mission_to_fly(mission_path, err, quiet=options.quiet, nothing="nothing flown")
    if mission is None:
        return 1
    _check_faults(mission, options.faults)
    _check_vary(mission, options.vary)
    check_minimums = _check_minimums(mission)
    settings = mission.campaign
    runs = options.runs if options.runs is not None else int(settings.get("runs", DEFAULT_RUNS))
    campaign_seed = int(
        options.seed
        if options.seed is not None
        else settings.get("seed", mission.sim.get("seed", 0))
    )
    run_minimum = (
        options.min_pass_rate
        if options.min_pass_rate is not None
        else settings.get("min_pass_rate")
    )
    until = options.until_s if options.until_s is not None else mission.sim_duration_s
    folder = ReportFolder(options.report) if options.report is not None else None
    if folder is not None:
        folder.check()  # before any run: a folder it may not replace is refused at once
    sitl_spec = None
    timeout = options.run_timeout_s
    if options.sitl is not None:
        instances = options.sitl.instances
        sitl_spec = SitlSpec(
            str(options.sitl.launcher), (instances[0], instances[-1]), options.sitl_speedup
        )
        timeout = timeout if timeout is not None else DEFAULT_SITL_RUN_TIMEOUT_S
    path = mission_path.resolve()
    digest = mission_sha256(path)
    specs = [
        RunSpec(
            index=i,
            seed=run_seed(campaign_seed, i),
            mission_path=str(path),
            mission_sha256=digest,
            until_s=options.until_s,
            faults=options.faults,
            vary=options.vary,
            sitl=sitl_spec,
            timeout_s=timeout,
            report=options.failure_reports and folder is not None,
        )
        for i in range(runs)
    ]
    # Import the engine here, before a pool forks: each worker starts with it loaded.
    import clark_engine.dryrun.command  # noqa: F401

    backend = backend_for(
        options.scheduler, options.workers, sitl_spec is not None, options.sitl_per_worker, runs
    )
    autopilot = (
        f"ArduPilot SITL at {options.sitl_speedup:g}x"
        if sitl_spec is not None
        else "the simulated autopilot"
    )
    print(
        f"campaign of {mission.name}: {runs} runs of {until:g} s on {autopilot}, campaign seed "
        f"{campaign_seed}, on {backend.description}",
        file=err,
    )
    progress = None if options.quiet else Progress(err)
    start = time.perf_counter()
    try:
        flown = fly_all(specs, backend, options.retries, progress)
    except KeyboardInterrupt:
        if progress is not None:
            progress.finish()
        where = f" ({folder.target} is as it was)" if folder is not None else ""
        print(f"interrupted: the workers were stopped; no report written{where}", file=err)
        raise
    if progress is not None:
        progress.finish()
    wall_s = time.perf_counter() - start
    sitl_words: list[str] = []
    if options.sitl is not None:
        sitl_words = ["--autopilot", "sitl", "--sitl", str(options.sitl.folder)]
        if options.sitl_speedup != 10.0:
            sitl_words += ["--sitl-speedup", f"{options.sitl_speedup:g}"]
    reproduce = {
        r.index: reproduce_command(
            str(mission_path),
            r,
            until_s=options.until_s,
            faults=options.faults,
            vary=options.vary,
            sitl=sitl_words,
        )
        for r in flown.results
        if not r.infrastructure_failure and not r.passed
    }
    fixed = [f"--fault {t}" for t in options.faults] + [f"--vary {t}" for t in options.vary]
    report_dirs = {r.index: f"runs/{r.index}" for r in flown.results if r.report_tar is not None}
    summary = CampaignSummary(
        mission=mission.name,
        mission_file=str(mission_path),
        command=_shell_join(command_line)
        if command_line is not None
        else _shell_join(["clark", "campaign", str(mission_path), "--runs", str(runs)]),
        campaign_seed=campaign_seed,
        runs=runs,
        results=flown.results,
        infrastructure=flown.infrastructure,
        rate_rows=rates(flown.results, run_minimum, check_minimums),
        spreads=figure_spreads(flown.results),
        factor_rows=factors(flown.results),
        reproduce=reproduce,
        autopilot=autopilot,
        until_s=until,
        wall_s=wall_s,
        where=backend.description,
        fixed=fixed,
        report_dirs=report_dirs,
    )
    out.write(summary.stdout_text())
    rate = runs / wall_s * 60 if wall_s > 0 else float("inf")
    print(f"flew {runs} runs in {wall_s:.1f} s ({rate:.1f} runs per minute)", file=err)
    if flown.infrastructure:
        print(
            f"{len(flown.infrastructure)} infrastructure failure(s) (retried up to "
            f"{options.retries} times; counted apart from the mission's):",
            file=err,
        )
        for r in flown.infrastructure[:10]:
            print(f"  run {r.index}, try {r.attempt + 1}: {r.error}", file=err)
    if folder is not None:
        try:
            _write_report(folder, summary, flown.results)
        finally:
            folder.discard()
        print(f"report: {folder.target / 'summary.md'}", file=err)
    if summary.judged == 0:
        print("no run gave a verdict: every one failed for want of infrastructure", file=err)
        return 2
    missed = [r for r in summary.rate_rows if r.met is False]
    for row in missed:
        print(
            f"minimum pass rate not met: {row.name}: {row.passed} of {row.judged} "
            f"({100 * (row.rate or 0.0):.1f} %) < {100 * (row.minimum or 0.0):.1f} %",
            file=err,
        )
    return 1 if missed else 0


def _shell_join(words: Sequence[str]) -> str:
    import shlex

    return shlex.join(words)


def _write_report(
    folder: ReportFolder, summary: CampaignSummary, results: Sequence[RunResult]
) -> None:
    """Write the report whole beside DIR, then put it in DIR's place."""
    logs = folder.open()
    logs.rmdir()  # a campaign has no agents' logs of its own
    target = folder.folder
    plots: dict[str, str] = {}
    for factor in summary.factor_rows:
        name = plot_name(factor.path)
        plot_factor(target / name, factor)
        plots[factor.path] = name
    for result in results:
        if result.report_tar is not None:
            place = target / "runs" / str(result.index)
            unpack(result.report_tar, place)
            (place / REPORT_MARKER).unlink(missing_ok=True)  # the campaign's lists its files
    (target / "summary.md").write_text(summary.markdown(plots), encoding="utf-8")
    (target / "runs.csv").write_text(runs_csv(results), encoding="utf-8")
    folder.commit()


def runs_csv(results: Sequence[RunResult]) -> str:
    """One row per run: its seed, verdict, drawn values, checks and figures."""
    drawn: list[str] = []
    checks: list[str] = []
    figures: list[tuple[str, str]] = []
    for r in results:
        drawn += [p for p in r.drawn if p not in drawn]
        checks += [c.name for c in r.checks if c.name not in checks]
        figures += [k for k in r.figures if k not in figures]
    figures.sort(key=lambda k: FIGURE_KINDS.index(k[0]))
    buffer = io.StringIO()
    writer = csv.writer(buffer, lineterminator="\n")
    writer.writerow(["run", "seed", "verdict", *drawn, *checks, *(f"{k}: {s}" for k, s in figures)])
    for r in results:
        verdict = "infrastructure" if r.infrastructure_failure else ("pass" if r.passed else "FAIL")
        by_name = {c.name: c for c in r.checks}
        row: list[str] = [str(r.index), str(r.seed), verdict]
        row += [vary_value_text(r.drawn[p]) if p in r.drawn else "" for p in drawn]
        row += [
            (("pass" if by_name[c].passed else "FAIL") if by_name[c].evaluated else "not evaluated")
            if c in by_name
            else ""
            for c in checks
        ]
        row += [f"{r.figures[k]:.3f}" if k in r.figures else "" for k in figures]
        writer.writerow(row)
    return buffer.getvalue()
