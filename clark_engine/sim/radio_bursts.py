"""Bursts of loss on the simulated radio links (``sim.radio_bursts``): a Gilbert-Elliott chain.

Why separate: a loss model of its own, with its own settings and randomness, that
:class:`~clark_engine.sim.radio.RadioMesh` asks for one number (the share of packets a
link loses at a time) and that is tested apart from the medium.

Real links lose packets in runs (a fade, a body in the way, another transmitter), not one
by one. Each link (pair of agents, both directions) has its own two-state Gilbert-Elliott
chain in simulated time: it stays in its good state for an exponentially distributed time
of mean ``good_s`` and in its bad state for one of mean ``bad_s``, losing ``loss_good`` and
``loss_bad`` of the packets in each. It starts in the bad state with the stationary probability
``bad_s / (good_s + bad_s)``, so the long-run loss share of a link within range is
``radio_loss + (1 - radio_loss) * (good_s * loss_good + bad_s * loss_bad) / (good_s +
bad_s)``. Each chain draws its sojourns from its own generator, seeded from the run's
seed and the link's two names (``{seed}:radio-burst:{a}:{b}``), lazily as simulated
time reaches them: its state at a time depends on nothing but that time (and the seed),
not on how many packets crossed the link before.
"""

from __future__ import annotations

import math
import random
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any


@dataclass(frozen=True, slots=True)
class BurstSettings:
    """The mission's ``sim.radio_bursts``: a Gilbert-Elliott chain on every link.

    Attributes:
        good_s: Mean time a link stays in its good state.
        bad_s: Mean time a link stays in its bad state (a burst).
        loss_good: Share of packets the good state loses.
        loss_bad: Share of packets the bad state loses.
    """

    good_s: float = 60.0
    bad_s: float = 2.0
    loss_good: float = 0.0
    loss_bad: float = 1.0

    def __post_init__(self) -> None:
        if not (self.good_s > 0 and self.bad_s > 0):
            raise ValueError("radio bursts: good_s and bad_s must be above 0")
        if not (0.0 <= self.loss_good <= 1.0 and 0.0 <= self.loss_bad <= 1.0):
            raise ValueError("radio bursts: loss_good and loss_bad must be within 0..1")

    @classmethod
    def from_sim(cls, sim: Mapping[str, Any]) -> BurstSettings | None:
        """Read ``sim.radio_bursts``; None when the mission does not declare it."""
        raw = sim.get("radio_bursts")
        if raw is None:
            return None
        defaults = cls()
        return cls(
            good_s=float(raw.get("good_s", defaults.good_s)),
            bad_s=float(raw.get("bad_s", defaults.bad_s)),
            loss_good=float(raw.get("loss_good", defaults.loss_good)),
            loss_bad=float(raw.get("loss_bad", defaults.loss_bad)),
        )

    @property
    def bad_share(self) -> float:
        """Long-run share of the time a link spends in its bad state."""
        return self.bad_s / (self.good_s + self.bad_s)

    @property
    def mean_loss(self) -> float:
        """Long-run share of packets the chain alone loses."""
        bad = self.bad_share
        return (1.0 - bad) * self.loss_good + bad * self.loss_bad


class BurstChain:
    """One link's Gilbert-Elliott chain in simulated time (see the module docstring).

    Args:
        settings: The chain's means and losses.
        rng: The link's own generator; the chain alone draws from it.
    """

    __slots__ = ("_last_s", "_rng", "_settings", "_until_s", "bad")

    def __init__(self, settings: BurstSettings, rng: random.Random) -> None:
        self._settings = settings
        self._rng = rng
        self.bad = rng.random() < settings.bad_share
        self._until_s = self._sojourn_s()
        self._last_s = -math.inf

    def _sojourn_s(self) -> float:
        mean_s = self._settings.bad_s if self.bad else self._settings.good_s
        return self._rng.expovariate(1.0 / mean_s)

    def loss_at(self, t_s: float) -> float:
        """The share of packets the link loses at ``t_s`` (times must not go back)."""
        if t_s < self._last_s:
            raise ValueError(f"time went back: a burst state at {t_s} s after {self._last_s} s")
        self._last_s = t_s
        while t_s >= self._until_s:
            self.bad = not self.bad
            self._until_s += self._sojourn_s()
        settings = self._settings
        return settings.loss_bad if self.bad else settings.loss_good
