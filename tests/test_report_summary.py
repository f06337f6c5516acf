"""summary.md records how the run was made: the command line, the seed, the faults injected."""

from __future__ import annotations

import io
import re
import shlex
from pathlib import Path

import pytest

from clark_engine.cli import main
from clark_engine.dryrun.command import run_dry_run

ROOT = Path(__file__).resolve().parent.parent
LOST_PEER = ROOT / "missions" / "fault_lost_peer.yaml"
FOLLOW = ROOT / "missions" / "cooperative_follow.yaml"


def section(summary: str, title: str) -> str:
    """The text of one ``## title`` section of summary.md."""
    start = summary.index(f"## {title}\n")
    end = summary.find("\n## ", start + 1)
    return summary[start : end if end != -1 else len(summary)]


def test_summary_records_the_command_line_seed_and_faults(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    folder = tmp_path / "report"
    argv = [
        "dry-run", str(LOST_PEER), "--until", "10", "--seed", "5",
        "--fault", "station_silent@2-4", "--report", str(folder),
    ]  # fmt: skip
    assert main(argv) == 0
    capsys.readouterr()
    summary = (folder / "summary.md").read_text(encoding="utf-8")
    assert f"Command line: `{shlex.join(['clark', *argv])}`" in summary
    assert "Seed 5;" in summary
    faults = section(summary, "Injected faults")
    rows = [line for line in faults.splitlines() if line.startswith("| ") and "---" not in line]
    assert rows == [
        "| fault | when (s) | given by |",
        "| kill slash_a | at 75 | mission |",
        "| autopilot of slash_c disconnected | 65 to 80 | mission |",
        "| 20% of packets corrupted | the whole run | mission |",
        "| stations silent | 2 to 4 | --fault station_silent@2-4 |",
    ]


def test_summary_without_a_command_line_gives_the_equivalent_one(tmp_path: Path) -> None:
    """Run in process (no command line): the command that repeats the run, seed included."""
    folder = tmp_path / "report"
    outcome = run_dry_run(
        FOLLOW, seed=None, until_s=5.0, report=folder, speed=None,
        out=io.StringIO(), err=io.StringIO(),
    )  # fmt: skip
    assert outcome.exit_code == 0
    summary = (folder / "summary.md").read_text(encoding="utf-8")
    seed = 1  # the mission's sim.seed
    assert re.search(rf"\bseed: {seed}\b", FOLLOW.read_text())
    words = ["clark", "dry-run", str(FOLLOW), "--seed", str(seed), "--until", "5"]
    expected = shlex.join([*words, "--report", str(folder)])
    assert f"Equivalent command: `{expected}`" in summary
    assert "No faults injected." in section(summary, "Injected faults")


def test_links_section_explains_deviation_from_ideal(tmp_path: Path) -> None:
    folder = tmp_path / "report"
    outcome = run_dry_run(
        FOLLOW, seed=None, until_s=20.0, report=folder, speed=None,
        out=io.StringIO(), err=io.StringIO(),
    )  # fmt: skip
    assert outcome.exit_code == 0
    links = section((folder / "summary.md").read_text(encoding="utf-8"), "Links (clark analyze)")
    assert "deviation from ideal" in links  # the figure, in analyze's table
    after_table = links[links.rindex("```") :]
    assert "**Deviation from ideal** is the sum of means" in after_table
    assert "minus the sample period (0.1 s, from mission logs)" in after_table
