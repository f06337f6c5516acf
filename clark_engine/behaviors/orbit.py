"""orbit: circle a point, or another agent, at a radius, a speed and a direction.

Rovers and multirotors are steered round the circle by guided targets streamed
ahead of them (a lead point, moved at ``retarget_hz``); turns are counted by the
angle the vehicle sweeps round the centre, so ``turns: 2`` is done after two
full circles flown the right way, and an orbit without ``turns`` runs until a
transition leaves the state. The centre is a point of the mission (``center``,
as a waypoint's ``to``) or another agent's reported position (``agent``, which
must send this agent its agent_status, as for follow_agent).

A fixed-wing aircraft is not steered by points: ArduPlane's GUIDED loiters round
its target, at the radius and in the direction a DO_REPOSITION gives (param3,
param4), so orbit sends it the centre with its radius and direction and counts
the turns it flies. A plane cannot circle tighter than it can turn: ``clark
validate`` refuses such a radius at the ``use:`` (E-ORBIT-RADIUS).
"""

from __future__ import annotations

import math
from collections.abc import Iterator, Mapping
from typing import TYPE_CHECKING, Any

from clark_engine.behaviors.base import AgentRef, BehaviorRuntime, Point, Status
from clark_engine.behaviors.declaration import (
    Behavior,
    CompileContext,
    Params,
    Plan,
    Traits,
    UseContext,
    param,
)
from clark_engine.behaviors.flight import GuidedLeg, Schedule, Target
from clark_engine.behaviors.shared import (
    AGENT_NAME_SCHEMA,
    DEFAULT_AIRSPEED_CRUISE_M_S,
    GRAVITY_M_S2,
    LOITER_RADIUS_FACTOR,
    ORBIT_FACTOR,
    POINT_SCHEMA,
    RESOLVED_AGENT_SCHEMA,
    RESOLVED_POINT_SCHEMA,
    SPEED_SCHEMA,
    check_agents_exist,
    check_ceiling,
    check_points,
    check_position_reports,
    check_speed,
)
from clark_engine.mission.envelope_checks import (
    check_floor,
    separation_m,
    separation_source,
    vertically_apart,
)
from clark_engine.mission.findings import Finding, error, warning
from clark_engine.mission.geo import EARTH_RADIUS_M
from clark_engine.mission.schema_source.common import altitude_m, distance_m, number, string

if TYPE_CHECKING:
    from clark_engine.mission.model import Agent
    from clark_engine.runtime.context import PrimitiveContext

#: How many points of the circle the plan (report, station, envelope checks) draws.
PLAN_POINTS = 12


class OrbitParams(Params):
    """Parameters of orbit."""

    DESCRIPTION = "Parameters of orbit."
    REQUIRED = ("radius_m",)

    center: Point | None = param(
        POINT_SCHEMA
        | {
            "description": "The point to circle, in the mission's frames as a waypoint's `to` "
            "takes it; its height (up_m) is the circle's. Give center or agent."
        },
        compiled=lambda: RESOLVED_POINT_SCHEMA,
        convert=Point.from_config,
    )
    agent: AgentRef | None = param(
        AGENT_NAME_SCHEMA
        | {
            "description": "Another agent to circle, at the position it reports (it must send "
            "this agent agent_status at retarget_hz or faster). Give center or agent."
        },
        compiled=lambda: RESOLVED_AGENT_SCHEMA,
        convert=AgentRef.from_config,
    )
    alt_m: float | None = param(
        altitude_m(
            "Height above the mission origin to circle an agent at (an aircraft must give "
            "it; a rover drives on the ground). A center point gives its own height."
        )
    )
    radius_m: float = param(
        distance_m("Radius of the circle.", minimum=1, maximum=2000),
    )
    speed_m_s: float | None = param(SPEED_SCHEMA)
    direction: str = param(
        string(
            "Which way round, seen from above: cw (clockwise) or ccw.",
            enum=["cw", "ccw"],
            default="cw",
        )
    )
    turns: float | None = param(
        number(
            "Done after this many full turns round the centre, counted by the angle swept "
            "once on the circle; omitted, it circles until a transition leaves the state.",
            exclusive_minimum=0,
            maximum=1000,
        )
    )
    tolerance_m: float = param(
        distance_m(
            "How far from the circle the vehicle may be for its sweep to count as turns "
            "(counting starts the first time it is this close).",
            exclusive_minimum=0,
            maximum=1000,
            default=5,
        )
    )
    lead_deg: float = param(
        number(
            "How far ahead of the vehicle, round the circle, each guided target is aimed: "
            "far enough that the autopilot does not slow down for it (ArduCopter flew 12 m "
            "circles at 3.5 m/s of 4 with 30 degrees, at 4.0 with 45, on SITL).",
            unit="deg",
            minimum=5,
            maximum=60,
            default=45,
        )
    )
    retarget_hz: float = param(
        number(
            "How often the guided target is moved on round the circle.",
            unit="Hz",
            exclusive_minimum=0,
            maximum=50,
            default=2,
        )
    )


def _events(params: Mapping[str, Any]) -> frozenset[str]:
    return frozenset({"done"}) if params.get("turns") is not None else frozenset()


def tightest_circle_m(
    airframe: Mapping[str, Any], autopilot: Mapping[str, Any], speed_m_s: float | None
) -> float:
    """The tightest circle a fixed-wing aircraft flies at a speed (its profile's limits).

    :data:`~clark_engine.behaviors.shared.ORBIT_FACTOR` times its tightest turn, by its
    bank limit (``V^2 / (g tan(max_bank_deg))``) or its turn-rate limit (``V /
    max_turn_rate_deg_s``), whichever is wider, at ``speed_m_s`` or, without one, its
    autopilot's AIRSPEED_CRUISE: what the dry run's plane flies at the least and what
    WP_LOITER_RAD's own floor is (:func:`~clark_engine.behaviors.shared.orbit_radius_m`).
    """
    params = autopilot.get("parameters") or {}
    speed = float(speed_m_s or params.get("AIRSPEED_CRUISE", DEFAULT_AIRSPEED_CRUISE_M_S))
    bank = math.radians(float(airframe.get("max_bank_deg") or 45.0))
    by_bank = speed * speed / (GRAVITY_M_S2 * math.tan(bank))
    rate = math.radians(float(airframe.get("max_turn_rate_deg_s") or 0.0))
    by_rate = speed / rate if rate > 0 else by_bank
    return ORBIT_FACTOR * max(by_bank, by_rate)


def _check_plane_radius(ctx: UseContext) -> Iterator[Finding]:
    """A fixed-wing aircraft cannot fly a circle tighter than it turns."""
    airframe = ctx.agent.hardware.part("airframe") or {}
    if airframe.get("class") != "fixed_wing":
        return
    autopilot = ctx.agent.hardware.part("autopilot") or {}
    speed = ctx.params.get("speed_m_s")
    least = tightest_circle_m(airframe, autopilot, speed)
    radius = float(ctx.params["radius_m"])
    if radius < least:
        at = f"{float(speed):g} m/s" if speed is not None else "its cruise airspeed"
        yield error(
            "E-ORBIT-RADIUS",
            ctx.locate("radius_m"),
            f"{ctx.agent.name} ({ctx.agent.profile}) is a fixed-wing aircraft: at {at} it "
            f"circles no tighter than {least:.0f} m ({ORBIT_FACTOR:g} times its tightest "
            f"turn, from its airframe's bank and turn-rate limits), so radius_m {radius:g} m "
            f"cannot be flown; give radius_m {math.ceil(least)} m or more, or fly slower",
            ctx.use_location,
        )


def _check(ctx: UseContext) -> Iterator[Finding]:
    yield from _check_plane_radius(ctx)
    center, agent = ctx.params.get("center"), ctx.params.get("agent")
    if (center is None) == (agent is None):
        yield error(
            "E-ORBIT-CENTER",
            ctx.use_location,
            "orbit needs exactly one centre: give center (a point) or agent (another agent), "
            + ("not both" if center is not None else "neither is given"),
        )
        return
    if center is not None:
        if ctx.params.get("alt_m") is not None:
            yield error(
                "E-ORBIT-CENTER",
                ctx.locate("alt_m"),
                "alt_m is the height of a circle round an agent; a center point gives its own "
                "height: write it as the point's up_m",
                ctx.use_location,
            )
        yield from check_points(ctx, [center], "center", indexed=False)
    else:
        yield from _check_agent(ctx, str(agent))
    yield from check_speed(ctx)
    retarget_hz = float(ctx.params["retarget_hz"])
    if retarget_hz > ctx.mission.loop_hz:
        yield error(
            "E-RATE",
            ctx.locate("retarget_hz"),
            f"retarget_hz {retarget_hz:g} Hz is above loop_hz {ctx.mission.loop_hz:g}; "
            "lower it or raise mission.loop_hz",
            ctx.use_location,
        )


def _check_agent(ctx: UseContext, name: str) -> Iterator[Finding]:
    """The centre agent exists, is another vehicle, and tells this one where it is."""
    unknown = list(check_agents_exist(ctx, [name], "agent"))
    if unknown:
        yield from unknown
        return
    me = ctx.agent
    if me.airframe_class != "rover":
        alt = ctx.params.get("alt_m")
        if alt is None:
            yield error(
                "E-ORBIT-CENTER",
                ctx.use_location,
                f"{me.name} is an aircraft circling {name!r}: give alt_m, the circle's height "
                "above the mission origin",
            )
        else:
            where = ctx.locate("alt_m")
            yield from check_ceiling(ctx, float(alt), where, "the circle")
            yield from check_floor(me, float(alt), where, "the circle", ctx.use_location)
    if name in ctx.mission.unresolved:
        return  # its own errors are reported where it is declared
    if name == me.name:
        yield error(
            "E-ORBIT-SELF",
            ctx.locate("agent"),
            f"{me.name!r} cannot orbit itself; name another agent or give a center point",
            ctx.use_location,
        )
        return
    centre = ctx.mission.agents[name]
    if not centre.is_vehicle:
        yield error(
            "E-ORBIT-STATUS",
            ctx.locate("agent"),
            f"{name!r} is a station and reports no position; circle its position as a "
            "center point instead",
            ctx.use_location,
        )
        return
    yield from _check_separation(ctx, centre)
    yield from check_position_reports(
        ctx,
        centre,
        "agent",
        ("E-ORBIT-STATUS", "W-ORBIT-RATE"),
        "where to circle",
        f"moves its target round {name!r} at {float(ctx.params['retarget_hz']):g} Hz",
    )


def _check_separation(ctx: UseContext, centre: Agent) -> Iterator[Finding]:
    """The circle keeps the pair's separation from the agent it circles.

    Round a rover (on the ground) the circle is ``hypot(radius_m, alt_m)`` from it (a
    rover orbiter: ``radius_m``): under the pair's separation is an error. Round an
    aircraft the heights may meet, so a radius under the separation is a warning unless
    the two can never come within it in height.
    """
    me = ctx.agent
    need = separation_m(me, centre)
    if need is None:
        return
    radius = float(ctx.params["radius_m"])
    source = separation_source(me, centre)
    if centre.airframe_class == "rover":
        alt = float(ctx.params.get("alt_m") or 0.0) if me.airframe_class != "rover" else 0.0
        apart = math.hypot(radius, alt)
        if apart < need:
            least = math.ceil(math.sqrt(need * need - alt * alt))
            yield error(
                "E-ORBIT-SEPARATION",
                ctx.locate("radius_m"),
                f"{me.name} circles {centre.name} {apart:.1f} m from it, inside the {need:g} m "
                f"the pair keeps apart ({source}); give radius_m {least} m or more",
                ctx.use_location,
            )
    elif radius < need and not vertically_apart(me, centre, need):
        yield warning(
            "W-ORBIT-SEPARATION",
            ctx.locate("radius_m"),
            f"{me.name} circles {centre.name} at radius_m {radius:g} m, inside the {need:g} m "
            f"the pair keeps apart ({source}), whenever the two fly at the same height; give "
            f"radius_m {math.ceil(need)} m or more (the runtime holds the separation in flight)",
            ctx.use_location,
        )


def _compile(params: dict[str, Any], ctx: CompileContext) -> dict[str, Any]:
    if params.get("center") is not None:
        params["center"] = ctx.point(params["center"])
    if params.get("agent") is not None:
        agent = ctx.mission.agents[params["agent"]]
        params["agent"] = {"name": agent.name, "id": agent.id}
    return params


def _shift(lat_deg: float, lon_deg: float, north_m: float, east_m: float) -> tuple[float, float]:
    """A latitude and longitude moved by metres north and east (the local frame's flat earth)."""
    lat = lat_deg + math.degrees(north_m / EARTH_RADIUS_M)
    lon = lon_deg + math.degrees(east_m / (EARTH_RADIUS_M * math.cos(math.radians(lat_deg))))
    return lat, lon


def circle_points(center: Any, radius_m: float, direction: str, count: int) -> list[Any]:
    """Points round a circle, from due north, the way it is flown, in the centre's own form.

    A local point (a list or ``{north_m, east_m, up_m}``) gives ``{north_m, east_m,
    up_m}``; a ``{lat, lon, alt_m}`` gives the same form; a compiled point (both frames)
    gives both frames.
    """
    sign = 1.0 if direction == "cw" else -1.0
    out: list[Any] = []
    for i in range(count):
        bearing = sign * 2 * math.pi * i / count
        north, east = radius_m * math.cos(bearing), radius_m * math.sin(bearing)
        if isinstance(center, Mapping) and "lat" in center:
            lat, lon = _shift(float(center["lat"]), float(center["lon"]), north, east)
            point: dict[str, float] = {"lat": lat, "lon": lon, "alt_m": center.get("alt_m", 0)}
            if "north_m" in center:
                point = {
                    "north_m": float(center["north_m"]) + north,
                    "east_m": float(center["east_m"]) + east,
                    "up_m": float(center["up_m"]),
                    **point,
                }
            out.append(point)
            continue
        if isinstance(center, Mapping):
            n0, e0, u0 = (float(center.get(k, 0.0)) for k in ("north_m", "east_m", "up_m"))
        else:
            n0, e0 = float(center[0]), float(center[1])
            u0 = float(center[2]) if len(center) > 2 else 0.0
        out.append({"north_m": n0 + north, "east_m": e0 + east, "up_m": u0})
    return out


def _plan(params: Mapping[str, Any]) -> Plan:
    center = params.get("center")
    if center is None:
        return Plan()  # round an agent: where depends on where it goes
    points = circle_points(center, float(params["radius_m"]), str(params["direction"]), PLAN_POINTS)
    return Plan(points=[(p, "center") for p in points], loop=True)


def bearing_rad(north_m: float, east_m: float) -> float:
    """Bearing of a vector from north, clockwise, in radians (0 for a zero vector)."""
    return math.atan2(east_m, north_m) if (north_m or east_m) else 0.0


def wrap_rad(angle: float) -> float:
    """An angle in (-pi, pi]."""
    wrapped = math.remainder(angle, 2 * math.pi)
    return math.pi if wrapped == -math.pi else wrapped


class OrbitBehavior(BehaviorRuntime):
    """What orbit commands in flight, tick by tick (its section of docs/runtime.md).

    Circle a point or another agent at `radius_m`, `cw` or `ccw`; done after `turns`.

    - The *centre* is `center`, or the latest Agent Status of `agent` (peeked, as
      follow_agent reads it); the circle's height is the centre point's, or `alt_m` round
      an agent.
    - `start`: `SetMode(guided)` and `Arm` as for waypoint, and a `Goto` at once when the
      vehicle's position and the centre are known.
    - The *lead point*: from the vehicle's bearing round the centre, `lead_deg` (default
      45) further round the way it flies, on the line tangent to the circle at the
      vehicle's bearing (so `radius_m / cos(lead_deg)` from the centre). A vehicle that
      steers straight at it, again and again, stays on the circle; aiming at a point on
      the circle itself would shrink the orbit to `radius_m * cos(lead_deg)`. The radius
      aimed at is corrected by twice the vehicle's distance outside the circle (inside:
      the reverse), kept within 0.5-1.5 times `radius_m`, because the autopilot's lag in
      the turn carries it outwards (ArduCopter SITL flew 15.2 m for 12 m without it, 13.0
      m with it). From the centre itself the bearing is taken as north.
    - Re-targeting: a `Goto(lead point, speed_m_s)` every `1 / retarget_hz` seconds on a
      fixed schedule counted from the first `Goto` (a late tick sends one, not a burst),
      and again as for waypoint (entering guided, armed, flying).
    - Turns: from the first tick the vehicle is within `tolerance_m` of the circle (its
      ground distance from the centre), every tick adds the change of its bearing round
      the centre (wrapped to +-180 degrees), counted positive the way it flies and
      negative the other way. `update` is DONE once that sum reaches `turns * 360`
      degrees; without `turns` it is RUNNING until a transition leaves the state, and
      without a vehicle state or a centre it is RUNNING and sends nothing new.
    - A fixed-wing aircraft is not steered by lead points: ArduPlane's GUIDED loiters
      round its target, so the `Goto` is the centre itself with `loiter_radius_m` =
      `radius_m` and `loiter_ccw` for `ccw` (DO_REPOSITION's param3 and param4, which
      ArduPlane keeps for later targets until GUIDED is entered again). A `center` point
      is sent once (and again as for waypoint); an `agent`'s position on the schedule
      above. Its turns count from the first tick it is within `tolerance_m` of a circle
      up to 15 % wider than `radius_m` (ArduPlane flies 126.7 m for 120 m on SITL).
    - Modes and arming are handled as for waypoint.

    Attributes:
        radius_m: The circle's radius.
        clockwise: True for cw.
        turns: Turns to fly, None for until a transition.
        swept_deg: Angle swept round the centre the way it flies, once counting began.
    """

    name = "orbit"
    params_type = OrbitParams
    params: OrbitParams

    def __init__(self, params: OrbitParams | Mapping[str, Any]) -> None:
        super().__init__(params)
        p = self.params
        self.radius_m = float(p.radius_m)
        self.clockwise = p.direction == "cw"
        self.turns = float(p.turns) if p.turns is not None else None
        self.tolerance_m = float(p.tolerance_m)
        self.lead_rad = math.radians(float(p.lead_deg))
        self.retarget_period_s = 1.0 / float(p.retarget_hz)
        speed = p.speed_m_s
        self.speed_m_s = float(speed) if speed is not None else None
        self._leg = GuidedLeg(self.speed_m_s)
        self._loiters = False
        self._schedule = Schedule(self.retarget_period_s)
        self.swept_deg = 0.0
        self._last_bearing: float | None = None

    def centre(self, ctx: PrimitiveContext) -> Target | None:
        """The centre now: the point, or the agent's latest reported position."""
        p = self.params
        if p.center is not None:
            return Target.from_point(p.center)
        assert p.agent is not None
        status = ctx.peer_status_by_id(p.agent.agent_id)
        if status is None:
            return None
        return Target(status.lat_deg, status.lon_deg, float(p.alt_m or 0.0))

    def _relative(self, ctx: PrimitiveContext, centre: Target) -> tuple[float, float] | None:
        """The vehicle's (north, east) metres from the centre; None without a vehicle state."""
        vehicle = ctx.vehicle
        if vehicle is None:
            return None
        mean_lat = math.radians((vehicle.lat_deg + centre.lat_deg) / 2)
        north = math.radians(vehicle.lat_deg - centre.lat_deg) * EARTH_RADIUS_M
        east = math.radians(vehicle.lon_deg - centre.lon_deg) * EARTH_RADIUS_M * math.cos(mean_lat)
        return north, east

    def lead_point(self, centre: Target, north_m: float, east_m: float) -> Target:
        """The guided target for a vehicle at (north, east) metres from the centre."""
        sign = 1.0 if self.clockwise else -1.0
        bearing = bearing_rad(north_m, east_m) + sign * self.lead_rad
        # twice as far inside the circle as the vehicle is outside it (and the reverse):
        # the autopilot's lag in a turn carries it outwards, so aiming at the circle
        # itself leaves it on a wider one (ArduCopter SITL: 15.2 m for 12 m at 45 deg)
        error_m = math.hypot(north_m, east_m) - self.radius_m
        aim_m = min(max(self.radius_m - 2.0 * error_m, 0.5 * self.radius_m), 1.5 * self.radius_m)
        reach_m = aim_m / math.cos(self.lead_rad)
        lat, lon = _shift(
            centre.lat_deg, centre.lon_deg, reach_m * math.cos(bearing), reach_m * math.sin(bearing)
        )
        return Target(lat, lon, centre.alt_m)

    def start(self, ctx: PrimitiveContext) -> None:
        """Enter guided mode; aim at the first lead point when position and centre are known."""
        self._loiters = ctx.config.airframe_class == "fixed_wing"
        if self._loiters:
            self._leg = GuidedLeg(self.speed_m_s, self.radius_m, not self.clockwise)
        self._schedule = Schedule(self.retarget_period_s)
        self.swept_deg = 0.0
        self._last_bearing = None
        self._leg.begin(ctx)
        if not self._leg.failed:
            self._retarget(ctx, self.centre(ctx))

    def update(self, ctx: PrimitiveContext) -> Status:
        """Count the angle swept; DONE after ``turns``; re-target when due."""
        if self._leg.failed:
            return Status.FAILED
        centre = self.centre(ctx)
        if centre is not None:
            self._count(ctx, centre)
            if self.turns is not None and self.swept_deg >= 360.0 * self.turns:
                return Status.DONE
        self._retarget(ctx, centre)
        self._leg.track(ctx)
        return Status.RUNNING

    def _count(self, ctx: PrimitiveContext, centre: Target) -> None:
        relative = self._relative(ctx, centre)
        if relative is None:
            return
        north, east = relative
        if self._last_bearing is None:
            # ArduPlane circles up to 15 % wide (and settles onto it from outside)
            widest_m = self.radius_m * (LOITER_RADIUS_FACTOR if self._loiters else 1.0)
            distance_m = math.hypot(north, east)
            if not self.radius_m - self.tolerance_m <= distance_m <= widest_m + self.tolerance_m:
                return
            self._last_bearing = bearing_rad(north, east)
            return
        bearing = bearing_rad(north, east)
        step = math.degrees(wrap_rad(bearing - self._last_bearing))
        self._last_bearing = bearing
        self.swept_deg += step if self.clockwise else -step

    def _retarget(self, ctx: PrimitiveContext, centre: Target | None) -> None:
        if centre is None:
            return
        if self._loiters:  # ArduPlane circles its target: the centre itself
            if not self._schedule.started:
                self._schedule.begin(ctx.now_s)
            elif self.params.center is not None or not self._schedule.due(ctx.now_s):
                return  # a fixed point is sent once (and again as for waypoint)
            self._leg.go(ctx, centre)
            return
        relative = self._relative(ctx, centre)
        if relative is None:
            return
        if not self._schedule.started:
            self._schedule.begin(ctx.now_s)
        elif not self._schedule.due(ctx.now_s):
            return
        self._leg.go(ctx, self.lead_point(centre, *relative))


BEHAVIOR = Behavior(
    name="orbit",
    summary="Circle a point or another agent at a radius, cw or ccw; done after turns if given.",
    parameters=OrbitParams,
    runtime=OrbitBehavior,
    events=_events,
    traits=Traits(guided=True, flies=True),
    check=_check,
    compile=_compile,
    plan=_plan,
    agent_params=("agent",),
)
