"""photo_trigger: ask a camera payload for a picture every ``interval_s``.

When the camera confirms a capture the agent sends Picture Data with the
position of capture (thesis 5.3.2: the Anaconda photographed every 5 s). Runs
alongside a flight behaviour in a parallel region; done after ``count``
pictures when a count is given.
"""

from __future__ import annotations

from collections.abc import Iterator, Mapping
from typing import TYPE_CHECKING, Any

from clark_engine.behaviors.base import BehaviorRuntime, Status
from clark_engine.behaviors.declaration import (
    Behavior,
    CompileContext,
    Params,
    Sends,
    Traits,
    UseContext,
    param,
)
from clark_engine.behaviors.flight import Schedule
from clark_engine.behaviors.shared import AGENT_NAME_SCHEMA, check_agents_exist, suggest
from clark_engine.mission.findings import Finding, error
from clark_engine.mission.schema_source.common import array, number, string
from clark_engine.mission.schema_source.common import count as count_schema

if TYPE_CHECKING:
    from clark_engine.runtime.context import PrimitiveContext
    from clark_engine.runtime.events import PayloadEvent


class PhotoTriggerParams(Params):
    """Parameters of photo_trigger."""

    DESCRIPTION = "Parameters of photo_trigger."
    REQUIRED = ("interval_s",)

    payload: str = param(
        string(
            "Name of the camera payload on this agent.",
            pattern="^[a-z][a-z0-9_]*$",
            default="camera",
        )
    )
    interval_s: float = param(
        number("Time between capture requests.", unit="s", exclusive_minimum=0, maximum=3600)
    )
    count: int | None = param(
        count_schema("Pictures to take before finishing; unlimited when omitted.", minimum=1)
    )
    to: tuple[str, ...] | None = param(
        array("Agents that receive Picture Data; every agent when omitted.", AGENT_NAME_SCHEMA),
        convert=tuple,
    )


def _events(params: Mapping[str, Any]) -> frozenset[str]:
    return frozenset({"done"}) if params.get("count") is not None else frozenset()


def _check(ctx: UseContext) -> Iterator[Finding]:
    name = str(ctx.params["payload"])
    payloads = ctx.agent.hardware.payloads
    interval = float(ctx.params["interval_s"])
    yield from check_agents_exist(ctx, ctx.params.get("to") or [], "to")
    if name not in payloads:
        yield error(
            "E-PAYLOAD-MISSING",
            ctx.locate("payload"),
            f"agent {ctx.agent.name!r} ({ctx.agent.profile}) has no payload {name!r} "
            f"({suggest(name, payloads)}); add a camera under its hardware.payloads",
            ctx.use_location,
        )
        return
    payload = payloads[name]
    if payload.get("payload_kind") != "camera":
        yield error(
            "E-PAYLOAD-KIND",
            ctx.locate("payload"),
            f"payload {name!r} of {ctx.agent.name!r} is a {payload.get('payload_kind')}, "
            "not a camera; name a camera payload",
            ctx.use_location,
        )
        return
    min_interval = float(payload.get("min_interval_s", 0))
    if interval < min_interval:
        yield error(
            "E-PHOTO-INTERVAL",
            ctx.locate("interval_s"),
            f"interval_s {interval:g} s is shorter than the minimum of camera {name!r}, "
            f"{min_interval:g} s between captures; take pictures at most every {min_interval:g} s",
            ctx.use_location,
        )
    tick_s = 1.0 / ctx.mission.loop_hz
    if interval < tick_s:
        yield error(
            "E-PHOTO-INTERVAL",
            ctx.locate("interval_s"),
            f"interval_s {interval:g} s is shorter than one tick ({tick_s:g} s at loop_hz "
            f"{ctx.mission.loop_hz:g}); make it at least {tick_s:g} s",
            ctx.use_location,
        )


def _compile(params: dict[str, Any], _ctx: CompileContext) -> dict[str, Any]:
    params.setdefault("to", [])
    return params


#: Unanswered requests remembered; older ones are forgotten.
MAX_PENDING_REQUESTS = 64


class PhotoTriggerBehavior(BehaviorRuntime):
    """What photo_trigger commands in flight, tick by tick (its section of docs/runtime.md).

    Ask a camera for a picture every `interval_s`; send Picture Data on each (thesis 5.3.2).

    - Requests: `PayloadCommand(payload, "capture", request_id)` at `start` and then every
      `interval_s` on the runtime clock, on a fixed schedule from the start (a late tick sends
      one request, not a burst), whether or not a vehicle state is known.
    - Answers (`on_payload`): only this payload's answers to this state's own requests count.
      `captured`: the picture counts, and Picture Data (this agent's id, the agent's GPS time,
      or 0 before it has one, the vehicle's position then, and `image_index`) is queued for
      `to` (every agent when empty) and sent in the tick's telemetry phase. `refused` and
      `error` are counted and logged.
    - `image_index` is 1 for the first picture taken since the state was entered.
    - No vehicle state when a capture is reported: the picture counts but no Picture Data is
      sent (a warning in the mission log), rather than one with a made-up position.
    - DONE at the first `update` after `count` captures, when `count` is given; RUNNING
      otherwise. A request not answered before 64 newer ones were sent is forgotten.

    Attributes:
        payload: The camera's payload name on this agent.
        interval_s: Time between capture requests.
        count: Pictures to take before DONE, None for unlimited.
        to: Agents that receive Picture Data; empty for every agent.
        captured: Pictures captured since the state was entered (the last image_index).
        refused: Requests the camera refused.
        errors: Requests that ended in a camera error.
    """

    name = "photo_trigger"
    params_type = PhotoTriggerParams
    params: PhotoTriggerParams

    def __init__(self, params: PhotoTriggerParams | Mapping[str, Any]) -> None:
        super().__init__(params)
        self.payload = self.params.payload
        self.interval_s = float(self.params.interval_s)
        count = self.params.count
        self.count = int(count) if count is not None else None
        self.to = tuple(str(name) for name in self.params.to or ())
        self.captured = 0
        self.refused = 0
        self.errors = 0
        self._pending: dict[int, None] = {}  # insertion-ordered set of request ids
        self._schedule = Schedule(self.interval_s)

    def start(self, ctx: PrimitiveContext) -> None:
        """Request the first picture now."""
        self.captured = self.refused = self.errors = 0
        self._pending.clear()
        self._schedule = Schedule(self.interval_s)
        self._schedule.begin(ctx.now_s)
        self.request(ctx)

    def update(self, ctx: PrimitiveContext) -> Status:
        """DONE after ``count`` pictures; otherwise request a picture when one is due."""
        if self.count is not None and self.captured >= self.count:
            return Status.DONE
        if self._schedule.due(ctx.now_s):
            self.request(ctx)
        return Status.RUNNING

    def on_payload(self, ctx: PrimitiveContext, event: PayloadEvent) -> None:
        """Count the camera's answer to one of our requests; send Picture Data on a capture."""
        if event.payload != self.payload or event.request_id not in self._pending:
            return
        from clark_engine.runtime.log_events import LogEvent

        del self._pending[event.request_id]
        agent = ctx.config.agent
        if event.kind == "captured":
            self.captured += 1
            vehicle = ctx.vehicle
            if vehicle is None:
                ctx.log.warning(
                    "%s: picture %d (%s) taken before any position from the autopilot; "
                    "no Picture Data sent",
                    agent,
                    self.captured,
                    event.detail,
                    extra=LogEvent.PHOTO_NO_POSITION.extra,
                )
                return
            from clark_engine.link.messages import PictureData

            picture = PictureData(
                agent_id=ctx.config.agent_id,
                gps_time_ms=ctx.gps_time_ms or 0,
                lat_deg=vehicle.lat_deg,
                lon_deg=vehicle.lon_deg,
                alt_m=vehicle.alt_m,
                image_index=self.captured,
            )
            ctx.send(picture, to=self.to)
        elif event.kind == "refused":
            self.refused += 1
            ctx.log.info(
                "%s: %s refused capture %d",
                agent,
                self.payload,
                event.request_id,
                extra=LogEvent.PHOTO_REFUSED.extra,
            )
        else:
            self.errors += 1
            ctx.log.warning(
                "%s: %s failed capture %d (%s): %s",
                agent,
                self.payload,
                event.request_id,
                event.kind,
                event.detail,
                extra=LogEvent.PHOTO_FAILED.extra,
            )

    def request(self, ctx: PrimitiveContext) -> None:
        """Ask the camera for a picture now (survey asks through this at its photo marks)."""
        from clark_engine.runtime.commands import PayloadCommand

        request_id = ctx.next_request_id()
        self._pending[request_id] = None
        while len(self._pending) > MAX_PENDING_REQUESTS:
            del self._pending[next(iter(self._pending))]
        ctx.command(PayloadCommand(self.payload, "capture", request_id))


BEHAVIOR = Behavior(
    name="photo_trigger",
    summary="Request a picture every interval_s and send Picture Data on each capture.",
    parameters=PhotoTriggerParams,
    runtime=PhotoTriggerBehavior,
    events=_events,
    traits=Traits(takes_pictures=True),
    check=_check,
    compile=_compile,
    sends=lambda params, _agent: [
        Sends("picture_data", float(params["interval_s"]), tuple(params.get("to") or ()))
    ],
)
