"""The envelope's watch: the vehicle and its peers looked at against the envelope each tick.

:class:`EnvelopeWatch`, run every tick: the vehicle's reported position against
the fence, the ceiling and the floor, its time armed against its endurance, and
every peer's fresh report against the separation. It reports what is in breach;
the runtime applies ``on_breach`` or ``on_near_miss`` once, as a failsafe.

Separate from the guard (``envelope_guard.py``) because it looks at what the vehicle
reports rather than at what the engine sends; what both share is in ``envelope.py``.
"""

from __future__ import annotations

import math
from collections.abc import Iterable
from dataclasses import dataclass, field
from typing import Final

from clark_engine.mission.geo import to_local
from clark_engine.runtime.config import AgentConfig, EnvelopeSpec
from clark_engine.runtime.envelope import (
    BREACH_CLEAR_M,
    PeerFix,
    largest_pair_separation_m,
    origin,
    separation_words,
)
from clark_engine.runtime.events import VehicleState

#: The order in which breaches found in the same tick are acted on: the first one
#: found is the one whose action is applied.
BREACH_KINDS: Final = ("fence", "ceiling", "floor", "endurance", "separation")


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
        self._origin = origin(config)
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
                        f"{separation_words(env, peer.name)}",
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
