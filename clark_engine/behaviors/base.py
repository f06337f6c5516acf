"""The lifecycle every behaviour's runtime class follows (py_trees' Behaviour), and its types.

``__init__`` takes the behaviour's typed, resolved parameters and nothing else;
``start`` runs on entering the state; ``update`` runs every tick, never blocks,
and reports running, done or failed; ``stop`` cleans up when the state is left
for any reason; ``on_payload`` receives payload events while the state is
active. The typed values compiled parameters become (:class:`Point`,
:class:`AgentRef`, :class:`ChannelMap`) live here too.

Nothing here imports the runtime at import time: a behaviour module is imported
by ``clark validate``, which must stay fast and free of the flight libraries.
"""

from __future__ import annotations

from collections.abc import Mapping
from enum import Enum
from typing import TYPE_CHECKING, Any, ClassVar, NamedTuple

from clark_engine.behaviors.declaration import Params

if TYPE_CHECKING:
    from clark_engine.runtime.context import PrimitiveContext
    from clark_engine.runtime.events import MissionProgress, MissionUploadResult, PayloadEvent


class Status(Enum):
    """What ``update`` reports each tick."""

    RUNNING = "running"
    DONE = "done"
    FAILED = "failed"


class Point(NamedTuple):
    """A compiled point, in both frames.

    Attributes:
        north_m: Metres north of the mission origin.
        east_m: Metres east of it.
        up_m: Metres above it.
        lat: Latitude, degrees.
        lon: Longitude, degrees.
        alt_m: Altitude above the mission origin, as Goto and VehicleState use it.
    """

    north_m: float
    east_m: float
    up_m: float
    lat: float
    lon: float
    alt_m: float

    @classmethod
    def from_config(cls, raw: Mapping[str, Any]) -> Point:
        """A point from a compiled config's ``{north_m, east_m, up_m, lat, lon, alt_m}``."""
        return cls(
            float(raw["north_m"]),
            float(raw["east_m"]),
            float(raw["up_m"]),
            float(raw["lat"]),
            float(raw["lon"]),
            float(raw["alt_m"]),
        )


def points_from_config(raw: list[Mapping[str, Any]]) -> tuple[Point, ...]:
    """The compiled points of a list parameter (a tour's ``waypoints``)."""
    return tuple(Point.from_config(p) for p in raw)


class AgentRef(NamedTuple):
    """Another agent as a compiled config names it: its name and its id.

    Attributes:
        name: The agent's name.
        agent_id: Its id (the fleet table is read by id).
    """

    name: str
    agent_id: int

    @classmethod
    def from_config(cls, raw: Mapping[str, Any]) -> AgentRef:
        """From a compiled ``{name, id}``."""
        return cls(str(raw["name"]), int(raw["id"]))


class ChannelMap(NamedTuple):
    """A control channel as a compiled config holds it.

    Attributes:
        name: The channel's name (``aileron``).
        rc: Its RC input, None when it has none.
        servo: Its servo output, None when it has none.
        pwm_min_us: Lowest pulse width it accepts.
        pwm_trim_us: Its trim (neutral) pulse width.
        pwm_max_us: Highest pulse width it accepts.
    """

    name: str
    rc: int | None
    servo: int | None
    pwm_min_us: int
    pwm_trim_us: int
    pwm_max_us: int

    @classmethod
    def from_config(cls, raw: Mapping[str, Any]) -> ChannelMap:
        """From a compiled channel map."""
        rc, servo = raw.get("rc"), raw.get("servo")
        return cls(
            name=str(raw["name"]),
            rc=int(rc) if rc is not None else None,
            servo=int(servo) if servo is not None else None,
            pwm_min_us=int(raw["pwm_min_us"]),
            pwm_trim_us=int(raw["pwm_trim_us"]),
            pwm_max_us=int(raw["pwm_max_us"]),
        )


class BehaviorRuntime:
    """Base class of the behaviours' runtime classes.

    Attributes:
        name: The behaviour's name as missions write it after ``use:``.
        params_type: Its typed parameters' class (a compiled mapping given to
            ``__init__`` is turned into it).
        params: The typed parameters.
    """

    name: ClassVar[str] = ""
    params_type: ClassVar[type[Params] | None] = None

    def __init__(self, params: Any) -> None:
        """Keep the parameters; no side effects here (the state may never be entered).

        Args:
            params: The typed parameters, or a compiled state's parameter mapping
                (turned into them through :attr:`params_type`).
        """
        if isinstance(params, Mapping) and self.params_type is not None:
            params = self.params_type.from_config(params)
        self.params = params

    def start(self, ctx: PrimitiveContext) -> None:
        """Called when the state is entered, before its first ``update``."""

    def update(self, ctx: PrimitiveContext) -> Status:
        """Called once per tick while the state is active; must not block."""
        return Status.RUNNING

    def stop(self, ctx: PrimitiveContext) -> None:
        """Called when the state is left (finished, interrupted, or terminated)."""

    def on_payload(self, ctx: PrimitiveContext, event: PayloadEvent) -> None:
        """Called for each payload event delivered while the state is active."""

    def on_mission(
        self, ctx: PrimitiveContext, event: MissionUploadResult | MissionProgress
    ) -> None:
        """Called for each mission event delivered while the state is active.

        An upload's outcome, or the autopilot's progress in the mission; only a behaviour
        that uploads a mission cares.
        """
