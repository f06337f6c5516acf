"""doublet: trim + amplitude for ``width_s``, trim - amplitude for ``width_s``, back to trim.

The classic system-identification input, commanded by the framework rather than
a pilot so that it is repeatable (thesis 5.3.3, figure 5.13). Runtime semantics
(the declaration is :mod:`clark_engine.mission.primitives.doublet`):

- Ticks are counted from the first ``update`` after ``start`` (tick 0); ``start``
  commands nothing. Each half lasts ``n = round(width_s * loop_hz)`` ticks
  (Python's round; the mission layer guarantees n >= 2).
- Ticks 0 .. n-1: trim + amplitude (``first: up``) or trim - amplitude (``down``);
  ticks n .. 2n-1: the opposite; tick 2n: trim once, then the channel is handed
  back and the doublet is DONE in that same tick.
- Every tick's pulse width is sent, not only changes: an RC override lapses on
  the autopilot unless refreshed, and a sample per tick is what the log records.
  ``via: rc_override`` sends RcOverride({rc: pwm}), ``via: servo``
  SetServo(servo, pwm). Pulse widths are whole microseconds clamped to the
  channel's [pwm_min_us, pwm_max_us] (the mission layer already rejects an
  amplitude that would leave them).
- Handing back: for rc_override the trim tick is followed by RcOverride({rc: 0}),
  which releases the channel to the pilot's stick; a servo output is left at trim.
- ``stop`` before the end (a timeout, a terminate, an interrupting transition)
  sends the same trim and release, so an interrupted doublet never leaves a
  surface deflected or the pilot locked out.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

from clark_engine.runtime.context import PrimitiveContext, Status
from clark_engine.runtime.primitives._shared import ChannelOutput
from clark_engine.runtime.primitives.base import Primitive


class Doublet(Primitive):
    """A doublet on one control channel.

    Attributes:
        channel: The channel driven and how.
        amplitude_us: Step either side of trim.
        width_s: Duration of each half.
        first_up: True when the first half is trim + amplitude.
    """

    name = "doublet"

    def __init__(self, params: Mapping[str, Any]) -> None:
        super().__init__(params)
        self.channel = ChannelOutput.from_params(params)
        self.amplitude_us = float(params["amplitude_us"])
        self.width_s = float(params["width_s"])
        self.first_up = params.get("first", "up") == "up"
        self._tick = 0
        self._half_ticks = 0
        self._active = False

    def half_ticks(self, loop_hz: float) -> int:
        """Ticks in each half at a loop rate."""
        return max(1, round(self.width_s * loop_hz))

    def pwm_us(self, tick: int, loop_hz: float) -> int:
        """The pulse width commanded at a tick (0 = first update); trim from tick 2n on."""
        n = self.half_ticks(loop_hz)
        sign = 1.0 if self.first_up else -1.0
        if 0 <= tick < n:
            step = sign * self.amplitude_us
        elif n <= tick < 2 * n:
            step = -sign * self.amplitude_us
        else:
            step = 0.0
        return self.channel.clamp(self.channel.pwm_trim_us + step)

    def start(self, ctx: PrimitiveContext) -> None:
        """Arm the doublet; its first half starts at the next update."""
        self._tick = 0
        self._half_ticks = self.half_ticks(ctx.config.loop_hz)
        self._active = True

    def update(self, ctx: PrimitiveContext) -> Status:
        """Send this tick's pulse width; DONE after the trim tick."""
        if not self._active:
            return Status.DONE
        tick = self._tick
        self._tick += 1
        if tick < 2 * self._half_ticks:
            ctx.command(self.channel.drive(self.pwm_us(tick, ctx.config.loop_hz)))
            return Status.RUNNING
        self._finish(ctx)
        return Status.DONE

    def stop(self, ctx: PrimitiveContext) -> None:
        """Return the channel to trim and release it if the doublet was cut short."""
        if self._active:
            self._finish(ctx)

    def _finish(self, ctx: PrimitiveContext) -> None:
        self._active = False
        for command in self.channel.finish():
            ctx.command(command)
