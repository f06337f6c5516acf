"""A simulated camera payload: answers capture requests as the thesis's Raspberry Pi camera did.

The thesis's Anaconda carried a Raspberry Pi 2 with a 5 MP camera, connected
to the mission computer over TCP and answering in ASCII strings (4.1.4); the
mission asked it for a picture every five seconds and it reported each image
once saved (5.3.2). :class:`SimCamera` is that payload behind the same typed
interface the real adapter gives the runtime: a capture request in, a
:class:`~clark_engine.runtime.events.PayloadEvent` out some time later.

Like the radio mesh it is pure: the simulator hands it requests with their
times, asks when its next answer is due (:meth:`SimCamera.next_event_s`) and
collects answers (:meth:`SimCamera.events_until`).

Timing (the profile's figures are estimates; the thesis did not measure them):

- Accepted request: reported ``captured`` ``capture_delay_s`` after the
  request, plus a jitter drawn uniformly from ``[0, jitter_s]`` when
  ``jitter_s > 0`` (never earlier than the profile's delay). ``detail`` is the
  image file name, ``IMG_0001.jpg``, ``IMG_0002.jpg``, ..., numbered in the
  order the images are saved (completion order), as a camera names its files.
- A request sooner than ``min_interval_s`` after the previous ACCEPTED one is
  ``refused`` after ``response_delay_s`` (the Pi's processing time); refused
  and failed requests do not restart the interval.
- Failure windows (:meth:`SimCamera.fail`): a request inside one is answered
  ``error`` after ``response_delay_s``; a capture accepted earlier that would
  complete inside one is reported ``error`` at its completion time instead of
  ``captured`` (it still counted as accepted for the interval).

Determinism: the camera draws from its ``random.Random`` only for accepted
requests and only when ``jitter_s > 0``, one ``uniform`` each, in request
order. Answers come out in time order; equal times in request order.
"""

from __future__ import annotations

import heapq
import math
import random
from collections.abc import Mapping
from dataclasses import dataclass, field, replace
from typing import Any

from clark_engine.runtime.commands import PayloadCommand
from clark_engine.runtime.events import PayloadEvent

#: Time the camera takes to answer a request it refuses or cannot serve, in seconds.
DEFAULT_RESPONSE_DELAY_S = 0.05


@dataclass(slots=True)
class CameraStats:
    """What the camera did.

    Attributes:
        requests: Capture requests received.
        accepted: Requests that started a capture.
        captured: Images reported saved.
        refused: Requests refused as too soon after the previous accepted one.
        errors: Requests answered ``error`` (failure window or unsupported action), and
            captures that failed before completing.
    """

    requests: int = 0
    accepted: int = 0
    captured: int = 0
    refused: int = 0
    errors: int = 0


@dataclass(order=True, slots=True)
class _Answer:
    at_s: float
    sequence: int
    request_id: int = field(compare=False)
    kind: str = field(compare=False)
    detail: str = field(compare=False, default="")


def _number(profile: Mapping[str, Any], key: str) -> float:
    value = profile.get(key)
    if isinstance(value, bool) or not isinstance(value, int | float):
        raise ValueError(f"camera profile: {key} must be a number, got {value!r}")
    number = float(value)
    if number < 0 or not math.isfinite(number):
        raise ValueError(f"camera profile: {key} must be >= 0, got {number}")
    return number


class SimCamera:
    """One simulated camera on one agent.

    Args:
        name: The payload's name on its agent (``camera``); echoed in every event.
        profile: The composed payload profile: ``min_interval_s`` and
            ``capture_delay_s`` (required), ``resolution_mp`` (optional, kept for reports).
        rng: Seeded random source for the jitter; required when ``jitter_s > 0``.
        jitter_s: Largest extra delay added to a capture (uniform in [0, jitter_s]).
        response_delay_s: Delay before a refusal or an error is reported.

    Raises:
        ValueError: A profile field missing or invalid, a negative delay, or jitter
            without a random source.
    """

    def __init__(
        self,
        name: str,
        profile: Mapping[str, Any],
        rng: random.Random | None = None,
        *,
        jitter_s: float = 0.0,
        response_delay_s: float = DEFAULT_RESPONSE_DELAY_S,
    ) -> None:
        if not name:
            raise ValueError("camera name must not be empty")
        self.name = name
        self.min_interval_s = _number(profile, "min_interval_s")
        self.capture_delay_s = _number(profile, "capture_delay_s")
        resolution = profile.get("resolution_mp")
        self.resolution_mp: float | None = (
            None if resolution is None else _number(profile, "resolution_mp")
        )
        if not jitter_s >= 0 or not math.isfinite(jitter_s):
            raise ValueError(f"jitter_s must be >= 0, got {jitter_s}")
        if jitter_s > 0 and rng is None:
            raise ValueError("a camera with jitter needs a seeded random source (rng)")
        if not response_delay_s >= 0 or not math.isfinite(response_delay_s):
            raise ValueError(f"response_delay_s must be >= 0, got {response_delay_s}")
        self.jitter_s = jitter_s
        self.response_delay_s = response_delay_s
        self._rng = rng
        self._answers: list[_Answer] = []
        self._sequence = 0
        self._last_accepted_s: float | None = None
        self._last_request_s = -math.inf
        self._images = 0
        self._failures: list[tuple[float, float]] = []
        self._stats = CameraStats()

    def fail(self, from_s: float, to_s: float = math.inf) -> None:
        """Fail in [from_s, to_s): requests and captures completing then get ``error``."""
        if math.isnan(from_s) or math.isnan(to_s) or to_s < from_s:
            raise ValueError(f"failure window must have from_s <= to_s, got [{from_s}, {to_s})")
        self._failures.append((from_s, to_s))

    def request(self, request_id: int, now_s: float) -> None:
        """Ask for one picture at ``now_s``; the answer comes later through :meth:`events_until`.

        Raises:
            ValueError: ``now_s`` earlier than a previous request.
        """
        self._check_time(now_s)
        self._stats.requests += 1
        if self._failed(now_s):
            self._answer(now_s + self.response_delay_s, request_id, "error", "camera failure")
            return
        if self._last_accepted_s is not None:
            since_s = now_s - self._last_accepted_s
            if since_s < self.min_interval_s:
                self._answer(
                    now_s + self.response_delay_s,
                    request_id,
                    "refused",
                    f"too soon: {since_s:.3f} s after the last capture, "
                    f"minimum {self.min_interval_s:g} s",
                )
                return
        self._last_accepted_s = now_s
        self._stats.accepted += 1
        delay_s = self.capture_delay_s
        if self.jitter_s > 0:
            assert self._rng is not None  # checked in __init__
            delay_s += self._rng.uniform(0.0, self.jitter_s)
        self._answer(now_s + delay_s, request_id, "captured")

    def command(self, command: PayloadCommand, now_s: float) -> None:
        """Serve a runtime :class:`PayloadCommand`: ``capture`` requests a picture.

        Any other action is answered ``error`` after ``response_delay_s``, as a payload
        answers a string it does not understand.

        Raises:
            ValueError: The command names another payload, or time went back.
        """
        if command.payload != self.name:
            raise ValueError(f"command for payload {command.payload!r} sent to {self.name!r}")
        if command.action == "capture":
            self.request(command.request_id, now_s)
            return
        self._check_time(now_s)
        self._stats.requests += 1
        self._answer(
            now_s + self.response_delay_s,
            command.request_id,
            "error",
            f"unsupported action {command.action!r}",
        )

    def next_event_s(self) -> float | None:
        """Time of the next answer, None when nothing is pending."""
        return self._answers[0].at_s if self._answers else None

    def events_until(self, t_s: float) -> list[tuple[float, PayloadEvent]]:
        """Every answer due at or before ``t_s``, in time order, with its time."""
        events: list[tuple[float, PayloadEvent]] = []
        while self._answers and self._answers[0].at_s <= t_s:
            answer = heapq.heappop(self._answers)
            kind, detail = answer.kind, answer.detail
            if kind == "captured" and self._failed(answer.at_s):
                kind, detail = "error", "camera failure during capture"
            if kind == "captured":
                self._images += 1
                detail = f"IMG_{self._images:04d}.jpg"
                self._stats.captured += 1
            elif kind == "refused":
                self._stats.refused += 1
            else:
                self._stats.errors += 1
            events.append((answer.at_s, PayloadEvent(self.name, kind, answer.request_id, detail)))
        return events

    @property
    def pending(self) -> int:
        """Answers not yet reported."""
        return len(self._answers)

    @property
    def stats(self) -> CameraStats:
        """A copy of the counts; answers count when reported, requests when received."""
        return replace(self._stats)

    def _check_time(self, now_s: float) -> None:
        if math.isnan(now_s) or now_s < self._last_request_s:
            raise ValueError(
                f"time went back: request at {now_s} s after one at {self._last_request_s} s"
            )
        self._last_request_s = now_s

    def _failed(self, t_s: float) -> bool:
        return any(from_s <= t_s < to_s for from_s, to_s in self._failures)

    def _answer(self, at_s: float, request_id: int, kind: str, detail: str = "") -> None:
        heapq.heappush(self._answers, _Answer(at_s, self._sequence, request_id, kind, detail))
        self._sequence += 1
