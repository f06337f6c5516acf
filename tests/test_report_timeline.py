"""timeline.png shows fault windows and failsafes, and no two of its labels overlap."""

from __future__ import annotations

import io
from itertools import combinations
from pathlib import Path
from typing import Any

from clark_engine.dryrun.command import parse_fault, run_dry_run
from clark_engine.dryrun.report import InjectedFault
from clark_engine.dryrun.report_plots import timeline_figure
from clark_engine.expectations.recording import Recording, StateEntry

ROOT = Path(__file__).resolve().parent.parent
LOST_PEER = ROOT / "missions" / "fault_lost_peer.yaml"


def label_boxes(figure: Any) -> list[tuple[str, Any]]:
    """Every visible label of the figure's axes and legends, with its box on the canvas."""
    figure.canvas.draw()
    renderer = figure.canvas.get_renderer()
    texts = []
    for ax in figure.axes:
        texts += list(ax.texts)
        legend = ax.get_legend()
        if legend is not None:
            texts += list(legend.get_texts())
    return [(t.get_text(), t.get_window_extent(renderer)) for t in texts if t.get_visible()]


def assert_no_overlap(figure: Any) -> None:
    boxes = label_boxes(figure)
    for (a, box_a), (b, box_b) in combinations(boxes, 2):
        assert not box_a.overlaps(box_b), (a, b)


def test_close_states_do_not_overlap_their_labels() -> None:
    """States every 3 s with long names: too close for every label on one line."""
    recording = Recording(end_s=60.0)
    for agent in ("alpha", "bravo"):
        recording.states[agent] = [
            StateEntry(3.0 * i, "next", (f"survey.leg_{i}.approach_the_waypoint",), ())
            for i in range(20)
        ]
    recording.safety["alpha"] = [(30.0, "failsafe hold"), (30.5, "autopilot_lost")]
    faults = [InjectedFault(parse_fault("station_silent@29-31"), "--fault station_silent@29-31")]
    figure = timeline_figure(recording, faults)
    assert_no_overlap(figure)
    shown = [text for text, _ in label_boxes(figure)]
    assert any(t.startswith("survey.leg_") for t in shown), "some state labels are kept"


def test_timeline_shows_fault_windows_and_failsafes() -> None:
    extra = ["station_silent@60-70"]
    outcome = run_dry_run(
        LOST_PEER, seed=None, until_s=90.0, report=None, speed=None, faults=extra,
        out=io.StringIO(), err=io.StringIO(),
    )  # fmt: skip
    assert outcome.result is not None
    recording = outcome.result.recording
    faults = [
        InjectedFault({"kill": {"agent": "slash_a", "at_s": 75}}, "mission"),
        InjectedFault(
            {"autopilot_disconnect": {"agent": "slash_c", "from_s": 65, "to_s": 80}}, "mission"
        ),
        InjectedFault({"corrupt": {"share": 0.2}}, "mission"),
        InjectedFault(parse_fault(extra[0]), f"--fault {extra[0]}"),
    ]  # fmt: skip
    figure = timeline_figure(recording, faults)
    (ax,) = figure.axes
    legend = [t.get_text() for t in ax.get_legend().get_texts()]
    assert "kill slash_a (at 75 s)" in legend
    assert "autopilot of slash_c disconnected (65 to 80 s)" in legend
    assert "20% of packets corrupted (the whole run s)" not in legend
    assert "20% of packets corrupted (the whole run)" in legend
    assert "stations silent (60 to 70 s)" in legend
    events = [(agent, t, what) for agent, seen in recording.safety.items() for t, what in seen]
    assert events, "the mission's faults set off failsafes"
    for agent, t, what in events:
        assert f"{agent}: {what} at {t:.1f} s" in legend
    assert_no_overlap(figure)
