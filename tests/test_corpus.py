"""The data-driven mission corpus: tests/valid and tests/invalid.

Every ``tests/valid/*.yaml`` must validate (exit 0) and compile into configs that match
the agent-config schema. Warnings are allowed only when the file's first comment line
lists exactly the warning codes expected: ``# warnings: W-RATE-DIVIDER, W-NO-HEARTBEAT``.

Every ``tests/invalid/*.yaml`` demonstrates one user mistake. Its leading comment lines
are a header:

* ``# expect: E-CODE line N`` - a finding with that code must point at line N of the
  case (one or more such lines); ``# expect: E-CODE line N in support/x/y.yaml`` for a
  finding in another file (a block or profile the case includes), relative to the case's
  folder or to the repository root;
* ``# exit: N`` - also run the real ``clark validate`` and expect exit code N;
* ``# xfail: reason`` - a known engine bug: the case is expected to fail until it is fixed.

Files under ``tests/invalid/support/`` are blocks and profiles the cases include, not
cases. Inputs that cannot carry a header (an empty file, a binary file, an oversized
file, a directory, a missing path) are generated at run time in ``tmp_path``.
"""

from __future__ import annotations

import json
import re
import subprocess
import sys
from dataclasses import dataclass, field
from pathlib import Path

import pytest

from clark_engine.mission.compiler import compile_mission
from clark_engine.mission.findings import Finding, Severity
from clark_engine.mission.schemas import validator
from clark_engine.mission.validate import Validation, validate_path
from clark_engine.mission.yaml_loader import MAX_FILE_BYTES

ROOT = Path(__file__).resolve().parents[1]
VALID_DIR = ROOT / "tests" / "valid"
INVALID_DIR = ROOT / "tests" / "invalid"
VALID = sorted(VALID_DIR.glob("*.yaml"))
INVALID = sorted(INVALID_DIR.glob("*.yaml"))

#: Generous bound on one ``clark validate`` run: a hang guard, not a timing assertion.
CLI_TIMEOUT_S = 10
MIN_CODES_COVERED = 30

_EXPECT = re.compile(r"^#\s*expect:\s*([EW]-[A-Z0-9-]+)\s+line\s+(\d+)(?:\s+in\s+(\S+))?\s*$")
_WARNINGS = re.compile(r"^#\s*warnings:\s*(.*?)\s*$")
_EXIT = re.compile(r"^#\s*exit:\s*(\d+)\s*$")
_XFAIL = re.compile(r"^#\s*xfail:\s*(.+?)\s*$")
_CODE = re.compile(r"^[EW]-[A-Z0-9-]+$")


@dataclass(frozen=True)
class Expect:
    """One finding a case must produce: its code, its line, and the file it is in."""

    code: str
    line: int
    file: str | None = None  # None: the case file itself

    def __str__(self) -> str:
        where = f" in {self.file}" if self.file else ""
        return f"{self.code} line {self.line}{where}"


@dataclass
class Header:
    """What a corpus file's leading comment lines say about it."""

    expects: list[Expect] = field(default_factory=list)
    warnings: frozenset[str] | None = None
    exit: int | None = None
    xfail: str | None = None


def read_header(path: Path) -> Header:
    """Parse the leading ``#`` lines of a corpus file (bytes decoded leniently)."""
    header = Header()
    lines = path.read_bytes().decode("utf-8", errors="replace").splitlines()
    for index, raw in enumerate(lines):
        line = raw.strip()
        if not line.startswith("#"):
            break
        if match := _EXPECT.match(line):
            header.expects.append(Expect(match[1], int(match[2]), match[3]))
        elif (match := _WARNINGS.match(line)) and index == 0:
            codes = {c.strip() for c in match[1].split(",") if c.strip()}
            assert all(_CODE.match(c) for c in codes), f"{path.name}: bad warnings header"
            header.warnings = frozenset(codes)
        elif match := _EXIT.match(line):
            header.exit = int(match[1])
        elif match := _XFAIL.match(line):
            header.xfail = match[1]
    return header


def _params(paths: list[Path]) -> list[object]:
    params: list[object] = []
    for path in paths:
        reason = read_header(path).xfail
        marks = [pytest.mark.xfail(strict=True, reason=reason)] if reason else []
        params.append(pytest.param(path, id=path.name, marks=marks))
    return params


def _validate(path: Path) -> Validation:
    return validate_path(path, str(path))


def _describe(findings: list[Finding]) -> str:
    return "\n".join(f.format_text() for f in findings) or "(no findings)"


def _same_file(finding: Finding, case: Path, expected: str | None) -> bool:
    """True when ``finding`` is in the case file, or in ``expected`` when one is named."""
    if expected is None:
        return finding.location.file == str(case)
    shown = Path(finding.location.file)
    actual = (shown if shown.is_absolute() else Path.cwd() / shown).resolve()
    return actual in {(case.parent / expected).resolve(), (ROOT / expected).resolve()}


def _check_invalid(path: Path, result: Validation, expects: list[Expect]) -> None:
    assert expects, f"{path.name}: an invalid case needs at least one '# expect:' line"
    assert not result.ok, f"{path.name} validated:\n{_describe(result.findings)}"
    for finding in result.findings:
        assert finding.message.strip(), f"empty message: {finding!r}"
        assert finding.location.line is not None and finding.location.line >= 1, (
            f"finding without a line: {finding.format_text()}"
        )
    missing = [
        str(e)
        for e in expects
        if not any(
            f.code == e.code and f.location.line == e.line and _same_file(f, path, e.file)
            for f in result.findings
        )
    ]
    assert not missing, (
        f"{path.name}: expected {', '.join(missing)}; got:\n{_describe(result.findings)}"
    )


def _run_cli(path: Path) -> subprocess.CompletedProcess[str]:
    return subprocess.run(
        [sys.executable, "-m", "clark_engine", "validate", str(path)],
        cwd=ROOT,
        capture_output=True,
        text=True,
        timeout=CLI_TIMEOUT_S,
        check=False,
    )


# -- valid missions ---------------------------------------------------------------------


@pytest.mark.parametrize("path", _params(VALID))
def test_valid_mission(path: Path) -> None:
    header = read_header(path)
    result = _validate(path)
    assert result.kind == "mission"
    assert result.ok, _describe(result.errors)
    warnings = {f.code for f in result.findings if f.severity is Severity.WARNING}
    assert warnings == (header.warnings or frozenset()), (
        f"warnings differ from the '# warnings:' header:\n{_describe(result.findings)}"
    )
    assert result.mission is not None
    configs = compile_mission(result.mission)
    assert set(configs) == set(result.mission.agents)
    schema = validator("agent-config")
    for name, text in configs.items():
        config = json.loads(text)
        schema.validate(config)
        assert config["agent"]["name"] == name


# -- invalid missions -------------------------------------------------------------------


@pytest.mark.parametrize("path", _params(INVALID))
def test_invalid_mission(path: Path) -> None:
    _check_invalid(path, _validate(path), read_header(path).expects)


#: Inputs that cannot carry a header, written at run time: name -> (bytes, expected code).
GENERATED: dict[str, tuple[bytes, str]] = {
    "empty_file.yaml": (b"", "E-YAML-EMPTY"),
    "whitespace_only_file.yaml": (b"\n   \n\n", "E-YAML-EMPTY"),
    "binary_file.yaml": (b"\x89PNG\r\n\x1a\n\x00\x00\x00\rIHDR\x00\x00\x01\x00", "E-YAML-BINARY"),
    "too_large_file.yaml": (
        b"clark: 1\n" + (b"# padding\n" * (MAX_FILE_BYTES // 10 + 1)),
        "E-YAML-TOO-LARGE",
    ),
}


@pytest.mark.parametrize(("name", "content", "code"), [(n, *v) for n, v in GENERATED.items()])
def test_generated_invalid(tmp_path: Path, name: str, content: bytes, code: str) -> None:
    path = tmp_path / name
    path.write_bytes(content)
    _check_invalid(path, _validate(path), [Expect(code, 1)])


# -- the real command line --------------------------------------------------------------

#: Committed cases whose header asks for a CLI run (``# exit: N``).
CLI_CASES = [p for p in INVALID if read_header(p).exit is not None]


@pytest.mark.parametrize("path", [pytest.param(p, id=p.name) for p in CLI_CASES])
def test_cli_exit_code(path: Path) -> None:
    done = _run_cli(path)
    output = done.stdout + done.stderr
    assert "Traceback" not in output, output
    assert done.returncode == read_header(path).exit, output


@pytest.mark.parametrize("name", ["empty_file.yaml", "binary_file.yaml"])
def test_cli_generated_input(tmp_path: Path, name: str) -> None:
    path = tmp_path / name
    path.write_bytes(GENERATED[name][0])
    done = _run_cli(path)
    output = done.stdout + done.stderr
    assert "Traceback" not in output, output
    assert done.returncode == 1, output
    assert GENERATED[name][1] in output


def test_cli_directory_is_a_usage_error(tmp_path: Path) -> None:
    done = _run_cli(tmp_path)
    output = done.stdout + done.stderr
    assert "Traceback" not in output, output
    assert done.returncode == 2, output
    assert "directory" in done.stderr


def test_cli_missing_file_is_a_usage_error(tmp_path: Path) -> None:
    done = _run_cli(tmp_path / "no_such_mission.yaml")
    output = done.stdout + done.stderr
    assert "Traceback" not in output, output
    assert done.returncode == 2, output
    assert "no_such_mission.yaml" in done.stderr


def test_cli_cases_include_the_alias_bomb() -> None:
    assert INVALID_DIR / "alias_bomb.yaml" in CLI_CASES


# -- the corpus itself ------------------------------------------------------------------


def test_corpus_sizes() -> None:
    assert len(VALID) >= 8
    assert len(INVALID) >= 40


def test_invalid_corpus_covers_many_codes() -> None:
    codes = {e.code for p in INVALID for e in read_header(p).expects}
    codes |= {code for _, code in GENERATED.values()}
    assert len(codes) >= MIN_CODES_COVERED, sorted(codes)


def test_support_files_are_not_cases() -> None:
    assert not any("support" in p.parts for p in INVALID)
    assert all(read_header(p).expects for p in INVALID)
