"""The safety judgement of every dry run: did any vehicle leave its envelope?

A dry run's ``checks:`` judge what a mission asks; a mission that asks nothing was
judged on nothing, and a green run did not mean a safe flight. This module judges
every run against each vehicle's compiled envelope
(:attr:`~clark_engine.runtime.config.AgentConfig.envelope`), whether or not the
mission declares a check, from the recording's true tracks: every sample, read back
from disk (:meth:`~clark_engine.expectations.recording.Track.samples`), never the plots'
decimated lists. Any breach fails the run.

Per vehicle:

- **Ceiling.** Its highest altitude above the origin over the whole run, against its
  ``ceiling_m`` (aircraft only: a rover is on the ground).
- **Floor.** Its lowest altitude while it *flies guided*, against its ``floor_m``: an
  aircraft's sample counts when it is armed, in its autopilot's guided mode, its
  behaviour is not in a ``takeoff``, ``land`` or ``return_home`` state (the floor's
  exemptions, as the runtime's), and it has been at or above the floor since it was
  last armed (ArduPilot's FENCE_ALT_MIN likewise waits until the vehicle first climbs
  above it, so a climb through the floor after a takeoff is no breach). A floor at the
  ground (0 m, the default) is not judged: the field is flat at the origin's height.
- **Geofence.** Its smallest margin to its fence
  (:meth:`~clark_engine.mission.fence.Fence.margin_m`: negative outside), where and
  when, at every sample, armed or not (a vehicle put down outside its fence is
  outside it; ArduPilot would not even arm it there).
- **Endurance.** Its time armed, summed over the run, against its ``endurance_s``
  (not judged when the airframe declares none). An aircraft handed over in flight is
  counted from the run's start.

Per pair of vehicles: their closest approach in 3-D (who, when, where in local
metres), against the larger of their two separations
(:meth:`~clark_engine.runtime.config.EnvelopeSpec.separation_from_m`), over the samples
where at least one of the two is armed: two vehicles parked side by side before a
mission are not a near miss (``clark validate`` judges start points).

The recording's arming and modes are the autopilot's own
(:attr:`~clark_engine.expectations.recording.Recording.flight`), so a vehicle whose mission
computer died is still judged. The judgement runs once, at the end of the run: one
pass over every track's samples together.
"""

from __future__ import annotations

import itertools
import math
from collections.abc import Iterator, Mapping, Sequence
from dataclasses import dataclass, field
from typing import Final

from clark_engine.expectations.evaluate import CheckResult
from clark_engine.expectations.recording import FlightEntry, Recording, StateEntry
from clark_engine.runtime.config import AgentConfig, EnvelopeSpec, StateSpec

_EPSILON_M: Final = 1e-6
"""Float noise: a figure this close to its limit is on it, not beyond it."""

Position = tuple[float, float, float]
"""A local position: (north_m, east_m, up_m)."""


@dataclass(frozen=True, slots=True)
class Extreme:
    """A figure at the moment and place it was reached.

    Attributes:
        value: The figure (an altitude, a margin), in metres.
        time_s: When, in simulated seconds.
        where: Where the vehicle was: north, east, up in metres from the origin.
    """

    value: float
    time_s: float
    where: Position


@dataclass(frozen=True, slots=True)
class VehicleSafety:
    """One vehicle judged against its envelope.

    Attributes:
        name: The vehicle.
        aircraft: True for anything but a rover (ceiling and floor apply).
        envelope: Its compiled envelope; None for a config that has none (not judged).
        highest: Its highest altitude above the origin; None without a sample.
        lowest_guided: Its lowest altitude in guided flight (see the module's rule);
            None when it never flew guided above its floor, or the floor is at the ground.
        fence: Its smallest margin to its geofence (negative: outside); None without a
            sample.
        armed_s: Its time armed over the run.
        endurance_over_s: When its time armed passed its endurance; None if it did not.
    """

    name: str
    aircraft: bool
    envelope: EnvelopeSpec | None
    highest: Extreme | None
    lowest_guided: Extreme | None
    fence: Extreme | None
    armed_s: float
    endurance_over_s: float | None

    @property
    def breaches(self) -> list[str]:
        """Each way it left its envelope, in words (empty when it stayed inside)."""
        env = self.envelope
        if env is None:
            return []
        out = []
        high = self.highest
        if self.aircraft and high is not None and high.value > env.ceiling_m + _EPSILON_M:
            out.append(
                f"{self.name} climbed to {high.value:.1f} m above the origin at "
                f"{high.time_s:.1f} s at {where(high.where)}, above its {env.ceiling_m:g} m "
                "ceiling"
            )
        low = self.lowest_guided
        if low is not None and low.value < env.floor_m - _EPSILON_M:
            out.append(
                f"{self.name} flew guided at {low.value:.1f} m above the origin at "
                f"{low.time_s:.1f} s at {where(low.where)}, below its {env.floor_m:g} m floor"
            )
        fence = self.fence
        if fence is not None and fence.value < -_EPSILON_M:
            out.append(
                f"{self.name} was {-fence.value:.1f} m outside its geofence at "
                f"{fence.time_s:.1f} s at {where(fence.where)}"
            )
        if self.endurance_over_s is not None and env.endurance_s is not None:
            out.append(
                f"{self.name} was armed for {self.armed_s:.1f} s, beyond its "
                f"{env.endurance_s:g} s endurance from {self.endurance_over_s:.1f} s on"
            )
        return out

    @property
    def passed(self) -> bool:
        """True when it stayed inside its envelope."""
        return not self.breaches


@dataclass(frozen=True, slots=True)
class PairSafety:
    """Two vehicles' closest approach, against the separation they keep.

    Attributes:
        a: One vehicle (the first in the mission's order).
        b: The other.
        limit_m: The separation they keep: the larger of their envelopes' figures.
        distance_m: Their smallest 3-D distance while either was armed; None when
            neither ever was (or no sample was shared).
        time_s: When.
        where_a: Where ``a`` was then.
        where_b: Where ``b`` was then.
    """

    a: str
    b: str
    limit_m: float
    distance_m: float | None = None
    time_s: float = 0.0
    where_a: Position = (0.0, 0.0, 0.0)
    where_b: Position = (0.0, 0.0, 0.0)

    @property
    def passed(self) -> bool:
        """True when they never came closer than their separation."""
        return self.distance_m is None or self.distance_m >= self.limit_m - _EPSILON_M

    @property
    def breach(self) -> str | None:
        """The near miss in words: who, when, where; None when there was none."""
        if self.passed or self.distance_m is None:
            return None
        return (
            f"{self.a} and {self.b} came within {self.distance_m:.1f} m of each other at "
            f"{self.time_s:.1f} s ({self.a} at {where(self.where_a)}, {self.b} at "
            f"{where(self.where_b)}), under their {self.limit_m:g} m separation"
        )


@dataclass(frozen=True, slots=True)
class SafetyJudgement:
    """Every vehicle and every pair of a run, judged."""

    vehicles: tuple[VehicleSafety, ...]
    pairs: tuple[PairSafety, ...]

    @property
    def breaches(self) -> list[str]:
        """Every breach in words, vehicles first, then pairs."""
        out = [b for v in self.vehicles for b in v.breaches]
        out += [p.breach for p in self.pairs if p.breach is not None]
        return out

    @property
    def passed(self) -> bool:
        """True when no vehicle left its envelope and no pair came too close."""
        return not self.breaches

    @property
    def closest_pair(self) -> PairSafety | None:
        """The pair that came closest (the track plot marks it); None without one."""
        judged = [p for p in self.pairs if p.distance_m is not None]
        return min(judged, key=lambda p: p.distance_m or 0.0, default=None)

    def table(self) -> str:
        """The judgement as Markdown: one table of vehicles, one of pairs."""
        lines = [
            "| vehicle | highest (ceiling) | lowest in guided flight (floor) | geofence margin "
            "| armed (endurance) | result |",
            "|---|---|---|---|---|---|",
        ]
        for v in self.vehicles:
            lines.append(
                f"| {v.name} | {_highest_text(v)} | {_lowest_text(v)} | {_fence_text(v)} "
                f"| {_armed_text(v)} | {_verdict(v.passed)} |"
            )
        if self.pairs:
            lines += [
                "",
                "| pair | closest (3-D) | when | where (north, east, up m) | separation | result |",
                "|---|---|---|---|---|---|",
            ]
            for p in self.pairs:
                if p.distance_m is None:
                    closest, when, place = "- (neither armed)", "-", "-"
                else:
                    closest, when = f"{p.distance_m:.1f} m", f"{p.time_s:.1f} s"
                    place = f"{p.a} {where(p.where_a)}, {p.b} {where(p.where_b)}"
                lines.append(
                    f"| {p.a} - {p.b} | {closest} | {when} | {place} | {p.limit_m:g} m "
                    f"| {_verdict(p.passed)} |"
                )
        return "\n".join(lines) + "\n"

    def results(self) -> list[CheckResult]:
        """The judgement as check rows (for a view that shows check verdicts)."""
        out = []
        for v in self.vehicles:
            observed = "; ".join(v.breaches) or (
                f"highest {_highest_text(v)}, fence margin {_fence_text(v)}, armed {_armed_text(v)}"
            )
            out.append(CheckResult(f"safety: {v.name}", "inside its envelope", observed, v.passed))
        for p in self.pairs:
            observed = p.breach or (
                "neither armed"
                if p.distance_m is None
                else f"closest {p.distance_m:.1f} m at {p.time_s:.1f} s"
            )
            out.append(
                CheckResult(
                    f"safety: {p.a} - {p.b}", f"at least {p.limit_m:g} m apart", observed, p.passed
                )
            )
        return out


def metres(value: float) -> str:
    """A distance to a tenth of a metre, never ``-0.0``."""
    text = f"{value:.1f}"
    return "0.0" if text == "-0.0" else text


def where(position: Position) -> str:
    """A local position as the report writes it: ``(12.0, -3.5, 10.0)`` (north, east, up m)."""
    return "(" + ", ".join(metres(v) for v in position) + ")"


def count_breaches(count: int) -> str:
    """``1 breach``, ``2 breaches``."""
    return f"{count} breach" if count == 1 else f"{count} breaches"


def _verdict(passed: bool) -> str:
    return "pass" if passed else "**FAIL**"


def _highest_text(v: VehicleSafety) -> str:
    if not v.aircraft:
        return "- (rover)"
    if v.highest is None or v.envelope is None:
        return "- (no sample)" if v.highest is None else f"{v.highest.value:.1f} m"
    return (
        f"{v.highest.value:.1f} m at {v.highest.time_s:.1f} s (ceiling {v.envelope.ceiling_m:g} m)"
    )


def _lowest_text(v: VehicleSafety) -> str:
    env = v.envelope
    if not v.aircraft:
        return "- (rover)"
    if env is None or env.floor_m <= 0:
        return "- (floor at the ground)"
    if v.lowest_guided is None:
        return f"- (never guided above its floor; floor {env.floor_m:g} m)"
    low = v.lowest_guided
    return f"{low.value:.1f} m at {low.time_s:.1f} s (floor {env.floor_m:g} m)"


def _fence_text(v: VehicleSafety) -> str:
    fence = v.fence
    if fence is None:
        return "- (no sample)"
    if math.isinf(fence.value):
        return "- (no zone)"
    north, east, _ = fence.where
    return f"{metres(fence.value)} m at {fence.time_s:.1f} s ({metres(north)}, {metres(east)})"


def _armed_text(v: VehicleSafety) -> str:
    env = v.envelope
    endurance = env.endurance_s if env is not None else None
    limit = f"endurance {endurance:g} s" if endurance is not None else "no endurance declared"
    return f"{v.armed_s:.1f} s ({limit})"


# ------------------------------------------------------------------ judging


def _exempt_paths(machine: StateSpec | None) -> frozenset[str]:
    """Paths of the states whose primitive is exempt from the floor."""
    if machine is None:
        return frozenset()
    return frozenset(s.path for s in machine.walk() if s.traits.floor_exempt)


def _is_exempt(entry: StateEntry, exempt: frozenset[str]) -> bool:
    """True when an active state, or one above it, is a floor-exempt primitive's."""
    for path in entry.active:
        parts = path.split(".") if path else []
        if any(".".join(parts[: i + 1]) in exempt for i in range(len(parts))) or path in exempt:
            return True
    return False


@dataclass(slots=True)
class _Watch:
    """One vehicle's figures, built sample by sample in time order."""

    name: str
    config: AgentConfig
    flight: list[FlightEntry]
    states: list[StateEntry]
    exempt: frozenset[str]
    guided_mode: str | None
    floor_m: float
    fence_check: bool
    armed: bool = False
    mode: str = ""
    above_floor: bool = False
    in_exempt: bool = False
    highest: Extreme | None = None
    lowest: Extreme | None = None
    fence: Extreme | None = None
    _flight_i: int = 0
    _state_i: int = 0
    _fence_at: tuple[float, float, float] | None = field(default=None)  # (n, e, margin)

    def see(self, t_s: float, north: float, east: float, up: float) -> None:
        """Take one sample (samples come in time order)."""
        flight = self.flight
        while self._flight_i < len(flight) and flight[self._flight_i].time_s <= t_s + 1e-9:
            entry = flight[self._flight_i]
            if entry.armed and not self.armed:
                self.above_floor = False  # the floor waits for a climb above it, each flight
            self.armed, self.mode = entry.armed, entry.mode
            self._flight_i += 1
        states = self.states
        moved = False
        while self._state_i < len(states) and states[self._state_i].time_s <= t_s + 1e-9:
            self._state_i += 1
            moved = True
        if moved:
            self.in_exempt = _is_exempt(states[self._state_i - 1], self.exempt)
        if self.highest is None or up > self.highest.value:
            self.highest = Extreme(up, t_s, (north, east, up))
        if self.floor_m > 0 and self.armed:
            if up >= self.floor_m:
                self.above_floor = True
            if (
                self.above_floor
                and self.mode == self.guided_mode
                and not self.in_exempt
                and (self.lowest is None or up < self.lowest.value)
            ):
                self.lowest = Extreme(up, t_s, (north, east, up))
        if self.fence_check:
            self._see_fence(t_s, north, east, up)

    def _see_fence(self, t_s: float, north: float, east: float, up: float) -> None:
        """The fence margin, computed only where it could be a new smallest.

        A margin is a distance to the fence's edges, so it changes by at most the
        distance moved: while the vehicle stays closer to the last point computed
        than that point's margin exceeds the smallest so far, it cannot be smaller
        (and a margin equal to the smallest is not a new one: the first is kept, so a
        vehicle standing still at its smallest margin is not measured again).
        """
        best = self.fence
        last = self._fence_at
        if best is not None and last is not None:
            moved = math.hypot(north - last[0], east - last[1])
            if last[2] - moved >= best.value:
                return
        envelope = self.config.envelope
        assert envelope is not None
        margin = envelope.fence.margin_m(north, east)
        self._fence_at = (north, east, margin)
        if best is None or margin < best.value:
            self.fence = Extreme(margin, t_s, (north, east, up))


def _endurance_over_s(
    intervals: Sequence[tuple[float, float]], endurance_s: float | None
) -> tuple[float, float | None]:
    """(time armed, when it passed ``endurance_s`` or None)."""
    total = 0.0
    over: float | None = None
    for start, end in intervals:
        length = max(0.0, end - start)
        if over is None and endurance_s is not None and total + length > endurance_s + 1e-9:
            over = start + (endurance_s - total)
        total += length
    return total, over


def _pair_limit(a: AgentConfig, b: AgentConfig) -> float:
    """The separation a pair keeps: the larger of what each one's envelope says."""
    limits = [
        env.separation_from_m(other)
        for env, other in ((a.envelope, b.agent), (b.envelope, a.agent))
        if env is not None
    ]
    return max(limits, default=0.0)


def _rows(
    recording: Recording, names: Sequence[str]
) -> Iterator[tuple[tuple[float, float, float, float] | None, ...]]:
    """Every track's samples side by side (None past a shorter track's end)."""
    return itertools.zip_longest(*(recording.tracks[n].samples() for n in names))


def judge(recording: Recording, configs: Mapping[str, AgentConfig]) -> SafetyJudgement:
    """Judge every vehicle with a track, and every pair of them, against their envelopes.

    Args:
        recording: The run's recording (true tracks, arming and modes, states).
        configs: Every agent's compiled config (its envelope, its behaviour's states).
    """
    names = [n for n in recording.tracks if n in configs and configs[n].is_vehicle]
    watches = []
    for name in names:
        config = configs[name]
        envelope = config.envelope
        watches.append(
            _Watch(
                name,
                config,
                recording.flight.get(name, []),
                recording.states.get(name, []),
                _exempt_paths(config.machine),
                config.guided_mode,
                envelope.floor_m if envelope is not None and config.is_aircraft else 0.0,
                envelope is not None,
            )
        )
    pair_index = [(i, j) for i in range(len(names)) for j in range(i + 1, len(names))]
    limits = [_pair_limit(configs[names[i]], configs[names[j]]) for i, j in pair_index]
    # Each pair's closest so far: distance, time, both positions (the hot loop: flat lists).
    best_m = [math.inf] * len(pair_index)
    best_s = [0.0] * len(pair_index)
    best_at: list[tuple[Position, Position] | None] = [None] * len(pair_index)
    dist = math.dist
    for row in _rows(recording, names):
        here: list[Position | None] = []
        armed: list[bool] = []
        t_s = 0.0
        for watch, sample in zip(watches, row, strict=True):
            if sample is None:
                here.append(None)
                armed.append(False)
                continue
            t_s, north, east, up = sample
            watch.see(t_s, north, east, up)
            here.append((north, east, up))
            armed.append(watch.armed)
        for k, (i, j) in enumerate(pair_index):
            if not (armed[i] or armed[j]):
                continue
            a, b = here[i], here[j]
            if a is None or b is None:
                continue
            d = dist(a, b)
            if d < best_m[k]:
                best_m[k], best_s[k], best_at[k] = d, t_s, (a, b)
    vehicles = []
    for watch in watches:
        envelope = watch.config.envelope
        armed_s, over_s = _endurance_over_s(
            recording.armed_intervals(watch.name),
            envelope.endurance_s if envelope is not None else None,
        )
        vehicles.append(
            VehicleSafety(
                watch.name,
                watch.config.is_aircraft,
                envelope,
                watch.highest,
                watch.lowest,
                watch.fence,
                armed_s,
                over_s,
            )
        )
    pairs = []
    for k, ((i, j), limit) in enumerate(zip(pair_index, limits, strict=True)):
        at = best_at[k]
        if at is None:
            pairs.append(PairSafety(names[i], names[j], limit))
        else:
            pairs.append(PairSafety(names[i], names[j], limit, best_m[k], best_s[k], *at))
    return SafetyJudgement(tuple(vehicles), tuple(pairs))
