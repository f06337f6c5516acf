"""The envelope guard's judgement of a mission to fly in AUTO (an UploadMission).

A Goto is judged one target at a time, as it leaves, and moved inside the envelope when
it is not. A mission is the autopilot's to fly once uploaded: the engine never sees its
targets go out one by one, and half a mission (the items up to the first outside) is
worse than none, since the vehicle would fly a plan nobody wrote. So an upload is judged
whole before it leaves the core, and goes out as it is or not at all:

- every waypoint inside the geofence by ``margin_m`` (a fixed-wing aircraft's by its
  loiter radius more, as for its Gotos: ArduPlane circles a point it cannot pass), and
  each leg from one waypoint to the next, and from where the vehicle is to the first,
  inside it too;
- for aircraft, every waypoint's height between the floor and the ceiling, each by
  ``margin_m`` (the engine's datum: metres above the origin; the adapter converts to
  ArduPilot's height above home only when it encodes the items). A rover's height is
  the ground's: not judged.

Separation from other vehicles cannot be judged for a plan flown later; the runtime's
watch keeps judging it in flight (:class:`~clark_engine.runtime.envelope.EnvelopeWatch`).
A refusal is counted and logged by the guard as its other refusals are
(``envelope.limit``), whatever ``outside`` says: a mission is never clamped. The
runtime then hands the behaviour a refused :class:`MissionUploadResult` (``ENVELOPE``),
and the survey fails.
"""

from __future__ import annotations

import math
from typing import TYPE_CHECKING

from clark_engine.mission.geo import Origin, to_local
from clark_engine.runtime.commands import UploadMission
from clark_engine.runtime.events import MissionUploadResult, VehicleState

if TYPE_CHECKING:
    from clark_engine.runtime.envelope_guard import EnvelopeGuard

ENVELOPE_RESULT = "ENVELOPE"
"""A :class:`MissionUploadResult`'s ``result`` when the runtime's guard refused the upload."""

_STRAIGHT_M = 1e-3
"""A leg whose fence clamp moves its end less than this stays inside (float round-off)."""


def judge_upload(
    guard: EnvelopeGuard,
    upload: UploadMission,
    vehicle: VehicleState | None,
    origin: Origin,
    now_s: float,
) -> UploadMission | None:
    """The upload itself when every waypoint and leg is inside the envelope; else None.

    Args:
        guard: The runtime's guard (its envelope, its config, its counts and log).
        upload: The upload the behaviour issued.
        vehicle: The vehicle's latest state: the first leg starts there (None: not judged).
        origin: The mission's origin.
        now_s: The runtime clock, for the log.
    """
    problems = mission_problems(guard, upload, vehicle, origin)
    if not problems:
        return upload
    reasons = tuple(dict.fromkeys(kind for kind, _ in problems))
    shown = "; ".join(note for _, note in problems[:3])
    more = f"; and {len(problems) - 3} more" if len(problems) > 3 else ""
    guard._refuse(  # the guard counts and logs it as its own
        "UploadMission",
        reasons,
        f"{upload.what or 'the mission'}: {shown}{more}; the whole mission not sent "
        "(never half a mission)",
        now_s,
    )
    return None


def mission_problems(
    guard: EnvelopeGuard,
    upload: UploadMission,
    vehicle: VehicleState | None,
    origin: Origin,
) -> list[tuple[str, str]]:
    """Every (reason, note) that keeps the mission out of the envelope, in item order."""
    env = guard.envelope
    aircraft = guard.config.is_aircraft
    speed = next((i.speed_m_s for i in upload.items if i.kind == "speed"), None)
    inset_m = env.margin_m + guard._loiter(speed)  # inset as for a Goto
    low, high = env.floor_m + env.margin_m, env.ceiling_m - env.margin_m
    problems: list[tuple[str, str]] = []
    previous: tuple[float, float] | None = None
    if vehicle is not None:
        here = to_local(vehicle.lat_deg, vehicle.lon_deg, vehicle.alt_m, origin)
        previous = (here.north_m, here.east_m)
    for index, item in enumerate(upload.items):
        if not item.navigates:
            continue
        point = to_local(item.lat_deg, item.lon_deg, item.alt_m, origin)
        where = f"item {index} (north {point.north_m:.1f} m, east {point.east_m:.1f} m)"
        if aircraft and point.up_m > high + 1e-6:
            problems.append(
                (
                    "ceiling",
                    f"{where} at {point.up_m:.1f} m above the origin is over the ceiling "
                    f"{env.ceiling_m:g} m less the {env.margin_m:g} m margin",
                )
            )
        if aircraft and point.up_m < low - 1e-6:
            problems.append(
                (
                    "floor",
                    f"{where} at {point.up_m:.1f} m above the origin is under the floor "
                    f"{env.floor_m:g} m and the {env.margin_m:g} m margin",
                )
            )
        target = (point.north_m, point.east_m)
        margin = env.fence.margin_m(*target)
        if margin < inset_m - 1e-6:
            problems.append(
                (
                    "fence",
                    f"{where} is {margin:.1f} m inside the geofence, closer to its edge than "
                    f"the {inset_m:g} m kept"
                    if margin >= 0
                    else f"{where} is {-margin:.1f} m outside the geofence",
                )
            )
        elif previous is not None and env.fence.margin_m(*previous) >= inset_m - 1e-6:
            kept = env.fence.clamp(previous, target, inset_m)
            if kept is None or math.dist(kept, target) > _STRAIGHT_M:
                problems.append(
                    (
                        "fence",
                        f"the straight leg to {where} from north {previous[0]:.1f} m, east "
                        f"{previous[1]:.1f} m leaves the geofence",
                    )
                )
        previous = target
    return problems


def refused_by_envelope(upload: UploadMission) -> MissionUploadResult:
    """What the behaviour hears of an upload the guard refused (the log says why)."""
    return MissionUploadResult(
        upload.upload_id,
        False,
        ENVELOPE_RESULT,
        "a waypoint or leg outside the envelope (envelope.limit in the mission log)",
    )
