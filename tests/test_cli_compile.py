"""``clark compile -o DIR`` replaces what an earlier compile wrote, and only that."""

from __future__ import annotations

from pathlib import Path

import pytest

from clark_engine.cli import main

ROOT = Path(__file__).resolve().parent.parent
FOLLOW = ROOT / "missions" / "cooperative_follow.yaml"


def _without_slash_b(tmp_path: Path) -> Path:
    """cooperative_follow with slash_b (and its checks) removed: a mission that lost an agent."""
    text = FOLLOW.read_text(encoding="utf-8")
    head, rest = text.split("  slash_b:\n", 1)
    tail = rest[rest.index("\nchecks:") :] if "\nchecks:" in rest else ""
    mission = tmp_path / "cooperative_follow.yaml"
    mission.write_text(head + tail.split("\nchecks:")[0] + "\n", encoding="utf-8")
    return mission


def test_removed_agent_config_does_not_linger(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    out = tmp_path / "build"
    assert main(["compile", str(FOLLOW), "-o", str(out)]) == 0
    smaller = _without_slash_b(tmp_path)
    code = main(["compile", str(smaller), "-o", str(out)])
    assert code == 0, capsys.readouterr().err
    names = sorted(p.name for p in (out / "cooperative-follow").iterdir())
    assert names == ["mcs.json", "slash_a.json"]
    assert not [p for p in out.iterdir() if p.name.startswith(".")], "no staging left behind"


def test_agent_option_keeps_the_other_configs(tmp_path: Path) -> None:
    out = tmp_path / "build"
    assert main(["compile", str(FOLLOW), "-o", str(out)]) == 0
    assert main(["compile", str(FOLLOW), "-o", str(out), "--agent", "slash_b"]) == 0
    names = sorted(p.name for p in (out / "cooperative-follow").iterdir())
    assert names == ["mcs.json", "slash_a.json", "slash_b.json"]


def test_foreign_files_are_never_deleted(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    out = tmp_path / "build"
    assert main(["compile", str(FOLLOW), "-o", str(out)]) == 0
    notes = out / "cooperative-follow" / "notes.txt"
    notes.write_text("mine")
    before = sorted(p.name for p in notes.parent.iterdir())
    assert main(["compile", str(FOLLOW), "-o", str(out)]) == 2
    err = capsys.readouterr().err
    assert "notes.txt" in err and "did not write" in err
    assert notes.read_text() == "mine"
    assert sorted(p.name for p in notes.parent.iterdir()) == before
    assert not [p for p in out.iterdir() if p.name.startswith(".")]
