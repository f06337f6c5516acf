"""Reading a run's log files, one kind at a time, into each agent's :class:`AgentLogs`.

Why separate: ``clark analyze --checks`` (:mod:`clark_engine.expectations.from_logs`) and
``clark replay`` (:mod:`clark_engine.station.replay`) read the same four files of each agent
(``<agent>.mission.log``, ``<agent>.interface.log``, ``<agent>.fleet.csv``,
``<agent>.messages.csv``, named by its compiled config: :func:`file_names`); what a line or a
row means is said once, here, on the agent's own clock. Putting the agents on one clock is
:mod:`clark_engine.expectations.log_clocks`'s, and rebuilding the run from what was read
:mod:`clark_engine.expectations.log_run`'s.

Lines are told apart by the event they name (docs/logs.md, "Events"), never by the code
that wrote them; logs written before events named ``module.function`` instead, and the
names the readers need are read as their events
(:data:`~clark_engine.runtime.log_events.LEGACY_NAMES`).

A row or line that cannot be read is a warning with its file and line, and is
skipped; the rest is still evaluated.
"""

from __future__ import annotations

import math
import re
from collections.abc import Iterator, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Final

from clark_engine.analysis.latency import Problem, csv_rows, open_log
from clark_engine.analysis.log_folder import LOG_FILES
from clark_engine.errors import UsageError
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
ARRIVAL_DIGITS: Final = 6


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
class FleetSample:
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


def read_fleet_csv(
    path: Path, logs: AgentLogs, problems: list[Problem]
) -> dict[str, list[FleetSample]]:
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
    seen: dict[str, dict[float, FleetSample]] = {}
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
            key = round(arrival, ARRIVAL_DIGITS)
            arrivals = seen.setdefault(peer, {})
            if key in arrivals:
                continue
            arrivals[key] = FleetSample(
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
