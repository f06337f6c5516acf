"""Where the shipped data folders are: schemas, behaviours, hardware profiles, missions.

In a wheel they sit inside the package under ``_data/`` (see pyproject.toml's
force-include); in a checkout or an editable install they are the folders at the
top of the repository. Both layouts answer the same names, so the engine behaves
the same installed or not.
"""

from __future__ import annotations

from pathlib import Path

_PACKAGE_DIR = Path(__file__).resolve().parent
_FOLDERS = ("schemas", "behaviors", "hardware_profiles", "missions")


def data_dir(name: str) -> Path:
    """Return the directory holding one of the shipped data folders.

    Args:
        name: One of ``schemas``, ``behaviors``, ``hardware_profiles``, ``missions``.

    Raises:
        ValueError: ``name`` is not a shipped folder.
        FileNotFoundError: The installation is broken and the folder is missing.
    """
    if name not in _FOLDERS:
        raise ValueError(f"unknown data folder {name!r}; expected one of {', '.join(_FOLDERS)}")
    for candidate in (_PACKAGE_DIR / "_data" / name, _PACKAGE_DIR.parent / name):
        if candidate.is_dir():
            return candidate
    raise FileNotFoundError(
        f"the data folder {name!r} is missing from this installation of clark-engine; "
        "reinstall the package"
    )
