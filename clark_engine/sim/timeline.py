"""The same mission both ways: the states a SITL run reached against the simulated run's.

``clark dry-run --autopilot sitl`` flies the mission on real ArduPilot and, on its
own virtual clock, on the simulated autopilot too. If the simulation is as strict
as ArduPilot, every agent enters the same states in the same order at about the
same times. :func:`compare` lines the two up: for each agent, the first time each
state was entered in either run, in the order the simulated run entered them. The
comparison holds when both runs entered the same states, in the same order, each
within the mission's tolerance (``sim.sitl_tolerance_s``).

States are compared by their first entry only: a looping tour re-enters its
states at times that drift apart lap by lap, which says nothing about fidelity
once the first lap matched.
"""

from __future__ import annotations

import math
from collections.abc import Iterable, Mapping
from dataclasses import dataclass
from typing import Final

from clark_engine.sim.checks import CheckResult
from clark_engine.sim.recording import Recording

DEFAULT_TOLERANCE_S: Final = 10.0
"""How far apart a state's first entry may be in the two runs when a mission says nothing."""


@dataclass(frozen=True, slots=True)
class StateTimes:
    """One state of one agent: when each run first entered it (None: never)."""

    agent: str
    path: str
    simulated_s: float | None
    sitl_s: float | None

    @property
    def difference_s(self) -> float | None:
        """SITL minus simulated, seconds; None when one run never entered it."""
        if self.simulated_s is None or self.sitl_s is None:
            return None
        return self.sitl_s - self.simulated_s


@dataclass(frozen=True, slots=True)
class Comparison:
    """Both runs' state timelines, side by side.

    Attributes:
        rows: Every state either run entered, per agent in mission order, in the
            order the simulated run entered them (states only SITL entered last).
        tolerance_s: The largest difference allowed.
        out_of_order: Agents whose states SITL entered in another order.
    """

    rows: tuple[StateTimes, ...]
    tolerance_s: float
    out_of_order: tuple[str, ...]

    @property
    def missing(self) -> tuple[StateTimes, ...]:
        """States one run entered and the other did not."""
        return tuple(r for r in self.rows if r.difference_s is None)

    @property
    def late(self) -> tuple[StateTimes, ...]:
        """States entered in both, further apart than the tolerance."""
        return tuple(
            r
            for r in self.rows
            if r.difference_s is not None and abs(r.difference_s) > self.tolerance_s
        )

    @property
    def holds(self) -> bool:
        """Same states, same order, each within the tolerance."""
        return not (self.missing or self.late or self.out_of_order)

    def check(self) -> CheckResult:
        """The comparison as one row of the checks table."""
        expected = (
            f"every agent enters the simulated run's states in the same order, each within "
            f"{self.tolerance_s:g} s"
        )
        if not self.rows:
            observed = "no state entered in either run (yet)"
        elif self.holds:
            worst = max((abs(r.difference_s or 0.0) for r in self.rows), default=0.0)
            observed = f"{len(self.rows)} states matched; largest difference {worst:.1f} s"
        else:
            problems: list[str] = []
            if self.out_of_order:
                problems.append(f"another order: {', '.join(self.out_of_order)}")
            for r in self.missing:
                run = "SITL" if r.sitl_s is None else "the simulated run"
                problems.append(f"{r.agent} {r.path} never entered in {run}")
            for r in self.late:
                problems.append(f"{r.agent} {r.path} {r.difference_s:+.1f} s")
            observed = "; ".join(problems)
        return CheckResult(
            "the same mission on ArduPilot SITL", expected, observed, passed=self.holds
        )

    def table(self) -> str:
        """A Markdown table: agent, state, simulated and SITL first-entry times."""
        lines = [
            "| agent | state | simulated | SITL | difference |",
            "|---|---|---|---|---|",
        ]
        for r in self.rows:
            sim = "-" if r.simulated_s is None else f"{r.simulated_s:.1f} s"
            sitl = "-" if r.sitl_s is None else f"{r.sitl_s:.1f} s"
            diff = "-" if r.difference_s is None else f"{r.difference_s:+.1f} s"
            lines.append(
                f"| {r.agent} | {r.path or '(the whole behaviour)'} | {sim} | {sitl} | {diff} |"
            )
        return "\n".join(lines) + "\n"


def first_entries(recording: Recording, agent: str, end_s: float = math.inf) -> dict[str, float]:
    """Each state path the agent entered up to ``end_s``, with the first time, in entry order."""
    out: dict[str, float] = {}
    for entry in recording.states.get(agent, []):
        if entry.time_s > end_s:
            break
        for path in entry.entered:
            out.setdefault(path, entry.time_s)
    return out


def compare(
    simulated: Recording,
    sitl: Recording,
    agents: Iterable[str],
    tolerance_s: float = DEFAULT_TOLERANCE_S,
    *,
    end_s: float = math.inf,
) -> Comparison:
    """Line up the two runs' state timelines (see the module docstring).

    ``end_s``: compare up to this time only (a SITL run ended early by Ctrl-C).
    """
    rows: list[StateTimes] = []
    out_of_order: list[str] = []
    for agent in agents:
        ours, theirs = first_entries(simulated, agent, end_s), first_entries(sitl, agent, end_s)
        if _order(ours, theirs) != _order(theirs, ours):
            out_of_order.append(agent)
        for path in [*ours, *(p for p in theirs if p not in ours)]:
            rows.append(StateTimes(agent, path, ours.get(path), theirs.get(path)))
    return Comparison(tuple(rows), tolerance_s, tuple(out_of_order))


def _order(first: Mapping[str, float], other: Mapping[str, float]) -> list[str]:
    """The states both runs entered, in ``first``'s order."""
    return [path for path in first if path in other]
