"""Fuzz the validator far beyond the suite's bounded run, with fresh randomness.

Prints the number of inputs tried, unexpected exceptions (must be 0) and the
slowest input. Run: python benchmarks/fuzz_validate.py [EXAMPLES]
"""

from __future__ import annotations

import sys
import time
from pathlib import Path

from hypothesis import HealthCheck, given, settings

sys.path.insert(0, str(Path(__file__).resolve().parent.parent / "tests"))
import test_fuzz_validate as cases


def main() -> None:
    examples = int(sys.argv[1]) if len(sys.argv) > 1 else 2000
    slowest = [0.0]
    count = [0]

    @settings(
        max_examples=examples, deadline=None, database=None, suppress_health_check=list(HealthCheck)
    )
    @given(cases.mutated())
    def run(text: str) -> None:
        start = time.perf_counter()
        cases._validate_text(text)
        slowest[0] = max(slowest[0], time.perf_counter() - start)
        count[0] += 1

    run()
    print(f"inputs: {count[0]}, unexpected exceptions: 0, slowest: {slowest[0] * 1e3:.1f} ms")


if __name__ == "__main__":
    main()
