"""clark dry-run end to end: every example passes its own checks, runs are reproducible.

These run the real thing: every agent's runtime, ClarkLink over the simulated mesh,
MAVLink through pymavlink to the simulated autopilots. The shorter runs keep the
suite quick; the examples run for their declared duration.
"""

from __future__ import annotations

import io
import subprocess
import sys
from pathlib import Path

import pytest

from clark_engine.dryrun.command import parse_fault, run_dry_run
from clark_engine.dryrun.engine import DryRun
from clark_engine.errors import UsageError
from clark_engine.validation import validate_file

ROOT = Path(__file__).resolve().parent.parent
MISSIONS = sorted((ROOT / "missions").glob("*.yaml"))
FOLLOW = ROOT / "missions" / "cooperative_follow.yaml"


#: Examples that fail the dry run's safety judgement, and why (the mission change is pending).
def dry_run(path: Path, **kwargs: object) -> tuple[int, str, str]:
    """Run in process; the exit code, the checks table and the diagnostics."""
    out, err = io.StringIO(), io.StringIO()
    options: dict[str, object] = {"seed": None, "until_s": None, "report": None, "speed": None}
    options.update(kwargs)
    outcome = run_dry_run(path, out=out, err=err, **options)  # type: ignore[arg-type]
    return outcome.exit_code, out.getvalue(), err.getvalue()


def checks_part(table: str) -> str:
    """The checks table of a dry run's output (the safety tables follow it)."""
    return table.split("\nSafety (judged in every run):", 1)[0]


@pytest.mark.parametrize("path", MISSIONS, ids=[p.stem for p in MISSIONS])
def test_every_example_passes_its_checks_and_stays_in_its_envelope(path: Path) -> None:
    code, table, err = dry_run(path)
    checks = checks_part(table)
    assert "| pass |" in checks and "FAIL" not in checks, table + err
    rows = [line for line in checks.splitlines() if line.startswith("| ") and "---" not in line]
    assert len(rows) >= 3, "an example checks what it demonstrates"
    assert "Safety (judged in every run):" in table
    assert code == 0, table + err  # no breach either


def test_examples_cover_the_faults() -> None:
    """The shipped examples show every kind of fault the dry run injects."""
    text = "\n".join(p.read_text() for p in MISSIONS)
    for kind in ("station_silent:", "kill:", "autopilot_disconnect:", "corrupt:"):
        assert kind in text, kind


def report_files(folder: Path) -> dict[str, bytes]:
    return {
        str(p.relative_to(folder)): p.read_bytes()
        for p in sorted(folder.rglob("*"))
        if p.is_file() and p.suffix in (".csv", ".log")
    }


def test_same_seed_gives_byte_identical_logs(tmp_path: Path) -> None:
    first, second, other = tmp_path / "a", tmp_path / "b", tmp_path / "c"
    for folder, seed in ((first, 7), (second, 7), (other, 8)):
        code, _, _ = dry_run(FOLLOW, seed=seed, until_s=40.0, report=folder)
        assert code in (0, 1)
    a, b = report_files(first), report_files(second)
    assert a and a.keys() == b.keys()
    for name in a:
        assert a[name] == b[name], name
    assert report_files(other) != a, "the seed changes the noise"


#: One fault of every kind the dry run injects, in a seven-agent fleet (below).
EVERY_FAULT = [
    {"kill": {"agent": "v003", "at_s": 6.0}},
    {"link_drop": {"between": ["v002", "v005"], "from_s": 2.0, "to_s": 8.0}},
    {"corrupt": {"share": 0.3, "from_s": 1.0, "to_s": 12.0}},
    {"station_silent": {"from_s": 9.0, "to_s": 12.0}},
    {"autopilot_disconnect": {"agent": "v004", "from_s": 3.0, "to_s": 7.0}},
]


def xbee_fleet(tmp_path: Path) -> Path:
    """Seven agents of benchmarks/fleet.py on one XBee mesh (aircraft handed over in flight)."""
    sys.path.insert(0, str(ROOT / "benchmarks"))
    try:
        from fleet import fleet_mission
    finally:
        sys.path.pop(0)
    path = tmp_path / "fleet.yaml"
    path.write_text(fleet_mission(7, radio="xbee"))
    return path


def test_every_fault_kind_is_reproduced_byte_for_byte(tmp_path: Path) -> None:
    """The same seed and faults give the same logs, recording and link counts.

    Each kind of fault changes what crosses the radio (a dead radio, a dropped link,
    flipped bytes, a silent station, an autopilot out of reach): none of it may depend
    on anything but the seed. (The removed process split's tests checked this across
    processes.)
    """
    path = xbee_fleet(tmp_path)
    validation = validate_file(path, str(path))
    assert validation.mission is not None, [f.format_text() for f in validation.findings]
    runs = []
    for name in ("a", "b"):
        (tmp_path / name).mkdir()
        run = DryRun(
            validation.mission,
            path,
            seed=11,
            until_s=14.0,
            log_dir=tmp_path / name,
            extra_faults=EVERY_FAULT,
        )
        runs.append(run.run())
    first, again = runs
    files = [
        {str(p.relative_to(d)): p.read_bytes() for p in sorted(d.rglob("*")) if p.is_file()}
        for d in (tmp_path / "a", tmp_path / "b")
    ]
    assert files[0] and files[0] == files[1]
    assert first.recording == again.recording
    assert first.radio.links() == again.radio.links()
    assert first.ticks == again.ticks
    # Not vacuous: the faults acted on packets.
    totals = first.radio.totals()
    assert totals.delivered > 100
    assert totals.corrupted > 0 and totals.lost_fault > 0
    assert first.recording.killed == {"v003": 6.0}


def test_report_has_summary_plots_and_logs(tmp_path: Path) -> None:
    folder = tmp_path / "report"
    code, _, err = dry_run(FOLLOW, report=folder)
    assert code == 0
    assert f"report: {folder / 'summary.md'}" in err
    for name in ("summary.md", "tracks.png", "timeline.png"):
        assert (folder / name).stat().st_size > 0, name
    assert (folder / "tracks.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    summary = (folder / "summary.md").read_text()
    assert "Slash B reaches Slash A" in summary and "pass" in summary
    assert "## Safety" in summary and "No breach." in summary
    # Only aircraft make the altitude plot worth drawing: two rovers have none.
    assert not (folder / "altitude.png").exists()
    # Slash A's behaviour is one block: its state is the root, named rather than blank.
    assert "| slash_a | start | (the whole behaviour) |" in summary
    assert "| slash_b | activate | chase |" in summary
    # The links section names the report's own logs folder, not where it was staged.
    assert "\nlogs: 3 agent(s) (mcs, slash_a, slash_b)" in summary
    assert ".incomplete" not in summary and str(tmp_path) not in summary.split("\n", 3)[3]
    for agent in ("mcs", "slash_a", "slash_b"):
        for kind in ("mission.log", "messages.csv", "fleet.csv"):
            assert (folder / "logs" / f"{agent}.{kind}").exists(), (agent, kind)


def test_sysid_report_plots_the_control_inputs(tmp_path: Path) -> None:
    folder = tmp_path / "report"
    code, _, _ = dry_run(ROOT / "missions" / "supercub_sysid.yaml", report=folder)
    assert code == 0
    assert (folder / "inputs.png").stat().st_size > 0


def test_failed_check_exits_1(tmp_path: Path) -> None:
    mission = tmp_path / "m.yaml"
    text = FOLLOW.read_text().replace("by_s: 120, distance_m", "by_s: 5, distance_m")
    mission.write_text(text)
    code, table, err = dry_run(mission)
    assert code == 1
    assert "**FAIL**" in table and "1 of 3 checks failed" in err


def test_checks_past_until_are_not_evaluated_and_do_not_fail_the_run(tmp_path: Path) -> None:
    # --until 40 ends the run before the checks' by_s (120 s): they were not judged, so
    # the table says so, the run does not exit 1 for them, and the summary agrees.
    code, table, err = dry_run(FOLLOW, until_s=40.0, report=tmp_path / "out")
    rows = [line for line in table.splitlines() if line.startswith("| Slash B")]
    assert len(rows) == 2 and all(row.endswith("| not evaluated |") for row in rows), rows
    assert "**FAIL**" not in table
    assert code == 0
    assert "2 of 3 checks not evaluated" in err
    summary = (tmp_path / "out" / "summary.md").read_text()
    assert "1 of 3 checks pass (no check failed, 2 not evaluated" in summary


def test_a_photo_count_on_a_run_cut_short_is_not_evaluated() -> None:
    """--until 60 of anaconda_survey's 150 s: 'min 14 photos' may still come (not
    evaluated, not a failure); the run exits 0 (before: FAIL, exit 1)."""
    code, table, err = dry_run(ROOT / "missions" / "anaconda_survey.yaml", until_s=60.0)
    (row,) = [line for line in table.splitlines() if line.startswith("| a photo every 5 s")]
    assert row.endswith("| not evaluated |"), row
    assert "the run ended at 60 s, before its planned end at 150 s" in row
    assert code == 0, table + err


def test_a_state_reached_late_says_so(tmp_path: Path) -> None:
    """Slash B parks near 100 s; a check that wants it by 80 s fails saying when it did
    (before: "not reached (last: chase)", as if it never had)."""
    mission = tmp_path / "m.yaml"
    text = FOLLOW.read_text().replace(
        "{name: Slash B parks, by_s: 120,", "{name: Slash B parks, by_s: 80,"
    )
    assert text != FOLLOW.read_text()
    mission.write_text(text)
    code, table, _ = dry_run(mission)
    (row,) = [line for line in table.splitlines() if line.startswith("| Slash B parks")]
    assert "reached late, at " in row and "(by 80 s: chase)" in row, row
    assert row.endswith("| **FAIL** |") and code == 1


def test_operator_actions_after_the_end_are_said_not_played() -> None:
    """cooperative_follow activates Slash B at 65 s: a run to 40 s says it never came."""
    _, _, err = dry_run(FOLLOW, until_s=40.0)
    assert "operator: 1 action(s) not played: the run ended at 40 s, before them (the " in err
    assert "first at 65 s)" in err
    _, _, err = dry_run(FOLLOW, until_s=70.0)
    assert "not played" not in err


def test_a_sequence_out_of_order_fails(tmp_path: Path) -> None:
    mission = tmp_path / "m.yaml"
    sysid = ROOT / "missions" / "supercub_sysid.yaml"
    text = sysid.read_text().replace(
        "states: [excite.aileron, excite.rudder, excite.sweep]",
        "states: [excite.aileron, excite.sweep, excite.rudder]",
    )
    assert text != sysid.read_text()
    mission.write_text(text)
    code, table, _ = dry_run(mission)
    assert code == 1
    row = next(line for line in table.splitlines() if "then the sweep" in line)
    assert "excite.sweep at 28.2 s; then never excite.rudder" in row and "**FAIL**" in row


def test_a_cli_fault_can_fail_a_mission() -> None:
    """Killing the leader early: Slash B never catches it, and the check says so."""
    code, table, _ = dry_run(FOLLOW, faults=["kill:slash_a@5"])
    assert code == 1
    assert "Slash B reaches Slash A" in table and "**FAIL**" in table


def test_invalid_mission_exits_1_without_simulating(tmp_path: Path) -> None:
    mission = tmp_path / "m.yaml"
    mission.write_text(FOLLOW.read_text().replace("loop_hz: 10", "loop_hz: 0"))
    code, table, err = dry_run(mission, report=tmp_path / "report")
    assert code == 1
    assert "m.yaml:" in err and "E-" in err
    assert table == ""
    assert not (tmp_path / "report").exists(), "nothing written for an invalid mission"


@pytest.mark.parametrize(
    ("text", "fault"),
    [
        ("kill:slash_a@30", {"kill": {"agent": "slash_a", "at_s": 30.0}}),
        (
            "link_drop:mcs,slash_b@10-20.5",
            {"link_drop": {"between": ["mcs", "slash_b"], "from_s": 10.0, "to_s": 20.5}},
        ),
        ("station_silent@40-70", {"station_silent": {"from_s": 40.0, "to_s": 70.0}}),
        (
            "autopilot_disconnect:slash_b@1-2",
            {"autopilot_disconnect": {"agent": "slash_b", "from_s": 1.0, "to_s": 2.0}},
        ),
        ("corrupt:0.25@0-60", {"corrupt": {"share": 0.25, "from_s": 0.0, "to_s": 60.0}}),
    ],
)
def test_fault_forms(text: str, fault: dict[str, object]) -> None:
    assert parse_fault(text) == fault


@pytest.mark.parametrize(
    "text",
    [
        "kill:slash_a",
        "kill:slash_a@1-2",
        "station_silent@5",
        "melt:a@1",
        "link_drop:mcs@1-2",
        "corrupt:lots@1-2",
    ],
)
def test_bad_fault_is_a_usage_error(text: str) -> None:
    with pytest.raises(UsageError, match="is not a fault"):
        parse_fault(text)


def test_reversed_fault_window_says_so() -> None:
    with pytest.raises(UsageError, match="reversed window"):
        parse_fault("station_silent@9-3")


def cli(*args: str) -> subprocess.CompletedProcess[str]:
    return subprocess.run(
        [sys.executable, "-m", "clark_engine", "dry-run", *args],
        cwd=ROOT,
        capture_output=True,
        text=True,
        timeout=120,
        check=False,
    )


def test_cli_exit_codes_and_no_tracebacks(tmp_path: Path) -> None:
    good = cli(str(FOLLOW), "--until", "130")
    assert good.returncode == 0, good.stderr
    bad_fault = cli(str(FOLLOW), "--fault", "kill:nobody@3")
    assert bad_fault.returncode == 2
    assert "there is no agent 'nobody'" in bad_fault.stderr
    missing = cli(str(tmp_path / "absent.yaml"))
    assert missing.returncode == 2
    blocked = tmp_path / "file"
    blocked.write_text("")
    unwritable = cli(str(FOLLOW), "--until", "5", "--report", str(blocked / "report"))
    assert unwritable.returncode == 2
    assert "cannot write the report" in unwritable.stderr
    for result in (good, bad_fault, missing, unwritable):
        assert "Traceback" not in result.stderr


def test_cli_applies_a_station_loss() -> None:
    """The station falls silent before it activates Slash B: the failsafe holds Slash B.

    Silence counts once a vehicle's behaviour has started (Slash B's autopilot is ready at
    about 42 s), so the window opens after that.
    """
    result = cli(str(FOLLOW), "--until", "90", "--fault", "station_silent@50-80")
    assert result.returncode == 1
    failsafe_row = next(line for line in result.stdout.splitlines() if "| no failsafe" in line)
    assert "slash_b failsafe hold" in failsafe_row and "**FAIL**" in failsafe_row


@pytest.mark.parametrize("given", [["--workers", "2"], ["--workers=auto"], ["--workers"]])
def test_workers_is_refused_with_the_reason_and_where_to_go(
    given: list[str], capsys: pytest.CaptureFixture[str]
) -> None:
    """The dry run's own process split is gone (issue 19): one line says so, exit 2.

    It points to what uses several cores now: a campaign's runs, one per core.
    """
    from clark_engine import cli as clark

    with pytest.raises(SystemExit) as exit_info:
        clark.main(["dry-run", str(FOLLOW), "--until", "1", *given])
    err = capsys.readouterr().err
    assert exit_info.value.code == 2, err
    message = err.strip().splitlines()[-1]
    assert message.startswith("clark dry-run: error: --workers was removed"), err
    assert "clark campaign" in message and "--workers" in message
    assert "Traceback" not in err
    with pytest.raises(SystemExit):
        clark.main(["dry-run", "--help"])
    assert "--workers" not in capsys.readouterr().out  # not offered any more
