"""Findings: what validation reports, each with a stable code and an exact place.

A finding is data, not an exception, so that validation can collect every
problem in a mission and report them all at once.
"""

from __future__ import annotations

import re
from dataclasses import dataclass, field
from enum import StrEnum

PathPart = str | int
DocPath = tuple[PathPart, ...]

_SIMPLE_KEY = re.compile(r"^[A-Za-z0-9_:\-/$]+$")


class Severity(StrEnum):
    """How bad a finding is: errors make a mission invalid, warnings do not."""

    ERROR = "error"
    WARNING = "warning"


def format_path(path: DocPath) -> str:
    """Render a document path the way users write it: ``agents.cub.telemetry[0]``.

    Keys that are not plain identifiers are quoted in brackets so the path
    stays unambiguous (``states["take off"]``).
    """
    out = ""
    for part in path:
        if isinstance(part, int):
            out += f"[{part}]"
        elif _SIMPLE_KEY.match(part):
            out += f".{part}" if out else part
        else:
            out += f"[{part!r}]"
    return out


@dataclass(frozen=True, slots=True)
class Location:
    """Where a finding points: file, 1-based line and column, path inside the document."""

    file: str
    line: int | None = None
    column: int | None = None
    path: DocPath = ()

    @property
    def dotted_path(self) -> str:
        """The document path as users write it."""
        return format_path(self.path)

    def prefix(self) -> str:
        """``file:line:column`` as compilers print it, omitting what is unknown."""
        if self.line is None:
            return self.file
        if self.column is None:
            return f"{self.file}:{self.line}"
        return f"{self.file}:{self.line}:{self.column}"


@dataclass(frozen=True, slots=True)
class Finding:
    """One problem in a mission, or a warning about it.

    Attributes:
        code: Stable identifier, e.g. ``E-RATE``; docs/check-codes.md lists them all.
        severity: Error (mission invalid) or warning (mission still valid).
        location: The exact place the user must change.
        message: A sentence saying what is wrong and what to change.
        related: Other places that explain the finding (e.g. where a block is used).
    """

    code: str
    severity: Severity
    location: Location
    message: str
    related: tuple[Location, ...] = field(default=())

    @property
    def is_error(self) -> bool:
        """True when the finding makes the mission invalid."""
        return self.severity is Severity.ERROR

    def format_text(self) -> str:
        """One line (plus one per related place) in the compiler style."""
        path = self.location.dotted_path
        inside = f"{path}: " if path else ""
        text = (
            f"{self.location.prefix()}: {self.severity.value}: {inside}{self.message} [{self.code}]"
        )
        for rel in self.related:
            rel_path = f" ({rel.dotted_path})" if rel.dotted_path else ""
            text += f"\n    note: see {rel.prefix()}{rel_path}"
        return text

    def to_json(self) -> dict[str, object]:
        """The same fields as the text form, for tools."""
        return {
            "file": self.location.file,
            "line": self.location.line,
            "column": self.location.column,
            "path": self.location.dotted_path,
            "code": self.code,
            "severity": self.severity.value,
            "message": self.message,
            "related": [
                {"file": r.file, "line": r.line, "column": r.column, "path": r.dotted_path}
                for r in self.related
            ],
        }

    def sort_key(self) -> tuple[str, int, int, str, str]:
        """Order findings by file, then position, so reports read top to bottom."""
        loc = self.location
        return (loc.file, loc.line or 0, loc.column or 0, self.code, self.message)


def _notes(location: Location, related: tuple[Location, ...]) -> tuple[Location, ...]:
    """Related places worth a note: not the finding's own place, each once."""
    out: list[Location] = []
    for rel in related:
        same = (rel.file, rel.line, rel.column) == (location.file, location.line, location.column)
        if not same and rel not in out:
            out.append(rel)
    return tuple(out)


def error(code: str, location: Location, message: str, *related: Location) -> Finding:
    """Make an error finding."""
    return Finding(code, Severity.ERROR, location, message, _notes(location, related))


def warning(code: str, location: Location, message: str, *related: Location) -> Finding:
    """Make a warning finding."""
    return Finding(code, Severity.WARNING, location, message, _notes(location, related))


def rehome(finding: Finding, mission_file: str, mission_use: Location | None) -> Finding:
    """Point a finding about a block's own value at the mission's use of the block.

    When the value that does not fit this agent was written in a block file (the
    block's ``channel: aileron`` on a quadcopter, a survey waypoint outside this
    vehicle's geofence), the place to change is where the mission uses the block;
    the block line becomes a note.

    Args:
        finding: The finding, located where the value was written.
        mission_file: The mission file as findings name it.
        mission_use: Where the mission's ``use:`` brought the block in; None for
            states written in the mission itself.
    """
    if finding.location.file == mission_file or mission_use is None:
        return finding
    related = tuple(r for r in finding.related if r != mission_use)
    return Finding(
        finding.code,
        finding.severity,
        mission_use,
        finding.message,
        (finding.location, *related),
    )
