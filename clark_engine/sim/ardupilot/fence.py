"""ArduPilot's geofence, as the simulated autopilot flies it: AC_Fence and each firmware's reaction.

:class:`ArduFence` is ArduPilot's ``AC_Fence`` (libraries/AC_Fence/AC_Fence.cpp at the
SITL build 90700977): which fences are enabled (FENCE_ENABLE, FENCE_TYPE,
FENCE_AUTOENABLE, MAV_CMD_DO_FENCE_ENABLE), breach detection with its thresholds
(at or above FENCE_ALT_MAX above home, at or beyond FENCE_RADIUS from home, outside
an uploaded inclusion zone or inside an exclusion zone), backup fences that re-fire a
breach 20 m (100 m on ArduPlane) further out, the ten seconds of "manual recovery"
after a mode change during a breach, the guided-destination check, the pre-arm
checks and their words, and what SYS_STATUS and FENCE_STATUS say. :func:`react`
is each firmware's ``fence_check``: the texts and the FENCE_ACTION it takes.

Quirks kept because ArduPilot has them (measured on SITL: docs/sitl-measurements.md, section 3):

- The enabled fences are worked out again only when FENCE_ENABLE or
  FENCE_AUTOENABLE *change*: a FENCE_TYPE change with the fence on does nothing until
  FENCE_ENABLE is toggled; FENCE_ENABLE values other than 0 and 1 re-enable
  everything at every check (AC_Fence keeps the last value as a bool).
- FENCE_ENABLE set to 0 during a breach leaves the breach recorded (SYS_STATUS
  unhealthy) until a check clears it.
- The floor (FENCE_ALT_MIN) is never enabled with the others; it enables itself
  once the vehicle is FENCE_MARGIN above it.
- Altitudes are above home as the autopilot reports them: ArduRover's home sits at
  its barometer's height, so an ArduRover altitude fence sees it 90 m up on a 90 m
  field.

Not simulated: the margin notifications of FENCE_OPTIONS bit 2 (FENCE_NTF_FREQ),
FENCE_AUTOENABLE 1 and 2 (enable after an auto-takeoff; deprecated, "will be removed
in 4.7"), FENCE_RET_RALLY (no rally points are flown: home instead), and ArduPlane's
return to the previous mode when the fence is switched off during a GUIDED action.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Iterable, Sequence
from dataclasses import dataclass, field
from enum import IntEnum
from typing import Final, NamedTuple

from pymavlink.dialects.v20 import ardupilotmega as mavlink2

from clark_engine.mission.fence import Zone
from clark_engine.sim.ardupilot.mission_items import MissionItem
from clark_engine.sim.ardupilot.vehicle_safety import ApVehicle

ALT_MAX: Final = 1
"""FENCE_TYPE bit: the ceiling, FENCE_ALT_MAX above home."""
CIRCLE: Final = 2
"""FENCE_TYPE bit: the circle of FENCE_RADIUS around home."""
POLYGON: Final = 4
"""FENCE_TYPE bit: the uploaded inclusion and exclusion polygons and circles."""
ALT_MIN: Final = 8
"""FENCE_TYPE bit: the floor, FENCE_ALT_MIN above home."""
ARMING_FENCES: Final = ALT_MAX | CIRCLE | POLYGON
ALL_FENCES: Final = ARMING_FENCES | ALT_MIN

ALT_BACKUP_M: Final = 20.0
"""A breached altitude fence fires again this much further out (AC_FENCE_ALT_*_BACKUP_DISTANCE)."""
CIRCLE_BACKUP_M: Final = {"arduplane": 100.0}
"""A breached circle fires again this much further out: 100 m on ArduPlane, 20 m elsewhere."""
MANUAL_RECOVERY_S: Final = 10.0
"""New breaches are ignored this long after a mode change during a breach."""
GIVE_UP_DISTANCE_M: Final = 100.0
"""Further outside than this, ArduCopter lands and ArduRover holds whatever FENCE_ACTION says."""
BREACH_NOTIFY_S: Final = 1.0
"""FENCE_STATUS is sent at once on a new breach, at most this often."""
AUTOENABLE_WARNING_S: Final = 60.0
"""How often the pre-arm check warns about FENCE_AUTOENABLE 1 or 2."""

CHECK_PERIOD_S: Final = {"arducopter": 0.04, "ardurover": 0.1, "arduplane": 0.333}
"""How often each firmware checks its fence (``fence_checks_async``: 25, 10 and 3 Hz)."""

_NAMES: Final = (
    (ALT_MAX, "Max Alt"),
    (CIRCLE, "Circle"),
    (POLYGON, "Polygon"),
    (ALT_MIN, "Min Alt"),
)
_NOTICE, _INFO = int(mavlink2.MAV_SEVERITY_NOTICE), int(mavlink2.MAV_SEVERITY_INFO)

_POLY_INCLUSION = int(mavlink2.MAV_CMD_NAV_FENCE_POLYGON_VERTEX_INCLUSION)
_POLY_EXCLUSION = int(mavlink2.MAV_CMD_NAV_FENCE_POLYGON_VERTEX_EXCLUSION)
_CIRCLE_INCLUSION = int(mavlink2.MAV_CMD_NAV_FENCE_CIRCLE_INCLUSION)
_CIRCLE_EXCLUSION = int(mavlink2.MAV_CMD_NAV_FENCE_CIRCLE_EXCLUSION)
_RETURN_POINT = int(mavlink2.MAV_CMD_NAV_FENCE_RETURN_POINT)

Point2 = tuple[float, float]
"""(north_m, east_m) from the mission origin."""


class Action(IntEnum):
    """FENCE_ACTION values whose meaning the firmwares share (the others are per firmware)."""

    REPORT_ONLY = 0
    RTL_AND_LAND = 1


def fence_names(fences: int) -> str:
    """ArduPilot's name for a set of fences: "Max Alt fence", "Max Alt and Circle fences"...

    Empty for no fence (``AC_Fence::get_fence_names``).
    """
    names = [name for bit, name in _NAMES if fences & bit]
    if not names:
        return ""
    joined = names[0] if len(names) == 1 else ", ".join(names[:-1]) + " and " + names[-1]
    return joined + (" fences" if len(names) > 1 else " fence")


class FencePosition(NamedTuple):
    """Where the fence sees the vehicle (its EKF's estimate, not a noisy GPS fix).

    Attributes:
        alt_above_home_m: Height above home as the autopilot reports it
            (GLOBAL_POSITION_INT's relative_alt; the barometer's height before home).
        from_home: (north_m, east_m) from home; None before home or a position.
        here: (north_m, east_m) from the mission origin; None before a position.
    """

    alt_above_home_m: float
    from_home: Point2 | None
    here: Point2 | None


@dataclass(frozen=True, slots=True)
class FenceZones:
    """The uploaded fence (MAV_MISSION_TYPE_FENCE items) as zones on the local plane.

    Attributes:
        inclusion_polygons: Polygons the vehicle must stay inside.
        exclusion_polygons: Polygons it must stay out of.
        inclusion_circles: Circles it must stay inside.
        exclusion_circles: Circles it must stay out of.
        return_point: The fence return point (ArduPlane's GUIDED action flies there).
    """

    inclusion_polygons: tuple[Zone, ...] = ()
    exclusion_polygons: tuple[Zone, ...] = ()
    inclusion_circles: tuple[Zone, ...] = ()
    exclusion_circles: tuple[Zone, ...] = ()
    return_point: Point2 | None = None

    @classmethod
    def from_items(
        cls, items: Iterable[MissionItem], to_local: Callable[[float, float], Point2]
    ) -> FenceZones:
        """Zones from stored fence items (x, y in 1e-7 degrees).

        A polygon is its run of vertex items (param1 is the vertex count, as
        AC_PolyFence_loader stores them); a circle's radius is its param1.
        """
        zones: dict[int, list[Zone]] = {
            _POLY_INCLUSION: [],
            _POLY_EXCLUSION: [],
            _CIRCLE_INCLUSION: [],
            _CIRCLE_EXCLUSION: [],
        }
        return_point: Point2 | None = None
        corners: list[Point2] = []
        for item in items:
            command = int(item.command)
            where = to_local(item.x / 1e7, item.y / 1e7)
            param1 = float(item.param1)
            if command in (_POLY_INCLUSION, _POLY_EXCLUSION):
                corners.append(where)
                if len(corners) >= int(param1):
                    zones[command].append(Zone.polygon(corners))
                    corners = []
            elif command in (_CIRCLE_INCLUSION, _CIRCLE_EXCLUSION):
                zones[command].append(Zone.circle(where, param1))
            elif command == _RETURN_POINT:
                return_point = where
        return cls(
            tuple(zones[_POLY_INCLUSION]),
            tuple(zones[_POLY_EXCLUSION]),
            tuple(zones[_CIRCLE_INCLUSION]),
            tuple(zones[_CIRCLE_EXCLUSION]),
            return_point,
        )

    @property
    def count(self) -> int:
        """How many zones were uploaded (a fence with none has no polygon fence to enable)."""
        return (
            len(self.inclusion_polygons)
            + len(self.exclusion_polygons)
            + len(self.inclusion_circles)
            + len(self.exclusion_circles)
        )

    @property
    def inclusions(self) -> tuple[Zone, ...]:
        """Every inclusion zone."""
        return self.inclusion_polygons + self.inclusion_circles

    @property
    def exclusions(self) -> tuple[Zone, ...]:
        """Every exclusion zone."""
        return self.exclusion_polygons + self.exclusion_circles

    def breached(self, here: Point2, union: bool = False) -> tuple[bool, float]:
        """Whether ``here`` breaches the zones, and by how much (AC_PolyFence_loader::breached).

        Outside an inclusion zone (with ``union``, FENCE_OPTIONS bit 1: outside every
        one of them) or inside an exclusion zone is a breach. The distance is how far
        outside (negative: how far inside), ArduPilot's way of folding the zones.
        """
        if self.count == 0:
            return False, 0.0
        distance = -math.inf
        outside = 0
        for zone in self.inclusion_polygons:
            edge_m = abs(zone.signed_distance_m(*here))
            if not zone.contains(*here):
                outside += 1
                distance = min(distance, edge_m) if distance > 0 else edge_m
            else:
                distance = max(distance, -edge_m)
        for zone in self.exclusion_polygons:
            edge_m = abs(zone.signed_distance_m(*here))
            if zone.contains(*here):
                return True, edge_m
            distance = max(distance, -edge_m)
        for zone in self.exclusion_circles:
            inside_by_m = zone.signed_distance_m(*here)
            distance = max(distance, inside_by_m)
            if inside_by_m > 0:
                return True, distance
        for zone in self.inclusion_circles:
            outside_by_m = -zone.signed_distance_m(*here)
            distance = max(distance, outside_by_m)
            if outside_by_m > 0:
                outside += 1
        inclusions = len(self.inclusion_polygons) + len(self.inclusion_circles)
        if (union and inclusions > 0 and outside == inclusions) or (not union and outside > 0):
            return True, distance
        return False, 0.0 if distance == -math.inf else distance


class _MinAltState(IntEnum):
    DEFAULT = 0
    MANUALLY_ENABLED = 1
    MANUALLY_DISABLED = 2


@dataclass
class ArduFence:
    """ArduPilot's AC_Fence for one autopilot (see the module docstring).

    Args:
        firmware: ``ardurover``, ``arducopter`` or ``arduplane``.
        param: The autopilot's parameter values by name (FENCE_*).
        say: Sends a STATUSTEXT (severity, text).
        send_status: Queues a FENCE_STATUS (sent once the breach is recorded).
    """

    firmware: str
    param: Callable[[str], float]
    say: Callable[[int, str], None]
    send_status: Callable[[], None]
    zones: FenceZones = field(default_factory=FenceZones)
    """The uploaded zones (the autopilot replaces them when the fence list changes)."""
    breaches: int = 0
    """The fences breached now (a FENCE_TYPE bitmask)."""
    breach_count: int = 0
    """Breaches so far (FENCE_STATUS.breach_count)."""
    breach_time_s: float = 0.0
    """Simulator time of the last new breach (FENCE_STATUS.breach_time, once in boot ms)."""
    _enabled_fences: int = 0
    _last_enabled: bool = False
    _last_auto_enabled: int = 0
    _alt_max_backup: float = 0.0
    _alt_min_backup: float = 0.0
    _circle_backup: float = 0.0
    _distances: dict[int, float] = field(default_factory=dict)
    _home_distance_m: float = 0.0
    _recovery_s: float | None = None
    _last_notify_s: float = -math.inf
    _last_autoenable_warning_s: float = -math.inf
    _min_alt_state: _MinAltState = _MinAltState.DEFAULT

    # -- parameters -----------------------------------------------------------------------

    @property
    def configured(self) -> int:
        """FENCE_TYPE as the int8 ArduPilot stores (bits 0-7)."""
        return int(self.param("FENCE_TYPE")) & 0xFF

    @property
    def action(self) -> int:
        """FENCE_ACTION."""
        return int(self.param("FENCE_ACTION"))

    @property
    def auto_enable(self) -> int:
        """FENCE_AUTOENABLE."""
        return int(self.param("FENCE_AUTOENABLE"))

    @property
    def margin_m(self) -> float:
        """FENCE_MARGIN."""
        return self.param("FENCE_MARGIN")

    def option(self, bit: int) -> bool:
        """Whether FENCE_OPTIONS has ``bit`` (1: no mode change in recovery, 2: union)."""
        return bool(int(self.param("FENCE_OPTIONS")) & bit)

    # -- which fences are on ----------------------------------------------------------------

    def update(self) -> None:
        """AC_Fence::update: FENCE_ENABLE or FENCE_AUTOENABLE changed, so start afresh.

        The last FENCE_ENABLE is kept as a bool, as ArduPilot's ``_last_enabled``: a
        value other than 0 or 1 never equals it, and everything is re-enabled each time.
        """
        enable = int(self.param("FENCE_ENABLE"))
        auto = self.auto_enable
        if enable != int(self._last_enabled) or auto != self._last_auto_enabled:
            self._last_enabled = enable != 0
            self._last_auto_enabled = auto
            self._enabled_fences = self.configured & ~ALT_MIN if enable else 0

    @property
    def update_pending(self) -> bool:
        """FENCE_ENABLE or FENCE_AUTOENABLE changed since :meth:`update` last looked."""
        return (
            int(self.param("FENCE_ENABLE")) != int(self._last_enabled)
            or self.auto_enable != self._last_auto_enabled
        )

    def present(self) -> int:
        """The configured fences that exist: the polygon fence only with zones uploaded."""
        mask = CIRCLE | ALT_MIN | ALT_MAX | (POLYGON if self.zones.count > 0 else 0)
        return self.configured & mask

    def enabled_fences(self) -> int:
        """The fences enabled and present."""
        return self._enabled_fences & self.present()

    @property
    def enabled(self) -> bool:
        """Any fence enabled (AC_Fence::enabled; not masked by what is present)."""
        return self._enabled_fences != 0

    def enable(self, value: bool, fences: int, update_auto: bool = True) -> int:
        """Enable or disable some configured fences; returns those that changed.

        Disabling a fence clears its breach. The floor switched by hand is remembered
        (it is then never enabled or disabled automatically).
        """
        wanted = self.configured & fences
        after = self._enabled_fences | wanted if value else self._enabled_fences & ~wanted
        if update_auto and wanted & ALT_MIN:
            self._min_alt_state = (
                _MinAltState.MANUALLY_ENABLED if value else _MinAltState.MANUALLY_DISABLED
            )
        changed = self._enabled_fences ^ after
        if changed:
            self._enabled_fences = after
            if not value:
                self.breaches &= ~changed
        return changed

    def auto_enable_on_arming(self) -> None:
        """FENCE_AUTOENABLE 3: the fences (not the floor) come on at arming, and say so."""
        if self.auto_enable != 3:
            return
        self._min_alt_state = _MinAltState.DEFAULT
        changed = self.enable(True, ARMING_FENCES, update_auto=False)
        if changed:
            self.say(_NOTICE, f"{fence_names(changed)} auto-enabled")

    def auto_disable_on_disarming(self) -> None:
        """FENCE_AUTOENABLE 3: every fence goes off at disarming, and says so."""
        if self.auto_enable != 3:
            return
        changed = self.enable(False, ALL_FENCES, update_auto=False)
        if changed:
            self.say(_NOTICE, f"{fence_names(changed)} auto-disabled")

    # -- checking -------------------------------------------------------------------------

    @property
    def idle(self) -> bool:
        """Nothing to check: no breach, and no fence on, to come on by itself, or a floor.

        :meth:`check` would change nothing and return 0 (it returns before looking).
        """
        configured = self.configured
        return not self.breaches and (
            not configured
            or (not self.enabled and not self.auto_enable and not configured & ALT_MIN)
        )

    def check(self, pos: FencePosition, now_s: float, landing_or_landed: bool = False) -> int:
        """AC_Fence::check: the fences newly breached (a bitmask), or 0.

        Breaches are recorded whatever the arming state (the pre-arm check reads
        them); the caller acts on what is returned. ``landing_or_landed`` switches the
        floor off (ArduCopter and ArduPlane pass it; ArduRover never). During the ten
        seconds of a manual recovery new breaches are recorded and not returned.
        """
        disabled = self._auto_disable_fences() if landing_or_landed else 0
        to_disable = disabled & self._enabled_fences
        self.breaches &= self.configured
        self.breaches &= ~to_disable
        if self._min_alt_state == _MinAltState.MANUALLY_ENABLED:
            to_disable &= ~ALT_MIN
        if to_disable:
            self.say(_NOTICE, f"{fence_names(to_disable)} auto-disabled")
        if not self.configured or (
            not self.enabled and not self.auto_enable and not self.configured & ALT_MIN
        ):
            return 0
        self.enable(False, disabled, update_auto=False)
        new = 0
        if not disabled & ALT_MAX and self._check_alt_max(pos, now_s):
            new |= ALT_MAX
        if not disabled & ALT_MIN:
            if self._check_alt_min(pos, now_s):
                new |= ALT_MIN
            self._auto_enable_floor(pos)
        if not disabled & CIRCLE and self._check_circle(pos, now_s):
            new |= CIRCLE
        if not disabled & POLYGON and self._check_polygon(pos, now_s):
            new |= POLYGON
        if self._recovery_s is not None:
            if now_s - self._recovery_s < MANUAL_RECOVERY_S:
                return 0
            self._recovery_s = None
        return new

    def _auto_disable_fences(self) -> int:
        fences = ALL_FENCES if self.auto_enable == 1 else ALT_MIN
        if self._min_alt_state == _MinAltState.MANUALLY_ENABLED:
            fences &= ~ALT_MIN
        return fences

    def _record_breach(self, fence: int, now_s: float) -> None:
        if not self.breaches:
            self.breach_time_s = now_s
            if now_s - self._last_notify_s > BREACH_NOTIFY_S:
                self._last_notify_s = now_s
                self.send_status()
        self.breach_count = min(self.breach_count + 1, 65500)
        self.breaches |= fence

    def _check_alt_max(self, pos: FencePosition, now_s: float) -> bool:
        if not self.enabled_fences() & ALT_MAX:
            return False
        alt_m, limit_m = pos.alt_above_home_m, self.param("FENCE_ALT_MAX")
        self._distances[ALT_MAX] = alt_m - limit_m
        if alt_m >= limit_m:
            if not self.breaches & ALT_MAX or (
                self._alt_max_backup and alt_m >= self._alt_max_backup
            ):
                self._record_breach(ALT_MAX, now_s)
                self._alt_max_backup = alt_m + ALT_BACKUP_M
                return True
            return False
        if self.breaches & ALT_MAX:
            self.breaches &= ~ALT_MAX
            self._alt_max_backup = 0.0
        return False

    def _check_alt_min(self, pos: FencePosition, now_s: float) -> bool:
        if not self.enabled_fences() & ALT_MIN:
            return False
        alt_m, limit_m = pos.alt_above_home_m, self.param("FENCE_ALT_MIN")
        self._distances[ALT_MIN] = limit_m - alt_m
        if alt_m <= limit_m:
            if not self.breaches & ALT_MIN or (
                self._alt_min_backup and alt_m <= self._alt_min_backup
            ):
                self._record_breach(ALT_MIN, now_s)
                self._alt_min_backup = alt_m - ALT_BACKUP_M
                return True
            return False
        if self.breaches & ALT_MIN:
            self.breaches &= ~ALT_MIN
            self._alt_min_backup = 0.0
        return False

    def _auto_enable_floor(self, pos: FencePosition) -> None:
        if (
            not self.configured & ALT_MIN
            or self.enabled_fences() & ALT_MIN
            or self._min_alt_state == _MinAltState.MANUALLY_DISABLED
            or (not int(self.param("FENCE_ENABLE")) and self.auto_enable in (0, 1))
        ):
            return
        if pos.alt_above_home_m >= self.param("FENCE_ALT_MIN") + self.margin_m:
            self.enable(True, ALT_MIN, update_auto=False)
            self.say(_NOTICE, "Min Alt fence enabled (auto enable)")

    def _check_circle(self, pos: FencePosition, now_s: float) -> bool:
        if not self.enabled_fences() & CIRCLE:
            return False
        if pos.from_home is not None:
            self._home_distance_m = math.hypot(*pos.from_home)
        distance_m, radius_m = self._home_distance_m, self.param("FENCE_RADIUS")
        self._distances[CIRCLE] = distance_m - radius_m
        if distance_m >= radius_m:
            if not self.breaches & CIRCLE or (
                self._circle_backup and distance_m >= self._circle_backup
            ):
                self._record_breach(CIRCLE, now_s)
                self._circle_backup = distance_m + CIRCLE_BACKUP_M.get(self.firmware, 20.0)
                return True
            return False
        if self.breaches & CIRCLE:
            self.breaches &= ~CIRCLE
            self._circle_backup = 0.0
        return False

    def _check_polygon(self, pos: FencePosition, now_s: float) -> bool:
        if not self.enabled_fences() & POLYGON:
            self.breaches &= ~POLYGON
            return False
        was = bool(self.breaches & POLYGON)
        if pos.here is not None:
            breached, distance_m = self.zones.breached(pos.here, self.option(2))
            self._distances[POLYGON] = distance_m
            if breached:
                if not was:
                    self._record_breach(POLYGON, now_s)
                    return True
                return False
        if was:
            self.breaches &= ~POLYGON
        return False

    def breach_distance(self, fences: int) -> float:
        """How far outside the given fences the vehicle was at the last check (m)."""
        fences &= self.present()
        distances = [d for bit, d in self._distances.items() if fences & bit]
        return max(distances, default=-math.inf)

    def destination_inside(
        self, alt_above_home_m: float | None, from_home: Point2 | None, here: Point2
    ) -> bool:
        """AC_Fence::check_destination_within_fence: may a guided target go there?

        Above the ceiling, below the floor, beyond the circle, or breaching the zones
        (only the fences enabled) is refused; FENCE_MARGIN is not applied here.
        """
        enabled = self.enabled_fences()
        if alt_above_home_m is not None:
            if enabled & ALT_MAX and alt_above_home_m > self.param("FENCE_ALT_MAX"):
                return False
            if enabled & ALT_MIN and alt_above_home_m < self.param("FENCE_ALT_MIN"):
                return False
        beyond = from_home is not None and math.hypot(*from_home) > self.param("FENCE_RADIUS")
        if enabled & CIRCLE and beyond:
            return False
        return not (enabled & POLYGON and self.zones.breached(here, self.option(2))[0])

    def manual_recovery_start(self, now_s: float) -> None:
        """A mode change during a breach: new breaches are ignored for ten seconds."""
        if not self.breaches:
            return
        self._recovery_s = now_s
        self.say(_INFO, "Manual recovery started")

    # -- what it tells ------------------------------------------------------------------

    def pre_arm_failure(self, pos: FencePosition | None, now_s: float) -> str | None:
        """The fence's pre-arm failure (AC_Fence::pre_arm_check), None when it passes.

        ``pos`` is None while the vehicle has no position relative to home.
        """
        auto = self.auto_enable
        if int(self.param("FENCE_ENABLE")) and not self.present():
            return "Fences enabled, but none selected"
        if auto in (1, 2) and now_s - self._last_autoenable_warning_s > AUTOENABLE_WARNING_S:
            self._last_autoenable_warning_s = now_s
            self.say(
                int(mavlink2.MAV_SEVERITY_WARNING),
                f"FENCE_AUTOENABLE is {auto}, will be removed in 4.7, use 3",
            )
        configured = self.configured
        if (not self.enabled and not auto) or not configured:
            return None
        if configured & (CIRCLE | POLYGON) and (pos is None or pos.from_home is None):
            return "Fence requires position"
        margin_m = self.margin_m
        if configured & POLYGON and any(
            z.radius_m < margin_m for z in self.zones.inclusion_circles
        ):
            return "Polygon fence margin is greater than inclusion circle radius"
        radius_m = self.param("FENCE_RADIUS")
        if radius_m < 0:
            return "Invalid Circle FENCE_RADIUS value"
        if radius_m < margin_m:
            return "Circle FENCE_MARGIN is greater than FENCE_RADIUS"
        alt_max_m, alt_min_m = self.param("FENCE_ALT_MAX"), self.param("FENCE_ALT_MIN")
        if alt_max_m < 0:
            return "Invalid FENCE_ALT_MAX value"
        if alt_min_m < -100:
            return "Invalid FENCE_ALT_MIN value"
        breached = self.breaches
        if auto == 3:
            if pos is None or pos.here is None:
                return "Fence requires position"
            if self.zones.breached(pos.here, self.option(2))[0]:
                breached |= POLYGON
        if breached:
            # (ArduPilot names the breaches recorded, not the one just found.)
            return f"Vehicle breaching {fence_names(self.breaches)}"
        if margin_m < 0:
            return "Invalid FENCE_MARGIN value"
        if alt_max_m < alt_min_m:
            return "FENCE_ALT_MAX < FENCE_ALT_MIN"
        if alt_max_m - alt_min_m <= 2 * margin_m:
            return "FENCE_MARGIN too big"
        return None

    def sys_status(self) -> tuple[bool, bool, bool]:
        """SYS_STATUS's geofence bit: (present, enabled, healthy)."""
        present = self.present() != 0
        enabled = present and self.action != Action.REPORT_ONLY and self.enabled
        return present, enabled, not (present and self.breaches)

    def status(self) -> tuple[int, int, int, float] | None:
        """FENCE_STATUS (breach_status, breach_count, breach_type, breach time in sim s).

        None while no fence is enabled: ArduPilot sends none then.
        """
        if not self.enabled:
            return None
        kind = int(mavlink2.FENCE_BREACH_NONE)
        if self.breaches & ALT_MIN:
            kind = int(mavlink2.FENCE_BREACH_MINALT)
        if self.breaches & ALT_MAX:
            kind = int(mavlink2.FENCE_BREACH_MAXALT)
        if self.breaches & (CIRCLE | POLYGON):
            kind = int(mavlink2.FENCE_BREACH_BOUNDARY)
        return int(self.breaches != 0), self.breach_count, kind, self.breach_time_s


# -- each firmware's reaction (its fence_check) ---------------------------------------------

_COPTER_MANUAL_THROTTLE: Final = frozenset({"STABILIZE", "ACRO"})
"""ArduCopter's modes with the pilot's throttle (has_manual_throttle)."""

_COPTER_ACTIONS: Final[dict[int, tuple[str, ...]]] = {
    1: ("RTL", "LAND"),
    2: ("LAND",),
    3: ("SMART_RTL", "RTL", "LAND"),
    4: ("BRAKE", "LAND"),
    5: ("SMART_RTL", "LAND"),
}
"""ArduCopter's FENCE_ACTION: the modes tried in turn (others act as 1)."""

_ROVER_ACTIONS: Final[dict[int, tuple[str, ...]]] = {
    1: ("RTL", "HOLD"),
    2: ("HOLD",),
    3: ("SMART_RTL", "RTL", "HOLD"),
    4: ("SMART_RTL", "HOLD"),
    6: ("LOITER", "HOLD"),
}
"""ArduRover's FENCE_ACTION (its FailsafeAction): the modes tried in turn; 5 disarms."""

_PLANE_GUIDED_ACTIONS: Final = frozenset({6, 7})
"""ArduPlane's FENCE_ACTION 6 (Guided) and 7 (GuidedThrottlePass): to the return point."""


def _first_mode(vehicle: ApVehicle, modes: Sequence[str]) -> None:
    for mode in modes:
        if vehicle.try_mode(mode, "fence"):
            return


def react(
    vehicle: ApVehicle,
    fence: ArduFence,
    new: int,
    orig: int,
    guide: Callable[[Point2 | None, float], None],
) -> None:
    """Each firmware's fence_check after a check: its texts, and FENCE_ACTION when armed.

    Args:
        vehicle: The autopilot.
        fence: Its fence, just checked.
        new: The fences newly breached by that check.
        orig: The fences breached before it.
        guide: ArduPlane's GUIDED action: fly to a point (None: home) at a height
            above home.
    """
    firmware = vehicle.firmware
    if firmware == "arducopter":
        _react_copter(vehicle, fence, new, orig)
    elif firmware == "ardurover":
        _react_rover(vehicle, fence, new)
    else:
        _react_plane(vehicle, fence, new, orig, guide)


def _react_copter(vehicle: ApVehicle, fence: ArduFence, new: int, orig: int) -> None:
    if not new and orig and not fence.breaches and not vehicle.landed:
        vehicle.text(_NOTICE, "Fence breach cleared")
    if not vehicle.armed or not new:
        return
    if not vehicle.landed:
        vehicle.text(_NOTICE, f"{fence_names(new)} breached")
    action = fence.action
    if action == Action.REPORT_ONLY:
        return
    manual_zero = (
        vehicle.mode in _COPTER_MANUAL_THROTTLE
        and vehicle.throttle_zero
        and not fence.breaches & ALT_MAX
    )
    if vehicle.landed or manual_zero:
        vehicle.disarm()
    elif fence.breach_distance(new) > GIVE_UP_DISTANCE_M:
        vehicle.try_mode("LAND", "fence")
    else:
        _first_mode(vehicle, _COPTER_ACTIONS.get(action, _COPTER_ACTIONS[1]))


def _react_rover(vehicle: ApVehicle, fence: ArduFence, new: int) -> None:
    if not vehicle.armed or not new:
        return
    action = fence.action
    if action == Action.REPORT_ONLY:
        return
    if fence.breach_distance(new) > GIVE_UP_DISTANCE_M:
        vehicle.try_mode("HOLD", "fence")
    elif action == 5:
        vehicle.disarm()
    else:
        _first_mode(vehicle, _ROVER_ACTIONS.get(action, ()))


def _react_plane(
    vehicle: ApVehicle,
    fence: ArduFence,
    new: int,
    orig: int,
    guide: Callable[[Point2 | None, float], None],
) -> None:
    if not fence.enabled or not vehicle.armed:
        return
    if vehicle.mode_reason == "fence":
        return  # in fence recovery: once only, until the fence is switched off and on
    if not new:
        if orig and not fence.breaches:
            vehicle.text(_NOTICE, "Fence breach cleared")
        return
    vehicle.text(_NOTICE, f"{fence_names(new)} breached")
    action = fence.action
    if action in (1, 8):
        if action == 8 and vehicle.try_mode("AUTOLAND", "fence"):
            return
        vehicle.try_mode("RTL", "fence")
    elif action in _PLANE_GUIDED_ACTIONS:
        vehicle.try_mode("GUIDED", "fence")
        ret_alt_m = vehicle.param("FENCE_RET_ALT")
        safe_min = fence.param("FENCE_ALT_MIN") + fence.margin_m
        safe_max = fence.param("FENCE_ALT_MAX") - fence.margin_m
        if ret_alt_m > 0:
            alt_m = ret_alt_m
        elif safe_min >= safe_max:
            alt_m = vehicle.param("RTL_ALTITUDE")
        else:
            alt_m = (safe_min + safe_max) / 2
        guide(fence.zones.return_point, alt_m)
