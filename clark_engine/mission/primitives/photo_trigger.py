"""photo_trigger: ask a camera payload for a picture every ``interval_s``.

When the camera confirms a capture the agent sends Picture Data with the
position of capture (thesis 5.3.2: the Anaconda photographed every 5 s). Runs
alongside a flight behaviour in a parallel region; done after ``count``
pictures when a count is given.
"""

from __future__ import annotations

from collections.abc import Iterator, Mapping
from typing import Any

from clark_engine.mission.findings import Finding, error
from clark_engine.mission.primitives._shared import AGENT_NAME_SCHEMA, check_agents_exist, suggest
from clark_engine.mission.primitives.base import PrimitiveSpec, UseContext
from clark_engine.mission.schema_source.common import array, count, number, obj, string


def _events(params: Mapping[str, Any]) -> frozenset[str]:
    return frozenset({"done"}) if params.get("count") is not None else frozenset()


def _check(ctx: UseContext) -> Iterator[Finding]:
    name = str(ctx.params["payload"])
    payloads = ctx.agent.hardware.payloads
    interval = float(ctx.params["interval_s"])
    yield from check_agents_exist(ctx, ctx.params.get("to", []), "to")
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


SPEC = PrimitiveSpec(
    name="photo_trigger",
    summary="Request a picture every interval_s and send Picture Data on each capture.",
    params=obj(
        "Parameters of photo_trigger.",
        {
            "payload": string(
                "Name of the camera payload on this agent.",
                pattern="^[a-z][a-z0-9_]*$",
                default="camera",
            ),
            "interval_s": number(
                "Time between capture requests.", unit="s", exclusive_minimum=0, maximum=3600
            ),
            "count": count("Pictures to take before finishing; unlimited when omitted.", minimum=1),
            "to": array(
                "Agents that receive Picture Data; every agent when omitted.", AGENT_NAME_SCHEMA
            ),
        },
        required=["interval_s"],
    ),
    events=_events,
    check=_check,
)
