"""``clark analyze LOGDIR --checks MISSION``: a mission's checks, judged from a run's logs.

Why: a mission's ``checks:`` say what a good run looks like, but only ``clark dry-run``
judged them, against the :class:`~clark_engine.expectations.recording.Recording` the simulator
fills in. A real run (``clark run``, one process per agent) leaves only its logs.
This module rebuilds a ``Recording`` from a folder of them and evaluates the checks
with the dry run's own evaluators (:func:`clark_engine.expectations.evaluate.evaluate`), so a
flight and its rehearsal are judged by the same code and printed in the same table.

How (each agent's four files, named by its compiled config: ``<agent>.mission.log``,
``<agent>.interface.log``, ``<agent>.fleet.csv``, ``<agent>.messages.csv``):

- **Mission time.** t = 0 is the start of the station's runtime clock (the agent of
  role ``mcs``): the operator script counts from it. Every agent's clock is mapped
  onto it through GPS time: every text log line reads ``t=... gps_ms=...``, so an
  agent's offset is the median over its lines of ``gps_ms - 1000 * t`` (the GPS time
  at its own t = 0; lines with ``gps_ms=-`` are left out; without any such line, its
  message log's ``now_s`` and ``gps_time_ms`` are used). An agent's time ``t`` is then
  ``t + (offset - station's offset) / 1000`` in mission time. Without a station log
  (or without GPS time in it), t = 0 is the start of the agent that started first by
  GPS time; an agent without any GPS time keeps its own clock, with a warning.
- **Tracks** come from the fleet CSVs: each row holds another agent's latest Agent
  Status (``lat_deg``, ``lon_deg``, ``alt_m`` above the origin), which arrived
  ``status_age_s`` before the row's ``now_s``; one sample is kept per arrival. The
  station's view is preferred (what the operator saw); another agent's view fills in
  where the station's has none for over :data:`GAP_STATUS_PERIODS` of the vehicle's
  Agent Status periods: a vehicle the station never saw, or while the station was
  out of range, deaf, or had stopped logging (each use is a warning). Positions are
  converted to metres north, east and up of the mission's origin; attitude is the
  row's roll, pitch and yaw (0 when the agent sends no Agent Attitude). The
  evaluators compare tracks sample by sample, so every track is put on one time grid
  (every arrival of any vehicle), each holding its latest position; before a
  vehicle's first position its samples are NaN, which no distance can pass on.
- **States** come from each agent's mission log lines
  ``behavior.change: EVENT: SOURCE -> TARGET (active: A, B)``. The line does not
  say which states the change entered; they are rebuilt as
  :class:`~clark_engine.runtime.machine.BehaviorMachine` enters them
  (:func:`entered_states`): the target and every state active under it afterwards
  (entered again when it was active: a transition to itself, to an ancestor or to an
  active descendant), and every state active afterwards that was not before.
  ``failed`` enters nothing.
- **Why a state was not reached**: the last ``launch: the behaviour waits for ...``
  line (``launch.wait``, mission log) before the behaviour started, for an agent
  whose behaviour never did; the ``state`` and ``sequence`` checks quote it.
- **Safety events**, as the dry run records them: the first ``failsafe ACTION`` line
  (``failsafe.act``, mission log; ``continue`` is no failsafe) and the first
  ``autopilot silent ...: lost`` line (``autopilot.lost``, interface log).
- **Photos** are the Picture Data an agent sent (its message log's ``sent`` rows of
  ``picture_data``, one per picture however many destinations it went to) plus the
  pictures its mission log says were taken before any position (none sent), at the
  time they were sent. Their position is the agent's track's at that time. A picture
  taken in the last tick before the logs end, whose Picture Data was never sent, is
  not counted (the dry run counts the camera's captures).
- **Control signals** (the ``signal`` check) are not in the logs: that check is
  reported ``not evaluated``. So is any check whose data the folder lacks (an
  agent's log missing, a log level that hides the lines, a vehicle never seen):
  no check passes on missing data. ``altitude_m`` and ``ends_at`` read the tracks
  (the altitude is Agent Status's ``alt_m``, above the origin), as ``reached`` does.
- ``end_s`` is the latest mission time in any of the logs.

Lines are told apart by the event they name (docs/logs.md, "Events"), never by the code
that wrote them; logs written before events named ``module.function`` instead, and the
names the readers need are read as their events
(:data:`~clark_engine.runtime.log_events.LEGACY_NAMES`).

A row or line that cannot be read is a warning with its file and line, and is
skipped; the rest is still evaluated.
"""

from __future__ import annotations

import bisect
import json
import math
import re
import statistics
import sys
from collections.abc import Iterator, Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Final, TextIO

from clark_engine.analysis.latency import Problem, csv_rows, open_log
from clark_engine.analysis.log_folder import LOG_FILES, find_log_files
from clark_engine.errors import ClarkError, UsageError
from clark_engine.expectations.evaluate import CheckResult, checks_table, evaluate
from clark_engine.expectations.recording import Photo, Recording, StateEntry, Track
from clark_engine.mission.geo import Origin, to_local
from clark_engine.mission.model import Mission
from clark_engine.runtime.config import AgentConfig
from clark_engine.runtime.log_events import LogEvent, event_of
from clark_engine.runtime.logbook import MESSAGE_LOG_COLUMNS
from clark_engine.untrusted import printable

#: A text log line (:data:`clark_engine.runtime.logbook.LINE_FORMAT`).
_LINE: Final = re.compile(
    r"t=(?P<t>\S+) gps_ms=(?P<gps>\S+) (?P<level>[A-Z]+) (?P<event>[^\s:]+): (?P<message>.*)"
)
#: ``behavior.change``'s message: ``EVENT: SOURCE -> TARGET (active: A, B)``.
_CHANGE: Final = re.compile(
    r"(?P<event>.+?): (?P<source>\S+) -> (?P<target>\S+) \(active: (?P<active>.*)\)"
)
_FAILSAFE: Final = re.compile(r"failsafe (?P<action>\S+)")
_AUTOPILOT_LOST: Final = re.compile(r"autopilot silent for \S+ s: lost\b")
_NO_POSITION_PICTURE: Final = re.compile(r".*: picture \d+ \(.*\) taken before any position\b")
_LAUNCH_WAITS: Final = "launch: the behaviour waits for "
_LAUNCH_STARTS: Final = re.compile(r"launch: the autopilot is ready; .*; the behaviour starts")
_HEADER: Final = "logbook opened: "
_LEVELS: Final = {"DEBUG": 10, "INFO": 20, "WARNING": 30, "ERROR": 40, "CRITICAL": 50}
_PICTURE_DATA: Final = "picture_data"
#: Fleet CSV columns the tracks need; roll, pitch and yaw are read when present.
_FLEET_COLUMNS: Final = ("now_s", "name", "lat_deg", "lon_deg", "alt_m", "status_age_s")
#: An Agent Status arrival time is ``now_s - status_age_s``; the same arrival, seen on
#: later rows, differs by rounding only. Arrivals are told apart to the microsecond.
_ARRIVAL_DIGITS: Final = 6
#: A vehicle's positions are taken from the station's fleet table; from another agent's
#: only where the station's has none for over this many of its Agent Status periods (out
#: of range, silent, or its log ended).
GAP_STATUS_PERIODS: Final = 2.5
#: Spread (10th to 90th percentile) of an agent's GPS clock offset above which it is noted.
_CLOCK_SPREAD_NOTE_S: Final = 1.0
#: Why the ``signal`` check cannot be judged from logs.
NO_SIGNALS: Final = (
    "the logs do not record the pulse widths the autopilot received (a dry run reads "
    "them from its simulated autopilot; the runtime logs no RC or servo values)"
)


class LogChecksError(ClarkError):
    """A folder holding none of the mission's logs (exit code 1)."""


@dataclass(frozen=True, slots=True)
class TextLine:
    """One readable text log line."""

    number: int
    t_s: float
    gps_ms: int | None
    level: str
    event: str
    """The event the line names (:class:`~clark_engine.runtime.log_events.LogEvent`'s
    value), a legacy ``module.function`` already read as its event."""
    message: str


@dataclass(slots=True)
class AgentLogs:
    """What one agent's logs say, on its own clock until :attr:`shift_s` is known.

    Attributes:
        name: The agent.
        files: Config key (``mission_log``...) -> the file found in the folder.
        header: The ``key=value`` fields of its mission log's header line.
        offsets_ms: ``gps_ms - 1000 * t`` of every text log line with a GPS time.
        message_offsets_ms: The same from its message log's rows (a fallback).
        shift_s: Added to its times to give mission time (0 until aligned).
        clock: How its clock was aligned, for the report.
        changes: (t, event, source, target, active leaves) of each state change.
        failsafe: (t, action) of its first failsafe, if any.
        autopilot_lost_s: When it first lost its autopilot, if it did.
        pictures_s: When it sent Picture Data or logged a picture without position.
        waiting: What its launch gate last said it waited for, until the behaviour
            started (None then, or without such a line).
        latest_s: Its latest time in any of its logs.
    """

    name: str
    files: dict[str, Path] = field(default_factory=dict)
    header: dict[str, str] = field(default_factory=dict)
    offsets_ms: list[float] = field(default_factory=list)
    message_offsets_ms: list[float] = field(default_factory=list)
    shift_s: float = 0.0
    clock: str = ""
    changes: list[tuple[float, str, str, str, tuple[str, ...]]] = field(default_factory=list)
    failsafe: tuple[float, str] | None = None
    autopilot_lost_s: float | None = None
    pictures_s: list[float] = field(default_factory=list)
    waiting: str | None = None
    latest_s: float | None = None

    def seen(self, t_s: float) -> None:
        """Note a time of this agent's (its own clock)."""
        if self.latest_s is None or t_s > self.latest_s:
            self.latest_s = t_s

    @property
    def level(self) -> str | None:
        """The log level its header names, None without a header."""
        return self.header.get("level")

    def hides(self, level: str) -> bool:
        """True when its logs were written at a level above ``level`` (those lines are absent)."""
        written = _LEVELS.get(self.level or "", 0)
        return written > _LEVELS[level]


@dataclass(slots=True)
class LogRun:
    """A run rebuilt from its logs.

    Attributes:
        folder: The folder read.
        mission: The mission the logs are of.
        configs: Agent -> its compiled config (the evaluators' view of the mission).
        recording: What the logs say, in mission time and the mission's local frame.
        agents: Agent -> its logs, for every agent of the mission with a log in the folder.
        time_origin: What t = 0 is, in words.
        problems: Rows, lines and files skipped, in file then line order.
        notes: Other warnings (clocks, files of other missions or agents).
    """

    folder: Path
    mission: Mission
    configs: dict[str, AgentConfig]
    recording: Recording
    agents: dict[str, AgentLogs]
    time_origin: str
    problems: list[Problem] = field(default_factory=list)
    notes: list[str] = field(default_factory=list)

    def warnings(self) -> list[str]:
        """Every problem and note, as the command prints them (after ``warning:``)."""
        return [p.format_text() for p in self.problems] + self.notes


@dataclass(frozen=True, slots=True)
class LogChecks:
    """The checks of a mission judged on a run's logs."""

    run: LogRun
    results: list[CheckResult]

    @property
    def failed(self) -> list[CheckResult]:
        """Checks evaluated that did not hold."""
        return [r for r in self.results if r.evaluated and not r.passed]

    @property
    def skipped(self) -> list[CheckResult]:
        """Checks not evaluated."""
        return [r for r in self.results if not r.evaluated]

    def to_json(self) -> dict[str, Any]:
        """A JSON-ready summary: the folder, the clocks and every check's verdict."""
        run = self.run
        return {
            "folder": str(run.folder),
            "mission": run.mission.name,
            "agents": sorted(run.agents),
            "time_origin": run.time_origin,
            "clocks": {
                name: {"shift_s": logs.shift_s, "how": logs.clock}
                for name, logs in sorted(run.agents.items())
            },
            "end_s": run.recording.end_s,
            "checks": [
                {
                    "name": r.name,
                    "expected": r.expected,
                    "observed": r.observed,
                    "result": r.verdict,
                    "passed": r.passed,
                    "evaluated": r.evaluated,
                }
                for r in self.results
            ],
            "warnings": run.warnings(),
        }


# ------------------------------------------------------------------ reading


def _finite(text: str, column: str) -> float:
    try:
        value = float(text)
    except ValueError:
        raise ValueError(f"{column} is {text!r}, not a number") from None
    if not math.isfinite(value):
        raise ValueError(f"{column} is {text!r}, not a finite number")
    return value


def text_lines(path: Path, problems: list[Problem]) -> Iterator[TextLine]:
    """Every readable line of a mission or interface log; the others are problems.

    Raises:
        UsageError: The file cannot be read.
    """
    name = str(path)
    with open_log(path) as stream:
        try:
            for number, raw in enumerate(stream, start=1):
                text = raw.rstrip("\r\n")
                if not text:
                    continue
                match = _LINE.fullmatch(text)
                if match is None:
                    problems.append(
                        Problem(name, number, "not a log line (t=... gps_ms=... LEVEL event: ...)")
                    )
                    continue
                gps = match["gps"]
                try:
                    t_s = _finite(match["t"], "t")
                except ValueError as exc:
                    problems.append(Problem(name, number, str(exc)))
                    continue
                if gps != "-" and not (gps.isascii() and gps.isdigit()):
                    problems.append(Problem(name, number, f"gps_ms is {gps!r}, not - or digits"))
                    continue
                gps_ms = None if gps == "-" else int(gps)
                level = match["level"]
                if level not in _LEVELS:
                    problems.append(Problem(name, number, f"level {level!r} is not a log level"))
                    continue
                yield TextLine(
                    number, t_s, gps_ms, level, event_of(match["event"]), match["message"]
                )
        except OSError as exc:
            raise UsageError(f"{path}: cannot read it ({exc.strerror or exc})") from None


def _header(message: str) -> dict[str, str]:
    fields = message.removeprefix(_HEADER).split()
    return dict(item.split("=", 1) for item in fields if "=" in item)


def read_mission_log(path: Path, logs: AgentLogs, problems: list[Problem]) -> None:
    """Its header, GPS offsets, state changes, first failsafe and pictures, into ``logs``.

    Raises:
        UsageError: The file cannot be read.
    """
    for line in text_lines(path, problems):
        logs.seen(line.t_s)
        if line.gps_ms is not None:
            logs.offsets_ms.append(line.gps_ms - 1000 * line.t_s)
        message = line.message
        event = line.event
        if event == LogEvent.LOG_OPEN and message.startswith(_HEADER):
            logs.header = _header(message)
        elif event == LogEvent.BEHAVIOR_CHANGE:
            match = _CHANGE.fullmatch(message)
            if match is None:
                problems.append(
                    Problem(str(path), line.number, "a state change that cannot be read")
                )
                continue
            text = match["active"]
            # The root of a one-primitive behaviour is the path "" (its only leaf).
            active = tuple(text.split(", ")) if text else ("",)
            source = "" if match["source"] == "(start)" else match["source"]
            target = "" if match["target"] == "(behavior)" else match["target"]
            logs.changes.append((line.t_s, match["event"], source, target, active))
        elif event == LogEvent.FAILSAFE_ACT and logs.failsafe is None:
            found = _FAILSAFE.fullmatch(message)
            if found is not None and found["action"] != "continue":
                logs.failsafe = (line.t_s, found["action"])
        elif event == LogEvent.PHOTO_NO_POSITION and _NO_POSITION_PICTURE.match(message):
            logs.pictures_s.append(line.t_s)
        elif event in (LogEvent.LAUNCH_WAIT, LogEvent.LAUNCH_START):
            if message.startswith(_LAUNCH_WAITS):
                logs.waiting = printable(message.removeprefix(_LAUNCH_WAITS), 400)
            elif _LAUNCH_STARTS.fullmatch(message):
                logs.waiting = None


def read_interface_log(path: Path, logs: AgentLogs, problems: list[Problem]) -> None:
    """Its GPS offsets, its first autopilot loss and (without a mission log) its header.

    Raises:
        UsageError: The file cannot be read.
    """
    for line in text_lines(path, problems):
        logs.seen(line.t_s)
        if line.gps_ms is not None:
            logs.offsets_ms.append(line.gps_ms - 1000 * line.t_s)
        if (
            logs.autopilot_lost_s is None
            and line.event == LogEvent.AUTOPILOT_LOST
            and _AUTOPILOT_LOST.match(line.message)
        ):
            logs.autopilot_lost_s = line.t_s
        if not logs.header and line.message.startswith(_HEADER):
            logs.header = _header(line.message)


def read_message_log(path: Path, logs: AgentLogs, problems: list[Problem]) -> None:
    """Clock pairs and the Picture Data sent, from one message log."""
    name = str(path)
    rows = csv_rows(path, problems)
    first = next(rows, None)
    if first is None or first[1] != list(MESSAGE_LOG_COLUMNS):
        problems.append(Problem(name, None, "not a message log (its header is not the logbook's)"))
        return
    pictures: dict[str, dict[str, int]] = {}  # sending tick's now_s -> destination -> count
    for number, row in rows:
        if len(row) != len(MESSAGE_LOG_COLUMNS):
            problems.append(
                Problem(
                    name, number, f"expected {len(MESSAGE_LOG_COLUMNS)} fields, found {len(row)}"
                )
            )
            continue
        direction, now_text, gps_text, peer, _counter, _size, kind = row[:7]
        try:
            now_s = _finite(now_text, "now_s")
            gps_ms = int(gps_text) if gps_text else None
        except ValueError as exc:
            problems.append(Problem(name, number, str(exc)))
            continue
        logs.seen(now_s)
        if gps_ms is not None:
            logs.message_offsets_ms.append(gps_ms - 1000 * now_s)
        if direction == "sent" and kind == _PICTURE_DATA:
            tick = pictures.setdefault(now_text, {})
            tick[peer] = tick.get(peer, 0) + 1
    for now_text, by_peer in pictures.items():
        # One picture goes out once per destination: a tick sent max(per destination).
        logs.pictures_s.extend([float(now_text)] * max(by_peer.values()))


@dataclass(slots=True)
class _Sample:
    """One Agent Status as an observer received it."""

    arrival_s: float  # observer's clock
    lat_deg: float
    lon_deg: float
    alt_m: float
    roll_deg: float
    pitch_deg: float
    yaw_deg: float


def _optional(row: list[str], index: int | None, column: str) -> float:
    if index is None or row[index] == "":
        return 0.0
    return _finite(row[index], column)


def fleet_csv(
    path: Path, required: Sequence[str], problems: list[Problem]
) -> tuple[list[str], Iterator[tuple[int, list[str]]]] | None:
    """A fleet CSV's header and its remaining (line, cells) rows; None when it is not one.

    It is one when its header starts with ``now_s`` and holds every ``required`` column;
    otherwise that is a problem (the header shown escaped and cut), and None.

    Raises:
        UsageError: The file cannot be read.
    """
    rows = csv_rows(path, problems)
    first = next(rows, None)
    header = first[1] if first is not None else []
    if first is None or header[:1] != ["now_s"] or not set(required) <= set(header):
        shown = "empty file" if first is None else f"header is {printable(','.join(header), 80)!r}"
        problems.append(
            Problem(str(path), None, f"not a fleet CSV ({shown}; expected the logbook's)")
        )
        return None
    return header, rows


def _read_fleet_csv(
    path: Path, logs: AgentLogs, problems: list[Problem]
) -> dict[str, list[_Sample]]:
    """Observed agent -> the Agent Status arrivals this agent's fleet table logged."""
    name = str(path)
    opened = fleet_csv(path, _FLEET_COLUMNS, problems)
    if opened is None:
        return {}
    header, rows = opened
    at = {column: header.index(column) for column in _FLEET_COLUMNS}
    attitude = {
        c: header.index(c) if c in header else None for c in ("roll_deg", "pitch_deg", "yaw_deg")
    }
    seen: dict[str, dict[float, _Sample]] = {}
    for number, row in rows:
        if len(row) != len(header):
            problems.append(
                Problem(name, number, f"expected {len(header)} fields, found {len(row)}")
            )
            continue
        try:
            now_s = _finite(row[at["now_s"]], "now_s")
            logs.seen(now_s)
            if row[at["lat_deg"]] == "":
                continue  # no Agent Status from it yet
            peer = row[at["name"]]
            if not peer:
                raise ValueError("name is empty")
            arrival = now_s - _finite(row[at["status_age_s"]], "status_age_s")
            key = round(arrival, _ARRIVAL_DIGITS)
            arrivals = seen.setdefault(peer, {})
            if key in arrivals:
                continue
            arrivals[key] = _Sample(
                arrival,
                _finite(row[at["lat_deg"]], "lat_deg"),
                _finite(row[at["lon_deg"]], "lon_deg"),
                _finite(row[at["alt_m"]], "alt_m"),
                _optional(row, attitude["roll_deg"], "roll_deg"),
                _optional(row, attitude["pitch_deg"], "pitch_deg"),
                _optional(row, attitude["yaw_deg"], "yaw_deg"),
            )
        except ValueError as exc:
            problems.append(Problem(name, number, str(exc)))
    return {
        peer: sorted(arrivals.values(), key=lambda s: s.arrival_s)
        for peer, arrivals in seen.items()
    }


# ------------------------------------------------------------------ rebuilding


def file_names(config: AgentConfig) -> dict[str, str]:
    """Config key -> the file the agent writes (its config's name, else ``<agent>.<suffix>``)."""
    names = {}
    for key, suffix in LOG_FILES.items():
        name = config.log_files.get(key) or ""
        names[key] = name if name and Path(name).name == name else config.agent + suffix
    return names


OTHER_TIME_BASE_S: Final = 6 * 3600.0
"""Agents of one run start within minutes of each other: a GPS time further than this from
the reference's is another time base (a simulated GPS clock against the system clock),
not a late start, and aligning by it would spread the run over days."""


def align_clocks(
    agents: Mapping[str, AgentLogs], roles: Mapping[str, str], notes: list[str]
) -> str:
    """Set every agent's :attr:`AgentLogs.shift_s`; returns what t = 0 is, in words.

    Args:
        agents: The agents' logs, read (their GPS offsets collected).
        roles: Agent -> its role (``mcs`` for a station: t = 0 is a station's start).
        notes: Where the warnings about clocks go.
    """
    offsets: dict[str, float] = {}
    for name, logs in agents.items():
        samples = logs.offsets_ms or logs.message_offsets_ms
        if not samples:
            continue
        offsets[name] = statistics.median(samples)
        if len(samples) >= 10:
            deciles = statistics.quantiles(samples, n=10)
            spread_s = (deciles[-1] - deciles[0]) / 1000
            if spread_s > _CLOCK_SPREAD_NOTE_S:
                notes.append(
                    f"{name}: its GPS time and runtime clock disagree by up to {spread_s:.1f} s "
                    "over the run (a GPS fix taken late, or a clock step); the median is used"
                )
    stations = sorted(n for n in agents if roles.get(n) == "mcs" and n in offsets)
    if stations:
        reference = offsets[stations[0]]
        origin = f"t=0 is the start of station {stations[0]}'s clock"
    elif offsets:
        first = min(offsets, key=lambda n: (offsets[n], n))
        reference = offsets[first]
        has_station = any(roles.get(n) == "mcs" for n in agents)
        why = "its log has no GPS time" if has_station else "no station log in the folder"
        origin = f"t=0 is the start of {first}, the first agent to start by GPS time ({why})"
        notes.append(f"{why}: mission time counts from {first}'s start, not the station's")
    else:
        reference = 0.0
        origin = "each agent's own clock (no GPS time in any log)"
    for name, logs in agents.items():
        if name in offsets and abs(offsets[name] - reference) / 1000 > OTHER_TIME_BASE_S:
            apart_s = abs(offsets[name] - reference) / 1000
            shown = f"{apart_s / 86_400:.0f} days" if apart_s >= 86_400 else f"{apart_s:.0f} s"
            logs.shift_s = 0.0
            logs.clock = "its own clock (its GPS time is on another time base)"
            notes.append(
                f"{name}: its GPS time is {shown} from the reference's, more than agents of "
                "one run start apart: its logs were stamped on another time base "
                "(docs/logs.md#time-bases), so its own start is taken as t=0"
            )
        elif name in offsets:
            logs.shift_s = (offsets[name] - reference) / 1000
            source = "mission and interface logs" if logs.offsets_ms else "message log"
            logs.clock = f"{logs.shift_s:+.3f} s, by GPS time ({source})"
        else:
            logs.shift_s = 0.0
            logs.clock = "its own clock (no GPS time in its logs)"
            notes.append(
                f"{name}: no GPS time in its logs; its own clock is taken as mission time, "
                "so its times may be off by the difference between its start and t=0's"
            )
    return origin


def _prefixes(path: str) -> list[str]:
    """``path`` and its ancestors, the root ``""`` included."""
    if not path:
        return [""]
    parts = path.split(".")
    return ["", *(".".join(parts[: i + 1]) for i in range(len(parts)))]


def _under(path: str, top: str) -> bool:
    """``path`` is ``top`` or inside it."""
    return not top or path == top or path.startswith(top + ".")


def entered_states(
    event: str, target: str, before: Sequence[str], after: Sequence[str]
) -> set[str]:
    """The states one change entered, from its log line and the active leaves before it.

    As :class:`~clark_engine.runtime.machine.BehaviorMachine` (the ``transitions``
    library under it) enters them: the target and every state active under it afterwards
    (a transition to the target's own state, an ancestor or a descendant that is already
    active leaves and enters it again), and every state active afterwards that was not
    before (the branch down to the target, a parallel state's other regions). A state
    between the source and the target that stays active is not entered again.

    Args:
        event: The change's event (``failed`` enters nothing).
        target: The state the transition names (``""``: the root, as ``start`` does).
        before: Active leaf paths before the change.
        after: Active leaf paths after it.
    """
    if event == "failed":
        return set()
    active_before = {p for leaf in before for p in _prefixes(leaf)}
    active_after = {p for leaf in after for p in _prefixes(leaf)}
    return {p for p in active_after if _under(p, target)} | (active_after - active_before)


def _states(logs: AgentLogs, config: AgentConfig) -> list[StateEntry]:
    order = {spec.path: i for i, spec in enumerate(config.machine.walk())} if config.machine else {}
    entries = []
    before: tuple[str, ...] = ()
    for t_s, event, _source, target, active in logs.changes:
        entered = entered_states(event, target, before, active)
        ranked = sorted(entered, key=lambda p: (order.get(p, len(order)), p.count("."), p))
        entries.append(StateEntry(t_s + logs.shift_s, event, active, tuple(ranked)))
        before = active
    return entries


def _tracks(samples: Mapping[str, list[tuple[float, _Sample]]], origin: Origin) -> dict[str, Track]:
    """One track per vehicle on a shared time grid (every arrival), positions held.

    The evaluators pair tracks sample by sample; before a vehicle's first position its
    samples are NaN (no distance passes on them).
    """
    grid = sorted({round(t, _ARRIVAL_DIGITS) for seen in samples.values() for t, _ in seen})
    tracks: dict[str, Track] = {}
    nan = math.nan
    for name, seen in sorted(samples.items()):
        track = Track()
        index = -1
        point = (nan, nan, nan, 0.0, 0.0, 0.0)
        for t_s in grid:
            while index + 1 < len(seen) and round(seen[index + 1][0], _ARRIVAL_DIGITS) <= t_s:
                index += 1
                s = seen[index][1]
                local = to_local(s.lat_deg, s.lon_deg, s.alt_m, origin)
                point = (
                    local.north_m,
                    local.east_m,
                    local.up_m,
                    s.roll_deg,
                    s.pitch_deg,
                    s.yaw_deg,
                )
            track.add(t_s, *point)
        tracks[name] = track
    return tracks


def _position(track: Track | None, t_s: float) -> tuple[float, float, float]:
    found = track.at(t_s) if track is not None else None
    return found if found is not None else (math.nan, math.nan, math.nan)


def _status_rate_hz(config: AgentConfig) -> float:
    """How often the agent sends its Agent Status (1 Hz when its config does not say)."""
    rates = [t.rate_hz for t in config.telemetry if t.message == "agent_status" and t.rate_hz > 0]
    return max(rates, default=1.0)


def _fill(
    merged: list[tuple[float, _Sample]], view: list[tuple[float, _Sample]], gap_s: float
) -> tuple[list[tuple[float, _Sample]], int]:
    """``merged`` with the samples of ``view`` that fall where it has none for over ``gap_s``.

    Between two of its samples over ``gap_s`` apart, or over ``gap_s`` before its first or
    after its last (all of ``view`` when it is empty).

    Returns:
        The samples, in time order, and how many came from ``view``.
    """
    if not merged:
        return list(view), len(view)
    times = [t for t, _ in merged]
    taken = []
    for item in view:
        t_s = item[0]
        i = bisect.bisect_right(times, t_s)
        before = times[i - 1] if i > 0 else t_s
        after = times[i] if i < len(times) else t_s
        if after - before > gap_s:
            taken.append(item)
    return sorted([*merged, *taken], key=lambda item: item[0]), len(taken)


def _find_logs(
    folder: Path, mission: Mission, configs: Mapping[str, AgentConfig], notes: list[str]
) -> dict[str, AgentLogs]:
    """The mission's agents with at least one log in ``folder``, and their files.

    Found by the readers' one rule (:func:`clark_engine.analysis.log_folder.find_log_files`): in
    ``folder``, its ``logs/`` folder and their sub-folders; the agents in the mission's
    order.

    Raises:
        UsageError: The folder does not exist, is not a folder, or cannot be listed.
        LogChecksError: It holds no log of any agent of the mission.
    """
    names = {name: file_names(config) for name, config in configs.items()}
    found = find_log_files(folder, notes, names)
    agents = {name: AgentLogs(name, files=dict(found[name])) for name in configs if found.get(name)}
    strangers = sorted(
        path.name for name, files in found.items() if name not in configs for path in files.values()
    )
    if not agents:
        shown = f" (it holds {', '.join(strangers[:5])})" if strangers else ""
        raise LogChecksError(
            f"{folder}: no log of any agent of mission {mission.name} "
            f"({', '.join(sorted(configs))}){shown}; looked in it, its logs/ folder and "
            "their sub-folders"
        )
    if strangers:
        notes.append(
            f"{folder}: not of an agent of mission {mission.name}, ignored: {', '.join(strangers)}"
        )
    missing = sorted(set(configs) - set(agents))
    if missing:
        notes.append(
            f"{folder}: no log of {', '.join(missing)}; the checks that need them are not evaluated"
        )
    return agents


def _read_logs(
    agents: Mapping[str, AgentLogs], mission: Mission, problems: list[Problem], notes: list[str]
) -> dict[str, dict[str, list[_Sample]]]:
    """Read every agent's files; returns observer -> observed agent -> its arrivals.

    Raises:
        UsageError: A file cannot be read.
        LogChecksError: Every header names another mission.
    """
    fleet: dict[str, dict[str, list[_Sample]]] = {}
    for name, logs in agents.items():
        files = logs.files
        if "mission_log" in files:
            read_mission_log(files["mission_log"], logs, problems)
        if "interface_log" in files:
            read_interface_log(files["interface_log"], logs, problems)
        if "message_log" in files:
            read_message_log(files["message_log"], logs, problems)
        if "fleet_csv" in files:
            fleet[name] = _read_fleet_csv(files["fleet_csv"], logs, problems)
        logged_mission = logs.header.get("mission")
        if logged_mission is not None and logged_mission != mission.name:
            notes.append(
                f"{name}: its logs are of mission {logged_mission!r}, not {mission.name!r}"
            )
    others = [
        n for n, logs in agents.items() if logs.header.get("mission") not in (None, mission.name)
    ]
    if len(others) == len(agents):
        raise LogChecksError(
            f"its logs are of mission {agents[others[0]].header['mission']!r}, not "
            f"{mission.name!r} ({mission.file}); give that mission, or its logs"
        )
    return fleet


def _positions(
    fleet: Mapping[str, Mapping[str, list[_Sample]]],
    agents: Mapping[str, AgentLogs],
    configs: Mapping[str, AgentConfig],
    notes: list[str],
) -> dict[str, list[tuple[float, _Sample]]]:
    """Vehicle -> its positions in mission time: the station's view, gaps filled by others'."""
    observers = sorted(fleet, key=lambda n: (configs[n].role != "mcs", n))
    stations_logged = any(configs[n].role == "mcs" for n in observers)
    samples: dict[str, list[tuple[float, _Sample]]] = {}
    for vehicle in (n for n, c in configs.items() if c.is_vehicle):
        gap_s = GAP_STATUS_PERIODS / _status_rate_hz(configs[vehicle])
        merged: list[tuple[float, _Sample]] = []
        used: list[str] = []
        for observer in observers:
            seen = fleet[observer].get(vehicle)
            if not seen:
                continue
            shift = agents[observer].shift_s
            merged, added = _fill(merged, [(s.arrival_s + shift, s) for s in seen], gap_s)
            if added and used:
                notes.append(
                    f"{vehicle}: {added} position(s) from {observer}'s fleet table, where "
                    f"{' and '.join(used)}'s had none for over {gap_s:g} s"
                )
            elif added and configs[observer].role != "mcs" and stations_logged:
                notes.append(
                    f"{vehicle}: positions from {observer}'s fleet table (no station saw it)"
                )
            used.append(observer)
        if merged:
            samples[vehicle] = merged
    return samples


def rebuild(
    folder: Path,
    mission: Mission,
    configs: Mapping[str, AgentConfig],
    *,
    files: Mapping[str, Mapping[str, Path]] | None = None,
) -> LogRun:
    """Read a folder of a run's logs and rebuild what the run did (see the module's doc).

    Args:
        folder: Where the agents wrote their logs.
        mission: The mission that was run.
        configs: Agent -> its compiled config.
        files: Agent -> config key (``mission_log``...) -> its file, when the caller
            found them already (``clark replay`` also looks in the agents' own
            sub-folders); agents that are not the mission's are left out. None: the
            files named by the configs in ``folder``.

    Raises:
        UsageError: The folder does not exist, is not a folder, or a file cannot be read.
        LogChecksError: The folder holds no log of any of the mission's agents, or only
            logs of another mission.
    """
    problems: list[Problem] = []
    notes: list[str] = []
    if files is None:
        agents = _find_logs(folder, mission, configs, notes)
    else:
        agents = {
            name: AgentLogs(name, files=dict(found))
            for name, found in files.items()
            if name in configs and found
        }
        if not agents:
            raise LogChecksError(f"{folder}: no log of any agent of mission {mission.name}")
    try:
        fleet = _read_logs(agents, mission, problems, notes)
    except LogChecksError as exc:
        raise LogChecksError(f"{folder}: {exc}") from None
    time_origin = align_clocks(agents, {n: c.role for n, c in configs.items()}, notes)
    recording = Recording()
    recording.tracks = _tracks(_positions(fleet, agents, configs, notes), mission.origin)
    for name, logs in agents.items():
        recording.states[name] = _states(logs, configs[name])
        shift = logs.shift_s
        events: list[tuple[float, str]] = []
        if logs.failsafe is not None:
            events.append((logs.failsafe[0] + shift, f"failsafe {logs.failsafe[1]}"))
        if logs.autopilot_lost_s is not None:
            events.append((logs.autopilot_lost_s + shift, "autopilot_lost"))
        if events:
            recording.safety[name] = sorted(events, key=lambda e: e[0])
        if logs.waiting is not None and not recording.states[name]:
            recording.waiting[name] = (logs.waiting,)
        if logs.pictures_s:
            track = recording.tracks.get(name)
            recording.photos[name] = [
                Photo(t + shift, *_position(track, t + shift)) for t in sorted(logs.pictures_s)
            ]
    ends = [logs.latest_s + logs.shift_s for logs in agents.values() if logs.latest_s is not None]
    recording.end_s = max(ends, default=0.0)
    problems.sort(key=lambda p: (p.file, p.line or 0))
    return LogRun(folder, mission, dict(configs), recording, agents, time_origin, problems, notes)


# ------------------------------------------------------------------ judging


def _needs_file(run: LogRun, agent: str, key: str, what: str) -> str | None:
    logs = run.agents.get(agent)
    if logs is None or key not in logs.files:
        file_name = file_names(run.configs[agent])[key] if agent in run.configs else agent
        return f"no {file_name} in the folder ({what})"
    return None


def _needs_level(run: LogRun, agent: str, level: str, what: str) -> str | None:
    logs = run.agents[agent]
    if logs.hides(level):
        return (
            f"{agent}'s logs are at level {logs.level}, which leaves out the {level} lines "
            f"of {what}"
        )
    return None


def _needs_position(run: LogRun, agent: str) -> str | None:
    if agent not in run.recording.tracks:
        return f"no position of {agent} in the logs (no fleet CSV row with its Agent Status)"
    return None


def _needs_safety(run: LogRun, agent: str) -> str | None:
    """Why the safety events of ``agent`` are not known (stations have none)."""
    config = run.configs.get(agent)
    if config is None or not config.is_vehicle:
        return None
    return (
        _needs_file(run, agent, "mission_log", "failsafes are logged there")
        or _needs_file(run, agent, "interface_log", "an autopilot loss is logged there")
        or _needs_level(run, agent, "ERROR", "failsafes and autopilot losses")
    )


def unsupported(check: Mapping[str, Any], run: LogRun) -> str | None:
    """Why ``check`` cannot be judged from these logs, or None when it can."""
    kind = next(k for k in check if k not in ("name", "by_s"))
    body = check[kind]
    if kind == "signal":
        return NO_SIGNALS
    if kind in ("distance_m", "reached", "altitude_m", "ends_at"):
        names = [str(n) for n in body["between"]] if kind == "distance_m" else [str(body["agent"])]
        why = next((w for n in names if (w := _needs_position(run, n)) is not None), None)
        by_s = float(check.get("by_s", run.recording.end_s))
        if why is None and by_s <= run.recording.end_s:
            late = [n for n in names if math.isnan(_position(run.recording.tracks[n], by_s)[0])]
            if late:
                return f"no position of {', '.join(late)} known by {by_s:g} s"
        return why
    if kind == "separation_m":
        names = [str(n) for n in body.get("agents", [])] or [
            n for n, c in run.configs.items() if c.is_vehicle
        ]
        missing = [n for n in names if n not in run.recording.tracks]
        if missing:
            return (
                f"no position of {', '.join(missing)} in the logs (no fleet CSV row with "
                "its Agent Status)"
            )
        return None
    if kind in ("state", "sequence"):
        agent = str(body["agent"])
        return _needs_file(run, agent, "mission_log", "state changes are logged there") or (
            _needs_level(run, agent, "INFO", "state changes")
        )
    if kind == "photos":
        agent = str(body["agent"])
        return _needs_file(run, agent, "message_log", "the Picture Data sent is logged there") or (
            _needs_file(
                run, agent, "mission_log", "pictures taken without a position are logged there"
            )
        )
    if kind == "failsafe":
        return _needs_safety(run, str(body["agent"]))
    if kind == "no_failsafe":
        names = [str(n) for n in body.get("agents", [])] or list(run.configs)
        return next((w for n in names if (w := _needs_safety(run, n)) is not None), None)
    return None


def judge(run: LogRun) -> list[CheckResult]:
    """The mission's checks on the rebuilt run, with the dry run's evaluators.

    A check whose data the logs lack is ``not evaluated``, with the reason.
    """
    checks = run.mission.checks
    results = evaluate(checks, run.recording, run.configs, run.mission.origin)
    out = []
    for check, result in zip(checks, results, strict=True):
        why = unsupported(check, run)
        if why is not None:
            result = CheckResult(
                result.name, result.expected, f"not evaluated: {why}", False, False
            )
        out.append(result)
    return out


def check_folder(folder: Path, mission: Mission) -> LogChecks:
    """Rebuild the run in ``folder`` and judge ``mission``'s checks on it.

    Raises:
        UsageError: The folder or a file in it cannot be read.
        LogChecksError: The folder holds none of the mission's logs.
    """
    from clark_engine.mission.compiler import agent_config
    from clark_engine.runtime.config import config_from_dict

    configs = {
        name: config_from_dict(agent_config(mission, agent))
        for name, agent in mission.agents.items()
    }
    run = rebuild(folder, mission, configs)
    return LogChecks(run, judge(run))


def format_text(checks: LogChecks) -> str:
    """The report: which logs, how the clocks were aligned, then the dry run's checks table."""
    run = checks.run
    lines = [
        f"{run.folder}: mission {run.mission.name}, logs of {len(run.agents)} of "
        f"{len(run.configs)} agents ({', '.join(sorted(run.agents))}); "
        f"{run.recording.end_s:.1f} s of mission time",
        f"time: {run.time_origin}",
    ]
    for name, logs in sorted(run.agents.items()):
        lines.append(f"  {name}: {logs.clock}")
    lines.append("")
    table = checks_table(checks.results) if checks.results else "the mission declares no checks\n"
    return "\n".join(lines) + "\n" + table


def run_log_checks(
    folder: Path,
    mission_path: Path,
    *,
    json_format: bool = False,
    quiet: bool = False,
    out: TextIO | None = None,
    err: TextIO | None = None,
) -> int:
    """``clark analyze LOGDIR --checks MISSION``: print the checks; returns the exit code.

    0 when every evaluated check holds, 1 when one fails or the mission is invalid.
    ``quiet`` hides warnings: the mission's, and the logs' (rows skipped, clocks).

    Raises:
        UsageError: The mission or a log cannot be read, or the folder does not exist (2).
        LogChecksError: The folder holds none of the mission's logs (1).
    """
    from clark_engine.mission.validate import validate_path

    out = sys.stdout if out is None else out
    err = sys.stderr if err is None else err
    validation = validate_path(mission_path, str(mission_path))
    if validation.kind != "mission" and validation.ok:
        raise UsageError(f"--checks {mission_path} is a {validation.kind}, not a mission")
    for finding in validation.findings:
        if finding.is_error or not quiet:
            print(finding.format_text(), file=err)
    mission = validation.mission
    if mission is None:
        print(f"{mission_path}: invalid; no check evaluated", file=err)
        return 1
    checks = check_folder(folder, mission)
    for warning in [] if quiet else checks.run.warnings():
        print(f"clark analyze: warning: {warning}", file=err)
    if json_format:
        out.write(json.dumps(checks.to_json(), indent=2) + "\n")
    else:
        out.write(format_text(checks))
    total = len(checks.results)
    if checks.skipped:
        print(
            f"{len(checks.skipped)} of {total} checks not evaluated (the table says why)", file=err
        )
    if checks.failed:
        print(f"{len(checks.failed)} of {total} checks failed", file=err)
    return 1 if checks.failed else 0
