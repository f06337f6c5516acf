"""Where a run's logs are: the one rule of ``clark analyze``, ``--checks`` and ``clark replay``.

Why: the three readers had two rules. ``clark analyze`` and ``clark analyze --checks``
read only the folder given (and suggested ``logs/`` in their error), ``clark replay``
also looked in ``logs/`` and in sub-folders; a folder one command took, another refused.
Now every reader asks :func:`find_log_files`, which accepts every layout any of them
accepted (docs/logs.md, "Which folder"):

- the folder the agents logged to: a ``clark run`` folder, where one or several agents
  write ``<agent>.mission.log`` and the rest side by side, or a dry-run report's
  ``logs/`` folder given itself;
- a dry-run report folder, whose logs are in its ``logs/`` folder;
- a folder of the agents' own folders (gathered from several machines), or such a
  folder's ``logs/``: their sub-folders, one level down.

Files are found by name: ``<agent>`` and one of the suffixes of :data:`LOG_FILES`, or the
file names a compiled config gives (``log:`` in the mission), when the reader knows the
mission. A file found twice is taken from the first place in the order above and noted.
"""

from __future__ import annotations

from collections.abc import Mapping
from pathlib import Path
from typing import Final

from clark_engine.errors import UsageError
from clark_engine.untrusted import printable

#: The four files of an agent: config key -> the default suffix after the agent's name.
LOG_FILES: Final = {
    "mission_log": ".mission.log",
    "interface_log": ".interface.log",
    "fleet_csv": ".fleet.csv",
    "message_log": ".messages.csv",
}

MAX_NAME_CHARS: Final = 64
"""Longest agent name taken from a file name or a log (longer ones are cut, escaped)."""

MAX_SUBFOLDERS: Final = 256
"""Most sub-folders searched for agents' logs."""

#: What the readers say when a folder holds no log at all.
NO_LOGS: Final = (
    "no agent's log in it (files named <agent>.mission.log, <agent>.interface.log, "
    "<agent>.fleet.csv or <agent>.messages.csv, in it, in its logs/ folder or in their "
    "sub-folders)"
)


def shown_name(text: str) -> str:
    """An agent's name from a file name or a log, bounded and escaped."""
    return printable(text, MAX_NAME_CHARS)


def _listed(place: Path) -> list[Path]:
    try:
        return sorted(place.iterdir())
    except OSError as exc:
        raise UsageError(f"{place}: cannot list it ({exc.strerror or exc})") from None


def log_places(folder: Path, notes: list[str]) -> list[Path]:
    """The folders searched, in order: ``folder``, its ``logs/``, then their sub-folders.

    Raises:
        UsageError: The folder does not exist, is not a folder, or cannot be listed (2).
    """
    if not folder.exists():
        raise UsageError(f"{folder}: no such folder")
    if not folder.is_dir():
        raise UsageError(f"{folder}: not a folder; give the folder the agents logged to")
    places = [folder]
    if (folder / "logs").is_dir():
        places.append(folder / "logs")
    subfolders = [
        path
        for place in list(places)
        for path in _listed(place)
        if path.is_dir() and not (place == folder and path.name == "logs")
    ]
    if len(subfolders) > MAX_SUBFOLDERS:
        notes.append(f"{folder}: only the first {MAX_SUBFOLDERS} sub-folders were searched")
    return places + subfolders[:MAX_SUBFOLDERS]


def find_log_files(
    folder: Path,
    notes: list[str],
    names: Mapping[str, Mapping[str, str]] | None = None,
) -> dict[str, dict[str, Path]]:
    """Agent -> config key (``mission_log``...) -> its file, wherever the run left them.

    Args:
        folder: What the user gave (see the module's doc for the layouts).
        notes: Warnings are appended here (files found twice, sub-folders not searched).
        names: Agent -> config key -> the file name its compiled config gives, when the
            reader knows the mission: such a file is the agent's whatever its name.
            Other files are taken by their suffix either way.

    Returns:
        Every agent with at least one file, in the order found; empty when there is none
        (each reader says so in its own words and exit code).

    Raises:
        UsageError: The folder does not exist, is not a folder, or cannot be listed (2).
    """
    configured: dict[str, tuple[str, str]] = {}
    for agent, given in (names or {}).items():
        for key, file_name in given.items():
            configured.setdefault(file_name, (agent, key))
    found: dict[str, dict[str, Path]] = {}
    twice: list[str] = []
    for place in log_places(folder, notes):
        for path in _listed(place):
            owner = configured.get(path.name)
            if owner is None:
                owner = next(
                    (
                        (shown_name(path.name[: -len(suffix)]), key)
                        for key, suffix in LOG_FILES.items()
                        if path.name.endswith(suffix) and len(path.name) > len(suffix)
                    ),
                    None,
                )
            if owner is None or not owner[0] or not path.is_file():
                continue
            agent, key = owner
            files = found.setdefault(agent, {})
            if key in files:
                twice.append(f"{path} (using {files[key]})")
            else:
                files[key] = path
    if twice:
        notes.append("found twice: " + "; ".join(twice[:5]) + (" ..." if len(twice) > 5 else ""))
    return found
