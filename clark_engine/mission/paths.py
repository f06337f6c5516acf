"""What a mission may name on disk: files and folders in its own folder, or the shipped data.

A mission is a file someone may hand you. Left free, its ``include:`` could point at any
folder on the machine (``/etc``, ``../../home/you``) and have its YAML parsed and quoted
back in findings, and its ``key_file`` could probe whether a file exists elsewhere and
what its mode is. So every path a mission writes is confined: relative, and inside the
mission's own folder (symbolic links resolved) or one of the shipped data folders. A path
that breaks the rule is refused before anything is opened.
"""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path, PurePosixPath, PureWindowsPath


def confine(base: Path, written: str, allowed: Sequence[Path] = ()) -> tuple[Path | None, str]:
    """Resolve a path a mission wrote, or say why it may not name it.

    Args:
        base: The mission's folder; ``written`` is relative to it.
        written: The path as the mission wrote it.
        allowed: More folders (the shipped data) the path may resolve into.

    Returns:
        (the resolved path, "") when allowed; (None, why not) otherwise. The reason never
        says what exists on disk outside the allowed folders.
    """
    if not written.strip() or "\x00" in written:
        return None, "it is empty" if not written.strip() else "it holds a NUL character"
    if PurePosixPath(written).is_absolute() or PureWindowsPath(written).is_absolute():
        return None, "it is an absolute path"
    if written.startswith("~"):
        return None, "it starts with ~ (a home folder)"
    home = base.resolve()
    try:
        full = (home / written).resolve()
    except (OSError, RuntimeError):  # a symbolic link loop
        return None, "it cannot be resolved"
    for folder in (home, *(a.resolve() for a in allowed)):
        if full == folder or full.is_relative_to(folder):
            return full, ""
    if ".." in PurePosixPath(written.replace("\\", "/")).parts:
        return None, "it climbs out of the mission's folder (..)"
    return None, "it leads out of the mission's folder (through a symbolic link)"
