"""What one agent writes down: two text logs and two CSV files (thesis 2.4.1-2.4.4, 7.3.6).

One :class:`Logbook` per agent, owned by its runtime and never shared:

- the **mission log** (thesis 2.4.2: high level, what the mission does) and the
  **interface log** (2.4.1: low level, what the autopilot, radio and payloads
  do), through two standard :class:`logging.Logger` objects, :attr:`Logbook.mission`
  and :attr:`Logbook.interface`, at the level the mission sets (2.4.3). Each line
  starts with the time, the level and the event it records (2.4.4 asked for the module
  and the function; a stable event name serves the same reader and survives moving the
  code, :mod:`clark_engine.runtime.log_events`)::

      t=65.043 gps_ms=1451260883043 INFO behavior.change: activate: idle -> chase (active: chase)

  The time is the *runtime's* clock (``now_s``, virtual in a dry run) and the
  GPS time when known, never the wall clock, so a dry run writes the same bytes
  for the same seed. The runtime sets it with :meth:`Logbook.set_time` before it
  logs anything in a call.
- the **fleet CSV** (7.3.6): the fleet table's rows every tick (:meth:`Logbook.fleet_row`);
- the **message log**: one row per message sent or received and per packet
  rejected (:meth:`Logbook.message`), which ``clark analyze`` turns into the
  thesis's latency tables (section 5.1.2).

Decisions:

- **The loggers are private to the logbook**, built as ``logging.Logger`` objects
  and never registered with ``logging.getLogger``: two agents in one process
  (a dry run) cannot share a logger or its handlers, a second run of the same
  agent in one process cannot inherit the first one's, and a
  ``logging.config.dictConfig`` elsewhere (whose default disables every
  registered logger) cannot silence them. They never propagate, so nothing
  reaches the root logger. Their names still read
  ``clark.<mission>.<agent>.mission`` and ``...interface`` for
  ``%(name)s``. A shell that wants a copy of the lines (a console) adds a
  handler to :attr:`Logbook.mission` itself, or builds the logbook on its own
  streams.
- **Call the loggers directly, naming the event** (``logbook.mission.info("found %s",
  name, extra=LogEvent.FLEET_FOUND.extra)``): they stay standard loggers that
  primitives and adapters take as ``logging.Logger``. A call without an event writes
  ``undeclared``; ``tests/test_log_events.py`` fails on such a call.
- **Every line and every CSV row is written whole and flushed at once**, so a
  process that is killed leaves every completed line and row intact.
- **The first line of each text log is a header**, written whatever the level:
  it names the mission, the agent and the loop period (``period_s=0.1``), from
  which ``clark analyze`` takes the sample period.
- **The key never reaches the logbook**: it is built from the config, which
  holds only the key file's name, and nothing here reads key material.
- **Nothing from outside can write a line**: strings that arrive over the air (a
  Terminate's reason, a claimed sender) reach the logs as arguments, and the logbook
  escapes every string argument, every CSV text cell and any message that is not
  printable (:func:`line_safe`): no newline, no control character, bounded length.
  The CSV files are written by the csv module, which quotes delimiters and quotes.
- **What a packet makes the logbook write is counted, not written one by one**
  (:meth:`Logbook.from_air`): anyone in range can send packets at the radio's full rate,
  and on a mission without a key nothing tells a forger from a genuine agent, so a line
  per packet would fill the disk. One rate limiter serves every per-packet line: rejected
  packets (:meth:`Logbook.rejected`), packets from agents not in the mission, commands
  not obeyed or coalesced, the station's commands. Per kind of line (:data:`AIR_KINDS`),
  the first :data:`AIR_LINES_PER_INTERVAL` of each :data:`AIR_SUMMARY_S` are written
  whole; the interval ends with one summary line per kind of counts per reason and per
  claimed sender ("240 more packets from agents not in the mission in the last 10.0 s,
  not logged one by one"). Each kind has its own allowance, so a flood of one kind
  cannot hide the few lines of another (a genuine station's activation).

Over 800 lines because the four files and the air's allowance are one agent's one record
(one clock, one set of handles, one flush on close); the allowance, the one seam left,
is called from some twenty places as ``logbook.from_air`` and moving it would only
change those calls.
"""

from __future__ import annotations

import csv
import io
import logging
import math
import sys
import threading
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Literal, TextIO

from clark_engine import __version__
from clark_engine.errors import ClarkError
from clark_engine.runtime.config import AgentConfig
from clark_engine.runtime.log_events import RECORD_ATTRIBUTE, UNDECLARED, LogEvent
from clark_engine.runtime.log_lines import (
    MAX_LOGGED_LINE_CHARS,
    line_safe,
    plain_cell,
    plain_lines,
    safe_arg,
)

#: Per-packet lines from the air are summarised once per this many seconds (runtime clock).
AIR_SUMMARY_S = 10.0
#: Per-packet lines from the air written whole in each summary interval, per kind of line
#: (:data:`AIR_KINDS`); the rest are only counted in the interval's summary.
AIR_LINES_PER_INTERVAL = 10
#: The rejections' names for the same limits (a rejected packet is one kind of line).
REJECTION_SUMMARY_S = AIR_SUMMARY_S
REJECTIONS_LOGGED_PER_INTERVAL = AIR_LINES_PER_INTERVAL
#: Distinct claimed senders counted apart in one summary; the rest are counted together
#: (a sender id is whatever the packet claims, so their number is the sender's choice).
MAX_SUMMARY_SENDERS = 8

AirKind = Literal["rejected", "unknown", "received", "ignored", "command"]


@dataclass(frozen=True, slots=True)
class _AirKindSpec:
    """Where one kind of per-packet line goes, and how its summary names what it counts."""

    log: Literal["mission", "interface"]
    what: str
    per_sender: bool = False
    """The allowance is each sender's (the caller's, and only for a bounded set of senders:
    the mission's agents), not the kind's."""


#: The kinds of per-packet lines from the air (:meth:`Logbook.from_air`): the log the
#: lines and their summary go to, and what the summary counts.
AIR_KINDS: dict[str, _AirKindSpec] = {
    "rejected": _AirKindSpec("interface", "packets rejected"),
    "unknown": _AirKindSpec("interface", "packets from agents not in the mission"),
    "received": _AirKindSpec(
        "interface", "packets from mission agents beyond their configured rates", per_sender=True
    ),
    "ignored": _AirKindSpec("mission", "commands not obeyed (not from a station)"),
    "command": _AirKindSpec("mission", "station commands"),
}


@dataclass(slots=True)
class _AirTally:
    """One kind of per-packet line in the current summary interval."""

    total: int = 0
    logged: int = 0
    size_bytes: int = 0
    reasons: dict[str, int] = field(default_factory=dict)
    senders: dict[str, int] = field(default_factory=dict)
    logged_by: dict[str, int] = field(default_factory=dict)  # per_sender kinds only


#: Columns of the message log, in order (see docs/logs.md).
MESSAGE_LOG_COLUMNS: tuple[str, ...] = (
    "direction",
    "now_s",
    "gps_time_ms",
    "peer",
    "counter",
    "size_bytes",
    "message_type",
    "message_gps_time_ms",
    "latency_ms",
    "detail",
)

#: The ``peer`` of a message sent to every agent.
BROADCAST_PEER = "*"

#: The values of the message log's ``direction`` column.
DIRECTIONS: tuple[str, ...] = ("sent", "received", "rejected")

Direction = Literal["sent", "received", "rejected"]

#: Format of every text log line; the ``clark_*`` fields come from the logbook's clock and
#: the event the call declared (:mod:`clark_engine.runtime.log_events`), never from where
#: the code that logged it lives.
LINE_FORMAT = (
    "t=%(clark_now_s).3f gps_ms=%(clark_gps_ms)s %(levelname)s %(clark_event)s: %(message)s"
)

_LOG_KEYS = ("mission_log", "interface_log", "fleet_csv", "message_log")
_CsvCell = str | int | float


class LogbookError(ClarkError):
    """A logbook that cannot be opened: a folder or file that cannot be written."""


@dataclass(frozen=True, slots=True)
class LogStreams:
    """The four text streams a logbook writes to.

    Attributes:
        mission: The mission log.
        interface: The interface log.
        fleet: The fleet CSV.
        messages: The message log CSV.
    """

    mission: TextIO
    interface: TextIO
    fleet: TextIO
    messages: TextIO

    def all(self) -> tuple[TextIO, TextIO, TextIO, TextIO]:
        """The four streams, in a fixed order."""
        return (self.mission, self.interface, self.fleet, self.messages)


class _Stamp(logging.Filter):
    """Adds the logbook's current runtime time to every record its loggers handle, escaped.

    A logger filter, not a handler one, so that a handler a shell adds to the
    logger sees the same fields. It also makes the record one safe line: every
    string argument through :func:`line_safe`, and the message itself when it is
    not printable (a caller that formatted received text into it).
    """

    def __init__(self, logbook: Logbook) -> None:
        super().__init__()
        self._logbook = logbook

    def filter(self, record: logging.LogRecord) -> bool:
        logbook = self._logbook
        record.clark_now_s = logbook.now_s
        gps_ms = logbook.gps_time_ms
        record.clark_gps_ms = "-" if gps_ms is None else gps_ms
        if not hasattr(record, RECORD_ATTRIBUTE):
            setattr(record, RECORD_ATTRIBUTE, UNDECLARED)
        args = record.args
        if args:
            if isinstance(args, tuple):
                record.args = tuple(safe_arg(a) for a in args)
            else:  # a mapping, for %(name)s formats
                record.args = {k: safe_arg(v) for k, v in args.items()}
        msg = record.msg
        if isinstance(msg, str) and not msg.isprintable():
            record.msg = line_safe(msg, MAX_LOGGED_LINE_CHARS)
        return True


class _AgentLogger(logging.Logger):
    """A logger outside logging's registry whose level changes take effect at once.

    ``logging.Logger`` caches its level decisions and relies on the registry to
    clear the cache when a level changes; an unregistered logger would keep a
    stale answer after :meth:`setLevel` or :func:`logging.disable`. This one
    decides afresh each time (a comparison or two).
    """

    def isEnabledFor(self, level: int) -> bool:
        """True when a record at ``level`` would be handled."""
        if self.disabled or self.manager.disable >= level:
            return False
        return level >= self.getEffectiveLevel()


class _Handler(logging.StreamHandler[TextIO]):
    """A stream handler that counts write failures on its logbook instead of printing them.

    logging's default prints a traceback to stderr per failed line; a full disk
    would flood the console of the computer flying the mission.
    """

    def __init__(self, stream: TextIO, logbook: Logbook) -> None:
        super().__init__(stream)
        self._logbook = logbook

    def handleError(self, record: logging.LogRecord) -> None:
        """Count the failure; the loop goes on."""
        exc = sys.exc_info()[1]
        self._logbook._write_failed(f"{record.name}: {exc}")


def _csv_text(
    now_s: float,
    header: Sequence[str] | None,
    rows: Sequence[Sequence[_CsvCell]],
    *,
    plain: bool,
) -> str:
    """The fleet CSV's lines for one tick: the header when given, then ``now_s`` and each row.

    With ``plain``, line breaks inside text cells become spaces
    (:func:`~clark_engine.runtime.log_lines.plain_cell`).
    """
    buffer = io.StringIO()
    writer = csv.writer(buffer, lineterminator="\n")
    if header is not None:
        writer.writerow(["now_s", *header])
    now = repr(now_s)  # as the csv module writes a float, once for every row of the tick
    if plain:
        writer.writerows(
            [now, *(plain_cell(c) if isinstance(c, str) else c for c in row)] for row in rows
        )
    else:
        writer.writerows([now, *row] for row in rows)
    return buffer.getvalue()


def _cell(value: int | float | None) -> _CsvCell:
    """An absent figure as an empty cell."""
    return "" if value is None else value


class Logbook:
    """One agent's mission log, interface log, fleet CSV and message log.

    Build it with :meth:`to_folder` (a flight or a dry run) or :meth:`in_memory`
    (tests, and shells that route the text elsewhere); the constructor takes
    any four text streams.

    The loop that owns it is single-threaded by design; still, each CSV row and
    each log line is written under a lock, so a shell's reader thread may log
    too (its lines carry the loop's latest :meth:`set_time`).

    A write that fails (a full disk) is counted in :attr:`write_errors`, never
    raised: losing a log must not stop the loop that flies the vehicles.

    Args:
        config: The agent's compiled config: names, loop rate and log level.
        streams: Where the four files go.
        close_streams: True when :meth:`close` closes the streams (the logbook
            opened them); False leaves them open for their owner to read.

    Attributes:
        mission: The mission log's logger (thesis 2.4.2).
        interface: The interface log's logger (thesis 2.4.1).
        streams: The four streams.
        now_s: The runtime time stamped on log lines, from :meth:`set_time`.
        gps_time_ms: The GPS time stamped on log lines, None while unknown.
        write_errors: Lines and rows that could not be written.
        last_write_error: What the latest failure was, for the runtime to report.
    """

    def __init__(
        self, config: AgentConfig, streams: LogStreams, *, close_streams: bool = False
    ) -> None:
        levels = logging.getLevelNamesMapping()
        if config.log_level not in levels:
            raise ValueError(f"log level {config.log_level!r} is not a logging level name")
        self.config = config
        self.streams = streams
        self.now_s = 0.0
        self.gps_time_ms: int | None = None
        self._close_streams = close_streams
        self._closed = False
        self._csv_lock = threading.Lock()
        self._fleet_header: list[str] | None = None
        self.write_errors = 0
        self.last_write_error: str | None = None
        #: True while per-packet lines from the air are counted for a summary not yet
        #: written (:meth:`from_air`).
        self.air_pending = False
        self._air_since_s = 0.0
        self._air: dict[str, _AirTally] = {}
        #: False when fleet CSV and message log rows are dropped unformatted.
        self.tables = True
        #: Called in order as the logbook closes, before anything is flushed: what its
        #: owner writes last (the runtime's envelope summary), whoever closes it (a
        #: terminate, the real-time shell, the end of a dry run).
        self.closing: list[Callable[[], None]] = []
        level = levels[config.log_level]
        prefix = f"clark.{config.mission_name}.{config.agent}"
        formatter = logging.Formatter(LINE_FORMAT)
        stamp = _Stamp(self)
        self._handlers: list[logging.Handler] = []
        self.mission = self._logger(f"{prefix}.mission", level, streams.mission, formatter, stamp)
        self.interface = self._logger(
            f"{prefix}.interface", level, streams.interface, formatter, stamp
        )
        period_s = 1.0 / config.loop_hz
        header = (
            f"logbook opened: clark_engine={__version__} mission={config.mission_name} "
            f"mission_id={config.mission_id} agent={config.agent} agent_id={config.agent_id} "
            f"role={config.role} loop_hz={config.loop_hz!r} period_s={period_s!r} "
            f"level={config.log_level}"
        )
        for logger in (self.mission, self.interface):
            # Logger.handle runs the filters and handlers but not the level check:
            # the header is written whatever the level.
            logger.handle(
                logger.makeRecord(
                    logger.name,
                    logging.INFO,
                    __file__,
                    0,
                    header,
                    (),
                    None,
                    func="__init__",
                    extra=LogEvent.LOG_OPEN.extra,
                )
            )
        self._write(self.streams.messages, ",".join(MESSAGE_LOG_COLUMNS) + "\n")

    def _logger(
        self,
        name: str,
        level: int,
        stream: TextIO,
        formatter: logging.Formatter,
        stamp: logging.Filter,
    ) -> logging.Logger:
        """A logger of this logbook alone: unregistered, not propagating, one handler."""
        logger = _AgentLogger(name, level)
        logger.propagate = False
        logger.addFilter(stamp)
        handler = _Handler(stream, self)  # flushes after every record
        handler.setFormatter(formatter)
        logger.addHandler(handler)
        self._handlers.append(handler)
        return logger

    # ------------------------------------------------------------ factories

    @classmethod
    def to_folder(cls, folder: Path, config: AgentConfig, *, overwrite: bool = False) -> Logbook:
        """Open the four files the config names in ``folder``, creating the folder.

        Args:
            folder: Where the files go (one folder per run).
            config: The agent's compiled config; ``log_files`` names the files.
            overwrite: Replace files of an earlier run. By default an existing file
                is an error, so that a flight's logs are never lost to the next run.

        Raises:
            LogbookError: The folder cannot be created, a file exists (without
                ``overwrite``) or cannot be opened, or a file name in the config
                is not a plain file name. Nothing is left behind: files already
                opened are closed and removed.
        """
        names: list[str] = []
        for key in _LOG_KEYS:
            name = config.log_files.get(key)
            if not name or Path(name).name != name or name in (".", ".."):
                raise LogbookError(
                    f"log.{key} is {name!r}, not a plain file name; compile the mission again",
                    file=str(folder),
                )
            names.append(name)
        try:
            folder.mkdir(parents=True, exist_ok=True)
        except OSError as exc:
            raise LogbookError(
                f"cannot create the log folder: {exc.strerror or exc}", file=str(folder)
            ) from None
        mode: Literal["w", "x"] = "w" if overwrite else "x"
        opened: list[tuple[Path, TextIO]] = []
        try:
            for name in names:
                path = folder / name
                # newline="": lines end in "\n" on every platform, as the CSV module needs.
                opened.append((path, open(path, mode, encoding="utf-8", newline="")))  # noqa: SIM115
        except OSError as exc:
            for path, stream in opened:
                stream.close()
                path.unlink(missing_ok=True)
            where = exc.filename or folder
            if isinstance(exc, FileExistsError):
                raise LogbookError(
                    "exists, from an earlier run; log to a new folder, or overwrite on purpose",
                    file=str(where),
                ) from None
            raise LogbookError(f"cannot open it: {exc.strerror or exc}", file=str(where)) from None
        streams = LogStreams(*(stream for _, stream in opened))
        return cls(config, streams, close_streams=True)

    @classmethod
    def in_memory(cls, config: AgentConfig, *, tables: bool = True) -> Logbook:
        """A logbook on four ``io.StringIO`` streams, readable after :meth:`close`.

        Args:
            config: The agent's compiled config.
            tables: False drops the fleet CSV and message log rows without formatting
                them (a dry run nobody asked a report of: with 50 agents the fleet table
                alone is 25,000 rows a simulated second); the text logs are kept.
        """
        logbook = cls(
            config,
            LogStreams(io.StringIO(), io.StringIO(), io.StringIO(), io.StringIO()),
            close_streams=False,
        )
        logbook.tables = tables
        return logbook

    # ----------------------------------------------------------------- time

    def set_time(self, now_s: float, gps_time_ms: int | None) -> None:
        """Set the time stamped on the lines logged from now on.

        The runtime calls it at the start of each call (tick, delivery), before
        it logs anything.

        Args:
            now_s: The runtime clock, seconds since the runtime started.
            gps_time_ms: The best estimate of GPS time now, None while unknown.
        """
        self.now_s = now_s
        self.gps_time_ms = gps_time_ms

    # ------------------------------------------------------------------ CSV

    def _write(self, stream: TextIO, text: str) -> None:
        """Write whole rows and flush them, so a killed process leaves them complete.

        A failed write (a full disk, a removed USB stick) is counted, never
        raised: losing a log must not stop the loop that flies the vehicles.
        """
        if self._closed:
            raise ValueError("the logbook is closed")
        try:
            stream.write(text)
            stream.flush()
        except OSError as exc:
            self._write_failed(f"{getattr(stream, 'name', 'stream')}: {exc.strerror or exc}")

    def _write_failed(self, what: str) -> None:
        """Count a write that failed; the runtime reports :attr:`write_errors`."""
        self.write_errors += 1
        self.last_write_error = what

    def fleet_row(
        self, now_s: float, header: Sequence[str], rows: Sequence[Sequence[_CsvCell]]
    ) -> None:
        """Append one tick of the fleet table to the fleet CSV (thesis 7.3.6).

        The header (``now_s`` and ``header``) is written on the first call, even
        when there are no rows yet; each row is ``now_s`` and one of ``rows``.

        Args:
            now_s: The runtime clock at this tick.
            header: Column names, :meth:`FleetTable.csv_header`.
            rows: One row per agent, :meth:`FleetTable.csv_rows`.

        Raises:
            ValueError: ``header`` is not the one of the first call, or a row has
                another number of cells: the file would be unreadable.
        """
        if not self.tables:
            return
        width = len(header)
        for row in rows:
            if len(row) != width:
                raise ValueError(f"fleet CSV row has {len(row)} cells for {width} columns")
        with self._csv_lock:
            lines = len(rows)
            first = self._fleet_header is None
            if first:
                self._fleet_header = list(header)
                lines += 1
            elif self._fleet_header != list(header):
                raise ValueError("fleet CSV header changed after the first row")
            # Every tick writes a row per agent (a 50-agent fleet: 500 rows a second per
            # agent), so the rows are written as they are and only re-written cell by cell
            # in the rare case that a cell would have broken a line.
            text = _csv_text(now_s, header if first else None, rows, plain=False)
            if not plain_lines(text, lines):
                text = _csv_text(now_s, header if first else None, rows, plain=True)
            self._write(self.streams.fleet, text)

    def message(
        self,
        direction: Direction,
        now_s: float,
        gps_time_ms: int | None,
        peer: str,
        counter: int | None,
        size_bytes: int,
        message_type: str = "",
        message_gps_time_ms: int | None = None,
        latency_ms: float | None = None,
        detail: str = "",
    ) -> None:
        """Append one row to the message log.

        One row per message of a packet sent or received (a bundle of three is
        three rows with the same counter), and one per packet rejected.

        Args:
            direction: ``sent``, ``received`` or ``rejected``.
            now_s: The runtime clock when it was sent or arrived.
            gps_time_ms: This agent's GPS time then, None while unknown.
            peer: Sent: the destination's name, or :data:`BROADCAST_PEER` for every
                agent. Received and rejected: the sender's name; for an agent not
                in the mission, its id in digits (names start with a letter); empty
                when the header was unreadable.
            counter: The packet counter; None for a rejected packet whose header
                could not be read.
            size_bytes: The packet's size on the wire.
            message_type: The message name (``agent_status``); for a rejected packet,
                the error's class name (``BadTag``) or empty.
            message_gps_time_ms: The message's GPS stamp; None for a rejected packet.
            latency_ms: Received only: ``gps_time_ms - message_gps_time_ms``, or None
                when either is unknown or the stamp is not a send time (Picture Data).
            detail: Free text; for a rejected packet, why (``BadTag: tag does not match``).

        Raises:
            ValueError: ``direction`` is not one of :data:`DIRECTIONS`, or
                ``latency_ms`` is not finite.
        """
        if not self.tables:
            return
        if direction not in DIRECTIONS:
            raise ValueError(f"direction must be one of {', '.join(DIRECTIONS)}, not {direction!r}")
        if latency_ms is not None and not math.isfinite(latency_ms):
            raise ValueError(f"latency_ms must be finite, not {latency_ms!r}")
        buffer = io.StringIO()
        writer = csv.writer(buffer, lineterminator="\n")
        with self._csv_lock:
            writer.writerow(
                (
                    direction,
                    now_s,
                    _cell(gps_time_ms),
                    plain_cell(peer),
                    _cell(counter),
                    size_bytes,
                    plain_cell(message_type),
                    _cell(message_gps_time_ms),
                    _cell(latency_ms),
                    plain_cell(detail),
                )
            )
            self._write(self.streams.messages, buffer.getvalue())

    # ------------------------------------------------------- lines from the air

    def from_air(
        self,
        now_s: float,
        kind: AirKind,
        peer: str,
        size_bytes: int = 0,
        reason: str = "",
        allowance: int = AIR_LINES_PER_INTERVAL,
    ) -> bool:
        """Count one per-packet event from the air; True while its line may be written whole.

        The one rate limiter of every line a packet makes the logbook write. The caller
        writes its line (or message-log rows) only when this returns True: the first
        :data:`AIR_LINES_PER_INTERVAL` of each kind in each :data:`AIR_SUMMARY_S`
        interval. Every one is counted, per reason and per claimed sender, and
        :meth:`summarise_air` writes the interval's summary. So a flood costs a bounded
        number of bytes of log per interval, whatever its rate and whether or not the
        mission has a key. O(1) time; the memory is bounded by
        :data:`MAX_SUMMARY_SENDERS` senders and the caller's fixed set of reasons.

        Args:
            now_s: The runtime clock when it arrived.
            kind: Which kind of line (:data:`AIR_KINDS`).
            peer: The sender the packet claims (a name, ``#id``), empty when unreadable.
            size_bytes: The packet's size on the wire, 0 when it does not apply.
            reason: What happened to it (``BadTag``, ``coalesced``), from a fixed set.
            allowance: Lines written whole per interval: the kind's, or for a kind
                counted per sender (``received``) this sender's.
        """
        if self.air_pending and now_s - self._air_since_s >= AIR_SUMMARY_S:
            self.summarise_air(now_s)
        if not self.air_pending:
            self.air_pending = True
            self._air_since_s = now_s
        tally = self._air.get(kind)
        if tally is None:
            tally = self._air[kind] = _AirTally()
        tally.total += 1
        tally.size_bytes += size_bytes
        if reason:
            tally.reasons[reason] = tally.reasons.get(reason, 0) + 1
        senders = tally.senders
        sender = peer or "(unreadable)"
        if sender not in senders and len(senders) >= MAX_SUMMARY_SENDERS:
            sender = "(others)"
        senders[sender] = senders.get(sender, 0) + 1
        if AIR_KINDS[kind].per_sender:
            logged = tally.logged_by.get(peer, 0)
            if logged >= allowance:
                return False
            tally.logged_by[peer] = logged + 1
        elif tally.logged >= allowance:
            return False
        tally.logged += 1
        return True

    def summarise_air(self, now_s: float, *, force: bool = False) -> None:
        """Write the summaries of the lines counted, once their interval is over.

        Rejected packets get their summary line whenever any was counted (it is the
        only record of their number); every other kind only when some of its lines were
        not written whole.

        Args:
            now_s: The runtime clock now.
            force: Write them now, interval over or not (closing the logbook).
        """
        if not self.air_pending:
            return
        elapsed_s = now_s - self._air_since_s
        if elapsed_s < AIR_SUMMARY_S and not force:
            return
        for kind, tally in self._air.items():
            senders = ", ".join(
                f"{s} {n}" for s, n in sorted(tally.senders.items(), key=lambda i: -i[1])
            )
            reasons = ", ".join(f"{r} {n}" for r, n in sorted(tally.reasons.items()))
            unlogged = tally.total - tally.logged
            if kind == "rejected":
                self.interface.warning(
                    "rejected %d packets (%d bytes) in %.1f s, %d of them not logged one by "
                    "one; by reason: %s; by claimed sender: %s",
                    tally.total,
                    tally.size_bytes,
                    elapsed_s,
                    unlogged,
                    reasons,
                    senders,
                    extra=LogEvent.AIR_SUMMARY.extra,
                )
                continue
            if not unlogged:
                continue
            spec = AIR_KINDS[kind]
            logger = self.mission if spec.log == "mission" else self.interface
            logger.warning(
                "%d more %s in the last %.1f s, not logged one by one (%d in all%s); "
                "by claimed sender: %s",
                unlogged,
                spec.what,
                elapsed_s,
                tally.total,
                f"; {reasons}" if reasons else "",
                senders,
                extra=LogEvent.AIR_SUMMARY.extra,
            )
        self.air_pending = False
        self._air = {}

    def rejected(
        self,
        now_s: float,
        gps_time_ms: int | None,
        peer: str,
        size_bytes: int,
        reason: str,
        detail: str,
    ) -> None:
        """Count a rejected packet; write it only while this interval's allowance lasts.

        Through :meth:`from_air` (kind ``rejected``): the first
        :data:`AIR_LINES_PER_INTERVAL` rejections of each :data:`AIR_SUMMARY_S`
        interval get an interface-log line and a message-log row (``rejected``); every
        one is counted, per reason and per claimed sender, in the interval's summary.

        Args:
            now_s: The runtime clock when it arrived.
            gps_time_ms: This agent's GPS time then, None while unknown.
            peer: The sender its header claims (a name, ``#id``), empty when unreadable.
            size_bytes: The packet's size on the wire.
            reason: Why, the error's class name (``BadTag``).
            detail: The error's text.
        """
        if not self.from_air(now_s, "rejected", peer, size_bytes, reason):
            return
        self.interface.info(
            "rejected %d bytes from %s: %s",
            size_bytes,
            peer or "(unreadable)",
            reason,
            extra=LogEvent.AIR_REJECTED.extra,
        )
        self.message(
            "rejected", now_s, gps_time_ms, peer, None, size_bytes, reason, None, None, detail
        )

    # ---------------------------------------------------------------- close

    @property
    def closed(self) -> bool:
        """True after :meth:`close`."""
        return self._closed

    def close(self) -> None:
        """Flush everything and close the files (terminate, thesis 7.3.5). Idempotent.

        After this the loggers are disabled: a late line is dropped, not sent to
        stderr by logging's last resort, and the CSV writers raise ValueError.
        """
        if self._closed:
            return
        closing, self.closing = self.closing, []
        for last_words in closing:
            last_words()
        self.summarise_air(self.now_s, force=True)
        with self._csv_lock:
            self._closed = True
        for logger, handler in zip((self.mission, self.interface), self._handlers, strict=True):
            logger.removeHandler(handler)
            logger.disabled = True
            handler.flush()
            handler.close()  # a StreamHandler never closes its stream
        for stream in self.streams.all():
            try:
                stream.flush()
                if self._close_streams:
                    stream.close()
            except OSError as exc:
                self._write_failed(f"{getattr(stream, 'name', 'stream')}: {exc.strerror or exc}")

    def __enter__(self) -> Logbook:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()
