"""Generated documentation stays in step with the engine."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import pytest

from clark_engine.validation import validate_file

ROOT = Path(__file__).resolve().parents[1]


def test_check_codes_page_is_generated_from_the_engine() -> None:
    """docs/check-codes.md is what tools/gen_check_codes.py makes of docs/check-codes.yaml.

    The generator also fails when an example no longer reports its code, or when the engine
    can report a code that has no example.
    """
    proc = subprocess.run(
        [sys.executable, "tools/gen_check_codes.py", "--check"],
        cwd=ROOT,
        capture_output=True,
        text=True,
        timeout=120,
        check=False,
    )
    assert proc.returncode == 0, (
        proc.stdout + proc.stderr + "\nrun `python tools/gen_check_codes.py`"
    )


def _ignored_by_git(path: str) -> bool:
    proc = subprocess.run(
        ["git", "check-ignore", "-q", path], cwd=ROOT, capture_output=True, check=False
    )
    if proc.returncode == 128:  # not a checkout (an unpacked sdist)
        pytest.skip("not a git checkout")
    return proc.returncode == 0


def test_tutorial_works_apart_from_the_examples() -> None:
    """The tutorial's files never land in missions/ (make demo and make test read it)."""
    text = (ROOT / "docs" / "tutorial.md").read_text(encoding="utf-8")
    assert "missions/first_flight" not in text
    assert "$ clark validate tutorial/first_flight.yaml" in text
    assert "mkdir -p tutorial" in text
    for made in ("tutorial/first_flight.yaml", "tutorial/first_flight.key", "build2/x"):
        assert _ignored_by_git(made), f"{made} is not ignored by git"


def test_readme_outputs_are_ignored_by_git() -> None:
    readme = (ROOT / "README.md").read_text(encoding="utf-8")
    assert "clark keygen keys/mission.key" in readme
    assert "clark schema mission > mission.schema.json" in readme
    for made in ("keys/mission.key", "out/summary.md", "build/x/cub.json", "mission.schema.json"):
        assert _ignored_by_git(made), f"{made} is not ignored by git"


def test_readme_mission_sketch_is_a_valid_mission(tmp_path: Path) -> None:
    """The README's sketch says it is cut from the example and validates as it stands."""
    readme = (ROOT / "README.md").read_text(encoding="utf-8")
    lead, rest = readme.split("A mission is short.", 1)[1].split("```yaml\n", 1)
    assert "missions/cooperative_follow.yaml" in lead
    sketch = tmp_path / "missions" / "sketch.yaml"  # its $schema line is relative to missions/
    sketch.parent.mkdir()
    sketch.write_text(rest.split("```", 1)[0], encoding="utf-8")
    result = validate_file(sketch)
    assert result.ok, [f.message for f in result.findings]


def test_readme_says_the_station_loss_fails_on_purpose(
    capsys: pytest.CaptureFixture[str],
) -> None:
    """The README's "what if?" output is the command's real output."""
    command = "clark dry-run missions/cooperative_follow.yaml --fault station_silent@50-80 -q"
    readme = (ROOT / "README.md").read_text(encoding="utf-8")
    assert f"$ {command}\n" in readme, "the README shows the command and its output"
    block = readme.split(f"$ {command}\n", 1)[1].split("```", 1)[0]
    assert "fails on purpose" in readme.split(f"$ {command}")[0].rsplit("```", 2)[-2]
    from clark_engine.cli import main

    args = command.split()[1:]
    args[1] = str(ROOT / args[1])
    code = main(args)
    out, err = capsys.readouterr()
    assert code == 1
    shown = [line for line in block.splitlines() if line.startswith("|") or "checks" in line]
    real = [line for line in (out + err).splitlines() if line.startswith("|") or "checks" in line]
    assert shown == real


def test_the_rehearsal_script_parses_and_flight_md_uses_it() -> None:
    """tools/rehearse.sh is what docs/flight.md runs (it is flown by hand: it takes 100 s
    of real time, as tests/test_run_end_to_end.py's rehearsals do)."""
    script = ROOT / "tools" / "rehearse.sh"
    assert script.stat().st_mode & 0o111, "executable"
    parsed = subprocess.run(["bash", "-n", str(script)], capture_output=True, text=True)
    assert parsed.returncode == 0, parsed.stderr
    flight = (ROOT / "docs" / "flight.md").read_text(encoding="utf-8")
    assert "tools/rehearse.sh" in flight
    assert "use the connection each\n`autopilot-sim` prints" in flight
