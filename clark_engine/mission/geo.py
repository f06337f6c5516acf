"""Points in the mission's local frame and their conversion to latitude/longitude.

Missions may give positions as north/east/up metres from ``mission.origin`` or
as latitude/longitude/altitude. Over the few kilometres a small-vehicle mission
spans, a local tangent plane (equirectangular projection) is accurate to well
under a GPS error, so that is what the engine uses.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Any

EARTH_RADIUS_M = 6_371_008.8


@dataclass(frozen=True, slots=True)
class Origin:
    """The mission's reference point, on the ground; every other altitude is metres above it.

    Attributes:
        lat_deg: Latitude.
        lon_deg: Longitude.
        alt_amsl_m: Height of the ground there above mean sea level: the one AMSL figure
            of a mission, from which the engine works out altitudes above the origin.
    """

    lat_deg: float
    lon_deg: float
    alt_amsl_m: float = 0.0


@dataclass(frozen=True, slots=True)
class LocalPoint:
    """A position in metres north, east and up from the origin."""

    north_m: float
    east_m: float
    up_m: float = 0.0

    def horizontal_distance_m(self, other: LocalPoint) -> float:
        """Ground distance to another point."""
        return math.hypot(self.north_m - other.north_m, self.east_m - other.east_m)


def to_local(lat_deg: float, lon_deg: float, alt_m: float, origin: Origin) -> LocalPoint:
    """Latitude/longitude/relative altitude to north/east/up metres from ``origin``."""
    north = math.radians(lat_deg - origin.lat_deg) * EARTH_RADIUS_M
    east = (
        math.radians(lon_deg - origin.lon_deg)
        * EARTH_RADIUS_M
        * math.cos(math.radians(origin.lat_deg))
    )
    return LocalPoint(north, east, alt_m)


def to_global(point: LocalPoint, origin: Origin) -> tuple[float, float, float]:
    """North/east/up metres to (latitude deg, longitude deg, altitude m above origin)."""
    lat = origin.lat_deg + math.degrees(point.north_m / EARTH_RADIUS_M)
    lon = origin.lon_deg + math.degrees(
        point.east_m / (EARTH_RADIUS_M * math.cos(math.radians(origin.lat_deg)))
    )
    if not -180.0 <= lon <= 180.0:
        # Across the antimeridian, or metres east of an origin a metre from a pole (where a
        # degree of longitude is a few centimetres): the same meridian, in range.
        lon = (lon + 180.0) % 360.0 - 180.0
    return lat, lon, point.up_m


def parse_point(value: Any, origin: Origin) -> LocalPoint:
    """Read any of the point forms the mission schema allows.

    Forms: ``[north_m, east_m]``, ``[north_m, east_m, up_m]``,
    ``{north_m, east_m, up_m}`` and ``{lat, lon, alt_m}``. The schema has
    already checked the shape; this only converts.
    """
    if isinstance(value, Sequence) and not isinstance(value, str):
        up = float(value[2]) if len(value) > 2 else 0.0
        return LocalPoint(float(value[0]), float(value[1]), up)
    if isinstance(value, Mapping):
        if "lat" in value:
            return to_local(
                float(value["lat"]), float(value["lon"]), float(value.get("alt_m", 0.0)), origin
            )
        return LocalPoint(
            float(value.get("north_m", 0.0)),
            float(value.get("east_m", 0.0)),
            float(value.get("up_m", 0.0)),
        )
    raise TypeError(f"not a point: {value!r}")


def round_coordinate(value: float) -> float:
    """Round to 1e-7 degrees, the resolution ClarkLink and MAVLink carry."""
    return round(value, 7)
