"""survey's plan: its limits, and its parameters resolved against the agent's camera and airframe.

What both the checks before flight (:mod:`~clark_engine.behaviors.survey_checks`) and the
compile and runtime (:mod:`~clark_engine.behaviors.survey`) need: the line spacing and
photo distance from the camera's footprint, the run-out past the area, the firmware's
AUTO limits. Its own module so that the checks and the runtime class share it without
importing each other.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import TYPE_CHECKING, Any, NamedTuple

from clark_engine.behaviors.lawnmower import (
    Line,
    lawnmower,
    line_count,
    longest_edge_heading_deg,
    polygon_area_m2,
    self_crossing,
)

if TYPE_CHECKING:
    pass


MAX_VERTICES = 100
#: Most lines a survey may fly: bounds the compiled config and the work of checking it
#: (each line's ends and legs are checked against the envelope).
MAX_LINES = 200
#: Smallest area, square metres: anything smaller is a mistake (points in degrees
#: written as metres, a repeated vertex).
MIN_AREA_M2 = 1.0
#: Camera optics a footprint needs, as the payload profile names them.
OPTICS = ("sensor_width_mm", "sensor_height_mm", "focal_length_mm")
#: The autopilot mode a ``fly_as: auto`` survey flies its uploaded mission in.
AUTO_MODE = "AUTO"
#: Firmware that fly an uploaded mission in AUTO, and the most mission items each stores
#: (home included; "Only N items are supported", measured on SITL 4.7).
AUTO_MISSION_ITEMS = {"arducopter": 650, "arduplane": 655, "ardurover": 655}
#: How far from its last waypoint a firmware may end a mission, metres, when the
#: autopilot profile's parameters do not say: the parameter, and its value. ArduRover
#: stops where it counts the waypoint reached (WP_RADIUS, 2 m by default, 3 m in
#: ArduPilot's SITL); ArduPlane turns to RTL there (WP_RADIUS, 90 m by default).
#: ArduCopter settles on the waypoint itself: no radius to meet.
WAYPOINT_RADIUS = {
    "arduplane": ("WP_RADIUS", 90.0),
    "ardurover": ("WP_RADIUS", 3.0),
}


# -------------------------------------------------------------- resolved parameters


class Resolved(NamedTuple):
    """A survey's plan in local metres, worked out from its parameters and its camera.

    Attributes:
        vertices: The area, (north_m, east_m).
        spacing_m: Distance between lines.
        heading_deg: Direction of the lines.
        run_out_m: Extension past the area at both ends of each line.
        photo_every_m: Longest distance between pictures; None for no pictures.
        lines: The lines, in the order flown.
    """

    vertices: list[tuple[float, float]]
    spacing_m: float
    heading_deg: float
    run_out_m: float
    photo_every_m: float | None
    lines: list[Line]


def footprint_m(camera: Mapping[str, Any], height_m: float) -> tuple[float, float] | None:
    """(across, along) the ground a picture covers from ``height_m``; None without optics."""
    if any(camera.get(key) is None for key in OPTICS):
        return None
    focal = float(camera["focal_length_mm"])
    return (
        height_m * float(camera["sensor_width_mm"]) / focal,
        height_m * float(camera["sensor_height_mm"]) / focal,
    )


def survey_camera(agent: Any, params: Mapping[str, Any]) -> Mapping[str, Any] | None:
    """The camera payload the survey names, or None when that payload is not a camera."""
    payload = agent.hardware.payloads.get(str(params["payload"]))
    return payload if payload is not None and payload.get("payload_kind") == "camera" else None


def wants_photos(params: Mapping[str, Any]) -> bool:
    """Whether the survey takes pictures: a photo distance or a forward overlap given."""
    return params.get("photo_every_m") is not None or params.get("forward_overlap") is not None


def _default_run_out_m(agent: Any, params: Mapping[str, Any]) -> float:
    if params.get("run_out_m") is not None:
        return float(params["run_out_m"])
    return float(params["tolerance_m"]) if agent.airframe_class == "fixed_wing" else 0.0


def line_speed_m_s(params: Mapping[str, Any], agent: Any) -> float | None:
    """The speed the lines are flown at: asked, else the autopilot's cruise, else None."""
    if params.get("speed_m_s") is not None:
        return float(params["speed_m_s"])
    autopilot = agent.hardware.part("autopilot") or {}
    parameters = autopilot.get("parameters") or {}
    if agent.airframe_class == "fixed_wing":
        return float(parameters.get("AIRSPEED_CRUISE", 15.0))
    if "WPNAV_SPEED" in parameters:
        return float(parameters["WPNAV_SPEED"]) / 100.0
    if "WP_SPEED" in parameters:
        return float(parameters["WP_SPEED"])
    return None


def photo_spacing_m(params: Mapping[str, Any], agent: Any) -> float | None:
    """How far apart the pictures are along a line, metres (None: it takes none).

    Asked (``photo_every_m``), or from the camera's footprint and the forward overlap.
    """
    every = params.get("photo_every_m")
    if every is not None:
        return float(every)
    overlap = params.get("forward_overlap")
    camera = survey_camera(agent, params)
    if overlap is None or camera is None:
        return None
    footprint = footprint_m(camera, float(params["altitude_m"]))
    return None if footprint is None else footprint[1] * (1.0 - float(overlap))


def resolve(
    params: Mapping[str, Any], agent: Any, vertices: list[tuple[float, float]]
) -> Resolved | None:
    """The plan, or None when the parameters or the camera cannot give one (checks say why)."""
    height = float(params["altitude_m"])
    camera = survey_camera(agent, params)
    footprint = footprint_m(camera, height) if camera is not None else None
    spacing = params.get("line_spacing_m")
    if spacing is None:
        overlap = params.get("side_overlap")
        if overlap is None or footprint is None:
            return None
        spacing = footprint[0] * (1.0 - float(overlap))
    every = photo_spacing_m(params, agent)
    if every is None and params.get("forward_overlap") is not None:
        return None  # no footprint to space them by (the checks say why)
    if float(spacing) <= 0 or (every is not None and float(every) <= 0):
        return None
    if len(vertices) < 3 or polygon_area_m2(vertices) < MIN_AREA_M2 or self_crossing(vertices):
        return None
    heading = params.get("heading_deg")
    heading = float(heading) if heading is not None else longest_edge_heading_deg(vertices)
    if line_count(vertices, float(spacing), heading) > MAX_LINES:
        return None
    run_out = _default_run_out_m(agent, params)
    lines = lawnmower(vertices, float(spacing), heading, run_out)
    return Resolved(
        vertices,
        float(spacing),
        heading,
        run_out,
        float(every) if every is not None else None,
        lines,
    )
