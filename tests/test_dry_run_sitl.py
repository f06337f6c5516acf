"""``clark dry-run --autopilot sitl``: the same mission on real ArduPilot, compared.

The comparison of the two runs' state timelines (:mod:`clark_engine.sim.timeline`)
and the command line's rules are tested without SITL. The example missions are
then flown on real ArduPilot SITL (ArduRover, ArduCopter) at its speed-up: each
passes its checks there too, and enters the same states as on the simulated
autopilot within the tolerance. Those tests skip without SITL (CI has it).
"""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import pytest
from sitl_here import real_install

from clark_engine.sim.recording import Recording, StateEntry
from clark_engine.sim.sitl import ENV_SITL
from clark_engine.sim.timeline import compare

ROOT = Path(__file__).resolve().parent.parent
MISSIONS = ROOT / "missions"


def recording(**agents: list[tuple[float, tuple[str, ...]]]) -> Recording:
    """A recording whose agents entered the given states at the given times."""
    rec = Recording()
    for agent, entries in agents.items():
        rec.states[agent] = [StateEntry(t, "e", paths, paths) for t, paths in entries]
    return rec


# -- the comparison ------------------------------------------------------------------------


def test_the_same_states_within_the_tolerance_hold() -> None:
    sim = recording(a=[(42.0, ("", "ready")), (50.0, ("climb",)), (60.0, ("out",))])
    sitl = recording(a=[(41.0, ("", "ready")), (50.0, ("climb",)), (66.0, ("out",))])
    result = compare(sim, sitl, ["a"], tolerance_s=10.0)
    assert result.holds
    check = result.check()
    assert check.passed
    assert check.observed == "4 states matched; largest difference 6.0 s"
    assert "| a | out | 60.0 s | 66.0 s | +6.0 s |" in result.table()
    assert "| a | (the whole behaviour) | 42.0 s | 41.0 s | -1.0 s |" in result.table()


def test_a_state_too_late_fails_and_says_by_how_much() -> None:
    sim = recording(a=[(42.0, ("ready",)), (60.0, ("out",))])
    sitl = recording(a=[(42.0, ("ready",)), (72.5, ("out",))])
    check = compare(sim, sitl, ["a"], tolerance_s=10.0).check()
    assert not check.passed
    assert check.observed == "a out +12.5 s"


def test_a_state_one_run_never_entered_fails() -> None:
    sim = recording(a=[(42.0, ("ready",)), (60.0, ("out",))], b=[(1.0, ("idle",))])
    sitl = recording(a=[(42.0, ("ready",)), (50.0, ("stuck",))], b=[(1.0, ("idle",))])
    result = compare(sim, sitl, ["a", "b"])
    assert [(r.agent, r.path) for r in result.missing] == [("a", "out"), ("a", "stuck")]
    assert result.check().observed == (
        "a out never entered in SITL; a stuck never entered in the simulated run"
    )


def test_states_entered_in_another_order_fail() -> None:
    sim = recording(a=[(1.0, ("x",)), (2.0, ("y",))])
    sitl = recording(a=[(1.0, ("y",)), (2.0, ("x",))])
    result = compare(sim, sitl, ["a"])
    assert result.out_of_order == ("a",)
    assert not result.check().passed


def test_only_first_entries_count_and_a_run_ended_early_is_compared_up_to_its_end() -> None:
    # a tour re-enters its states lap after lap; only the first entry says anything
    sim = recording(a=[(1.0, ("x",)), (2.0, ("y",)), (3.0, ("x",)), (90.0, ("z",))])
    sitl = recording(a=[(1.5, ("x",)), (2.5, ("y",)), (9.0, ("x",))])
    assert not compare(sim, sitl, ["a"]).holds  # z: never entered on SITL
    assert compare(sim, sitl, ["a"], end_s=50.0).holds  # Ctrl-C at 50 s: z was still to come
    early = compare(sim, sitl, ["a"], end_s=0.5).check()  # Ctrl-C before anything happened
    assert (early.observed, early.passed) == ("no state entered in either run (yet)", True)


# -- the command line ----------------------------------------------------------------------


def clark(*args: str, env: dict[str, str] | None = None) -> subprocess.CompletedProcess[str]:
    return subprocess.run(
        [sys.executable, "-m", "clark_engine", "dry-run", *args],
        cwd=ROOT,
        capture_output=True,
        text=True,
        timeout=600,
        check=False,
        env=env,
    )


@pytest.mark.parametrize(
    ("args", "message"),
    [
        (["--sitl", "x"], "--sitl only applies with --autopilot sitl"),
        (["--sitl-speedup", "5"], "--sitl-speedup only applies with --autopilot sitl"),
        (["--autopilot", "sitl", "--speed", "2"], "SITL sets the pace"),
        (
            ["--autopilot", "sitl", "--realtime", "--mavlink-port", "14560"],
            "--mavlink-port does not go with --realtime --autopilot sitl",
        ),
        (["--autopilot", "sitl", "--sitl", "/nowhere/at/all"], "--sitl /nowhere/at/all: not found"),
        (["--autopilot", "sitl", "--sitl-speedup", "0"], "must be a number > 0"),
    ],
)
def test_usage_errors_exit_2_with_a_message(args: list[str], message: str) -> None:
    run = clark(str(MISSIONS / "single_vehicle_mode_change.yaml"), *args)
    assert run.returncode == 2, run.stderr
    assert message in run.stderr
    assert "Traceback" not in run.stderr


def test_no_sitl_anywhere_says_where_to_point() -> None:
    env = {k: v for k, v in os.environ.items() if k != ENV_SITL}
    run = clark(str(MISSIONS / "single_vehicle_mode_change.yaml"), "--autopilot", "sitl", env=env)
    assert run.returncode == 2
    assert "pass --sitl PATH or set CLARK_SITL" in run.stderr


# -- on real ArduPilot SITL ------------------------------------------------------------------


REAL = real_install()
needs_sitl = pytest.mark.skipif(
    REAL is None,
    reason=f"no ArduPilot SITL: set {ENV_SITL} to the folder with the `sitl` launcher",
)
SPEEDUP = os.environ.get("CLARK_SITL_SPEEDUP_TESTS", "10")
"""SITL's speed-up in these tests: the run's pace (10 keeps ArduPilot's loops on time on a
busy 2-core machine)."""


def comparison_row(stdout: str) -> str:
    """The checks table's last row: the SITL comparison (the safety tables follow it)."""
    checks = stdout.split("\nSafety (judged in every run):", 1)[0]
    last = checks.strip().splitlines()[-1]
    assert last.startswith("| the same mission on ArduPilot SITL |"), stdout
    return last


def on_sitl(mission: Path, tmp_path: Path, *args: str) -> subprocess.CompletedProcess[str]:
    assert REAL is not None
    return clark(
        str(mission),
        "--autopilot",
        "sitl",
        "--sitl",
        str(REAL.folder),
        "--sitl-speedup",
        SPEEDUP,
        "--report",
        str(tmp_path / "report"),
        *args,
    )


@pytest.mark.sitl
@needs_sitl
@pytest.mark.parametrize(
    "mission",
    [
        "single_vehicle_mode_change.yaml",  # ArduRover: pilot-armed, guided, back to MANUAL
        "cooperative_follow.yaml",  # two ArduRovers and a station: follow over the radio
        "copter_takeoff_land.yaml",  # ArduCopter: engine-armed takeoff, legs, land, disarm
    ],
)
def test_the_example_flies_on_sitl_as_on_the_simulated_autopilot(
    mission: str, tmp_path: Path
) -> None:
    path = MISSIONS / mission
    run = on_sitl(path, tmp_path)
    assert run.returncode == 0, run.stdout + run.stderr
    last = comparison_row(run.stdout)
    assert last.endswith("| pass |")
    assert "Safety (judged in every run):" in run.stdout
    assert "on ArduPilot SITL at" in run.stderr
    summary = (tmp_path / "report" / "summary.md").read_text(encoding="utf-8")
    assert "## ArduPilot SITL against the simulated autopilot" in summary
    # the engine's logs name the real firmware: this was not the simulated autopilot
    logs = (tmp_path / "report" / "logs").glob("*.interface.log")
    assert any("answers: ArduPilot 4." in log.read_text(encoding="utf-8") for log in logs)


@pytest.mark.sitl
@needs_sitl
def test_a_copter_its_pilot_arms_takes_off_on_sitl(tmp_path: Path) -> None:
    """Issue 17 item 7 on real ArduCopter: the pilot arms at the ready light, it takes off.

    Armed on a streamed GPS position (about 25 s), ArduCopter disarmed it at 35 s, before
    the engine's behaviour could start; the run said so and failed.
    """
    mission = ROOT / "tests" / "dryrun" / "copter_pilot_takeoff.yaml"
    run = on_sitl(mission, tmp_path)
    assert run.returncode == 0, run.stdout + run.stderr
    row = next(line for line in run.stdout.splitlines() if line.startswith("| takes off |"))
    assert "| entered at " in row and row.endswith("| pass |")
    assert comparison_row(run.stdout).endswith("| pass |")
    # Its arming comes from ArduCopter's own HEARTBEAT: the judgement counts it armed.
    f450 = next(line for line in run.stdout.splitlines() if line.startswith("| f450 |"))
    armed_s = float(f450.split(" | ")[4].split(" s ")[0])
    assert 30.0 < armed_s < 60.0, f450


@pytest.mark.sitl
@needs_sitl
def test_a_simulation_kinder_than_sitl_fails_the_comparison(tmp_path: Path) -> None:
    # sim.autopilot_ready_s makes the simulated rover ready at 2 s; ArduRover takes ~42 s,
    # more than even the mission's own, wider tolerance
    text = (MISSIONS / "single_vehicle_mode_change.yaml").read_text(encoding="utf-8")
    quick = tmp_path / "quick.yaml"
    quick.write_text(
        text.replace("sim: {", "sim: {autopilot_ready_s: 2, ").replace(
            "sitl_tolerance_s: 10", "sitl_tolerance_s: 30"
        ),
        encoding="utf-8",
    )
    assert "autopilot_ready_s: 2, " in quick.read_text(encoding="utf-8")
    assert "sitl_tolerance_s: 30" in quick.read_text(encoding="utf-8")
    run = on_sitl(quick, tmp_path, "--until", "50")
    assert run.returncode == 1
    assert "sim.autopilot_ready_s (2 s) speeds up the simulated autopilot only" in run.stderr
    last = comparison_row(run.stdout)
    assert last.endswith("| **FAIL** |")
    assert "each within 30 s" in last
    assert "slash ready +" in last
