"""What a dry run records: tracks, state changes, control signals, pictures, safety events.

The simulator fills a :class:`Recording` as it runs; the checks and the report
read it afterwards. Everything is in simulated time and the mission's local
frame (metres north, east and up of the origin).
"""

from __future__ import annotations

import contextlib
import math
import os
import tempfile
import weakref
from array import array
from collections.abc import Iterator
from dataclasses import dataclass, field
from typing import Any, NamedTuple

#: Most samples a track keeps in memory for the plots: past it, every other one is dropped
#: and the sampling interval kept doubles, so memory stays constant in the run's length.
#: Every example mission fits whole (its longest, 417 s at 10 Hz, is 4,200 samples).
MAX_TRACK_POINTS = 8192
#: Samples a track holds before it appends them to its file on disk.
SPOOL_CHUNK = 4096
#: Values per sample in a track's file: time, north, east, up.
_FIELDS = 4


def _unlink(path: str) -> None:
    with contextlib.suppress(OSError):
        os.unlink(path)


@dataclass(slots=True, eq=False, weakref_slot=True)
class Track:
    """One vehicle's true path, sampled at the recorder's rate.

    Every sample's time and position go to a temporary file as the run goes (the checks
    read them back in order with :meth:`samples`), so a long run's memory does not grow
    with its length. The lists are what the plots draw: every sample while there are at
    most :data:`MAX_TRACK_POINTS`, then a decimated path (every 2nd, 4th, ... sample from
    the first, and the latest), still in time order.
    """

    times_s: list[float] = field(default_factory=list)
    north_m: list[float] = field(default_factory=list)
    east_m: list[float] = field(default_factory=list)
    up_m: list[float] = field(default_factory=list)
    roll_deg: list[float] = field(default_factory=list)
    pitch_deg: list[float] = field(default_factory=list)
    yaw_deg: list[float] = field(default_factory=list)
    capacity: int = MAX_TRACK_POINTS
    """Most samples the lists keep (at least 2)."""
    count: int = 0
    """Samples added (all of them are in :meth:`samples`)."""
    _stride: int = 1
    _tail: bool = False  # the lists' last sample is the latest, off the stride
    _pending: array[float] = field(default_factory=lambda: array("d"))
    _path: str | None = None
    _finalizer: weakref.finalize[[str], Track] | None = None

    def add(
        self,
        t_s: float,
        north_m: float,
        east_m: float,
        up_m: float,
        roll_deg: float,
        pitch_deg: float,
        yaw_deg: float,
    ) -> None:
        """Append one sample (to the file, and to the lists if it is on their stride)."""
        pending = self._pending
        pending.extend((t_s, north_m, east_m, up_m))
        if len(pending) >= SPOOL_CHUNK * _FIELDS:
            self._spill()
        index = self.count
        self.count += 1
        if self._tail:
            self._pop()
            self._tail = False
        self._push(t_s, north_m, east_m, up_m, roll_deg, pitch_deg, yaw_deg)
        if index % self._stride:
            self._tail = True
        elif len(self.times_s) >= self.capacity:  # room for a latest sample off the stride
            # Keep the samples at multiples of twice the stride (the first among them).
            self._stride *= 2
            for values in self._lists():
                del values[1::2]
            if index % self._stride:
                self._push(t_s, north_m, east_m, up_m, roll_deg, pitch_deg, yaw_deg)
                self._tail = True

    def _lists(self) -> tuple[list[float], ...]:
        return (
            self.times_s,
            self.north_m,
            self.east_m,
            self.up_m,
            self.roll_deg,
            self.pitch_deg,
            self.yaw_deg,
        )

    def _push(self, *values: float) -> None:
        for target, value in zip(self._lists(), values, strict=True):
            target.append(value)

    def _pop(self) -> None:
        for values in self._lists():
            values.pop()

    def _spill(self) -> None:
        """Append the pending samples to the track's file (made on first use)."""
        if not self._pending:
            return
        if self._path is None:
            handle, self._path = tempfile.mkstemp(prefix="clark-track-", suffix=".f64")
            os.close(handle)
            self._finalizer = weakref.finalize(self, _unlink, self._path)
        with open(self._path, "ab") as file:
            self._pending.tofile(file)
        self._pending = array("d")

    def samples(self) -> Iterator[tuple[float, float, float, float]]:
        """Every sample added, in order: (time, north, east, up), read back from disk."""
        if self._path is not None:
            with open(self._path, "rb") as file:
                while True:
                    chunk = array("d")
                    with contextlib.suppress(EOFError):  # the last, shorter chunk is read
                        chunk.fromfile(file, SPOOL_CHUNK * _FIELDS)
                    if not chunk:
                        break
                    yield from _rows(chunk)
        yield from _rows(self._pending)

    def at(self, t_s: float) -> tuple[float, float, float] | None:
        """The last sample at or before ``t_s`` (north, east, up), None before the first."""
        best: tuple[float, float, float] | None = None
        for time, north, east, up in self.samples():
            if time > t_s + 1e-9:
                break
            best = (north, east, up)
        return best

    def __eq__(self, other: object) -> bool:
        if not isinstance(other, Track):
            return NotImplemented
        return (
            self.count == other.count
            and self._lists() == other._lists()
            and all(a == b for a, b in zip(self.samples(), other.samples(), strict=True))
        )

    __hash__ = None  # type: ignore[assignment]

    def __getstate__(self) -> dict[str, Any]:
        """For another process: the file goes with the pickled track (the receiver deletes it)."""
        self._spill()
        if self._finalizer is not None:
            self._finalizer.detach()  # this process no longer owns the file
            self._finalizer = None
        return {name: getattr(self, name) for name in (*_TRACK_STATE,)}

    def __setstate__(self, state: dict[str, Any]) -> None:
        for name in _TRACK_STATE:
            object.__setattr__(self, name, state[name])
        self._pending = array("d")
        self._finalizer = (
            weakref.finalize(self, _unlink, self._path) if self._path is not None else None
        )


_TRACK_STATE = (
    "times_s",
    "north_m",
    "east_m",
    "up_m",
    "roll_deg",
    "pitch_deg",
    "yaw_deg",
    "capacity",
    "count",
    "_stride",
    "_tail",
    "_path",
)


def _rows(values: array[float]) -> Iterator[tuple[float, float, float, float]]:
    it = iter(values)
    return zip(it, it, it, it, strict=True)


@dataclass(frozen=True, slots=True)
class StateEntry:
    """One state change of an agent's behaviour."""

    time_s: float
    event: str
    active: tuple[str, ...]
    entered: tuple[str, ...]


class FlightEntry(NamedTuple):
    """A vehicle's arming or flight mode as its autopilot truly had it, from a time on.

    Recorded when either changes (sampled with the tracks), from the simulated
    autopilot's model or SITL's own HEARTBEAT: what the vehicle did, not what the
    engine heard. The safety judgement reads it (time armed, guided flight).
    """

    time_s: float
    armed: bool
    mode: str


@dataclass(frozen=True, slots=True)
class Photo:
    """A picture a camera took, with where the vehicle truly was."""

    time_s: float
    north_m: float
    east_m: float
    up_m: float


@dataclass(slots=True)
class Pace:
    """How well the engine kept ArduPilot SITL's pace over a run (SITL's clock, seconds).

    SITL cannot be paused: an engine that falls behind it hears what SITL said late, and
    its commands and heartbeats reach SITL late and far apart (ArduPlane's ground-station
    failsafe flew RTL in a run that fell behind during a sweep). Set by
    :class:`~clark_engine.dryrun.sitl_backend.SitlBackend`.
    """

    behind_s: float = 0.0
    """The most SITL's clock was past the run's time when the run got there."""
    behind_at_s: float = 0.0
    """The run's time when it was."""
    silent_s: float = 0.0
    """The longest the engine's link to the autopilot went without a byte from the engine
    (heartbeats, RC overrides, commands): what ArduPilot's ground-station failsafe counts."""
    silent_at_s: float = 0.0
    """The run's time at the end of that silence."""
    start_speedup: float = 1.0
    """SITL's speed-up when the run started (``--sitl-speedup``)."""
    speedups: list[tuple[float, float]] = field(default_factory=list)
    """Each change of SITL's speed-up: the run's time, the new speed-up (lower when the
    engine fell behind, higher again once it kept up a while)."""


@dataclass(slots=True)
class Recording:
    """Everything a dry run observed.

    Attributes:
        tracks: Vehicle name -> its true path.
        states: Agent name -> its behaviour's state changes, in order.
        signals: (agent, rc or servo label) -> (time, pulse width) the autopilot received,
            sampled at each of the agent's ticks while a doublet or sweep drove it.
        photos: Agent name -> pictures its cameras took.
        safety: Agent name -> (time, what): mcs_lost, autopilot_lost, failsafe actions.
        flight: Vehicle name -> its arming and flight mode, an entry at each change.
        waiting: Agent name -> what its launch gate still waited for when the run ended
            (or its mission computer died), for an agent whose behaviour never started;
            absent for one whose behaviour started.
        killed: Agent name -> when a fault killed its mission computer.
        pace: Vehicle name -> how well the engine kept its ArduPilot SITL's pace
            (``--autopilot sitl`` only).
        end_s: Simulated time at which the run ended.
    """

    tracks: dict[str, Track] = field(default_factory=dict)
    states: dict[str, list[StateEntry]] = field(default_factory=dict)
    signals: dict[tuple[str, str], list[tuple[float, int]]] = field(default_factory=dict)
    photos: dict[str, list[Photo]] = field(default_factory=dict)
    safety: dict[str, list[tuple[float, str]]] = field(default_factory=dict)
    flight: dict[str, list[FlightEntry]] = field(default_factory=dict)
    waiting: dict[str, tuple[str, ...]] = field(default_factory=dict)
    killed: dict[str, float] = field(default_factory=dict)
    pace: dict[str, Pace] = field(default_factory=dict)
    end_s: float = 0.0

    def entered_by(self, agent: str, path: str, by_s: float) -> float | None:
        """When ``path`` (or one of its descendants) was first entered by ``by_s``."""
        for entry in self.states.get(agent, []):
            if entry.time_s > by_s + 1e-9:
                return None
            if any(p == path or p.startswith(path + ".") for p in entry.entered):
                return entry.time_s
        return None

    def armed_intervals(self, vehicle: str) -> list[tuple[float, float]]:
        """Every (armed, disarmed) time interval of a vehicle; the last may end at the run's."""
        out: list[tuple[float, float]] = []
        start: float | None = None
        for entry in self.flight.get(vehicle, []):
            if entry.armed and start is None:
                start = entry.time_s
            elif not entry.armed and start is not None:
                out.append((start, entry.time_s))
                start = None
        if start is not None:
            out.append((start, self.end_s))
        return out

    def intervals(self, agent: str, path: str) -> list[tuple[float, float]]:
        """Every (entered, left) time interval during which ``path`` was active."""
        out: list[tuple[float, float]] = []
        start: float | None = None
        for entry in self.states.get(agent, []):
            active = any(p == path or p.startswith(path + ".") for p in entry.active)
            if active and start is None:
                start = entry.time_s
            elif not active and start is not None:
                out.append((start, entry.time_s))
                start = None
        if start is not None:
            out.append((start, self.end_s))
        return out


def distance_m(a: tuple[float, float, float], b: tuple[float, float, float]) -> float:
    """Straight-line distance between two local points."""
    return math.dist(a, b)
