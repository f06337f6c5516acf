"""What the clark command prints: warnings once or not at all, help texts, progress."""

from __future__ import annotations

import importlib.metadata
import io
import os
from pathlib import Path

import pytest

from clark_engine.cli import build_parser, main
from clark_engine.data import data_dir
from clark_engine.dryrun import command as dryrun
from clark_engine.dryrun.command import run_dry_run

ROOT = Path(__file__).resolve().parent.parent
EXAMPLE = str(ROOT / "missions" / "cooperative_follow.yaml")
OTHER = str(ROOT / "missions" / "fault_station_loss.yaml")


def test_quiet_hides_warnings_but_keeps_the_verdict(capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["validate", "--quiet", EXAMPLE]) == 0
    out = capsys.readouterr().out
    assert "W-NO-KEY" not in out and "W-ENVELOPE-REACTIVE" not in out
    assert "W-POSITION-ERROR" not in out
    assert "valid mission (3 warnings)" in out


def test_quiet_still_shows_errors(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    bad = tmp_path / "bad.yaml"
    bad.write_text("clark: 1\nmission: {id: 1, name: x, lopp_hz: 1}\nagents: {}\n")
    assert main(["validate", "-q", str(bad)]) == 1
    assert "E-KEY-UNKNOWN" in capsys.readouterr().out


def test_no_key_advice_is_given_once_per_command(capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["validate", EXAMPLE, OTHER]) == 0
    out = capsys.readouterr().out
    assert out.count("[W-NO-KEY]") == 2, "each file still says it has no key"
    assert out.count("clark keygen") == 1, "the advice is given once"


def test_dry_run_quiet_hides_warnings(capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["dry-run", EXAMPLE, "--until", "3", "--quiet"]) in (0, 1)
    assert "W-NO-KEY" not in capsys.readouterr().err


class _Terminal(io.StringIO):
    def isatty(self) -> bool:
        return True


def test_no_carriage_returns_into_a_log() -> None:
    log = io.StringIO()
    progress = dryrun._progress_for(log, 3600.0)
    assert progress is not None
    for second in range(25):
        progress(second * 100.0, 3600.0)
    progress.finish()
    text = log.getvalue()
    assert "\r" not in text
    assert 1 <= text.count("\n") <= 3, "a plain line now and then, not one a second"


def test_a_terminal_gets_the_bar() -> None:
    term = _Terminal()
    progress = dryrun._progress_for(term, 10.0)
    assert progress is not None
    progress(5.0, 10.0)
    assert "\r" in term.getvalue()


def test_interrupted_starts_on_its_own_line(
    monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    def interrupted_run(self: dryrun.DryRun) -> None:
        assert self.progress is not None
        self.progress(1.0, 10.0)
        raise KeyboardInterrupt

    monkeypatch.setattr(dryrun.DryRun, "run", interrupted_run)
    monkeypatch.setattr(dryrun, "_progress_for", lambda err, until_s: dryrun._Progress(err))
    err = _Terminal()
    with pytest.raises(KeyboardInterrupt):
        run_dry_run(Path(EXAMPLE), seed=None, until_s=10.0, report=None, speed=None, err=err)
    assert err.getvalue().endswith("\n"), "the bar's line is ended before 'interrupted'"


def test_analyze_reads_a_report_folder_through_its_logs_folder(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """One folder rule for every log reader (docs/logs.md): a dry run's report folder is
    read through its ``logs/``, as `clark replay` always did (it used to be refused with a
    "did you mean .../logs" hint)."""
    report = tmp_path / "out"
    assert main(["dry-run", EXAMPLE, "--until", "3", "--report", str(report)]) in (0, 1)
    capsys.readouterr()
    assert main(["analyze", str(report)]) == 0
    out = capsys.readouterr().out
    assert "mcs" in out, out


def test_analyze_prints_the_problems_it_refers_to(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    (tmp_path / "cub.messages.csv").write_text("not,a,log\n1,2\n")
    assert main(["analyze", str(tmp_path)]) == 1
    err = capsys.readouterr().err
    assert "cub.messages.csv" in err.replace(str(tmp_path) + os.sep, "")
    assert "problems above" not in err or err.count("\n") > 1


@pytest.mark.parametrize("speed", ["0", "-1"])
def test_speed_must_be_above_zero(speed: str, capsys: pytest.CaptureFixture[str]) -> None:
    with pytest.raises(SystemExit) as exc:
        main(["dry-run", EXAMPLE, "--speed", speed])
    assert exc.value.code == 2
    err = capsys.readouterr().err
    assert "> 0" in err
    assert "seconds" not in err.split("error:")[-1]


def test_negative_seed_is_refused(capsys: pytest.CaptureFixture[str]) -> None:
    with pytest.raises(SystemExit) as exc:
        main(["dry-run", EXAMPLE, "--seed", "-1"])
    assert exc.value.code == 2
    assert ">= 0" in capsys.readouterr().err


def test_keygen_creates_parent_folders(tmp_path: Path) -> None:
    key = tmp_path / "keys" / "deeper" / "mission.key"
    assert main(["keygen", str(key)]) == 0
    assert key.is_file()


def test_keygen_io_error_exits_2(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    blocker = tmp_path / "file"
    blocker.write_text("x")
    assert main(["keygen", str(blocker / "mission.key")]) == 2
    assert "Traceback" not in capsys.readouterr().err


def test_top_level_help_names_every_command() -> None:
    text = build_parser().format_help()
    description = text.split("positional arguments")[0]
    for command in ("validate", "compile", "explain", "dry-run", "analyze"):
        assert command in description


def _sub_help(name: str) -> str:
    parser = build_parser()
    action = next(a for a in parser._actions if a.dest == "command")
    return str(action.choices[name].format_help())  # type: ignore[index]


def test_schema_help_lists_the_schema_names() -> None:
    from clark_engine.mission.schemas import SCHEMA_NAMES

    text = _sub_help("schema")
    for name in SCHEMA_NAMES:
        assert name in text.split("positional arguments")[1]


def test_explain_format_has_help() -> None:
    text = " ".join(_sub_help("explain").split())
    after = text.split("--format {tree,mermaid,both}")[-1]
    assert "indented tree" in after and "Mermaid" in after


def test_version_comes_from_the_package_metadata(
    monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    monkeypatch.setattr(importlib.metadata, "version", lambda name: "9.8.7")
    with pytest.raises(SystemExit) as exc:
        main(["--version"])
    assert exc.value.code == 0
    assert capsys.readouterr().out.strip() == "clark-engine 9.8.7"


def test_examples_copies_the_missions_and_the_schemas_they_name(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """A pip-installed engine's user gets the examples to edit, each valid where it lands."""
    target = tmp_path / "mine"
    assert main(["examples", str(target)]) == 0
    out = capsys.readouterr().out
    shipped = sorted(p.name for p in data_dir("missions").glob("*.yaml"))
    assert sorted(p.name for p in (target / "missions").glob("*.yaml")) == shipped
    assert (target / "schemas" / "mission.schema.json").is_file()
    assert f"wrote {len(shipped)} example missions" in out
    assert not [p for p in target.iterdir() if p.name.startswith(".")], "no staging left"
    mission = target / "missions" / "cooperative_follow.yaml"
    assert "$schema=../schemas/mission.schema.json" in mission.read_text(encoding="utf-8")
    assert main(["validate", "-q", str(mission)]) == 0


def test_examples_never_overwrites(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    (tmp_path / "missions").mkdir()
    (tmp_path / "missions" / "mine.yaml").write_text("clark: 1\n", encoding="utf-8")
    assert main(["examples", str(tmp_path)]) == 2
    err = capsys.readouterr().err
    assert "missions already exists; clark examples never overwrites" in err
    assert "Traceback" not in err
    assert [p.name for p in (tmp_path / "missions").iterdir()] == ["mine.yaml"]
    assert not (tmp_path / "schemas").exists()
