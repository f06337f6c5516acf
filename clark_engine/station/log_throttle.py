"""The station view's floods of log lines, one line per kind per interval with a count.

Separate from the server because it is a concern of its own: anyone who reaches the
view's port can make aiohttp and asyncio log (bad requests, accept() out of file
descriptors), and a flood of such lines must not fill the station's logs. The server
and its connection caps (:mod:`clark_engine.station.connections`) both note their
trouble here.
"""

from __future__ import annotations

import logging
import time
from typing import Any


class Throttle:
    """Log lines that may come in floods: one per kind per interval, the rest counted.

    ``note`` logs at once when its kind has been quiet for the interval, else counts;
    the count goes out with the next line of that kind (or :meth:`flush`), so a flood of
    a thousand accept failures a second is one line every ``interval_s``.
    """

    def __init__(self, logger: logging.Logger, interval_s: float) -> None:
        self.logger = logger
        self.interval_s = interval_s
        self._last_s: dict[str, float] = {}
        self._counts: dict[str, int] = {}
        self._texts: dict[str, str] = {}
        self.total: dict[str, int] = {}

    def admit(self, kind: str) -> int | None:
        """Count one of ``kind``; the number to report when a line may go out now, or None."""
        self.total[kind] = self.total.get(kind, 0) + 1
        self._counts[kind] = self._counts.get(kind, 0) + 1
        now = time.monotonic()
        last = self._last_s.get(kind)
        if last is not None and now - last < self.interval_s:
            return None
        self._last_s[kind] = now
        return self._counts.pop(kind)

    def remember(self, kind: str, text: str) -> None:
        """The line (a %-format with one ``%d``) :meth:`flush` writes for ``kind``."""
        self._texts[kind] = text

    def note(self, kind: str, text: str, level: int = logging.WARNING) -> None:
        """Log ``text`` (a %-format with one ``%d`` for the count) when its kind may."""
        self._texts[kind] = text
        count = self.admit(kind)
        if count is not None:
            self.logger.log(level, text, count)

    def flush(self) -> None:
        """Log what was counted and not yet reported (when the server stops)."""
        for kind, count in list(self._counts.items()):
            text = self._texts.get(kind)
            if count and text is not None:
                self.logger.warning(text, count)
        self._counts.clear()


class ThrottledLogger(logging.LoggerAdapter):  # type: ignore[type-arg]
    """aiohttp's server logger, one record per message per interval, counted.

    aiohttp logs each bad request ("Error handling request", with a traceback) and
    each error of its own; from anyone who reaches the port, that is a flood. The first
    of a kind keeps its traceback; later ones go out once per interval as one line with
    their count. Debug records pass (they are off unless asked for).
    """

    def __init__(self, logger: logging.Logger, throttle: Throttle) -> None:
        super().__init__(logger, {})
        self.throttle = throttle

    def log(self, level: int, msg: object, *args: Any, **kwargs: Any) -> None:
        """Log a record: at once below WARNING, else once per kind per interval."""
        if level < logging.WARNING:
            self.logger.log(level, msg, *args, **kwargs)
            return
        kind = f"aiohttp:{msg}"
        first = kind not in self.throttle.total
        self.throttle.remember(
            kind, f"station view: %d more of aiohttp's {msg!s}".replace("%s", "...")
        )
        count = self.throttle.admit(kind)
        if count is None:
            return
        if not first:
            kwargs.pop("exc_info", None)
            kwargs.pop("stack_info", None)
            msg = f"{msg} (%d like it in the last {self.throttle.interval_s:g} s)"
            args = (*args, count)
        self.logger.log(level, msg, *args, **kwargs)


__all__ = ["Throttle", "ThrottledLogger"]
