"""The safety envelope: as a mission declares it, and as each vehicle flies inside it.

A mission's ``envelope:`` section and each vehicle's own ``envelope:`` are read here
into an :class:`EnvelopeDecl` (what was written, and where), then resolved into one
:class:`Envelope` per vehicle: the ceiling and floor above the origin, the geofence
zones on the local plane, the separations from every other vehicle, the actions on a
breach and a near miss, what to do with a target outside, and the endurance. Every
key has a safe default (the schema's, in :mod:`.schema_source.envelope`), so a
vehicle always has an envelope.

Resolving also checks the declaration itself (a vehicle's envelope may only narrow
the mission's; the ceiling stays under the legal limit unless the mission raises the
limit on purpose; polygons do not cross themselves; separations name vehicles). What
the behaviours do inside the envelope is proved in :mod:`.envelope_checks`.
"""

from __future__ import annotations

from collections.abc import Collection, Iterator, Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any

from clark_engine.mission.fence import Fence, Zone
from clark_engine.mission.findings import DocPath, Finding, Location, error, warning
from clark_engine.mission.geo import LocalPoint, Origin, parse_point
from clark_engine.mission.yaml_loader import Document

#: The altitude limit above the origin that applies unless the mission raises it
#: (120 m: the 400 ft of FAA Part 107 and the EU's open category).
DEFAULT_LEGAL_CEILING_M = 120.0
#: The highest legal ceiling a mission may declare (a waiver beyond it is not this tool's).
MAX_LEGAL_CEILING_M = 500.0
#: Default 3-D distance every pair of vehicles keeps.
DEFAULT_MIN_SEPARATION_M = 5.0
#: Default distance inside the envelope at which the runtime keeps the targets it sends.
DEFAULT_MARGIN_M = 2.0
#: Default expected horizontal position error of a vehicle (``position_error_m``): none,
#: so that a mission that declares none flies as it did before the figure existed; a
#: mission whose dry run simulates a GPS error is warned to declare one (W-POSITION-ERROR).
DEFAULT_POSITION_ERROR_M = 0.0
#: The largest ``position_error_m`` a mission may declare.
MAX_POSITION_ERROR_M = 100.0
#: Radius of the default geofence around home for a radio that declares no range (UDP).
DEFAULT_FENCE_RADIUS_M = 1000.0
#: What a vehicle does on a breach, and on a near miss.
BREACH_ACTIONS = ("hold", "rtl", "land")
#: What the runtime does with a Goto outside the envelope.
OUTSIDE_ACTIONS = ("clamp", "refuse")


@dataclass(frozen=True, slots=True)
class DeclaredZone:
    """One geofence zone as written: its geometry and the raw value for the compiled config.

    Attributes:
        zone: The zone on the local plane (metres north and east of the origin).
        points: A polygon's corners, or a circle's centre, as local points.
        location: Where the zone was written.
        owner: ``mission`` or the vehicle whose envelope declared it.
    """

    zone: Zone
    points: tuple[LocalPoint, ...]
    location: Location
    owner: str


@dataclass(slots=True)
class EnvelopeDecl:
    """An ``envelope:`` section as written (the mission's, or one vehicle's).

    Attributes:
        values: The scalar settings written (ceiling_m, floor_m, on_breach...).
        include: Inclusion zones written here.
        exclude: Exclusion zones written here.
        separation: Pair overrides (mission only): ((a, b), min_m, where).
        location: Where the section is (the mission's or agent's place when absent).
        key_locations: Where each written key is.
    """

    values: dict[str, Any] = field(default_factory=dict)
    include: list[DeclaredZone] = field(default_factory=list)
    exclude: list[DeclaredZone] = field(default_factory=list)
    separation: list[tuple[tuple[str, str], float, Location]] = field(default_factory=list)
    location: Location = field(default_factory=lambda: Location(""))
    key_locations: dict[str, Location] = field(default_factory=dict)

    def get(self, key: str, default: Any = None) -> Any:
        """A written setting, or ``default``."""
        return self.values.get(key, default)

    def locate(self, key: str) -> Location:
        """Where ``key`` was written, else where the section is."""
        return self.key_locations.get(key, self.location)


@dataclass(slots=True)
class Envelope:
    """Where one vehicle may fly, every default filled in.

    Altitudes are metres above the mission origin. ``sources`` says where each limit
    came from, so a finding about a waypoint over the ceiling can point at the line
    that set the ceiling as well as at the waypoint.

    Attributes:
        ceiling_m: Highest altitude above the origin.
        floor_m: Lowest altitude above the origin in guided flight (aircraft).
        legal_ceiling_m: The legal limit the mission flies under.
        margin_m: How far inside the envelope targets are kept.
        include: Inclusion zones (the mission's and the vehicle's).
        exclude: Exclusion zones (the mission's and the vehicle's).
        default_radius_m: With no inclusion zone: the radius of the circle around home
            the vehicle stays in (its radio's range, or 1000 m); None otherwise.
        home: The vehicle's start (the centre of the default circle).
        min_separation_m: Smallest 3-D distance from any other vehicle.
        separation: Other vehicle -> its minimum distance, where a pair override says.
        on_breach: hold, rtl or land on a fence, altitude or endurance breach.
        on_near_miss: hold, rtl or land when another vehicle comes too close.
        outside: clamp or refuse a target outside the envelope.
        endurance_s: Time armed allowed; None when nothing declares one.
        sources: Limit name -> where it was set (absent for built-in defaults).
        ceiling_by: What set the ceiling: ``mission``, ``agent``, ``airframe`` or ``legal``.
        position_error_m: How far the vehicle's reported horizontal position may be from
            the truth (its own figure, else the mission's, else 0): the runtime keeps
            this, and each peer's figure, on top of the separation.
    """

    ceiling_m: float
    floor_m: float
    legal_ceiling_m: float
    margin_m: float
    include: tuple[DeclaredZone, ...]
    exclude: tuple[DeclaredZone, ...]
    default_radius_m: float | None
    home: LocalPoint
    min_separation_m: float
    separation: dict[str, float]
    on_breach: str
    on_near_miss: str
    outside: str
    endurance_s: float | None
    sources: dict[str, Location] = field(default_factory=dict)
    ceiling_by: str = "legal"
    position_error_m: float = DEFAULT_POSITION_ERROR_M

    def fence(self) -> Fence:
        """The geofence on the local plane (the default circle around home included)."""
        include = tuple(z.zone for z in self.include)
        if self.default_radius_m is not None:
            include = (Zone.circle((self.home.north_m, self.home.east_m), self.default_radius_m),)
        return Fence(include, tuple(z.zone for z in self.exclude))

    def separation_from_m(self, other: str) -> float:
        """The minimum distance this vehicle keeps from ``other``."""
        return self.separation.get(other, self.min_separation_m)

    def describe_ceiling(self) -> str:
        """The ceiling with what set it, for messages: ``60 m (agents.cub.envelope)``."""
        by = {
            "legal": "the legal limit",
            "mission": "envelope.ceiling_m",
            "agent": "the vehicle's envelope.ceiling_m",
            "airframe": "its airframe's max_altitude_m",
        }[self.ceiling_by]
        return f"{self.ceiling_m:g} m above the origin ({by})"


def read_decl(
    doc: Document, path: DocPath, raw: Any, origin: Origin, owner: str, fallback: Location
) -> EnvelopeDecl:
    """Read an ``envelope:`` mapping the schema accepted (or nothing) into a declaration."""
    decl = EnvelopeDecl(location=doc.location(path) if isinstance(raw, Mapping) else fallback)
    if not isinstance(raw, Mapping):
        return decl
    for key, value in raw.items():
        decl.key_locations[key] = doc.location((*path, key))
        if key not in ("geofence", "separation"):
            decl.values[key] = value
    fence = raw.get("geofence")
    if isinstance(fence, Mapping):
        for side in ("include", "exclude"):
            zones = fence.get(side)
            if not isinstance(zones, list):
                continue
            for index, item in enumerate(zones):
                where = (*path, "geofence", side, index)
                zone = _zone(item, origin, doc.location(where), owner)
                if zone is not None:
                    (decl.include if side == "include" else decl.exclude).append(zone)
    for index, item in enumerate(raw.get("separation") or ()):
        if isinstance(item, Mapping):
            a, b = (str(n) for n in item["between"])
            decl.separation.append(
                ((a, b), float(item["min_m"]), doc.location((*path, "separation", index)))
            )
    return decl


def _zone(item: Any, origin: Origin, where: Location, owner: str) -> DeclaredZone | None:
    if not isinstance(item, Mapping):
        return None
    if "polygon" in item:
        points = tuple(parse_point(p, origin) for p in item["polygon"])
        return DeclaredZone(
            Zone.polygon((p.north_m, p.east_m) for p in points), points, where, owner
        )
    circle = item.get("circle")
    if isinstance(circle, Mapping):
        center = parse_point(circle["center"], origin)
        zone = Zone.circle((center.north_m, center.east_m), float(circle["radius_m"]))
        return DeclaredZone(zone, (center,), where, owner)
    return None


def resolve(
    mission_decl: EnvelopeDecl,
    agent_decl: EnvelopeDecl,
    *,
    airframe: Mapping[str, Any] | None,
    radio_range_m: float | None,
    home: LocalPoint,
    name: str,
) -> Envelope:
    """One vehicle's envelope: the mission's, narrowed by the vehicle's, defaults filled in."""
    sources: dict[str, Location] = {}

    def pick(key: str, default: Any) -> Any:
        if key in agent_decl.values:
            sources[key] = agent_decl.locate(key)
            return agent_decl.values[key]
        if key in mission_decl.values:
            sources[key] = mission_decl.locate(key)
            return mission_decl.values[key]
        return default

    legal = float(mission_decl.get("legal_ceiling_m", DEFAULT_LEGAL_CEILING_M))
    if "legal_ceiling_m" in mission_decl.values:
        sources["legal_ceiling_m"] = mission_decl.locate("legal_ceiling_m")
    ceiling, ceiling_by = legal, "legal"
    if "ceiling_m" in mission_decl.values:
        ceiling, ceiling_by = float(mission_decl.values["ceiling_m"]), "mission"
        sources["ceiling_m"] = mission_decl.locate("ceiling_m")
    if "ceiling_m" in agent_decl.values and float(agent_decl.values["ceiling_m"]) <= ceiling:
        ceiling, ceiling_by = float(agent_decl.values["ceiling_m"]), "agent"
        sources["ceiling_m"] = agent_decl.locate("ceiling_m")
    kind = (airframe or {}).get("class")
    limit = (airframe or {}).get("max_altitude_m")
    if kind != "rover" and limit is not None and 0 < float(limit) < ceiling:
        ceiling, ceiling_by = float(limit), "airframe"
    floor = float(mission_decl.get("floor_m", 0.0))
    if "floor_m" in mission_decl.values:
        sources["floor_m"] = mission_decl.locate("floor_m")
    if "floor_m" in agent_decl.values and float(agent_decl.values["floor_m"]) >= floor:
        floor = float(agent_decl.values["floor_m"])
        sources["floor_m"] = agent_decl.locate("floor_m")
    include = tuple(mission_decl.include) + tuple(agent_decl.include)
    exclude = tuple(mission_decl.exclude) + tuple(agent_decl.exclude)
    separation: dict[str, float] = {}
    for (a, b), min_m, where in mission_decl.separation:
        if name in (a, b) and a != b:
            separation[b if a == name else a] = min_m
            sources[f"separation:{b if a == name else a}"] = where
    min_separation = float(mission_decl.get("min_separation_m", DEFAULT_MIN_SEPARATION_M))
    if "min_separation_m" in mission_decl.values:
        sources["min_separation_m"] = mission_decl.locate("min_separation_m")
    endurance = pick("endurance_s", (airframe or {}).get("endurance_s"))
    position_error = float(pick("position_error_m", DEFAULT_POSITION_ERROR_M))
    return Envelope(
        ceiling_m=ceiling,
        floor_m=floor,
        legal_ceiling_m=legal,
        margin_m=float(mission_decl.get("margin_m", DEFAULT_MARGIN_M)),
        include=include,
        exclude=exclude,
        default_radius_m=None
        if include
        else (radio_range_m if radio_range_m is not None else DEFAULT_FENCE_RADIUS_M),
        home=home,
        min_separation_m=min_separation,
        separation=separation,
        on_breach=str(pick("on_breach", "hold" if kind == "rover" else "rtl")),
        on_near_miss=str(pick("on_near_miss", "hold")),
        outside=str(pick("outside", "clamp")),
        endurance_s=float(endurance) if endurance is not None else None,
        sources=sources,
        ceiling_by=ceiling_by,
        position_error_m=position_error,
    )


def check_decl(
    mission_decl: EnvelopeDecl,
    agent_decls: Mapping[str, EnvelopeDecl],
    vehicles: Sequence[str],
    stations: Sequence[str],
    unresolved: Collection[str] = (),
) -> Iterator[Finding]:
    """What is wrong with the envelope as written, before any behaviour is looked at.

    Args:
        mission_decl: The mission's ``envelope:``.
        agent_decls: Agent -> its ``envelope:``, for the agents that wrote one.
        vehicles: The mission's vehicles.
        stations: The mission's stations.
        unresolved: Agents declared but too broken to resolve (their own errors say
            why); a separation naming one is not reported again.
    """
    legal = float(mission_decl.get("legal_ceiling_m", DEFAULT_LEGAL_CEILING_M))
    if legal > DEFAULT_LEGAL_CEILING_M:
        yield warning(
            "W-CEILING-WAIVER",
            mission_decl.locate("legal_ceiling_m"),
            f"envelope.legal_ceiling_m {legal:g} m overrides the {DEFAULT_LEGAL_CEILING_M:g} m "
            "limit most authorities set for small unmanned aircraft; fly above it only with "
            "the waiver that allows it",
        )
    ceiling = mission_decl.get("ceiling_m")
    if ceiling is not None and float(ceiling) > legal:
        yield error(
            "E-CEILING-LEGAL",
            mission_decl.locate("ceiling_m"),
            f"envelope.ceiling_m {float(ceiling):g} m is above the legal ceiling of {legal:g} m "
            "above the origin; lower it, or, with the authority's waiver, raise "
            "envelope.legal_ceiling_m",
        )
    mission_ceiling = float(ceiling) if ceiling is not None else legal
    mission_floor = float(mission_decl.get("floor_m", 0.0))
    if mission_floor >= mission_ceiling:
        yield error(
            "E-ENVELOPE-FLOOR",
            mission_decl.locate("floor_m"),
            f"envelope.floor_m {mission_floor:g} m is not below the ceiling of "
            f"{mission_ceiling:g} m; lower the floor or raise the ceiling",
        )
    for zone in (*mission_decl.include, *mission_decl.exclude):
        yield from _check_zone(zone)
    for (a, b), _min_m, where in mission_decl.separation:
        for other in (a, b):
            if other not in vehicles and other not in unresolved:
                known = "a station has no separation" if other in stations else "no such vehicle"
                yield error(
                    "E-SEPARATION-AGENT",
                    where,
                    f"envelope.separation names {other!r}: {known}; name two vehicles of "
                    f"the mission ({', '.join(vehicles)})",
                )
        if a == b:
            yield error(
                "E-SEPARATION-AGENT",
                where,
                f"envelope.separation names {a!r} twice; name two different vehicles",
            )
    for name, decl in agent_decls.items():
        if name in stations:
            yield error(
                "E-ENVELOPE-STATION",
                decl.location,
                f"{name} is a station: it flies nowhere, so it has no envelope; remove "
                f"agents.{name}.envelope",
            )
            continue
        own = decl.get("ceiling_m")
        if own is not None and float(own) > mission_ceiling:
            yield error(
                "E-ENVELOPE-WIDEN",
                decl.locate("ceiling_m"),
                f"agents.{name}.envelope.ceiling_m {float(own):g} m is above the mission's "
                f"ceiling of {mission_ceiling:g} m; a vehicle's envelope only narrows the "
                "mission's: lower it, or raise envelope.ceiling_m",
            )
        own_floor = decl.get("floor_m")
        if own_floor is not None and float(own_floor) < mission_floor:
            yield error(
                "E-ENVELOPE-WIDEN",
                decl.locate("floor_m"),
                f"agents.{name}.envelope.floor_m {float(own_floor):g} m is below the "
                f"mission's floor of {mission_floor:g} m; a vehicle's envelope only narrows "
                "the mission's: raise it, or lower envelope.floor_m",
            )
        top = min(float(own), mission_ceiling) if own is not None else mission_ceiling
        bottom = max(float(own_floor), mission_floor) if own_floor is not None else mission_floor
        if bottom >= top and (own is not None or own_floor is not None):
            yield error(
                "E-ENVELOPE-FLOOR",
                decl.locate("floor_m" if own_floor is not None else "ceiling_m"),
                f"agents.{name}'s floor of {bottom:g} m is not below its ceiling of {top:g} m; "
                "lower the floor or raise the ceiling",
            )
        for zone in (*decl.include, *decl.exclude):
            yield from _check_zone(zone)


def _check_zone(zone: DeclaredZone) -> Iterator[Finding]:
    crossing = zone.zone.self_crossing()
    if crossing is not None:
        i, j = crossing
        yield error(
            "E-GEOFENCE-POLYGON",
            zone.location,
            f"this polygon's edges {i + 1} and {j + 1} cross each other, so inside and "
            "outside are ambiguous; list its corners in order around it",
        )
    elif zone.zone.kind == "polygon" and zone.zone.area_m2 < 1.0:
        yield error(
            "E-GEOFENCE-POLYGON",
            zone.location,
            "this polygon has no area (its corners lie on one line); give corners around "
            "the area the vehicles may fly in",
        )
