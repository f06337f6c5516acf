"""sine_sweep: a frequency sweep (chirp) on one control channel.

The instantaneous frequency goes from ``f_start_hz`` to ``f_stop_hz`` over
``duration_s``, linearly or exponentially, with optional amplitude fades at
either end (thesis figure 5.14). The runtime samples it once per tick, so the
highest frequency must stay well under the Nyquist limit loop_hz / 2: 2 samples
per period or fewer cannot represent it (error: at exactly 2 a sine can come out
flat), fewer than 5 distorts it badly (warning).
"""

from __future__ import annotations

import math
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
from clark_engine.mission.findings import Finding, error, warning
from clark_engine.mission.schema_source.common import number, string, time_s

if TYPE_CHECKING:
    from clark_engine.runtime.context import PrimitiveContext


class SineSweepParams(Params):
    """Parameters of sine_sweep."""

    DESCRIPTION = "Parameters of sine_sweep."
    REQUIRED = ("channel", "amplitude_us", "f_start_hz", "f_stop_hz", "duration_s")

    channel: ChannelMap = param(
        CHANNEL_SCHEMA, compiled=resolved_channel_schema, convert=ChannelMap.from_config
    )
    amplitude_us: float = param(
        number(
            "Peak pulse-width deviation from the channel's trim.",
            unit="us",
            exclusive_minimum=0,
            maximum=1000,
        )
    )
    f_start_hz: float = param(
        number("Instantaneous frequency at the start.", unit="Hz", exclusive_minimum=0, maximum=100)
    )
    f_stop_hz: float = param(
        number("Instantaneous frequency at the end.", unit="Hz", exclusive_minimum=0, maximum=100)
    )
    duration_s: float = param(
        number("Length of the sweep.", unit="s", exclusive_minimum=0, maximum=3600)
    )
    law: str = param(
        string(
            "How frequency moves from start to stop: linear in time, or exponential "
            "(equal time per octave).",
            enum=["linear", "exponential"],
            default="linear",
        )
    )
    fade_in_s: float = param(
        time_s("Time over which the amplitude ramps up from zero.", maximum=3600, default=0)
    )
    fade_out_s: float = param(
        time_s("Time over which the amplitude ramps down to zero.", maximum=3600, default=0)
    )
    via: str = param(VIA_SCHEMA)


MIN_SAMPLES_PER_PERIOD = 2.0
GOOD_SAMPLES_PER_PERIOD = 5.0


def _check(ctx: UseContext) -> Iterator[Finding]:
    loop_hz = ctx.mission.loop_hz
    f_start, f_stop = float(ctx.params["f_start_hz"]), float(ctx.params["f_stop_hz"])
    f_max = max(f_start, f_stop)
    param = "f_stop_hz" if f_stop >= f_start else "f_start_hz"
    samples = loop_hz / f_max
    # At exactly 2 samples per period a sine is sampled at the same phases every period
    # (a 5 Hz sine at 10 Hz: always at its zero crossings) and comes out flat.
    if samples <= MIN_SAMPLES_PER_PERIOD * (1 + 1e-9):
        where = "at" if math.isclose(samples, MIN_SAMPLES_PER_PERIOD) else "above"
        yield error(
            "E-SWEEP-NYQUIST",
            ctx.locate(param),
            f"{f_max:g} Hz is {where} the Nyquist limit {loop_hz / 2:g} Hz of loop_hz {loop_hz:g} "
            f"({samples:.2g} samples per period); sweep below "
            f"{loop_hz / GOOD_SAMPLES_PER_PERIOD:g} Hz or raise mission.loop_hz",
            ctx.use_location,
        )
    elif samples < GOOD_SAMPLES_PER_PERIOD:
        yield warning(
            "W-SWEEP-SAMPLES",
            ctx.locate(param),
            f"{f_max:g} Hz gets only {samples:.2g} samples per period at loop_hz {loop_hz:g}; "
            f"the sweep will be distorted above {loop_hz / GOOD_SAMPLES_PER_PERIOD:g} Hz, lower "
            "it or raise mission.loop_hz",
            ctx.use_location,
        )
    duration = float(ctx.params["duration_s"])
    fades = float(ctx.params["fade_in_s"]) + float(ctx.params["fade_out_s"])
    if fades > duration:
        yield error(
            "E-SWEEP-FADE",
            ctx.locate("fade_in_s"),
            f"fade_in_s + fade_out_s = {fades:g} s is longer than duration_s {duration:g} s; "
            "shorten the fades",
            ctx.use_location,
        )
    yield from check_channel_swing(ctx)


def _waveform(params: SineSweepParams, t: float) -> float:
    """The intended sweep at ``t`` seconds into it: pulse width from trim, before clamping.

    The continuous waveform the behaviour stands for, not its samples; written from its
    definition, apart from the runtime class, so the dry run's checks compare the two.
    """
    amplitude = float(params.amplitude_us)
    f0, f1 = float(params.f_start_hz), float(params.f_stop_hz)
    duration = float(params.duration_s)
    fade_in, fade_out = float(params.fade_in_s), float(params.fade_out_s)
    if params.law == "exponential" and f1 != f0:
        ratio = f1 / f0
        phase = 2 * math.pi * f0 * duration * (ratio ** (t / duration) - 1) / math.log(ratio)
    else:
        phase = 2 * math.pi * (f0 * t + (f1 - f0) * t * t / (2 * duration))
    envelope = 1.0
    if fade_in > 0 and t < fade_in:
        envelope = t / fade_in
    if fade_out > 0 and t > duration - fade_out:
        envelope = min(envelope, (duration - t) / fade_out)
    return amplitude * envelope * math.sin(phase)


def _signal(params: SineSweepParams, loop_hz: float) -> list[int]:
    """The waveform sampled once a tick (clamped), then trim at duration_s."""
    channel = params.channel
    trim, low, high = channel.pwm_trim_us, channel.pwm_min_us, channel.pwm_max_us
    duration = float(params.duration_s)
    out = []
    k = 0
    while True:
        t = k / loop_hz
        if t >= duration - 1e-9:
            out.append(int(trim))
            return out
        out.append(int(min(max(round(trim + _waveform(params, t)), low), high)))
        k += 1


class SineSweepBehavior(ChannelExcitation):
    """What sine_sweep commands in flight, tick by tick (its section of docs/runtime.md).

    A frequency sweep (chirp) on one control channel (thesis 5.3.3), with f0 = `f_start_hz`,
    f1 = `f_stop_hz`, T = `duration_s`:

    - Frequency: `linear` f0 + (f1 - f0) t / T; `exponential` f0 (f1 / f0)^(t / T).
    - Phase: 2 pi times the integral of the frequency from 0, in closed form (no rounding
      accumulates): `linear` 2 pi (f0 t + (f1 - f0) t^2 / (2T)); `exponential`
      2 pi f0 T (r^(t/T) - 1) / ln r with r = f1 / f0. The phase is 0 at t = 0, so the sweep
      starts at trim.
    - Envelope: rises linearly from 0 over `fade_in_s` and falls to 0 over the last
      `fade_out_s`.
    - Tick k (k = 0 at the first `update`; `start` commands nothing) is at t = k / loop_hz.
      While t < T it sends `round(trim + amplitude_us * envelope(t) * sin(phase(t)))`,
      clamped, every tick (`RcOverride` or `SetServo` as for the doublet). At the first tick
      with t >= T it sends trim, hands the channel back as the doublet does, and is DONE.
    - `stop` before the end sends the same trim and release.

    Attributes:
        channel: The channel driven and how.
        amplitude_us: Peak deviation from trim.
        f_start_hz: Frequency at t = 0.
        f_stop_hz: Frequency at t = duration_s.
        duration_s: Length of the sweep.
        law: ``linear`` or ``exponential``.
        fade_in_s: Amplitude ramp-up time at the start.
        fade_out_s: Amplitude ramp-down time at the end.
    """

    name = "sine_sweep"
    params_type = SineSweepParams
    params: SineSweepParams

    def __init__(self, params: SineSweepParams | Mapping[str, Any]) -> None:
        super().__init__(params)
        p = self.params
        self.channel = ChannelOutput.of(p.channel, p.via)
        self.amplitude_us = float(p.amplitude_us)
        self.f_start_hz = float(p.f_start_hz)
        self.f_stop_hz = float(p.f_stop_hz)
        self.duration_s = float(p.duration_s)
        self.law = p.law
        self.fade_in_s = float(p.fade_in_s)
        self.fade_out_s = float(p.fade_out_s)
        self._ratio_log = math.log(self.f_stop_hz / self.f_start_hz)
        self._tick = 0
        self._active = False

    def frequency_hz(self, t_s: float) -> float:
        """The instantaneous frequency at time t since the sweep started."""
        x = t_s / self.duration_s
        if self.law == "exponential":
            return self.f_start_hz * math.exp(self._ratio_log * x)
        return self.f_start_hz + (self.f_stop_hz - self.f_start_hz) * x

    def phase_rad(self, t_s: float) -> float:
        """The phase at time t: 2 pi times the integral of :meth:`frequency_hz` from 0."""
        if self.law == "exponential":
            if self._ratio_log == 0.0:
                return 2.0 * math.pi * self.f_start_hz * t_s
            # expm1 keeps full precision when the ratio is close to 1
            cycles = (
                self.f_start_hz
                * self.duration_s
                * math.expm1(self._ratio_log * t_s / self.duration_s)
                / self._ratio_log
            )
            return 2.0 * math.pi * cycles
        slope_hz_s = (self.f_stop_hz - self.f_start_hz) / self.duration_s
        return 2.0 * math.pi * (self.f_start_hz * t_s + 0.5 * slope_hz_s * t_s * t_s)

    def envelope(self, t_s: float) -> float:
        """Amplitude factor in [0, 1]: the fade-in and fade-out ramps, 0 outside the sweep."""
        if t_s < 0.0 or t_s > self.duration_s:
            return 0.0
        level = 1.0
        if self.fade_in_s > 0.0:
            level = min(level, t_s / self.fade_in_s)
        if self.fade_out_s > 0.0:
            level = min(level, (self.duration_s - t_s) / self.fade_out_s)
        return level

    def pwm_us(self, t_s: float) -> int:
        """The pulse width commanded at time t."""
        deviation_us = self.amplitude_us * self.envelope(t_s) * math.sin(self.phase_rad(t_s))
        return self.channel.clamp(self.channel.pwm_trim_us + deviation_us)

    def start(self, ctx: PrimitiveContext) -> None:
        """Arm the sweep; it starts at the next update."""
        self._tick = 0
        self._active = True

    def update(self, ctx: PrimitiveContext) -> Status:
        """Send this tick's sample; at t >= duration_s send trim, release and be DONE."""
        if not self._active:
            return Status.DONE
        t_s = self._tick / ctx.config.loop_hz
        self._tick += 1
        if t_s < self.duration_s:
            ctx.command(self.channel.drive(self.pwm_us(t_s)))
            return Status.RUNNING
        self._finish(ctx)
        return Status.DONE


BEHAVIOR = Behavior(
    name="sine_sweep",
    summary="Sinusoid sweeping from f_start_hz to f_stop_hz over duration_s; then done.",
    parameters=SineSweepParams,
    runtime=SineSweepBehavior,
    events=raises_done,
    traits=Traits(flies=True, drives_channel=True),
    check=_check,
    compile=compile_channel,
    signal=_signal,
    waveform=_waveform,
)
