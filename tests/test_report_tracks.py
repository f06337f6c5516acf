"""tracks.png shows the altitude of air vehicles (planes, multirotors), not of rovers."""

from __future__ import annotations

import io
from pathlib import Path

from clark_engine.sim.dryrun import run_dry_run
from clark_engine.sim.report import tracks_figure

ROOT = Path(__file__).resolve().parent.parent
THREE = ROOT / "missions" / "three_vehicles_payload.yaml"


def test_tracks_show_altitude_for_air_vehicles_only() -> None:
    outcome = run_dry_run(
        THREE, seed=None, until_s=60.0, report=None, speed=None,
        out=io.StringIO(), err=io.StringIO(),
    )  # fmt: skip
    assert outcome.result is not None
    recording, configs = outcome.result.recording, outcome.result.configs
    kinds = {name: configs[name].airframe_class for name in recording.tracks}
    assert kinds == {"f450": "multirotor", "anaconda": "fixed_wing", "slash": "rover"}, kinds
    figure = tracks_figure(recording, configs)
    paths, altitude = figure.axes
    assert paths.get_xlabel() == "east of origin (m)"
    assert altitude.get_ylabel() == "altitude above origin (m)"
    assert altitude.get_xlabel() == "simulated time (s)"
    lines = {line.get_label(): line for line in altitude.get_lines()}
    assert sorted(lines) == ["anaconda", "f450"]
    for name, line in lines.items():
        track = recording.tracks[name]
        assert list(line.get_xdata()) == track.times_s
        assert list(line.get_ydata()) == track.up_m
    assert max(recording.tracks["anaconda"].up_m) > 20, "the plane flies"
