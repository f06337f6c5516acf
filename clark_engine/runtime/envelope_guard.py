"""The envelope's guard: every Goto and Takeoff kept inside the envelope as it leaves.

:class:`EnvelopeGuard` is the last step before a vehicle command leaves the core
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

Separate from the watch (``envelope_watch.py``) because it acts on what the engine
sends, not on what the vehicle reports; what both share is in ``envelope.py``.
"""

from __future__ import annotations

import logging
import math
from collections.abc import Iterable, Sequence
from dataclasses import dataclass, replace
from typing import Final

from clark_engine.behaviors.shared import LOITER_RADIUS_FACTOR, orbit_radius_m
from clark_engine.mission.fence import Zone
from clark_engine.mission.geo import LocalPoint, to_global, to_local
from clark_engine.runtime.commands import Goto, Takeoff, UploadMission
from clark_engine.runtime.config import AgentConfig, EnvelopeSpec
from clark_engine.runtime.envelope import PeerFix, origin, separation_words
from clark_engine.runtime.events import VehicleState
from clark_engine.runtime.log_events import LogEvent
from clark_engine.runtime.mission_envelope import judge_upload

SEPARATION_ROUNDS: Final = 4
"""How many times a target pushed out of one peer's bubble is checked again against
the fence, the heights and every bubble, before the guard gives up and refuses it."""

_MOVED_M: Final = 1e-3
"""A clamp that moves a target less than this (float round-off) did not move it."""


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
        self._origin = origin(config)
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
            command: A Goto, a Takeoff or a mission upload the behaviour issued.
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
        return f"{separation_words(env, peer)} and the {env.margin_m:g} m margin"

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
