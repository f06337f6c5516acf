"""``clark analyze``: the thesis's message latency tables from a folder of message logs.

Each agent writes ``<agent>.messages.csv`` (see :mod:`clark_engine.runtime.logbook`
and docs/logs.md). This module reads every one in a run's folder (found by the
readers' one rule, :func:`clark_engine.analysis.log_folder.find_log_files`: the folder, its
``logs/`` folder and their sub-folders) and reports, per link
(sender -> receiver, sorted by sender then receiver):

- **latency** as in the thesis's Tables 5.3-5.5: how many messages, mean,
  standard deviation, median, minimum and maximum, in seconds. The latency of a
  message is the receiver's GPS time when it arrived minus the message's GPS
  stamp: the ``latency_ms`` column of the receiver's ``received`` rows (Picture
  Data left out: its stamp is the capture time);
- **loss**, by packet counter: packets the sender logged as sent to the
  receiver (a broadcast counts for every other agent with a message log in the
  folder) against the packets the receiver logged from it.

Then the summary of Table 5.6 (section 5.1.2):

- **mean of means**: the mean of every link's mean latency;
- **sum of means**: for each pair of agents, mean(A -> B) + mean(B -> A); over
  more than one pair, the mean of those sums. With two agents this is the
  thesis's sum of the two means; with three and four it reproduces Table 5.6,
  whose sums are twice the mean of means. A pair is the unit because the
  latency one way depends on the phase between the two agents' loops and the
  other way on its complement, so their sum, not either mean, is stable;
- **deviation from ideal**: the sum of means minus the sample period.

The sample period is ``--period-s`` when given, else the ``period_s`` the
logbook writes in the header line of each ``<agent>.mission.log`` in the folder.
Without either (or when the headers disagree) the deviation is not computed
and the report says how to get it.

Bad input never raises past this module's boundary: a row that cannot be read
is reported with its file and line and skipped; a file whose header is not a
message log's is reported and skipped.
"""

from __future__ import annotations

import csv
import math
import re
import statistics
from collections import defaultdict
from collections.abc import Iterable, Iterator, Mapping
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Any, Final, TextIO

from clark_engine.analysis.log_folder import find_log_files
from clark_engine.errors import ClarkError, UsageError
from clark_engine.link.messages import MESSAGE_NAMES, PictureData
from clark_engine.runtime.logbook import BROADCAST_PEER, DIRECTIONS, MESSAGE_LOG_COLUMNS

MESSAGE_LOG_SUFFIX = ".messages.csv"
MISSION_LOG_SUFFIX = ".mission.log"

# Its stamp is the capture time, not the send time: no latency (as in the fleet table).
_PICTURE_DATA = MESSAGE_NAMES[PictureData]
_PERIOD = re.compile(r"\bperiod_s=(\S+)")
_HEADER_LINE_CHARS = 4096  # the mission log's header line is far shorter; never read more


class AnalyzeError(ClarkError):
    """A folder that holds nothing to analyze (exit code 1)."""


@dataclass(frozen=True, slots=True)
class Problem:
    """A row or file that was skipped, and why.

    Attributes:
        file: The file, as found in the folder.
        line: 1-based line of the row, or None for the whole file.
        message: What is wrong.
        clocks: A link between two time bases: its rows are read, its latency refused.
    """

    file: str
    line: int | None
    message: str
    clocks: bool = False

    def format_text(self) -> str:
        """``file:line: message; skipped``, as the command prints it."""
        where = self.file if self.line is None else f"{self.file}:{self.line}"
        return f"{where}: {self.message}" + ("" if self.clocks else "; skipped")


@dataclass(frozen=True, slots=True)
class LinkReport:
    """Latency and loss of one link (sender -> receiver).

    Figures that cannot be known are None: latency without samples, the
    standard deviation below two samples, loss without both agents' logs.

    Attributes:
        sender: The sending agent.
        receiver: The receiving agent.
        messages: Latency samples: messages the receiver logged with a latency.
        mean_s: Mean latency.
        std_s: Sample standard deviation of the latency (n - 1).
        median_s: Median latency.
        min_s: Smallest latency.
        max_s: Largest latency.
        packets_sent: Distinct counters the sender logged as sent to the receiver
            (broadcasts included); None without the sender's log.
        packets_received: Of those, how many the receiver logged; every counter
            it logged from the sender when the sender's log is missing; None
            without the receiver's log.
        packets_lost: Sent but not received; None without both logs.
        loss_ratio: ``packets_lost / packets_sent``; None when unknown or nothing was sent.
        rejected: Packets the receiver rejected (bad tag, malformed, replayed...)
            that claimed to come from the sender; None without the receiver's log.
    """

    sender: str
    receiver: str
    messages: int
    mean_s: float | None
    std_s: float | None
    median_s: float | None
    min_s: float | None
    max_s: float | None
    packets_sent: int | None
    packets_received: int | None
    packets_lost: int | None
    loss_ratio: float | None
    rejected: int | None


@dataclass(frozen=True, slots=True)
class PairReport:
    """The two directions of one pair of agents (``first`` sorts before ``second``).

    Attributes:
        first: One agent.
        second: The other.
        sum_of_means_s: mean(first -> second) + mean(second -> first).
        deviation_s: ``sum_of_means_s`` minus the sample period; None without a period.
    """

    first: str
    second: str
    sum_of_means_s: float
    deviation_s: float | None


@dataclass(frozen=True, slots=True)
class Analysis:
    """Everything ``clark analyze`` reports about one folder.

    Attributes:
        folder: The folder read.
        agents: Agents with a message log that could be read, sorted.
        links: One report per link, sorted by sender then receiver.
        pairs: One report per pair with latency both ways, sorted.
        mean_of_means_s: Mean of the links' mean latencies; None without any.
        sum_of_means_s: Mean over pairs of each pair's sum of means; None without a pair.
        deviation_s: ``sum_of_means_s`` minus ``period_s``; None without either.
        period_s: The sample period used; None when unknown.
        period_source: Where it came from: ``"--period-s"``, ``"mission logs"`` or None.
        period_note: Why there is no period, when there is none.
        rows: Rows read (message log rows, headers excluded).
        problems: Rows and files skipped, in file then line order.
    """

    folder: str
    agents: tuple[str, ...]
    links: tuple[LinkReport, ...]
    pairs: tuple[PairReport, ...]
    mean_of_means_s: float | None
    sum_of_means_s: float | None
    deviation_s: float | None
    period_s: float | None
    period_source: str | None
    period_note: str | None
    rows: int
    problems: tuple[Problem, ...] = field(default=())

    def to_json(self) -> dict[str, Any]:
        """A JSON-ready dict of every field.

        Problems carry file, line and message, and ``clocks: true`` on a link between two
        time bases.
        """
        data = asdict(self)
        data["agents"] = list(self.agents)
        for problem in data["problems"]:
            if problem.pop("clocks"):
                problem["clocks"] = True
        return data


@dataclass(slots=True)
class _Tally:
    """What the folder's logs say about one link, before statistics."""

    sent: set[int] = field(default_factory=set)
    received: set[int] = field(default_factory=set)
    latencies_ms: list[float] = field(default_factory=list)
    rejected: int = 0


@dataclass(slots=True)
class _Row:
    """One valid message log row, as the analysis needs it."""

    direction: str
    peer: str
    counter: int | None
    message_type: str
    latency_ms: float | None


def _optional_int(text: str, column: str) -> int | None:
    if text == "":
        return None
    try:
        return int(text)
    except ValueError:
        raise ValueError(f"{column} is {text!r}, not a whole number") from None


def _finite(text: str, column: str) -> float:
    try:
        value = float(text)
    except ValueError:
        raise ValueError(f"{column} is {text!r}, not a number") from None
    if not math.isfinite(value):
        raise ValueError(f"{column} is {text!r}, not a finite number")
    return value


def _parse_row(row: list[str]) -> _Row:
    """Check one row against the message log's columns.

    Raises:
        ValueError: What is wrong with it, for the problem report.
    """
    if len(row) != len(MESSAGE_LOG_COLUMNS):
        raise ValueError(f"expected {len(MESSAGE_LOG_COLUMNS)} fields, found {len(row)}")
    direction, now_s, gps_ms, peer, counter, size, kind, stamp_ms, latency, _ = row
    if direction not in DIRECTIONS:
        raise ValueError(f"direction is {direction!r}, not one of {', '.join(DIRECTIONS)}")
    _finite(now_s, "now_s")
    _optional_int(gps_ms, "gps_time_ms")
    _optional_int(stamp_ms, "message_gps_time_ms")
    if _optional_int(size, "size_bytes") is None:
        raise ValueError("size_bytes is empty")
    number = _optional_int(counter, "counter")
    if number is not None and number < 0:
        raise ValueError(f"counter is {number}, below zero")
    if direction != "rejected":
        if number is None:
            raise ValueError(f"a {direction} row needs a counter")
        if not peer:
            raise ValueError(f"a {direction} row needs a peer")
        if not kind:
            raise ValueError(f"a {direction} row needs a message_type")
    latency_ms = None if latency == "" else _finite(latency, "latency_ms")
    if latency_ms is not None and direction != "received":
        raise ValueError(f"a {direction} row has a latency_ms")
    return _Row(direction, peer, number, kind, latency_ms)


def open_log(path: Path) -> TextIO:
    """A log file for reading; a bad byte spoils its line only (found with its number).

    Raises:
        UsageError: It cannot be read.
    """
    try:
        # errors="replace": a bad byte spoils its row, found with its line number,
        # instead of a decode error somewhere in an 8 KiB chunk.
        return path.open(encoding="utf-8", errors="replace", newline="")
    except OSError as exc:
        raise UsageError(f"{path}: cannot read it ({exc.strerror or exc})") from None


def csv_rows(path: Path, problems: list[Problem]) -> Iterator[tuple[int, list[str]]]:
    """(line, cells) of every non-blank CSV row, the header first; bad rows are problems.

    The one reader of the logs' CSV files (message logs, fleet CSVs), for ``clark
    analyze``, ``clark analyze --checks`` and ``clark replay``: a row the csv module
    cannot parse is a problem with its line number, never an exception.

    Raises:
        UsageError: The file cannot be read.
    """
    name = str(path)
    with open_log(path) as stream:
        reader = csv.reader(stream)
        line = 0
        while True:
            start = line + 1
            try:
                row = next(reader)
            except StopIteration:
                return
            except csv.Error as exc:
                line = reader.line_num
                problems.append(Problem(name, start, f"not a CSV row ({exc})"))
                continue
            except OSError as exc:
                raise UsageError(f"{path}: cannot read it ({exc.strerror or exc})") from None
            line = reader.line_num
            if row:
                yield start, row


def _read_log(path: Path, problems: list[Problem]) -> list[_Row] | None:
    """Every valid row of one message log; None when it is not a message log.

    Raises:
        UsageError: The file cannot be read at all.
    """
    name = str(path)
    rows: list[_Row] = []
    lines = csv_rows(path, problems)
    first = next(lines, None)
    if first is None or first[0] != 1 or first[1] != list(MESSAGE_LOG_COLUMNS):
        if first is None:
            shown = "empty file"
        elif first[0] != 1:
            shown = "its first line is not a CSV row"
        else:
            shown = f"header is {','.join(first[1])[:80]!r}"
        problems.append(Problem(name, None, f"not a message log ({shown}; expected the logbook's)"))
        return None
    for line, row in lines:
        if any("\ufffd" in cell for cell in row[:-1]):  # detail is free text
            problems.append(Problem(name, line, "not UTF-8 text"))
            continue
        try:
            rows.append(_parse_row(row))
        except ValueError as exc:
            problems.append(Problem(name, line, str(exc)))
    return rows


def _mission_log_period(path: Path) -> float | None:
    """The ``period_s`` in a mission log's header line, or None."""
    try:
        with path.open(encoding="utf-8", errors="replace") as stream:
            first = stream.readline(_HEADER_LINE_CHARS)
    except OSError:
        return None
    match = _PERIOD.search(first)
    if match is None:
        return None
    try:
        period_s = float(match.group(1))
    except ValueError:
        return None
    return period_s if math.isfinite(period_s) and period_s > 0 else None


def _period(
    mission_logs: Mapping[str, Path], period_s: float | None
) -> tuple[float | None, str | None, str | None]:
    """The sample period, where it came from, and why there is none when there is none."""
    if period_s is not None:
        return period_s, "--period-s", None
    found = {
        agent: p
        for agent, path in sorted(mission_logs.items())
        if (p := _mission_log_period(path)) is not None
    }
    values = sorted(set(found.values()))
    if len(values) == 1:
        return values[0], "mission logs", None
    if not values:
        return None, None, "no mission log header gives period_s; give --period-s"
    shown = ", ".join(f"{agent} {p!r} s" for agent, p in sorted(found.items()))
    return None, None, f"the mission logs disagree on the period ({shown}); give --period-s"


def _link_report(sender: str, receiver: str, tally: _Tally, logged: set[str]) -> LinkReport:
    sender_logged = sender in logged
    receiver_logged = receiver in logged
    samples = tally.latencies_ms
    count = len(samples)
    if sender_logged and receiver_logged:
        received: int | None = len(tally.received & tally.sent)
        lost: int | None = len(tally.sent - tally.received)
    else:
        received = len(tally.received) if receiver_logged else None
        lost = None
    sent = len(tally.sent) if sender_logged else None
    return LinkReport(
        sender=sender,
        receiver=receiver,
        messages=count,
        mean_s=statistics.mean(samples) / 1000 if count else None,
        std_s=statistics.stdev(samples) / 1000 if count > 1 else None,
        median_s=statistics.median(samples) / 1000 if count else None,
        min_s=min(samples) / 1000 if count else None,
        max_s=max(samples) / 1000 if count else None,
        packets_sent=sent,
        packets_received=received,
        packets_lost=lost,
        loss_ratio=lost / sent if lost is not None and sent else None,
        rejected=tally.rejected if receiver_logged else None,
    )


def summarize(
    links: Iterable[LinkReport], period_s: float | None
) -> tuple[tuple[PairReport, ...], float | None, float | None, float | None]:
    """The thesis's Table 5.6 figures from per-link mean latencies.

    Args:
        links: Link reports; those without a mean are left out.
        period_s: The sample period, or None.

    Returns:
        The pairs with latency both ways, the mean of means, the sum of means
        (mean over pairs) and the deviation from ideal (None when unknown).
    """
    means = {(link.sender, link.receiver): link.mean_s for link in links}
    known = {key: mean for key, mean in means.items() if mean is not None}
    mean_of_means = statistics.mean(known.values()) if known else None
    pairs: list[PairReport] = []
    for (a, b), there in sorted(known.items()):
        back = known.get((b, a))
        if a < b and back is not None:
            total = there + back
            deviation = None if period_s is None else total - period_s
            pairs.append(PairReport(a, b, total, deviation))
    sum_of_means = statistics.mean(p.sum_of_means_s for p in pairs) if pairs else None
    deviation_s = None if sum_of_means is None or period_s is None else sum_of_means - period_s
    return tuple(pairs), mean_of_means, sum_of_means, deviation_s


CLOCKS_APART_S: Final = 60.0
"""A link whose median latency is larger than this (either way) is between two clocks, not
a radio: no radio holds a packet for a minute. The agents stamped their logs on different
time bases (a simulated autopilot's GPS time against the system clock's), and its
latencies would be garbage."""


def _clocks_apart(sender: str, receiver: str, latencies_ms: list[float]) -> Problem | None:
    """A problem when the link's latencies measure two clocks rather than the link."""
    if not latencies_ms:
        return None
    median_s = statistics.median(latencies_ms) / 1000.0
    if abs(median_s) <= CLOCKS_APART_S:
        return None
    apart = (
        f"{abs(median_s) / 86_400:.0f} days"
        if abs(median_s) >= 86_400
        else f"{abs(median_s):.0f} s"
    )
    return Problem(
        f"{receiver}{MESSAGE_LOG_SUFFIX}",
        None,
        f"{sender} -> {receiver}: the two agents' GPS clocks are {apart} apart (median "
        f"latency {median_s:+.6g} s): their logs were stamped on different time bases, so "
        "this link's latency is not computed (its loss is); run every agent on one time "
        "base (docs/logs.md#time-bases)",
        clocks=True,
    )


def analyze_folder(folder: Path, period_s: float | None = None) -> Analysis:
    """Read every ``*.messages.csv`` in ``folder`` and compute the latency and loss report.

    Args:
        folder: Where the agents wrote their logs.
        period_s: The sample period for the deviation from ideal; by default the
            ``period_s`` of the mission logs' header lines.

    Raises:
        UsageError: The folder does not exist, is not a folder, or a file cannot be read.
        AnalyzeError: No message log in it could be read.
    """
    if period_s is not None and not (math.isfinite(period_s) and period_s > 0):
        raise UsageError(f"the sample period must be a positive number of seconds, not {period_s}")
    problems: list[Problem] = []
    notes: list[str] = []
    found = find_log_files(folder, notes)
    paths = {a: files["message_log"] for a, files in found.items() if "message_log" in files}
    if not paths:
        raise AnalyzeError(
            f"{folder}: no message logs (<agent>{MESSAGE_LOG_SUFFIX}) in it, in its logs/ "
            "folder or in their sub-folders; give the folder the agents wrote their logs to"
        )
    problems += [Problem(str(folder), None, note) for note in notes]
    logs: dict[str, list[_Row]] = {}
    for agent, path in sorted(paths.items()):
        rows = _read_log(path, problems)
        if rows is not None:
            logs[agent] = rows
    if not logs:
        problems.sort(key=lambda p: (p.file, p.line or 0))
        raise AnalyzeError(
            f"{folder}: none of its {len(paths)} message log(s) could be read:\n"
            + "\n".join(f"  {problem.format_text()}" for problem in problems),
        )
    problems.sort(key=lambda p: (p.file, p.line or 0))
    logged = set(logs)
    tallies: defaultdict[tuple[str, str], _Tally] = defaultdict(_Tally)
    for agent, rows in logs.items():
        for row in rows:
            if row.direction == "sent":
                assert row.counter is not None
                receivers = sorted(logged - {agent}) if row.peer == BROADCAST_PEER else [row.peer]
                for receiver in receivers:
                    tallies[(agent, receiver)].sent.add(row.counter)
            elif row.direction == "received":
                assert row.counter is not None
                tally = tallies[(row.peer, agent)]
                tally.received.add(row.counter)
                if row.latency_ms is not None and row.message_type != _PICTURE_DATA:
                    tally.latencies_ms.append(row.latency_ms)
            elif row.peer:  # rejected, with a claimed sender
                tallies[(row.peer, agent)].rejected += 1
    for (sender, receiver), tally in sorted(tallies.items()):
        problem = _clocks_apart(sender, receiver, tally.latencies_ms)
        if problem is not None:
            problems.append(problem)
            tally.latencies_ms.clear()
    links = tuple(
        _link_report(sender, receiver, tally, logged)
        for (sender, receiver), tally in sorted(tallies.items())
    )
    mission_logs = {
        agent: files["mission_log"]
        for agent, files in found.items()
        if agent in logged and "mission_log" in files
    }
    period, source, note = _period(mission_logs, period_s)
    pairs, mean_of_means, sum_of_means, deviation = summarize(links, period)
    return Analysis(
        folder=str(folder),
        agents=tuple(sorted(logged)),
        links=links,
        pairs=pairs,
        mean_of_means_s=mean_of_means,
        sum_of_means_s=sum_of_means,
        deviation_s=deviation,
        period_s=period,
        period_source=source,
        period_note=note,
        rows=sum(len(rows) for rows in logs.values()),
        problems=tuple(problems),
    )


# ------------------------------------------------------------------ text


def _seconds(value: float | None) -> str:
    return "-" if value is None else f"{value:.3f}"


def _count(value: int | None) -> str:
    return "-" if value is None else str(value)


def _table(header: list[str], rows: list[list[str]]) -> list[str]:
    """Columns padded to their widest cell: the first left-aligned, the rest right-aligned."""
    widths = [max(len(r[i]) for r in [header, *rows]) for i in range(len(header))]
    lines = []
    for row in [header, *rows]:
        cells = [row[0].ljust(widths[0])]
        cells += [cell.rjust(width) for cell, width in zip(row[1:], widths[1:], strict=True)]
        lines.append("  ".join(cells).rstrip())
    return lines


def format_text(analysis: Analysis) -> str:
    """The report for people: latency table, pairs, summary, loss table."""
    out: list[str] = [
        f"{analysis.folder}: {len(analysis.agents)} agent(s) "
        f"({', '.join(analysis.agents)}), {analysis.rows} row(s)",
        "",
        "Message latency by link (seconds; receiver's GPS time at receipt - message's GPS stamp)",
    ]
    if not analysis.links:
        out.append("  no messages were sent or received")
    else:
        out += _table(
            ["link", "messages", "mean", "std", "median", "min", "max"],
            [
                [
                    f"{link.sender} -> {link.receiver}",
                    str(link.messages),
                    _seconds(link.mean_s),
                    _seconds(link.std_s),
                    _seconds(link.median_s),
                    _seconds(link.min_s),
                    _seconds(link.max_s),
                ]
                for link in analysis.links
            ],
        )
    out += [f"  not computed: {p.message}" for p in analysis.problems if p.clocks]
    if analysis.pairs:
        out += ["", "Pairs (sum of means = mean A -> B + mean B -> A)"]
        out += _table(
            ["pair", "sum of means", "deviation"],
            [
                [
                    f"{pair.first} <-> {pair.second}",
                    _seconds(pair.sum_of_means_s),
                    _seconds(pair.deviation_s),
                ]
                for pair in analysis.pairs
            ],
        )
    if analysis.period_s is None:
        period = f"unknown: {analysis.period_note}"
    else:
        period = f"{analysis.period_s!r} s (from {analysis.period_source})"
    out += [
        "",
        f"mean of means         {_seconds(analysis.mean_of_means_s)} s",
        f"sum of means          {_seconds(analysis.sum_of_means_s)} s",
        f"deviation from ideal  {_seconds(analysis.deviation_s)} s",
        f"sample period         {period}",
    ]
    if analysis.links:
        out += [
            "",
            "Packet loss by link (by packet counter; a broadcast counts for every receiver)",
        ]
        out += _table(
            ["link", "sent", "received", "lost", "loss", "rejected"],
            [
                [
                    f"{link.sender} -> {link.receiver}",
                    _count(link.packets_sent),
                    _count(link.packets_received),
                    _count(link.packets_lost),
                    "-" if link.loss_ratio is None else f"{100 * link.loss_ratio:.1f}%",
                    _count(link.rejected),
                ]
                for link in analysis.links
            ],
        )
    return "\n".join(out) + "\n"


def explain_deviation(analysis: Analysis) -> str:
    """What "deviation from ideal" means, with this analysis's figures, in Markdown.

    For the dry run's report, under ``clark analyze``'s tables (docs/logs.md says the same
    at length): how the figure is made, why the thesis's ideal is zero, and why Clark
    Engine's runs read near minus one period.
    """
    if analysis.deviation_s is not None and analysis.sum_of_means_s is not None:
        figures = (
            f"Here: sum of means ({_seconds(analysis.sum_of_means_s)} s) minus the sample "
            f"period ({analysis.period_s!r} s, from {analysis.period_source}) "
            f"= {_seconds(analysis.deviation_s)} s."
        )
    elif analysis.sum_of_means_s is None:
        figures = "Here it is not computed: no pair of agents heard each other both ways."
    else:
        figures = (
            f"Here it is not computed: the sample period is unknown ({analysis.period_note}); "
            "`clark analyze --period-s SECONDS` gives it."
        )
    return (
        "**Deviation from ideal** is the sum of means (for a pair of agents, the mean "
        "latency A -> B plus the mean latency B -> A) minus the sample period (1 / loop_hz). "
        "In the thesis (section 5.1.2) a message waited in the receiver's buffer until the "
        "receiver's next loop read it, so the two directions' waits added up to one loop "
        "period: the ideal sum of means was one period, and the deviation measured the delay "
        "beyond it. Clark Engine takes a message the moment it arrives, so its latencies are "
        "transport alone (packing, radio, decoding): with a fast link the sum of means is near "
        "zero and the deviation near minus one period; how far it lies above minus one period "
        "is transport delay (the per-link means say which way it comes from). "
        f"{figures} (docs/logs.md, clark analyze.)\n"
    )
