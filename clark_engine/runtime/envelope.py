"""The envelope held in flight: every target checked as it leaves, the vehicle watched.

``clark validate`` proves what it can before flight, but a reactive behaviour (a
follow, an orbit, a failsafe) decides its targets from what arrives over the air, and
a peer's report is hostile until proved otherwise: a rover whose origin height is
wrong reports 90 m, and a copter told to follow it 12 m up would climb to 102 m. So
the runtime holds the envelope itself, in three pieces, each pure (no clock, no I/O):

- :class:`EnvelopeGuard`, the last step before a vehicle command leaves the core
  (``AgentRuntime._drain``; primitives never know it is there). A Goto is moved
  inside the envelope: its height between the floor and the ceiling, ``margin_m``
  in (aircraft; a rover's height is the ground's); its position inside the geofence
  by ``margin_m`` along the straight line from where the vehicle is
  (:meth:`clark_engine.mission.fence.Fence.clamp`), a fixed-wing aircraft's by its
  loiter radius more, since it circles its target; and outside every other
  vehicle's separation bubble around its latest reported position (the separation
  widened by both vehicles' ``position_error_m``, so that it holds on the truth
  whichever way each GPS is off). With
  ``outside: clamp`` the moved target goes out, as a fixed point (its velocity
  dropped: a moving target's velocity would carry the vehicle back out); with
  ``outside: refuse`` nothing goes out and the vehicle keeps its last target. A
  Takeoff's height is kept under the ceiling the same way. Every clamp and refusal
  is counted and logged, once per episode (the first, and a summary when the reason
  changes or the log closes), never a line per tick.
- :class:`EnvelopeWatch`, run every tick: the vehicle's reported position against
  the fence, the ceiling and the floor, its time armed against its endurance, and
  every peer's fresh report against the separation. It reports what is in breach;
  the runtime applies ``on_breach`` or ``on_near_miss`` once, as a failsafe.
- :class:`ModeOwner`: whether the mode the vehicle reports is one the engine put
  it in, so that a breach never fights a pilot (or a station) who took the vehicle.

docs/safety.md (the runtime's row) and docs/runtime.md (Safety) say what is held and
what is logged.
"""

from __future__ import annotations

import logging
import math
from collections.abc import Iterable, Sequence
from dataclasses import dataclass, field, replace
from typing import Final

from clark_engine.behaviors.shared import LOITER_RADIUS_FACTOR, orbit_radius_m
from clark_engine.link.fleet import FleetTable
from clark_engine.link.messages import AgentStatus
from clark_engine.mission.fence import Zone
from clark_engine.mission.geo import LocalPoint, Origin, to_global, to_local
from clark_engine.runtime.commands import Goto, Takeoff, UploadMission
from clark_engine.runtime.config import AgentConfig, EnvelopeSpec
from clark_engine.runtime.events import VehicleState
from clark_engine.runtime.log_events import LogEvent
from clark_engine.runtime.mission_envelope import judge_upload

BREACH_CLEAR_M: Final = 1.0
"""How far back inside a limit a vehicle must be before a breach of it is over. A
vehicle hovering on the fence's edge in GPS noise would otherwise start and end a
breach every tick, and log each."""

SEPARATION_ROUNDS: Final = 4
"""How many times a target pushed out of one peer's bubble is checked again against
the fence, the heights and every bubble, before the guard gives up and refuses it."""

_MOVED_M: Final = 1e-3
"""A clamp that moves a target less than this (float round-off) did not move it."""

#: The order in which breaches found in the same tick are acted on: the first one
#: found is the one whose action is applied.
BREACH_KINDS: Final = ("fence", "ceiling", "floor", "endurance", "separation")


PREDICT_MAX_S: Final = 1.0
"""How far ahead a peer's report is carried along its reported velocity, at most: a report
at 2 Hz is up to half a second old, and a truck closing at 4 m/s is 2 m nearer than it
says. Beyond a second a straight line is no longer a fair guess of where it went."""

PREDICT_MIN_SPEED_M_S: Final = 0.5
"""Below this reported ground speed a peer is taken to stand where it reported (a GPS's
speed at rest is noise)."""


@dataclass(frozen=True, slots=True)
class PeerFix:
    """Another vehicle's position on the local plane, as its latest Agent Status puts it.

    A moving peer has two fixes: where it reported itself, and where that report's
    velocity puts it now (``predicted``); the separation is kept from both, so a report's
    age never lets a vehicle come closer than its separation says.

    Attributes:
        name: The peer's name.
        north_m: Metres north of the origin.
        east_m: Metres east of the origin.
        up_m: Metres above the origin (as it reported).
        received_s: When the report arrived (runtime clock).
        predicted: Carried forward from the report along its velocity, to now.
    """

    name: str
    north_m: float
    east_m: float
    up_m: float
    received_s: float
    predicted: bool = False


_Velocity = tuple[float, float, float, float]
"""North, east and up (m/s), and the 3-D speed they make."""

PREDICT_NEAR_M: Final = 100.0
"""Beyond the largest separation the envelope keeps, how far (on the ground) a peer's report
may put it from the vehicle and still be carried forward. A peer farther than that, plus
what its speed covers in :data:`PREDICT_MAX_S`, cannot be inside any separation within the
second a prediction covers; fifty peers' predictions every tick would otherwise cost the
time of the tick itself."""


class PeerPositions:
    """The peers' latest reports as :class:`PeerFix`, converted once per report.

    Only the mission's other vehicles are looked at (a station sends no position).
    Each report is converted to the local plane when it first arrives and reused
    until the next one, and the list is made once per tick (the watch and the guard
    share it), so the per-tick cost is one dictionary look-up per peer.

    Args:
        config: The agent's compiled config (its peers, its origin).
        fleet: The agent's fleet table.
        largest_separation_m: The largest separation (with its margins) the envelope
            keeps from any peer: a moving peer is carried forward while its report is
            within this, :data:`PREDICT_NEAR_M` and a second of its speed.
    """

    def __init__(
        self, config: AgentConfig, fleet: FleetTable, largest_separation_m: float = 0.0
    ) -> None:
        self._fleet = fleet
        self._near_m = largest_separation_m + PREDICT_NEAR_M
        self._origin = _origin(config)
        self._peers = tuple((p.id, p.name) for p in config.peers if p.role == "vehicle")
        self._cache: dict[int, tuple[object, PeerFix, _Velocity | None]] = {}
        #: The reported fixes with their velocities, as of the fleet table's ``stored``.
        self._reported: list[tuple[PeerFix, _Velocity | None]] = []
        self._stored = -1
        self._made: tuple[float | None, tuple[float, float] | None, list[PeerFix]] | None = None
        self._made_from: list[tuple[PeerFix, _Velocity | None]] | None = None

    def _reports(self) -> list[tuple[PeerFix, _Velocity | None]]:
        """Every vehicle peer's latest report as a fix and a velocity.

        Rebuilt only when the fleet table stored an Agent Status since the last time.
        """
        if self._fleet.statuses_stored == self._stored:
            return self._reported
        self._stored = self._fleet.statuses_stored
        out: list[tuple[PeerFix, _Velocity | None]] = []
        for peer_id, name in self._peers:
            record = self._fleet.record(peer_id)
            if record is None:
                continue
            sample = record.sample(AgentStatus)
            if sample is None:
                continue
            cached = self._cache.get(peer_id)
            if cached is None or cached[0] is not sample:
                status = sample.value
                point = to_local(status.lat_deg, status.lon_deg, status.alt_m, self._origin)
                fix = PeerFix(name, point.north_m, point.east_m, point.up_m, sample.received_s)
                cached = (sample, fix, _velocity(status))
                self._cache[peer_id] = cached
            out.append((cached[1], cached[2]))
        self._reported = out
        return out

    def fixes(
        self, now_s: float | None = None, here: tuple[float, float] | None = None
    ) -> list[PeerFix]:
        """Every vehicle peer's latest reported position, stale or not.

        With ``now_s`` and the vehicle's own position ``here`` (north, east), a peer that
        reported itself moving near it (see :data:`PREDICT_NEAR_M`) also gets a second
        fix: its report carried along its reported velocity to ``now_s`` (at most
        :data:`PREDICT_MAX_S` ahead). Asked again with the same time and position (the
        guard, after the watch, in one tick) and nothing new heard, the same list is
        given back.
        """
        reports = self._reports()
        made = self._made
        if (
            made is not None
            and now_s is not None
            and made[0] == now_s
            and made[1] == here
            and made[2] is not None
            and self._made_from is reports
        ):
            return made[2]
        out = [fix for fix, _ in reports]
        if now_s is not None and here is not None:
            for fix, velocity in reports:
                if velocity is None:
                    continue
                vn, ve, vu, speed_m_s = velocity
                dn, de = fix.north_m - here[0], fix.east_m - here[1]
                near_m = self._near_m + speed_m_s * PREDICT_MAX_S
                if dn * dn + de * de > near_m * near_m:
                    continue
                ahead_s = min(max(now_s - fix.received_s, 0.0), PREDICT_MAX_S)
                if ahead_s > 0.0:
                    out.append(
                        PeerFix(
                            fix.name,
                            fix.north_m + vn * ahead_s,
                            fix.east_m + ve * ahead_s,
                            fix.up_m + vu * ahead_s,
                            fix.received_s,
                            predicted=True,
                        )
                    )
        self._made = (now_s, here, out)
        self._made_from = reports
        return out


def _velocity(status: AgentStatus) -> _Velocity | None:
    """A report's velocity north, east and up, and its 3-D speed (m/s).

    None for a peer standing still.
    """
    speed = status.ground_speed_m_s
    if speed < PREDICT_MIN_SPEED_M_S:
        return None
    heading = math.radians(status.heading_deg)
    climb = status.climb_rate_m_s
    return (
        speed * math.cos(heading),
        speed * math.sin(heading),
        climb,
        math.sqrt(speed * speed + climb * climb),
    )


def largest_pair_separation_m(envelope: EnvelopeSpec) -> float:
    """The largest distance the envelope keeps from any peer on reported positions.

    The largest separation (mission-wide or a pair's), widened by this vehicle's position
    error and the largest of its peers' (an upper bound of every pair's figure).
    """
    errors_m = envelope.position_error_m + max(envelope.peer_position_error_m.values(), default=0.0)
    return max(envelope.min_separation_m, *envelope.separation.values(), 0.0) + errors_m


def largest_separation_m(envelope: EnvelopeSpec) -> float:
    """The farthest from any peer that the watch or the guard acts on.

    That is the largest separation, the margin and a breach's clearance (a plane's loiter
    circle is left to :data:`PREDICT_NEAR_M`).
    """
    return largest_pair_separation_m(envelope) + envelope.margin_m + BREACH_CLEAR_M


def _origin(config: AgentConfig) -> Origin:
    return Origin(config.origin_lat_deg, config.origin_lon_deg, config.origin_alt_amsl_m)


def _convex(zone: Zone) -> bool:
    """True for a circle, and for a polygon whose corners all turn the same way."""
    if zone.kind == "circle":
        return True
    corners = zone.corners
    turns = set()
    for i, (n0, e0) in enumerate(corners):
        n1, e1 = corners[(i + 1) % len(corners)]
        n2, e2 = corners[(i + 2) % len(corners)]
        cross = (n1 - n0) * (e2 - e1) - (e1 - e0) * (n2 - n1)
        if abs(cross) > 1e-9:
            turns.add(cross > 0)
    return len(turns) <= 1


def loiter_radius_m(config: AgentConfig, speed_m_s: float | None = None) -> float:
    """How far from its guided target the vehicle circles it: 0 but for a fixed wing.

    The mission layer's figure (:func:`clark_engine.behaviors.shared.
    orbit_radius_m`, the one behind W-ORBIT-TOLERANCE): ArduPlane's WP_LOITER_RAD from
    the autopilot profile's parameters, as flown, or wider when the airframe's speed
    and bank limits force it.
    """
    hardware = config.raw["agent"]["hardware"]
    radius = orbit_radius_m(hardware.get("airframe") or {}, hardware.get("autopilot"), speed_m_s)
    return float(radius or 0.0)


@dataclass(frozen=True, slots=True)
class EnvelopeCounts:
    """What the guard did with the targets it checked.

    Attributes:
        checked: Gotos and Takeoffs checked.
        clamped: Sent moved inside the envelope.
        refused: Not sent.
        clamped_by: Reason -> how many of the clamped it moved (a target moved for two
            reasons counts under both).
        refused_by: Reason -> how many refusals it caused.
    """

    checked: int
    clamped: int
    refused: int
    clamped_by: dict[str, int]
    refused_by: dict[str, int]

    def describe(self) -> str:
        """One phrase for the mission log: ``12 targets checked, 3 clamped (ceiling 3)...``."""

        def by(counts: dict[str, int]) -> str:
            if not counts:
                return ""
            return " (" + ", ".join(f"{k} {n}" for k, n in sorted(counts.items())) + ")"

        return (
            f"{self.checked} targets checked, {self.clamped} clamped{by(self.clamped_by)}, "
            f"{self.refused} refused{by(self.refused_by)}"
        )


@dataclass(slots=True)
class _Episode:
    """Targets handled alike in a row: logged once at the start, summed up at the end."""

    key: tuple[str, str, tuple[str, ...]]  # (command, outcome, reasons)
    first_s: float
    last_s: float
    count: int = 1


class EnvelopeGuard:
    """Keeps every Goto and Takeoff inside the envelope before it leaves the core.

    Args:
        config: The agent's compiled config (a vehicle with an envelope).
        envelope: Its envelope.
        log: The mission log.
    """

    def __init__(self, config: AgentConfig, envelope: EnvelopeSpec, log: logging.Logger) -> None:
        self.config = config
        self.envelope = envelope
        self._log = log
        self._origin = _origin(config)
        self._aircraft = config.is_aircraft
        self._fixed_wing = config.airframe_class == "fixed_wing"
        self._loiter_m: dict[float | None, float] = {}
        self._checked = 0
        self._clamped = 0
        self._refused = 0
        self._clamped_by: dict[str, int] = {}
        self._refused_by: dict[str, int] = {}
        self._episode: _Episode | None = None
        fence = envelope.fence
        self._convex_fence = not fence.exclude and all(_convex(z) for z in fence.include)

    @property
    def counts(self) -> EnvelopeCounts:
        """What was checked, clamped and refused so far."""
        return EnvelopeCounts(
            self._checked,
            self._clamped,
            self._refused,
            dict(self._clamped_by),
            dict(self._refused_by),
        )

    # -- the check ---------------------------------------------------------------------

    def check(
        self,
        command: Goto | Takeoff | UploadMission,
        vehicle: VehicleState | None,
        peers: Sequence[PeerFix],
        now_s: float,
    ) -> Goto | Takeoff | UploadMission | None:
        """The command to send instead of ``command``: itself, moved inside, or None.

        Args:
            command: A Goto or a Takeoff the behaviour issued.
            vehicle: The vehicle's latest state (None before the first).
            peers: The other vehicles' latest reported positions.
            now_s: The runtime clock, for the log.
        """
        self._checked += 1
        if isinstance(command, UploadMission):  # whole or not at all (mission_envelope.py)
            return judge_upload(self, command, vehicle, self._origin, now_s)
        if isinstance(command, Takeoff):
            return self._takeoff(command, now_s)
        return self._goto(command, vehicle, peers, now_s)

    def _takeoff(self, takeoff: Takeoff, now_s: float) -> Takeoff | None:
        env = self.envelope
        top_m = env.ceiling_m - env.margin_m
        if not self._aircraft or takeoff.alt_m <= top_m:
            return takeoff
        note = (
            f"{takeoff.alt_m:.1f} m above the origin is over the ceiling {env.ceiling_m:g} m "
            f"less the {env.margin_m:g} m margin"
        )
        if env.outside == "refuse":
            self._refuse("Takeoff", ("ceiling",), note + "; not sent", now_s)
            return None
        self._clamp("Takeoff", ("ceiling",), f"{note}; sent to {top_m:.1f} m", now_s)
        return Takeoff(top_m)

    def _goto(
        self,
        goto: Goto,
        vehicle: VehicleState | None,
        peers: Sequence[PeerFix],
        now_s: float,
    ) -> Goto | None:
        env = self.envelope
        if vehicle is None:
            self._refuse(
                "Goto",
                ("no vehicle state",),
                "no VehicleState has arrived yet, so where the vehicle is, and the line "
                "to the target, are unknown: the target cannot be checked; not sent",
                now_s,
            )
            return None
        here = to_local(vehicle.lat_deg, vehicle.lon_deg, vehicle.alt_m, self._origin)
        start = (here.north_m, here.east_m)
        aimed = to_local(goto.lat_deg, goto.lon_deg, goto.alt_m, self._origin)
        north, east = aimed.north_m, aimed.east_m
        # A rover's height is the ground's: its own, whatever the target says.
        up = aimed.up_m if self._aircraft else vehicle.alt_m
        reasons: list[str] = []
        notes: list[str] = []

        if self._aircraft:
            kept = self._height(up)
            if kept != up:
                kind = "ceiling" if up > kept else "floor"
                reasons.append(kind)
                notes.append(self._height_note(kind, up, kept))
                up = kept

        inset_m = env.margin_m + self._loiter(goto.speed_m_s, goto.loiter_radius_m)
        point = self._fence_clamp(start, (north, east), inset_m)
        if point is None:
            self._refuse(
                "Goto",
                (*reasons, "fence"),
                "; ".join(
                    [
                        *notes,
                        f"fence: no point {self._inset_text(inset_m)} inside the geofence "
                        f"was found on the way to north {north:.1f} m, east {east:.1f} m; "
                        "not sent",
                    ]
                ),
                now_s,
            )
            return None
        if math.dist(point, (north, east)) > _MOVED_M:
            reasons.append("fence")
            notes.append(self._fence_note((north, east), point, start, inset_m))
            north, east = point

        for _ in range(SEPARATION_ROUNDS):
            intruded = self._intruded(north, east, up, peers, goto.speed_m_s)
            if intruded is None:
                break
            peer, need_m, apart_m = intruded
            pushed = self._push(peer, need_m, (north, east, up), here)
            kind = f"separation from {peer.name}"
            if pushed is None:
                self._refuse(
                    "Goto",
                    (*reasons, kind),
                    "; ".join(
                        [
                            *notes,
                            f"separation: the target is at {peer.name}'s last reported "
                            "position and the vehicle too: no way out of its bubble; not sent",
                        ]
                    ),
                    now_s,
                )
                return None
            if kind not in reasons:
                reasons.append(kind)
                notes.append(
                    f"separation: the target is {apart_m:.1f} m from {peer.name}'s last "
                    f"reported position, inside its {self._separation_text(peer.name)}; "
                    f"moved out to {need_m:.1f} m from it"
                )
            north, east, up = pushed
            if self._aircraft:
                up = self._height(up)
            point = self._fence_clamp(start, (north, east), inset_m)
            if point is None:
                break
            north, east = point
        # Pushed out of one bubble into another, or against the fence, round after round:
        # no target keeps them all.
        if point is None or self._intruded(north, east, up, peers, goto.speed_m_s) is not None:
            self._refuse(
                "Goto",
                tuple(reasons),
                "; ".join(
                    [
                        *notes,
                        "no target was found that keeps out of every other vehicle's "
                        "separation and inside the geofence; not sent",
                    ]
                ),
                now_s,
            )
            return None

        if not reasons:
            return goto
        if env.outside == "refuse":
            self._refuse("Goto", tuple(reasons), "; ".join(notes) + "; not sent", now_s)
            return None
        lat_deg, lon_deg, _ = to_global(LocalPoint(north, east, up), self._origin)
        alt_m = up if self._aircraft else goto.alt_m
        self._clamp(
            "Goto",
            tuple(reasons),
            "; ".join(notes) + f"; sent to {lat_deg:.7f} {lon_deg:.7f} {alt_m:.1f} m",
            now_s,
        )
        return replace(
            goto,
            lat_deg=lat_deg,
            lon_deg=lon_deg,
            alt_m=alt_m,
            velocity_north_m_s=None,
            velocity_east_m_s=None,
        )

    # -- geometry ----------------------------------------------------------------------

    def _fence_clamp(
        self, start: tuple[float, float], target: tuple[float, float], inset_m: float
    ) -> tuple[float, float] | None:
        """:meth:`Fence.clamp`, without its walk along the line where the line is plainly in.

        ``Fence.clamp`` moves a target outside to the nearest point inside, then walks
        the line from the vehicle to it in up to 256 steps, looking for where it leaves
        the fence: milliseconds for a polygon. The walk is skipped when both ends are
        ``inset_m`` inside and either the fence is convex (inclusion circles and convex
        polygons, no exclusion zone: a straight line between two points inside stays
        inside, at least as far in as its nearer end), or the ends are far enough in
        that no line between them could reach the edge (a fence's margin changes by at
        most a metre per metre moved). Same answer, two margins instead of hundreds.
        """
        fence = self.envelope.fence
        goal = target
        goal_margin_m = fence.margin_m(*goal)
        if goal_margin_m < inset_m:
            moved = fence.nearest_inside(*goal, inset_m)
            if moved is None:
                return None
            goal, goal_margin_m = moved, fence.margin_m(*moved)
        start_margin_m = fence.margin_m(*start)
        if start_margin_m >= inset_m and goal_margin_m >= inset_m - 1e-6:
            if self._convex_fence:
                return goal
            if (start_margin_m + goal_margin_m - math.dist(start, goal)) / 2.0 >= inset_m:
                return goal
        return fence.clamp(start, goal, inset_m)

    def _height(self, up_m: float) -> float:
        """A height kept ``margin_m`` inside the floor and the ceiling (aircraft)."""
        env = self.envelope
        low, high = env.floor_m + env.margin_m, env.ceiling_m - env.margin_m
        if high < low:  # a band narrower than two margins: its middle
            return (env.floor_m + env.ceiling_m) / 2.0
        return min(max(up_m, low), high)

    def _height_note(self, kind: str, up_m: float, kept_m: float) -> str:
        env = self.envelope
        if kind == "ceiling":
            limit = f"over the ceiling {env.ceiling_m:g} m"
        else:
            limit = f"under the floor {env.floor_m:g} m"
        return (
            f"{kind}: {up_m:.1f} m above the origin is {limit} less the {env.margin_m:g} m "
            f"margin; sent at {kept_m:.1f} m"
        )

    def _loiter(self, speed_m_s: float | None, asked_m: float | None = None) -> float:
        if not self._fixed_wing:
            return 0.0
        radius = self._loiter_m.get(speed_m_s)
        if radius is None:
            radius = self._loiter_m[speed_m_s] = loiter_radius_m(self.config, speed_m_s)
        if asked_m:  # a Goto's own loiter radius (orbit), flown as WP_LOITER_RAD is
            radius = max(radius, LOITER_RADIUS_FACTOR * asked_m)
        return radius

    def _inset_text(self, inset_m: float) -> str:
        margin = self.envelope.margin_m
        if inset_m <= margin + 1e-9:
            return f"{margin:g} m"
        loiter_m = inset_m - margin
        return f"{inset_m:.0f} m (the {margin:g} m margin and its {loiter_m:.0f} m loiter radius)"

    def _fence_note(
        self,
        target: tuple[float, float],
        point: tuple[float, float],
        start: tuple[float, float],
        inset_m: float,
    ) -> str:
        margin_m = self.envelope.fence.margin_m(*target)
        if margin_m < 0.0:
            where = f"is {-margin_m:.1f} m outside the geofence"
        elif margin_m < inset_m:
            where = f"is {margin_m:.1f} m inside the geofence, closer to its edge than"
            where += f" the {self._inset_text(inset_m)} kept"
        else:
            where = (
                f"is inside, but the straight line to it from north {start[0]:.1f} m, "
                f"east {start[1]:.1f} m leaves the geofence"
            )
        return (
            f"fence: north {target[0]:.1f} m, east {target[1]:.1f} m {where}; moved to "
            f"north {point[0]:.1f} m, east {point[1]:.1f} m"
        )

    def _separation_text(self, peer: str) -> str:
        env = self.envelope
        return f"{_separation_words(env, peer)} and the {env.margin_m:g} m margin"

    def _intruded(
        self,
        north_m: float,
        east_m: float,
        up_m: float,
        peers: Iterable[PeerFix],
        speed_m_s: float | None,
    ) -> tuple[PeerFix, float, float] | None:
        """The peer whose bubble the point is deepest inside: (peer, bubble, distance).

        A peer's bubble is its separation, the margin and, for a plane, its loiter circle.
        """
        env = self.envelope
        extra_m = env.margin_m + self._loiter(speed_m_s) + env.position_error_m
        default_m = env.min_separation_m + extra_m
        pairs = env.separation
        errors = env.peer_position_error_m
        worst: tuple[PeerFix, float, float] | None = None
        depth = 1e-6
        for peer in peers:
            dn, de, du = north_m - peer.north_m, east_m - peer.east_m, up_m - peer.up_m
            apart2 = dn * dn + de * de + du * du
            need_m = pairs[peer.name] + extra_m if peer.name in pairs else default_m
            if peer.name in errors:
                need_m += errors[peer.name]
            if apart2 >= (need_m - depth) ** 2:
                continue  # the usual case: far outside this bubble
            apart_m = math.sqrt(apart2)
            if need_m - apart_m > depth:
                worst, depth = (peer, need_m, apart_m), need_m - apart_m
        return worst

    def _push(
        self,
        peer: PeerFix,
        need_m: float,
        target: tuple[float, float, float],
        here: LocalPoint,
    ) -> tuple[float, float, float] | None:
        """The target moved out to ``need_m`` from the peer, along the line from the peer.

        An aircraft is moved in 3-D; a rover along the ground, at its own height. A
        target exactly at the peer is moved along the line from the peer to the
        vehicle instead; None when the vehicle is there too.
        """
        north, east, up = target
        if self._aircraft:
            for dn, de, du in (
                (north - peer.north_m, east - peer.east_m, up - peer.up_m),
                (here.north_m - peer.north_m, here.east_m - peer.east_m, here.up_m - peer.up_m),
            ):
                length = math.sqrt(dn * dn + de * de + du * du)
                if length > 1e-6:
                    k = need_m / length
                    return peer.north_m + dn * k, peer.east_m + de * k, peer.up_m + du * k
            return None
        dz = up - peer.up_m
        flat_m = math.sqrt(max(need_m * need_m - dz * dz, 0.0))
        for dn, de in (
            (north - peer.north_m, east - peer.east_m),
            (here.north_m - peer.north_m, here.east_m - peer.east_m),
        ):
            length = math.hypot(dn, de)
            if length > 1e-6:
                k = flat_m / length
                return peer.north_m + dn * k, peer.east_m + de * k, up
        return None

    # -- counting and logging ----------------------------------------------------------

    def _clamp(self, what: str, reasons: tuple[str, ...], note: str, now_s: float) -> None:
        self._clamped += 1
        for reason in reasons:
            self._clamped_by[reason] = self._clamped_by.get(reason, 0) + 1
        self._note((what, "clamped", reasons), note, now_s)

    def _refuse(self, what: str, reasons: tuple[str, ...], note: str, now_s: float) -> None:
        self._refused += 1
        for reason in reasons:
            self._refused_by[reason] = self._refused_by.get(reason, 0) + 1
        self._note((what, "refused", reasons), note, now_s)

    def _note(self, key: tuple[str, str, tuple[str, ...]], note: str, now_s: float) -> None:
        """Log the first of an episode; count the rest, summed up when the reason changes.

        A follow re-targets every second, so a leader above the ceiling would write a
        line a second for as long as it stays there; one line when it starts, and one
        when it is over (a different reason, or the log closing), say as much.
        """
        episode = self._episode
        if episode is not None and episode.key == key:
            episode.count += 1
            episode.last_s = now_s
            return
        self.end_episode()
        self._episode = _Episode(key, now_s, now_s)
        what, outcome, reasons = key
        self._log.warning(
            "envelope: %s %s (%s): %s",
            what,
            outcome,
            ", ".join(reasons),
            note,
            extra=LogEvent.ENVELOPE_LIMIT.extra,
        )

    def end_episode(self) -> None:
        """Write the summary of the episode under way, if it had more than its first."""
        episode, self._episode = self._episode, None
        if episode is None or episode.count < 2:
            return
        what, outcome, reasons = episode.key
        self._log.warning(
            "envelope: %d %ss %s (%s) from t=%.3f to t=%.3f, %d of them not logged one by one",
            episode.count,
            what,
            outcome,
            ", ".join(reasons),
            episode.first_s,
            episode.last_s,
            episode.count - 1,
            extra=LogEvent.ENVELOPE_LIMIT.extra,
        )


def _separation_words(envelope: EnvelopeSpec, peer: str) -> str:
    """What is kept from ``peer`` on reported positions, in words.

    ``5 m separation``, or with position errors ``1 m separation and the 7.4 m of the two
    vehicles' position errors``.
    """
    text = f"{envelope.separation_from_m(peer):g} m separation"
    errors_m = envelope.position_errors_m(peer)
    if errors_m > 0:
        text += f" and the {errors_m:g} m of the two vehicles' position errors"
    return text


@dataclass(frozen=True, slots=True)
class Breach:
    """One limit of the envelope the vehicle is outside of.

    Attributes:
        kind: ``fence``, ``ceiling``, ``floor``, ``endurance`` or ``separation``.
        detail: What was measured, in words (``12.3 m outside the geofence at ...``).
        action: What the envelope says to do: ``on_breach``, or ``on_near_miss`` for
            a separation.
        began_s: When it began (runtime clock).
        peer: The other vehicle, for a separation.
    """

    kind: str
    detail: str
    action: str
    began_s: float
    peer: str | None = None

    def describe(self) -> str:
        """``fence: 12.3 m outside the geofence at north 310.2 m, east 40.0 m``."""
        return f"{self.kind}: {self.detail}"


@dataclass(slots=True)
class WatchResult:
    """What one look found.

    Attributes:
        active: Every breach in force, in :data:`BREACH_KINDS` order.
        began: Those of them that began in this look.
        ended: Breaches that were in force and are over.
    """

    active: list[Breach] = field(default_factory=list)
    began: list[Breach] = field(default_factory=list)
    ended: list[Breach] = field(default_factory=list)


class EnvelopeWatch:
    """Looks at the vehicle's reported position, its time armed and its peers, each tick.

    Limits (docs/safety.md):

    - **fence**: the vehicle outside its geofence (every vehicle);
    - **ceiling**: an aircraft above its ceiling;
    - **floor**: an aircraft below its floor in guided flight (``guided_flight``: it
      flies in the guided mode, in the air, to a Goto rather than a take-off). The
      floor is watched from the moment it is first at or above it in guided flight,
      so the climb from a take-off to the first target is not a breach; leaving the
      guided mode (landing, returning home, the pilot's mode) stops watching it;
    - **endurance**: time armed, summed over the run, over ``endurance_s``;
    - **separation**: another vehicle's fresh report (no older than the mission's
      heartbeat timeout) within the separation, widened by both vehicles'
      ``position_error_m``, of the vehicle's position, in 3-D,
      while the vehicle is armed (two vehicles parked side by side are no danger).

    A breach is over when the vehicle is :data:`BREACH_CLEAR_M` back inside the limit;
    an endurance breach is never over.

    Args:
        config: The agent's compiled config.
        envelope: Its envelope.
    """

    def __init__(self, config: AgentConfig, envelope: EnvelopeSpec) -> None:
        self.envelope = envelope
        self._origin = _origin(config)
        self._aircraft = config.is_aircraft
        self._stale_s = config.heartbeat_timeout_s
        self.armed_s = 0.0
        """Time armed so far, summed over the run (the ticks the vehicle reported armed)."""
        self._last_s: float | None = None
        self._last_armed = False
        self._floor_watched = False
        self._active: dict[str, Breach] = {}
        self._reach_m = largest_pair_separation_m(envelope) + BREACH_CLEAR_M
        """No peer farther than this can be in breach of any pair's separation."""
        self._measured: tuple[float, float, float] | None = None
        """Where the fence margin was last measured: (north, east, margin)."""

    def _fence_margin_m(self, north_m: float, east_m: float) -> float:
        """The fence margin here, or a lower bound of it that is clear of any breach.

        A margin is a distance to the fence's edges, so it shrinks by at most the
        distance moved since it was measured: while that bound stays above the
        clearance a breach needs, the polygon is not measured again (a parked rover, a
        vehicle deep inside its fence). Near the edge it is measured every time.
        """
        last = self._measured
        if last is not None:
            moved_m = math.hypot(north_m - last[0], east_m - last[1])
            bound_m = last[2] - moved_m
            if bound_m > BREACH_CLEAR_M:
                return bound_m
        margin_m = self.envelope.fence.margin_m(north_m, east_m)
        self._measured = (north_m, east_m, margin_m)
        return margin_m

    def look(
        self,
        vehicle: VehicleState,
        peers: Iterable[PeerFix],
        now_s: float,
        *,
        guided_flight: bool,
    ) -> WatchResult:
        """Measure once; what is in breach, what began, what ended.

        Args:
            vehicle: The vehicle's latest state.
            peers: The other vehicles' latest reported positions (stale ones are skipped).
            now_s: The runtime clock.
            guided_flight: An aircraft flying to a Goto in the guided mode, in the air.
        """
        env = self.envelope
        if self._last_s is not None and self._last_armed:
            self.armed_s += max(0.0, now_s - self._last_s)
        self._last_s, self._last_armed = now_s, vehicle.armed
        here = to_local(vehicle.lat_deg, vehicle.lon_deg, vehicle.alt_m, self._origin)
        north, east, up = here.north_m, here.east_m, here.up_m
        found: dict[str, tuple[str, str, str | None]] = {}  # key -> (kind, detail, peer)

        margin_m = self._fence_margin_m(north, east)
        if margin_m < (BREACH_CLEAR_M if "fence" in self._active else 0.0):
            found["fence"] = (
                "fence",
                f"{max(-margin_m, 0.0):.1f} m outside the geofence at north {north:.1f} m, "
                f"east {east:.1f} m",
                None,
            )
        if self._aircraft:
            if up > env.ceiling_m - (BREACH_CLEAR_M if "ceiling" in self._active else 0.0):
                found["ceiling"] = (
                    "ceiling",
                    f"{up:.1f} m above the origin, over the ceiling {env.ceiling_m:g} m",
                    None,
                )
            if not guided_flight or env.floor_m <= 0.0:
                self._floor_watched = False
            elif up >= env.floor_m:
                self._floor_watched = True
            floor_m = env.floor_m + (BREACH_CLEAR_M if "floor" in self._active else 0.0)
            if self._floor_watched and guided_flight and up < floor_m:
                found["floor"] = (
                    "floor",
                    f"{up:.1f} m above the origin in guided flight, under the floor "
                    f"{env.floor_m:g} m",
                    None,
                )
        if env.endurance_s is not None and self.armed_s > env.endurance_s:
            found["endurance"] = (
                "endurance",
                f"armed for {self.armed_s:.0f} s, over its endurance of {env.endurance_s:g} s",
                None,
            )
        if vehicle.armed:
            closest: dict[str, float] = {}
            stale_before_s = now_s - self._stale_s
            # Any peer nearer than this is looked at closely; the rest (nearly all, in a
            # big fleet) cost one distance each.
            reach_m = self._reach_m
            reach2 = reach_m * reach_m
            for peer in peers:
                if peer.received_s < stale_before_s:
                    continue  # stale: where it was, not where it is
                dn, de, du = north - peer.north_m, east - peer.east_m, up - peer.up_m
                apart2 = dn * dn + de * de + du * du
                if apart2 >= reach2:
                    continue
                key = f"separation:{peer.name}"
                need_m = env.reported_separation_from_m(peer.name)
                limit_m = need_m + (BREACH_CLEAR_M if key in self._active else 0.0)
                if apart2 < limit_m * limit_m:
                    apart_m = math.sqrt(apart2)
                    if key in found and closest.get(key, math.inf) <= apart_m:
                        continue  # its other fix (reported or carried forward) is nearer
                    closest[key] = apart_m
                    where = " where its last report puts it now" if peer.predicted else ""
                    found[key] = (
                        "separation",
                        f"{peer.name} {apart_m:.1f} m away (3-D){where}, inside the "
                        f"{_separation_words(env, peer.name)}",
                        peer.name,
                    )

        result = WatchResult()
        for key in list(self._active):
            if key not in found:
                result.ended.append(self._active.pop(key))
        for key, (kind, detail, other) in found.items():
            breach = self._active.get(key)
            if breach is None:
                action = env.on_near_miss if kind == "separation" else env.on_breach
                breach = self._active[key] = Breach(kind, detail, action, now_s, other)
                result.began.append(breach)
            result.active.append(breach)
        result.active.sort(key=lambda b: BREACH_KINDS.index(b.kind))
        result.began.sort(key=lambda b: BREACH_KINDS.index(b.kind))
        return result


class ModeOwner:
    """Whether the vehicle is in a mode the engine put it in.

    The engine asks for modes (its behaviour's states, its failsafe); the pilot's
    switch, the station's Mode Change Request and the autopilot's own failsafes
    change them too. The vehicle is the engine's while the mode it reports is the
    last one the engine asked for: from the report that shows the engine's mode
    granted until a report of any other. While a request is pending the vehicle
    stays with whoever put it in the mode it still reports.
    """

    def __init__(self) -> None:
        self.asked: str | None = None
        """The mode the engine last asked for."""
        self.reported: str | None = None
        """The mode the vehicle last reported."""
        self.engine_holds = False
        """True while the reported mode is one the engine put the vehicle in."""

    def engine_asked(self, mode: str) -> None:
        """The engine asked for ``mode`` (a behaviour's SetMode, a failsafe's)."""
        self.asked = mode
        if self.reported == mode:
            self.engine_holds = True

    def mode_reported(self, mode: str) -> None:
        """The vehicle reported ``mode`` (a VehicleState, an autopilot heartbeat)."""
        if mode == self.reported:
            return
        self.reported = mode
        self.engine_holds = mode == self.asked
