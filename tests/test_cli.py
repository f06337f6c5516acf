"""The clark command: exit codes, output formats, no tracebacks, no flight libraries."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import pytest

from clark_engine.cli import main

ROOT = Path(__file__).resolve().parent.parent
EXAMPLE = str(ROOT / "missions" / "cooperative_follow.yaml")


def run(*args: str, cwd: Path = ROOT) -> subprocess.CompletedProcess[str]:
    return subprocess.run(
        [sys.executable, "-m", "clark_engine", *args],
        cwd=cwd,
        capture_output=True,
        text=True,
        timeout=60,
        check=False,
    )


def test_validate_all_examples(capsys: pytest.CaptureFixture[str]) -> None:
    paths = [str(p) for p in sorted((ROOT / "missions").glob("*.yaml"))]
    assert main(["validate", *paths]) == 0
    out = capsys.readouterr().out
    assert out.count("valid mission") == len(paths)


def test_validate_json_has_every_field(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    bad = tmp_path / "bad.yaml"
    bad.write_text("clark: 1\nmission: {id: 1, name: x, lopp_hz: 1}\nagents: {}\n")
    assert main(["validate", "--format", "json", str(bad)]) == 1
    payload = json.loads(capsys.readouterr().out)
    assert payload["files"][0]["valid"] is False
    finding = payload["findings"][0]
    assert set(finding) >= {"file", "line", "column", "path", "code", "severity", "message"}
    codes = {f["code"] for f in payload["findings"]}
    assert "E-KEY-UNKNOWN" in codes
    unknown = next(f for f in payload["findings"] if f["code"] == "E-KEY-UNKNOWN")
    assert (unknown["line"], unknown["column"], unknown["path"]) == (2, 27, "mission.lopp_hz")
    assert "loop_hz" in unknown["message"]


def test_warnings_alone_exit_zero(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    text = (
        Path(EXAMPLE)
        .read_text(encoding="utf-8")
        .replace(
            "agents:\n  mcs:\n    id: 1\n    profile: mcs_laptop\n",
            "agents:\n  mcs:\n    id: 1\n    profile: mcs_laptop\n",
            1,
        )
        .replace(
            "telemetry: {heartbeat: 1, agent_status: 2, vehicle_health",
            "telemetry: {heartbeat: 1, agent_status: 3, vehicle_health",
            1,
        )
    )
    path = tmp_path / "warn.yaml"
    path.write_text(text, encoding="utf-8")
    assert main(["validate", str(path)]) == 0
    out = capsys.readouterr().out
    assert "W-RATE-DIVIDER" in out and "warning" in out


@pytest.mark.parametrize(
    ("args", "code"),
    [
        (("validate", "no/such/file.yaml"), 2),
        (("validate", "missions"), 2),
        (("validate",), 2),
        (("frobnicate",), 2),
        (("schema", "nope"), 2),
        (("explain", EXAMPLE, "--agent", "nobody"), 2),
        ((), 2),
    ],
)
def test_usage_and_io_errors_exit_2_without_traceback(args: tuple[str, ...], code: int) -> None:
    proc = run(*args)
    assert proc.returncode == code
    assert "Traceback" not in proc.stderr + proc.stdout
    assert proc.stderr.strip()


def test_unreadable_file_exits_2(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    # Tests run as root here, where chmod 000 does not stop reading; make the OS refuse.
    path = tmp_path / "locked.yaml"
    path.write_text("clark: 1\n")
    real = Path.read_bytes

    def refuse(self: Path) -> bytes:
        if self == path:
            raise PermissionError(13, "Permission denied")
        return real(self)

    monkeypatch.setattr(Path, "read_bytes", refuse)
    assert main(["validate", str(path)]) == 2
    assert "permission denied" in capsys.readouterr().err


def test_schema_prints_the_shipped_file(capsys: pytest.CaptureFixture[str]) -> None:
    for name, file_name in [
        ("mission", "mission.schema.json"),
        ("agent-config", "agent_config.schema.json"),
        ("hardware_profile", "hardware_profile.schema.json"),
        ("behavior", "behavior.schema.json"),
    ]:
        assert main(["schema", name]) == 0
        assert capsys.readouterr().out == (ROOT / "schemas" / file_name).read_text()


def test_explain_tree_and_mermaid(capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["explain", str(ROOT / "missions" / "supercub_sysid.yaml"), "--agent", "cub"]) == 0
    out = capsys.readouterr().out
    assert "excite: machine, initial aileron (block system_id_sequence)" in out
    assert "channel=aileron (rc 1" in out
    assert "stateDiagram-v2" in out
    assert "excite__aileron --> excite__settle_1 : done" in out
    assert "piloted --> excite : activate" in out


def test_explain_invalid_mission_exits_1(tmp_path: Path) -> None:
    bad = tmp_path / "bad.yaml"
    bad.write_text("clark: 2\n")
    assert main(["explain", str(bad)]) == 1


def test_the_clark_command_exits_with_signals_ignored() -> None:
    """A third Ctrl-C as `clark run`'s stop ended landed in the interpreter's shutdown,
    where Python's default action killed the process (exit -2, not 130; seen in
    tests/test_cli_run_stop.py). Once the command is done, signals are ignored."""
    code = (
        "import atexit, signal, sys\n"
        "atexit.register(lambda: print('AT EXIT', signal.getsignal(signal.SIGINT) =="
        " signal.SIG_IGN, signal.getsignal(signal.SIGTERM) == signal.SIG_IGN))\n"
        f"sys.argv = ['clark', 'validate', {EXAMPLE!r}]\n"
        "from clark_engine.cli import console_main\n"
        "console_main()\n"
    )
    proc = subprocess.run(
        [sys.executable, "-c", code],
        cwd=ROOT,
        capture_output=True,
        text=True,
        timeout=60,
        check=False,
    )
    assert proc.returncode == 0, proc.stderr
    assert "AT EXIT True True" in proc.stdout, proc.stdout


def test_validate_does_not_import_flight_libraries() -> None:
    code = (
        "import sys\n"
        "from clark_engine.cli import main\n"
        f"rc = main(['validate', {EXAMPLE!r}])\n"
        # 'digi' alone is a namespace stub that digi-xbee's .pth creates at start-up;
        # the library itself is digi.xbee. (protobuf is loaded: the link budget
        # measures real encoded sizes.)
        "loaded = sorted(m for m in sys.modules if m.startswith("
        "('pymavlink', 'digi.xbee', 'transitions')))\n"
        "print('LOADED', loaded)\n"
        "sys.exit(rc)\n"
    )
    proc = subprocess.run(
        [sys.executable, "-c", code],
        cwd=ROOT,
        capture_output=True,
        text=True,
        timeout=60,
        check=False,
    )
    assert proc.returncode == 0, proc.stderr
    assert "LOADED []" in proc.stdout


def test_version() -> None:
    proc = run("--version")
    assert proc.returncode == 0
    assert proc.stdout.startswith("clark-engine ")
