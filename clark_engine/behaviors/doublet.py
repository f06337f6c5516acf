"""doublet: a control-surface doublet, the classic system-identification input.

Trim + amplitude for ``width_s``, trim - amplitude for ``width_s``, back to trim
(thesis 5.3.3, figure 5.13). The channel is named (``aileron``) and resolved
through each airframe's profile, so one block serves a Super Cub and an
Anaconda. The runtime samples the shape once per tick, so each half must span
at least two ticks to exist at all.
"""

from __future__ import annotations

from collections.abc import Iterator, Mapping
from typing import TYPE_CHECKING, Any

from clark_engine.behaviors.base import ChannelMap, Status
from clark_engine.behaviors.declaration import (
    Behavior,
    Params,
    Traits,
    UseContext,
    param,
    raises_done,
)
from clark_engine.behaviors.flight import ChannelExcitation, ChannelOutput
from clark_engine.behaviors.shared import (
    CHANNEL_SCHEMA,
    VIA_SCHEMA,
    check_channel_swing,
    compile_channel,
    resolved_channel_schema,
)
from clark_engine.mission.findings import Finding, error
from clark_engine.mission.schema_source.common import number, string

if TYPE_CHECKING:
    from clark_engine.runtime.context import PrimitiveContext


class DoubletParams(Params):
    """Parameters of doublet."""

    DESCRIPTION = "Parameters of doublet."
    REQUIRED = ("channel", "amplitude_us", "width_s")

    channel: ChannelMap = param(
        CHANNEL_SCHEMA, compiled=resolved_channel_schema, convert=ChannelMap.from_config
    )
    amplitude_us: float = param(
        number(
            "Pulse-width step either side of the channel's trim.",
            unit="us",
            exclusive_minimum=0,
            maximum=1000,
        )
    )
    width_s: float = param(
        number(
            "Duration of each half of the doublet.",
            unit="s",
            exclusive_minimum=0,
            maximum=60,
        )
    )
    first: str = param(
        string(
            "Direction of the first half: up (trim + amplitude) or down.",
            enum=["up", "down"],
            default="up",
        )
    )
    via: str = param(VIA_SCHEMA)


MIN_TICKS_PER_HALF = 2


def _check(ctx: UseContext) -> Iterator[Finding]:
    width_s = float(ctx.params["width_s"])
    ticks = width_s * ctx.mission.loop_hz
    if ticks < MIN_TICKS_PER_HALF:
        needed = MIN_TICKS_PER_HALF / ctx.mission.loop_hz
        yield error(
            "E-DOUBLET-WIDTH",
            ctx.locate("width_s"),
            f"width_s {width_s:g} s spans {ticks:g} tick{'' if ticks == 1 else 's'} at loop_hz "
            f"{ctx.mission.loop_hz:g}; "
            f"each half must span at least {MIN_TICKS_PER_HALF} ticks, so make it at least "
            f"{needed:g} s or raise mission.loop_hz",
            ctx.use_location,
        )
    yield from check_channel_swing(ctx)


def _signal(params: DoubletParams, loop_hz: float) -> list[int]:
    """Trim + amplitude for n ticks, trim - amplitude for n ticks, then trim (clamped)."""
    channel = params.channel
    trim, low, high = channel.pwm_trim_us, channel.pwm_min_us, channel.pwm_max_us

    def clamp(value: float) -> int:
        return int(min(max(round(value), low), high))

    amplitude = float(params.amplitude_us)
    n = round(float(params.width_s) * loop_hz)
    sign = 1 if params.first == "up" else -1
    return [clamp(trim + sign * amplitude)] * n + [clamp(trim - sign * amplitude)] * n + [int(trim)]


class DoubletBehavior(ChannelExcitation):
    """What doublet commands in flight, tick by tick (its section of docs/runtime.md).

    Trim + amplitude for `width_s`, trim - amplitude for `width_s`, back to trim (thesis 5.3.3).

    - Ticks count from the first `update` after `start` (tick 0); `start` commands nothing.
      Each half lasts `n = round(width_s * loop_hz)` ticks (at least 1; the mission layer
      guarantees 2).
    - Ticks 0 to n-1: trim + amplitude (`first: up`) or trim - amplitude (`down`); ticks n to
      2n-1: the opposite; tick 2n: trim, then the channel is handed back and the doublet is
      DONE in that tick.
    - Every tick's width is sent, not only changes (an RC override lapses unless refreshed):
      `RcOverride({rc: pwm})` for `via: rc_override`, `SetServo(servo, pwm)` for
      `via: servo`; whole microseconds, clamped to the channel's limits.
    - Handing back: for rc_override, trim is followed by `RcOverride({rc: 0})`, which releases
      the channel to the pilot's stick; a servo output is left at trim.
    - `stop` before the end (a timeout, a deactivate, terminate, a failsafe) sends the same
      trim and release, so an interrupted doublet never leaves a surface deflected or the
      pilot locked out.

    Attributes:
        channel: The channel driven and how.
        amplitude_us: Step either side of trim.
        width_s: Duration of each half.
        first_up: True when the first half is trim + amplitude.
    """

    name = "doublet"
    params_type = DoubletParams
    params: DoubletParams

    def __init__(self, params: DoubletParams | Mapping[str, Any]) -> None:
        super().__init__(params)
        self.channel = ChannelOutput.of(self.params.channel, self.params.via)
        self.amplitude_us = float(self.params.amplitude_us)
        self.width_s = float(self.params.width_s)
        self.first_up = self.params.first == "up"
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


BEHAVIOR = Behavior(
    name="doublet",
    summary="Trim+amplitude for width_s, trim-amplitude for width_s, back to trim; then done.",
    parameters=DoubletParams,
    runtime=DoubletBehavior,
    events=raises_done,
    traits=Traits(flies=True, drives_channel=True),
    check=_check,
    compile=compile_channel,
    signal=_signal,
)
