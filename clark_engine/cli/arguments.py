"""What ``clark``'s arguments are: its exit codes, its parser class and its argument types.

Separate from the commands because every command group shares them, and the parser
(:func:`clark_engine.cli.build_parser`) names the types: each checks one value and, when
it is not good, says why in words (a usage error, exit 2, never a traceback).
"""

from __future__ import annotations

import argparse
import sys
from collections.abc import Sequence
from typing import Any

EXIT_OK = 0
EXIT_INVALID = 1
EXIT_USAGE = 2


class Parser(argparse.ArgumentParser):
    """argparse, but usage errors exit 2 with a hint and no traceback (its default too)."""

    def error(self, message: str) -> None:  # type: ignore[override]
        """Print the usage and the error, and exit 2."""
        self.print_usage(sys.stderr)
        self.exit(EXIT_USAGE, f"{self.prog}: error: {message}\n")


def count_arg(text: str) -> int:
    """A whole number >= 1."""
    try:
        value = int(text)
    except ValueError:
        value = 0
    if value < 1:
        raise argparse.ArgumentTypeError(f"must be a whole number >= 1, not {text!r}")
    return value


def runs_arg(text: str) -> int:
    """A number of runs: 1 to the most a campaign may fly."""
    from clark_engine.mission.schema_source.dry_run import MAX_CAMPAIGN_RUNS

    value = count_arg(text)
    if value > MAX_CAMPAIGN_RUNS:
        raise argparse.ArgumentTypeError(f"at most {MAX_CAMPAIGN_RUNS} runs, not {text!r}")
    return value


def retries_arg(text: str) -> int:
    """A number of retries: a whole number 0 to 100."""
    try:
        value = int(text)
    except ValueError:
        value = -1
    if not 0 <= value <= 100:
        raise argparse.ArgumentTypeError(f"must be a whole number 0..100, not {text!r}")
    return value


def share_arg(text: str) -> float:
    """A share: a number from 0 to 1."""
    try:
        value = float(text)
    except ValueError:
        value = float("nan")
    if not 0 <= value <= 1:
        raise argparse.ArgumentTypeError(f"must be a number from 0 to 1, not {text!r}")
    return value


#: What ``clark dry-run --workers`` answers since the dry run's own split was removed.
WORKERS_REMOVED = (
    "--workers was removed: one dry run no longer splits across processes (beside other "
    "runs it was never faster; docs/performance.md); to use several cores, fly many runs "
    "with clark campaign MISSION --runs N --workers N"
)


class Removed(argparse.Action):
    """An option that is gone: taking it (with or without a value) is a usage error saying why.

    Kept hidden in the parser so that a user's old command line gets the reason and the
    way forward (exit 2), not argparse's "unrecognized arguments".
    """

    def __call__(
        self,
        parser: argparse.ArgumentParser,
        namespace: argparse.Namespace,
        values: str | Sequence[Any] | None,
        option_string: str | None = None,
    ) -> None:
        """Refuse the option with the reason it was removed (exit 2)."""
        parser.error(str(self.const))


def positive_arg(text: str, refusal: str) -> float:
    """``text`` as a finite number above 0; otherwise a usage error (exit 2) saying ``refusal``."""
    try:
        value = float(text)
    except ValueError:
        value = float("nan")
    if not 0 < value < float("inf"):
        raise argparse.ArgumentTypeError(refusal.format(text=text))
    return value


def period_s_arg(text: str) -> float:
    """A positive, finite number of seconds (or hertz)."""
    return positive_arg(text, "{text!r} is not a positive number of seconds")


def until_s_arg(text: str) -> float:
    """How long to simulate: seconds above 0, at most the language's longest time."""
    from clark_engine.mission.schema_source.common import TIME_MAX_S

    value = period_s_arg(text)
    if value > TIME_MAX_S:
        raise argparse.ArgumentTypeError(
            f"{text!r} is longer than any run (at most {TIME_MAX_S} s, as sim.duration_s)"
        )
    return value


def speed_arg(text: str) -> float:
    """A speed-up factor: a finite number above 0."""
    return positive_arg(text, "must be a number > 0, not {text!r}")


def seed_arg(text: str) -> int:
    """A random seed: a whole number >= 0; anything else is a usage error (exit 2)."""
    try:
        value = int(text)
    except ValueError:
        value = -1
    if value < 0:
        raise argparse.ArgumentTypeError(f"must be a whole number >= 0, not {text!r}")
    return value


__all__ = [
    "EXIT_INVALID",
    "EXIT_OK",
    "EXIT_USAGE",
    "WORKERS_REMOVED",
    "Parser",
    "Removed",
    "count_arg",
    "period_s_arg",
    "positive_arg",
    "retries_arg",
    "runs_arg",
    "seed_arg",
    "share_arg",
    "speed_arg",
    "until_s_arg",
]
