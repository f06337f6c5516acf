"""The golden manifest (tests/golden/manifest.json) is current, and tools/golden.py says so.

The manifest gates issue 20's layout move: everything the engine makes from the shipped
examples must stay byte-identical unless a change is listed in it. The whole check
(every example's seed-1 dry run, and docs/check-codes.md made by running its examples)
takes minutes and is `make golden`'s job; the suite checks the quick parts of it: the
generated files and every example's compiled configs, and the dry run of one short
example, so that a drift is caught here before the full gate runs.
"""

from __future__ import annotations

import hashlib
import importlib.util
import json
import shutil
import sys
from pathlib import Path
from types import ModuleType

import pytest

ROOT = Path(__file__).resolve().parents[1]
#: The example dry-run here: the shortest in wall time (about 1 s of simulation).
SHORT_EXAMPLE = "single_vehicle_mode_change"


def _load_tool() -> ModuleType:
    spec = importlib.util.spec_from_file_location("golden", ROOT / "tools" / "golden.py")
    assert spec is not None and spec.loader is not None
    module = importlib.util.module_from_spec(spec)
    sys.modules["golden"] = module  # dataclasses resolve their module by name
    spec.loader.exec_module(module)
    return module


golden = _load_tool()


def _report(differences: list[object], notes: list[str]) -> str:
    shown = "\n".join(d.format() for d in differences)  # type: ignore[attr-defined]
    return (
        f"{shown}\n{chr(10).join(notes)}\nwhat the engine makes is not what "
        "tests/golden/manifest.json recorded: if the change is intended, run "
        "`python tools/golden.py record --reason TEXT` and commit the manifest with it"
    )


def test_generated_files_and_compiled_configs_are_as_recorded() -> None:
    differences, notes = golden.check(parts=("generated", "compile"))
    assert not differences, _report(differences, notes)


def test_one_short_dry_run_is_as_recorded() -> None:
    differences, notes = golden.check(missions=[SHORT_EXAMPLE], parts=("dry-run",))
    assert not differences, _report(differences, notes)


def test_check_codes_page_is_as_recorded() -> None:
    # Remaking the page runs its examples (about 20 s): the committed page stands in for it,
    # since tests/test_docs.py proves it is what its source makes.
    manifest = golden.Manifest.load(golden.MANIFEST)
    committed = (ROOT / "docs" / "check-codes.md").read_bytes()
    assert manifest.files[golden.CHECK_CODES_KEY] == hashlib.sha256(committed).hexdigest()


def test_the_manifest_covers_every_example_and_is_deterministic_text() -> None:
    text = golden.MANIFEST.read_text(encoding="utf-8")
    manifest = golden.Manifest.load(golden.MANIFEST)
    assert text == manifest.dump(), (
        "the manifest is not as tools/golden.py writes it (sorted keys, trailing newline)"
    )
    recorded = {golden.mission_of(path) for path in manifest.files} - {None}
    assert recorded == set(golden.example_missions())
    for name in golden.example_missions():
        for kind in ("stdout.txt", "report/summary.md", "outcome.txt"):
            assert f"dry-run/{name}/{kind}" in manifest.files
        assert any(p.startswith(f"dry-run/{name}/report/logs/") for p in manifest.files)
        assert any(p.startswith(f"compile/{name}/") and p.endswith(".json") for p in manifest.files)


def test_a_wrong_hash_and_a_missing_file_exit_1_naming_each(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    data = json.loads(golden.MANIFEST.read_text(encoding="utf-8"))
    data["files"]["generated/schemas/mission.schema.json"] = "0" * 64
    data["files"]["generated/schemas/gone.schema.json"] = "1" * 64
    copy = tmp_path / "manifest.json"
    copy.write_text(json.dumps(data), encoding="utf-8")

    code = golden.main(["--check", "--manifest", str(copy), "--part", "generated"])

    out = capsys.readouterr().out
    assert code == 1
    assert f"generated/schemas/mission.schema.json: expected sha256 {'0' * 64}, got sha256 " in out
    assert f"generated/schemas/gone.schema.json: expected sha256 {'1' * 64}, got no such file" in (
        out
    )
    assert "2 file(s) differ" in out


def test_a_missing_manifest_exits_2_with_a_message(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    code = golden.main(["--check", "--manifest", str(tmp_path / "none.json")])

    captured = capsys.readouterr()
    assert code == 2
    assert "none.json: no such manifest; record one with: python tools/golden.py record" in (
        captured.err
    )
    assert "Traceback" not in captured.err + captured.out


@pytest.mark.parametrize(
    ("argv", "message"),
    [
        (["--check", "no_such_mission"], "no such example mission: no_such_mission"),
        (["recrod"], "say `record` or `--check [MISSION ...]`"),
        (["--check", "--reason", "x"], "--reason goes with record"),
        (["--check", "--part", "everything"], "invalid choice: 'everything'"),
    ],
)
def test_usage_errors_exit_2(
    argv: list[str], message: str, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    manifest = tmp_path / "manifest.json"
    shutil.copy(golden.MANIFEST, manifest)

    code = golden.main([*argv, "--manifest", str(manifest)])

    captured = capsys.readouterr()
    assert code == 2
    assert message in captured.err
    assert "Traceback" not in captured.err


def test_a_malformed_manifest_exits_2_with_its_line(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    manifest = tmp_path / "manifest.json"
    manifest.write_text('{"files": {\n  "a": 3\n}}\n', encoding="utf-8")
    assert golden.main(["--check", "--manifest", str(manifest)]) == 2
    assert "'files' must map each path to a SHA-256" in capsys.readouterr().err
    manifest.write_text('{"files": \n', encoding="utf-8")
    assert golden.main(["--check", "--manifest", str(manifest)]) == 2
    assert "manifest.json:2:1: not JSON" in capsys.readouterr().err


def test_only_wall_clock_figures_and_the_temporary_folder_are_normalised(tmp_path: Path) -> None:
    summary = (
        f"Equivalent command: `clark dry-run missions/m.yaml --seed 1 --report {tmp_path}/r`\n"
        "\n"
        "Seed 1; 170 simulated seconds in 4.1 s of wall time (42x real time); 3 of 3 checks\n"
    )
    stderr = (
        "dry run of m: 3 agents, 417 s, seed 1\n"
        "  simulated 214.0 of 417 s (51%)\n"
        "simulated 417 s in 21.9 s (19x real time)\n"
        f"report: {tmp_path}/r/summary.md\n"
    )

    assert golden.normalise("dry-run/m/report/summary.md", summary.encode(), tmp_path) == (
        b"Equivalent command: `clark dry-run missions/m.yaml --seed 1 --report <tmp>/r`\n"
        b"\n"
        b"Seed 1; 170 simulated seconds in <wall> s of wall time (<ratio>x real time); "
        b"3 of 3 checks\n"
    )
    assert golden.normalise("dry-run/m/stderr.txt", stderr.encode(), tmp_path) == (
        b"dry run of m: 3 agents, 417 s, seed 1\n"
        b"simulated 417 s in <wall> s (<ratio>x real time)\n"
        b"report: <tmp>/r/summary.md\n"
    )
    log = b"12.5 simulated seconds in 4.1 s of wall time (42x real time)\n"
    assert golden.normalise("dry-run/m/report/logs/a.mission.log", log, tmp_path) == log


def test_re_recording_a_change_needs_a_reason_which_is_listed(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    manifest = tmp_path / "manifest.json"
    first = {"compile/m/a.json": b"{}\n", "compile/m/findings.txt": b""}
    assert golden.write_manifest(manifest, first, None) == 0
    recorded = manifest.read_text(encoding="utf-8")
    changed = {"compile/m/a.json": b'{"x": 1}\n', "compile/m/b.json": b"{}\n"}

    assert golden.write_manifest(manifest, changed, None) == 1
    out = capsys.readouterr().out
    assert "changed: compile/m/a.json" in out
    assert "added: compile/m/b.json" in out
    assert "removed: compile/m/findings.txt" in out
    assert manifest.read_text(encoding="utf-8") == recorded, "nothing written without a reason"

    assert golden.write_manifest(manifest, changed, "a renamed log line") == 0
    data = golden.Manifest.load(manifest)
    assert data.intended_changes == [
        {
            "reason": "a renamed log line",
            "files": {
                "compile/m/a.json": "changed",
                "compile/m/b.json": "added",
                "compile/m/findings.txt": "removed",
            },
        }
    ]
    assert manifest.read_text(encoding="utf-8").endswith("}\n")
    assert golden.write_manifest(manifest, changed, None) == 0, "no change, no reason needed"
