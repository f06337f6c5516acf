"""Make the plugin visible to the engine without installing it.

An installation puts the module on ``sys.path`` and a ``.dist-info`` folder whose
``entry_points.txt`` names it in the ``clark_engine.behaviors`` group (and its folders of
blocks and profiles in ``clark_engine.blocks`` and ``clark_engine.hardware_profiles``); the engine
finds plugins through ``importlib.metadata``, so doing the same by hand, for the
test session, is indistinguishable from ``pip install``.
"""

from __future__ import annotations

import sys
from collections.abc import Iterator
from pathlib import Path

import pytest

HERE = Path(__file__).resolve().parent.parent


@pytest.fixture(scope="session", autouse=True)
def installed(tmp_path_factory: pytest.TempPathFactory) -> Iterator[Path]:
    """The plugin's folder and a dist-info declaring its entry point, on sys.path."""
    site = tmp_path_factory.mktemp("site")
    info = site / "clark_behavior_zigzag-0.1.0.dist-info"
    info.mkdir()
    (info / "METADATA").write_text(
        "Metadata-Version: 2.1\nName: clark-behavior-zigzag\nVersion: 0.1.0\n", encoding="utf-8"
    )
    (info / "entry_points.txt").write_text(
        "[clark_engine.behaviors]\nzigzag = clark_behavior_zigzag:BEHAVIOR\n"
        "[clark_engine.blocks]\nzigzag = clark_behavior_zigzag.blocks\n"
        "[clark_engine.hardware_profiles]\nzigzag = clark_behavior_zigzag.hardware_profiles\n",
        encoding="utf-8",
    )
    sys.path[:0] = [str(HERE), str(site)]
    yield site
    sys.path.remove(str(HERE))
    sys.path.remove(str(site))
