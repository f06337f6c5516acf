"""Where ArduPilot SITL is for the tests: ``$CLARK_SITL``, else ``../shared/ardupilot-sitl``.

Tests that need SITL skip with a reason where neither is here (CI has it). One function,
for the modules that decide at import time (a ``skipif`` marker), and the ``sitl_install``
fixture of conftest.py, for tests that ask for it.
"""

from __future__ import annotations

import os
from pathlib import Path

from clark_engine.sitl.errors import SitlNotFound
from clark_engine.sitl.launcher import ENV_SITL, SitlInstall

ROOT = Path(__file__).resolve().parent.parent

NO_SITL = f"no ArduPilot SITL: set {ENV_SITL} to the folder with the `sitl` launcher"
"""The skip reason where SITL is not here."""


def real_install() -> SitlInstall | None:
    """The SITL launcher, or None where there is none."""
    default = ROOT.parent / "shared" / "ardupilot-sitl"
    given = os.environ.get(ENV_SITL) or (str(default) if default.is_dir() else None)
    try:
        return SitlInstall.find(given) if given else None
    except SitlNotFound:
        return None
