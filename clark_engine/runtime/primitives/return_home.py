"""return_home: go home in the autopilot's RTL mode; done within ``tolerance_m`` of home.

Runtime semantics (the declaration is :mod:`clark_engine.mission.primitives.return_home`):

- ``start``: SetMode(the profile's ``rtl_mode``), always, and again while refused,
  as :mod:`.hold` does.
  ArduRover drives home and stops; ArduCopter climbs to RTL_ALT, flies home,
  lands and disarms; ArduPlane flies home and circles it.
- ``update``: DONE once the vehicle is within ``tolerance_m`` of home, ground
  distance. Home is where the autopilot says (HOME_POSITION: where it got its
  first fix or was armed), not the mission origin. Before the autopilot has
  reported home, and without a vehicle state, RUNNING. ArduCopter goes on to land
  after this is done; a following state that changes the mode stops the landing.
- FAILED when the profile names no RTL mode (the mission layer refuses that).
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

from clark_engine.runtime.context import PrimitiveContext, Status
from clark_engine.runtime.primitives._shared import ProfileModePrimitive


class ReturnHome(ProfileModePrimitive):
    """Return to launch.

    Attributes:
        tolerance_m: Ground distance from home that counts as home.
    """

    name = "return_home"
    mode_key = "rtl_mode"

    def __init__(self, params: Mapping[str, Any]) -> None:
        super().__init__(params)
        self.tolerance_m = float(params.get("tolerance_m", 5.0))

    def update(self, ctx: PrimitiveContext) -> Status:
        """DONE within tolerance of home."""
        if not self.keep_mode(ctx):
            return Status.FAILED
        home = ctx.autopilot.home if ctx.autopilot is not None else None
        if home is None:
            return Status.RUNNING
        distance = ctx.distance_to_m(home[0], home[1])
        if distance is not None and distance <= self.tolerance_m:
            return Status.DONE
        return Status.RUNNING
