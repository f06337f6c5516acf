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

from clark_engine.mission.envelope_checks import (
    goal_distance_range,
    possible_heights,
    separation_m,
    separation_source,
    vertically_apart,
)
from clark_engine.mission.findings import Finding, error, warning
from clark_engine.mission.model import Agent
from clark_engine.mission.primitives._shared import (
    AGENT_NAME_SCHEMA,
    RESOLVED_AGENT_SCHEMA,
    TOLERANCE_SCHEMA,
    check_agents_exist,
)
from clark_engine.mission.primitives.base import PrimitiveSpec, UseContext
from clark_engine.mission.schema_source.common import altitude_m, boolean, number, obj, position_m


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
    reported = status is not None and status.reaches(me.name)
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
    yield from _check_envelope(ctx, target, reported=reported)
    if retarget_hz > ctx.mission.loop_hz:
        yield error(
            "E-RATE",
            ctx.locate("retarget_hz"),
            f"retarget_hz {retarget_hz:g} Hz is above loop_hz {ctx.mission.loop_hz:g}; "
            "lower it or raise mission.loop_hz",
            ctx.use_location,
        )


def _offset(ctx: UseContext) -> tuple[float, float, float]:
    offset = ctx.params.get("offset") or {}
    north, east, up = (float(offset.get(k, 0.0)) for k in ("north_m", "east_m", "up_m"))
    return north, east, up


def _check_envelope(ctx: UseContext, target: Agent, *, reported: bool) -> Iterator[Finding]:
    """The follower's goal against its envelope and its target's separation.

    The goal is the target's height above the origin plus ``offset.up_m``: a rover
    target is at 0 m, an aircraft anywhere between the ground (while it takes off or
    lands) and its ceiling. A goal always over the follower's ceiling or always under
    its floor is an error, and so is an offset that aims inside the pair's separation;
    what depends on where the target goes is said once, as a warning the dry run judges
    (not while the target reports no position to the follower, which then goes nowhere:
    E-FOLLOW-STATUS says so).
    """
    me = ctx.agent
    mine = me.envelope
    if mine is None or target.envelope is None:
        return
    north, east, up = _offset(ctx)
    offset_at = ctx.locate("offset") if "offset" in ctx.params else ctx.use_location
    low, high = possible_heights(target)
    on_ground = target.airframe_class == "rover"
    where_target = "a rover, on the ground" if on_ground else f"at {low:g}..{high:g} m"
    reasons: list[str] = []
    if me.airframe_class != "rover":
        lowest, highest = low + up, high + up
        if lowest > mine.ceiling_m:
            yield error(
                "E-FOLLOW-HEIGHT",
                offset_at,
                f"{me.name} aims {up:g} m above {target.name} ({where_target}), so at least "
                f"{lowest:g} m above the origin, over its ceiling of "
                f"{mine.describe_ceiling()} wherever {target.name} goes; lower offset.up_m to "
                f"at most {mine.ceiling_m - mine.margin_m - low:g} m",
                ctx.use_location,
            )
            return
        if highest < mine.floor_m:
            yield error(
                "E-FOLLOW-HEIGHT",
                offset_at,
                f"{me.name} aims {up:g} m above {target.name} ({where_target}), so at most "
                f"{highest:g} m above the origin, under its floor of {mine.floor_m:g} m "
                f"wherever {target.name} goes; raise offset.up_m to at least "
                f"{mine.floor_m + mine.margin_m - high:g} m",
                ctx.use_location,
            )
            return
        if highest > mine.ceiling_m:
            reasons.append(
                f"its goal, {up:g} m above {target.name}, is over its ceiling of "
                f"{mine.ceiling_m:g} m whenever {target.name} flies above "
                f"{mine.ceiling_m - up:g} m (the runtime then holds it under the ceiling)"
            )
        if lowest < mine.floor_m:
            reasons.append(
                f"its goal, {up:g} m above {target.name}, is under its floor of "
                f"{mine.floor_m:g} m whenever {target.name} is below {mine.floor_m - up:g} m "
                "(the runtime then holds it over the floor)"
            )
    need = separation_m(me, target)
    if need is not None:
        near, far = goal_distance_range(me, target, (north, east, up))
        # What the offset aims at as written: 3-D for an aircraft, on the ground between
        # rovers; a rover under an aircraft is as far from it as the aircraft's height.
        if me.airframe_class != "rover":
            aimed = math.sqrt(north**2 + east**2 + up**2)
        else:
            aimed = math.hypot(north, east) if target.airframe_class == "rover" else far
        tolerance = float(ctx.params.get("tolerance_m", 5.0))
        source = separation_source(me, target)
        if aimed < need:
            yield error(
                "E-FOLLOW-SEPARATION",
                offset_at,
                f"{me.name} aims {aimed:.1f} m from {target.name}, inside the {need:g} m the "
                f"pair keeps apart ({source}), so it drives up to its leader; give an offset "
                f"of at least {need:g} m (such as offset: {{north_m: -{need:g}}}), or, if the "
                "two are meant to meet, lower the pair's separation in envelope.separation",
                ctx.use_location,
            )
            return
        if near < need:
            reasons.append(
                f"its goal comes within {near:.1f} m of {target.name} when the runtime holds "
                f"it inside {me.name}'s envelope, inside the {need:g} m the pair keeps apart"
                if me.airframe_class != "rover"
                else f"its goal comes within {near:.1f} m of {target.name} when "
                f"{target.name} flies low, inside the {need:g} m the pair keeps apart"
            )
        elif not ctx.params.get("continuous") and aimed - tolerance < need:
            yield warning(
                "W-FOLLOW-SEPARATION",
                ctx.locate("tolerance_m"),
                f"{me.name} is done anywhere within tolerance_m {tolerance:g} m of its goal, "
                f"{aimed:.1f} m from {target.name}, so it may stop "
                f"{max(aimed - tolerance, 0):.1f} m from it, inside the {need:g} m the pair "
                f"keeps apart ({source}); lower tolerance_m to at most {aimed - need:.1f} m or "
                "widen the offset",
                ctx.use_location,
            )
        elif not vertically_apart(me, target, need):
            reasons.append(
                f"nothing before flight proves it keeps {need:g} m from {target.name} on its "
                f"way to its goal and while {target.name} moves (it may turn back toward it)"
            )
    if reasons and reported:
        yield warning(
            "W-ENVELOPE-REACTIVE",
            ctx.use_location,
            f"{me.name} follows {target.name}, so where it goes depends on where "
            f"{target.name} goes: {'; and '.join(reasons)}; the runtime holds the envelope in "
            "flight and the dry run judges it (read its altitude and closest-approach "
            "figures)",
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
                    "north_m": position_m("Metres north of the target.", default=0),
                    "east_m": position_m("Metres east of the target.", default=0),
                    "up_m": altitude_m("Metres above the target.", default=0),
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
    compiled=lambda: {"target": RESOLVED_AGENT_SCHEMA},
    events=_events,
    check=_check,
)
