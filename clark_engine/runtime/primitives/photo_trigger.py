"""photo_trigger: ask a camera for a picture every ``interval_s``; send Picture Data on each.

The thesis's Anaconda asked its Raspberry Pi camera for a picture every five
seconds and sent a Picture Data message whenever the camera reported one
(thesis 5.3.2). Runtime semantics (the declaration is
:mod:`clark_engine.mission.primitives.photo_trigger`):

- Requests: PayloadCommand(payload, "capture", ctx.next_request_id()) at
  ``start`` and then every ``interval_s`` on the runtime clock, on a fixed
  schedule from the start (no drift; a late tick sends one request, not a burst).
  Requests go out whether or not a vehicle state is known: the picture is worth
  taking either way.
- Answers (``on_payload``): only events from this payload answering one of this
  state's own requests count (another photo_trigger may share the camera).
  ``captured``: the picture counts, and Picture Data is sent to ``to`` (every
  agent when empty) with this agent's id, ``ctx.gps_time_ms`` (0, proto3's
  "unset", before the autopilot gave a time), the vehicle's position at that
  moment and ``image_index``. ``refused`` and ``error`` are counted and logged;
  no message is sent.
- ``image_index`` is 1 for the first picture taken since the state was entered
  and counts up by one per captured picture. The machine builds a fresh
  primitive on every entry, so a state entered again starts again at 1; a
  picture is identified by the sender's agent id and its GPS time.
- No vehicle state when a capture is reported: the picture still counts, but no
  Picture Data is sent (logged as a warning). A message with a made-up position
  would put a picture on the station's map where it was not taken; a missing
  one shows as a gap in ``image_index``.
- DONE at the first ``update`` after ``count`` pictures of this entry into the
  state were captured, when ``count`` is given; RUNNING forever otherwise.
  A request answered so late that :data:`MAX_PENDING_REQUESTS` newer ones were
  sent meanwhile is forgotten and its answer ignored, keeping memory bounded
  when a camera stops answering.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

from clark_engine.link.messages import PictureData
from clark_engine.runtime.commands import PayloadCommand
from clark_engine.runtime.context import PrimitiveContext, Status
from clark_engine.runtime.events import PayloadEvent
from clark_engine.runtime.log_events import LogEvent
from clark_engine.runtime.primitives._shared import Schedule
from clark_engine.runtime.primitives.base import Primitive

#: Unanswered requests remembered; older ones are forgotten.
MAX_PENDING_REQUESTS = 64


class PhotoTrigger(Primitive):
    """Periodic capture requests and Picture Data for the pictures taken.

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

    def __init__(self, params: Mapping[str, Any]) -> None:
        super().__init__(params)
        self.payload = str(params.get("payload", "camera"))
        self.interval_s = float(params["interval_s"])
        count = params.get("count")
        self.count = int(count) if count is not None else None
        self.to = tuple(str(name) for name in params.get("to") or ())
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
        self._request(ctx)

    def update(self, ctx: PrimitiveContext) -> Status:
        """DONE after ``count`` pictures; otherwise request a picture when one is due."""
        if self.count is not None and self.captured >= self.count:
            return Status.DONE
        if self._schedule.due(ctx.now_s):
            self._request(ctx)
        return Status.RUNNING

    def on_payload(self, ctx: PrimitiveContext, event: PayloadEvent) -> None:
        """Count the camera's answer to one of our requests; send Picture Data on a capture."""
        if event.payload != self.payload or event.request_id not in self._pending:
            return
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

    def _request(self, ctx: PrimitiveContext) -> None:
        request_id = ctx.next_request_id()
        self._pending[request_id] = None
        while len(self._pending) > MAX_PENDING_REQUESTS:
            del self._pending[next(iter(self._pending))]
        ctx.command(PayloadCommand(self.payload, "capture", request_id))
