"""Slowing ArduPilot SITL down to a pace the engine can follow.

SITL cannot be paused: it runs at its speed-up whether the engine keeps up or not. A
run that falls behind SITL's clock hears SITL late, and its heartbeats and commands reach
SITL late and far apart; seconds behind, ArduPilot's ground-station failsafe takes the
vehicle home (a loaded CI run fell 10 s behind ArduCopter SITL at 10x, which flew RTL
before the copter took off, and the run then failed as a flight it never was). SITL
takes a new speed-up while it runs (its ``SIM_SPEEDUP``), so :class:`SitlPace` lowers
every SITL's speed-up together when the run falls behind any of them: the run stays the
mission's flight on ArduPilot, only slower against the wall. A run that then keeps up
with SITL for :data:`RAISE_AFTER_WALL_S` gives some of the speed back (the machine was busy
for a while: a test suite's other workers, another run starting), never above the start's.

Together, because the run keeps the slowest SITL's pace: a SITL that runs faster gets
ahead of the run, and slowing only that one would leave the two to overtake each other
in turn, each halving the other. The new speed-up is what the run kept over the last
wall seconds, with a margin, and never more than :data:`GENTLEST` of the old one: one
step for an engine that is slow, a small one for a single stall.
"""

from __future__ import annotations

import time
from collections import deque
from collections.abc import Sequence
from typing import Final

from clark_engine.dryrun.sitl_backend import SitlBackend

BEHIND_S: Final = 2.0
"""How far behind a SITL's clock (seconds of it) the run may fall before SITL is slowed.
Under :data:`~clark_engine.dryrun.report.PACE_LATE_S`, the run's warning, with room to catch
up: ArduPilot's ground-station failsafe counts the engine's silence, about this plus a
heartbeat period, against the 5 s the mission's safety set-up gives it. Not less: a busy
2-core machine puts a run at 10x a second or two behind now and then, and slowing SITL at
1 s made the suite's SITL runs half as fast again (measured) for no better flight."""
AGAIN_WALL_S: Final = 1.0
"""Wall seconds between slow-downs, at least, and only while the run is not catching up
(as far behind as at the last one, or further). Not the run's seconds: an engine that
keeps a third of SITL's pace falls 5 s further behind in the 5 s of its run it takes to
notice (measured: 9 s behind a copter at 7.5x, with 5.4 s of silence)."""
MARGIN: Final = 0.8
"""The new speed-up is this share of the pace the run kept."""
GENTLEST: Final = 0.75
"""...and at most this share of the old speed-up."""
SLOWEST: Final = 1.0
"""SITL is never slowed below real time."""
WINDOW_WALL_S: Final = 3.0
"""The pace the run kept is measured over this many of the last wall seconds."""
SAMPLE_WALL_S: Final = 0.25
"""...from a sample of the run's time this often."""
ON_TIME_S: Final = 0.5
"""A run at most this far behind every SITL (seconds of SITL's clock) keeps up with them."""
RAISE_AFTER_WALL_S: Final = 5.0
"""Wall seconds of keeping up (and since the last change) before the speed-up is raised."""
RAISE: Final = 1.25
"""Each raise multiplies the speed-up by this, up to the start's."""


class SitlPace:
    """Watches how far the run is behind its SITL vehicles; slows them all when it is.

    ``backends`` need only a ``behind_s`` (how far SITL's clock was past the run's time at
    the last step) and ``set_speedup(speedup, t_s)``: :class:`SitlBackend` has both.

    Args:
        backends: Every SITL vehicle of the run.
        speedup: Their speed-up at the start (``--sitl-speedup``).
    """

    def __init__(self, backends: Sequence[SitlBackend], speedup: float) -> None:
        self._backends = tuple(backends)
        self._start_speedup = float(speedup)
        self._on_time_since: float | None = None  # wall time since the run keeps up
        self.speedup = float(speedup)
        """The speed-up every SITL of the run has now."""
        self._changed_wall = float("-inf")
        self._behind_then_s = 0.0  # how far behind the run was at the last slow-down
        self._samples: deque[tuple[float, float]] = deque(
            maxlen=round(WINDOW_WALL_S / SAMPLE_WALL_S) + 1
        )

    def after_step(self, t_s: float) -> None:
        """After every SITL stepped to the run's time ``t_s``: slow them if behind.

        And speed them up again once the run has kept up with them a while.
        """
        now = time.monotonic()
        if not self._samples or now - self._samples[-1][0] >= SAMPLE_WALL_S:
            self._samples.append((now, t_s))
        behind_s = max((backend.behind_s for backend in self._backends), default=0.0)
        if behind_s > ON_TIME_S:
            self._on_time_since = None
        elif self._on_time_since is None:
            self._on_time_since = now
        elif (
            self.speedup < self._start_speedup
            and now - self._on_time_since >= RAISE_AFTER_WALL_S
            and now - self._changed_wall >= RAISE_AFTER_WALL_S
        ):
            self._change(min(self._start_speedup, self.speedup * RAISE), now, t_s, 0.0)
            return
        if (
            behind_s <= max(BEHIND_S, self._behind_then_s)
            or self.speedup <= SLOWEST
            or now - self._changed_wall < AGAIN_WALL_S
        ):
            return
        speedup = self.speedup * GENTLEST
        kept = self.kept_pace(now, t_s)
        if kept is not None:
            speedup = min(speedup, kept * MARGIN)
        self._change(max(SLOWEST, speedup), now, t_s, behind_s)

    def _change(self, speedup: float, now: float, t_s: float, behind_s: float) -> None:
        """Every SITL of the run to ``speedup`` from the run's time ``t_s``."""
        self.speedup = speedup
        self._changed_wall, self._behind_then_s = now, behind_s
        for backend in self._backends:
            backend.set_speedup(self.speedup, t_s)

    def kept_pace(self, now: float, t_s: float) -> float | None:
        """The run's seconds per wall second over the window; None before half a second."""
        wall_s, first_s = self._samples[0]
        if now - wall_s < 0.5:
            return None
        return (t_s - first_s) / (now - wall_s)
