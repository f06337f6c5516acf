"""Evaluate a mission's ``checks:`` against what a dry run recorded.

Each check states one expectation (see the mission schema); the result says
what was expected, what was observed, and whether it held, for the table the
dry run prints and writes into its report.

Distances are 3-D where a check is about an aircraft (any airframe but a rover):
``distance_m`` and ``separation_m`` when either vehicle of a pair is one, ``reached``
and ``ends_at`` when the agent is one (a point written without a height is on the
ground). Between rovers, and from a rover to a point, they are ground distances: a
rover's altitude is the ground's, and its GPS height noise says nothing.

A ``state`` or ``sequence`` check that fails says why the state was not reached when
the recording knows (:func:`why_not_entered`): the behaviour never started and what
its launch still waited for, the autopilot disarmed the vehicle, a failsafe stopped
the behaviour, a fault killed the mission computer.
"""

from __future__ import annotations

import itertools
import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Any, Final, NamedTuple

from clark_engine.behaviors import Behavior, behaviors
from clark_engine.expectations.recording import Recording
from clark_engine.mission.geo import Origin, parse_point
from clark_engine.runtime.config import AgentConfig, StateSpec


class Figure(NamedTuple):
    """One number a check observed, for comparing two runs of a mission.

    ``kind`` says how the number is compared (the mission's ``sim.sitl_tolerance``):
    ``time_s`` (a moment of the run), ``distance_m``, ``altitude_m``, ``count`` or
    ``error_us`` (a pulse width's error). ``agent``: whose figure a moment is (the leg it
    falls in is that agent's), or None.
    """

    name: str
    value: float
    kind: str
    agent: str | None = None


@dataclass(frozen=True, slots=True)
class CheckResult:
    """One check's outcome."""

    name: str
    expected: str
    observed: str
    passed: bool
    evaluated: bool = True
    """False when the run ended before the check's ``by_s`` and it had not yet held: it
    was not judged (``passed`` is then False too; it did not pass)."""
    figures: tuple[Figure, ...] = ()
    """The numbers behind ``observed`` (closest approach, time reached, photos...), for
    comparing this run with another of the same mission (:mod:`clark_engine.dryrun.timeline`)."""

    @property
    def verdict(self) -> str:
        """``pass``, ``FAIL`` or ``not evaluated``, as the checks table shows it."""
        if not self.evaluated:
            return "not evaluated"
        return "pass" if self.passed else "FAIL"


def _aircraft(run: Run, name: str) -> bool:
    """True when ``name`` is a vehicle that flies (distances to it are 3-D)."""
    config = run.configs.get(name)
    return config is not None and config.is_aircraft


def _gap_m(a: tuple[float, float, float], b: tuple[float, float, float], three_d: bool) -> float:
    """Distance between two local points: 3-D, or on the ground (north and east only)."""
    if three_d:
        return math.dist(a, b)
    return math.hypot(a[0] - b[0], a[1] - b[1])


def _label(check: Mapping[str, Any], kind: str, index: int) -> str:
    return str(check.get("name") or f"check {index + 1}: {kind}")


@dataclass(frozen=True, slots=True)
class Run:
    """What every check is evaluated against: the recording and the mission's agents."""

    rec: Recording
    configs: Mapping[str, AgentConfig]
    origin: Origin


def evaluate(
    checks: Sequence[Mapping[str, Any]],
    recording: Recording,
    configs: Mapping[str, AgentConfig],
    origin: Origin,
    planned_end_s: float | None = None,
) -> list[CheckResult]:
    """Evaluate every check, in the order the mission lists them.

    Args:
        checks: The mission's checks.
        recording: The run.
        configs: Every agent's compiled config.
        origin: The mission's origin.
        planned_end_s: When the mission's run was meant to end (its ``sim.duration_s``):
            a check without ``by_s`` is due then. A run cut short of it (``--until``,
            Ctrl-C) leaves such a check "not evaluated" where the rest of the run could
            still change its verdict. None: the recording's end.
    """
    run = Run(recording, configs, origin)
    end_s = recording.end_s
    planned_s = end_s if planned_end_s is None else max(planned_end_s, end_s)
    results = []
    for index, check in enumerate(checks):
        kind = next(k for k in check if k not in ("name", "by_s"))
        given_by_s = check.get("by_s")
        by_s = float(given_by_s) if given_by_s is not None else planned_s
        body = check[kind]
        label = _label(check, kind, index)
        evaluator = _EVALUATORS[kind]
        result = evaluator(label, body, min(by_s, end_s) if given_by_s is None else by_s, run)
        early = by_s > end_s + 1e-9
        at_by_s = (kind == "distance_m" and isinstance(body, Mapping) and "min" in body) or (
            kind == "ends_at"
        )
        until_by_s = result.passed and (
            kind in _UNTIL_BY_S_KINDS or (kind == "photos" and "max" in body)
        )
        pending = not result.passed and (
            kind in _BY_S_KINDS or (kind == "signal" and result.observed == _NOT_ENTERED)
        )
        if early and (at_by_s or until_by_s or pending):
            # It may still hold before by_s (or, for a distance or position at by_s,
            # not hold then; for a bound held so far, break it before by_s): the run
            # ended too early to say.
            due = (
                f"before by_s {by_s:g} s"
                if given_by_s is not None
                else f"before its planned end at {by_s:g} s"
            )
            result = CheckResult(
                label,
                result.expected,
                f"not evaluated: the run ended at {end_s:g} s, {due} (so far: {result.observed})",
                passed=False,
                evaluated=False,
                figures=result.figures,
            )
        results.append(result)
    return results


def _distance(label: str, body: Mapping[str, Any], by_s: float, run: Run) -> CheckResult:
    """max: the two come within max of each other by by_s; min: they are min apart at by_s."""
    a, b = (str(n) for n in body["between"])
    ta, tb = run.rec.tracks.get(a), run.rec.tracks.get(b)
    three_d = _aircraft(run, a) or _aircraft(run, b)
    parts = []
    if "max" in body:
        parts.append(f"within {float(body['max']):g} m by {by_s:g} s")
    if "min" in body:
        parts.append(f"at least {float(body['min']):g} m apart at {by_s:g} s")
    expected = f"{a} and {b} " + " and ".join(parts) + (" (3-D)" if three_d else "")
    if ta is None or tb is None:
        return CheckResult(label, expected, "no position recorded", False)
    passed = True
    observed = []
    figures: list[Figure] = []
    if "max" in body:
        closest, when = math.inf, 0.0
        # Every sample, read back from disk (the tracks' lists are decimated for plots).
        for (t, na, ea, ua), (_, nb, eb, ub) in zip(ta.samples(), tb.samples(), strict=False):
            if t > by_s + 1e-9:
                break
            d = _gap_m((na, ea, ua), (nb, eb, ub), three_d)
            if d < closest:
                closest, when = d, t
        passed = passed and closest <= float(body["max"])
        observed.append(f"closest {closest:.1f} m at {when:.1f} s")
        figures.append(Figure("closest", closest, "distance_m"))
    if "min" in body:
        pa, pb = ta.at(by_s), tb.at(by_s)
        if pa is None or pb is None:
            return CheckResult(label, expected, "no position recorded", False)
        d = _gap_m(pa, pb, three_d)
        passed = passed and d >= float(body["min"])
        observed.append(f"{d:.1f} m at {by_s:g} s")
        figures.append(Figure(f"apart at {by_s:g} s", d, "distance_m"))
    return CheckResult(label, expected, "; ".join(observed), passed, figures=tuple(figures))


def _reached(label: str, body: Mapping[str, Any], by_s: float, run: Run) -> CheckResult:
    agent = str(body["agent"])
    target = parse_point(body["to"], run.origin)
    tolerance = float(body.get("tolerance_m", 5.0))
    point = (target.north_m, target.east_m, target.up_m)
    three_d = _aircraft(run, agent)
    expected = f"{agent} within {tolerance:g} m of {_point_text(point, three_d)} by {by_s:g} s"
    track = run.rec.tracks.get(agent)
    if track is None:
        return CheckResult(label, expected, "no position recorded", False)
    best = math.inf
    when: float | None = None
    for t, north, east, up in track.samples():
        if t > by_s + 1e-9:
            break
        d = _gap_m((north, east, up), point, three_d)
        if d < best:
            best = d
        if d <= tolerance and when is None:
            when = t
    if when is not None:
        reached = (Figure("reached at", when, "time_s", agent),)
        return CheckResult(label, expected, f"reached at {when:.1f} s", True, figures=reached)
    closest = (Figure("closest", best, "distance_m"),)
    return CheckResult(label, expected, f"closest {best:.1f} m", False, figures=closest)


def _separation(label: str, body: Mapping[str, Any], _by_s: float, run: Run) -> CheckResult:
    minimum = float(body["min"])
    names = [str(n) for n in body.get("agents", [])] or [
        n for n, c in run.configs.items() if c.is_vehicle and n in run.rec.tracks
    ]
    expected = f"vehicles at least {minimum:g} m apart at all times"
    closest = math.inf
    pair = ("", "")
    when = 0.0
    tracks = [(n, run.rec.tracks[n]) for n in names if n in run.rec.tracks]
    pairs = [(i, j) for i in range(len(tracks)) for j in range(i + 1, len(tracks))]
    # 3-D when either of the two flies; on the ground between two rovers.
    flat = [not (_aircraft(run, tracks[i][0]) or _aircraft(run, tracks[j][0])) for i, j in pairs]
    # One pass over every track's samples (read back from disk), each pair's closest kept.
    best = [(math.inf, 0.0)] * len(pairs)
    for row in itertools.zip_longest(*(track.samples() for _, track in tracks)):
        for k, (i, j) in enumerate(pairs):
            a, b = row[i], row[j]
            if a is None or b is None:
                continue
            d = math.hypot(a[1] - b[1], a[2] - b[2]) if flat[k] else math.dist(a[1:], b[1:])
            if d < best[k][0]:
                best[k] = (d, a[0])
    for (i, j), (d, t) in zip(pairs, best, strict=True):
        if d < closest:
            closest, pair, when = d, (tracks[i][0], tracks[j][0]), t
    if math.isinf(closest):
        return CheckResult(label, expected, "fewer than two vehicles", True)
    observed = f"closest {closest:.1f} m ({pair[0]}-{pair[1]} at {when:.1f} s)"
    figures = (Figure("closest", closest, "distance_m"),)
    return CheckResult(label, expected, observed, closest >= minimum, figures=figures)


def _state(label: str, body: Mapping[str, Any], by_s: float, run: Run) -> CheckResult:
    agent, path = str(body["agent"]), str(body["reached"])
    expected = f"{agent} in {path} by {by_s:g} s"
    when = run.rec.entered_by(agent, path, by_s)
    if when is None:
        last = [e for e in run.rec.states.get(agent, []) if e.time_s <= by_s + 1e-9]
        where = ", ".join(last[-1].active) if last else "no state"
        late_s = run.rec.entered_by(agent, path, math.inf)
        if late_s is not None:
            observed = f"reached late, at {late_s:.1f} s (by {by_s:g} s: {where})"
            late = (Figure("entered at", late_s, "time_s", agent),)
            return CheckResult(label, expected, observed, False, figures=late)
        why = why_not_entered(run.rec, agent, by_s)
        observed = f"not reached (last: {where})" + (f": {why}" if why else "")
        return CheckResult(label, expected, observed, False)
    entered = (Figure("entered at", when, "time_s", agent),)
    return CheckResult(label, expected, f"entered at {when:.1f} s", True, figures=entered)


def _sequence(label: str, body: Mapping[str, Any], by_s: float, run: Run) -> CheckResult:
    agent = str(body["agent"])
    paths = [str(p) for p in body["states"]]
    expected = f"{agent} enters {' then '.join(paths)}, the last by {by_s:g} s"
    seen: list[str] = []
    figures: list[Figure] = []
    for entry in run.rec.states.get(agent, []):
        if entry.time_s > by_s + 1e-9:
            break
        # One change may enter several of them at once (a parent and its first child).
        while len(seen) < len(paths) and any(
            p == paths[len(seen)] or p.startswith(paths[len(seen)] + ".") for p in entry.entered
        ):
            figures.append(Figure(f"{paths[len(seen)]} at", entry.time_s, "time_s", agent))
            seen.append(f"{paths[len(seen)]} at {entry.time_s:.1f} s")
    if len(seen) == len(paths):
        return CheckResult(label, expected, ", ".join(seen), True, figures=tuple(figures))
    missing = paths[len(seen)]
    observed = ", ".join(seen) + ("; then " if seen else "") + f"never {missing}"
    why = why_not_entered(run.rec, agent, by_s)
    observed += f": {why}" if why else ""
    return CheckResult(label, expected, observed, False, figures=tuple(figures))


def _photos(label: str, body: Mapping[str, Any], _by_s: float, run: Run) -> CheckResult:
    agent = str(body["agent"])
    count = len(run.rec.photos.get(agent, []))
    low, high = body.get("min"), body.get("max")
    parts = []
    if low is not None:
        parts.append(f">= {low}")
    if high is not None:
        parts.append(f"<= {high}")
    expected = f"{agent} photos " + (" and ".join(parts) or "any number")
    passed = (low is None or count >= int(low)) and (high is None or count <= int(high))
    figures = (Figure("photos", count, "count"),)
    return CheckResult(label, expected, f"{count} photos", passed, figures=figures)


def _no_failsafe(label: str, body: Mapping[str, Any], _by_s: float, run: Run) -> CheckResult:
    names = [str(n) for n in body.get("agents", [])] or list(run.configs)
    events = [(t, n, what) for n in names for t, what in run.rec.safety.get(n, [])]
    expected = "no failsafe on " + (", ".join(body.get("agents", [])) or "any agent")
    if not events:
        return CheckResult(label, expected, "none", True)
    t, name, what = min(events)
    return CheckResult(label, expected, f"{name} {what} at {t:.1f} s", False)


def _find_state(spec: StateSpec | None, path: str) -> StateSpec | None:
    if spec is None:
        return None
    for state in spec.walk():
        if state.path == path:
            return state
    return None


def _behavior(state: StateSpec) -> Behavior | None:
    return behaviors().get(state.primitive) if state.primitive is not None else None


def _limits(params: Mapping[str, Any]) -> tuple[float, float, float]:
    channel = params["channel"]
    return channel["pwm_trim_us"], channel["pwm_min_us"], channel["pwm_max_us"]


def expected_signal(state: StateSpec, loop_hz: float) -> list[int]:
    """The pulse widths a doublet or sweep state must command, one per tick.

    Computed from the behaviour's declaration (its ``signal``, written apart from its
    runtime class), so the check compares the two; empty for a behaviour without one.
    """
    behavior = _behavior(state)
    if behavior is None or behavior.signal is None:
        return []
    return behavior.signal(behavior.parameters.from_config(state.params), loop_hz)


#: A sweep's commanded output must keep at least this share of the intended waveform's
#: RMS swing in every second; sampled near the Nyquist limit it loses it (flat at 2 samples
#: per period), however exactly each sample matches the waveform at its tick.
MIN_SWEEP_FIDELITY = 0.5
#: Points per tick at which the intended (continuous) waveform is evaluated.
_SUBSAMPLES = 8


def sweep_fidelity(state: StateSpec, loop_hz: float, got: Sequence[int]) -> tuple[float, float]:
    """The worst share of the intended sweep's swing that the commanded output carries.

    The sweep is cut into one-second windows; in each, the RMS of the commanded pulse
    widths about trim is compared with the RMS of the intended continuous waveform
    (clamped to the channel's limits) over the same time. Windows where the waveform
    itself is under 1 us (a fade) are skipped.

    Returns:
        (share, start of the worst window in seconds); (1.0, 0.0) when every window holds.
    """
    params = state.params
    behavior = _behavior(state)
    if behavior is None or behavior.waveform is None:
        return 1.0, 0.0
    waveform = behavior.waveform
    typed = behavior.parameters.from_config(params)
    trim, low, high = _limits(params)
    duration = float(params["duration_s"])
    ticks = [k for k in range(len(got)) if k / loop_hz < duration - 1e-9]
    window = max(1, round(loop_hz))
    worst, worst_at = 1.0, 0.0
    for first in range(0, len(ticks), window):
        chunk = ticks[first : first + window]
        commanded = math.sqrt(sum((got[k] - trim) ** 2 for k in chunk) / len(chunk))
        points = [(k + j / _SUBSAMPLES) / loop_hz for k in chunk for j in range(_SUBSAMPLES)]
        intended = math.sqrt(
            sum((min(max(trim + waveform(typed, t), low), high) - trim) ** 2 for t in points)
            / len(points)
        )
        if intended < 1.0:
            continue
        share = commanded / intended
        if share < worst:
            worst, worst_at = share, chunk[0] / loop_hz
    return worst, worst_at


def _signal(label: str, body: Mapping[str, Any], _by_s: float, run: Run) -> CheckResult:
    agent, path = str(body["agent"]), str(body["state"])
    config = run.configs[agent]
    state = _find_state(config.machine, path)
    expected_text = f"{agent} {path}: the autopilot receives the primitive's signal"
    behavior = _behavior(state) if state is not None else None
    driven = behavior.driven_channel(state.params) if behavior and state else None
    if state is None or behavior is None or behavior.signal is None or driven is None:
        return CheckResult(label, expected_text, "no doublet or sweep state there", False)
    key = driven.label
    samples = run.rec.signals.get((agent, key), [])
    intervals = run.rec.intervals(agent, path)
    if not intervals:
        return CheckResult(label, expected_text, _NOT_ENTERED, False)
    start, end = intervals[0]
    received = [pwm for t, pwm in samples if start - 1e-9 <= t <= end + 1e-9]
    want = expected_signal(state, config.loop_hz)
    # A state entered by an event is first updated in its entry tick, one entered on
    # the previous state's done a tick later: align on the first tick of the signal.
    worst = math.inf
    aligned: list[int] = []
    for offset in (0, 1):
        got = received[offset : offset + len(want)]
        if len(got) == len(want):
            error_us = max(abs(a - b) for a, b in zip(got, want, strict=True))
            if error_us < worst:
                worst, aligned = error_us, got
    if math.isinf(worst):
        return CheckResult(
            label,
            expected_text,
            f"{len(received)} of {len(want)} samples (state left early)",
            False,
        )
    figures = (
        Figure("samples", len(want), "count"),
        Figure("largest error", worst, "error_us"),
    )
    shape = "sweep" if behavior.waveform is not None else str(state.primitive)
    observed = f"{len(want)} samples, largest error {worst:g} us ({shape} on {key})"
    if behavior.waveform is not None:
        # Each sample can match the waveform at its tick and still not carry it (a 5 Hz
        # sine at 10 Hz is sampled at its zero crossings): compare with the waveform.
        share, at_s = sweep_fidelity(state, config.loop_hz, aligned)
        if share < MIN_SWEEP_FIDELITY:
            observed += (
                f", but from {at_s:g} s into the sweep the output keeps only {share:.0%} of "
                f"the intended waveform's swing (sampled at loop_hz {config.loop_hz:g}, "
                "too slow for its frequency)"
            )
            return CheckResult(
                label, expected_text + " (within 1 us)", observed, False, figures=figures
            )
    return CheckResult(
        label, expected_text + " (within 1 us)", observed, worst <= 1, figures=figures
    )


def _failsafe(label: str, body: Mapping[str, Any], by_s: float, run: Run) -> CheckResult:
    agent, event = str(body["agent"]), str(body.get("event", "any"))
    expected = f"{agent} {event if event != 'any' else 'a safety reaction'} by {by_s:g} s"
    seen = [(t, what) for t, what in run.rec.safety.get(agent, []) if t <= by_s + 1e-9]
    matching = [
        (t, what) for t, what in seen if event == "any" or what in (event, f"failsafe {event}")
    ]
    if matching:
        t, what = matching[0]
        figures = (Figure(f"{what} at", t, "time_s", agent),)
        return CheckResult(label, expected, f"{what} at {t:.1f} s", True, figures=figures)
    observed = ", ".join(f"{w} at {t:.1f} s" for t, w in seen) or "none"
    return CheckResult(label, expected, observed, False)


def _point_text(point: tuple[float, float, float], three_d: bool) -> str:
    """A local point as a check's expectation shows it: with its height for an aircraft."""
    if three_d:
        return f"({point[0]:g}, {point[1]:g}, {point[2]:g})"
    return f"({point[0]:g}, {point[1]:g})"


def _altitude(label: str, body: Mapping[str, Any], by_s: float, run: Run) -> CheckResult:
    """The agent's altitude above the origin stays within [min, max] at every sample to by_s."""
    agent = str(body["agent"])
    low, high = body.get("min"), body.get("max")
    bounds = []
    if low is not None:
        bounds.append(f">= {float(low):g} m")
    if high is not None:
        bounds.append(f"<= {float(high):g} m")
    expected = f"{agent} altitude above origin {' and '.join(bounds)} until {by_s:g} s"
    track = run.rec.tracks.get(agent)
    if track is None:
        return CheckResult(label, expected, "no position recorded", False)
    lowest: tuple[float, float] | None = None  # (altitude, time)
    highest: tuple[float, float] | None = None
    first_out: tuple[float, float] | None = None
    for t, _, _, up in track.samples():
        if t > by_s + 1e-9:
            break
        if lowest is None or up < lowest[0]:
            lowest = (up, t)
        if highest is None or up > highest[0]:
            highest = (up, t)
        out = (low is not None and up < float(low)) or (high is not None and up > float(high))
        if out and first_out is None:
            first_out = (up, t)
    if lowest is None or highest is None:
        return CheckResult(label, expected, "no position recorded", False)
    observed = (
        f"lowest {lowest[0]:.1f} m at {lowest[1]:.1f} s, highest {highest[0]:.1f} m at "
        f"{highest[1]:.1f} s"
    )
    if first_out is not None:
        observed += f"; first outside at {first_out[1]:.1f} s ({first_out[0]:.1f} m)"
    figures = (
        Figure("lowest", lowest[0], "altitude_m"),
        Figure("highest", highest[0], "altitude_m"),
    )
    return CheckResult(label, expected, observed, first_out is None, figures=figures)


def _ends_at(label: str, body: Mapping[str, Any], by_s: float, run: Run) -> CheckResult:
    """The agent's position at by_s (the run's end by default) is within_m of the point."""
    agent = str(body["agent"])
    target = parse_point(body["to"], run.origin)
    within = float(body.get("within_m", 5.0))
    point = (target.north_m, target.east_m, target.up_m)
    three_d = _aircraft(run, agent)
    expected = f"{agent} ends within {within:g} m of {_point_text(point, three_d)} at {by_s:g} s"
    track = run.rec.tracks.get(agent)
    here = track.at(by_s) if track is not None else None
    if here is None:
        return CheckResult(label, expected, "no position recorded", False)
    d = _gap_m(here, point, three_d)
    place = ", ".join(f"{v:.1f}" for v in (here if three_d else here[:2]))
    observed = f"{d:.1f} m away, at ({place})"
    figures = (Figure("away", d, "distance_m"),)
    return CheckResult(label, expected, observed, d <= within + 1e-9, figures=figures)


def why_not_entered(rec: Recording, agent: str, by_s: float) -> str:
    """Why an agent's behaviour did not get somewhere by ``by_s``, from what was recorded.

    Each thing that held it back, in words: its mission computer killed by a fault, a
    failsafe or a lost autopilot that stopped the behaviour, a behaviour that never
    started and what its launch still waited for, the autopilot disarming the vehicle
    (the engine never disarms: a disarm is the autopilot's, as ArduCopter's after 10 s
    armed on the ground). Empty when the recording says nothing of the kind.
    """
    reasons = []
    killed = rec.killed.get(agent)
    if killed is not None and killed <= by_s + 1e-9:
        reasons.append(f"its mission computer was killed at {killed:.1f} s (fault)")
    for t, what in rec.safety.get(agent, []):
        if t > by_s + 1e-9:
            continue
        if what.startswith("failsafe"):
            reasons.append(f"the behaviour was stopped by a failsafe ({what[9:]}) at {t:.1f} s")
        elif what == "autopilot_lost":
            reasons.append(f"its autopilot was lost at {t:.1f} s")
    states = rec.states.get(agent, [])
    started_s = states[0].time_s if states else None
    if started_s is None or started_s > by_s + 1e-9:
        waiting = rec.waiting.get(agent)
        reasons.append(
            "the behaviour never started"
            + (f", waiting for {', '.join(waiting)}" if waiting else "")
        )
    reasons.extend(_disarms(rec, agent, by_s, started_s))
    return "; ".join(reasons)


def _disarms(rec: Recording, agent: str, by_s: float, started_s: float | None) -> list[str]:
    """The autopilot's disarms that explain a stall, in words.

    Those before the behaviour started, and one after it started that was never
    followed by another arming by ``by_s``.
    """
    out = []
    armed_s: float | None = None
    flight = [e for e in rec.flight.get(agent, []) if e.time_s <= by_s + 1e-9]
    for index, entry in enumerate(flight):
        if entry.armed and armed_s is None:
            armed_s = entry.time_s
        elif not entry.armed and armed_s is not None:
            before_start = started_s is None or entry.time_s < started_s
            rearmed = any(e.armed for e in flight[index + 1 :])
            if before_start:
                out.append(
                    f"armed at {armed_s:.1f} s and disarmed by the autopilot at "
                    f"{entry.time_s:.1f} s, before the behaviour started"
                )
            elif not rearmed:
                out.append(f"disarmed by the autopilot at {entry.time_s:.1f} s")
            armed_s = None
    return out


_NOT_ENTERED: Final = "state never entered"
"""A signal check's finding when its state never ran: a run cut short may yet run it."""

#: Kinds whose verdict is "by by_s": a run that ends sooner cannot fail them.
_BY_S_KINDS = frozenset({"distance_m", "reached", "state", "sequence", "failsafe", "photos"})
#: Kinds that must hold at every moment until by_s: a run that ends sooner, with the
#: kind holding so far, was not judged (it could still break before by_s).
_UNTIL_BY_S_KINDS = frozenset({"altitude_m"})

_EVALUATORS = {
    "distance_m": _distance,
    "reached": _reached,
    "separation_m": _separation,
    "state": _state,
    "sequence": _sequence,
    "photos": _photos,
    "no_failsafe": _no_failsafe,
    "failsafe": _failsafe,
    "signal": _signal,
    "altitude_m": _altitude,
    "ends_at": _ends_at,
}


def checks_table(results: Sequence[CheckResult]) -> str:
    """The checks as a Markdown table."""
    lines = ["| check | expected | observed | result |", "|---|---|---|---|"]
    for r in results:
        verdict = "**FAIL**" if r.verdict == "FAIL" else r.verdict
        lines.append(f"| {r.name} | {r.expected} | {r.observed} | {verdict} |")
    return "\n".join(lines) + "\n"
