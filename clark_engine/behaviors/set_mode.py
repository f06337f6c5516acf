"""set_mode: put the autopilot in a flight mode; done once the autopilot reports it.

The mode is checked against the modes of the agent's autopilot firmware
(thesis 5.2: the Slash switched from MANUAL to AUTO and back).
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import TYPE_CHECKING, Any

from clark_engine.behaviors.base import BehaviorRuntime, Status
from clark_engine.behaviors.declaration import Behavior, Params, param, raises_done
from clark_engine.behaviors.flight import TIME_EPSILON_S, mode_command, reported_mode
from clark_engine.behaviors.shared import check_mode
from clark_engine.mission.schema_source.common import string

if TYPE_CHECKING:
    from clark_engine.runtime.context import PrimitiveContext


class SetModeParams(Params):
    """Parameters of set_mode."""

    DESCRIPTION = "Parameters of set_mode."
    REQUIRED = ("mode",)

    mode: str = param(string("Flight mode name of the agent's autopilot firmware (e.g. AUTO)."))


#: Shortest time between two SetMode commands while the mode is not confirmed.
RESEND_INTERVAL_S = 1.0


class SetModeBehavior(BehaviorRuntime):
    """What set_mode commands in flight, tick by tick (its section of docs/runtime.md).

    Put the autopilot in a mode; done once it reports it. `start` sends `SetMode(mode)`;
    `update` is DONE once the reported mode is `mode`, and until then re-sends `SetMode` when
    at least 1 s has passed since the last one (a SET_MODE can be lost or refused). Nothing
    but the confirmation or a transition ends the attempts: put a `timeout_s` on the state
    when the mode might never be granted.

    Attributes:
        mode: The mode's name in the agent's autopilot firmware.
    """

    name = "set_mode"
    params_type = SetModeParams
    params: SetModeParams

    def __init__(self, params: SetModeParams | Mapping[str, Any]) -> None:
        super().__init__(params)
        self.mode = self.params.mode
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


BEHAVIOR = Behavior(
    name="set_mode",
    summary="Set the autopilot's flight mode; done when the autopilot reports it.",
    parameters=SetModeParams,
    runtime=SetModeBehavior,
    events=raises_done,
    check=check_mode,
)
