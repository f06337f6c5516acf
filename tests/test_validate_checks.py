"""Checks that should exist (issue 10, item 12).

Before: a mission without a station had no range check (a waypoint 500 km away passed); a
continuous follower with no offset drove onto its leader unwarned (now an error:
tests/test_validate_envelope.py has the envelope's checks); checks no run can pass
(photos from an agent with no camera, a failsafe on a station, min > max, by_s after the
run's end) passed ``clark validate`` and failed only in the dry run; and a check whose
by_s lay past ``--until`` said FAIL rather than "not evaluated".
"""

from __future__ import annotations

from pathlib import Path

import pytest

from clark_engine.expectations.evaluate import evaluate
from clark_engine.expectations.recording import Recording, StateEntry
from clark_engine.mission.geo import Origin
from clark_engine.validation import validate_file

HEAD = """\
clark: 1
mission: {id: 1, name: demo, loop_hz: 10, origin: {lat: 30.6372, lon: -96.4787, alt_amsl_m: 0}}
"""

ROVERS = """\
agents:
  lead:
    id: 2
    profile: traxxas_slash
    telemetry: {heartbeat: 1, agent_status: 2}
    behavior: {use: waypoint, with: {to: [TARGET, 0]}}
  chase:
    id: 3
    profile: traxxas_slash
    position: [-10, 0]
    telemetry: {heartbeat: 1, agent_status: 2}
    behavior: {use: follow_agent, with: {target: lead, continuous: true, retarget_hz: 2OFFSET}}
"""
#: What any follower of a moving leader is warned about: the dry run judges the pair.
REACTIVE = ("W-ENVELOPE-REACTIVE", 14)


def _codes(tmp_path: Path, text: str) -> list[tuple[str, int | None]]:
    path = tmp_path / "m.yaml"
    path.write_text(text, encoding="utf-8")
    result = validate_file(path, "m.yaml")
    return [(f.code, f.location.line) for f in result.findings if f.code != "W-NO-KEY"]


def _rovers(target: str = "30", offset: str = ", offset: {north_m: -5}") -> str:
    return HEAD + ROVERS.replace("TARGET", target).replace("OFFSET", offset)


def test_range_is_checked_without_a_station(tmp_path: Path) -> None:
    # 50 km is beyond the radio's mile, and so outside the default geofence too.
    far = [("E-GEOFENCE-POINT", 8), ("E-RADIO-RANGE", 8), REACTIVE]
    assert _codes(tmp_path, _rovers("50000")) == far
    assert _codes(tmp_path, _rovers("300")) == [REACTIVE]


def test_lone_vehicle_is_measured_from_the_origin(tmp_path: Path) -> None:
    text = HEAD + "\n".join(_rovers("50000").splitlines()[2:8]) + "\n"
    assert _codes(tmp_path, text) == [("E-GEOFENCE-POINT", 8), ("E-RADIO-RANGE", 8)]


def test_continuous_follower_without_offset_is_an_error(tmp_path: Path) -> None:
    assert _codes(tmp_path, _rovers(offset="")) == [("E-FOLLOW-SEPARATION", 14)]
    assert _codes(tmp_path, _rovers(offset=", offset: {east_m: 1}")) == [
        ("E-FOLLOW-SEPARATION", 14)
    ]
    assert _codes(tmp_path, _rovers()) == [REACTIVE]


STATION = """\
agents:
  mcs: {id: 1, profile: mcs_laptop, telemetry: {heartbeat: 1}}
  slash:
    id: 2
    profile: traxxas_slash
    telemetry: {heartbeat: 1}
    behavior: {use: waypoint, with: {to: [30, 0]}}
sim: {duration_s: 100}
checks:
"""


@pytest.mark.parametrize(
    "check",
    [
        "{photos: {agent: slash, min: 3}}",
        "{failsafe: {agent: mcs}}",
        "{distance_m: {between: [mcs, slash], min: 10, max: 5}}",
        "{photos: {agent: slash, min: 5, max: 2}}",
        "{by_s: 150, state: {agent: slash, reached: ''}}".replace("''", "x"),
    ],
)
def test_impossible_checks_are_errors(check: str, tmp_path: Path) -> None:
    text = HEAD + STATION + f"  - {check}\n"
    if "reached: x" in check:
        text = text.replace("reached: x", "reached: go").replace(
            "behavior: {use: waypoint, with: {to: [30, 0]}}",
            "behavior: {initial: go, states: {go: {use: waypoint, with: {to: [30, 0]}}}}",
        )
    codes = _codes(tmp_path, text)
    assert ("E-CHECK-IMPOSSIBLE", 12) in codes, codes


def test_possible_checks_are_not_flagged(tmp_path: Path) -> None:
    checks = [
        "{photos: {agent: slash, max: 0}}",
        "{failsafe: {agent: slash}}",
        "{by_s: 100, distance_m: {between: [mcs, slash], min: 1, max: 50}}",
    ]
    text = HEAD + STATION + "".join(f"  - {c}\n" for c in checks)
    assert _codes(tmp_path, text) == []


def test_a_check_past_the_end_of_the_run_is_not_evaluated() -> None:
    rec = Recording(end_s=40.0)
    rec.states["slash"] = [StateEntry(0.0, "start", ("go",), ("go",))]
    checks = [
        {"name": "later", "by_s": 120, "state": {"agent": "slash", "reached": "parked"}},
        {"name": "now", "by_s": 30, "state": {"agent": "slash", "reached": "parked"}},
        {"name": "done", "by_s": 120, "state": {"agent": "slash", "reached": "go"}},
    ]
    later, now, done = evaluate(checks, rec, {}, Origin(30.0, -96.0))
    assert later.verdict == "not evaluated" and not later.evaluated
    assert "the run ended at 40 s, before by_s 120 s" in later.observed
    assert now.verdict == "FAIL"
    assert done.verdict == "pass"
