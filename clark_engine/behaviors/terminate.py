"""terminate: end this agent's part in the mission.

The agent stops commanding, puts its vehicle in its terminal mode (the
profile's, or ``mode`` here), closes its interfaces and flushes its logs
(thesis 7.3.5). Nothing follows it.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import TYPE_CHECKING, Any

from clark_engine.behaviors.base import BehaviorRuntime, Status
from clark_engine.behaviors.declaration import Behavior, Params, Traits, param, raises_nothing
from clark_engine.behaviors.shared import check_mode
from clark_engine.mission.schema_source.common import string

if TYPE_CHECKING:
    from clark_engine.runtime.context import PrimitiveContext


class TerminateParams(Params):
    """Parameters of terminate."""

    DESCRIPTION = "Parameters of terminate."

    mode: str | None = param(
        string("Mode to leave the vehicle in; the agent's terminal_mode when omitted.")
    )


class TerminateBehavior(BehaviorRuntime):
    """What terminate commands in flight, tick by tick (its section of docs/runtime.md).

    End this agent's part in the mission. `start` asks the runtime to terminate, with the
    `mode` parameter or the agent's configured terminal mode; the runtime does it at the end
    of that tick's machine phase ([Safety](#safety)). The primitive itself commands nothing.

    Attributes:
        mode: Mode to leave the vehicle in, None for the agent's terminal mode.
    """

    name = "terminate"
    params_type = TerminateParams
    params: TerminateParams

    def __init__(self, params: TerminateParams | Mapping[str, Any]) -> None:
        super().__init__(params)
        mode = self.params.mode
        self.mode = str(mode) if mode is not None else None

    def start(self, ctx: PrimitiveContext) -> None:
        """Request termination."""
        ctx.request_terminate(self.mode)

    def update(self, ctx: PrimitiveContext) -> Status:
        """RUNNING: the runtime ends the agent; nothing follows."""
        return Status.RUNNING


BEHAVIOR = Behavior(
    name="terminate",
    summary="Stop commanding, switch to the terminal mode, close interfaces and flush logs.",
    parameters=TerminateParams,
    runtime=TerminateBehavior,
    events=raises_nothing,
    traits=Traits(lands=True),
    check=check_mode,
)
