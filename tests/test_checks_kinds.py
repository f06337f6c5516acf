"""The check kinds of issue 17: altitude_m, ends_at, and 3-D distances for aircraft.

Judged on recordings written sample by sample, with the configs of a small mission (a
copter and two rovers); and ``clark validate`` on the names and bounds they use.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import pytest

from clark_engine.expectations.evaluate import CheckResult, evaluate
from clark_engine.expectations.recording import Recording, Track
from clark_engine.mission.compiler import agent_config
from clark_engine.mission.geo import Origin
from clark_engine.runtime.config import AgentConfig, config_from_dict
from clark_engine.validation import validate_file

MISSION = """\
clark: 1
mission: {id: 9, name: kinds, loop_hz: 10, origin: {lat: 30.6372, lon: -96.4787, alt_amsl_m: 90}}
agents:
  mcs: {id: 1, profile: mcs_laptop, telemetry: {heartbeat: 1}}
  f450:
    id: 2
    profile: dji_f450
    launch: {armed_by: engine}
    telemetry: {heartbeat: 1, agent_status: 2}
    behavior:
      initial: climb
      states:
        climb: {use: takeoff, with: {alt_m: 10}, transitions: {done: hover}}
        hover: {use: hold, final: true}
  rover_a:
    id: 3
    profile: traxxas_slash
    position: [-8, 0]
    telemetry: {heartbeat: 1, agent_status: 2}
    behavior: {use: hold}
  rover_b:
    id: 4
    profile: traxxas_slash
    position: [0, 8]
    telemetry: {heartbeat: 1, agent_status: 2}
    behavior: {use: hold}
sim: {duration_s: 100}
"""
ORIGIN = Origin(30.6372, -96.4787, 90.0)


def mission_configs(tmp_path: Path) -> dict[str, AgentConfig]:
    path = tmp_path / "m.yaml"
    path.write_text(MISSION, encoding="utf-8")
    mission = validate_file(path, "m.yaml").mission
    assert mission is not None
    return {n: config_from_dict(agent_config(mission, a)) for n, a in mission.agents.items()}


def track(*samples: tuple[float, float, float, float]) -> Track:
    out = Track()
    for t, north, east, up in samples:
        out.add(t, north, east, up, 0.0, 0.0, 0.0)
    return out


def judged(tmp_path: Path, rec: Recording, *checks: dict[str, Any]) -> list[CheckResult]:
    return evaluate(list(checks), rec, mission_configs(tmp_path), ORIGIN)


def recording() -> Recording:
    """The copter climbs to 12 m over the origin; the rovers sit 8 m apart, heights noisy."""
    rec = Recording(end_s=4.0)
    rec.tracks["f450"] = track(
        (0, 0, 0, 0), (1, 0, 0, 4), (2, 0, 0, 12), (3, 0, 1, 12), (4, 0, 2, 9)
    )
    rec.tracks["rover_a"] = track(
        (0, 0, 0, 0), (1, 0, 0, 3), (2, 0, 0, -3), (3, 0, 0, 0), (4, 0, 0, 0)
    )
    rec.tracks["rover_b"] = track(
        (0, 0, 8, 0), (1, 0, 8, -3), (2, 0, 8, 3), (3, 0, 8, 0), (4, 0, 8, 0)
    )
    return rec


def test_altitude_bounds_hold_until_by_s(tmp_path: Path) -> None:
    rec = recording()
    inside, above, early_cut = judged(
        tmp_path,
        rec,
        {"name": "under 15", "altitude_m": {"agent": "f450", "max": 15}},
        {"name": "under 10", "altitude_m": {"agent": "f450", "min": 0, "max": 10}},
        {"name": "to 1 s", "by_s": 1, "altitude_m": {"agent": "f450", "max": 10}},
    )
    assert inside.passed
    assert inside.observed == "lowest 0.0 m at 0.0 s, highest 12.0 m at 2.0 s"
    assert not above.passed and above.verdict == "FAIL"
    assert "first outside at 2.0 s (12.0 m)" in above.observed
    assert early_cut.passed  # by_s 1: the climb to 12 m comes later
    assert inside.expected == "f450 altitude above origin <= 15 m until 4 s"


def test_altitude_past_the_end_is_not_evaluated_unless_already_broken(tmp_path: Path) -> None:
    rec = recording()
    holding, broken = judged(
        tmp_path,
        rec,
        {"by_s": 60, "altitude_m": {"agent": "f450", "max": 50}},
        {"by_s": 60, "altitude_m": {"agent": "f450", "max": 5}},
    )
    assert holding.verdict == "not evaluated"  # it could still break before 60 s
    assert broken.verdict == "FAIL"  # it already broke


def test_ends_at_is_3d_for_an_aircraft_and_on_the_ground_for_a_rover(tmp_path: Path) -> None:
    rec = recording()
    at_height, on_ground, rover, early = judged(
        tmp_path,
        rec,
        {"ends_at": {"agent": "f450", "to": [0, 2, 9], "within_m": 1}},
        {"ends_at": {"agent": "f450", "to": [0, 2], "within_m": 1}},  # a point on the ground
        {"ends_at": {"agent": "rover_b", "to": [0, 8, 50], "within_m": 1}},  # height ignored
        {"by_s": 2, "ends_at": {"agent": "f450", "to": [0, 0, 12], "within_m": 0.5}},
    )
    assert at_height.passed and at_height.observed == "0.0 m away, at (0.0, 2.0, 9.0)"
    assert at_height.expected == "f450 ends within 1 m of (0, 2, 9) at 4 s"
    assert not on_ground.passed and on_ground.observed.startswith("9.0 m away")
    assert rover.passed and rover.expected == "rover_b ends within 1 m of (0, 8) at 4 s"
    assert early.passed, early.observed  # where it was at by_s 2


def test_distances_are_3d_with_an_aircraft_and_flat_between_rovers(tmp_path: Path) -> None:
    rec = recording()
    copter, rovers, apart, sep = judged(
        tmp_path,
        rec,
        {"distance_m": {"between": ["f450", "rover_b"], "max": 8.5}},
        {"distance_m": {"between": ["rover_a", "rover_b"], "max": 8}},
        {"by_s": 2, "distance_m": {"between": ["f450", "rover_a"], "min": 11}},
        {"separation_m": {"min": 7.9, "agents": ["rover_a", "rover_b"]}},
    )
    # The copter at 12 m over the origin is 14.4 m from rover_b, not 8 m: it never came
    # within 8.5 m once off the ground; at 0 s, on the ground, it was 8 m away.
    assert copter.observed == "closest 8.0 m at 0.0 s" and copter.passed
    assert copter.expected.endswith("(3-D)")
    # The rovers' heights (GPS noise of +-3 m) do not count: 8 m apart on the ground.
    assert rovers.observed == "closest 8.0 m at 0.0 s" and rovers.passed
    assert not rovers.expected.endswith("(3-D)")
    # 3-D with the rover's height as recorded (-3 m then): 15 m.
    assert apart.observed == "15.0 m at 2 s" and apart.passed
    assert sep.passed and sep.observed == "closest 8.0 m (rover_a-rover_b at 0.0 s)"


def test_reached_is_3d_for_an_aircraft(tmp_path: Path) -> None:
    rec = recording()
    over, up_there = judged(
        tmp_path,
        rec,
        {"reached": {"agent": "f450", "to": [0, 1], "tolerance_m": 2}},
        {"reached": {"agent": "f450", "to": [0, 1, 12], "tolerance_m": 0.5}},
    )
    assert over.passed and over.observed == "reached at 0.0 s"  # on the ground, at the start
    assert up_there.passed and up_there.observed == "reached at 3.0 s"


HEAD = MISSION + "checks:\n"


@pytest.mark.parametrize(
    ("check", "code"),
    [
        ("{altitude_m: {agent: f450}}", "E-CHECK-SHAPE"),
        ("{altitude_m: {agent: f450, min: 20, max: 10}}", "E-CHECK-IMPOSSIBLE"),
        ("{altitude_m: {agent: mcs, max: 10}}", "E-CHECK-IMPOSSIBLE"),
        ("{ends_at: {agent: mcs, to: [0, 0]}}", "E-CHECK-IMPOSSIBLE"),
        ("{ends_at: {agent: nobody, to: [0, 0]}}", "E-AGENT-UNKNOWN"),
        ("{altitude_m: {agent: f45, max: 10}}", "E-AGENT-UNKNOWN"),
        ("{ends_at: {agent: f450, to: [0, 0], within_m: 0}}", "E-RANGE"),
    ],
)
def test_validate_checks_the_new_kinds(check: str, code: str, tmp_path: Path) -> None:
    path = tmp_path / "m.yaml"
    path.write_text(HEAD + f"  - {check}\n", encoding="utf-8")
    findings = validate_file(path, "m.yaml").findings
    codes = [f.code for f in findings if f.is_error]
    assert code in codes, [f.format_text() for f in findings]


def test_validate_takes_the_new_kinds(tmp_path: Path) -> None:
    checks = [
        "{altitude_m: {agent: f450, min: 0, max: 30}}",
        "{by_s: 90, altitude_m: {agent: rover_a, max: 1}}",
        "{ends_at: {agent: f450, to: [0, 0], within_m: 2}}",
        "{by_s: 50, ends_at: {agent: rover_b, to: {north_m: 0, east_m: 8}}}",
    ]
    path = tmp_path / "m.yaml"
    path.write_text(HEAD + "".join(f"  - {c}\n" for c in checks), encoding="utf-8")
    errors = [f.format_text() for f in validate_file(path, "m.yaml").findings if f.is_error]
    assert errors == []


def test_clark_analyze_judges_the_new_kinds_from_logs(tmp_path: Path) -> None:
    """The logs of a dry run give its verdicts on ends_at and altitude_m too."""
    import io

    from clark_engine.dryrun.command import run_dry_run
    from clark_engine.expectations.from_logs import check_folder

    near_miss = Path(__file__).resolve().parent / "dryrun" / "near_miss.yaml"
    report = tmp_path / "report"
    outcome = run_dry_run(
        near_miss, seed=None, until_s=None, report=report, speed=None,
        out=io.StringIO(), err=io.StringIO(),
    )  # fmt: skip
    mission = validate_file(near_miss, str(near_miss)).mission
    assert mission is not None
    from_logs = {r.name: r for r in check_folder(report / "logs", mission).results}
    for result in outcome.results:
        again = from_logs[result.name]
        assert again.evaluated and again.passed == result.passed, (result, again)
    assert from_logs["A ends at the crossing"].observed.endswith(")")
