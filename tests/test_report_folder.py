"""``--report DIR``: written whole beside DIR, never deleting a file the engine did not write."""

from __future__ import annotations

import io
import json
from pathlib import Path

import pytest

from clark_engine.cli import main
from clark_engine.dryrun import command as dryrun
from clark_engine.dryrun.command import run_dry_run
from clark_engine.dryrun.report import REPORT_MARKER

ROOT = Path(__file__).resolve().parent.parent
FOLLOW = ROOT / "missions" / "cooperative_follow.yaml"


def _run(report: Path, until_s: float = 3.0) -> int:
    return run_dry_run(
        FOLLOW,
        seed=None,
        until_s=until_s,
        report=report,
        speed=None,
        out=io.StringIO(),
        err=io.StringIO(),
    ).exit_code


def _files(folder: Path) -> dict[str, bytes]:
    return {
        p.relative_to(folder).as_posix(): p.read_bytes()
        for p in sorted(folder.rglob("*"))
        if p.is_file()
    }


def test_user_files_in_the_report_folder_are_never_deleted(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    report = tmp_path / "out"
    (report / "logs").mkdir(parents=True)
    (report / "logs" / "my_flight_notes.txt").write_text("precious")
    (report / "notes.md").write_text("mine")
    code = main(["dry-run", str(FOLLOW), "--until", "3", "--report", str(report), "-q"])
    assert code == 2
    err = capsys.readouterr().err
    assert "did not write" in err and "my_flight_notes.txt" in err and "notes.md" in err
    assert "Traceback" not in err
    assert _files(report) == {"logs/my_flight_notes.txt": b"precious", "notes.md": b"mine"}
    assert [p.name for p in tmp_path.iterdir()] == ["out"], "nothing left beside it"


def test_a_report_replaces_the_previous_report_whole(tmp_path: Path) -> None:
    report = tmp_path / "out"
    _run(report)
    marker = json.loads((report / REPORT_MARKER).read_text())
    assert "summary.md" in marker["files"] and "logs/slash_a.messages.csv" in marker["files"]
    (report / "logs" / "gone_agent.messages.csv").write_text("x")  # engine-written, say
    marker["files"].append("logs/gone_agent.messages.csv")
    (report / REPORT_MARKER).write_text(json.dumps(marker))
    assert _run(report, until_s=4.0) in (0, 1)
    assert not (report / "logs" / "gone_agent.messages.csv").exists()
    assert "4 simulated seconds" in (report / "summary.md").read_text()
    assert sorted(p.name for p in tmp_path.iterdir()) == ["out"]


def test_a_report_from_before_the_marker_is_recognised(tmp_path: Path) -> None:
    report = tmp_path / "out"
    _run(report)
    (report / REPORT_MARKER).unlink()
    assert _run(report) in (0, 1)
    assert (report / REPORT_MARKER).exists()


def test_an_empty_folder_is_fine(tmp_path: Path) -> None:
    report = tmp_path / "out"
    report.mkdir()
    assert _run(report) in (0, 1)
    assert (report / "summary.md").exists()


def test_interrupted_run_leaves_the_previous_report_as_it_was(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    report = tmp_path / "out"
    _run(report)
    before = _files(report)

    def interrupted(self: dryrun.DryRun) -> None:
        for agent in self.agents.values():  # the logbooks hold partial logs: close them
            agent.logbook.close()
        raise KeyboardInterrupt

    monkeypatch.setattr(dryrun.DryRun, "run", interrupted)
    err = io.StringIO()
    with pytest.raises(KeyboardInterrupt):
        run_dry_run(FOLLOW, seed=None, until_s=3.0, report=report, speed=None, err=err)
    assert _files(report) == before, "no partial logs beside the previous summary"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["out"], "no partial folder left"
    assert "no report written" in err.getvalue()


def test_interrupted_first_run_leaves_nothing(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    def interrupted(self: dryrun.DryRun) -> None:
        for agent in self.agents.values():
            agent.logbook.close()
        raise KeyboardInterrupt

    monkeypatch.setattr(dryrun.DryRun, "run", interrupted)
    with pytest.raises(KeyboardInterrupt):
        run_dry_run(
            FOLLOW, seed=None, until_s=3.0, report=tmp_path / "out", speed=None, err=io.StringIO()
        )
    assert list(tmp_path.iterdir()) == []
