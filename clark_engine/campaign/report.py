"""A campaign's report: the pass-rate table, the figures' spread, the failing runs.

Everything here is built from the runs' results sorted by run number, so the same
campaign seed gives the same tables and the same ``summary.md`` whatever the number of
workers or the backend; only the lines that quote wall time (and the infrastructure
failures, which depend on the machines) differ.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Final

from clark_engine.campaign.runs import FIGURE_KINDS, Figure, RunResult
from clark_engine.campaign.stats import spread, wilson_interval
from clark_engine.dryrun.report import equivalent_command
from clark_engine.dryrun.report import vary_value_text as value_text

RUN_VERDICT: Final = "every check (the run's verdict)"
"""The first row of the checks table: runs that held every check and their safety."""

FIGURE_UNITS: Final = {"closest approach": "m", "highest altitude": "m", "first entry": "s"}

MAX_BINS: Final = 5
"""Bins of a drawn number in the pass-rate-against-factor tables and plots."""

SHOWN_FAILURES: Final = 20
"""Failing runs listed on standard output (summary.md lists every one)."""


@dataclass(frozen=True, slots=True)
class Rate:
    """A pass rate: passes among the runs where it was judged, with its Wilson interval.

    Attributes:
        name: The check (or :data:`RUN_VERDICT`).
        passed: Runs in which it held.
        judged: Runs in which it was judged.
        minimum: The declared minimum pass rate, if any.
    """

    name: str
    passed: int
    judged: int
    minimum: float | None = None

    @property
    def rate(self) -> float | None:
        """The rate: passed / judged; None when never judged."""
        return self.passed / self.judged if self.judged else None

    @property
    def interval(self) -> tuple[float, float]:
        """The 95 % Wilson score interval."""
        return wilson_interval(self.passed, self.judged)

    @property
    def met(self) -> bool | None:
        """Whether the observed rate reaches the minimum; None without one or a judgement."""
        if self.minimum is None:
            return None
        rate = self.rate
        return None if rate is None else rate >= self.minimum - 1e-12


def percent(value: float) -> str:
    """``95.0 %``."""
    return f"{100 * value:.1f} %"


def rates(
    results: Sequence[RunResult],
    run_minimum: float | None,
    check_minimums: Mapping[str, float],
) -> list[Rate]:
    """The run verdict's rate, then each check's, in the order the runs list them."""
    judged = [r for r in results if not r.infrastructure_failure]
    out = [Rate(RUN_VERDICT, sum(r.passed for r in judged), len(judged), run_minimum)]
    order: list[str] = []
    passed: dict[str, int] = {}
    counted: dict[str, int] = {}
    for result in judged:
        for verdict in result.checks:
            if verdict.name not in counted:
                order.append(verdict.name)
                counted[verdict.name] = passed[verdict.name] = 0
            if verdict.evaluated:
                counted[verdict.name] += 1
                passed[verdict.name] += verdict.passed
    out += [Rate(n, passed[n], counted[n], check_minimums.get(n)) for n in order]
    return out


def rates_table(table: Sequence[Rate]) -> str:
    """The pass rates as Markdown."""
    lines = [
        "| check | runs judged | passed | pass rate | 95 % interval | minimum | result |",
        "|---|---:|---:|---:|---|---:|---|",
    ]
    for row in table:
        rate = row.rate
        low, high = row.interval
        shown = percent(rate) if rate is not None else "-"
        span = f"{percent(low)} - {percent(high)}" if row.judged else "-"
        minimum = percent(row.minimum) if row.minimum is not None else "-"
        met = row.met
        verdict = "-" if met is None else ("met" if met else "**NOT MET**")
        lines.append(
            f"| {row.name} | {row.judged} | {row.passed} | {shown} | {span} | {minimum} "
            f"| {verdict} |"
        )
    return "\n".join(lines) + "\n"


@dataclass(frozen=True, slots=True)
class FigureSpread:
    """One figure over the runs that have it: min, p5, median, p95, max."""

    key: Figure
    runs: int
    values: tuple[float, ...]


def figure_spreads(results: Sequence[RunResult]) -> list[FigureSpread]:
    """Each figure's spread, kind by kind, in the order the runs first give them."""
    order: list[Figure] = []
    values: dict[Figure, list[float]] = {}
    for result in results:
        if result.infrastructure_failure:
            continue
        for key, value in result.figures.items():
            if key not in values:
                order.append(key)
                values[key] = []
            values[key].append(value)
    ranked = sorted(order, key=lambda k: FIGURE_KINDS.index(k[0]))  # stable: first seen
    return [FigureSpread(k, len(values[k]), spread(values[k])) for k in ranked]


def figures_table(spreads: Sequence[FigureSpread], judged: int) -> str:
    """The figures' spread as Markdown (a figure absent from some runs says in how many)."""
    if not spreads:
        return "No figures: the mission has no vehicle pairs, aircraft or states.\n"
    lines = [
        "| figure | runs | min | p5 | median | p95 | max |",
        "|---|---:|---:|---:|---:|---:|---:|",
    ]
    for item in spreads:
        kind, subject = item.key
        unit = FIGURE_UNITS[kind]
        cells = " | ".join(f"{v:.1f}" for v in item.values)
        runs = f"{item.runs}" if item.runs == judged else f"{item.runs} of {judged}"
        lines.append(f"| {kind}, {subject} ({unit}) | {runs} | {cells} |")
    return "\n".join(lines) + "\n"


def reproduce_command(
    mission: str,
    result: RunResult,
    *,
    until_s: float | None,
    faults: Sequence[str],
    vary: Sequence[str],
    sitl: Sequence[str] = (),
) -> str:
    """The one ``clark dry-run`` command that flies this run alone.

    Its seed, the campaign's ``--until`` and ``--fault``, and every value drawn for it
    as ``--vary PATH=VALUE`` (the seed alone would draw them again; written out, the
    command says what the run met, and a value can be changed to see what it does).
    """
    drawn = dict(result.drawn)
    vary_texts = [text for text in vary if text.partition("=")[0].strip() not in drawn]
    vary_texts += [f"{path}={value_text(value)}" for path, value in drawn.items()]
    return equivalent_command(mission, result.seed, until_s, faults, None, vary_texts, sitl)


@dataclass(frozen=True, slots=True)
class FactorBin:
    """Runs whose drawn value fell in one bin."""

    label: str
    centre: float
    passed: int
    runs: int


@dataclass(frozen=True, slots=True)
class Factor:
    """The pass rate against one drawn value."""

    path: str
    bins: tuple[FactorBin, ...]
    boolean: bool = False


def factors(results: Sequence[RunResult]) -> list[Factor]:
    """Pass rate against each drawn value, binned.

    A bin per value for true/false or a few numbers, else :data:`MAX_BINS` equal bins
    between the smallest and largest draw.
    """
    judged = [r for r in results if not r.infrastructure_failure]
    paths: list[str] = []
    for result in judged:
        paths += [p for p in result.drawn if p not in paths]
    out = []
    for path in paths:
        pairs = [(r.drawn[path], r.passed) for r in judged if path in r.drawn]
        if all(isinstance(v, bool) for v, _ in pairs):
            bins = tuple(
                FactorBin(
                    value_text(flag),
                    float(flag),
                    sum(p for v, p in pairs if v is flag),
                    sum(1 for v, _ in pairs if v is flag),
                )
                for flag in (False, True)
            )
            out.append(Factor(path, bins, boolean=True))
            continue
        numbers = [(float(v), p) for v, p in pairs]
        distinct = sorted({v for v, _ in numbers})
        if len(distinct) <= MAX_BINS:
            bins = tuple(
                FactorBin(
                    f"{d:.4g}",
                    d,
                    sum(p for v, p in numbers if v == d),
                    sum(1 for v, _ in numbers if v == d),
                )
                for d in distinct
            )
        else:
            low, high = distinct[0], distinct[-1]
            width = (high - low) / MAX_BINS
            counts = [[0, 0] for _ in range(MAX_BINS)]
            for v, p in numbers:
                k = min(MAX_BINS - 1, int((v - low) / width))
                counts[k][0] += p
                counts[k][1] += 1
            bins = tuple(
                FactorBin(
                    f"{low + k * width:.4g} - {low + (k + 1) * width:.4g}",
                    low + (k + 0.5) * width,
                    passed,
                    runs,
                )
                for k, (passed, runs) in enumerate(counts)
            )
        out.append(Factor(path, bins))
    return out


def factor_table(factor: Factor) -> str:
    """One factor's bins as Markdown."""
    lines = [
        f"| {factor.path} | runs | passed | pass rate | 95 % interval |",
        "|---|---:|---:|---:|---|",
    ]
    for b in factor.bins:
        if b.runs:
            low, high = wilson_interval(b.passed, b.runs)
            rate, span = percent(b.passed / b.runs), f"{percent(low)} - {percent(high)}"
        else:
            rate, span = "-", "-"
        lines.append(f"| {b.label} | {b.runs} | {b.passed} | {rate} | {span} |")
    return "\n".join(lines) + "\n"


def plot_name(path: str) -> str:
    """The file of a factor's plot: ``factors/sim.wind.speed_mps.png``."""
    safe = "".join(c if c.isalnum() or c in "._-" else "_" for c in path)
    return f"factors/{safe}.png"


def plot_factor(target: Path, factor: Factor) -> None:
    """A bar per bin: its pass rate, with its 95 % Wilson interval and its run count."""
    from clark_engine.dryrun.report_plots import _pyplot, _save

    plt = _pyplot()
    fig, ax = plt.subplots(figsize=(6.4, 3.6))
    xs = list(range(len(factor.bins)))
    heights, below, above = [], [], []
    for b in factor.bins:
        if b.runs:
            rate = b.passed / b.runs
            low, high = wilson_interval(b.passed, b.runs)
        else:
            rate = low = high = 0.0
        heights.append(100 * rate)
        below.append(100 * (rate - low))
        above.append(100 * (high - rate))
    ax.bar(xs, heights, color="#4c72b0", yerr=[below, above], capsize=4)
    ax.set_xticks(xs, [f"{b.label}\n{b.runs} runs" for b in factor.bins], fontsize=8)
    ax.set_ylim(0, 105)
    ax.set_ylabel("runs passing (%)")
    ax.set_xlabel(factor.path)
    ax.set_title(f"Pass rate against {factor.path} (95 % Wilson interval)", fontsize=10)
    fig.tight_layout()
    target.parent.mkdir(parents=True, exist_ok=True)
    _save(fig, target)


@dataclass(slots=True)
class CampaignSummary:
    """What ``summary.md`` and standard output say about a finished campaign.

    Attributes:
        mission: The mission's name.
        mission_file: The mission file as typed.
        command: The command line as typed.
        campaign_seed: The campaign's seed.
        runs: Runs asked for.
        results: Every run's last result, in run order.
        infrastructure: Every infrastructure failure met (retried or not).
        rate_rows: The pass-rate table's rows.
        spreads: The figures' spread.
        factor_rows: Pass rate against each drawn value.
        reproduce: Run number -> the command that flies it alone (failing runs).
        autopilot: ``the simulated autopilot`` or ``ArduPilot SITL at 10x``.
        until_s: Simulated seconds of each run.
        wall_s: Wall-clock seconds of the whole campaign.
        where: The backend (``local pool of 2 processes``).
        fixed: What every run was given (``--fault``, ``--vary``), as typed.
        report_dirs: Run number -> its dry-run report, relative to the report folder.
    """

    mission: str
    mission_file: str
    command: str
    campaign_seed: int
    runs: int
    results: Sequence[RunResult]
    infrastructure: Sequence[RunResult]
    rate_rows: Sequence[Rate]
    spreads: Sequence[FigureSpread]
    factor_rows: Sequence[Factor]
    reproduce: Mapping[int, str]
    autopilot: str
    until_s: float
    wall_s: float
    where: str
    fixed: Sequence[str] = ()
    report_dirs: Mapping[int, str] = field(default_factory=dict)

    @property
    def judged(self) -> int:
        """Runs with a verdict."""
        return sum(1 for r in self.results if not r.infrastructure_failure)

    @property
    def unflown(self) -> list[RunResult]:
        """Runs left without a verdict after every retry."""
        return [r for r in self.results if r.infrastructure_failure]

    def headline(self) -> str:
        """``190 of 200 runs pass (95.0 %, 95 % interval 91.0 - 97.3 %)``."""
        row = self.rate_rows[0]
        if not row.judged:
            return "no run gave a verdict"
        low, high = row.interval
        text = (
            f"{row.passed} of {row.judged} runs pass ({percent(row.passed / row.judged)}, "
            f"95 % interval {percent(low)} - {percent(high)})"
        )
        unflown = len(self.unflown)
        if unflown:
            text += f"; {unflown} more gave no verdict (infrastructure)"
        return text

    def minimums_text(self) -> str:
        """Which declared minimums were met and which were not."""
        declared = [r for r in self.rate_rows if r.minimum is not None]
        if not declared:
            return "No minimum pass rate declared."
        missed = [r for r in declared if r.met is False]
        if not missed:
            return f"Every declared minimum pass rate is met ({len(declared)})."
        names = ", ".join(
            f"{r.name} ({percent(r.rate or 0.0)} < {percent(r.minimum or 0.0)})" for r in missed
        )
        return f"**Minimum pass rate not met**: {names}."

    def varied_text(self) -> str:
        """What varied from run to run."""
        paths = [f.path for f in self.factor_rows]
        if not paths:
            return (
                "The mission declares no variations: only the seed varies from run to run "
                "(GPS noise, radio loss, tick phases)."
            )
        return "Drawn for each run from its seed: " + ", ".join(f"`{p}`" for p in paths) + "."

    def stdout_text(self) -> str:
        """What the command prints on standard output."""
        lines = [
            f"campaign of {self.mission}: {self.headline()}",
            "",
            rates_table(self.rate_rows),
            figures_table(self.spreads, self.judged),
        ]
        failing = [r for r in self.results if not r.infrastructure_failure and not r.passed]
        if failing:
            lines.append(f"failing runs ({len(failing)}), each reproduced alone by:")
            for result in failing[:SHOWN_FAILURES]:
                lines.append(f"  run {result.index}: {self.reproduce[result.index]}")
            if len(failing) > SHOWN_FAILURES:
                lines.append(f"  ... and {len(failing) - SHOWN_FAILURES} more (see summary.md)")
            lines.append("")
        lines.append(self.minimums_text())
        return "\n".join(lines) + "\n"

    def markdown(self, plots: Mapping[str, str]) -> str:
        """``summary.md``."""
        rate = self.runs / self.wall_s * 60 if self.wall_s > 0 else math.inf
        text = [
            f"# Campaign of {self.mission}",
            "",
            f"Command line: `{self.command}`",
            "",
            f"Campaign seed {self.campaign_seed}; {self.runs} runs of {self.until_s:g} simulated "
            f"seconds on {self.autopilot}; run i's seed is the first four bytes of "
            f"SHA-256(`clark-campaign:{self.campaign_seed}:i`).",
            "",
            self.varied_text(),
            "",
            *(
                ["Given to every run: " + ", ".join(f"`{t}`" for t in self.fixed) + ".", ""]
                if self.fixed
                else []
            ),
            f"Wall time: {self.wall_s:.1f} s on {self.where} ({rate:.1f} runs per minute).",
            "",
            f"**{self.headline()}.** {self.minimums_text()}",
            "",
            "## Checks",
            "",
            "Each check's pass rate over the runs that judged it (a run cut short of a check's "
            "by_s does not judge it), with its 95 % Wilson score interval: where the true "
            "rate lies, given this many runs (docs/campaigns.md). The safety judgement's "
            "rows (`safety: ...`) come from every run, whether or not the mission checks.",
            "",
            rates_table(self.rate_rows),
            "## Figures",
            "",
            "The figures the checks look at, over the runs: each pair's closest approach "
            "while either was armed (3-D), each aircraft's highest altitude above the "
            "origin, and when each agent first entered each state (simulated seconds).",
            "",
            figures_table(self.spreads, self.judged),
            "## Pass rate against each varied factor",
            "",
        ]
        if not self.factor_rows:
            text += ["Nothing was drawn: the mission declares no variations.", ""]
        for factor in self.factor_rows:
            text += [factor_table(factor)]
            if factor.path in plots:
                text += [f"![{factor.path}]({plots[factor.path]})", ""]
        failing = [r for r in self.results if not r.infrastructure_failure and not r.passed]
        text += ["## Failing runs", ""]
        if not failing:
            text += ["None.", ""]
        for result in failing:
            names = [
                f"{v.name} ({v.observed})" if v.observed else v.name
                for v in result.checks
                if v.evaluated and not v.passed
            ]
            text += [
                f"### Run {result.index} (seed {result.seed})",
                "",
                "Failed: " + ("; ".join(names) if names else "(no check named)") + ".",
                "",
                f"Reproduce: `{self.reproduce[result.index]}`",
                "",
            ]
            if result.index in self.report_dirs:
                where = self.report_dirs[result.index]
                text += [f"Its report: [{where}/summary.md]({where}/summary.md)", ""]
        text += ["## Infrastructure failures", ""]
        if not self.infrastructure:
            text += ["None.", ""]
        else:
            text += [
                "Runs that could not be flown (SITL that did not start, a lost worker, a "
                "timeout): retried with the same seed, and counted apart from the mission's "
                "failures.",
                "",
                "| run | try | worker | what |",
                "|---:|---:|---|---|",
            ]
            for r in self.infrastructure:
                what = (r.error or "").replace("|", "\\|").replace("\n", " ")
                text.append(f"| {r.index} | {r.attempt + 1} | {r.worker or '-'} | {what} |")
            text.append("")
        return "\n".join(text)
