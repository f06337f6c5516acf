"""The zigzag plugin: its declaration, its runtime, and the engine that finds it."""

from __future__ import annotations

import json
import math
from pathlib import Path

import pytest

MISSION = """\
clark: 1
mission:
  id: 7
  name: zigzag-sweep
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
    telemetry: {heartbeat: 1, agent_status: 1}
    behavior:
      initial: sweep
      states:
        sweep:
          use: zigzag
          with: {start: [0, 0], heading_deg: 0, advance_m: 10, width_m: 20, legs: 4}
          transitions: {done: stopped}
        stopped: {use: hold}
"""


def test_the_corners_alternate_either_side_of_the_line() -> None:
    from clark_behavior_zigzag import corners_m

    corners = corners_m(heading_deg=0, advance_m=10, width_m=20, legs=3)
    expected = [(10, 10), (20, -10), (30, 10)]
    for (n, e), (n0, e0) in zip(corners, expected, strict=True):
        assert math.isclose(n, n0, abs_tol=1e-9)
        assert math.isclose(e, e0, abs_tol=1e-9)


def test_the_engine_lists_it_with_its_origin() -> None:
    from clark_engine.behaviors import behaviors

    zigzag = behaviors()["zigzag"]
    assert zigzag.origin == "clark-behavior-zigzag"
    assert "zig-zag" in zigzag.summary


def test_a_mission_using_it_validates_and_compiles(tmp_path: Path) -> None:
    from clark_engine.cli import main

    mission = tmp_path / "zigzag.yaml"
    mission.write_text(MISSION, encoding="utf-8")
    assert main(["validate", str(mission)]) == 0
    out = tmp_path / "build"
    assert main(["compile", str(mission), "-o", str(out)]) == 0
    config = json.loads((out / "zigzag-sweep" / "slash.json").read_text(encoding="utf-8"))
    sweep = config["machine"]["states"][0]
    assert sweep["primitive"] == "zigzag"
    assert set(sweep["params"]["start"]) >= {"north_m", "lat", "alt_m"}


def test_its_runtime_flies_the_corners_in_order() -> None:
    from clark_behavior_zigzag import Zigzag

    start = {"north_m": 0, "east_m": 0, "up_m": 0, "lat": 52.0, "lon": 0.0, "alt_m": 0}
    zz = Zigzag({"start": start, "heading_deg": 90, "advance_m": 10, "width_m": 20, "legs": 2})
    assert len(zz.targets) == 3
    # Heading east: the corners are east of the start, alternately north and south of it.
    assert zz.targets[1].lon_deg > 0 and zz.targets[1].lat_deg < 52.0
    assert zz.targets[2].lon_deg > zz.targets[1].lon_deg and zz.targets[2].lat_deg > 52.0


@pytest.mark.parametrize("legs", [0, 101])
def test_its_parameters_are_checked_by_the_engine(tmp_path: Path, legs: int) -> None:
    from clark_engine.cli import main

    mission = tmp_path / "zigzag.yaml"
    mission.write_text(MISSION.replace("legs: 4", f"legs: {legs}"), encoding="utf-8")
    assert main(["validate", str(mission)]) == 1
