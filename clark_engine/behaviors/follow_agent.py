"""follow_agent: drive or fly to another agent's reported position, plus an offset.

The target's position comes from its Agent Status messages, so the target must
send agent_status, to this agent, at least as often as the follower re-targets
(thesis 5.2.1: Slash B drives to Slash A). The guided target leads the target by
``lead_s`` along its reported velocity, so that the follower keeps up with it.
Done on reaching the target unless ``continuous``.

The offset is in one of two frames: fixed to the ground (``north_m``, ``east_m``,
``up_m``) or the target's own (``behind_m``, ``left_m``, ``above_m``), which turns
with the target's heading so that a formation keeps its shape through every turn.
One module owns both: a formation is a follower keeping its place beside a leader,
and only the frame of that place differs (docs/tutorial.md, "Formations").
"""

from __future__ import annotations

import math
from collections.abc import Iterator, Mapping
from typing import TYPE_CHECKING, Any, NamedTuple

from clark_engine.behaviors.base import AgentRef, BehaviorRuntime, Status
from clark_engine.behaviors.declaration import (
    Behavior,
    CompileContext,
    Params,
    Traits,
    UseContext,
    param,
)
from clark_engine.behaviors.flight import GuidedLeg, Schedule, Target, distance_m
from clark_engine.behaviors.shared import (
    AGENT_NAME_SCHEMA,
    RESOLVED_AGENT_SCHEMA,
    TOLERANCE_SCHEMA,
    check_agents_exist,
    check_position_reports,
    status_gap,
)
from clark_engine.mission.envelope_checks import (
    goal_distance_range,
    possible_heights,
    separation_m,
    separation_source,
    vertically_apart,
)
from clark_engine.mission.findings import Finding, error, warning
from clark_engine.mission.model import Agent
from clark_engine.mission.schema_source.common import (
    Schema,
    altitude_m,
    boolean,
    number,
    obj,
    position_m,
)

if TYPE_CHECKING:
    from clark_engine.link.messages import AgentStatus
    from clark_engine.runtime.context import PrimitiveContext


class Offset(NamedTuple):
    """Where the follower keeps itself relative to its target.

    Attributes:
        north_m: Metres north of the target.
        east_m: Metres east of it.
        up_m: Metres above it.
    """

    north_m: float = 0.0
    east_m: float = 0.0
    up_m: float = 0.0

    @classmethod
    def from_config(cls, raw: Mapping[str, Any]) -> Offset:
        """From a compiled ``offset`` (every key present)."""
        return cls(float(raw["north_m"]), float(raw["east_m"]), float(raw["up_m"]))


#: The leader's reported heading turns its followers' places only while it moves at least
#: this fast: its Agent Status then carries its course over ground (the autopilot adapter
#: sends the course from 0.5 m/s, ``io.autopilot_decode.MOVING_SPEED_M_S``, its yaw
#: below). Standing or creeping (where a GPS's noise turns a course round), it keeps the
#: heading it last moved along, so that its followers do not spin round it in place.
COURSE_MIN_SPEED_M_S = 0.5


class LeaderOffset(NamedTuple):
    """Where the follower keeps itself in its target's own frame (turning with it).

    Attributes:
        behind_m: Metres behind the target, along its heading (negative: ahead of it).
        left_m: Metres to its left (negative: to its right).
        above_m: Metres above it: the target's reported altitude, as ``up_m``.
    """

    behind_m: float = 0.0
    left_m: float = 0.0
    above_m: float = 0.0

    def north_east_m(self, heading_deg: float) -> tuple[float, float]:
        """The offset north and east for a target heading ``heading_deg`` (clockwise from north).

        Ahead is (cos h, sin h) north/east, left is ahead turned 90 degrees
        anticlockwise: (sin h, -cos h).
        """
        heading = math.radians(heading_deg)
        ahead_north, ahead_east = math.cos(heading), math.sin(heading)
        north = -self.behind_m * ahead_north + self.left_m * ahead_east
        east = -self.behind_m * ahead_east - self.left_m * ahead_north
        return north, east


def _offset_from_config(raw: Mapping[str, Any]) -> Offset | LeaderOffset:
    """A compiled ``offset`` in either frame (every key of its frame present)."""
    if "behind_m" in raw:
        return LeaderOffset(float(raw["behind_m"]), float(raw["left_m"]), float(raw["above_m"]))
    return Offset.from_config(raw)


#: The two frames' keys, in the order the reference lists them.
GROUND_KEYS = ("north_m", "east_m", "up_m")
LEADER_KEYS = ("behind_m", "left_m", "above_m")


def _ground_properties() -> dict[str, Schema]:
    return {
        "north_m": position_m("Metres north of the target.", default=0),
        "east_m": position_m("Metres east of the target.", default=0),
        "up_m": altitude_m("Metres above the target.", default=0),
    }


def _leader_properties() -> dict[str, Schema]:
    return {
        "behind_m": position_m(
            "Metres behind the target, along its heading (negative: ahead of it); turns "
            "with the target.",
            default=0,
        ),
        "left_m": position_m(
            "Metres to the target's left (negative: to its right); turns with the target.",
            default=0,
        ),
        "above_m": altitude_m(
            "Metres above the target's reported altitude (the datum of up_m).", default=0
        ),
    }


_ONE_FRAME = (
    "an offset is in one frame: behind_m/left_m/above_m (the target's own, turning with "
    "it) or north_m/east_m/up_m (fixed to the ground), not both; write above_m for the "
    "height with behind_m/left_m"
)


def _offset_schema() -> Schema:
    """The mission's ``offset``: either frame's keys, never both (E-CONFLICT at the key)."""
    out = obj(
        "Offset from the target's position, in metres: north_m/east_m/up_m fixed to the "
        "ground, or behind_m/left_m/above_m in the target's own frame, which turns with "
        "its heading (its course while it moves at "
        f"{COURSE_MIN_SPEED_M_S:g} m/s or more, else the heading it last moved along). "
        "One frame per offset.",
        {**_ground_properties(), **_leader_properties()},
    )
    out["if"] = {"anyOf": [{"required": [key]} for key in LEADER_KEYS]}
    out["then"] = {
        "properties": {key: {"not": {}, "description": _ONE_FRAME} for key in GROUND_KEYS}
    }
    return out


def _compiled_offset_schema() -> Schema:
    """A compiled ``offset``: every key of exactly one frame."""
    return {
        "description": "Offset from the target, every key of one frame present.",
        "oneOf": [
            obj("Fixed to the ground.", _ground_properties(), required=list(GROUND_KEYS)),
            obj("In the target's frame.", _leader_properties(), required=list(LEADER_KEYS)),
        ],
    }


class FollowAgentParams(Params):
    """Parameters of follow_agent."""

    DESCRIPTION = "Parameters of follow_agent."
    REQUIRED = ("target",)

    target: AgentRef = param(
        AGENT_NAME_SCHEMA, compiled=lambda: RESOLVED_AGENT_SCHEMA, convert=AgentRef.from_config
    )
    offset: Offset | LeaderOffset | None = param(
        _offset_schema(), compiled=_compiled_offset_schema, convert=_offset_from_config
    )
    retarget_hz: float = param(
        number(
            "How often the guided target is moved to the target's latest position.",
            unit="Hz",
            exclusive_minimum=0,
            maximum=50,
            default=1,
        )
    )
    lead_s: float = param(
        number(
            "Aim this many seconds ahead of the target, along the velocity it reports: "
            "ArduPilot trails a moving guided target (ArduRover by about 2.3 s of its "
            "speed, measured on SITL), so a follower aimed at where the target is never "
            "reaches it. 0 aims at the reported position.",
            unit="s",
            minimum=0,
            maximum=30,
            default=2.5,
        )
    )
    tolerance_m: float = param(TOLERANCE_SCHEMA)
    continuous: bool = param(
        boolean("Keep following after reaching the target instead of finishing.", default=False)
    )


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
    retarget_hz = float(ctx.params["retarget_hz"])
    reported = status_gap(target, me.name) is None
    yield from check_position_reports(
        ctx,
        target,
        "target",
        ("E-FOLLOW-STATUS", "W-FOLLOW-RATE"),
        "where it is",
        f"re-targets at {retarget_hz:g} Hz",
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


class _Written(NamedTuple):
    """The offset as the mission wrote it, for the checks: its frame's names and figures.

    Before flight the target's heading is unknown, so a leader-frame offset's ground
    part is checked by its length (the same whatever the heading): it is given as
    ``north_m = -behind_m``, ``east_m = -left_m``, whose norm is the same.
    """

    north_m: float
    east_m: float
    up_m: float
    up_key: str
    example: str

    @classmethod
    def of(cls, ctx: UseContext) -> _Written:
        offset = ctx.params.get("offset") or {}
        if any(key in offset for key in LEADER_KEYS):
            behind, left, above = (float(offset.get(k, 0.0)) for k in LEADER_KEYS)
            return cls(-behind, -left, above, "above_m", "behind_m: {need:g}")
        north, east, up = (float(offset.get(k, 0.0)) for k in GROUND_KEYS)
        return cls(north, east, up, "up_m", "north_m: -{need:g}")


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
    written = _Written.of(ctx)
    north, east, up = written.north_m, written.east_m, written.up_m
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
                f"{mine.describe_ceiling()} wherever {target.name} goes; lower "
                f"offset.{written.up_key} to at most {mine.ceiling_m - mine.margin_m - low:g} m",
                ctx.use_location,
            )
            return
        if highest < mine.floor_m:
            yield error(
                "E-FOLLOW-HEIGHT",
                offset_at,
                f"{me.name} aims {up:g} m above {target.name} ({where_target}), so at most "
                f"{highest:g} m above the origin, under its floor of {mine.floor_m:g} m "
                f"wherever {target.name} goes; raise offset.{written.up_key} to at least "
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
                f"of at least {need:g} m (such as offset: "
                f"{{{written.example.format(need=need)}}}), or, if the two are meant to meet, "
                "lower the pair's separation in envelope.separation",
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


def _compile(params: dict[str, Any], ctx: CompileContext) -> dict[str, Any]:
    target = ctx.mission.agents[params["target"]]
    params["target"] = {"name": target.name, "id": target.id}
    written = params.get("offset") or {}
    keys = LEADER_KEYS if any(key in written for key in LEADER_KEYS) else GROUND_KEYS
    offset: dict[str, Any] = dict.fromkeys(keys, 0)
    offset.update(written)
    params["offset"] = offset
    return params


class FollowAgentBehavior(BehaviorRuntime):
    """What follow_agent commands in flight, tick by tick (its section of docs/runtime.md).

    Go to another agent's reported position plus an offset.

    - The target's position is its latest Agent Status in the fleet table (peeked, so the
      new-data flag is left to others); the *goal* is that position moved by `offset` north and
      east, and `offset.up_m` above the target's altitude.
    - A leader-frame offset (`behind_m`, `left_m`, `above_m`) is turned by the target's
      heading first: the `heading_deg` of its Agent Status (its course over ground, from
      the velocity its autopilot reports) while its `ground_speed_m_s` is at least
      0.5 m/s, else the heading last taken while it moved, so that a leader standing
      still keeps its followers where they were (no spin in place as its reported
      heading wanders); the first status of a
      leader never seen moving gives its heading as reported. `above_m` is above the
      target's reported altitude, as `up_m`.
    - The guided target *leads* the goal: it is the goal moved `lead_s` seconds (default 2.5)
      ahead along the velocity the target reports (its ground speed and heading), because
      ArduPilot trails a moving guided target (ArduRover by about 2.3 s of its speed,
      measured on SITL) and a follower aimed at where the target is never reaches it.
      `lead_s: 0` aims at the goal itself. Each `Goto` also carries the target's velocity
      (north and east): ArduCopter flies it as a moving target; ArduRover and ArduPlane get
      the position only. No speed is requested.
    - `start`: `SetMode(guided)` and `Arm` as for waypoint, and a `Goto` at once when a status
      is known.
    - Re-targeting: until the first `Goto`, each tick looks for a status (none yet: RUNNING,
      no command). After it, a `Goto` to the latest aim every `1 / retarget_hz` seconds on a
      fixed schedule counted from the first `Goto` (no drift; a late tick sends one, not a
      burst), and again as for waypoint (entering guided, armed, flying). A stale status is
      still followed; `lost:<agent>` is the machine's business.
    - `update`: DONE (unless `continuous`) once the vehicle is within `tolerance_m` of the
      goal (not the lead) computed from the latest status; never done without a vehicle
      state or a status.
    - Modes and arming are handled as for waypoint.

    Attributes:
        target_name: The agent followed.
        target_id: Its id: the fleet table is read by id (loading proved it is a peer's).
        offset_north_m: Metres north of the target.
        offset_east_m: Metres east of the target.
        offset_up_m: Metres above the target.
        leader_offset: The offset in the target's frame, or None for a ground-fixed one.
        retarget_period_s: Time between Gotos once the target is known.
        tolerance_m: Distance that counts as arrived.
        continuous: Never finish; keep following.
    """

    name = "follow_agent"
    params_type = FollowAgentParams
    params: FollowAgentParams

    def __init__(self, params: FollowAgentParams | Mapping[str, Any]) -> None:
        super().__init__(params)
        p = self.params
        self.target_name = p.target.name
        self.target_id = p.target.agent_id
        offset = p.offset or Offset()
        self.leader_offset = offset if isinstance(offset, LeaderOffset) else None
        if isinstance(offset, LeaderOffset):
            self.offset_north_m, self.offset_east_m = 0.0, 0.0
            self.offset_up_m = offset.above_m
        else:
            self.offset_north_m = offset.north_m
            self.offset_east_m = offset.east_m
            self.offset_up_m = offset.up_m
        self._leader_heading_deg: float | None = None
        self.retarget_period_s = 1.0 / float(p.retarget_hz)
        self.lead_s = float(p.lead_s)
        self.tolerance_m = float(p.tolerance_m)
        self.continuous = bool(p.continuous)
        self._leg = GuidedLeg(None)
        self._three_d = True
        self._schedule = Schedule(self.retarget_period_s)

    def leader_heading_deg(self, status: AgentStatus) -> float:
        """The target's heading for a leader-frame offset: as reported while it moves.

        Below :data:`COURSE_MIN_SPEED_M_S` the heading last taken is kept (a standing
        leader's reported heading is noise, and a follower turned by it would circle
        round it); a leader never seen moving gives its heading as first reported.
        """
        if self._leader_heading_deg is None or status.ground_speed_m_s >= COURSE_MIN_SPEED_M_S:
            self._leader_heading_deg = status.heading_deg % 360.0
        return self._leader_heading_deg

    def offset_north_east_m(self, status: AgentStatus) -> tuple[float, float]:
        """The offset north and east of the target for a status of it (turned, if need be)."""
        if self.leader_offset is None:
            return self.offset_north_m, self.offset_east_m
        return self.leader_offset.north_east_m(self.leader_heading_deg(status))

    def goal(self, status: AgentStatus) -> Target:
        """Where to be for a given status of the target: its position plus the offset."""
        from clark_engine.runtime.context import offset_position

        north_m, east_m = self.offset_north_east_m(status)
        lat_deg, lon_deg = offset_position(status.lat_deg, status.lon_deg, north_m, east_m)
        return Target(lat_deg, lon_deg, status.alt_m + self.offset_up_m)

    @staticmethod
    def velocity(status: AgentStatus) -> tuple[float, float]:
        """The target's reported velocity north and east, m/s."""
        heading = math.radians(status.heading_deg)
        speed = max(status.ground_speed_m_s, 0.0)
        return speed * math.cos(heading), speed * math.sin(heading)

    def aim(self, status: AgentStatus) -> Target:
        """The guided target: the goal moved ``lead_s`` ahead along the target's velocity."""
        from clark_engine.runtime.context import offset_position

        goal = self.goal(status)
        north, east = self.velocity(status)
        lat_deg, lon_deg = offset_position(
            goal.lat_deg, goal.lon_deg, north * self.lead_s, east * self.lead_s
        )
        return Target(lat_deg, lon_deg, goal.alt_m)

    def start(self, ctx: PrimitiveContext) -> None:
        """Enter guided mode; send the goal at once when the target's status is known."""
        self._three_d = ctx.config.is_aircraft
        self._schedule = Schedule(self.retarget_period_s)
        self._leader_heading_deg = None
        self._leg.begin(ctx)
        if not self._leg.failed:
            self._retarget(ctx, ctx.peer_status_by_id(self.target_id))

    def update(self, ctx: PrimitiveContext) -> Status:
        """DONE at the goal unless continuous; otherwise re-target when due."""
        if self._leg.failed:
            return Status.FAILED
        status = ctx.peer_status_by_id(self.target_id)
        if status is not None and not self.continuous:
            remaining_m = distance_m(ctx, self.goal(status), three_d=self._three_d)
            if remaining_m is not None and remaining_m <= self.tolerance_m:
                return Status.DONE
        self._retarget(ctx, status)
        self._leg.track(ctx)
        return Status.RUNNING

    def _retarget(self, ctx: PrimitiveContext, status: AgentStatus | None) -> None:
        if status is None:
            return
        if not self._schedule.started:  # the first Goto: as soon as the target is known
            self._schedule.begin(ctx.now_s)
        elif not self._schedule.due(ctx.now_s):
            return
        self._leg.go(ctx, self.aim(status), self.velocity(status))


BEHAVIOR = Behavior(
    name="follow_agent",
    summary="Go to another agent's reported position plus an offset; done on reaching it.",
    parameters=FollowAgentParams,
    runtime=FollowAgentBehavior,
    events=_events,
    traits=Traits(guided=True, flies=True),
    check=_check,
    compile=_compile,
    agent_params=("target",),
)
