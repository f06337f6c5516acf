"""The simulated ArduPilot's fence, wired in: when and against what it is checked.

:class:`FenceChecks` builds the fence's zones from the uploaded fence list, gives the
position the fence sees (the altitude above home the autopilot reports, the position from
home and from the origin once it has a fix), checks at each firmware's rate and reacts
(:func:`~clark_engine.sim.ardupilot.fence.react`), flies ArduPlane's GUIDED fence action,
tells whether a guided destination is inside the fence, and queues FENCE_STATUS when the
fence's state changes. The fence's own logic (FENCE_*, breaches, actions, texts) is
:class:`~clark_engine.sim.ardupilot.fence.ArduFence`'s.

Apart from :class:`~clark_engine.sim.ardupilot.autopilot.SimAutopilot` because this is the
fence's plumbing, one concept: a helper object the autopilot owns
(``SimAutopilot.fence_checks``). When the fence was last checked and whether it is quiet
stay on the autopilot, whose parameters, arming and commands wake it.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

from clark_engine.sim.ardupilot.fence import (
    CHECK_PERIOD_S,
    FencePosition,
    FenceZones,
    Point2,
    react,
)

if TYPE_CHECKING:
    from clark_engine.sim.ardupilot.autopilot import SimAutopilot


class FenceChecks:
    """The fence's checks for one simulated autopilot (owned by it, acting through it).

    Args:
        ap: The autopilot it belongs to.
    """

    def __init__(self, ap: SimAutopilot) -> None:
        self._ap = ap

    def zones(self) -> FenceZones:
        """The uploaded fence as zones, built again whenever the lists changed."""
        if self._ap.missions.changed != self._ap._fence_list_changes:
            self._ap._fence_list_changes = self._ap.missions.changed
            self._ap.fence.zones = FenceZones.from_items(
                self._ap.missions.fence_items, self._ap._to_local
            )
        return self._ap.fence.zones

    def position(self, now_s: float) -> FencePosition:
        """Where the fence sees the vehicle: its true position through the firmware's datum."""
        truth = self._ap.model.truth()
        alt_above_home_m = self._ap.readiness.alt_above_home_m(now_s, truth.up_m)
        if not self._ap.readiness.gps_fix(now_s):
            return FencePosition(alt_above_home_m, None, None)
        here = (truth.north_m, truth.east_m)
        from_home = None
        if self._ap._home is not None:
            home = self._ap._to_local(self._ap._home[0], self._ap._home[1])
            from_home = (here[0] - home[0], here[1] - home[1])
        return FencePosition(alt_above_home_m, from_home, here)

    def check(self, now_s: float) -> None:
        """Each firmware's fence_checks_async and fence_check, at its rate (25, 10, 3 Hz)."""
        self._ap._next_fence_check_s = now_s + CHECK_PERIOD_S[self._ap.firmware]
        if self._ap._fence_quiet and self._ap.missions.changed == self._ap._fence_list_changes:
            return
        fence = self._ap.fence
        self.zones()
        if fence.idle and not fence.update_pending:
            if self._ap.firmware == "ardurover":
                self._ap.avoidance.update(now_s)
            self._ap._fence_quiet = True
            return
        orig = fence.breaches
        model = self._ap.model
        if self._ap.firmware == "arducopter":
            landing = self._ap._hooks.landing or self._ap._hooks.landed or not model.armed
        elif self._ap.firmware == "arduplane":
            landing = not model.armed or self._ap._hooks.landing
        else:
            landing = False
        new = fence.check(self.position(now_s), now_s, landing)
        react(self._ap._hooks, fence, new, orig, self.guide)
        if self._ap.firmware == "ardurover":
            self._ap.avoidance.update(now_s)

    def status_due(self) -> None:
        """FENCE_STATUS to send with the next advance (the fence changed its state)."""
        if "FENCE_STATUS" not in self._ap._deferred:
            self._ap._deferred.append("FENCE_STATUS")
        self._ap._next_due_us = 0

    def guide(self, point: Point2 | None, alt_above_home_m: float) -> None:
        """ArduPlane's GUIDED fence action: to the fence's return point (or home)."""
        if point is None:
            if self._ap._home is None:
                return
            lat, lon = self._ap._home[0], self._ap._home[1]
        else:
            lat, lon = self._ap._from_local(*point)
        alt_m = alt_above_home_m + self._ap._home_alt_m() - self._ap.origin_alt_amsl_m
        self._ap._goto(lat, lon, alt_m)

    def target_inside(self, lat_deg: float, lon_deg: float, alt_m: float) -> bool:
        """AC_Fence::check_destination_within_fence for a target (its height above the origin)."""
        here = self._ap._to_local(lat_deg, lon_deg)
        from_home = None
        above_home_m = None
        if self._ap._home is not None:
            home = self._ap._to_local(self._ap._home[0], self._ap._home[1])
            from_home = (here[0] - home[0], here[1] - home[1])
            above_home_m = alt_m + self._ap.origin_alt_amsl_m - self._ap._home[2]
        self.zones()
        return self._ap.fence.destination_inside(above_home_m, from_home, here)
