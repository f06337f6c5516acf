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

from collections.abc import Mapping
from typing import Any

from clark_engine.runtime.context import PrimitiveContext, Status
from clark_engine.runtime.launch import is_airborne
from clark_engine.runtime.primitives._shared import ModeRequest
from clark_engine.runtime.primitives.base import Primitive


class Land(Primitive):
    """Land in the autopilot's land mode."""

    name = "land"

    _failed = False

    def __init__(self, params: Mapping[str, Any]) -> None:
        super().__init__(params)
        self._mode = ModeRequest()

    def start(self, ctx: PrimitiveContext) -> None:
        """Switch to the land mode."""
        mode = ctx.config.land_mode
        self._failed = mode is None
        if mode is None:
            ctx.log.error("%s: the autopilot profile names no land_mode", ctx.config.agent)
            return
        self._mode.begin(ctx, mode)

    def update(self, ctx: PrimitiveContext) -> Status:
        """DONE on the ground."""
        if self._failed:
            return Status.FAILED
        self._mode.update(ctx)
        vehicle = ctx.vehicle
        if vehicle is None or is_airborne(ctx.autopilot, vehicle):
            return Status.RUNNING
        return Status.DONE
