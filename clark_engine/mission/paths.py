"""What a mission may name on disk: files and folders in its own folder, or the shipped data.

A mission is a file someone may hand you. Left free, its ``include:`` could point at any
folder on the machine (``/etc``, ``../../home/you``) and have its YAML parsed and quoted
back in findings, and its ``key_file`` could probe whether a file exists elsewhere and
what its mode is. So every path a mission writes is confined: relative, and inside the
mission's own folder (symbolic links resolved) or one of the shipped data folders. A path
that breaks the rule is refused before anything is opened.

A path is also bounded in length before any filesystem call: a fuzzed mission's
6,000-character include path raised ``OSError: File name too long`` out of
``Path.resolve()``. The limits are the schema's (:data:`MAX_PATH_CHARS` in all,
:data:`MAX_NAME_BYTES` per file or folder name, what every common filesystem allows).
"""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path, PurePosixPath, PureWindowsPath

from clark_engine.mission.schema_source.common import MAX_NAME_BYTES, MAX_PATH_CHARS


def too_long(written: str, max_chars: int = MAX_PATH_CHARS) -> str | None:
    """Why a path is too long to hand to the filesystem, or None when it is not.

    Checked on the text alone (no filesystem call): at most ``max_chars`` characters, and
    no file or folder name over :data:`MAX_NAME_BYTES` bytes of UTF-8. The reason quotes
    neither the path nor the name whole.
    """
    if len(written) > max_chars:
        return f"it is {len(written)} characters long, and a path may be at most {max_chars}"
    for part in written.replace("\\", "/").split("/"):
        size = len(part.encode("utf-8", "surrogatepass"))
        if size > MAX_NAME_BYTES:
            return (
                f"its name {part[:20]!r}... is {size} bytes long, and a file or folder name "
                f"may be at most {MAX_NAME_BYTES} bytes"
            )
    return None


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
    long = too_long(written)
    if long is not None:
        return None, long
    if PurePosixPath(written).is_absolute() or PureWindowsPath(written).is_absolute():
        return None, "it is an absolute path"
    if written.startswith("~"):
        return None, "it starts with ~ (a home folder)"
    home = base.resolve()
    try:
        full = (home / written).resolve()
    except (OSError, RuntimeError):  # a symbolic link loop, or a mission folder near PATH_MAX
        return None, "it cannot be resolved"
    for folder in (home, *(a.resolve() for a in allowed)):
        if full == folder or full.is_relative_to(folder):
            return full, ""
    if ".." in PurePosixPath(written.replace("\\", "/")).parts:
        return None, "it climbs out of the mission's folder (..)"
    return None, "it leads out of the mission's folder (through a symbolic link)"
