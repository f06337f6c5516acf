"""The envelope held in flight: what its guard and its watch share.

``clark validate`` proves what it can before flight, but a reactive behaviour (a
follow, an orbit, a failsafe) decides its targets from what arrives over the air, and
a peer's report is hostile until proved otherwise: a rover whose origin height is
wrong reports 90 m, and a copter told to follow it 12 m up would climb to 102 m. So
the runtime holds the envelope itself, in three pieces, each pure (no clock, no I/O)
and each a module of its own:

- :class:`~clark_engine.runtime.envelope_guard.EnvelopeGuard`, the last step before a
  vehicle command leaves the core (``envelope_guard.py``);
- :class:`~clark_engine.runtime.envelope_watch.EnvelopeWatch`, run every tick
  (``envelope_watch.py``);
- :class:`~clark_engine.runtime.mode_owner.ModeOwner`: whether the mode the vehicle
  reports is one the engine put it in (``mode_owner.py``).

This module holds what the guard and the watch both use, and is separate so that
neither imports the other: where the peers are (:class:`PeerPositions`, one list per
tick that both read), how far apart the envelope keeps vehicles, and the clearance
that ends a breach.

docs/safety.md (the runtime's row) and docs/runtime.md (Safety) say what is held and
what is logged.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Final

from clark_engine.link.fleet import FleetTable
from clark_engine.link.messages import AgentStatus
from clark_engine.mission.geo import Origin, to_local
from clark_engine.runtime.config import AgentConfig, EnvelopeSpec

BREACH_CLEAR_M: Final = 1.0
"""How far back inside a limit a vehicle must be before a breach of it is over. A
vehicle hovering on the fence's edge in GPS noise would otherwise start and end a
breach every tick, and log each."""


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
        self._origin = origin(config)
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


def origin(config: AgentConfig) -> Origin:
    """The agent's origin, the point its local plane (north, east, up) is measured from."""
    return Origin(config.origin_lat_deg, config.origin_lon_deg, config.origin_alt_amsl_m)


def separation_words(envelope: EnvelopeSpec, peer: str) -> str:
    """What is kept from ``peer`` on reported positions, in words.

    ``5 m separation``, or with position errors ``1 m separation and the 7.4 m of the two
    vehicles' position errors``.
    """
    text = f"{envelope.separation_from_m(peer):g} m separation"
    errors_m = envelope.position_errors_m(peer)
    if errors_m > 0:
        text += f" and the {errors_m:g} m of the two vehicles' position errors"
    return text
