"""The station's alarms: a breach, a near miss or a failsafe, raised once per episode.

What the station knows of every vehicle (its latest Agent Status, its heartbeat's
condition, its Vehicle Health) is judged against every vehicle's envelope, which the
station's compiled config carries (:attr:`~clark_engine.runtime.config.PeerSpec.envelope`):

- **breach**: a vehicle's reported position outside its geofence, or above its ceiling;
- **near miss**: two vehicles closer (3-D, by their reported positions) than the
  separation they must keep (the larger of the two envelopes' figures for the pair),
  widened by both vehicles' ``position_error_m`` (what their reports may be off by);
- **failsafe**: a vehicle whose heartbeat's condition is ``failsafe``, or whose Vehicle
  Health names a failsafe in force; it ends when neither says so (a terminated vehicle
  has ended its failsafe too).

Alarms must not flood an operator: each is *raised* once when it starts and *cleared*
once when it ends, with hysteresis (:data:`HYSTERESIS_M`) so that GPS noise along a
boundary does not make an episode of every sample. A position older than the stale limit
(the mission's heartbeat timeout) neither raises nor clears anything: an alarm on a
vehicle that fell silent stays raised, because nothing says it ended.

Pure (no clock, no I/O) and shared: the live view
(:class:`~clark_engine.station.view_model.StationView`) feeds it from the station's fleet
table after every tick, the replay (:mod:`clark_engine.station.replay`) from the station's
fleet CSV, row by row, so both raise the same episodes at the same times. Cost: a new
position is checked against its own envelope and against every other vehicle, O(vehicles)
per Agent Status received.
"""

from __future__ import annotations

import math
from collections import deque
from collections.abc import Callable, Mapping
from dataclasses import dataclass
from typing import Any, Final

from clark_engine.runtime.config import EnvelopeSpec
from clark_engine.untrusted import printable

HYSTERESIS_M: Final = 1.0
"""An alarm ends only once the vehicle is this far back on the right side of its limit
(inside its fence, under its ceiling, apart beyond the separation): about a GPS error."""

CLEARED_SHOWN_S: Final = 10.0
"""A cleared alarm stays in the banner, greyed, this long after it ended."""

MAX_CLEARED_KEPT: Final = 50
"""Cleared alarms kept for the banner, at most (the newest)."""

BREACH: Final = "breach"
NEAR_MISS: Final = "near miss"
FAILSAFE: Final = "failsafe"


@dataclass(slots=True)
class Alarm:
    """One alarm episode.

    Attributes:
        id: Its number (1, 2, ...), in the order alarms were raised.
        kind: :data:`BREACH`, :data:`NEAR_MISS` or :data:`FAILSAFE`.
        agents: The vehicles it is about (two for a near miss).
        what: The limit for a breach (``fence``, ``ceiling``); empty otherwise.
        text: What happened, in words, when it was raised (a failsafe's: why, as its
            vehicle last said).
        raised_s: When it was raised, on the station's clock.
        cleared_s: When it ended; None while it is active.
        worst: The worst figure of the episode (metres outside or over, or apart).
    """

    id: int
    kind: str
    agents: tuple[str, ...]
    what: str
    text: str
    raised_s: float
    cleared_s: float | None = None
    worst: float = 0.0

    def to_json(self) -> dict[str, Any]:
        """The alarm as the page receives it (docs/station-view.md, "The protocol")."""
        return {
            "id": self.id,
            "kind": self.kind,
            "agents": list(self.agents),
            "what": self.what or None,
            "text": self.text,
            "raised_s": round(self.raised_s, 3),
            "cleared_s": None if self.cleared_s is None else round(self.cleared_s, 3),
        }


@dataclass(frozen=True, slots=True)
class AlarmChange:
    """An alarm raised or cleared by one :meth:`AlarmWatch.evaluate`."""

    alarm: Alarm
    raised: bool
    """True when it was raised now, False when it was cleared now."""


def pair_separation_m(a: EnvelopeSpec, b: EnvelopeSpec, name_a: str, name_b: str) -> float:
    """The distance two vehicles must keep: the larger of their envelopes' figures."""
    return max(a.separation_from_m(name_b), b.separation_from_m(name_a))


def pair_position_errors_m(a: EnvelopeSpec, b: EnvelopeSpec) -> float:
    """How far two vehicles' reports may together be off: their two position errors.

    Two reports farther apart than the separation and this are two vehicles the
    separation apart on the truth.
    """
    return a.position_error_m + b.position_error_m


class AlarmWatch:
    """Every vehicle's reported state against every envelope; alarms raised and cleared.

    Args:
        envelopes: Vehicle name -> its envelope (vehicles without one are not judged).
        stale_after_s: A position older than this is not judged (neither raises nor
            clears): the mission's heartbeat timeout.
    """

    def __init__(self, envelopes: Mapping[str, EnvelopeSpec], stale_after_s: float) -> None:
        self.envelopes = dict(envelopes)
        self.stale_after_s = stale_after_s
        self._names = sorted(self.envelopes)
        # Near misses are looked for among neighbours only: the plane is cut in square
        # cells as wide as the largest separation (and its hysteresis), so a pair that
        # could be a near miss is in the same or an adjacent cell (3-D distance is never
        # less than the horizontal one).
        widest = max(
            (max([e.min_separation_m, *e.separation.values()]) for e in self.envelopes.values()),
            default=0.0,
        ) + 2.0 * max((e.position_error_m for e in self.envelopes.values()), default=0.0)
        self._cell_m = max(widest + HYSTERESIS_M, 1.0)
        self._cells: dict[tuple[int, int], set[str]] = {}
        self._cell_of: dict[str, tuple[int, int]] = {}
        # name -> (north_m, east_m, up_m, when it was reported)
        self._positions: dict[str, tuple[float, float, float, float]] = {}
        self._failsafe: dict[str, str | None] = {}  # name -> its failsafe in words, or None
        self._moved: set[str] = set()
        self._changed: set[str] = set()
        self._active: dict[tuple[str, ...], Alarm] = {}
        # a pair's separation and position errors, worked out once
        self._keep: dict[tuple[str, str], tuple[float, float]] = {}
        self._cleared: deque[Alarm] = deque(maxlen=MAX_CLEARED_KEPT)
        self._next_id = 1

    # -- what the station learnt ---------------------------------------------------------

    def see_position(
        self, name: str, north_m: float, east_m: float, up_m: float, t_s: float
    ) -> None:
        """A vehicle's new reported position (metres from the origin), received at ``t_s``."""
        if name in self.envelopes and all(map(math.isfinite, (north_m, east_m, up_m))):
            self._positions[name] = (north_m, east_m, up_m, t_s)
            self._moved.add(name)
            cell = (math.floor(north_m / self._cell_m), math.floor(east_m / self._cell_m))
            old = self._cell_of.get(name)
            if old != cell:
                if old is not None:
                    self._cells[old].discard(name)
                self._cells.setdefault(cell, set()).add(name)
                self._cell_of[name] = cell

    def see_condition(self, name: str, failsafe: str | None) -> None:
        """A vehicle's failsafe as its heartbeat and health tell it: words, or None when none.

        Args:
            name: The vehicle.
            failsafe: ``hold: mcs_lost`` (its health's), ``in force`` (its heartbeat's
                condition only), or None when neither says a failsafe is in force.
        """
        if name in self.envelopes and self._failsafe.get(name) != failsafe:
            self._failsafe[name] = failsafe
            self._changed.add(name)

    # -- judging -------------------------------------------------------------------------

    def evaluate(self, now_s: float) -> list[AlarmChange]:
        """Judge what changed since the last call; the alarms raised and cleared now."""
        changes: list[AlarmChange] = []
        if not self._moved and not self._changed:
            return changes
        moved, self._moved = self._moved, set()
        changed, self._changed = self._changed, set()
        for name in sorted(changed):
            self._judge_failsafe(name, now_s, changes)
        oldest_s = now_s - self.stale_after_s
        positions = self._positions
        for name in sorted(moved):
            position = positions[name]
            if position[3] < oldest_s:
                continue
            self._judge_breach(name, position, now_s, changes)
            for other in self._near(name):
                there = positions[other]
                if there[3] >= oldest_s and (other not in moved or other > name):
                    self._judge_pair(name, other, position, there, now_s, changes)
        return changes

    def _near(self, name: str) -> list[str]:
        """The vehicles that may be within a separation of ``name``, or in a near miss with it.

        Those in its cell and the eight around it, and those an alarm in force pairs it
        with (wherever they are now: the alarm must be judged to end), in name order.
        """
        cn, ce = self._cell_of[name]
        found: set[str] = set()
        cells = self._cells
        for dn in (-1, 0, 1):
            for de in (-1, 0, 1):
                there = cells.get((cn + dn, ce + de))
                if there:
                    found |= there
        for key in self._active:
            if key[0] == NEAR_MISS and name in key:
                found.update(key[1:])
        found.discard(name)
        return sorted(found)

    def _judge_breach(
        self,
        name: str,
        position: tuple[float, float, float, float],
        now_s: float,
        changes: list[AlarmChange],
    ) -> None:
        # Every position of every vehicle comes here: the words are made only for an
        # alarm that starts (the usual position raises and clears nothing).
        envelope = self.envelopes[name]
        north, east, up, _ = position
        outside_m = -envelope.fence.margin_m(north, east)
        key = (BREACH, name, "fence")
        if outside_m > 0.0 or key in self._active:
            self._hold(
                key,
                outside_m > 0.0,
                outside_m <= -HYSTERESIS_M,
                outside_m,
                lambda: f"{name} {outside_m:.1f} m outside its geofence at {_where(north, east)}",
                now_s,
                changes,
            )
        over_m = up - envelope.ceiling_m
        key = (BREACH, name, "ceiling")
        if over_m > 0.0 or key in self._active:
            self._hold(
                key,
                over_m > 0.0,
                over_m <= -HYSTERESIS_M,
                over_m,
                lambda: (
                    f"{name} at {up:.1f} m, {over_m:.1f} m above its ceiling of "
                    f"{envelope.ceiling_m:g} m, at {_where(north, east)}"
                ),
                now_s,
                changes,
            )

    def _judge_pair(
        self,
        a: str,
        b: str,
        pa: tuple[float, float, float, float],
        pb: tuple[float, float, float, float],
        now_s: float,
        changes: list[AlarmChange],
    ) -> None:
        # O(vehicles) per position received: kept to a distance and a comparison unless
        # the pair is, or becomes, a near miss.
        first, second = (a, b) if a < b else (b, a)
        kept = self._keep.get((first, second))
        if kept is None:
            env_a, env_b = self.envelopes[first], self.envelopes[second]
            kept = (
                pair_separation_m(env_a, env_b, first, second),
                pair_position_errors_m(env_a, env_b),
            )
            self._keep[(first, second)] = kept
        separation_m, errors_m = kept
        keep_m = separation_m + errors_m
        apart_m = math.dist(pa[:3], pb[:3])
        key = (NEAR_MISS, first, second)
        if apart_m >= keep_m and key not in self._active:
            return
        self._hold(
            key,
            apart_m < keep_m,
            apart_m >= keep_m + HYSTERESIS_M,
            -apart_m,
            lambda: (
                f"{first} and {second} {apart_m:.1f} m apart, inside their {separation_m:g} m "
                f"separation{_errors_words(errors_m)}, "
                f"near {_where((pa[0] + pb[0]) / 2, (pa[1] + pb[1]) / 2)}"
            ),
            now_s,
            changes,
        )

    def _judge_failsafe(self, name: str, now_s: float, changes: list[AlarmChange]) -> None:
        words = self._failsafe.get(name)
        text = f"{name} in failsafe: {printable(words or '', 64)}"
        alarm = self._active.get((FAILSAFE, name))
        if alarm is not None and words is not None:
            alarm.text = text  # its health may tell why after its heartbeat told that
        self._hold(
            (FAILSAFE, name), words is not None, words is None, 0.0, lambda: text, now_s, changes
        )

    def _hold(
        self,
        key: tuple[str, ...],
        starts: bool,
        ends: bool,
        figure: float,
        text: Callable[[], str],
        now_s: float,
        changes: list[AlarmChange],
    ) -> None:
        """Raise the alarm ``key`` when ``starts``, clear it when ``ends``, once each.

        ``text`` makes the alarm's words, called only when it is raised.
        """
        alarm = self._active.get(key)
        if alarm is None:
            if starts:
                alarm = Alarm(self._next_id, key[0], _agents(key), _what(key), text(), now_s)
                alarm.worst = figure
                self._next_id += 1
                self._active[key] = alarm
                changes.append(AlarmChange(alarm, True))
            return
        if figure > alarm.worst:
            alarm.worst = figure
        if ends:
            alarm.cleared_s = now_s
            del self._active[key]
            self._cleared.append(alarm)
            changes.append(AlarmChange(alarm, False))

    # -- what the banner shows -----------------------------------------------------------

    @property
    def active(self) -> list[Alarm]:
        """The alarms in force, oldest first."""
        return sorted(self._active.values(), key=lambda a: a.id)

    def shown(self, now_s: float) -> list[Alarm]:
        """What the banner shows: the alarms in force and those cleared in the last seconds."""
        recent = [a for a in self._cleared if now_s - (a.cleared_s or now_s) < CLEARED_SHOWN_S]
        return sorted([*self._active.values(), *recent], key=lambda a: a.id)

    def in_alarm(self) -> set[str]:
        """The vehicles some alarm in force is about."""
        return {name for alarm in self._active.values() for name in alarm.agents}


def _errors_words(errors_m: float) -> str:
    """`` and the 7.4 m of their position errors``, or nothing when they have none."""
    return f" and the {errors_m:g} m of their position errors" if errors_m > 0 else ""


def _where(north_m: float, east_m: float) -> str:
    return f"N {north_m:.1f} E {east_m:.1f} m"


def _agents(key: tuple[str, ...]) -> tuple[str, ...]:
    return key[1:3] if key[0] == NEAR_MISS else key[1:2]


def _what(key: tuple[str, ...]) -> str:
    return key[2] if key[0] == BREACH else ""


def failsafe_words(condition: str | None, health_failsafe: str | None) -> str | None:
    """A vehicle's failsafe in words from its heartbeat's condition and its health's text.

    None when neither says a failsafe is in force, or when the vehicle has terminated
    (its failsafe ended with it; its last Vehicle Health may still name it).
    """
    if condition == "terminated":
        return None
    if health_failsafe:
        return health_failsafe
    if condition == "failsafe":
        return "in force (its heartbeat's condition)"
    return None


__all__ = [
    "BREACH",
    "CLEARED_SHOWN_S",
    "FAILSAFE",
    "HYSTERESIS_M",
    "NEAR_MISS",
    "Alarm",
    "AlarmChange",
    "AlarmWatch",
    "failsafe_words",
    "pair_position_errors_m",
    "pair_separation_m",
]
