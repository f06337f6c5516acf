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
from collections.abc import Iterator

from clark_engine.mission.findings import Finding, error, warning
from clark_engine.mission.primitives._shared import (
    CHANNEL_SCHEMA,
    VIA_SCHEMA,
    check_channel_swing,
    resolved_channel_schema,
)
from clark_engine.mission.primitives.base import PrimitiveSpec, UseContext, raises_done
from clark_engine.mission.schema_source.common import number, obj, string, time_s

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


SPEC = PrimitiveSpec(
    name="sine_sweep",
    summary="Sinusoid sweeping from f_start_hz to f_stop_hz over duration_s; then done.",
    params=obj(
        "Parameters of sine_sweep.",
        {
            "channel": CHANNEL_SCHEMA,
            "amplitude_us": number(
                "Peak pulse-width deviation from the channel's trim.",
                unit="us",
                exclusive_minimum=0,
                maximum=1000,
            ),
            "f_start_hz": number(
                "Instantaneous frequency at the start.", unit="Hz", exclusive_minimum=0, maximum=100
            ),
            "f_stop_hz": number(
                "Instantaneous frequency at the end.", unit="Hz", exclusive_minimum=0, maximum=100
            ),
            "duration_s": number(
                "Length of the sweep.", unit="s", exclusive_minimum=0, maximum=3600
            ),
            "law": string(
                "How frequency moves from start to stop: linear in time, or exponential "
                "(equal time per octave).",
                enum=["linear", "exponential"],
                default="linear",
            ),
            "fade_in_s": time_s(
                "Time over which the amplitude ramps up from zero.", maximum=3600, default=0
            ),
            "fade_out_s": time_s(
                "Time over which the amplitude ramps down to zero.", maximum=3600, default=0
            ),
            "via": VIA_SCHEMA,
        },
        required=["channel", "amplitude_us", "f_start_hz", "f_stop_hz", "duration_s"],
    ),
    compiled=lambda: {"channel": resolved_channel_schema()},
    events=raises_done,
    check=_check,
)
