"""The statistics of a campaign's table: a pass rate's interval, a figure's spread.

Both are written from their formulas (no numerical library) so that the table is the
same bytes on every machine and every worker count.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import Final

Z_95: Final = 1.959963984540054
"""The standard normal quantile for a two-sided 95 % interval (Phi^-1(0.975))."""

PERCENTILES: Final = (0.0, 5.0, 50.0, 95.0, 100.0)
"""The spread the table gives of each figure: min, p5, median, p95, max."""


def wilson_interval(passed: int, total: int, z: float = Z_95) -> tuple[float, float]:
    """The Wilson score interval of a pass rate: where the true rate likely lies.

    With ``p = passed / total`` and ``n = total``, the interval is::

        (p + z^2 / 2n -+ z * sqrt(p (1 - p) / n + z^2 / 4n^2)) / (1 + z^2 / n)

    Unlike the normal approximation ``p -+ z sqrt(p (1 - p) / n)`` it never leaves 0..1
    and is not empty at 0 or n passes (10 passes of 10 is not proof of a rate of 1: the
    interval is 0.72..1), which is why campaigns of a few hundred runs use it.

    Args:
        passed: Runs in which it held.
        total: Runs in which it was judged (0 gives the whole 0..1).
        z: The normal quantile of the confidence level (95 % by default).

    Raises:
        ValueError: ``passed`` outside 0..total.
    """
    if not 0 <= passed <= total:
        raise ValueError(f"passed {passed} is outside 0..{total}")
    if total == 0:
        return 0.0, 1.0
    n = float(total)
    p = passed / n
    z2 = z * z
    centre = p + z2 / (2 * n)
    half = z * math.sqrt(p * (1 - p) / n + z2 / (4 * n * n))
    scale = 1 + z2 / n
    low = (centre - half) / scale
    high = (centre + half) / scale
    # The bounds are exactly 0 and 1 at 0 and n passes; keep float noise from showing.
    return (0.0 if passed == 0 else max(0.0, low)), (1.0 if passed == total else min(1.0, high))


def percentile(sorted_values: Sequence[float], q: float) -> float:
    """The ``q``-th percentile (0..100) of sorted values, linearly interpolated.

    The definition of numpy's default (``linear``, Hyndman and Fan's type 7): the value
    at rank ``(n - 1) q / 100``, between the two nearest values.

    Raises:
        ValueError: No values, or ``q`` outside 0..100.
    """
    if not sorted_values:
        raise ValueError("no values")
    if not 0 <= q <= 100:
        raise ValueError(f"percentile {q} is outside 0..100")
    rank = (len(sorted_values) - 1) * q / 100.0
    below = math.floor(rank)
    above = min(below + 1, len(sorted_values) - 1)
    share = rank - below
    low, high = sorted_values[below], sorted_values[above]
    return low + (high - low) * share if share else low


def spread(values: Sequence[float]) -> tuple[float, ...]:
    """min, p5, median, p95 and max of ``values`` (:data:`PERCENTILES`).

    Raises:
        ValueError: No values.
    """
    ordered = sorted(values)
    return tuple(percentile(ordered, q) for q in PERCENTILES)
