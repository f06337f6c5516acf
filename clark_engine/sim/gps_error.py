"""A vehicle's slowly wandering GPS error, and its glitches, for the dry run (``sim.gps_error``).

A GPS receiver's horizontal error is not white: most of it (the atmosphere, the
satellites' orbits and clocks, multipath) changes over minutes, so a vehicle
told to hold a point holds the point its estimate says, and truly wanders with
the error. :class:`GpsError` models that error on each horizontal axis:

- A random walk: a first-order Gauss-Markov process per axis, of steady-state
  standard deviation ``walk_m`` and time constant ``walk_time_constant_s`` (the
  error's memory: two samples that far apart are correlated by 1/e, 0.37; ten
  seconds apart with a 300 s constant, by 0.97). Sampled on a fixed grid of
  :data:`WALK_STEP_S`: ``x[k+1] = a x[k] + walk_m sqrt(1 - a**2) w``,
  ``a = exp(-WALK_STEP_S / walk_time_constant_s)``, ``w`` standard normal; the
  first sample is drawn from the steady state, so the error is there from power-on.
- A fleet-wide share: ``common_share`` (0..1) of the walk's variance is one
  process every vehicle of the run shares (vehicles under the same sky see the
  same atmosphere and satellites), the rest is the vehicle's own:
  ``x = sqrt(c) common + sqrt(1 - c) own``. The errors of two vehicles are then
  correlated by ``c``, and each still has standard deviation ``walk_m``.
- Glitches: at a rate of ``glitch_rate_per_h`` (a Poisson process in simulated
  time), the position jumps ``glitch_m`` in a random direction, stays off for
  ``glitch_s`` and comes back.

The dry run's vehicle model is the autopilot's estimate (what it reports and
flies by); the vehicle's TRUE position is the estimate minus this error
(:class:`~clark_engine.dryrun.backend.SimulatedBackend`). When the error changes,
the estimate moves and the truth does not; the autopilot then flies the
estimate back to its target, which moves the truth. The white ``gps_noise_m``
of each fix comes on top, as before. ArduPilot's EKF rejects a GPS jump larger
than its innovation gate for a while before it resets to the GPS; the model
follows the GPS at once (a glitch here is one the EKF accepted).

Determinism: every draw comes from generators seeded from the run's seed and a
stable key (``{seed}:gps:{agent}`` for the vehicle's walk, ``{seed}:gps:common``
for the shared one, ``{seed}:gps-glitch:{agent}`` for glitches); the walk is
sampled on the fixed grid whatever the caller's steps, so every vehicle's copy
of the common process is the same, whenever and in whatever order it is asked.
"""

from __future__ import annotations

import math
import random
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

#: The walk is sampled this often (simulated seconds) and held in between.
WALK_STEP_S = 0.1


@dataclass(frozen=True, slots=True)
class GpsErrorSettings:
    """The mission's ``sim.gps_error`` (after its distributions were drawn).

    Attributes:
        walk_m: Steady-state standard deviation of the random walk, per horizontal axis.
        walk_time_constant_s: The walk's correlation time (first-order Gauss-Markov).
        common_share: Share (0..1) of the walk's variance common to the whole fleet.
        glitch_rate_per_h: Glitches per hour of simulated time (a Poisson process).
        glitch_m: How far a glitch moves the position.
        glitch_s: How long a glitch lasts.
    """

    walk_m: float = 0.0
    walk_time_constant_s: float = 300.0
    common_share: float = 0.0
    glitch_rate_per_h: float = 0.0
    glitch_m: float = 0.0
    glitch_s: float = 0.0

    @classmethod
    def from_sim(cls, sim: Mapping[str, Any]) -> GpsErrorSettings | None:
        """Read ``sim.gps_error``; None when it is absent or declares no error at all."""
        raw = sim.get("gps_error")
        if not raw:
            return None
        defaults = cls()
        settings = cls(
            walk_m=float(raw.get("walk_m", defaults.walk_m)),
            walk_time_constant_s=float(
                raw.get("walk_time_constant_s", defaults.walk_time_constant_s)
            ),
            common_share=float(raw.get("common_share", defaults.common_share)),
            glitch_rate_per_h=float(raw.get("glitch_rate_per_h", defaults.glitch_rate_per_h)),
            glitch_m=float(raw.get("glitch_m", defaults.glitch_m)),
            glitch_s=float(raw.get("glitch_s", defaults.glitch_s)),
        )
        if settings.walk_m < 0 or settings.glitch_m < 0 or settings.glitch_s < 0:
            raise ValueError("sim.gps_error: sizes and durations must not be negative")
        if settings.walk_time_constant_s <= 0:
            raise ValueError("sim.gps_error.walk_time_constant_s must be above 0")
        if not 0.0 <= settings.common_share <= 1.0:
            raise ValueError("sim.gps_error.common_share must be within 0..1")
        if settings.glitch_rate_per_h < 0:
            raise ValueError("sim.gps_error.glitch_rate_per_h must not be negative")
        return settings if settings.active else None

    @property
    def active(self) -> bool:
        """True when the settings move a position at all."""
        return self.walk_m > 0 or (
            self.glitch_rate_per_h > 0 and self.glitch_m > 0 and self.glitch_s > 0
        )


class _Walk:
    """One first-order Gauss-Markov process per horizontal axis, on the fixed grid."""

    __slots__ = ("_a", "_b", "_gauss", "_index", "east_m", "north_m")

    def __init__(self, rng: random.Random, sigma_m: float, time_constant_s: float) -> None:
        self._a = math.exp(-WALK_STEP_S / time_constant_s)
        self._b = sigma_m * math.sqrt(1.0 - self._a * self._a)
        self._gauss = rng.gauss
        self._index = 0
        self.north_m = self._gauss(0.0, sigma_m) if sigma_m else 0.0
        self.east_m = self._gauss(0.0, sigma_m) if sigma_m else 0.0

    def advance(self, t_s: float) -> None:
        """Take the grid's samples up to ``t_s`` (never back)."""
        index = math.floor(t_s / WALK_STEP_S + 1e-9)
        if index <= self._index or not self._b:
            self._index = max(index, self._index)
            return
        a, b, gauss = self._a, self._b, self._gauss
        north, east = self.north_m, self.east_m
        for _ in range(index - self._index):
            north = a * north + b * gauss(0.0, 1.0)
            east = a * east + b * gauss(0.0, 1.0)
        self.north_m, self.east_m = north, east
        self._index = index


class GpsError:
    """One vehicle's horizontal GPS error over simulated time.

    Args:
        settings: The mission's ``sim.gps_error``.
        seed: The run's seed.
        agent: The vehicle's name (its generators' key).
    """

    def __init__(self, settings: GpsErrorSettings, seed: int, agent: str) -> None:
        self.settings = settings
        share = settings.common_share
        sigma, tau = settings.walk_m, settings.walk_time_constant_s
        self._own = _Walk(random.Random(f"{seed}:gps:{agent}"), sigma, tau)
        self._common = _Walk(random.Random(f"{seed}:gps:common"), sigma, tau) if share > 0 else None
        self._own_k = math.sqrt(1.0 - share)
        self._common_k = math.sqrt(share)
        self._glitch_rng = random.Random(f"{seed}:gps-glitch:{agent}")
        self._glitching = (
            settings.glitch_rate_per_h > 0 and settings.glitch_m > 0 and settings.glitch_s > 0
        )
        self._glitch_from_s = math.inf
        self._glitch_n = self._glitch_e = 0.0
        self._glitch_seen = False
        if self._glitching:
            self._glitch_from_s = self._next_gap_s()
            self._draw_direction()
        self.glitches: list[float] = []
        """Start times of the glitches so far (for tests and the report)."""

    def _next_gap_s(self) -> float:
        return self._glitch_rng.expovariate(self.settings.glitch_rate_per_h / 3600.0)

    def _draw_direction(self) -> None:
        bearing = self._glitch_rng.uniform(0.0, 2.0 * math.pi)
        self._glitch_n = self.settings.glitch_m * math.cos(bearing)
        self._glitch_e = self.settings.glitch_m * math.sin(bearing)

    def offset_m(self, t_s: float) -> tuple[float, float]:
        """The error (north, east) in metres at ``t_s``; times must not go back."""
        own = self._own
        own.advance(t_s)
        k = self._own_k
        north, east = k * own.north_m, k * own.east_m
        common = self._common
        if common is not None:
            common.advance(t_s)
            north += self._common_k * common.north_m
            east += self._common_k * common.east_m
        if self._glitching:
            glitch_s = self.settings.glitch_s
            while t_s >= self._glitch_from_s + glitch_s:  # that glitch is over: the next
                if not self._glitch_seen:
                    self.glitches.append(self._glitch_from_s)
                self._glitch_seen = False
                self._glitch_from_s += glitch_s + self._next_gap_s()
                self._draw_direction()
            if t_s >= self._glitch_from_s:
                if not self._glitch_seen:
                    self._glitch_seen = True
                    self.glitches.append(self._glitch_from_s)
                north += self._glitch_n
                east += self._glitch_e
        return north, east
