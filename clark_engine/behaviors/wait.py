"""wait: do nothing, for a while or until an event.

With ``duration_s`` it finishes after that time; without, it waits for a
transition's event (e.g. the station's ``activate``). It commands nothing, so a
pilot keeps flying the vehicle meanwhile. The station may use it too.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import TYPE_CHECKING, Any

from clark_engine.behaviors.base import BehaviorRuntime, Status
from clark_engine.behaviors.declaration import Behavior, Params, Traits, param
from clark_engine.behaviors.flight import TIME_EPSILON_S
from clark_engine.mission.schema_source.common import number

if TYPE_CHECKING:
    from clark_engine.runtime.context import PrimitiveContext


class WaitParams(Params):
    """Parameters of wait."""

    DESCRIPTION = "Parameters of wait."

    duration_s: float | None = param(
        number(
            "How long to wait; until an event when omitted.",
            unit="s",
            exclusive_minimum=0,
            maximum=86400,
        )
    )


def _events(params: Mapping[str, Any]) -> frozenset[str]:
    return frozenset({"done"}) if params.get("duration_s") is not None else frozenset()


class WaitBehavior(BehaviorRuntime):
    """What wait commands in flight, tick by tick (its section of docs/runtime.md).

    Command nothing. With `duration_s`, DONE at the first `update` at least that long after
    `start` on the runtime clock; without, RUNNING until a transition leaves the state. A
    pilot keeps flying meanwhile (the Super Cub's `piloted` state). Stations may use it too.

    Attributes:
        duration_s: How long to wait, None to wait for an event.
    """

    name = "wait"
    params_type = WaitParams
    params: WaitParams

    def __init__(self, params: WaitParams | Mapping[str, Any]) -> None:
        super().__init__(params)
        duration = self.params.duration_s
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


BEHAVIOR = Behavior(
    name="wait",
    summary="Command nothing; done after duration_s, or wait for an event when omitted.",
    parameters=WaitParams,
    runtime=WaitBehavior,
    events=_events,
    needs_autopilot=False,
    traits=Traits(stays_put_on_ground=True),
)
