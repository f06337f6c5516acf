"""The one exception root of the engine.

Every error a user can cause is a :class:`ClarkError` (or a subclass) carrying
where it happened, so that the command line can print it without a traceback.
Programming errors stay ordinary exceptions: they are bugs, not user mistakes.
"""

from __future__ import annotations


class ClarkError(Exception):
    """Base of every error the engine raises on purpose.

    Attributes:
        file: The file the error is about, when there is one.
        line: 1-based line in ``file``, when known.
        path: Dotted path inside the document, when known.
    """

    def __init__(
        self, message: str, *, file: str | None = None, line: int | None = None, path: str = ""
    ) -> None:
        super().__init__(message)
        self.message = message
        self.file = file
        self.line = line
        self.path = path

    def __str__(self) -> str:
        where = self.file or ""
        if self.file and self.line is not None:
            where = f"{self.file}:{self.line}"
        prefix = f"{where}: " if where else ""
        inside = f"{self.path}: " if self.path else ""
        return f"{prefix}{inside}{self.message}"


class UsageError(ClarkError):
    """The command was called wrongly or a file could not be read (exit code 2)."""
