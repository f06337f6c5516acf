"""The statistics of clark campaign's table, against published and computed values."""

from __future__ import annotations

import random

import numpy as np
import pytest

from clark_engine.campaign.runs import run_seed
from clark_engine.campaign.stats import percentile, spread, wilson_interval

# Newcombe (1998), "Two-sided confidence intervals for the single proportion: comparison
# of seven methods", Statistics in Medicine 17, Table II, method 3 (Wilson score, no
# continuity correction), to four decimals.
NEWCOMBE = [
    (81, 263, 0.2553, 0.3662),
    (15, 148, 0.0624, 0.1605),
    (0, 20, 0.0, 0.1611),
    (1, 29, 0.0061, 0.1718),
]


@pytest.mark.parametrize(("passed", "total", "low", "high"), NEWCOMBE)
def test_wilson_interval_matches_newcombes_table(
    passed: int, total: int, low: float, high: float
) -> None:
    got = wilson_interval(passed, total)
    assert got == pytest.approx((low, high), abs=5e-5)


def test_wilson_interval_at_the_ends_and_its_symmetry() -> None:
    # 10 of 10 is no proof of a rate of 1; the interval stays inside 0..1.
    assert wilson_interval(10, 10) == pytest.approx((0.7225, 1.0), abs=5e-5)
    assert wilson_interval(0, 10) == pytest.approx((0.0, 0.2775), abs=5e-5)
    low, high = wilson_interval(3, 8)
    mirrored = wilson_interval(5, 8)
    assert (low, high) == pytest.approx((1 - mirrored[1], 1 - mirrored[0]))
    assert wilson_interval(0, 0) == (0.0, 1.0)
    with pytest.raises(ValueError, match="outside"):
        wilson_interval(5, 4)


def test_percentiles_match_numpys_linear_definition() -> None:
    rng = random.Random("campaign-percentiles")
    for size in (1, 2, 3, 7, 20, 201):
        values = [rng.gauss(10, 3) for _ in range(size)]
        expected = np.percentile(values, [0, 5, 50, 95, 100])
        assert spread(values) == pytest.approx(list(expected), rel=1e-12, abs=1e-12)
    assert percentile([1.0, 2.0, 3.0, 4.0], 50) == 2.5
    with pytest.raises(ValueError):
        percentile([], 50)


def test_run_seeds_are_stable_and_distinct() -> None:
    # SHA-256, not hash(): the same on every machine and in every worker process.
    assert run_seed(1, 0) == 1527807775
    assert run_seed(1, 1) == 1634134365
    seeds = {run_seed(7, i) for i in range(1000)}
    assert len(seeds) == 1000
    assert all(0 <= s < 2**32 for s in seeds)
