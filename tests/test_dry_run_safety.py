"""Every dry run judges the envelope (issue 17 item 6), whether or not the mission checks it.

The done-when test flies a near miss no check asks about: the run fails with the pair,
the time and the place in the report. The judgement's rules are then held one by one
on recordings written sample by sample (ceiling, floor in guided flight, geofence
margin, endurance, pairs while either is armed), and its fence shortcut against the
plain minimum over every sample.
"""

from __future__ import annotations

import io
import math
from pathlib import Path

from hypothesis import example, given, settings
from hypothesis import strategies as st

from clark_engine.dryrun.command import run_dry_run
from clark_engine.dryrun.report_plots import tracks_figure
from clark_engine.expectations.recording import FlightEntry, Recording, StateEntry, Track
from clark_engine.expectations.safety import judge
from clark_engine.mission.compiler import agent_config
from clark_engine.runtime.config import AgentConfig, config_from_dict
from clark_engine.validation import validate_file

HERE = Path(__file__).resolve().parent
NEAR_MISS = HERE / "dryrun" / "near_miss.yaml"

MISSION = """\
clark: 1
mission: {id: 9, name: judged, loop_hz: 10, origin: {lat: 30.6372, lon: -96.4787, alt_amsl_m: 90}}
envelope:
  ceiling_m: 60
  floor_m: 20
  geofence:
    include: [{polygon: [[-50, -50], [50, -50], [50, 50], [-50, 50]]}]
  separation: [{between: [f450, slash], min_m: 10}]
agents:
  f450:
    id: 2
    profile: dji_f450
    launch: {armed_by: engine}
    envelope: {endurance_s: 100}
    telemetry: {heartbeat: 1, agent_status: 2}
    behavior:
      initial: climb
      states:
        climb: {use: takeoff, with: {alt_m: 25}, transitions: {done: cruise}}
        cruise: {use: waypoint, with: {to: [20, 0, 30]}, transitions: {done: down}}
        down: {use: land, final: true}
  slash:
    id: 3
    profile: traxxas_slash
    position: [0, 20]
    telemetry: {heartbeat: 1, agent_status: 2}
    behavior: {use: hold}
"""


def configs(tmp_path: Path, text: str = MISSION) -> dict[str, AgentConfig]:
    path = tmp_path / "m.yaml"
    path.write_text(text, encoding="utf-8")
    validation = validate_file(path, "m.yaml")
    mission = validation.mission
    assert mission is not None, [f.format_text() for f in validation.findings]
    return {n: config_from_dict(agent_config(mission, a)) for n, a in mission.agents.items()}


def track(*samples: tuple[float, float, float, float]) -> Track:
    out = Track()
    for t, north, east, up in samples:
        out.add(t, north, east, up, 0.0, 0.0, 0.0)
    return out


def flying(rec: Recording, name: str, *flight: tuple[float, bool, str]) -> None:
    rec.flight[name] = [FlightEntry(t, armed, mode) for t, armed, mode in flight]


def states(rec: Recording, name: str, *changes: tuple[float, str]) -> None:
    rec.states[name] = [StateEntry(t, "e", (path,), (path,)) for t, path in changes]


# -- the done-when test -------------------------------------------------------------------


def test_a_near_miss_fails_the_run_with_the_pair_time_and_place(tmp_path: Path) -> None:
    report = tmp_path / "report"
    out, err = io.StringIO(), io.StringIO()
    outcome = run_dry_run(
        NEAR_MISS, seed=None, until_s=None, report=report, speed=None, out=out, err=err
    )
    assert outcome.exit_code == 1, out.getvalue() + err.getvalue()
    # Every check the mission declares passes: the judgement alone fails the run.
    assert [r.passed for r in outcome.results] == [True] * 4
    safety, result = outcome.safety, outcome.result
    assert safety is not None and result is not None
    pair = safety.closest_pair
    assert pair is not None and pair.distance_m is not None
    assert (pair.a, pair.b, pair.limit_m) == ("slash_a", "slash_b", 5.0)
    assert pair.distance_m < 1.0, pair
    # The figures are the recording's: its closest sample, both positions at that time.
    a = {t: (n, e, u) for t, n, e, u in result.recording.tracks["slash_a"].samples()}
    b = {t: (n, e, u) for t, n, e, u in result.recording.tracks["slash_b"].samples()}
    closest_t = min(a, key=lambda t: math.dist(a[t], b[t]))
    assert pair.time_s == closest_t
    assert pair.where_a == a[closest_t] and pair.where_b == b[closest_t]
    assert pair.distance_m == math.dist(a[closest_t], b[closest_t])
    # Where: near the crossing of the two paths at the origin.
    assert math.hypot(*pair.where_a[:2]) < 2.0 and math.hypot(*pair.where_b[:2]) < 2.0
    when = f"at {pair.time_s:.1f} s"
    stderr = err.getvalue()
    assert "safety: 2 breaches; the run fails:" in stderr
    assert f"slash_a and slash_b came within {pair.distance_m:.1f} m of each other {when}" in (
        stderr
    )
    assert "under their 5 m separation" in stderr
    # Slash B's envelope allows 30 s armed; it was armed from its launch to the end.
    assert "slash_b was armed for" in stderr and "beyond its 30 s endurance" in stderr
    summary = (report / "summary.md").read_text(encoding="utf-8")
    assert "## Safety" in summary and "**2 breaches: the run fails.**" in summary
    row = next(line for line in summary.splitlines() if line.startswith("| slash_a - slash_b |"))
    assert f"{pair.distance_m:.1f} m" in row and f"{pair.time_s:.1f} s" in row
    assert "slash_a (" in row and "slash_b (" in row and row.endswith("| **FAIL** |")
    # The checks table is the checks' alone.
    checks = summary.split("## Checks", 1)[1].split("## Safety", 1)[0]
    assert "| A drives |" in checks and "slash_a - slash_b" not in checks
    assert (report / "tracks.png").stat().st_size > 0
    figure = tracks_figure(result.recording, result.configs, pair)
    labels = [line.get_label() for line in figure.axes[0].get_lines()]
    assert f"closest: slash_a - slash_b, {pair.distance_m:.1f} m {when}, under 5 m" in labels


# -- the rules, on recordings written sample by sample -----------------------------------------


def test_the_ceiling_breach_says_how_high_when_and_where(tmp_path: Path) -> None:
    rec = Recording(end_s=3.0)
    rec.tracks["f450"] = track((0, 0, 0, 0), (1, 5, 0, 30), (2, 6, 1, 61.5), (3, 6, 1, 40))
    flying(rec, "f450", (0, True, "GUIDED"))
    states(rec, "f450", (0, "cruise"))
    (f450,) = judge(rec, configs(tmp_path)).vehicles
    assert f450.highest is not None and f450.highest.value == 61.5
    assert f450.breaches == [
        "f450 climbed to 61.5 m above the origin at 2.0 s at (6.0, 1.0, 61.5), above its "
        "60 m ceiling"
    ]


def test_the_floor_holds_in_guided_flight_once_above_it(tmp_path: Path) -> None:
    config = configs(tmp_path)
    # Climbing through the floor, even in guided flight after its takeoff, is no breach;
    # nor is anything below it in LOITER, or while landing.
    rec = Recording(end_s=9.0)
    rec.tracks["f450"] = track(
        (0, 0, 0, 0), (1, 0, 0, 10), (2, 0, 0, 15), (3, 0, 0, 25), (4, 0, 0, 12),
        (5, 0, 0, 24), (6, 0, 0, 5), (7, 0, 0, 0),
    )  # fmt: skip
    flying(rec, "f450", (0, True, "GUIDED"), (4, True, "LOITER"), (5, True, "GUIDED"))
    states(rec, "f450", (0, "climb"), (1.5, "cruise"), (6, "down"))
    (f450,) = judge(rec, config).vehicles
    assert f450.lowest_guided is not None and f450.lowest_guided.value == 24.0
    assert f450.passed, f450.breaches
    # Below it in guided flight, after being above it: a breach, with when and where.
    rec.tracks["f450"] = track((0, 0, 0, 0), (3, 0, 0, 25), (4, 3, 4, 18.5), (5, 0, 0, 25))
    flying(rec, "f450", (0, True, "GUIDED"))
    states(rec, "f450", (0, "climb"), (2, "cruise"))
    (f450,) = judge(rec, config).vehicles
    assert f450.breaches == [
        "f450 flew guided at 18.5 m above the origin at 4.0 s at (3.0, 4.0, 18.5), below its "
        "20 m floor"
    ]
    # Each flight waits for its own climb above the floor: disarmed and armed again.
    rec.tracks["f450"] = track((0, 0, 0, 25), (1, 0, 0, 0), (2, 0, 0, 10), (3, 0, 0, 25))
    flying(rec, "f450", (0, True, "GUIDED"), (1, False, "GUIDED"), (2, True, "GUIDED"))
    states(rec, "f450", (0, "cruise"))
    (f450,) = judge(rec, config).vehicles
    assert f450.passed and f450.lowest_guided is not None
    assert f450.lowest_guided.value == 25.0


def test_the_fence_margin_where_and_when(tmp_path: Path) -> None:
    rec = Recording(end_s=3.0)
    rec.tracks["f450"] = track((0, 0, 0, 30), (1, 45, 0, 30), (2, 55, 10, 30), (3, 40, 0, 30))
    flying(rec, "f450", (0, True, "GUIDED"))
    (f450,) = judge(rec, configs(tmp_path)).vehicles
    assert f450.fence is not None and f450.fence.value == -5.0
    assert f450.breaches == ["f450 was 5.0 m outside its geofence at 2.0 s at (55.0, 10.0, 30.0)"]


def test_endurance_is_time_armed(tmp_path: Path) -> None:
    rec = Recording(end_s=200.0)
    rec.tracks["f450"] = track((0, 0, 0, 0), (200, 0, 0, 0))
    flying(rec, "f450", (0, False, "GUIDED"), (10, True, "GUIDED"), (70, False, "GUIDED"),
           (100, True, "GUIDED"))  # fmt: skip
    (f450,) = judge(rec, configs(tmp_path)).vehicles
    # 60 s, then 100 s more to the end: its 100 s were used up 40 s into the second.
    assert f450.armed_s == 160.0 and f450.endurance_over_s == 140.0
    assert f450.breaches == [
        "f450 was armed for 160.0 s, beyond its 100 s endurance from 140.0 s on"
    ]


def test_a_pair_counts_while_either_is_armed(tmp_path: Path) -> None:
    config = configs(tmp_path)
    rec = Recording(end_s=3.0)
    # Parked 3 m apart, both disarmed: no near miss. Then the copter is armed and lifts
    # off: 3-D, against the pair's own 10 m.
    rec.tracks["f450"] = track((0, 0, 0, 0), (1, 0, 0, 0), (2, 0, 0, 4), (3, 0, 0, 30))
    rec.tracks["slash"] = track((0, 0, 3, 0), (1, 0, 3, 0), (2, 0, 3, 0), (3, 0, 3, 0))
    flying(rec, "f450", (0, False, "STABILIZE"), (2, True, "GUIDED"))
    flying(rec, "slash", (0, False, "MANUAL"))
    (pair,) = judge(rec, config).pairs
    assert pair.limit_m == 10.0 and pair.distance_m == 5.0 and pair.time_s == 2.0
    assert pair.breach == (
        "f450 and slash came within 5.0 m of each other at 2.0 s (f450 at (0.0, 0.0, 4.0), "
        "slash at (0.0, 3.0, 0.0)), under their 10 m separation"
    )
    flying(rec, "f450", (0, False, "STABILIZE"))
    (pair,) = judge(rec, config).pairs
    assert pair.distance_m is None and pair.passed


def test_a_rover_is_not_held_to_a_ceiling(tmp_path: Path) -> None:
    rec = Recording(end_s=1.0)
    rec.tracks["slash"] = track((0, 0, 20, 95.0), (1, 0, 20, 95.0))  # a height it cannot fly
    flying(rec, "slash", (0, True, "GUIDED"))
    (slash,) = judge(rec, configs(tmp_path)).vehicles
    assert not slash.aircraft and slash.passed


@settings(max_examples=40, deadline=None)
@given(
    st.lists(st.tuples(st.floats(-8, 8), st.floats(-8, 8)), min_size=1, max_size=300),
    st.floats(-60, 60),
    st.floats(-60, 60),
)
# Out near the edge, back in, then straight out further in one long step: the step it
# may skip is the one that could be the smallest.
@example([(0.0, 0.0), (45.0, 0.0), (-25.0, 0.0), (28.0, 0.0)], 0.0, 0.0)
def test_the_fence_shortcut_finds_the_smallest_margin(
    steps: list[tuple[float, float]], north: float, east: float
) -> None:
    """Margins are skipped where they cannot be the smallest; the result is every sample's."""
    config = CONFIGS["f450"]
    rec = Recording(end_s=float(len(steps)))
    samples = []
    for i, (dn, de) in enumerate(steps):
        north, east = north + dn, east + de
        samples.append((float(i), north, east, 30.0))
    rec.tracks["f450"] = track(*samples)
    (f450,) = judge(rec, {"f450": config}).vehicles
    assert config.envelope is not None
    margins = [config.envelope.fence.margin_m(n, e) for _, n, e, _ in samples]
    assert f450.fence is not None and f450.fence.value == min(margins)
    assert f450.fence.time_s == samples[margins.index(min(margins))][0]


def _configs_once() -> dict[str, AgentConfig]:
    import tempfile

    with tempfile.TemporaryDirectory() as folder:
        return configs(Path(folder))


CONFIGS = _configs_once()
