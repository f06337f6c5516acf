"""survey: fly a lawnmower over an area, taking pictures by distance along each line.

The area is a polygon (local metres or latitude/longitude, as any point is written);
the lines are parallel, ``line_spacing_m`` apart or as far apart as the camera's
ground footprint at the survey's height allows with a ``side_overlap``, at
``heading_deg`` (by default along the area's longest edge). Each line is clipped to
the area and flown to its ends (a fixed-wing aircraft's lines run ``run_out_m`` past
the area at each end, so that it turns outside it); the lines alternate direction.

The plan is computed when the mission compiles, deterministically, and the compiled
config holds it (``lines``): the runtime flies the ends it was given, the report and
the station draw them. Pictures are asked of the camera payload at marks spaced at
most ``photo_every_m`` apart along each line inside the area (or from the footprint
and a ``forward_overlap``), first at the area's edge, last at its far edge; Picture
Data goes out on each capture, as photo_trigger sends it.

The ground footprint of a camera at a height ``h`` above flat ground at the origin's
altitude is ``h * sensor_width_mm / focal_length_mm`` across the line and ``h *
sensor_height_mm / focal_length_mm`` along it (the image's long side across the line);
the camera's payload profile declares the three figures.

With ``fly_as: auto`` the lines are not streamed as guided targets: the survey uploads
them to the autopilot as a mission (each line's start and end a waypoint, after a speed
change when the survey has a speed) and lets the autopilot fly it in its AUTO mode,
which holds a line better than a stream of targets (ArduPlane's lines, ArduCopter's
corners); the engine still takes the pictures, by the vehicle's position along each line.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from typing import TYPE_CHECKING, Any, NamedTuple

from clark_engine.behaviors.base import BehaviorRuntime, Point, Status
from clark_engine.behaviors.declaration import (
    Behavior,
    CompileContext,
    Params,
    Plan,
    Sends,
    Traits,
    param,
    raises_done,
)
from clark_engine.behaviors.flight import (
    EngineArming,
    GuidedLeg,
    ModeRequest,
    Target,
    distance_m,
)
from clark_engine.behaviors.lawnmower import (
    photo_marks,
)
from clark_engine.behaviors.photo_trigger import PhotoTriggerBehavior, PhotoTriggerParams
from clark_engine.behaviors.shared import (
    AGENT_NAME_SCHEMA,
    POINT_SCHEMA,
    RESOLVED_POINT_SCHEMA,
    SPEED_SCHEMA,
    TOLERANCE_SCHEMA,
)
from clark_engine.behaviors.survey_checks import all_checks
from clark_engine.behaviors.survey_plan import (
    AUTO_MODE,
    MAX_VERTICES,
    line_speed_m_s,
    photo_spacing_m,
    resolve,
)
from clark_engine.mission.geo import parse_point
from clark_engine.mission.schema_source.common import (
    Schema,
    altitude_m,
    array,
    number,
    obj,
    string,
)
from clark_engine.mission.schema_source.common import (
    distance_m as distance_schema,
)

if TYPE_CHECKING:
    from clark_engine.runtime.commands import MissionItem
    from clark_engine.runtime.context import PrimitiveContext
    from clark_engine.runtime.events import MissionProgress, MissionUploadResult, PayloadEvent

#: Most vertices an area may have (a field's outline needs a few dozen at most).
#: A photo mark counts as passed this close before it: the compiled ends are rounded to
#: 1e-7 degrees (about a centimetre), so a vehicle exactly on a mark may measure a hair short.
MARK_SLACK_M = 0.05
#: An upload that has had no answer at all this long (the runtime dropped it while the
#: autopilot was lost: the adapter itself answers within 7.5 s, NO_ANSWER when the
#: autopilot is silent) is sent again.
UPLOAD_RESEND_S = 10.0

_OVERLAP = "A share of the picture (0 to 0.9) that the next one covers again"
_AREA = array(
    "The area to survey: a polygon of 3 to 100 vertices, in order (clockwise or not), "
    "not crossing itself; each vertex a point in any form (its height is ignored: the "
    "survey flies at altitude_m).",
    POINT_SCHEMA,
    min_items=3,
    max_items=MAX_VERTICES,
)
_END_SCHEMA: Schema = obj(
    "One line as flown: where it starts and where it ends (run-outs included), and the "
    "stretch of it inside the area, where pictures are taken.",
    {
        "start": RESOLVED_POINT_SCHEMA,
        "end": RESOLVED_POINT_SCHEMA,
        "photo_from_m": distance_schema("Where the area starts, along the line."),
        "photo_to_m": distance_schema("Where the area ends, along the line."),
    },
    required=["start", "end", "photo_from_m", "photo_to_m"],
)


class SurveyLine(NamedTuple):
    """One compiled line of a survey.

    Attributes:
        start: Where the line is flown from (its run-out included).
        end: Where it is flown to.
        photo_from_m: Distance from ``start`` at which the area begins.
        photo_to_m: Distance from ``start`` at which the area ends.
    """

    start: Point
    end: Point
    photo_from_m: float
    photo_to_m: float

    @classmethod
    def from_config(cls, raw: Mapping[str, Any]) -> SurveyLine:
        """From a compiled ``{start, end, photo_from_m, photo_to_m}``."""
        return cls(
            Point.from_config(raw["start"]),
            Point.from_config(raw["end"]),
            float(raw["photo_from_m"]),
            float(raw["photo_to_m"]),
        )


def _lines_from_config(raw: list[Mapping[str, Any]]) -> tuple[SurveyLine, ...]:
    return tuple(SurveyLine.from_config(line) for line in raw)


class SurveyParams(Params):
    """Parameters of survey."""

    DESCRIPTION = "Parameters of survey."
    REQUIRED = ("area", "altitude_m")

    area: tuple[Any, ...] = param(
        _AREA, compiled=lambda: {**_AREA, "items": RESOLVED_POINT_SCHEMA}, convert=tuple
    )
    altitude_m: float = param(
        altitude_m(
            "Height to fly the lines at, metres above the mission origin (the engine's one "
            "datum); the camera's footprint is worked out for flat ground at the origin's "
            "altitude.",
            exclusive_minimum=0,
        )
    )
    line_spacing_m: float | None = param(
        distance_schema(
            "Distance between neighbouring lines; give this or side_overlap. The compiler "
            "writes the spacing it worked out here.",
            exclusive_minimum=0,
        )
    )
    side_overlap: float | None = param(
        number(
            _OVERLAP + " across the lines: the spacing is the footprint's width times "
            "(1 - side_overlap); needs the camera's optics.",
            minimum=0,
            maximum=0.9,
        )
    )
    heading_deg: float | None = param(
        number(
            "Direction of the lines, degrees clockwise from north; along the area's longest "
            "edge when omitted (the compiler writes the one it chose).",
            unit="deg",
            minimum=0,
            exclusive_maximum=360,
        )
    )
    speed_m_s: float | None = param(SPEED_SCHEMA)
    tolerance_m: float = param(TOLERANCE_SCHEMA)
    run_out_m: float | None = param(
        distance_schema(
            "How far each line runs past the area at both ends, so that the vehicle is on "
            "the line where the area starts and turns outside it; when omitted, tolerance_m "
            "for a fixed-wing aircraft (it counts a line's end as reached that far away), "
            "0 for others.",
            maximum=5000,
        )
    )
    photo_every_m: float | None = param(
        distance_schema(
            "Longest distance between two pictures along a line; give this or "
            "forward_overlap to take pictures, neither for none.",
            exclusive_minimum=0,
        )
    )
    forward_overlap: float | None = param(
        number(
            _OVERLAP + " along the line: pictures at most the footprint's length times "
            "(1 - forward_overlap) apart; needs the camera's optics.",
            minimum=0,
            maximum=0.9,
        )
    )
    payload: str = param(
        string(
            "Name of the camera payload on this agent.",
            pattern="^[a-z][a-z0-9_]*$",
            default="camera",
        )
    )
    to: tuple[str, ...] | None = param(
        array("Agents that receive Picture Data; every agent when omitted.", AGENT_NAME_SCHEMA),
        convert=tuple,
    )
    fly_as: str = param(
        string(
            "How the lines are flown: guided (the engine streams each line's ends as "
            "guided targets) or auto (uploaded to the autopilot as a mission of "
            "waypoints, flown in its AUTO mode; the engine still takes the pictures).",
            enum=["guided", "auto"],
            default="guided",
        )
    )
    lines: tuple[SurveyLine, ...] | None = param(
        array("The lines as the compiler planned them, in the order flown.", _END_SCHEMA),
        convert=_lines_from_config,
    )

    @classmethod
    def schema(cls) -> Schema:
        """The mission's schema: ``lines`` is the compiler's, never written by a mission."""
        out = super().schema()
        del out["properties"]["lines"]
        return out

    @classmethod
    def config_schema(cls) -> Schema:
        """The compiled config's schema: ``lines`` is required there (the runtime flies them)."""
        out = super().config_schema()
        out["required"] = [*out.get("required", []), "lines"]
        return out


# ---------------------------------------------------------------------- compile


def _compile(params: dict[str, Any], ctx: CompileContext) -> dict[str, Any]:
    origin = ctx.mission.origin
    height = float(params["altitude_m"])
    points = [parse_point(raw, origin) for raw in params["area"]]
    vertices = [(p.north_m, p.east_m) for p in points]
    plan = resolve(params, ctx.agent, vertices)
    if plan is None:  # the checks refused the mission before it got here
        raise ValueError("survey: compiled without a plan; validate the mission first")
    params["area"] = [ctx.point([n, e, height]) for n, e in vertices]
    params["line_spacing_m"] = round(plan.spacing_m, 3)
    params["heading_deg"] = round(plan.heading_deg, 6)
    params["run_out_m"] = round(plan.run_out_m, 3)
    if plan.photo_every_m is not None:
        params["photo_every_m"] = round(plan.photo_every_m, 3)
    params.setdefault("to", [])
    if params.get("fly_as") == "guided":  # the default: compiled configs as before it existed
        del params["fly_as"]
    params["lines"] = [
        {
            "start": ctx.point([line.start[0], line.start[1], height]),
            "end": ctx.point([line.end[0], line.end[1], height]),
            "photo_from_m": round(line.photo_from_m, 3),
            "photo_to_m": round(line.photo_to_m, 3),
        }
        for line in plan.lines
    ]
    return params


def _plan(params: Mapping[str, Any]) -> Plan:
    """The compiled lines' ends in the order flown; before compiling, the area's outline.

    Before compiling, the spacing may depend on the agent's camera, which a plan
    cannot see: the outline (at the survey's height) stands for the area; the
    survey's own checks check every line against the envelope.
    """
    lines = params.get("lines")
    if lines:
        points = [p for line in lines for p in (line["start"], line["end"])]
        return Plan(points=[(p, f"waypoints[{i}]") for i, p in enumerate(points)])
    height = float(params["altitude_m"])
    outline: list[Any] = []
    for raw in params["area"]:
        if isinstance(raw, Mapping) and "lat" in raw:
            outline.append({"lat": raw["lat"], "lon": raw["lon"], "alt_m": height})
        elif isinstance(raw, Mapping):
            outline.append({"north_m": raw["north_m"], "east_m": raw["east_m"], "up_m": height})
        else:
            outline.append([raw[0], raw[1], height])
    return Plan(points=[(p, f"waypoints[{i}]") for i, p in enumerate(outline)])


def _sends(params: Mapping[str, Any], agent: Any) -> Sequence[Sends]:
    """Picture Data at each photo, spaced by distance, at the line speed.

    The speed is the one asked, else the autopilot's cruise, else the airframe's top
    speed: the most often the pictures can come.
    """
    every = photo_spacing_m(params, agent)
    if every is None or every <= 0:
        return ()
    speed = line_speed_m_s(params, agent)
    if speed is None:
        airframe = agent.hardware.part("airframe") or {}
        speed = airframe.get("max_speed_m_s")
    if speed is None or float(speed) <= 0:
        return ()
    return [Sends("picture_data", every / float(speed), tuple(params.get("to") or ()))]


# ---------------------------------------------------------------------- runtime


class SurveyBehavior(BehaviorRuntime):
    """What survey commands in flight, tick by tick (its section of docs/runtime.md).

    Fly the compiled lines in order, a picture at each mark along them; done at the last end.

    - `start`: as for waypoint_tour, with `Goto(start of line 0)`; the route is each
      line's start then its end, in order, at `altitude_m`.
    - `update`: when the vehicle is within `tolerance_m` of the current end of the route
      (3-D for aircraft), the survey moves to the next one and sends its `Goto` in the
      same tick; after the last line's end it is DONE. At most one end is passed per tick.
    - Pictures: while a line is flown (from its start to its end), the vehicle's progress
      along it is measured from its ground distances to both ends; when it passes the next
      photo mark (marks evenly spaced at most `photo_every_m` apart from `photo_from_m` to
      `photo_to_m`), one `PayloadCommand(payload, "capture", request_id)` is sent, and the
      marks it has passed are spent (a late tick sends one request, not a burst). On
      arriving at a line's end, its last mark is taken if it was not. Answers are handled
      as for photo_trigger (Picture Data to `to` on each capture, `image_index` counting
      from 1 in the state).
    - No pictures are asked on the legs between lines, nor without a vehicle state.
    - Modes and arming are handled as for waypoint.

    With `fly_as: auto`:

    - `start`: one `UploadMission` of the route (each line's start and end a waypoint
      at `altitude_m`, after a speed change to `speed_m_s` when given); no `Goto`. The
      runtime's envelope guard judges the whole mission first: a waypoint or a leg
      outside the envelope, and nothing is sent and the survey is FAILED. Arming as for
      waypoint.
    - When the autopilot accepts the mission, `SetMode(AUTO)`, asked again while refused
      as for waypoint; once the vehicle reports another mode than the one it was in (the
      pilot's, the station's) it is never asked again: the survey stays RUNNING and
      follows the mission wherever the autopilot flies it (ArduPilot resumes it on
      re-entering AUTO). A refused upload (ArduPilot's MAV_MISSION_RESULT, or no answer):
      FAILED. An upload with no outcome at all after 10 s (dropped while the autopilot
      was lost) is sent again.
    - `update`: the route end being flown is the autopilot's (MISSION_ITEM_REACHED,
      MISSION_CURRENT); pictures are taken along each line as in guided flight, a line's
      last mark when the autopilot reports its end reached. DONE when the autopilot
      reports the last line's end reached and the vehicle is within `tolerance_m` of it.

    Attributes:
        lines: The compiled lines, in the order flown.
        tolerance_m: Distance that counts as arrived at a line's end.
        speed_m_s: Requested ground speed, None for the autopilot's own.
        index: The end of the route being flown to (even: a line's start; odd: its end).
        requested: Pictures asked for since the state was entered.
    """

    name = "survey"
    params_type = SurveyParams
    params: SurveyParams

    def __init__(self, params: SurveyParams | Mapping[str, Any]) -> None:
        super().__init__(params)
        self.lines = tuple(self.params.lines or ())
        self.route = tuple(
            Target.from_point(p) for line in self.lines for p in (line.start, line.end)
        )
        self.tolerance_m = float(self.params.tolerance_m)
        speed = self.params.speed_m_s
        self.speed_m_s = float(speed) if speed is not None else None
        every = self.params.photo_every_m
        self._marks = tuple(
            tuple(photo_marks(line.photo_from_m, line.photo_to_m, float(every)))
            if every is not None
            else ()
            for line in self.lines
        )
        self._camera_params = PhotoTriggerParams(
            payload=self.params.payload,
            interval_s=3600.0,
            count=None,
            to=tuple(self.params.to or ()),
        )
        self.index = 0
        self.requested = 0
        self._next_mark = 0
        self._leg = GuidedLeg(self.speed_m_s)
        self._camera = PhotoTriggerBehavior(self._camera_params)
        self._three_d = True
        self.fly_as = self.params.fly_as
        # fly_as auto: the upload's id and state (uploading, flying, failed), the route
        # index of the mission's first waypoint item, how many route ends the autopilot
        # has passed (what it reported, and what the pictures have caught up with).
        self._upload_id = 0
        self._upload_s = 0.0
        self._auto = ""
        self._first_waypoint = 0
        self._reported_passed = 0
        self._passed = 0
        self._mode = ModeRequest()
        self._arming = EngineArming()

    @property
    def captured(self) -> int:
        """Pictures the camera confirmed since the state was entered."""
        return self._camera.captured

    def start(self, ctx: PrimitiveContext) -> None:
        """Enter guided mode and send the first line's start."""
        self._three_d = ctx.config.is_aircraft
        self.index = 0
        self.requested = 0
        self._next_mark = 0
        self._camera = PhotoTriggerBehavior(self._camera_params)
        if self.fly_as == "auto":
            self._start_auto(ctx)
            return
        self._leg.begin(ctx)
        if not self._leg.failed and self.route:
            self._leg.go(ctx, self.route[0])

    def update(self, ctx: PrimitiveContext) -> Status:
        """Take the pictures due along the line; move on at each end; DONE after the last."""
        if self.fly_as == "auto":
            return self._update_auto(ctx)
        if self._leg.failed:
            return Status.FAILED
        if not self.route:
            return Status.DONE
        if self.index % 2:
            self._photograph(ctx)
        current = self.route[self.index]
        remaining_m = distance_m(ctx, current, three_d=self._three_d)
        if remaining_m is not None and remaining_m <= self.tolerance_m:
            if self.index % 2:
                self._finish_line(ctx)
            if self.index + 1 == len(self.route):
                return Status.DONE
            self.index += 1
            self._next_mark = 0
            if self.route[self.index] != current:
                self._leg.go(ctx, self.route[self.index])
        self._leg.track(ctx)
        return Status.RUNNING

    def on_payload(self, ctx: PrimitiveContext, event: PayloadEvent) -> None:
        """Count the camera's answer to one of our requests; send Picture Data on a capture."""
        self._camera.on_payload(ctx, event)

    # -- fly_as: auto -----------------------------------------------------------------

    def mission_items(self) -> tuple[MissionItem, ...]:
        """The mission a ``fly_as: auto`` survey uploads: a speed, then the route's ends."""
        from clark_engine.runtime.commands import MissionItem

        items: list[MissionItem] = []
        if self.speed_m_s is not None:
            items.append(MissionItem("speed", speed_m_s=self.speed_m_s))
        items.extend(MissionItem("waypoint", t.lat_deg, t.lon_deg, t.alt_m) for t in self.route)
        return tuple(items)

    def _start_auto(self, ctx: PrimitiveContext) -> None:
        from clark_engine.runtime.log_events import LogEvent

        self._reported_passed = self._passed = 0
        if not self.route:
            self._auto = "flying"
            return
        if AUTO_MODE not in ctx.config.modes:
            self._auto = "failed"
            ctx.log.error(
                "%s: the autopilot profile names no %s mode; cannot fly the survey as a mission",
                ctx.config.agent,
                AUTO_MODE,
                extra=LogEvent.BEHAVIOR_ERROR.extra,
            )
            return
        self._auto = "uploading"
        self._upload(ctx)
        self._arming.begin(ctx)

    def _upload(self, ctx: PrimitiveContext) -> None:
        from clark_engine.runtime.commands import UploadMission

        items = self.mission_items()
        self._first_waypoint = len(items) - len(self.route)
        self._upload_id = ctx.next_request_id()
        self._upload_s = ctx.now_s
        ctx.command(
            UploadMission(
                self._upload_id,
                items,
                f"survey: {len(self.lines)} line(s), {len(self.route)} waypoints",
            )
        )

    def on_mission(
        self, ctx: PrimitiveContext, event: MissionUploadResult | MissionProgress
    ) -> None:
        """The upload's outcome (then AUTO), or the autopilot's progress in the mission."""
        from clark_engine.runtime.events import MissionUploadResult
        from clark_engine.runtime.log_events import LogEvent

        if self.fly_as != "auto" or not self._auto:
            return
        if isinstance(event, MissionUploadResult):
            if event.upload_id != self._upload_id or self._auto != "uploading":
                return
            if not event.accepted:
                self._auto = "failed"
                ctx.log.error(
                    "survey: the mission was not uploaded: %s%s; the survey fails",
                    event.result,
                    f" ({event.reason})" if event.reason else "",
                    extra=LogEvent.AUTOPILOT_MISSION.extra,
                )
                return
            self._auto = "flying"
            ctx.log.info(
                "survey: the autopilot took the mission; flying it in %s",
                AUTO_MODE,
                extra=LogEvent.AUTOPILOT_MISSION.extra,
            )
            self._mode.begin(ctx, AUTO_MODE)
            return
        if self._auto != "flying":
            return
        index = event.item - self._first_waypoint  # the route end the item is
        passed = index + 1 if event.reached else index
        if passed > self._reported_passed:
            self._reported_passed = min(passed, len(self.route))
            if event.reached:
                ctx.log.info(
                    "survey: the autopilot reached waypoint %d of %d",
                    index + 1,
                    len(self.route),
                    extra=LogEvent.AUTOPILOT_MISSION.extra,
                )

    def _update_auto(self, ctx: PrimitiveContext) -> Status:
        if self._auto == "failed":
            return Status.FAILED
        if not self.route:
            return Status.DONE
        if self._auto == "uploading":
            # The adapter answers, or gives up, by itself; only a dropped upload is resent.
            if ctx.now_s - self._upload_s >= UPLOAD_RESEND_S:
                from clark_engine.runtime.log_events import LogEvent

                ctx.log.warning(
                    "survey: no answer to the mission's upload in %g s; sending it again",
                    UPLOAD_RESEND_S,
                    extra=LogEvent.AUTOPILOT_MISSION.extra,
                )
                self._upload(ctx)
            return Status.RUNNING
        self._mode.update(ctx)
        self._arming.update(ctx)
        while self._passed < self._reported_passed:
            # The autopilot passed route end self._passed: a line's end takes its last mark.
            if self._passed % 2 and self._passed == self.index:
                self._finish_line(ctx)
            self._passed += 1
            if self._passed < len(self.route):
                self.index = self._passed
                self._next_mark = 0
        if self._passed >= len(self.route):
            remaining_m = distance_m(ctx, self.route[-1], three_d=self._three_d)
            if remaining_m is not None and remaining_m <= self.tolerance_m:
                return Status.DONE
            return Status.RUNNING
        if self.index % 2:
            self._photograph(ctx)
        return Status.RUNNING

    def _progress_m(self, ctx: PrimitiveContext) -> float | None:
        """How far along the current line the vehicle is (ground), None without a position."""
        line = self.lines[self.index // 2]
        start, end = self.route[self.index - 1], self.route[self.index]
        from_start = ctx.distance_to_m(start.lat_deg, start.lon_deg)
        to_end = ctx.distance_to_m(end.lat_deg, end.lon_deg)
        if from_start is None or to_end is None:
            return None
        length = math.hypot(
            line.end.north_m - line.start.north_m, line.end.east_m - line.start.east_m
        )
        if length <= 0:
            return 0.0
        return (from_start**2 - to_end**2 + length**2) / (2.0 * length)

    def _photograph(self, ctx: PrimitiveContext) -> None:
        marks = self._marks[self.index // 2]
        if self._next_mark >= len(marks):
            return
        progress = self._progress_m(ctx)
        if progress is None or progress + MARK_SLACK_M < marks[self._next_mark]:
            return
        while self._next_mark < len(marks) and marks[self._next_mark] <= progress + MARK_SLACK_M:
            self._next_mark += 1
        self._request(ctx)

    def _finish_line(self, ctx: PrimitiveContext) -> None:
        marks = self._marks[self.index // 2]
        if self._next_mark < len(marks) and ctx.vehicle is not None:
            self._next_mark = len(marks)
            self._request(ctx)

    def _request(self, ctx: PrimitiveContext) -> None:
        self.requested += 1
        self._camera.request(ctx)


BEHAVIOR = Behavior(
    name="survey",
    summary="Fly a lawnmower over an area, lines spaced from the camera's footprint, "
    "pictures by distance; done at the last line's end.",
    parameters=SurveyParams,
    runtime=SurveyBehavior,
    events=raises_done,
    traits=Traits(guided=True, flies=True, takes_pictures=True),
    check=all_checks,
    compile=_compile,
    plan=_plan,
    sends=_sends,
)
