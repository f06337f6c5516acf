"""Text that arrives from outside the engine, made safe to write into a log line.

A string from a link (an autopilot's STATUSTEXT, a ClarkLink text field) may
hold a newline that forges a log line, a terminal escape sequence that rewrites
what an operator sees, or simply be long. :func:`printable` keeps what is
readable and escapes the rest, so one received string is always one bounded,
inert piece of one log line.
"""

from __future__ import annotations

from typing import Final

MAX_TEXT_CHARS: Final = 200
"""Longest escaped text kept; STATUSTEXT carries at most 50 characters per chunk."""


def printable(text: str, limit: int = MAX_TEXT_CHARS) -> str:
    r"""``text`` with every non-printable character and backslash escaped, at most ``limit``.

    Printable characters (letters, digits, punctuation and spaces of any script)
    pass unchanged; a backslash becomes ``\\\\`` and every other character its
    ``\\xNN``, ``\\uNNNN`` or ``\\UNNNNNNNN`` escape, so the result holds no line
    break and no control character and the original can be read back from it.
    A result longer than ``limit`` is cut and ends with ``...``.

    Args:
        text: The untrusted text.
        limit: Longest result, in characters (at least 4).
    """
    out: list[str] = []
    length = 0
    for char in text:
        if char == "\\":
            piece = "\\\\"
        elif char.isprintable():
            piece = char
        else:
            code = ord(char)
            piece = (
                f"\\x{code:02x}"
                if code < 0x100
                else f"\\u{code:04x}"
                if code < 0x10000
                else f"\\U{code:08x}"
            )
        if length + len(piece) > limit:
            return "".join(out)[: max(limit - 3, 0)] + "..."
        out.append(piece)
        length += len(piece)
    return "".join(out)
