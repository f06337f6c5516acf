"""terminate: end this agent's part in the mission.

Runtime semantics (the declaration is :mod:`clark_engine.mission.primitives.terminate`):
``start`` calls ``ctx.request_terminate(mode)`` with the ``mode`` parameter, or
None for the agent's configured terminal mode. The runtime carries the rest out
at the end of that call (stop commanding, terminal mode, close the interfaces,
flush the logs: thesis 7.3.5), so the primitive itself commands nothing and
``update`` stays RUNNING: nothing follows a terminate.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

from clark_engine.runtime.context import PrimitiveContext, Status
from clark_engine.runtime.primitives.base import Primitive


class Terminate(Primitive):
    """Ask the runtime to terminate this agent.

    Attributes:
        mode: Mode to leave the vehicle in, None for the agent's terminal mode.
    """

    name = "terminate"

    def __init__(self, params: Mapping[str, Any]) -> None:
        super().__init__(params)
        mode = params.get("mode")
        self.mode = str(mode) if mode is not None else None

    def start(self, ctx: PrimitiveContext) -> None:
        """Request termination."""
        ctx.request_terminate(self.mode)

    def update(self, ctx: PrimitiveContext) -> Status:
        """RUNNING: the runtime ends the agent; nothing follows."""
        return Status.RUNNING
