"""The station view's copy of the station's mission log: the newest lines, escaped.

Separate because it is a :class:`logging.Handler` attached to the runtime's mission
logger, a thing of its own: the live view sends its lines to the page, and the command
desk (:mod:`clark_engine.station.view_commands`) reads the runtime's answer to a command
in them.
"""

from __future__ import annotations

import logging
from collections import deque
from dataclasses import dataclass

from clark_engine.runtime.log_events import RECORD_ATTRIBUTE, UNDECLARED
from clark_engine.runtime.log_lines import line_safe
from clark_engine.station.view_protocol import MAX_LOG_LINES, MAX_LOG_TEXT_CHARS, Json, rounded

# -- the mission log -------------------------------------------------------------------------


@dataclass(frozen=True, slots=True)
class LogLine:
    """One mission-log line as the view holds it.

    Attributes:
        seq: Its sequence number (1, 2, ...), for the page to ask for what it lacks.
        now_s: The station's runtime time it was logged at.
        level: ``INFO``, ``WARNING``...
        text: The message, escaped (no control character) and at most
            :data:`MAX_LOG_TEXT_CHARS` long.
        event: The event it records (:mod:`clark_engine.runtime.log_events`; not sent
            to the page; used to tell the runtime's answer to a command).
        levelno: The numeric level (not sent).
    """

    seq: int
    now_s: float
    level: str
    text: str
    event: str
    levelno: int

    def to_json(self) -> Json:
        """The line as the page receives it."""
        return {
            "seq": self.seq,
            "t": rounded(self.now_s, 3),
            "level": self.level,
            "text": self.text,
        }


class MissionLogBuffer(logging.Handler):
    """A copy of the station's mission-log lines, the newest :data:`MAX_LOG_LINES`.

    Added to the logbook's mission logger (:attr:`~clark_engine.runtime.logbook.Logbook.mission`),
    as the logbook's docstring invites a shell to; the logbook's own filter has already
    escaped every argument, and the line is escaped again and cut here, so nothing
    received over the air reaches the page as markup or a forged line (the page also
    writes it as text, never as HTML).

    Args:
        max_lines: How many lines are held; older ones are dropped.
    """

    def __init__(self, max_lines: int = MAX_LOG_LINES) -> None:
        super().__init__(level=logging.NOTSET)
        self.lines: deque[LogLine] = deque(maxlen=max_lines)
        self.seq = 0
        self._logger: logging.Logger | None = None

    def attach(self, logger: logging.Logger) -> None:
        """Start copying ``logger``'s lines."""
        self.detach()
        logger.addHandler(self)
        self._logger = logger

    def detach(self) -> None:
        """Stop copying."""
        if self._logger is not None:
            self._logger.removeHandler(self)
            self._logger = None

    def emit(self, record: logging.LogRecord) -> None:
        """Keep one line (never raises into the logging call)."""
        try:
            text = record.getMessage()
        except Exception:  # a bad format must not break the station's loop
            text = str(record.msg)
        self.seq += 1
        self.lines.append(
            LogLine(
                self.seq,
                float(getattr(record, "clark_now_s", 0.0)),
                record.levelname,
                line_safe(text, MAX_LOG_TEXT_CHARS),
                str(getattr(record, RECORD_ATTRIBUTE, UNDECLARED)),
                record.levelno,
            )
        )

    def since(self, seq: int) -> list[LogLine]:
        """The lines held with a sequence number above ``seq``, oldest first."""
        return [line for line in self.lines if line.seq > seq]


__all__ = ["LogLine", "MissionLogBuffer"]
