"""survey's checks before flight: the area, the camera, the photo rate, the route, AUTO.

Each a finding at the parameter it is about; :func:`all_checks` is the declaration's
``check`` (:mod:`~clark_engine.behaviors.survey`).
"""

from __future__ import annotations

import math
from collections.abc import Generator, Iterator, Mapping
from typing import TYPE_CHECKING, Any

from clark_engine.behaviors.declaration import (
    UseContext,
)
from clark_engine.behaviors.lawnmower import (
    line_count,
    longest_edge_heading_deg,
    photo_marks,
    polygon_area_m2,
    self_crossing,
)
from clark_engine.behaviors.shared import (
    check_agents_exist,
    check_ceiling,
    check_orbit_tolerance,
    check_speed,
    off_the_globe,
    orbit_radius_m,
    suggest,
)
from clark_engine.mission.envelope_checks import check_leg, check_point
from clark_engine.mission.findings import Finding, error
from clark_engine.mission.geo import LocalPoint, parse_point

if TYPE_CHECKING:
    pass

from clark_engine.behaviors.survey_plan import (
    AUTO_MISSION_ITEMS,
    AUTO_MODE,
    MAX_LINES,
    MIN_AREA_M2,
    OPTICS,
    WAYPOINT_RADIUS,
    Resolved,
    footprint_m,
    line_speed_m_s,
    resolve,
    survey_camera,
    wants_photos,
)

# ----------------------------------------------------------------------- checks


def _check(ctx: UseContext) -> Iterator[Finding]:
    params = ctx.params
    origin = ctx.mission.origin
    points = [parse_point(raw, origin) for raw in params["area"]]
    vertices = [(p.north_m, p.east_m) for p in points]
    yield from check_agents_exist(ctx, params.get("to") or [], "to")
    yield from check_speed(ctx)
    if ctx.agent.airframe_class == "fixed_wing" and params.get("run_out_m") is None:
        yield from check_orbit_tolerance(ctx, "a line's end", "a line's end")
    yield from _check_area(ctx, vertices)
    yield from _check_choices(ctx)
    camera = yield from _check_camera(ctx)
    if camera is None and (
        params.get("side_overlap") is not None or params.get("forward_overlap") is not None
    ):
        return
    plan = resolve(params, ctx.agent, vertices)
    if plan is None:
        return
    yield from _check_photo_rate(ctx, camera, plan)
    height = float(params["altitude_m"])
    yield from check_ceiling(ctx, height, ctx.locate("altitude_m"), "the survey")
    yield from _check_route(ctx, plan, height)


def _check_area(ctx: UseContext, vertices: list[tuple[float, float]]) -> Iterator[Finding]:
    where = ctx.locate("area")
    for index, raw in enumerate(ctx.params["area"]):
        problem = off_the_globe(parse_point(raw, ctx.mission.origin), ctx.mission.origin)
        if problem:
            yield error("E-POSITION", ctx.locate(f"area[{index}]"), f"vertex {index} {problem}")
    crossing = self_crossing(vertices)
    if crossing is not None:
        i, j = crossing
        yield error(
            "E-SURVEY-AREA",
            where,
            f"the area crosses itself: its edge from vertex {i} to {i + 1} meets the edge "
            f"from vertex {j} to {(j + 1) % len(vertices)}; list the vertices in order round "
            "the outline",
            ctx.use_location,
        )
        return
    size = polygon_area_m2(vertices)
    if size < MIN_AREA_M2:
        yield error(
            "E-SURVEY-AREA",
            where,
            f"the area covers {size:.3g} m², less than {MIN_AREA_M2:g} m²; give the vertices "
            "of a real outline (metres from the origin, or {lat, lon})",
            ctx.use_location,
        )


def _check_choices(ctx: UseContext) -> Iterator[Finding]:
    params = ctx.params
    spacing, overlap = params.get("line_spacing_m"), params.get("side_overlap")
    if (spacing is None) == (overlap is None):
        yield error(
            "E-SURVEY-SPACING",
            ctx.locate("line_spacing_m" if spacing is not None else "side_overlap"),
            "give exactly one of line_spacing_m (metres between lines) and side_overlap "
            "(the lines' spacing from the camera's footprint)"
            + (", not both" if spacing is not None else ""),
            ctx.use_location,
        )
    if params.get("photo_every_m") is not None and params.get("forward_overlap") is not None:
        yield error(
            "E-SURVEY-SPACING",
            ctx.locate("forward_overlap"),
            "give photo_every_m or forward_overlap, not both",
            ctx.use_location,
        )
    if ctx.agent.airframe_class == "rover":
        for key in ("side_overlap", "forward_overlap"):
            if params.get(key) is not None:
                yield error(
                    "E-SURVEY-SPACING",
                    ctx.locate(key),
                    f"{ctx.agent.name} ({ctx.agent.profile}) is a rover: its camera looks at "
                    f"the ground from no height a footprint can be worked out from, so {key} "
                    "cannot space its "
                    + (
                        "lines; give line_spacing_m"
                        if key == "side_overlap"
                        else "pictures; give photo_every_m"
                    ),
                    ctx.use_location,
                )


def _check_camera(ctx: UseContext) -> Generator[Finding, None, Mapping[str, Any] | None]:
    """The camera must be there when pictures or a footprint are asked; returns it."""
    params = ctx.params
    needs_optics = [k for k in ("side_overlap", "forward_overlap") if params.get(k) is not None]
    if not wants_photos(params) and not needs_optics:
        return None
    name = str(params["payload"])
    payloads = ctx.agent.hardware.payloads
    if name not in payloads:
        yield error(
            "E-PAYLOAD-MISSING",
            ctx.locate("payload"),
            f"agent {ctx.agent.name!r} ({ctx.agent.profile}) has no payload {name!r} "
            f"({suggest(name, payloads)}); add a camera under its hardware.payloads",
            ctx.use_location,
        )
        return None
    camera = payloads[name]
    if camera.get("payload_kind") != "camera":
        yield error(
            "E-PAYLOAD-KIND",
            ctx.locate("payload"),
            f"payload {name!r} of {ctx.agent.name!r} is a {camera.get('payload_kind')}, "
            "not a camera; name a camera payload",
            ctx.use_location,
        )
        return None
    missing = [key for key in OPTICS if camera.get(key) is None]
    if needs_optics and missing:
        profile = ctx.agent.hardware.payload_profiles.get(name, name)
        yield error(
            "E-CAMERA-FOOTPRINT",
            ctx.locate(needs_optics[0]),
            f"{needs_optics[0]} needs the ground footprint of camera {name!r} ({profile}), "
            f"and its profile does not declare {', '.join(missing)}; add them to the profile "
            f"or under agents.{ctx.agent.name}.hardware.payloads.{name}, or give "
            + ("line_spacing_m" if needs_optics[0] == "side_overlap" else "photo_every_m"),
            ctx.use_location,
        )
        return None
    return camera


def _check_photo_rate(
    ctx: UseContext, camera: Mapping[str, Any] | None, plan: Resolved
) -> Iterator[Finding]:
    if camera is None or plan.photo_every_m is None or not plan.lines:
        return
    speed = line_speed_m_s(ctx.params, ctx.agent)
    if speed is None:
        return
    every_m = min(
        (marks[1] - marks[0] if len(marks) > 1 else plan.photo_every_m)
        for marks in (
            photo_marks(line.photo_from_m, line.photo_to_m, plan.photo_every_m)
            for line in plan.lines
        )
    )
    interval = every_m / speed
    given = "photo_every_m" if ctx.params.get("photo_every_m") is not None else "forward_overlap"
    shortest = float(camera.get("min_interval_s", 0))
    tick_s = 1.0 / ctx.mission.loop_hz
    if interval < max(shortest, tick_s):
        limit = max(shortest, tick_s)
        yield error(
            "E-PHOTO-INTERVAL",
            ctx.locate(given),
            f"pictures {every_m:.3g} m apart (at most {plan.photo_every_m:.3g} m, evenly along "
            f"each line) at {speed:g} m/s are one every "
            f"{interval:.3g} s, more often than camera {ctx.params['payload']!r} can take them "
            f"(at most one every {limit:g} s); space them at least {limit * speed:.3g} m "
            "apart or fly slower",
            ctx.use_location,
        )


def _check_route(ctx: UseContext, plan: Resolved, height: float) -> Iterator[Finding]:
    """Each line's ends inside the envelope, each line and each turn inside the fence."""
    where = ctx.locate("area")
    if not plan.lines:
        yield error(
            "E-SURVEY-LINES",
            where,
            "no line crosses the area; give a spacing smaller than the area is wide",
            ctx.use_location,
        )
        return
    airframe = ctx.agent.hardware.part("airframe") or {}
    autopilot = ctx.agent.hardware.part("autopilot") or {}
    orbit_m = orbit_radius_m(airframe, autopilot, ctx.params.get("speed_m_s"))
    route = [LocalPoint(n, e, height) for line in plan.lines for n, e in (line.start, line.end)]
    for index, point in enumerate(route):
        label = f"the {'start' if index % 2 == 0 else 'end'} of survey line {index // 2}"
        yield from check_point(ctx.agent, point, where, label, ctx.use_location, orbit_m=orbit_m)
        if index:
            yield from check_leg(
                ctx.agent,
                route[index - 1],
                point,
                where,
                f"the survey's leg to {label}",
                ctx.use_location,
            )


def _check_bounds(ctx: UseContext) -> Iterator[Finding]:
    """Too many lines is its own error: :func:`resolve` refuses such a plan."""
    params = ctx.params
    points = [parse_point(raw, ctx.mission.origin) for raw in params["area"]]
    vertices = [(p.north_m, p.east_m) for p in points]
    if self_crossing(vertices) or polygon_area_m2(vertices) < MIN_AREA_M2:
        return
    camera = survey_camera(ctx.agent, params)
    spacing = params.get("line_spacing_m")
    if spacing is None and params.get("side_overlap") is not None and camera is not None:
        footprint = footprint_m(camera, float(params["altitude_m"]))
        if footprint is not None:
            spacing = footprint[0] * (1.0 - float(params["side_overlap"]))
    if spacing is None or float(spacing) <= 0:
        return
    heading = params.get("heading_deg")
    heading = float(heading) if heading is not None else longest_edge_heading_deg(vertices)
    count = line_count(vertices, float(spacing), heading)
    if count > MAX_LINES:
        yield error(
            "E-SURVEY-LINES",
            ctx.locate("line_spacing_m" if params.get("line_spacing_m") else "side_overlap"),
            f"lines {float(spacing):.3g} m apart make {count} lines over this area, more than "
            f"{MAX_LINES}; space them further apart or split the area between states",
            ctx.use_location,
        )


def auto_items(line_count: int, speed: bool) -> int:
    """The items a ``fly_as: auto`` survey's mission holds: home, a speed, two per line."""
    return 1 + int(speed) + 2 * line_count


def waypoint_radius_m(autopilot: Mapping[str, Any]) -> tuple[str, float] | None:
    """(parameter, metres) within which the autopilot counts a waypoint reached in AUTO."""
    known = WAYPOINT_RADIUS.get(str(autopilot.get("firmware")))
    if known is None:
        return None
    name, value = known
    parameters = autopilot.get("parameters") or {}
    return name, float(parameters.get(name, value))


def _check_auto(ctx: UseContext) -> Iterator[Finding]:
    """``fly_as: auto`` needs an autopilot that flies missions in AUTO, and a tolerance.

    The tolerance must be one the autopilot can meet: the survey is done within
    ``tolerance_m`` of the last end, where ArduRover and ArduPlane count it reached up
    to their waypoint radius away (and then stop, or turn to RTL).
    """
    if ctx.params.get("fly_as") != "auto":
        return
    where = ctx.locate("fly_as")
    autopilot = ctx.agent.hardware.part("autopilot") or {}
    firmware = autopilot.get("firmware")
    profile = ctx.agent.hardware.part_profiles.get("autopilot", ctx.agent.profile)
    if firmware not in AUTO_MISSION_ITEMS or AUTO_MODE not in (autopilot.get("modes") or {}):
        yield error(
            "E-SURVEY-AUTO",
            where,
            f"fly_as: auto flies the lines as a mission in the autopilot's {AUTO_MODE} mode, "
            f"and {ctx.agent.name}'s autopilot ({profile}) "
            + (
                f"names no {AUTO_MODE} mode"
                if firmware in AUTO_MISSION_ITEMS
                else "runs no ArduPilot firmware that flies missions"
            )
            + f"; add {AUTO_MODE} to its profile's modes, or fly the survey as guided",
            ctx.use_location,
        )
        return
    plan_lines = ctx.params.get("lines")
    if plan_lines is None:
        points = [parse_point(raw, ctx.mission.origin) for raw in ctx.params["area"]]
        vertices = [(p.north_m, p.east_m) for p in points]
        plan = resolve(ctx.params, ctx.agent, vertices)
        count = len(plan.lines) if plan is not None else 0
    else:
        count = len(plan_lines)
    items = auto_items(count, ctx.params.get("speed_m_s") is not None)
    limit = AUTO_MISSION_ITEMS[str(firmware)]
    if items > limit:
        yield error(
            "E-SURVEY-AUTO",
            where,
            f"{count} lines make a mission of {items} items with home and the speed, more "
            f"than the {limit} {firmware} stores; space the lines further apart or split "
            "the area between states",
            ctx.use_location,
        )
    radius = waypoint_radius_m(autopilot)
    tolerance = float(ctx.params.get("tolerance_m", 5.0))
    if radius is not None and tolerance < radius[1]:
        name, value = radius
        yield error(
            "E-SURVEY-AUTO-RADIUS",
            ctx.locate("tolerance_m"),
            f"{firmware} counts a mission's waypoint reached up to {value:g} m from it "
            f"({name}) and then "
            + ("turns to RTL" if firmware == "arduplane" else "stops there")
            + f", so the survey, done within tolerance_m {tolerance:g} m of the last line's "
            f"end, may never be done; set tolerance_m to at least {math.ceil(value)} m, or "
            f"set {name} lower in the autopilot's parameters",
            ctx.use_location,
        )


def all_checks(ctx: UseContext) -> Iterator[Finding]:
    """Every check of one ``use: survey``: the declaration's ``check``."""
    yield from _check(ctx)
    yield from _check_bounds(ctx)
    yield from _check_auto(ctx)
