"""Behaviour blocks and hardware profiles that installed plugins add.

An installed Python package adds folders of YAML files through two entry-point
groups: :data:`BLOCKS_GROUP` (behaviour blocks, as in the shipped ``behaviors/``)
and :data:`PROFILES_GROUP` (hardware profiles, as in the shipped
``hardware_profiles/``, ``<kind>s/`` subfolders or not). Each entry point's value
names a package, not an object (``my_plugin.blocks``): the folder of that package
is the folder of YAML files, found wherever the package is installed (its
``__path__``), so a plugin ships data the way Python ships any package data and
needs no code to say where it is.

The folders are searched after the shipped folders and a mission's ``include:``
folders, exactly as those are (:class:`~clark_engine.mission.profiles.ProfileLibrary`,
:class:`~clark_engine.mission.blocks.BlockLibrary`); a name that is already taken is
a finding (``E-PROFILE-DUPLICATE``, ``E-BLOCK-DUPLICATE``) naming both files and the
plugin. A plugin's file is shown by a stable name, its distribution and the
package's path (``clark-behavior-zigzag/clark_behavior_zigzag/blocks/zigzag_search.yaml``),
never by where it happens to be installed, so that findings and reports are the same
on every machine. An entry point that fails to load, or names no folder, is a
:class:`~clark_engine.behaviors.PluginError` (exit code 2), as a behaviour plugin's is.
See docs/plugins.md.
"""

from __future__ import annotations

import functools
from pathlib import Path
from types import ModuleType
from typing import NamedTuple

from clark_engine.behaviors import PluginError

#: The entry-point group through which installed packages add behaviour blocks.
BLOCKS_GROUP = "clark_engine.blocks"
#: The entry-point group through which installed packages add hardware profiles.
PROFILES_GROUP = "clark_engine.hardware_profiles"

_WHAT = {BLOCKS_GROUP: "block plugin", PROFILES_GROUP: "hardware profile plugin"}


class PluginFolder(NamedTuple):
    """One folder of YAML files an installed plugin adds.

    Attributes:
        path: The folder, where the package is installed.
        shown: How its files are shown: the distribution, then the package's path.
        origin: Which plugin and entry point adds it, for messages.
        dist: The distribution's name (what ``pip uninstall`` takes).
    """

    path: Path
    shown: str
    origin: str
    dist: str


def _folders(group: str, point_name: str, value: str, dist: str, loaded: object) -> list[Path]:
    where = f"{_WHAT[group]} {dist!r} (entry point {point_name} = {value})"
    if not isinstance(loaded, ModuleType):
        raise PluginError(
            f"{where} gives {type(loaded).__name__}, not a package; name the package whose "
            "folder holds the YAML files (my_plugin.blocks), see docs/plugins.md"
        )
    paths = getattr(loaded, "__path__", None)
    if paths is None:
        raise PluginError(
            f"{where} names module {loaded.__name__}, not a package with a folder; name the "
            "package whose folder holds the YAML files (my_plugin.blocks), see docs/plugins.md"
        )
    found = [Path(p) for p in paths if Path(p).is_dir()]
    if not found:
        raise PluginError(
            f"{where}: the folder of package {loaded.__name__} is missing; reinstall the "
            f"plugin, or uninstall it (pip uninstall {dist})"
        )
    return found


@functools.cache
def plugin_folders(group: str) -> tuple[PluginFolder, ...]:
    """Every folder the installed plugins add through ``group``, in a stable order.

    Args:
        group: :data:`BLOCKS_GROUP` or :data:`PROFILES_GROUP`.

    Raises:
        PluginError: An entry point fails to load, names no package, or its package's
            folder is missing (exit code 2: the installation is at fault, not the mission).
    """
    from importlib.metadata import entry_points

    points = sorted(
        entry_points(group=group),
        key=lambda e: (e.dist.name if e.dist is not None else "", e.name),
    )
    out: list[PluginFolder] = []
    for point in points:
        dist = point.dist.name if point.dist is not None else point.value
        where = f"{_WHAT[group]} {dist!r} (entry point {point.name} = {point.value})"
        try:
            loaded = point.load()
        except Exception as exc:  # a plugin's own bug: report it, never a traceback
            raise PluginError(
                f"{where} failed to load: {type(exc).__name__}: {exc}; fix it, or "
                f"uninstall it (pip uninstall {dist})"
            ) from None
        for path in _folders(group, point.name, point.value, dist, loaded):
            shown = f"{dist}/{point.module.replace('.', '/')}"
            out.append(PluginFolder(path, shown, where, dist))
    return tuple(out)


def clash_message(kind: str, name: str, new: tuple[str, str], old: tuple[str, str]) -> str:
    """What a duplicate name says when a plugin's file is one of the two.

    Args:
        kind: ``profile`` or ``block``.
        name: The name both files declare.
        new: (how the file is shown, its plugin's origin) of the file that is refused.
        old: The same of the file that keeps the name ("" as origin: not a plugin's).
    """

    def described(shown: str, origin: str) -> str:
        return f"{origin}, file {shown}" if origin else shown

    return (
        f"{described(*new)} declares {kind} {name!r}, which {described(*old)} already "
        "declares; rename one of the two files (and the name inside it), or uninstall the "
        "plugin"
    )


__all__ = [
    "BLOCKS_GROUP",
    "PROFILES_GROUP",
    "PluginFolder",
    "clash_message",
    "plugin_folders",
]
