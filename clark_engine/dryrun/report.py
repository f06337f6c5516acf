"""The dry run's report: plots of paths and control inputs, a state timeline, a summary.

Written into ``--report DIR`` beside every agent's CSV and logs:

* ``tracks.png``: every vehicle's path in metres from the origin, with its
  waypoints, the positions of its pictures, and the closest approach of the pair of
  vehicles that came closest (both positions, the distance and the time);
* ``altitude.png`` (when the fleet has an aircraft): every vehicle's altitude above the
  origin over time, against each aircraft's ceiling and floor, breaches marked;
* ``inputs.png``: the pulse widths the autopilots received for doublets and sweeps,
  each channel named by its function in the vehicle's profile;
* ``timeline.png``: which state each agent was in, over time;
* ``summary.md``: the command line, seed and injected faults, the checks table, the
  safety judgement (:mod:`clark_engine.expectations.safety`), the state timeline as text, and
  the latency and loss tables of ``clark analyze``.

The plots are :mod:`clark_engine.dryrun.report_plots` (matplotlib's non-interactive Agg
backend; files are written with fixed metadata so the same run gives the same bytes); this
module writes the folder and the text.

The report is written whole into a fresh hidden folder beside ``DIR``
(``.DIR.incomplete-*``) and moved into place only when complete
(:class:`ReportFolder`), with a ``.clark-report.json`` that lists its files. A run
that is interrupted leaves ``DIR`` as it was. A later run replaces a report it
recognises (by that list, or as a report from before the list) and refuses a
``DIR`` holding any other file: it never deletes a file the engine did not write.
"""

from __future__ import annotations

import math
import os
import shlex
import shutil
import tempfile
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Final

from clark_engine.errors import UsageError
from clark_engine.expectations.evaluate import CheckResult, checks_table
from clark_engine.expectations.recording import Pace, Recording
from clark_engine.expectations.safety import SafetyJudgement, count_breaches
from clark_engine.mission.compiler import foreign_files, swap_in, write_marker

REPORT_MARKER: Final = ".clark-report.json"
"""Written last into a complete report: the list of its files, all the engine's."""

_REPORT_FILES: Final = frozenset(
    {"summary.md", "tracks.png", "altitude.png", "inputs.png", "timeline.png"}
)
_LOG_SUFFIXES: Final = (".mission.log", ".interface.log", ".fleet.csv", ".messages.csv")


def _older_report(folder: Path) -> Callable[[Path, str], bool]:
    """Recognises the files of a report from before :data:`REPORT_MARKER` existed.

    Its summary.md, plots and agents' logs, when summary.md is a dry run's.
    """
    try:
        with (folder / "summary.md").open(encoding="utf-8") as summary:
            is_report = summary.read(20).startswith("# Dry run of ")
    except (OSError, UnicodeDecodeError):
        is_report = False

    def recognise(path: Path, name: str) -> bool:
        if not is_report or path.is_symlink():
            return False
        folder_name, _, file_name = name.rpartition("/")
        if not folder_name:
            return name in _REPORT_FILES
        return folder_name == "logs" and file_name.endswith(_LOG_SUFFIXES)

    return recognise


class ReportFolder:
    """Where ``--report DIR`` is written: whole, beside DIR, then moved into place.

    :meth:`check` before the run refuses a DIR with files the engine did not write;
    :meth:`open` makes the fresh folder the run logs into; :meth:`commit` lists its
    files in :data:`REPORT_MARKER` and swaps it in for DIR; :meth:`discard` (always
    called, e.g. in ``finally``) removes it if it was never committed.
    """

    def __init__(self, target: Path) -> None:
        self.target = target
        """DIR as the user gave it (messages name it so)."""
        self.staging: Path | None = None
        """The folder being written, until it is committed or discarded."""

    @property
    def _place(self) -> Path:
        return self.target.resolve()

    def check(self) -> None:
        """Refuse a DIR that holds files the engine did not write (nothing is deleted).

        Raises:
            UsageError: DIR is a file, or holds such files.
        """
        foreign = foreign_files(self._place, REPORT_MARKER, _older_report(self._place))
        if foreign:
            shown = ", ".join(foreign[:5])
            if len(foreign) > 5:
                shown += f" and {len(foreign) - 5} more"
            raise UsageError(
                f"--report {self.target} holds files clark did not write ({shown}); "
                "a report replaces its folder, so give a new or empty folder, or move them"
            )

    def open(self) -> Path:
        """Make the fresh folder (a hidden sibling of DIR) and return its ``logs`` folder.

        Raises:
            UsageError: It cannot be made.
        """
        place = self._place
        try:
            place.parent.mkdir(parents=True, exist_ok=True)
            staging = Path(tempfile.mkdtemp(prefix=f".{place.name}.incomplete-", dir=place.parent))
            self.staging = staging
            staging.chmod(0o755)  # mkdtemp's 700 would become the report's mode
            (staging / "logs").mkdir()
        except OSError as exc:
            raise UsageError(
                f"cannot write the report to {self.target}: {exc.strerror or exc}"
            ) from None
        return staging / "logs"

    @property
    def folder(self) -> Path:
        """The folder to write the report's files into (before :meth:`commit`)."""
        assert self.staging is not None, "open() first"
        return self.staging

    def commit(self) -> None:
        """List the report's files, then put it in DIR's place.

        Raises:
            UsageError: DIR gained files the engine did not write during the run, or
                the folder cannot be moved.
        """
        self.check()
        try:
            write_marker(self.folder, REPORT_MARKER, "dry-run report (clark dry-run --report)")
            swap_in(self.folder, self._place)
        except OSError as exc:
            raise UsageError(
                f"cannot write the report to {self.target}: {exc.strerror or exc}"
            ) from None
        self.staging = None

    def discard(self) -> None:
        """Remove the fresh folder if it was not committed (an interrupted or failed run)."""
        if self.staging is not None and os.path.isdir(self.staging):
            shutil.rmtree(self.staging, ignore_errors=True)
        self.staging = None


@dataclass(frozen=True, slots=True)
class InjectedFault:
    """A fault the run injected, with where it was given.

    Attributes:
        fault: The fault in the mission's form (``{"kill": {"agent": "a", "at_s": 5}}``).
        given_by: ``mission`` for the mission's ``faults:``, or ``--fault TEXT``.
    """

    fault: Mapping[str, Any]
    given_by: str

    @property
    def kind(self) -> str:
        """The fault's kind (``kill``, ``link_drop``, ...)."""
        return next(iter(self.fault))

    @property
    def body(self) -> Mapping[str, Any]:
        """The fault's parameters."""
        body: Mapping[str, Any] = self.fault[self.kind]
        return body

    @property
    def agents(self) -> tuple[str, ...]:
        """The agents it strikes; empty for a fault on the whole fleet or its stations."""
        body = self.body
        return (*(str(n) for n in body.get("between", [])),) + (
            (str(body["agent"]),) if "agent" in body else ()
        )

    def window(self, end_s: float) -> tuple[float, float]:
        """(start, end) in simulated seconds, clipped to ``end_s``; a kill lasts to the end."""
        body = self.body
        start = float(body.get("at_s", body.get("from_s", 0.0)))
        end = float(body.get("to_s", math.inf)) if "at_s" not in body else math.inf
        return start, min(end, end_s)

    def describe(self) -> str:
        """What the fault does, in words (``kill slash_a``, ``stations silent``)."""
        body = self.body
        if self.kind == "kill":
            return f"kill {body['agent']}"
        if self.kind == "link_drop":
            a, b = body["between"]
            return f"link {a} - {b} dropped"
        if self.kind == "station_silent":
            return "stations silent"
        if self.kind == "autopilot_disconnect":
            return f"autopilot of {body['agent']} disconnected"
        if self.kind == "corrupt":
            return f"{100 * float(body['share']):g}% of packets corrupted"
        return self.kind

    def when(self) -> str:
        """When it strikes, in simulated seconds (``at 75``, ``65 to 80``, ``the whole run``)."""
        body = self.body
        if "at_s" in body:
            return f"at {float(body['at_s']):g}"
        start, end = float(body.get("from_s", 0.0)), float(body.get("to_s", math.inf))
        if start == 0 and math.isinf(end):
            return "the whole run"
        return f"{start:g} to end" if math.isinf(end) else f"{start:g} to {end:g}"


@dataclass(frozen=True, slots=True)
class RunOrigin:
    """How a run was made, for the report: its command line and the faults it injected.

    Attributes:
        command: The command line as typed, or the equivalent one for a run made in
            process (:func:`equivalent_command`).
        command_given: True when ``command`` is the one typed.
        faults: Every fault the run injected, the mission's then the command line's.
    """

    command: str
    command_given: bool
    faults: tuple[InjectedFault, ...] = ()
    drawn: tuple[tuple[str, float | bool], ...] = ()
    """The mission's varied values as this run drew them (or ``--vary`` fixed them)."""


def faults_table(faults: Sequence[InjectedFault]) -> str:
    """The injected faults as a Markdown table, in the order they were given."""
    if not faults:
        return "No faults injected.\n"
    lines = ["| fault | when (s) | given by |", "|---|---|---|"]
    lines += [f"| {f.describe()} | {f.when()} | {f.given_by} |" for f in faults]
    return "\n".join(lines) + "\n"


def drawn_table(drawn: Sequence[tuple[str, float | bool]]) -> str:
    """The varied values one run drew, as a Markdown table (nothing when none varies)."""
    if not drawn:
        return ""
    lines = ["| value | drawn |", "|---|---|"]
    lines += [f"| `{path}` | {vary_value_text(value)} |" for path, value in drawn]
    return "\n".join(lines) + "\n"


def vary_value_text(value: float | bool) -> str:
    """A drawn value as ``--vary`` takes it back: ``true``, or the number exactly (shortest)."""
    if isinstance(value, bool):
        return "true" if value else "false"
    number = float(value)
    return f"{number:g}" if number.is_integer() and abs(number) < 1e15 else repr(number)


def drawn_line(seed: int, drawn: Mapping[str, float | bool]) -> str:
    """What one run drew, as ``clark dry-run`` and ``clark autopilot-sim`` say it."""
    shown = ", ".join(f"{path}={vary_value_text(value)}" for path, value in drawn.items())
    return f"drawn for seed {seed}: {shown}"


def equivalent_command(
    mission_path: Path | str,
    seed: int,
    until_s: float | None,
    fault_texts: Sequence[str],
    report: Path | None,
    vary_texts: Sequence[str] = (),
    more: Sequence[str] = (),
) -> str:
    """The ``clark dry-run`` command line that repeats a run made in process.

    The one place such a line is written: a dry run's own (its report's ``Command
    line``) and each failing run of a campaign
    (:func:`clark_engine.campaign.report.reproduce_command`) are both this.

    Args:
        mission_path: The mission file, as the user named it (written as given).
        seed: The run's seed.
        until_s: ``--until``; None leaves it out (the mission's own duration).
        fault_texts: Each ``--fault``, in order.
        report: ``--report``; None leaves it out.
        vary_texts: Each ``--vary PATH=VALUE``, in order.
        more: Words put last as they are (a campaign's ``--autopilot sitl ...``).
    """
    words = ["clark", "dry-run", str(mission_path), "--seed", str(seed)]
    if until_s is not None:
        words += ["--until", f"{until_s:g}"]
    for text in fault_texts:
        words += ["--fault", text]
    for text in vary_texts:
        words += ["--vary", text]
    if report is not None:
        words += ["--report", str(report)]
    words += list(more)
    return shlex.join(words)


def states_label(active: Sequence[str]) -> str:
    """Active leaf states as the report shows them.

    A behaviour that is one primitive or block has one state, the root, whose path is
    empty: it is named rather than shown blank.
    """
    if not active:
        return "(none)"
    return ", ".join(path or "(the whole behaviour)" for path in active)


def timeline_text(recording: Recording) -> str:
    """Every state change of every agent, as a Markdown table."""
    lines = ["| time (s) | agent | event | active states |", "|---:|---|---|---|"]
    rows = [
        (entry.time_s, agent, entry.event, states_label(entry.active))
        for agent, entries in recording.states.items()
        for entry in entries
    ]
    for t, agent, event, active in sorted(rows):
        lines.append(f"| {t:.2f} | {agent} | {event} | {active} |")
    return "\n".join(lines) + "\n"


PACE_LATE_S: Final = 3.0
"""A SITL run whose engine fell further behind SITL's clock than this says so plainly: it
heard SITL that late, and its commands and heartbeats reached SITL late (three heartbeat
periods, thirty ticks at 10 Hz; with a heartbeat period more of silence, that is a second
short of the 5 s after which ArduPilot's ground-station failsafe acts). A busy machine puts
a run on time a second or two behind now and then; the run slows SITL down at 2 s
(:data:`~clark_engine.dryrun.sitl_pace.BEHIND_S`)."""


def pace_lines(pace: Mapping[str, Pace]) -> list[str]:
    """One line per SITL vehicle: how far behind SITL's clock the engine fell.

    For the run's output and its summary: a run that could not keep SITL's pace is not
    the mission's flight on ArduPilot, and must not pass for one.
    """
    lines = []
    for name, kept in pace.items():
        silence = f"its link to the autopilot silent {kept.silent_s:.1f} s at most"
        if kept.speedups:
            steps = ", ".join(f"{speedup:.3g}x at {t_s:.1f} s" for t_s, speedup in kept.speedups)
            silence += (
                f"; SITL's speed-up went from {kept.start_speedup:g}x to {steps} of the run, "
                "slowed where the engine fell behind it"
            )
        if kept.behind_s > PACE_LATE_S:
            lines.append(
                f"warning: {name}: the engine fell {kept.behind_s:.1f} s behind ArduPilot "
                f"SITL's clock (at {kept.behind_at_s:.1f} s of the run), too busy for this "
                f"speed-up: it heard SITL late and its commands and heartbeats reached it late "
                f"({silence}; ArduPilot's ground-station failsafe acts after its timeout), so "
                "this is not the mission's flight on ArduPilot; lower --sitl-speedup"
            )
        else:
            lines.append(
                f"{name}: the engine kept ArduPilot SITL's pace ({kept.behind_s:.1f} s behind "
                f"its clock at most; {silence})"
            )
    return lines


def safety_section(safety: SafetyJudgement) -> list[str]:
    """``summary.md``'s Safety section: what was judged, each breach, the two tables."""
    breaches = safety.breaches
    lines = [
        "## Safety",
        "",
        "Every vehicle against its envelope and every pair against its separation, from the "
        "true tracks, whether or not the mission checks it (docs/dry-run.md#safety). "
        + (f"**{count_breaches(len(breaches))}: the run fails.**" if breaches else "No breach."),
        "",
    ]
    lines += [f"- {breach}" for breach in breaches]
    if breaches:
        lines.append("")
    lines.append(safety.table())
    return lines


def write_summary(
    path: Path,
    *,
    mission: str,
    seed: int,
    end_s: float,
    wall_s: float,
    results: Sequence[CheckResult],
    recording: Recording,
    latency: str,
    plots: Sequence[str],
    comparison: str | None = None,
    origin: RunOrigin | None = None,
    links_note: str = "",
    safety: SafetyJudgement | None = None,
) -> None:
    """``summary.md``: how the run was made, the checks, safety, the timeline, the links.

    ``origin``: the command line and the injected faults (none shown when None).
    ``links_note``: Markdown under the link tables: what "deviation from ideal" means
    (:func:`clark_engine.analysis.latency.explain_deviation`).
    ``comparison``: with ``--autopilot sitl``, the tables of each agent's states and each
    check's figures on SITL and on the simulated autopilot
    (:meth:`~clark_engine.dryrun.timeline.Comparison.table`).
    ``safety``: the run's safety judgement, in a section of its own after the checks.
    """
    passed = sum(r.passed for r in results)
    failed = sum(r.evaluated and not r.passed for r in results)
    skipped = sum(not r.evaluated for r in results)
    verdict = f"{failed} failed" if failed else "no check failed"
    if skipped:
        verdict += f", {skipped} not evaluated: the run ended before their by_s"
    elif not failed:
        verdict = "all checks pass"
    if safety is not None and not safety.passed:
        verdict += f"; safety: {count_breaches(len(safety.breaches))}, so the run fails"
    how = "Command line" if origin is None or origin.command_given else "Equivalent command"
    text = [
        f"# Dry run of {mission}",
        "",
        *([f"{how}: `{origin.command}`", ""] if origin is not None else []),
        f"Seed {seed}; {end_s:g} simulated seconds in {wall_s:.1f} s of wall time "
        f"({end_s / wall_s if wall_s > 0 else float('inf'):.0f}x real time); "
        f"{passed} of {len(results)} checks pass ({verdict}).",
        "",
        *(
            ["## Drawn values", "", drawn_table(origin.drawn)]
            if origin is not None and origin.drawn
            else []
        ),
        "## Injected faults",
        "",
        faults_table(origin.faults if origin is not None else ()),
        "## Checks",
        "",
        checks_table(results) if results else "The mission declares no checks.\n",
        *(safety_section(safety) if safety is not None else []),
        "## Plots",
        "",
        *[f"![{p}]({p})" for p in plots],
        "",
        "## State timeline",
        "",
        timeline_text(recording),
        *(
            [
                "## ArduPilot SITL against the simulated autopilot",
                "",
                "Each state's first entry in this run (SITL) and in the same mission on the "
                "simulated autopilot: the difference judged is the entry's or the leg's "
                "(the time since the agent's previous state change), whichever is smaller, "
                "against a share of SITL's leg; how far apart the vehicle was then (and at "
                "the end of the run) and its altitude on SITL minus simulated; then each "
                "check's verdict and figures in both runs "
                '(docs/autopilot-fidelity.md, "The same mission both ways").',
                "",
                *[f"- {line}" for line in pace_lines(recording.pace)],
                *([""] if recording.pace else []),
                comparison,
            ]
            if comparison is not None
            else []
        ),
        "## Links (clark analyze)",
        "",
        "```",
        latency.rstrip(),
        "```",
        "",
        *([links_note] if links_note else []),
    ]
    path.write_text("\n".join(text), encoding="utf-8")
