"""Generated documentation stays in step with the engine."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

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
