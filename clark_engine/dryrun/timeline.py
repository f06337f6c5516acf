"""The same mission both ways: a SITL run against the simulated run, state by state.

``clark dry-run --autopilot sitl`` flies the mission on real ArduPilot and, on its
own virtual clock, on the simulated autopilot too. If the simulation is as strict
as ArduPilot, every agent enters the same states in the same order at about the
same times and places, and the mission's checks see about the same figures.
:func:`compare` judges, for each agent:

- **Each state's first entry.** Both runs must enter the same states in the same
  order. Each state's *leg* is the time since the agent's previous state change
  (the previous state it first entered), on SITL. A state holds when either its
  entry time or its leg's duration differs from SITL's by no more than the leg's
  share allowed (:attr:`Tolerance.sim_sooner_share` when the simulation was sooner,
  :attr:`Tolerance.sim_later_share` when later), and never less than
  :attr:`Tolerance.time_floor_s`. The leg's duration is what a motion changes (a leg
  flown 0.62x as fast fails however late it started); the entry time is what a
  clock-driven change keeps (the operator's action at 20 s comes at 20 s even after
  a state that was a little late).
- **Where it was.** At each state's entry, and at the end of the run (an aircraft that
  circles in both runs then: the centres of its circles), the vehicle's
  horizontal position in the two runs may be :attr:`Tolerance.position_m` apart, plus
  the way it covers (at its speed on SITL) in the entry times' difference; an
  aircraft's altitude :attr:`Tolerance.altitude_m`.
- **The mission's checks.** Each check's verdict must be the same in both runs (or
  FAIL simulated where SITL passed: the dry run was stricter, not kinder), and
  each figure it observed (:class:`~clark_engine.expectations.evaluate.Figure`) within its
  tolerance: a moment like a state's entry (the leg it falls in being its agent's),
  distances and altitudes in metres, counts (photos) within a share, a pulse width's
  error within 1 us.

The tolerances are the mission's ``sim.sitl_tolerance``; docs/autopilot-fidelity.md
("The same mission both ways") gives each default and why.

States are compared by their first entry only: a looping tour re-enters its
states at times that drift apart lap by lap, which says nothing about fidelity
once the first lap matched.
"""

from __future__ import annotations

import math
from collections.abc import Iterable, Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any, Final

from clark_engine.expectations.evaluate import CheckResult, Figure
from clark_engine.expectations.recording import Recording, Track

END_ROW: Final = "(end of run)"
"""The path shown for an agent's row at the end of the run (position only)."""
WHOLE_BEHAVIOUR: Final = "(the whole behaviour)"
"""How the root state (the empty path) is shown."""
CIRCLE_STEP_S: Final = 2.0
"""Seconds between the positions that find the circle an aircraft flies at the end."""
CIRCLE_MAX_M: Final = 500.0
"""A circle wider than this is not a loiter."""
SPEED_WINDOW_S: Final = 1.0
"""A vehicle's speed at a moment: over the second before it, on SITL."""
ERROR_US_TOLERANCE: Final = 1.0
"""A signal check's error may differ by this much: the check's own bound."""


@dataclass(frozen=True, slots=True)
class Tolerance:
    """How close the two runs must be (the mission's ``sim.sitl_tolerance``)."""

    time_floor_s: float = 3.0
    """The least a state's entry may differ, whatever its leg."""
    sim_sooner_share: float = 0.1
    """How much sooner the simulation may be, as a share of SITL's leg."""
    sim_later_share: float = 0.3
    """How much later the simulation may be, as a share of SITL's leg."""
    position_m: float = 10.0
    """Horizontal distance allowed between the runs at each state change and at the end."""
    altitude_m: float = 3.0
    """Altitude difference allowed for an aircraft, likewise."""
    count_share: float = 0.1
    """A check's count (photos) may differ by this share of SITL's, never less than one."""

    @classmethod
    def from_sim(cls, sim: Mapping[str, Any]) -> Tolerance:
        """The mission's ``sim.sitl_tolerance``, defaults for what it leaves out."""
        given = sim.get("sitl_tolerance") or {}
        return cls(**{k: float(v) for k, v in given.items() if k in cls.__dataclass_fields__})

    def allowed_s(self, leg_s: float, sim_sooner: bool) -> float:
        """The time difference allowed for a leg of ``leg_s`` seconds (on SITL)."""
        share = self.sim_sooner_share if sim_sooner else self.sim_later_share
        return max(self.time_floor_s, share * max(leg_s, 0.0))

    def text(self) -> str:
        """The tolerance in words, for the checks table."""
        return (
            f"{self.time_floor_s:g} s or {self.sim_sooner_share:.0%} of the leg sooner, "
            f"{self.sim_later_share:.0%} later; {self.position_m:g} m apart, altitude "
            f"{self.altitude_m:g} m"
        )


@dataclass(frozen=True, slots=True)
class StateTimes:
    """One state of one agent in both runs: when and where each first entered it.

    Also the end of the run (:data:`END_ROW`), where only the positions are compared.
    """

    agent: str
    path: str
    simulated_s: float | None
    sitl_s: float | None
    leg_s: float | None = None
    """SITL's time since the agent's previous state change (None: not in both runs)."""
    leg_difference_s: float | None = None
    """SITL's leg minus the simulated run's (positive: the simulation was quicker)."""
    allowed_s: float | None = None
    """The time difference allowed for this state."""
    horizontal_m: float | None = None
    """How far apart the vehicle was in the two runs, horizontally (None: no track)."""
    altitude_m: float | None = None
    """An aircraft's altitude on SITL minus in the simulation (None: a rover, no track)."""
    tolerance: Tolerance = field(default_factory=Tolerance)
    allowed_m: float | None = None
    """The horizontal distance allowed: :attr:`Tolerance.position_m`, plus what the vehicle
    covers (at its speed on SITL) in the entry-time difference."""
    circles: bool = False
    """The end row of an aircraft circling in both runs: its circles' centres compared
    (where on the circle it is says when it got there, which the states judge)."""

    @property
    def difference_s(self) -> float | None:
        """SITL minus simulated entry time, seconds; None when one run never entered it."""
        if self.simulated_s is None or self.sitl_s is None:
            return None
        return self.sitl_s - self.simulated_s

    @property
    def time_error_s(self) -> float | None:
        """The difference judged: the entry's or the leg's, whichever is smaller.

        Positive: the simulation was sooner than SITL. None for the end row, or a state
        one run never entered.
        """
        entry = self.difference_s
        if entry is None or self.path == END_ROW:
            return None
        leg = self.leg_difference_s
        if leg is None or abs(entry) <= abs(leg):
            return entry
        return leg

    @property
    def problems(self) -> list[str]:
        """What is out of tolerance in this row, in words (empty: it holds)."""
        out: list[str] = []
        if self.difference_s is None and self.path != END_ROW:
            run = "SITL" if self.sitl_s is None else "the simulated run"
            return [f"never entered in {run}"]
        error = self.time_error_s
        if error is not None and self.allowed_s is not None and abs(error) > self.allowed_s:
            out.append(f"{error:+.1f} s (allowed {self.allowed_s:.1f} s)")
        allowed_m = self.tolerance.position_m if self.allowed_m is None else self.allowed_m
        if self.horizontal_m is not None and self.horizontal_m > allowed_m + 1e-9:
            out.append(f"{self.horizontal_m:.1f} m apart (allowed {allowed_m:.1f} m)")
        if self.altitude_m is not None and abs(self.altitude_m) > self.tolerance.altitude_m:
            out.append(f"altitude {self.altitude_m:+.1f} m")
        return out

    @property
    def holds(self) -> bool:
        """Entered in both runs, within every tolerance."""
        return not self.problems


@dataclass(frozen=True, slots=True)
class FigureRow:
    """One figure of one check, in both runs."""

    check: str
    figure: str
    kind: str
    simulated: float | None
    sitl: float | None
    allowed: float | None

    @property
    def difference(self) -> float | None:
        """SITL minus simulated; None when one run did not observe it."""
        if self.simulated is None or self.sitl is None:
            return None
        return self.sitl - self.simulated

    @property
    def holds(self) -> bool:
        """Within its tolerance.

        A figure only one run observed says nothing on its own (the verdicts, compared
        apart, then differ).
        """
        diff = self.difference
        return diff is None or self.allowed is None or abs(diff) <= self.allowed + 1e-9

    def value_text(self, value: float | None) -> str:
        """A value with its unit."""
        if value is None:
            return "-"
        return _with_unit(value, self.kind)


@dataclass(frozen=True, slots=True)
class VerdictRow:
    """One check's verdict in both runs."""

    check: str
    simulated: str
    sitl: str

    @property
    def stricter(self) -> bool:
        """The simulated run failed the check and SITL passed it."""
        return self.simulated == "FAIL" and self.sitl == "pass"

    @property
    def holds(self) -> bool:
        """The same verdict, or a stricter one simulated.

        A check that passes simulated and fails on SITL is what the comparison is for
        (the simulation kinder than ArduPilot). One that fails simulated and passes on
        SITL is not: the dry run was stricter, and its own verdict said so already. The
        check's figures are judged apart (:class:`FigureRow`), so two runs that meet a
        check's edge on different sides (a closest approach of 6.0 m simulated and 5.9 m
        on SITL, 6 m allowed) hold, and two that differ beyond the figure's tolerance
        do not.
        """
        return self.simulated == self.sitl or self.stricter


@dataclass(frozen=True, slots=True)
class Comparison:
    """Both runs side by side: states, positions and the checks' figures.

    Attributes:
        rows: Every state either run entered, per agent in mission order, in the order
            the simulated run entered them (states only SITL entered last), then the
            agent's end-of-run row.
        tolerance: What is allowed.
        out_of_order: Agents whose states SITL entered in another order.
        verdicts: Each of the mission's checks: its verdict in both runs.
        figures: Each figure of each check, in both runs.
    """

    rows: tuple[StateTimes, ...]
    tolerance: Tolerance
    out_of_order: tuple[str, ...]
    verdicts: tuple[VerdictRow, ...] = ()
    figures: tuple[FigureRow, ...] = ()

    @property
    def tolerance_s(self) -> float:
        """The time floor (the least any state is allowed)."""
        return self.tolerance.time_floor_s

    @property
    def states(self) -> tuple[StateTimes, ...]:
        """The state rows, without the end-of-run rows."""
        return tuple(r for r in self.rows if r.path != END_ROW)

    @property
    def missing(self) -> tuple[StateTimes, ...]:
        """States one run entered and the other did not."""
        return tuple(r for r in self.states if r.difference_s is None)

    @property
    def late(self) -> tuple[StateTimes, ...]:
        """States entered in both whose time is out of tolerance."""
        return tuple(
            r
            for r in self.states
            if r.time_error_s is not None
            and r.allowed_s is not None
            and abs(r.time_error_s) > r.allowed_s
        )

    @property
    def holds(self) -> bool:
        """Same states, same order, each within its tolerances; same verdicts and figures."""
        return (
            not self.out_of_order
            and all(r.holds for r in self.rows)
            and all(v.holds for v in self.verdicts)
            and all(f.holds for f in self.figures)
        )

    def worst(self) -> list[str]:
        """The largest time, position, altitude and figure differences, in words."""
        out: list[str] = []
        timed = [r for r in self.states if r.time_error_s is not None and r.allowed_s]
        if timed:
            r = max(timed, key=lambda r: abs(r.time_error_s or 0.0) / (r.allowed_s or 1.0))
            out.append(
                f"time {r.agent} {_path(r.path)} {r.time_error_s:+.1f} s of {r.allowed_s:.1f} s"
            )
        placed = [r for r in self.rows if r.horizontal_m is not None]
        if placed:
            r = max(placed, key=lambda r: r.horizontal_m or 0.0)
            out.append(f"position {r.agent} {_path(r.path)} {r.horizontal_m:.1f} m")
        raised = [r for r in self.rows if r.altitude_m is not None]
        if raised:
            r = max(raised, key=lambda r: abs(r.altitude_m or 0.0))
            out.append(f"altitude {r.agent} {_path(r.path)} {r.altitude_m:+.1f} m")
        measured = [f for f in self.figures if f.difference is not None and f.allowed]
        if measured:
            f = max(measured, key=lambda f: abs(f.difference or 0.0) / (f.allowed or 1.0))
            diff = f.difference or 0.0
            out.append(
                f"figure {f.check}: {f.figure} {_with_unit(diff, f.kind, signed=True)} "
                f"of {_with_unit(f.allowed or 0.0, f.kind)}"
            )
        return out

    def check(self) -> CheckResult:
        """The comparison as one row of the checks table: what was compared, the worst."""
        expected = (
            "every agent enters the simulated run's states in the same order, each within "
            f"{self.tolerance.text()}; the checks' verdicts and figures alike"
        )
        states = len(self.states)
        if not states and not self.verdicts:
            observed = "no state entered in either run (yet)"
        elif self.holds:
            observed = (
                f"{states} states, {len(self.verdicts)} checks ({len(self.figures)} figures) "
                "matched; worst: " + ("; ".join(self.worst()) or "none")
            )
            stricter = [v.check for v in self.verdicts if v.stricter]
            if stricter:
                observed += "; failed simulated, passed on SITL: " + ", ".join(stricter)
        else:
            problems: list[str] = []
            if self.out_of_order:
                problems.append(f"another order: {', '.join(self.out_of_order)}")
            for r in self.rows:
                problems.extend(f"{r.agent} {_path(r.path)} {p}" for p in r.problems)
            for v in self.verdicts:
                if not v.holds:
                    problems.append(f"{v.check}: {v.sitl} on SITL, {v.simulated} simulated")
            for f in self.figures:
                if not f.holds:
                    problems.append(
                        f"{f.check}: {f.figure} {f.value_text(f.sitl)} on SITL, "
                        f"{f.value_text(f.simulated)} simulated (allowed "
                        f"{_with_unit(f.allowed or 0.0, f.kind)})"
                    )
            observed = "; ".join(problems)
        return CheckResult(
            "the same mission on ArduPilot SITL", expected, observed, passed=self.holds
        )

    def table(self) -> str:
        """Markdown: per agent, each state's times, allowance and distances; then the checks."""
        lines: list[str] = [f"Tolerance: {self.tolerance.text()}.", ""]
        agents = list(dict.fromkeys(r.agent for r in self.rows))
        for agent in agents:
            order = (
                " (SITL entered its states in another order)" if agent in self.out_of_order else ""
            )
            lines += [
                f"### {agent}{order}",
                "",
                "| state | simulated | SITL | leg (SITL) | difference (entry / leg) | allowed "
                "| apart (allowed) | altitude | verdict |",
                "|---|---|---|---|---|---|---|---|---|",
            ]
            for r in self.rows:
                if r.agent != agent:
                    continue
                lines.append(
                    f"| {_row_name(r)} | {_s(r.simulated_s)} | {_s(r.sitl_s)} | {_s(r.leg_s)} "
                    f"| {_diff(r)} | {_s(r.allowed_s)} | {_apart_text(r)} "
                    f"| {_m(r.altitude_m, signed=True)} "
                    f"| {'pass' if r.holds else '**FAIL**: ' + '; '.join(r.problems)} |"
                )
            lines.append("")
        if self.verdicts:
            lines += [
                "### The mission's checks",
                "",
                "| check | figure | simulated | SITL | allowed | verdict |",
                "|---|---|---|---|---|---|",
            ]
            for v in self.verdicts:
                held = "pass (stricter simulated)" if v.stricter else "pass"
                lines.append(
                    f"| {v.check} | verdict | {v.simulated} | {v.sitl} | the same, or FAIL "
                    f"simulated | {held if v.holds else '**FAIL**'} |"
                )
                for f in self.figures:
                    if f.check != v.check:
                        continue
                    allowed = "-" if f.allowed is None else _with_unit(f.allowed, f.kind)
                    lines.append(
                        f"| {f.check} | {f.figure} | {f.value_text(f.simulated)} "
                        f"| {f.value_text(f.sitl)} | {allowed} "
                        f"| {'pass' if f.holds else '**FAIL**'} |"
                    )
            lines.append("")
        return "\n".join(lines)


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
    tolerance: Tolerance | None = None,
    *,
    end_s: float = math.inf,
    aircraft: Iterable[str] = (),
    checks: tuple[Sequence[CheckResult], Sequence[CheckResult]] | None = None,
) -> Comparison:
    """Judge the SITL run against the simulated one (see the module docstring).

    Args:
        simulated: The run on the simulated autopilot.
        sitl: The run on ArduPilot SITL.
        agents: The vehicles to compare, in mission order.
        tolerance: What is allowed; the defaults when None.
        end_s: Compare up to this time only (a SITL run ended early by Ctrl-C).
        aircraft: The agents whose altitude counts (a rover's is the ground's).
        checks: The mission's checks as evaluated on (the simulated run, SITL), in the
            same order; their verdicts and figures are compared.
    """
    tol = tolerance if tolerance is not None else Tolerance()
    flying = set(aircraft)
    rows: list[StateTimes] = []
    out_of_order: list[str] = []
    for agent in agents:
        ours, theirs = first_entries(simulated, agent, end_s), first_entries(sitl, agent, end_s)
        if _order(ours, theirs) != _order(theirs, ours):
            out_of_order.append(agent)
        three_d = agent in flying
        for path in [*ours, *(p for p in theirs if p not in ours)]:
            sim_s, sitl_s = ours.get(path), theirs.get(path)
            if sim_s is None or sitl_s is None:
                rows.append(StateTimes(agent, path, sim_s, sitl_s, tolerance=tol))
                continue
            # The previous state change: the latest shared state SITL entered before this one.
            before = [(theirs[p], ours[p]) for p in theirs if p in ours and theirs[p] < sitl_s]
            prev_sitl, prev_sim = max(before) if before else (0.0, 0.0)
            leg_s = sitl_s - prev_sitl
            leg_difference_s = leg_s - (sim_s - prev_sim)
            entry_difference_s = sitl_s - sim_s
            judged = (
                entry_difference_s
                if abs(entry_difference_s) <= abs(leg_difference_s)
                else leg_difference_s
            )
            horizontal, altitude = _apart(simulated, sitl, agent, sim_s, sitl_s, three_d)
            rows.append(
                StateTimes(
                    agent,
                    path,
                    sim_s,
                    sitl_s,
                    leg_s,
                    leg_difference_s,
                    tol.allowed_s(leg_s, sim_sooner=judged > 0),
                    horizontal,
                    altitude,
                    tol,
                    _allowed_m(sitl, agent, sitl_s, abs(entry_difference_s), tol),
                )
            )
        if agent in simulated.tracks and agent in sitl.tracks:
            sim_end = min(end_s, simulated.end_s)
            sitl_end = min(end_s, sitl.end_s)
            horizontal, altitude = _apart(simulated, sitl, agent, sim_end, sitl_end, three_d)
            ours_c = _circling(simulated.tracks[agent], sim_end) if three_d else None
            theirs_c = _circling(sitl.tracks[agent], sitl_end) if three_d else None
            if ours_c is not None and theirs_c is not None:
                # Both circle at the end: where is the circle, not where on it.
                horizontal = math.dist(ours_c, theirs_c)
            rows.append(
                StateTimes(
                    agent,
                    END_ROW,
                    sim_end,
                    sitl_end,
                    horizontal_m=horizontal,
                    altitude_m=altitude,
                    tolerance=tol,
                    allowed_m=tol.position_m
                    if ours_c is not None and theirs_c is not None
                    else _allowed_m(sitl, agent, sitl_end, 0.0, tol),
                    circles=ours_c is not None and theirs_c is not None,
                )
            )
    verdicts: list[VerdictRow] = []
    figures: list[FigureRow] = []
    if checks is not None:
        for ours_check, theirs_check in zip(*checks, strict=False):
            verdicts.append(VerdictRow(ours_check.name, ours_check.verdict, theirs_check.verdict))
            figures.extend(_figure_rows(ours_check, theirs_check, sitl, tol))
    return Comparison(tuple(rows), tol, tuple(out_of_order), tuple(verdicts), tuple(figures))


def _figure_rows(
    ours: CheckResult, theirs: CheckResult, sitl: Recording, tol: Tolerance
) -> list[FigureRow]:
    """One row per figure either run observed (by name), with what is allowed."""
    mine = {f.name: f for f in ours.figures}
    other = {f.name: f for f in theirs.figures}
    out = []
    for name in [*mine, *(n for n in other if n not in mine)]:
        a, b = mine.get(name), other.get(name)
        either = a if a is not None else b
        kind = either.kind if either is not None else ""
        allowed = None
        if a is not None and b is not None:
            allowed = _figure_allowed(a, b, sitl, tol)
        out.append(
            FigureRow(
                ours.name, name, kind, a.value if a else None, b.value if b else None, allowed
            )
        )
    return out


def _figure_allowed(ours: Figure, theirs: Figure, sitl: Recording, tol: Tolerance) -> float:
    """How far apart the two runs' values of one figure may be."""
    if theirs.kind == "time_s":
        # A moment: judged as a state entered then, on its agent's leg at that moment.
        changes = [
            e.time_s
            for e in sitl.states.get(theirs.agent or "", [])
            if e.time_s < theirs.value - 1e-9
        ]
        leg_s = theirs.value - (changes[-1] if changes else 0.0)
        return tol.allowed_s(leg_s, sim_sooner=theirs.value > ours.value)
    if theirs.kind == "distance_m":
        return tol.position_m
    if theirs.kind == "altitude_m":
        return tol.altitude_m
    if theirs.kind == "count":
        return max(1.0, tol.count_share * abs(theirs.value))
    return ERROR_US_TOLERANCE


def _circling(track: Track, end_s: float) -> tuple[float, float] | None:
    """The centre of the circle an aircraft flies at ``end_s``; None when it does not circle.

    Three positions :data:`CIRCLE_STEP_S` apart give a circle; a fourth one step before
    must lie on it (within a fifth of its radius), and the radius be under
    :data:`CIRCLE_MAX_M`: a loiter, not a straight line or a turn.
    """
    points = [track.at(end_s - k * CIRCLE_STEP_S) for k in range(4)]
    if any(p is None for p in points):
        return None
    (ax, ay, _), (bx, by, _), (cx, cy, _), (dx, dy, _) = points  # type: ignore[misc]
    det = 2.0 * (ax * (by - cy) + bx * (cy - ay) + cx * (ay - by))
    if abs(det) < 1e-6:
        return None
    a2, b2, c2 = ax * ax + ay * ay, bx * bx + by * by, cx * cx + cy * cy
    ux = (a2 * (by - cy) + b2 * (cy - ay) + c2 * (ay - by)) / det
    uy = (a2 * (cx - bx) + b2 * (ax - cx) + c2 * (bx - ax)) / det
    radius = math.hypot(ax - ux, ay - uy)
    if radius > CIRCLE_MAX_M or abs(math.hypot(dx - ux, dy - uy) - radius) > radius / 5.0:
        return None
    return ux, uy


def _allowed_m(
    sitl: Recording, agent: str, sitl_s: float, difference_s: float, tol: Tolerance
) -> float:
    """The horizontal distance allowed at a moment: the tolerance, plus the way covered.

    The way the vehicle covers, at its speed on SITL, in the time the two runs differ by
    there: a plane at 18 m/s that begins its survey 1.9 s later is 34 m on. (Not the
    time floor's way: a plane whose path strayed 35 m would pass.)
    """
    track = sitl.tracks.get(agent)
    now = track.at(sitl_s) if track is not None else None
    before = track.at(sitl_s - SPEED_WINDOW_S) if track is not None else None
    if now is None or before is None:
        return tol.position_m
    speed_m_s = math.hypot(now[0] - before[0], now[1] - before[1]) / SPEED_WINDOW_S
    return tol.position_m + speed_m_s * difference_s


def _apart(
    simulated: Recording, sitl: Recording, agent: str, sim_s: float, sitl_s: float, three_d: bool
) -> tuple[float | None, float | None]:
    """(horizontal distance, SITL's altitude minus the simulation's) at those two moments."""
    a = simulated.tracks.get(agent)
    b = sitl.tracks.get(agent)
    here = a.at(sim_s) if a is not None else None
    there = b.at(sitl_s) if b is not None else None
    if here is None or there is None:
        return None, None
    horizontal = math.hypot(there[0] - here[0], there[1] - here[1])
    return horizontal, (there[2] - here[2]) if three_d else None


def _order(first: Mapping[str, float], other: Mapping[str, float]) -> list[str]:
    """The states both runs entered, in ``first``'s order."""
    return [path for path in first if path in other]


def _path(path: str) -> str:
    return path or WHOLE_BEHAVIOUR


def _row_name(row: StateTimes) -> str:
    return "(end of run: its circle's centre)" if row.circles else _path(row.path)


def _s(value: float | None) -> str:
    return "-" if value is None else f"{value:.1f} s"


def _m(value: float | None, signed: bool = False) -> str:
    if value is None:
        return "-"
    return f"{value:+.1f} m" if signed else f"{value:.1f} m"


def _apart_text(row: StateTimes) -> str:
    if row.horizontal_m is None:
        return "-"
    allowed = row.tolerance.position_m if row.allowed_m is None else row.allowed_m
    return f"{row.horizontal_m:.1f} m ({allowed:.1f} m)"


def _diff(row: StateTimes) -> str:
    if row.difference_s is None or row.path == END_ROW:
        return "-"
    leg = "-" if row.leg_difference_s is None else f"{row.leg_difference_s:+.1f} s"
    return f"{row.difference_s:+.1f} s / {leg}"


def _with_unit(value: float, kind: str, signed: bool = False) -> str:
    """A figure's value as the table shows it."""
    unit = {"time_s": " s", "distance_m": " m", "altitude_m": " m", "error_us": " us"}
    text = f"{value:+.1f}" if signed else f"{value:.1f}"
    if kind == "count":
        text = f"{value:+g}" if signed else f"{value:g}"
    return text + unit.get(kind, "")
