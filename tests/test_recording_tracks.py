"""A dry run's tracks hold a bounded number of points, whatever the run's length.

Every sample goes to a file the checks read back; the lists the plots draw are
decimated past :data:`MAX_TRACK_POINTS` (issue 10, item 18). Points are counted, never
memory or time.
"""

from __future__ import annotations

import functools
import gc
import os
import pickle
from pathlib import Path

import pytest

from clark_engine.dryrun import engine
from clark_engine.dryrun.engine import SAMPLE_PERIOD_S, DryRun
from clark_engine.expectations.evaluate import evaluate
from clark_engine.expectations.recording import MAX_TRACK_POINTS, Track
from clark_engine.validation import validate_file

ROOT = Path(__file__).resolve().parent.parent
FOLLOW = ROOT / "missions" / "cooperative_follow.yaml"
ONE_ROVER = ROOT / "missions" / "single_vehicle_mode_change.yaml"


def _filled(n: int, capacity: int = MAX_TRACK_POINTS) -> Track:
    track = Track(capacity=capacity)
    for i in range(n):
        track.add(i * 0.1, float(i), -float(i), 1.0 + i % 7, 0.5, -0.5, float(i % 360))
    return track


def test_a_days_track_keeps_a_bounded_number_of_points() -> None:
    n = 24 * 3600 * 10 // 8  # three simulated hours at 10 Hz
    track = _filled(n)
    assert len(track.times_s) <= MAX_TRACK_POINTS
    assert len(track.times_s) > MAX_TRACK_POINTS // 4
    assert all(len(values) == len(track.times_s) for values in track._lists())
    assert track.times_s == sorted(track.times_s)
    assert track.times_s[0] == 0.0  # the start
    assert track.times_s[-1] == (n - 1) * 0.1  # and the latest sample
    assert track.count == n


@pytest.mark.parametrize("n", [0, 1, 7, 8, 9, 100, 4096, 4097, 20_000])
def test_every_sample_is_read_back_in_order(n: int) -> None:
    track = _filled(n, capacity=8)
    samples = list(track.samples())
    assert samples == [(i * 0.1, float(i), -float(i), 1.0 + i % 7) for i in range(n)]
    assert len(track.times_s) <= 8
    if n:
        assert track.at((n - 1) * 0.1) == samples[-1][1:]
        assert track.at(-1.0) is None


def test_a_short_track_keeps_every_sample_in_its_lists() -> None:
    track = _filled(5000)
    assert track.times_s == [i * 0.1 for i in range(5000)]
    assert track.yaw_deg == [float(i % 360) for i in range(5000)]


def test_a_track_sent_to_another_process_takes_its_file_along() -> None:
    track = _filled(10_000, capacity=16)
    copy = pickle.loads(pickle.dumps(track))
    assert copy == track
    assert list(copy.samples()) == list(track.samples())
    path = copy._path
    assert path is not None and os.path.exists(path)
    del track
    gc.collect()
    assert os.path.exists(path)  # the sender gave it up
    del copy
    gc.collect()
    assert not os.path.exists(path)  # the receiver deletes it


def test_a_long_dry_run_holds_a_bounded_recording() -> None:
    """A quarter of an hour of one rover: past the bound (the fleet's example took 18 s)."""
    mission = validate_file(ONE_ROVER).mission
    assert mission is not None
    until_s = 1.2 * MAX_TRACK_POINTS * SAMPLE_PERIOD_S
    result = DryRun(mission, ONE_ROVER, seed=1, until_s=until_s).run()
    for track in result.recording.tracks.values():
        assert track.count == round(until_s / SAMPLE_PERIOD_S) + 1
        assert len(track.times_s) <= MAX_TRACK_POINTS
    assert sum(len(s) for s in result.recording.states.values()) < 20


def test_checks_read_every_sample_not_the_decimated_lists(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    """Closest approach, reaching a point and separation: the same text at any capacity.

    Two hundred seconds are 2,000 samples a vehicle: 125 times the small capacity.
    """
    mission = validate_file(FOLLOW).mission
    assert mission is not None
    until_s = 200.0
    checks = [
        {"by_s": until_s, "distance_m": {"between": ["slash_b", "slash_a"], "max": 6}},
        {"by_s": 100.0, "distance_m": {"between": ["slash_a", "slash_b"], "min": 1}},
        {"by_s": until_s, "reached": {"agent": "slash_a", "to": [0, 0], "tolerance_m": 0.5}},
        {"separation_m": {"min": 1}},
    ]

    def results(capacity: int) -> list[tuple[str, bool]]:
        monkeypatch.setattr(engine, "Track", functools.partial(Track, capacity=capacity))
        run = DryRun(mission, FOLLOW, seed=1, until_s=until_s).run()
        if capacity < 1000:
            assert all(len(t.times_s) <= capacity for t in run.recording.tracks.values())
        found = evaluate(checks, run.recording, run.configs, mission.origin)
        return [(r.observed, r.passed) for r in found]

    assert results(16) == results(10**9)
