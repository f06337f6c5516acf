"""clark analyze LOGDIR --checks MISSION: a mission's checks judged from a run's logs.

The strongest test flies missions in dry runs (which write every agent's real logs) and
asserts that the checks judged from those logs agree with the dry run's own verdicts.
The others use small logs written by hand: clocks with different origins, bad input.
"""

from __future__ import annotations

import io
import json
import shutil
from collections.abc import Callable, Mapping
from pathlib import Path
from typing import Any

import pytest

from clark_engine.behaviors.base import BehaviorRuntime as Primitive
from clark_engine.cli import main
from clark_engine.dryrun.command import run_dry_run
from clark_engine.expectations.from_logs import NO_SIGNALS, check_folder
from clark_engine.expectations.log_run import entered_states
from clark_engine.link.fleet import FleetTable
from clark_engine.mission.compiler import agent_config
from clark_engine.mission.geo import LocalPoint, to_global
from clark_engine.mission.model import Mission
from clark_engine.mission.validate import validate_path
from clark_engine.runtime.config import StateSpec, TransitionSpec, config_from_dict
from clark_engine.runtime.context import PrimitiveContext, Status
from clark_engine.runtime.machine import BehaviorMachine, StateChange

ROOT = Path(__file__).resolve().parent.parent
MISSIONS = ROOT / "missions"
GPS_MS = 1_400_000_000_000  # the station's GPS time at its t=0 in the hand-written logs

Verdicts = dict[str, str]


def table(text: str) -> Verdicts:
    """Check name -> verdict (``pass``, ``FAIL``, ``not evaluated``) from a checks table.

    Only the checks table: a dry run's output goes on with its safety judgement.
    """
    verdicts = {}
    for line in text.split("\nSafety (judged in every run):", 1)[0].splitlines():
        if line.startswith("| ") and not line.startswith("| check |"):
            cells = [cell.strip() for cell in line.strip("|").split(" | ")]
            verdicts[cells[0]] = cells[-1].replace("**", "")
    return verdicts


def mission_at(path: Path) -> Mission:
    validation = validate_path(path)
    assert validation.mission is not None
    return validation.mission


# -- 1. dry runs: the checks from the logs agree with the dry run's ----------------------


@pytest.fixture(scope="module")
def dry_run(
    tmp_path_factory: pytest.TempPathFactory,
) -> Callable[..., tuple[Path, Verdicts, int]]:
    """Run ``clark dry-run MISSION --report DIR [--fault F]`` once per mission and faults.

    Returns the report's logs folder, the dry run's verdicts and its exit code.
    """
    cache: dict[tuple[str, ...], tuple[Path, Verdicts, int]] = {}

    def run(mission: str, *faults: str) -> tuple[Path, Verdicts, int]:
        key = (mission, *faults)
        if key not in cache:
            report = tmp_path_factory.mktemp("report") / "r"
            args = ["dry-run", str(MISSIONS / mission), "--report", str(report), "-q"]
            for fault in faults:
                args += ["--fault", fault]
            out = io.StringIO()
            with pytest.MonkeyPatch.context() as patch:
                patch.setattr("sys.stdout", out)
                patch.setattr("sys.stderr", io.StringIO())
                code = main(args)
            cache[key] = (report / "logs", table(out.getvalue()), code)
        return cache[key]

    return run


CASES = [
    # two vehicles and a station: a distance, a state, no failsafe
    pytest.param("cooperative_follow.yaml", (), id="cooperative_follow"),
    # the station silent when the operator activates Slash B: every check fails
    pytest.param("cooperative_follow.yaml", ("station_silent@50-80",), id="station_silent"),
    # nested states in a sequence; its signal checks cannot be judged from logs
    pytest.param("supercub_sysid.yaml", (), id="supercub_sysid"),
    # an autopilot lost, a lost peer, separation of three rovers
    pytest.param("fault_lost_peer.yaml", (), id="fault_lost_peer"),
    # a failsafe hold; the station deaf for 30 s (positions from the vehicles' views)
    pytest.param("fault_station_loss.yaml", (), id="fault_station_loss"),
    # a parallel state (survey.tour and survey.photos) and a photo count
    pytest.param("anaconda_survey.yaml", (), id="anaconda_survey"),
]


@pytest.mark.parametrize(("mission", "faults"), CASES)
def test_the_logs_of_a_dry_run_give_its_verdicts(
    mission: str,
    faults: tuple[str, ...],
    dry_run: Callable[..., tuple[Path, Verdicts, int]],
    capsys: pytest.CaptureFixture[str],
) -> None:
    logs, expected, dry_code = dry_run(mission, *faults)
    capsys.readouterr()
    code = main(["analyze", str(logs), "--checks", str(MISSIONS / mission)])
    out, err = capsys.readouterr()
    assert "; skipped" not in err  # every line and row the engine wrote can be read
    got = table(out)
    assert list(got) == list(expected), out
    kinds = {
        str(c.get("name")): next(k for k in c if k not in ("name", "by_s"))
        for c in mission_at(MISSIONS / mission).checks
    }
    for name, verdict in expected.items():
        if kinds[name] == "signal":
            assert got[name] == "not evaluated", name  # never a pass on missing data
        else:
            assert got[name] == verdict, f"{name}: {out}"
    # The dry run's code also says whether it stayed in its envelope (its safety
    # judgement, which clark analyze --checks does not make): compare the checks'.
    checks_code = 1 if "FAIL" in expected.values() else 0
    assert code == checks_code
    assert dry_code >= checks_code
    assert "Traceback" not in err


def test_the_station_silent_run_fails_every_check(
    dry_run: Callable[..., tuple[Path, Verdicts, int]],
) -> None:
    """The failing case above really fails (so the agreement is not all passes)."""
    _, verdicts, code = dry_run("cooperative_follow.yaml", "station_silent@50-80")
    assert code == 1
    assert set(verdicts.values()) == {"FAIL"}


def test_the_rebuilt_recording_matches_the_dry_runs(tmp_path: Path) -> None:
    """States (with what each change entered), safety events and photos, one by one."""
    for name in ("anaconda_survey.yaml", "fault_lost_peer.yaml", "supercub_sysid.yaml"):
        report = tmp_path / name
        path = MISSIONS / name
        outcome = run_dry_run(
            path, seed=None, until_s=None, report=report, speed=None, out=io.StringIO(),
            err=io.StringIO(), quiet=True,
        )  # fmt: skip
        assert outcome.result is not None
        truth = outcome.result.recording
        rebuilt = check_folder(report / "logs", mission_at(path)).run.recording
        for agent, entries in truth.states.items():
            got = rebuilt.states[agent]
            assert [(e.event, e.active, set(e.entered)) for e in got] == [
                (e.event, e.active, set(e.entered)) for e in entries
            ], agent
            assert [e.time_s for e in got] == pytest.approx([e.time_s for e in entries], abs=1e-3)
        assert {a: [w for _, w in s] for a, s in rebuilt.safety.items()} == {
            a: [w for _, w in s] for a, s in truth.safety.items()
        }
        for agent, seen in rebuilt.safety.items():
            assert [t for t, _ in seen] == pytest.approx([t for t, _ in truth.safety[agent]], 1e-3)
        assert {a: len(p) for a, p in rebuilt.photos.items()} == {
            a: len(p) for a, p in truth.photos.items()
        }


# -- what a change entered, against the machine's own record -----------------------------


def _spec(tree: Mapping[str, Any], path: str = "") -> StateSpec:
    """A StateSpec from a compact dict: use, initial, states, parallel, final, on."""
    children = tuple(
        _spec(child, f"{path}.{name}" if path else name)
        for name, child in (tree.get("states") or {}).items()
    )
    transitions = tuple(
        TransitionSpec(event, target, None, "test") for event, target in tree.get("on", {}).items()
    )
    kind = "primitive" if tree.get("use") else "parallel" if tree.get("parallel") else "machine"
    kind = kind if children or tree.get("use") else "final"
    return StateSpec(
        name=path.rsplit(".", 1)[-1], path=path, kind=kind, primitive=tree.get("use"),
        params={}, block=None, initial=tree.get("initial"),
        parallel=bool(tree.get("parallel")), finish="all", final=bool(tree.get("final")),
        timeout_s=None, transitions=transitions, source="test", states=children,
    )  # fmt: skip


class _Done(Primitive):
    """Done at its first update."""

    def update(self, ctx: PrimitiveContext) -> Status:
        return Status.DONE


def _leaf(on: Mapping[str, str] | None = None, done: bool = False) -> dict[str, Any]:
    return {"use": "done" if done else "run", "on": dict(on or {})}


TREE = {
    "initial": "a",
    "states": {
        "a": {
            "initial": "b",
            "on": {"to_c": "a.b.c", "to_b": "a.b", "to_d": "a.b.d", "again": "a"},
            "states": {
                "b": {
                    "initial": "c",
                    "states": {
                        "c": _leaf({"self": "a.b.c", "deep": "x.y.z", "into": "s.p.later"}),
                        "d": _leaf({"up": "a.b"}),
                    },
                },
            },
        },
        "x": {
            "initial": "w",
            "states": {
                "w": _leaf(),
                "y": {"initial": "v", "states": {"v": _leaf(), "z": _leaf({"done": "a"}, True)}},
            },
        },
        "s": {
            "parallel": True,
            "on": {"again": "s", "to_leg2": "s.t.leg2", "to_t": "s.t"},
            "states": {
                "t": {
                    "initial": "leg",
                    "states": {
                        "leg": _leaf({"across": "s.p.later", "region": "s.p", "out": "a"}),
                        "leg2": _leaf(),
                    },
                },
                "p": {"initial": "now", "states": {"now": _leaf(), "later": _leaf()}},
            },
        },
    },
}

#: Event sequences from the start, each a fresh machine ("step": one tick, z is done).
SEQUENCES = [
    ["self", "to_d", "up", "to_d", "to_c", "to_b", "again"],  # itself, local, ancestors
    ["deep", "step"],  # into a deep target, then a done back to an ancestor
    ["into", "to_leg2", "to_t", "across", "again", "region", "out"],  # parallel states
]


@pytest.mark.parametrize("events", SEQUENCES, ids=["nested", "deep", "parallel"])
def test_what_each_change_entered_is_rebuilt_from_its_log_line(events: list[str]) -> None:
    """Every kind of transition the machine makes, against its own ``entered``.

    External (to itself, to an ancestor, a parent's to itself), local (a parent's to an
    active or inactive descendant), into a deep target and a parallel state through one
    region (the others start too), across regions, out of a parallel state, a done.
    """
    mission = mission_at(MISSIONS / "supercub_sysid.yaml")
    config = config_from_dict(agent_config(mission, mission.agents["cub"]))
    changes: list[StateChange] = []

    def make(state: StateSpec) -> Primitive:
        return _Done({}) if state.primitive == "done" else Primitive({})

    machine = BehaviorMachine(_spec(TREE), make, lambda *_: True, changes.append)
    ctx = PrimitiveContext(config, FleetTable(config.agent_id, config.mission_id, 3.0))
    machine.start(ctx)
    for event in events:
        if event == "step":
            machine.step(ctx)
        else:
            assert machine.dispatch(event, ctx), event
    assert len(changes) == len(events) + 1
    before: tuple[str, ...] = ()
    for change in changes:
        got = entered_states(change.event, change.target, before, change.active)
        assert got == set(change.entered), change
        before = change.active


def test_a_failed_primitive_enters_nothing() -> None:
    assert entered_states("failed", "a.b.c", ("a.b.c",), ("a.b.c",)) == set()


# -- 2. clocks: each agent's time mapped onto the station's through GPS time -------------


def header(agent: str, role: str, event: str = "log.open") -> str:
    return (
        f"t=0.000 gps_ms=- INFO {event}: logbook opened: clark_engine=0.1.0 "
        f"mission=cooperative-follow mission_id=521 agent={agent} agent_id=1 role={role} "
        "loop_hz=10.0 period_s=0.1 level=INFO"
    )


def line(t_s: float, offset_ms: int | None, where: str, message: str, level: str = "INFO") -> str:
    gps = "-" if offset_ms is None else str(round(GPS_MS + offset_ms + 1000 * t_s))
    return f"t={t_s:.3f} gps_ms={gps} {level} {where}: {message}"


def fleet_csv(rows: list[dict[str, Any]]) -> str:
    """A fleet CSV with the fleet table's real columns; cells not given are empty."""
    columns = ["now_s", *FleetTable.csv_header()]
    lines = [",".join(columns)]
    lines += [",".join(str(r.get(c, "")) for c in columns) for r in rows]
    return "\n".join(lines) + "\n"


def status(now_s: float, name: str, north_m: float, east_m: float, age_s: float) -> dict[str, Any]:
    lat, lon, _ = to_global(LocalPoint(north_m, east_m), ORIGIN)
    return {
        "now_s": now_s, "name": name, "agent_type": "vehicle", "lat_deg": round(lat, 7),
        "lon_deg": round(lon, 7), "alt_m": 0.0, "status_age_s": age_s,
    }  # fmt: skip


COOPERATIVE = MISSIONS / "cooperative_follow.yaml"
ORIGIN = mission_at(COOPERATIVE).origin
STATION_MS, SLASH_A_MS, SLASH_B_MS = 0, -3_000, 12_500  # GPS time at each one's t=0


#: The events the fixture's lines name, and what logs written before events named them
#: (``module.function``, docs/logs.md "Compatibility").
EVENTS = {
    "open": ("log.open", "logbook.__init__"),
    "change": ("behavior.change", "runtime._on_change"),
    "found": ("fleet.found", "runtime._fleet_events"),
    "command": ("station.command", "runtime._station_command"),
    "wait": ("launch.wait", "launch.update"),
}


def write_run(
    folder: Path,
    *,
    station: bool = True,
    gps: bool = True,
    station_shift_ms: int = 0,
    legacy: bool = False,
) -> Path:
    """Logs of cooperative_follow with three clocks: slash_a starts 3 s before the station,
    slash_b 12.5 s after it. The station sees slash_a only; slash_a sees slash_b.
    ``legacy``: lines name ``module.function`` as logs before events did."""
    folder.mkdir(exist_ok=True)
    name = {key: pair[legacy] for key, pair in EVENTS.items()}
    change = name["change"]

    def log(agent: str, role: str, *lines: str) -> None:
        first = header(agent, role, name["open"])
        (folder / f"{agent}.mission.log").write_text("\n".join([first, *lines]))

    def off(ms: int) -> int | None:
        return ms if gps else None

    a, b = off(SLASH_A_MS), off(SLASH_B_MS)
    if station:
        log(
            "mcs",
            "mcs",
            line(0.5, off(STATION_MS + station_shift_ms), name["found"], "found slash_a"),
            line(
                30.0,
                off(STATION_MS + station_shift_ms),
                name["command"],
                "operator: activate slash_b",
            ),
        )
        rows = [
            {"now_s": 0.1, "name": "slash_a"},  # heard, no Agent Status yet
            status(1.0, "slash_a", 0, 0, 0.25),
            status(1.1, "slash_a", 0, 0, 0.35),  # the same arrival again
            status(2.0, "slash_a", 10, 0, 0.2),
        ]
        (folder / "mcs.fleet.csv").write_text(fleet_csv(rows))
    log("slash_a", "vehicle", line(1.0, a, change, "start: (start) -> (behavior) (active: )"))
    rows = [status(5.0, "slash_b", -15, -10, 0.5), status(6.0, "slash_b", -5, -5, 0.1)]
    (folder / "slash_a.fleet.csv").write_text(fleet_csv(rows))
    log(
        "slash_b",
        "vehicle",
        line(0.04, None, name["wait"], "launch: the behaviour waits for the pilot to arm it"),
        line(5.0, b, change, "start: (start) -> (behavior) (active: idle)"),
        line(17.6, b, change, "activate: idle -> chase (active: chase)"),
        line(40.0, b, change, "done: chase -> parked (active: parked)"),
        # a GPS time far off (a clock step): the median offset ignores it
        line(41.0, off(SLASH_B_MS + 60_000), name["found"], "lost slash_a (silent 3 s)"),
    )
    return folder


def test_every_clock_is_mapped_onto_the_stations_through_gps_time(tmp_path: Path) -> None:
    run = check_folder(write_run(tmp_path / "logs"), mission_at(COOPERATIVE)).run
    assert {n: a.shift_s for n, a in run.agents.items()} == pytest.approx(
        {"mcs": 0.0, "slash_a": -3.0, "slash_b": 12.5}
    )
    assert "station mcs" in run.time_origin
    states = run.recording.states["slash_b"]
    assert [e.time_s for e in states] == pytest.approx([17.5, 30.1, 52.5])
    assert [(e.event, e.active) for e in states] == [
        ("start", ("idle",)),
        ("activate", ("chase",)),
        ("done", ("parked",)),
    ]
    assert [set(e.entered) for e in states] == [{"", "idle"}, {"chase"}, {"parked"}]
    assert run.recording.states["slash_a"][0].active == ("",)  # a one-primitive behaviour
    assert run.recording.states["slash_a"][0].time_s == pytest.approx(-2.0)
    # Positions on one grid: slash_a from the station (arrivals at 0.75 and 1.8 s, once
    # each), slash_b from slash_a's view (arrivals 4.5 and 5.9 s on its clock, -3 s).
    tracks = run.recording.tracks
    assert next(iter(tracks["slash_a"].samples()))[0] == pytest.approx(0.75)
    times = [t for t, *_ in tracks["slash_b"].samples()]
    assert times == pytest.approx([0.75, 1.5, 1.8, 2.9])
    a = list(tracks["slash_a"].samples())
    b = list(tracks["slash_b"].samples())
    assert a[-1][1:3] == pytest.approx((10.0, 0.0), abs=0.01)
    assert b[0][1] != b[0][1]  # NaN: slash_b not known yet at 0.75 s
    assert b[-1][1:3] == pytest.approx((-5.0, -5.0), abs=0.01)
    assert any("slash_b: positions from slash_a's fleet table" in n for n in run.notes)
    assert run.recording.end_s == pytest.approx(53.5)  # slash_b's last line, 41 + 12.5


def test_logs_written_before_events_are_read_alike(tmp_path: Path) -> None:
    """Lines naming ``module.function`` (clark_engine before events) rebuild the same run."""
    mission = mission_at(COOPERATIVE)
    new = check_folder(write_run(tmp_path / "new"), mission).run
    old = check_folder(write_run(tmp_path / "old", legacy=True), mission).run
    assert old.recording.states == new.recording.states
    assert old.recording.waiting == new.recording.waiting
    assert {n: a.header for n, a in old.agents.items()} == {
        n: a.header for n, a in new.agents.items()
    }
    assert not old.problems


def test_a_station_on_another_time_base_is_not_aligned_by_it(tmp_path: Path) -> None:
    """The station on the system clock, the vehicles on a simulated GPS clock 331 days
    behind: aligned by GPS time the run would span 331 days; each such agent keeps its
    own start instead, and a note says why."""
    logs = write_run(tmp_path / "logs", station_shift_ms=331 * 86_400_000)
    run = check_folder(logs, mission_at(COOPERATIVE)).run
    shifts = {n: a.shift_s for n, a in run.agents.items()}
    assert all(abs(s) < 60 for s in shifts.values()), shifts
    assert sum("331 days from the reference's" in n for n in run.notes) == 2
    assert run.recording.end_s < 3600


def test_without_a_station_log_t0_is_the_first_agent_to_start(tmp_path: Path) -> None:
    run = check_folder(write_run(tmp_path / "logs", station=False), mission_at(COOPERATIVE)).run
    assert {n: a.shift_s for n, a in run.agents.items()} == pytest.approx(
        {"slash_a": 0.0, "slash_b": 15.5}
    )
    assert "slash_a" in run.time_origin
    assert any("no station log" in n for n in run.notes)


def test_without_gps_time_each_agent_keeps_its_own_clock(tmp_path: Path) -> None:
    run = check_folder(write_run(tmp_path / "logs", gps=False), mission_at(COOPERATIVE)).run
    assert all(a.shift_s == 0 for a in run.agents.values())
    assert "own clock" in run.time_origin
    assert sum("no GPS time in its logs" in n for n in run.notes) == 3


def test_a_distance_before_a_vehicles_first_position_is_not_evaluated(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """slash_b's first position arrives at 1.5 s: a distance by 1 s cannot be judged."""
    mission = tmp_path / "early.yaml"
    mission.write_text(
        COOPERATIVE.read_text()
        + "  - {name: early, by_s: 1, distance_m: {between: [slash_b, slash_a], max: 100}}\n"
        + "  - {name: later, by_s: 3, distance_m: {between: [slash_b, slash_a], max: 100}}\n"
    )
    logs = write_run(tmp_path / "logs")
    code, out, _ = analyze(capsys, str(logs), "--checks", str(mission), "-q")
    verdicts = table(out)
    assert verdicts["early"] == "not evaluated"
    assert "not evaluated: no position of slash_b known by 1 s" in out
    assert verdicts["later"] == "pass"
    assert verdicts["Slash B parks"] == "pass"
    assert code == 0


# -- 3. bad input -------------------------------------------------------------------------


@pytest.fixture
def logs(dry_run: Callable[..., tuple[Path, Verdicts, int]], tmp_path: Path) -> Path:
    """A copy of cooperative_follow's dry-run logs, to spoil."""
    source, _, _ = dry_run("cooperative_follow.yaml")
    return Path(shutil.copytree(source, tmp_path / "logs"))


def analyze(capsys: pytest.CaptureFixture[str], *args: str) -> tuple[int, str, str]:
    capsys.readouterr()
    code = main(["analyze", *args])
    out, err = capsys.readouterr()
    assert "Traceback" not in out + err
    return code, out, err


def test_a_missing_folder_is_a_usage_error(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    code, _, err = analyze(capsys, str(tmp_path / "nowhere"), "--checks", str(COOPERATIVE))
    assert code == 2
    assert "no such folder" in err


def test_a_folder_without_the_missions_logs_says_so(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    (tmp_path / "logs").mkdir()
    (tmp_path / "logs" / "rover.mission.log").write_text(header("rover", "vehicle") + "\n")
    code, _, err = analyze(capsys, str(tmp_path), "--checks", str(COOPERATIVE), "-q")
    assert code == 1
    assert "no log of any agent of mission cooperative-follow (mcs, slash_a, slash_b)" in err
    assert "(it holds rover.mission.log); looked in it, its logs/ folder" in err


def test_logs_of_another_mission_are_refused(
    logs: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    code, _, err = analyze(capsys, str(logs), "--checks", str(MISSIONS / "fault_station_loss.yaml"))
    assert code == 1
    assert "logs are of mission 'cooperative-follow', not 'fault-station-loss'" in err


def test_a_garbled_row_is_a_warning_with_its_line_and_the_rest_is_evaluated(
    logs: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    fleet = logs / "mcs.fleet.csv"
    rows = fleet.read_text().splitlines(keepends=True)
    rows.insert(5, "12.5,2,slash_a,vehicle,ok\n")  # line 6: too few fields
    fleet.write_text("".join(rows))
    mission_log = logs / "slash_b.mission.log"
    mission_log.write_text(
        mission_log.read_text() + "t=oops gps_ms=- INFO x.y: z\nnot a log line\n"
    )
    lines = len(mission_log.read_text().splitlines())
    code, out, err = analyze(capsys, str(logs), "--checks", str(COOPERATIVE))
    assert code == 0
    width = len(FleetTable.csv_header()) + 1  # now_s and the fleet table's columns
    assert f"warning: {fleet}:6: expected {width} fields, found 5; skipped" in err
    assert f"warning: {mission_log}:{lines - 1}: t is 'oops', not a number; skipped" in err
    assert f"warning: {mission_log}:{lines}: not a log line" in err
    assert set(table(out).values()) == {"pass"}


def test_an_invalid_mission_exits_1(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    bad = tmp_path / "bad.yaml"
    bad.write_text(COOPERATIVE.read_text().replace("loop_hz: 10", "loop_hz: -10"))
    (tmp_path / "logs").mkdir()
    code, out, err = analyze(capsys, str(tmp_path / "logs"), "--checks", str(bad))
    assert code == 1
    assert "invalid; no check evaluated" in err
    assert out == ""


def test_checks_the_logs_cannot_support_are_not_evaluated_never_passed(
    logs: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """Missing files and a log level that hides the lines: not evaluated, with the reason."""
    mission = tmp_path / "more_checks.yaml"
    mission.write_text(
        COOPERATIVE.read_text()
        + "  - {name: few photos, photos: {agent: slash_b, max: 5}}\n"
        + "  - {name: apart, separation_m: {min: 0.1}}\n"
    )
    (logs / "slash_b.messages.csv").unlink()
    (logs / "mcs.fleet.csv").unlink()
    (logs / "slash_a.fleet.csv").unlink()  # slash_b is now seen by nobody
    quiet = (logs / "slash_b.mission.log").read_text().replace("level=INFO", "level=WARNING")
    (logs / "slash_b.mission.log").write_text(quiet)
    code, out, err = analyze(capsys, str(logs), "--checks", str(mission), "-q")
    verdicts = table(out)
    assert verdicts == {
        "Slash B reaches Slash A": "not evaluated",
        "Slash B parks": "not evaluated",
        "no failsafe": "pass",  # failsafes are ERROR lines, still in a WARNING log
        "few photos": "not evaluated",
        "apart": "not evaluated",
    }
    assert "not evaluated: no position of slash_b in the logs" in out
    assert "not evaluated: slash_b's logs are at level WARNING" in out
    assert "not evaluated: no slash_b.messages.csv in the folder" in out
    assert code == 0  # nothing evaluated failed
    assert "4 of 5 checks not evaluated" in err


def test_json_output(logs: Path, capsys: pytest.CaptureFixture[str]) -> None:
    code, out, _ = analyze(capsys, str(logs), "--checks", str(COOPERATIVE), "--format", "json")
    data = json.loads(out)
    assert code == 0
    assert data["mission"] == "cooperative-follow"
    assert [c["result"] for c in data["checks"]] == ["pass", "pass", "pass"]
    assert data["clocks"]["slash_b"]["shift_s"] == 0.0
    assert data["end_s"] == pytest.approx(170.0, abs=0.2)


def test_period_s_does_not_go_with_checks(logs: Path, capsys: pytest.CaptureFixture[str]) -> None:
    code, _, err = analyze(capsys, str(logs), "--checks", str(COOPERATIVE), "--period-s", "0.1")
    assert code == 2
    assert "--period-s" in err


def test_the_signal_check_is_never_judged_from_logs() -> None:
    assert "pulse widths" in NO_SIGNALS
