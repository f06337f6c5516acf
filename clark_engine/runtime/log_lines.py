"""One log line or CSV cell that nothing from outside can break.

Strings that arrive over the air or from the autopilot (a Terminate's reason, a claimed
sender, a STATUSTEXT) reach the logs as arguments and cells; every one goes through
:func:`line_safe` (no newline, no control character or terminal escape, bounded length),
and the fleet CSV's text is checked whole each tick (:func:`plain_lines`) before it is
written cell by cell in the rare case it must be. The station's pages use the same
escape for what they show.

Separate from :mod:`~clark_engine.runtime.logbook` because it is the one rule of what may
reach a line, used by the logbook, the station's view and its replay, and needs no
logbook.
"""

from __future__ import annotations

from clark_engine.untrusted import printable

#: Longest text argument or CSV cell written as it is; a longer one is cut (``...``).
MAX_LOGGED_TEXT_CHARS = 500
#: Longest log message written whole when it had to be escaped.
MAX_LOGGED_LINE_CHARS = 2000


def line_safe(text: str, limit: int = MAX_LOGGED_TEXT_CHARS) -> str:
    """``text`` when it is printable and at most ``limit`` long, else :func:`printable`'s escape.

    Printable text (an agent's name, an already escaped STATUSTEXT) is written as it is,
    so nothing is escaped twice; text with a newline, a control character or a terminal
    escape, or a long one, is escaped whole (backslashes too, so it reads back) and cut.
    """
    if len(text) <= limit and text.isprintable():
        return text
    return printable(text, limit)


def safe_arg(arg: object) -> object:
    """A log record argument that cannot break its line: numbers pass, the rest is escaped."""
    if isinstance(arg, str):
        return line_safe(arg)
    if arg is None or isinstance(arg, int | float):
        return arg
    return line_safe(str(arg))


def plain_cell(text: str) -> str:
    """One CSV cell on one line, inert and bounded (:func:`line_safe`).

    A row must never span lines, so grep and a crash cut cleanly, and a cell must
    never carry a control character or a terminal escape to whoever reads the file.
    """
    return line_safe(text)


#: ASCII control characters but the newline, deleted by bytes.translate to find any.
_CONTROL_BYTES = bytes(range(32)).replace(b"\n", b"") + b"\x7f"


def plain_lines(text: str, lines: int) -> bool:
    """True when ``text`` is ``lines`` lines of plain ASCII without a control character.

    The fleet CSV's every-tick check, in C and a few microseconds for 100 rows
    (``str.isprintable`` takes seven times as long); anything else, rare, is written
    again cell by cell through :func:`line_safe`.
    """
    return (
        text.count("\n") == lines
        and text.isascii()
        and len(text.encode("ascii").translate(None, _CONTROL_BYTES)) == len(text)
    )
