"""ArduRover's simple avoidance in the simulated ArduPilot: stopping short of the fence.

:class:`Avoidance` is AC_Avoid as ArduRover uses it with AVOID_ENABLE bit 0: a guided
target (or an AUTO waypoint) whose straight line crosses the enabled circle fence or an
uploaded zone is cut short FENCE_MARGIN inside it, and cut again when the fence's state
changes on the way.

Apart from :class:`~clark_engine.sim.ardupilot.autopilot.SimAutopilot` because avoidance is
a concept of its own (ArduPilot's AC_Avoid, beside AC_Fence): a helper object the autopilot
owns (``SimAutopilot.avoidance``), asked where the model goes. Whether the target was cut
short is the autopilot's, which its arrival messages read; the fence's state a cut was
worked out for is this one's.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

from clark_engine.mission.fence import Fence, Zone
from clark_engine.sim.ardupilot.fence import CIRCLE, POLYGON, Point2

if TYPE_CHECKING:
    from clark_engine.sim.ardupilot.autopilot import SimAutopilot


class Avoidance:
    """ArduRover's simple avoidance for one simulated autopilot (owned by it).

    Args:
        ap: The autopilot it belongs to.
    """

    def __init__(self, ap: SimAutopilot) -> None:
        self._ap = ap
        self._key: tuple[int, float, float] | None = None
        """The fence's state (enabled fences, margin, AVOID_ENABLE) the last cut was for."""

    def _fence(self) -> Fence | None:
        """The fence ArduRover's avoidance keeps inside of (AVOID_ENABLE bit 0), if any.

        AC_Avoid stops the rover FENCE_MARGIN short of the enabled circle fence and
        uploaded zones (measured: 48.09 m on a 50 m circle with the default margin 2).
        """
        if not int(self._ap._params["AVOID_ENABLE"].value) & 1 or self._ap._home is None:
            return None
        enabled = self._ap.fence.enabled_fences()
        include: list[Zone] = []
        exclude: list[Zone] = []
        if enabled & CIRCLE:
            home = self._ap._to_local(self._ap._home[0], self._ap._home[1])
            include.append(Zone.circle(home, self._ap._params["FENCE_RADIUS"].value))
        if enabled & POLYGON:
            include.extend(self._ap.fence.zones.inclusions)
            exclude.extend(self._ap.fence.zones.exclusions)
        if not include and not exclude:
            return None
        return Fence(tuple(include), tuple(exclude))

    def avoided(self, end: Point2) -> Point2 | None:
        """Where ArduRover stops short of the fence on its way to ``end``; None: not short.

        Sets :attr:`_key` to the fence's state it was worked out for.
        """
        self._key = (
            self._ap.fence.enabled_fences(),
            self._ap.fence.margin_m,
            self._ap._params["AVOID_ENABLE"].value,
        )
        fence = self._fence()
        if fence is None:
            return None
        truth = self._ap.model.truth()
        start = (truth.north_m, truth.east_m)
        cut = fence.leaves_at(start, end, self._ap.fence.margin_m)
        if cut is None:
            return None
        return start[0] + (end[0] - start[0]) * cut, start[1] + (end[1] - start[1]) * cut

    def drive_to(self, lat_deg: float, lon_deg: float, alt_m: float) -> bool:
        """The model goes to a guided target, or where ArduRover's avoidance stops it short."""
        self._ap._avoid_cut = False
        if self._ap.firmware == "ardurover":
            short = self.avoided(self._ap._to_local(lat_deg, lon_deg))
            if short is not None:
                self._ap._avoid_cut = True
                lat_deg, lon_deg = self._ap._from_local(*short)
        return self._ap.model.goto(lat_deg, lon_deg, alt_m, None)

    def update(self, now_s: float) -> None:
        """Cut the guided target short again when the fence's state changed on the way."""
        if not self._ap._in_guided() or self._ap._target is None:
            return
        key = (
            self._ap.fence.enabled_fences(),
            self._ap.fence.margin_m,
            self._ap._params["AVOID_ENABLE"].value,
        )
        if key != self._key:
            self.drive_to(*self._ap._target)
