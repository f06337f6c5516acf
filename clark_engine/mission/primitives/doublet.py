"""doublet: a control-surface doublet, the classic system-identification input.

Trim + amplitude for ``width_s``, trim - amplitude for ``width_s``, back to trim
(thesis 5.3.3, figure 5.13). The channel is named (``aileron``) and resolved
through each airframe's profile, so one block serves a Super Cub and an
Anaconda. The runtime samples the shape once per tick, so each half must span
at least two ticks to exist at all.
"""

from __future__ import annotations

from collections.abc import Iterator

from clark_engine.mission.findings import Finding, error
from clark_engine.mission.primitives._shared import (
    CHANNEL_SCHEMA,
    VIA_SCHEMA,
    check_channel_swing,
    resolved_channel_schema,
)
from clark_engine.mission.primitives.base import PrimitiveSpec, UseContext, raises_done
from clark_engine.mission.schema_source.common import number, obj, string

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


SPEC = PrimitiveSpec(
    name="doublet",
    summary="Trim+amplitude for width_s, trim-amplitude for width_s, back to trim; then done.",
    params=obj(
        "Parameters of doublet.",
        {
            "channel": CHANNEL_SCHEMA,
            "amplitude_us": number(
                "Pulse-width step either side of the channel's trim.",
                unit="us",
                exclusive_minimum=0,
                maximum=1000,
            ),
            "width_s": number(
                "Duration of each half of the doublet.",
                unit="s",
                exclusive_minimum=0,
                maximum=60,
            ),
            "first": string(
                "Direction of the first half: up (trim + amplitude) or down.",
                enum=["up", "down"],
                default="up",
            ),
            "via": VIA_SCHEMA,
        },
        required=["channel", "amplitude_us", "width_s"],
    ),
    compiled=lambda: {"channel": resolved_channel_schema()},
    events=raises_done,
    check=_check,
)
