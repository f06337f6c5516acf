"""The import rules of docs/architecture.md ("Import direction"), held by import-linter.

The rules themselves are pyproject.toml's ``[tool.importlinter]`` contracts: the packages
in layers, each importing only downwards, and what the simulated ArduPilot, the mission
language, the runtime core and ClarkLink must never import.
"""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
LINT_IMPORTS = Path(sys.executable).with_name("lint-imports")


def lint(*args: str) -> subprocess.CompletedProcess[str]:
    return subprocess.run(
        [str(LINT_IMPORTS), "--no-cache", *args],
        cwd=ROOT,
        capture_output=True,
        text=True,
        timeout=300,
        check=False,
    )


def test_every_package_keeps_the_import_rules() -> None:
    result = lint()
    assert result.returncode == 0, result.stdout + result.stderr
    assert "0 broken" in result.stdout


def test_a_broken_rule_is_reported(tmp_path: Path) -> None:
    """The checker sees the engine's imports: a rule the code breaks today fails."""
    config = tmp_path / "contracts.ini"
    config.write_text(
        "[importlinter]\n"
        "root_package = clark_engine\n"
        "\n"
        "[importlinter:contract:dry-run-without-simulator]\n"
        "name = the dry run without its simulated autopilot\n"
        "type = forbidden\n"
        "source_modules = clark_engine.dryrun.backend\n"
        "forbidden_modules = clark_engine.sim.ardupilot\n"
    )
    result = lint("--config", str(config))
    assert result.returncode == 1, result.stdout + result.stderr
    assert "clark_engine.dryrun.backend -> clark_engine.sim.ardupilot" in result.stdout
