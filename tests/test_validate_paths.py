"""What a mission may name on disk (issue 10, item 7).

``include`` and ``key_file`` accepted absolute and ``../`` paths: a YAML file elsewhere on
disk was parsed and its values quoted in findings, and a key_file error told whether
another file existed and what its mode was. Both are now confined to the mission's folder
(and, for include, the shipped data), refused before anything is opened.
"""

from __future__ import annotations

import os
from pathlib import Path

import pytest

from clark_engine.link.auth import generate_key_file
from clark_engine.validation import validate_file

MISSION = """\
clark: 1
mission: {{id: 1, name: demo, loop_hz: 10, origin: {{lat: 30.64, lon: -96.48, alt_amsl_m: 0}}{key}}}
{include}agents:
  slash: {{id: 2, profile: traxxas_slash, telemetry: {{heartbeat: 1}}}}
"""

SECRET_PROFILE = """\
profile: secret_profile
kind: platform
description: hunter2-the-secret-value
"""


def _validate(home: Path, *, key: str = "", include: str = "") -> list[tuple[str, int | None, str]]:
    mission = home / "m.yaml"
    mission.write_text(
        MISSION.format(key=f", key_file: {key}" if key else "", include=include),
        encoding="utf-8",
    )
    result = validate_file(mission, "m.yaml")
    return [(f.code, f.location.line, f.message) for f in result.findings]


@pytest.fixture
def outside(tmp_path: Path) -> Path:
    """A folder beside the mission's, holding a YAML file with a value to keep private."""
    folder = tmp_path / "elsewhere"
    folder.mkdir()
    (folder / "secret_profile.yaml").write_text(SECRET_PROFILE + "x: [unclosed\n")
    return folder


@pytest.fixture
def home(tmp_path: Path) -> Path:
    folder = tmp_path / "mission"
    folder.mkdir()
    return folder


@pytest.mark.parametrize("how", ["absolute", "dotdot", "symlink"])
def test_include_outside_the_mission_folder_is_refused(how: str, home: Path, outside: Path) -> None:
    if how == "absolute":
        written = str(outside)
    elif how == "dotdot":
        written = "../elsewhere"
    else:
        (home / "link").symlink_to(outside)
        written = "link"
    found = _validate(home, include=f"include: {{hardware_profiles: ['{written}']}}\n")
    assert [(code, line) for code, line, _ in found] == [("E-INCLUDE-PATH", 3)], found
    text = " ".join(message for _, _, message in found)
    assert "hunter2" not in text and "secret_profile" not in text
    assert "move the folder next to the mission" in text


def test_include_inside_the_mission_folder_still_works(home: Path) -> None:
    (home / "mine").mkdir()
    found = _validate(home, include="include: {behaviors: [mine, ./mine/../mine]}\n")
    assert not [f for f in found if f[0].startswith("E-")], found


@pytest.mark.parametrize("written", ["ABSOLUTE", "../elsewhere/k.key", "~/k.key"])
def test_key_file_outside_the_mission_folder_is_refused_unopened(
    written: str, home: Path, outside: Path
) -> None:
    key = outside / "k.key"
    if written == "ABSOLUTE":
        written = str(key)
    missing = _validate(home, key=written)
    key.write_text("not a key\n")
    os.chmod(key, 0o644)
    present = _validate(home, key=written)
    assert [(c, line) for c, line, _ in present] == [("E-KEY-PATH", 2)], present
    assert present == missing, "the answer must not depend on what exists outside"
    message = present[0][2]
    assert "644" not in message and "not found" not in message
    assert "key_file: mission.key" in message


def test_key_file_beside_the_mission_is_read(home: Path) -> None:
    generate_key_file(home / "mission.key")
    assert _validate(home, key="mission.key") == []
    os.chmod(home / "mission.key", 0o644)
    assert [c for c, _, _ in _validate(home, key="mission.key")] == ["E-KEY-FILE"]
