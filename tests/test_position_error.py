"""Separation under GPS error: the envelope's ``position_error_m`` (issue 19).

Each autopilot flies, and reports, its GPS estimate; the runtime kept each pair's
separation on those *reported* positions, so two GPS errors that point at each other let
the *true* distance fall under the separation while the reports kept it (1 run in 200 of a
noisy cooperative_follow campaign, docs/campaigns.md). A vehicle now declares how far its
reported horizontal position may be from the truth, and every pair is kept the sum of
their two figures further apart than its separation, on the reports: by the runtime's
guard (targets), its watch (near misses) and the station's alarms; `clark validate` warns
when the dry run simulates a larger GPS error than the vehicles declare; the dry run goes
on judging the separation on the true tracks.
"""

from __future__ import annotations

import io
import json
import math
from dataclasses import replace
from pathlib import Path

import pytest
from test_gcs_alarms import envelope as alarm_envelope
from test_gcs_alarms import kinds
from test_runtime_envelope import Flight, _leave, compiled, local, of, past_the_proofs

from clark_engine.dryrun.command import run_dry_run
from clark_engine.mission.compiler import compile_mission
from clark_engine.mission.envelope_mission_checks import WALK_95_FACTOR
from clark_engine.runtime.commands import Goto, SetMode
from clark_engine.station.alarms import NEAR_MISS, AlarmWatch
from clark_engine.validation import validate_file

FOLLOW_UP_3 = "{use: follow_agent, with: {target: rover, offset: {up_m: 3}, continuous: true}}"

# -------------------------------------------------------------------------- the runtime


def test_a_target_is_kept_both_position_errors_further_out(tmp_path: Path) -> None:
    """5 m separation, 2 m margin, and 1.5 m for each vehicle's GPS: 10 m, not 7 m."""
    config = compiled(tmp_path, "copter", envelope="{position_error_m: 1.5}", copter=FOLLOW_UP_3)
    assert config.envelope is not None
    assert config.envelope.position_errors_m("rover") == 3.0
    flight = Flight(config)
    out = flight.tick(flight.state(-30, 0, 10), flight.peer("rover", 0, 0, 0.0))
    (goto,) = of(out, Goto)
    point = local(goto)
    apart_m = math.dist((point.north_m, point.east_m, point.up_m), (0.0, 0.0, 0.0))
    assert apart_m == pytest.approx(10.0, abs=0.02)
    assert (
        "inside its 5 m separation and the 3 m of the two vehicles' position errors and "
        "the 2 m margin; moved out to 10.0 m from it" in flight.mission_log()
    )


def test_each_vehicle_brings_its_own_figure(tmp_path: Path) -> None:
    """An RTK rover (5 cm) beside a copter on a plain GPS (2 m, the mission's figure)."""
    text_edit = "{position_error_m: 2}"
    config = compiled(tmp_path, "copter", envelope=text_edit, copter=FOLLOW_UP_3)
    assert config.envelope is not None and config.envelope.position_errors_m("rover") == 4.0
    path = tmp_path / "mission.yaml"
    path.write_text(
        path.read_text(encoding="utf-8").replace(
            "    profile: traxxas_slash\n",
            "    profile: traxxas_slash\n    envelope: {position_error_m: 0.05}\n",
        ),
        encoding="utf-8",
    )
    files = {n: json.loads(t) for n, t in compile_mission(past_the_proofs(path)).items()}
    assert files["copter"]["envelope"]["position_error_m"] == 2.0
    assert files["copter"]["envelope"]["peer_position_error_m"] == {"rover": 0.05}
    assert files["rover"]["envelope"]["position_error_m"] == 0.05
    assert files["rover"]["envelope"]["peer_position_error_m"] == {"copter": 2.0}


def test_a_near_miss_counts_both_position_errors(tmp_path: Path) -> None:
    """6.3 m from the rover's report is outside the 5 m separation, but two GPS errors of
    1.5 m may put the two vehicles 3.3 m apart: a near miss."""
    config = compiled(tmp_path, "copter", envelope="{position_error_m: 1.5}")
    flight = Flight(config)
    _leave(flight, (0, 0, 30), peers=(flight.peer("rover", 0, 20, 0.0),))
    out = _leave(flight, (0, 0, 6), peers=(flight.peer("rover", 0, 2, 0.0),))
    assert of(out, SetMode) == [SetMode("LOITER", 5)]
    assert (
        "rover 6.3 m away (3-D), inside the 5 m separation and the 3 m of the two vehicles' "
        "position errors: hold" in flight.mission_log()
    )


def test_without_a_figure_the_reports_are_the_truth(tmp_path: Path) -> None:
    """The default is 0, and the compiled config is what it was before the figure existed."""
    config = compiled(tmp_path, "copter")
    assert config.envelope is not None and config.envelope.position_errors_m("rover") == 0.0
    assert "position_error_m" not in config.envelope.raw
    assert "peer_position_error_m" not in config.envelope.raw


def test_the_station_counts_both_position_errors() -> None:
    w = AlarmWatch(
        {
            "cub": replace(alarm_envelope(), position_error_m=1.0),
            "f450": replace(alarm_envelope(), position_error_m=2.0),
        },
        stale_after_s=3.0,
    )
    w.see_position("cub", 0.0, 0.0, 30.0, 0.0)
    w.see_position("f450", 0.0, 7.5, 30.0, 0.0)  # 7.5 m: outside 5, inside 5 + 1 + 2
    assert kinds(w.evaluate(0.0)) == [(NEAR_MISS, ("cub", "f450"), True)]
    (alarm,) = w.active
    assert "inside their 5 m separation and the 3 m of their position errors" in alarm.text


# ------------------------------------------------------------------ validate and dry run

PARK_BESIDE = Path(__file__).resolve().parent / "dryrun" / "park_beside.yaml"
"""Slash B parks 2.5 m behind Slash A's report; 1 m separation; a GPS walk of 1.5 m."""


def _park_beside(tmp_path: Path, position_error: str = "", walk: str = "1.5") -> Path:
    """The mission, with ``envelope.position_error_m`` declared (or not) and the walk set."""
    text = PARK_BESIDE.read_text(encoding="utf-8")
    text = text.replace("  margin_m: 1\n", "  margin_m: 1\n" + position_error)
    text = text.replace("{walk_m: 1.5,", f"{{walk_m: {walk},")
    path = tmp_path / "park_beside.yaml"
    path.write_text(text, encoding="utf-8")
    return path


def _warnings(path: Path) -> list[str]:
    result = validate_file(path)
    assert result.ok, [f.message for f in result.errors]
    return [f.format_text() for f in result.findings if f.code == "W-POSITION-ERROR"]


def test_validate_warns_when_the_dry_runs_gps_error_is_larger(tmp_path: Path) -> None:
    (warned,) = _warnings(_park_beside(tmp_path))
    assert warned.startswith(f"{tmp_path / 'park_beside.yaml'}:40:14: warning: sim.gps_error:")
    assert "walks 1.5 m on each axis, so a reported position is up to 3.7 m from the truth" in (
        warned
    )
    assert "slash_a, slash_b declare a position error of 0 m" in warned
    assert "declare envelope.position_error_m: 3.7 (or more)" in warned
    assert pytest.approx(2.4477, abs=1e-4) == WALK_95_FACTOR


def test_validate_takes_a_distributions_largest_walk(tmp_path: Path) -> None:
    path = _park_beside(tmp_path, "  position_error_m: 3.7\n", "{uniform: [0.5, 2]}")
    (warned,) = _warnings(path)
    assert ":19:21: warning: envelope.position_error_m:" in warned  # where the figure is
    assert "walks up to 2 m on each axis" in warned and "position_error_m: 4.9" in warned


def test_validate_is_quiet_when_the_figure_covers_it(tmp_path: Path) -> None:
    assert _warnings(_park_beside(tmp_path, "  position_error_m: 3.7\n")) == []


def test_the_separation_holds_on_the_truth_under_gps_error(tmp_path: Path) -> None:
    """Seed 109 draws two errors that point at each other: without a figure (the old
    behaviour, and the default) Slash B parks 2.5 m from Slash A's report and truly 0.9 m
    from Slash A, inside the 1 m separation, and the dry run's safety judgement, which
    measures the true tracks, fails the run. With each vehicle's 3.7 m declared the
    runtime keeps B 1 + 1 + 7.4 m from A's report, and the pair keeps its metre."""
    path = _park_beside(tmp_path, "  position_error_m: 3.7\n")
    out, err = io.StringIO(), io.StringIO()
    outcome = run_dry_run(path, seed=None, until_s=None, report=None, speed=None, out=out, err=err)
    assert outcome.safety is not None, err.getvalue()
    (pair,) = outcome.safety.pairs
    assert pair.limit_m == 1.0 and pair.distance_m is not None  # the truth's
    assert pair.distance_m > 5.0, pair.distance_m
    assert outcome.safety.passed and outcome.exit_code == 0, out.getvalue()


def test_validate_names_the_vehicle_whose_own_figure_is_short(tmp_path: Path) -> None:
    """An RTK figure on one truck, where the dry run gives it a plain GPS's walk."""
    path = _park_beside(tmp_path, "  position_error_m: 3.7\n")
    text = path.read_text(encoding="utf-8").replace(
        "    position: [-15, 0]\n",
        "    position: [-15, 0]\n    envelope: {position_error_m: 0.05}\n",
    )
    path.write_text(text, encoding="utf-8")
    (warned,) = _warnings(path)
    assert ": warning: agents.slash_b.envelope.position_error_m:" in warned
    assert "and slash_b declares a position error of 0.05 m" in warned


def test_validate_is_quiet_for_a_lone_vehicle(tmp_path: Path) -> None:
    path = _park_beside(tmp_path)
    text = path.read_text(encoding="utf-8")
    text = text[: text.index("  slash_b:\n")] + text[text.index("sim:\n") :]
    path.write_text(text.replace("  separation: [{between: [slash_a, slash_b], min_m: 1}]\n", ""))
    assert _warnings(path) == []
