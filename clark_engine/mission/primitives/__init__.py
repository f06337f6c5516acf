"""The registry of primitives a mission can ``use:``.

Each primitive is one module in this package exporting ``SPEC``; the registry
below is the single list of them, from which the mission schema is built and
against which every ``use:`` is resolved when a mission loads.
"""

from __future__ import annotations

from types import MappingProxyType

from clark_engine.mission.primitives import (
    doublet,
    follow_agent,
    hold,
    land,
    photo_trigger,
    return_home,
    set_mode,
    sine_sweep,
    takeoff,
    terminate,
    wait,
    waypoint,
    waypoint_tour,
)
from clark_engine.mission.primitives.base import PrimitiveSpec, UseContext

_MODULES = (
    waypoint,
    waypoint_tour,
    follow_agent,
    doublet,
    sine_sweep,
    photo_trigger,
    hold,
    set_mode,
    wait,
    terminate,
    takeoff,
    land,
    return_home,
)

#: Primitive name -> declaration, in the order the language reference lists them.
PRIMITIVES: MappingProxyType[str, PrimitiveSpec] = MappingProxyType(
    {module.SPEC.name: module.SPEC for module in _MODULES}
)

__all__ = ["PRIMITIVES", "PrimitiveSpec", "UseContext"]
