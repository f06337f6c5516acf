"""land: land where the vehicle is, in the autopilot's land mode; done on the ground.

Runtime semantics (the declaration is :mod:`clark_engine.mission.primitives.land`):

- ``start``: SetMode(the profile's ``land_mode``: LAND for ArduCopter), always,
  as :mod:`.hold` does. ArduCopter descends, detects the touchdown and disarms.
- ``update``: DONE once the vehicle is on the ground (the autopilot's landed
  state; without one, disarmed, or no more than 2 m up).
  SetMode is repeated only while the autopilot has refused it and nobody changed
  the mode since (:class:`~._shared.ModeRequest`): a pilot who takes over is not
  fought.
- FAILED when the profile names no land mode (the mission layer refuses that).
"""

from __future__ import annotations

from clark_engine.runtime.context import PrimitiveContext, Status
from clark_engine.runtime.launch import is_airborne
from clark_engine.runtime.primitives._shared import ProfileModePrimitive


class Land(ProfileModePrimitive):
    """Land in the autopilot's land mode."""

    name = "land"
    mode_key = "land_mode"

    def update(self, ctx: PrimitiveContext) -> Status:
        """DONE on the ground."""
        if not self.keep_mode(ctx):
            return Status.FAILED
        vehicle = ctx.vehicle
        if vehicle is None or is_airborne(ctx.autopilot, vehicle):
            return Status.RUNNING
        return Status.DONE
