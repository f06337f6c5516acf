"""wait: command nothing, for ``duration_s`` or until a transition's event.

Runtime semantics (the declaration is :mod:`clark_engine.mission.primitives.wait`):
it never issues a command, so a pilot keeps flying meanwhile (thesis 5.3.3: the
Cub was flown by its pilot until the station's Activate Controller). With
``duration_s`` it is DONE at the first ``update`` at least that long after
``start`` on the runtime clock; without, RUNNING until a transition leaves the
state. Stations may use it too.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

from clark_engine.runtime.context import PrimitiveContext, Status
from clark_engine.runtime.primitives._shared import TIME_EPSILON_S
from clark_engine.runtime.primitives.base import Primitive


class Wait(Primitive):
    """Do nothing for a while.

    Attributes:
        duration_s: How long to wait, None to wait for an event.
    """

    name = "wait"

    def __init__(self, params: Mapping[str, Any]) -> None:
        super().__init__(params)
        duration = params.get("duration_s")
        self.duration_s = float(duration) if duration is not None else None
        self._started_s = 0.0

    def start(self, ctx: PrimitiveContext) -> None:
        """Note the time the wait began."""
        self._started_s = ctx.now_s

    def update(self, ctx: PrimitiveContext) -> Status:
        """DONE once ``duration_s`` has passed; RUNNING forever without one."""
        if self.duration_s is None:
            return Status.RUNNING
        if ctx.now_s - self._started_s + TIME_EPSILON_S >= self.duration_s:
            return Status.DONE
        return Status.RUNNING
