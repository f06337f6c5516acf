"""Building a model: :func:`make_vehicle`, the model for an airframe profile's class.

Apart from the models because it is the one place that knows all three (the dry run, the
tests and the benchmarks build vehicles here), and checks what a profile and a start
point must give before any model is made.
"""

from __future__ import annotations

import random
from collections.abc import Mapping, Sequence
from typing import Any

from clark_engine.mission.geo import Origin
from clark_engine.sim.ardupilot.airframes.base import (
    DEFAULT_GPS_NOISE_M,
    DEFAULT_GPS_RATE_HZ,
    DEFAULT_GPS_VERTICAL_NOISE_M,
    DEFAULT_RC_OVERRIDE_TIMEOUT_S,
    SimulatedVehicle,
)
from clark_engine.sim.ardupilot.airframes.fixed_wing import FixedWing
from clark_engine.sim.ardupilot.airframes.multirotor import Multirotor
from clark_engine.sim.ardupilot.airframes.profile import (
    AirframeLimits,
    ChannelLike,
    VehicleSetupError,
)
from clark_engine.sim.ardupilot.airframes.rover import Rover

_MODELS: dict[str, type[SimulatedVehicle]] = {
    "multirotor": Multirotor,
    "fixed_wing": FixedWing,
    "rover": Rover,
}


def make_vehicle(
    airframe: Mapping[str, Any],
    autopilot: Mapping[str, Any],
    channels: Mapping[str, ChannelLike | Mapping[str, Any]] | None,
    origin: Origin | tuple[float, float, float],
    start: Sequence[float],
    rng: random.Random,
    *,
    gps_noise_m: float = DEFAULT_GPS_NOISE_M,
    gps_vertical_noise_m: float | None = None,
    gps_rate_hz: float | None = None,
    heading_deg: float = 0.0,
    armed: bool = True,
    mode: str | None = None,
    rc_override_timeout_s: float | None = DEFAULT_RC_OVERRIDE_TIMEOUT_S,
) -> SimulatedVehicle:
    """Build the model for an airframe profile's class, flying an autopilot profile.

    Args:
        airframe: The resolved airframe profile (a compiled config's
            ``agent.hardware.airframe``): ``class`` and the limits.
        autopilot: The resolved autopilot profile (``agent.hardware.autopilot``):
            ``modes``, the mode roles, and ``channels`` unless given separately.
        channels: Channel name -> rc/servo number and pulse widths (a config's
            ``AgentConfig.channels`` or the raw mapping); None for the autopilot's.
        origin: The mission origin (an Origin or latitude, longitude, altitude).
        start: Start point (north_m, east_m[, up_m]) from the origin; up_m above 0
            starts an aircraft flying (a fixed wing at cruise speed, level; a
            multirotor hovering); rovers are always on the ground.
        rng: The vehicle's seeded generator (GPS errors); nothing else is random.
        gps_noise_m: Standard deviation of the GPS error on each horizontal axis.
        gps_vertical_noise_m: Standard deviation of the GPS altitude error; None:
            twice ``gps_noise_m`` (a receiver's vertical error is about twice its
            horizontal one: :data:`DEFAULT_GPS_VERTICAL_NOISE_M` by default, none for
            a noise-free GPS).
        gps_rate_hz: GPS fix rate; the autopilot profile's ``gps_rate_hz`` when None,
            else :data:`DEFAULT_GPS_RATE_HZ`.
        heading_deg: Heading at the start.
        armed: Armed at the start (the dry run arms a vehicle its pilot hands over in
            flight; one on the ground is armed later, through its autopilot).
        mode: Mode at the start; the hold mode for aircraft, the manual mode for
            rovers when None (the mission's ``sim.mode`` default).
        rc_override_timeout_s: How long an RC override lasts unless refreshed;
            None: until released.

    Raises:
        VehicleSetupError: The airframe class has no model, a limit is missing,
            the start mode is unknown or refused, or an airborne start is disarmed.
    """
    airframe_class = airframe.get("class")
    model = _MODELS.get(str(airframe_class))
    if model is None:
        raise VehicleSetupError(
            f"no vehicle model for airframe class {airframe_class!r}; "
            f"expected one of {', '.join(sorted(_MODELS))}"
        )
    if not isinstance(autopilot.get("modes"), Mapping) or not autopilot["modes"]:
        raise VehicleSetupError("the autopilot profile lists no modes")
    if len(start) not in (2, 3):
        raise VehicleSetupError(f"a start point is (north_m, east_m[, up_m]), not {start!r}")
    point = (float(start[0]), float(start[1]), float(start[2]) if len(start) == 3 else 0.0)
    if point[2] < 0.0:
        raise VehicleSetupError(f"a vehicle cannot start below the origin (up_m {point[2]:g})")
    if gps_rate_hz is None:
        profile_rate = autopilot.get("gps_rate_hz")
        gps_rate_hz = float(profile_rate) if profile_rate else DEFAULT_GPS_RATE_HZ
    where = origin if isinstance(origin, Origin) else Origin(*origin)
    if gps_vertical_noise_m is None:
        gps_vertical_noise_m = gps_noise_m * DEFAULT_GPS_VERTICAL_NOISE_M / DEFAULT_GPS_NOISE_M
    if channels is None:
        channels = autopilot.get("channels") or {}
    return model(
        limits=AirframeLimits.from_profile(airframe),
        autopilot=autopilot,
        channels=channels,
        origin=where,
        start_m=point,
        rng=rng,
        gps_noise_m=gps_noise_m,
        gps_vertical_noise_m=gps_vertical_noise_m,
        gps_rate_hz=gps_rate_hz,
        heading_deg=heading_deg,
        armed=armed,
        mode=mode,
        rc_override_timeout_s=rc_override_timeout_s,
    )


#: The model classes by airframe class, for documentation and tests.
MODELS: Mapping[str, type[SimulatedVehicle]] = _MODELS
