"""set_mode: put the autopilot in a flight mode; done once the autopilot reports it.

As the thesis's ground tests switched the Slash between MANUAL and AUTO (thesis
5.2). Runtime semantics (the declaration is
:mod:`clark_engine.mission.primitives.set_mode`):

- ``start``: SetMode(mode), always (a stale report of the mode proves nothing).
- ``update``: DONE once the vehicle's reported mode is ``mode``. Until then
  RUNNING, and SetMode is sent again when at least
  :data:`RESEND_INTERVAL_S` has passed since the last one: a SET_MODE can be lost
  on the link or refused by the autopilot (a pre-arm check, a mode not allowed
  yet), and once a second keeps the link quiet while the autopilot's heartbeat
  (1 Hz or faster) has had time to confirm. No vehicle state yet counts as not
  confirmed.
- Nothing ends the attempts but the confirmation or a transition: put a
  ``timeout_s`` on the state when the mode might never be granted.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

from clark_engine.runtime.context import PrimitiveContext, Status
from clark_engine.runtime.primitives._shared import TIME_EPSILON_S, mode_command, reported_mode
from clark_engine.runtime.primitives.base import Primitive

#: Shortest time between two SetMode commands while the mode is not confirmed.
RESEND_INTERVAL_S = 1.0


class SetModePrimitive(Primitive):
    """Change the flight mode and wait for the autopilot to confirm it.

    Attributes:
        mode: The mode's name in the agent's autopilot firmware.
    """

    name = "set_mode"

    def __init__(self, params: Mapping[str, Any]) -> None:
        super().__init__(params)
        self.mode = str(params["mode"])
        self._last_sent_s = 0.0

    def start(self, ctx: PrimitiveContext) -> None:
        """Ask for the mode."""
        self._send(ctx)

    def update(self, ctx: PrimitiveContext) -> Status:
        """DONE when reported; re-ask at most once a second until then."""
        if reported_mode(ctx) == self.mode:
            return Status.DONE
        if ctx.now_s - self._last_sent_s + TIME_EPSILON_S >= RESEND_INTERVAL_S:
            self._send(ctx)
        return Status.RUNNING

    def _send(self, ctx: PrimitiveContext) -> None:
        self._last_sent_s = ctx.now_s
        ctx.command(mode_command(ctx, self.mode))
