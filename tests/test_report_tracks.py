"""tracks.png: the paths and the closest approach; altitude.png: every vehicle's altitude.

The altitude plot shows every vehicle (rovers too, on the ground) against each
aircraft's ceiling and floor; it is written only when the fleet has an aircraft.
"""

from __future__ import annotations

import io
from pathlib import Path

from clark_engine.dryrun.command import run_dry_run
from clark_engine.dryrun.report_plots import altitude_figure, tracks_figure
from clark_engine.expectations.recording import Recording, Track
from clark_engine.expectations.safety import judge

ROOT = Path(__file__).resolve().parent.parent
THREE = ROOT / "missions" / "three_vehicles_payload.yaml"


def test_altitude_of_every_vehicle_against_the_ceiling() -> None:
    outcome = run_dry_run(
        THREE, seed=None, until_s=60.0, report=None, speed=None,
        out=io.StringIO(), err=io.StringIO(),
    )  # fmt: skip
    assert outcome.result is not None
    recording, configs = outcome.result.recording, outcome.result.configs
    kinds = {name: configs[name].airframe_class for name in recording.tracks}
    assert kinds == {"f450": "multirotor", "anaconda": "fixed_wing", "slash": "rover"}, kinds
    figure = altitude_figure(recording, configs, outcome.safety)
    assert figure is not None
    (altitude,) = figure.axes
    assert altitude.get_ylabel() == "altitude above origin (m)"
    assert altitude.get_xlabel() == "simulated time (s)"
    lines = {line.get_label(): line for line in altitude.get_lines()}
    for name in ("anaconda", "f450", "slash"):
        track = recording.tracks[name]
        assert list(lines[name].get_xdata()) == track.times_s
        assert list(lines[name].get_ydata()) == track.up_m
    # Both aircraft have the default ceiling, drawn once; the floor at the ground is not.
    ceiling = lines["ceiling 120 m (anaconda, f450)"]
    assert set(ceiling.get_ydata()) == {120.0}
    assert not any(label.startswith("floor") for label in lines)
    assert max(recording.tracks["anaconda"].up_m) > 20, "the plane flies"


def test_tracks_mark_the_closest_approach() -> None:
    outcome = run_dry_run(
        THREE, seed=None, until_s=60.0, report=None, speed=None,
        out=io.StringIO(), err=io.StringIO(),
    )  # fmt: skip
    assert outcome.result is not None and outcome.safety is not None
    closest = outcome.safety.closest_pair
    assert closest is not None and closest.distance_m is not None
    figure = tracks_figure(outcome.result.recording, outcome.result.configs, closest)
    (paths,) = figure.axes
    assert paths.get_xlabel() == "east of origin (m)"
    marked = [line for line in paths.get_lines() if line.get_label().startswith("closest: ")]
    assert len(marked) == 1
    label = marked[0].get_label()
    assert f"{closest.a} - {closest.b}, {closest.distance_m:.1f} m at {closest.time_s:.1f} s" in (
        label
    )
    # Both positions, east right and north up.
    assert list(marked[0].get_xdata()) == [closest.where_a[1], closest.where_b[1]]
    assert list(marked[0].get_ydata()) == [closest.where_a[0], closest.where_b[0]]


def test_no_altitude_plot_for_rovers_only() -> None:
    from clark_engine.mission.compiler import agent_config
    from clark_engine.runtime.config import config_from_dict
    from clark_engine.validation import validate_file

    follow = ROOT / "missions" / "cooperative_follow.yaml"
    mission = validate_file(follow, str(follow)).mission
    assert mission is not None
    configs = {
        name: config_from_dict(agent_config(mission, agent))
        for name, agent in mission.agents.items()
    }
    recording = Recording(end_s=1.0)
    for name in ("slash_a", "slash_b"):
        recording.tracks[name] = Track()
        recording.tracks[name].add(0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0)
    assert altitude_figure(recording, configs, judge(recording, configs)) is None
