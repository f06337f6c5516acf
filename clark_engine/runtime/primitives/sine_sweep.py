"""sine_sweep: a frequency sweep (chirp) on one control channel.

A sinusoid whose frequency moves from ``f_start_hz`` to ``f_stop_hz`` over
``duration_s``, which a pilot cannot hold steady by hand and the framework can
(thesis 5.3.3, figure 5.14). Runtime semantics (the declaration is
:mod:`clark_engine.mission.primitives.sine_sweep`), with f0 = f_start_hz,
f1 = f_stop_hz, T = duration_s:

- Instantaneous frequency f(t): ``linear``: f0 + (f1 - f0) t / T;
  ``exponential``: f0 (f1 / f0) ** (t / T) (equal time per octave; f0 > 0 is
  guaranteed by the schema).
- Phase: 2 pi times the integral of f from 0, in closed form so that no
  rounding accumulates over a long sweep: ``linear``: 2 pi (f0 t + (f1 - f0)
  t^2 / (2 T)); ``exponential``: 2 pi f0 T (r^(t/T) - 1) / ln r with r = f1 / f0
  (2 pi f0 t when r = 1). The phase is 0 at t = 0, so the sweep starts at trim.
- Envelope: rises linearly from 0 over the first ``fade_in_s`` and falls
  linearly to 0 over the last ``fade_out_s`` (1 in between; no fade when 0).
- Tick k (k = 0 at the first ``update`` after ``start``, which commands nothing)
  is at t = k / loop_hz. While t < T it sends
  ``round(trim + amplitude_us * envelope(t) * sin(phase(t)))``, clamped to the
  channel's limits, every tick (RcOverride({rc: pwm}) or SetServo(servo, pwm)).
  At the first tick with t >= T it sends trim, hands the channel back as the
  doublet does (RcOverride({rc: 0}) after trim for rc_override), and is DONE.
- ``stop`` before the end sends the same trim and release.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from typing import Any

from clark_engine.runtime.context import PrimitiveContext, Status
from clark_engine.runtime.primitives._shared import ChannelOutput
from clark_engine.runtime.primitives.base import Primitive


class SineSweep(Primitive):
    """A frequency sweep on one control channel.

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

    def __init__(self, params: Mapping[str, Any]) -> None:
        super().__init__(params)
        self.channel = ChannelOutput.from_params(params)
        self.amplitude_us = float(params["amplitude_us"])
        self.f_start_hz = float(params["f_start_hz"])
        self.f_stop_hz = float(params["f_stop_hz"])
        self.duration_s = float(params["duration_s"])
        self.law = str(params.get("law", "linear"))
        self.fade_in_s = float(params.get("fade_in_s", 0.0))
        self.fade_out_s = float(params.get("fade_out_s", 0.0))
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

    def stop(self, ctx: PrimitiveContext) -> None:
        """Return the channel to trim and release it if the sweep was cut short."""
        if self._active:
            self._finish(ctx)

    def _finish(self, ctx: PrimitiveContext) -> None:
        self._active = False
        for command in self.channel.finish():
            ctx.command(command)
