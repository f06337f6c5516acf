"""follow_agent: drive or fly to another agent's reported position, plus an offset.

The target's position comes from its Agent Status messages, so the target must
send agent_status, to this agent, at least as often as the follower re-targets
(thesis 5.2.1: Slash B drives to Slash A). The guided target leads the target by
``lead_s`` along its reported velocity, so that the follower keeps up with it.
Done on reaching the target unless ``continuous``.
"""

from __future__ import annotations

import math
from collections.abc import Iterator, Mapping
from typing import Any

from clark_engine.mission.findings import Finding, error, warning
from clark_engine.mission.primitives._shared import (
    AGENT_NAME_SCHEMA,
    TOLERANCE_SCHEMA,
    check_agents_exist,
)
from clark_engine.mission.primitives.base import PrimitiveSpec, UseContext
from clark_engine.mission.schema_source.common import boolean, number, obj


def _events(params: Mapping[str, Any]) -> frozenset[str]:
    return frozenset() if params.get("continuous") else frozenset({"done"})


def _check(ctx: UseContext) -> Iterator[Finding]:
    target_name = str(ctx.params["target"])
    unknown = list(check_agents_exist(ctx, [target_name], "target"))
    if unknown:
        yield from unknown
        return
    me = ctx.agent
    if target_name in ctx.mission.unresolved:
        return  # the target's own errors are reported where it is declared
    if target_name == me.name:
        yield error(
            "E-FOLLOW-SELF",
            ctx.locate("target"),
            f"{me.name!r} cannot follow itself; name another agent",
            ctx.use_location,
        )
        return
    target = ctx.mission.agents[target_name]
    if not target.is_vehicle:
        yield error(
            "E-FOLLOW-STATUS",
            ctx.locate("target"),
            f"{target_name!r} is a station and reports no position; follow a vehicle",
            ctx.use_location,
        )
        return
    status = target.telemetry.get("agent_status")
    retarget_hz = float(ctx.params["retarget_hz"])
    if status is None or not status.reaches(me.name):
        why = (
            "sends no agent_status"
            if status is None
            else f"sends agent_status only to {', '.join(status.to)}"
        )
        yield error(
            "E-FOLLOW-STATUS",
            ctx.locate("target"),
            f"{target_name!r} {why}, so {me.name!r} never learns where it is; add "
            f"agent_status to agents.{target_name}.telemetry (at least {retarget_hz:g} Hz)",
            target.location,
        )
    elif status.rate_hz < retarget_hz:
        yield warning(
            "W-FOLLOW-RATE",
            ctx.locate("retarget_hz"),
            f"{me.name!r} re-targets at {retarget_hz:g} Hz but {target_name!r} reports its "
            f"position at only {status.rate_hz:g} Hz; raise its agent_status rate or lower "
            "retarget_hz",
            status.location,
        )
    yield from _check_separation(ctx, target_name)
    offset_up = float((ctx.params.get("offset") or {}).get("up_m", 0.0))
    is_air = (me.hardware.part("airframe") or {}).get("class") != "rover"
    envelope = me.envelope
    if is_air and envelope is not None and offset_up > envelope.ceiling_m:
        yield error(
            "E-ALTITUDE-CEILING",
            ctx.locate("offset"),
            f"an offset {offset_up:g} m above the target is over {me.name}'s ceiling of "
            f"{envelope.describe_ceiling()} wherever the target is; lower offset.up_m",
            ctx.use_location,
        )
    if retarget_hz > ctx.mission.loop_hz:
        yield error(
            "E-RATE",
            ctx.locate("retarget_hz"),
            f"retarget_hz {retarget_hz:g} Hz is above loop_hz {ctx.mission.loop_hz:g}; "
            "lower it or raise mission.loop_hz",
            ctx.use_location,
        )


#: A continuous follower's offset must keep it at least this far from its leader: it
#: keeps driving onto the point the offset names, whatever its tolerance_m.
MIN_FOLLOW_SEPARATION_M = 3.0


def _check_separation(ctx: UseContext, target_name: str) -> Iterator[Finding]:
    """A continuous follower keeps chasing: its offset is all that keeps it off its leader."""
    if not ctx.params.get("continuous"):
        return
    offset = ctx.params.get("offset") or {}
    north, east, up = (float(offset.get(k, 0.0)) for k in ("north_m", "east_m", "up_m"))
    rover = (ctx.agent.hardware.part("airframe") or {}).get("class") == "rover"
    distance = math.hypot(north, east) if rover else math.sqrt(north**2 + east**2 + up**2)
    if distance >= MIN_FOLLOW_SEPARATION_M:
        return
    need = MIN_FOLLOW_SEPARATION_M
    yield warning(
        "W-FOLLOW-SEPARATION",
        ctx.locate("offset") if "offset" in ctx.params else ctx.use_location,
        f"{ctx.agent.name!r} follows {target_name!r} without end, aiming {distance:g} m from "
        f"its reported position, so it drives up to its leader (a dry run closes to under a "
        f"metre); give an offset of at least {need:g} m, such as offset: {{north_m: -{need:g}}}",
        ctx.use_location,
    )


SPEC = PrimitiveSpec(
    name="follow_agent",
    summary="Go to another agent's reported position plus an offset; done on reaching it.",
    params=obj(
        "Parameters of follow_agent.",
        {
            "target": AGENT_NAME_SCHEMA,
            "offset": obj(
                "Offset from the target's position, in metres north/east/up.",
                {
                    "north_m": number("Metres north of the target.", unit="m", default=0),
                    "east_m": number("Metres east of the target.", unit="m", default=0),
                    "up_m": number("Metres above the target.", unit="m", default=0),
                },
            ),
            "retarget_hz": number(
                "How often the guided target is moved to the target's latest position.",
                unit="Hz",
                exclusive_minimum=0,
                maximum=50,
                default=1,
            ),
            "lead_s": number(
                "Aim this many seconds ahead of the target, along the velocity it reports: "
                "ArduPilot trails a moving guided target (ArduRover by about 2.3 s of its "
                "speed, measured on SITL), so a follower aimed at where the target is never "
                "reaches it. 0 aims at the reported position.",
                unit="s",
                minimum=0,
                maximum=30,
                default=2.5,
            ),
            "tolerance_m": TOLERANCE_SCHEMA,
            "continuous": boolean(
                "Keep following after reaching the target instead of finishing.", default=False
            ),
        },
        required=["target"],
    ),
    events=_events,
    check=_check,
)
