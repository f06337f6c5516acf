"""The runtime primitives: the behaviour classes that execute what missions ``use:``.

Each primitive is one module here, beside its mission-layer declaration in
:mod:`clark_engine.mission.primitives` (parameter schema, events, checks). The
registry below maps every mission name to its class; a test holds it equal to
the mission registry, so no primitive can be declared without being runnable, or
the reverse. :func:`make_primitive` builds one from a compiled state when the
runtime loads, so names are resolved before anything flies.
"""

from __future__ import annotations

from collections.abc import Mapping
from types import MappingProxyType

from clark_engine.runtime.config import ConfigError, StateSpec
from clark_engine.runtime.primitives.base import Primitive
from clark_engine.runtime.primitives.doublet import Doublet
from clark_engine.runtime.primitives.follow_agent import FollowAgent
from clark_engine.runtime.primitives.hold import Hold
from clark_engine.runtime.primitives.land import Land
from clark_engine.runtime.primitives.photo_trigger import PhotoTrigger
from clark_engine.runtime.primitives.return_home import ReturnHome
from clark_engine.runtime.primitives.set_mode import SetModePrimitive
from clark_engine.runtime.primitives.sine_sweep import SineSweep
from clark_engine.runtime.primitives.takeoff import Takeoff
from clark_engine.runtime.primitives.terminate import Terminate
from clark_engine.runtime.primitives.wait import Wait
from clark_engine.runtime.primitives.waypoint import Waypoint
from clark_engine.runtime.primitives.waypoint_tour import WaypointTour

_CLASSES: tuple[type[Primitive], ...] = (
    Waypoint,
    WaypointTour,
    FollowAgent,
    Doublet,
    SineSweep,
    PhotoTrigger,
    Hold,
    SetModePrimitive,
    Wait,
    Terminate,
    Takeoff,
    Land,
    ReturnHome,
)

#: Primitive name (as missions write it after ``use:``) -> its runtime class.
PRIMITIVE_CLASSES: Mapping[str, type[Primitive]] = MappingProxyType(
    {cls.name: cls for cls in _CLASSES}
)


def make_primitive(spec: StateSpec) -> Primitive:
    """Build the primitive a compiled state runs, from its resolved parameters.

    Args:
        spec: A state whose ``primitive`` names one of :data:`PRIMITIVE_CLASSES`.

    Raises:
        ConfigError: The state runs no primitive, or one this engine does not know
            (a config compiled by another version, or edited by hand).
    """
    if spec.primitive is None:
        raise ConfigError(f"{spec.source}: state {spec.path!r} runs no primitive")
    cls = PRIMITIVE_CLASSES.get(spec.primitive)
    if cls is None:
        known = ", ".join(PRIMITIVE_CLASSES)
        raise ConfigError(
            f"{spec.source}: state {spec.path!r} uses primitive {spec.primitive!r}, which this "
            f"engine does not have ({known}); compile the mission again with this clark"
        )
    return cls(spec.params)


__all__ = [
    "PRIMITIVE_CLASSES",
    "Doublet",
    "FollowAgent",
    "Hold",
    "Land",
    "PhotoTrigger",
    "Primitive",
    "ReturnHome",
    "SetModePrimitive",
    "SineSweep",
    "Takeoff",
    "Terminate",
    "Wait",
    "Waypoint",
    "WaypointTour",
    "make_primitive",
]
