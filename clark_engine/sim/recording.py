"""What a dry run records: tracks, state changes, control signals, pictures, safety events.

The simulator fills a :class:`Recording` as it runs; the checks and the report
read it afterwards. Everything is in simulated time and the mission's local
frame (metres north, east and up of the origin).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field


@dataclass(slots=True)
class Track:
    """One vehicle's true path, sampled at the recorder's rate."""

    times_s: list[float] = field(default_factory=list)
    north_m: list[float] = field(default_factory=list)
    east_m: list[float] = field(default_factory=list)
    up_m: list[float] = field(default_factory=list)
    roll_deg: list[float] = field(default_factory=list)
    pitch_deg: list[float] = field(default_factory=list)
    yaw_deg: list[float] = field(default_factory=list)

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
        """Append one sample."""
        self.times_s.append(t_s)
        self.north_m.append(north_m)
        self.east_m.append(east_m)
        self.up_m.append(up_m)
        self.roll_deg.append(roll_deg)
        self.pitch_deg.append(pitch_deg)
        self.yaw_deg.append(yaw_deg)

    def at(self, t_s: float) -> tuple[float, float, float] | None:
        """The last sample at or before ``t_s`` (north, east, up), None before the first."""
        best: tuple[float, float, float] | None = None
        for i, time in enumerate(self.times_s):
            if time > t_s + 1e-9:
                break
            best = (self.north_m[i], self.east_m[i], self.up_m[i])
        return best


@dataclass(frozen=True, slots=True)
class StateEntry:
    """One state change of an agent's behaviour."""

    time_s: float
    event: str
    active: tuple[str, ...]
    entered: tuple[str, ...]


@dataclass(frozen=True, slots=True)
class Photo:
    """A picture a camera took, with where the vehicle truly was."""

    time_s: float
    north_m: float
    east_m: float
    up_m: float


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
        end_s: Simulated time at which the run ended.
    """

    tracks: dict[str, Track] = field(default_factory=dict)
    states: dict[str, list[StateEntry]] = field(default_factory=dict)
    signals: dict[tuple[str, str], list[tuple[float, int]]] = field(default_factory=dict)
    photos: dict[str, list[Photo]] = field(default_factory=dict)
    safety: dict[str, list[tuple[float, str]]] = field(default_factory=dict)
    end_s: float = 0.0

    def entered_by(self, agent: str, path: str, by_s: float) -> float | None:
        """When ``path`` (or one of its descendants) was first entered by ``by_s``."""
        for entry in self.states.get(agent, []):
            if entry.time_s > by_s + 1e-9:
                return None
            if any(p == path or p.startswith(path + ".") for p in entry.entered):
                return entry.time_s
        return None

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
