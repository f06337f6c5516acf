"""The plugin's behaviour block and hardware profile: found, used, validated, flown."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

HERE = Path(__file__).resolve().parent.parent
PACKAGE = HERE / "clark_behavior_zigzag"

MISSION = """\
clark: 1
mission:
  id: 8
  name: zigzag-search
  loop_hz: 5
  heartbeat_timeout_s: 5
  origin: {lat: 30.6372, lon: -96.4787, alt_amsl_m: 90}
agents:
  mcs:
    id: 1
    profile: mcs_laptop
    hardware:
      radio: {address: "0013A20040A1B201"}
    telemetry: {heartbeat: 1}
  slash:
    id: 2
    profile: traxxas_slash
    hardware:
      radio: {address: "0013A20040A1B202"}
      payloads:
        camera: {profile: zigzag_dashcam}
    telemetry: {heartbeat: 1, agent_status: 1}
    behavior:
      initial: search
      states:
        search:
          use: zigzag_search
          with: {start: [0, 0], heading_deg: 0, advance_m: 10, width_m: 20, legs: 4, interval_s: 2}
          transitions: {done: stopped}
        stopped: {use: hold}
checks:
  - {name: the search ends at the last corner, by_s: 120, state: {agent: slash, reached: stopped}}
  - {name: pictures along the way, photos: {agent: slash, min: 10}}
"""


@pytest.fixture
def mission(tmp_path: Path) -> Path:
    """The mission above, in a file of its own."""
    path = tmp_path / "search.yaml"
    path.write_text(MISSION, encoding="utf-8")
    return path


def test_the_block_and_the_profile_are_listed_with_their_origin(
    capsys: pytest.CaptureFixture[str],
) -> None:
    from clark_engine.cli import main

    assert main(["behaviors", "--blocks", "--json"]) == 0
    blocks = {row["name"]: row for row in json.loads(capsys.readouterr().out)}
    assert blocks["zigzag_search"]["origin"] == "clark-behavior-zigzag"
    assert blocks["aileron_doublet"]["origin"] == "shipped"
    # A stable name, not where the package happens to be installed.
    assert blocks["zigzag_search"]["file"] == (
        "clark-behavior-zigzag/clark_behavior_zigzag/blocks/zigzag_search.yaml"
    )
    assert main(["profiles", "--kind", "payload", "--json"]) == 0
    profiles = {row["name"]: row for row in json.loads(capsys.readouterr().out)}
    assert profiles["zigzag_dashcam"]["origin"] == "clark-behavior-zigzag"
    assert profiles["zigzag_dashcam"]["kind"] == "payload"


def test_the_block_and_the_profile_files_validate_on_their_own() -> None:
    from clark_engine.cli import main

    block = PACKAGE / "blocks" / "zigzag_search.yaml"
    profile = PACKAGE / "hardware_profiles" / "payloads" / "zigzag_dashcam.yaml"
    assert main(["validate", str(block), str(profile)]) == 0


def test_a_mission_using_them_validates_and_compiles(mission: Path, tmp_path: Path) -> None:
    from clark_engine.cli import main

    assert main(["validate", str(mission)]) == 0
    out = tmp_path / "build"
    assert main(["compile", str(mission), "-o", str(out)]) == 0
    config = json.loads((out / "zigzag-search" / "slash.json").read_text(encoding="utf-8"))
    camera = config["agent"]["hardware"]["payloads"]["camera"]
    assert camera["profile"] == "zigzag_dashcam"
    assert camera["min_interval_s"] == 1.0  # the plugin's, over the shipped profile it extends
    search = config["machine"]["states"][0]
    assert sorted(s["primitive"] for s in search["states"]) == ["photo_trigger", "zigzag"]
    # Where the block's states were written: by a stable name, not where it is installed.
    assert search["states"][0]["source"].startswith(
        "clark-behavior-zigzag/clark_behavior_zigzag/blocks/zigzag_search.yaml:"
    )


def test_a_mission_using_them_dry_runs_and_passes_its_checks(
    mission: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    from clark_engine.cli import main

    assert main(["dry-run", str(mission), "--seed", "1", "--until", "120", "-q"]) == 0
    out = capsys.readouterr().out
    assert "| the search ends at the last corner |" in out
    assert "| fail |" not in out
