"""hold: keep the vehicle where it is, in the autopilot's hold mode.

The mode comes from the profile (LOITER for planes and copters, HOLD for
rovers). Never finishes by itself: a transition moves the machine on.
"""

from __future__ import annotations

from clark_engine.mission.primitives.base import PrimitiveSpec, raises_nothing
from clark_engine.mission.schema_source.common import obj

SPEC = PrimitiveSpec(
    name="hold",
    summary="Hold position in the autopilot's hold mode until a transition moves on.",
    params=obj("hold takes no parameters.", {}),
    events=raises_nothing,
)
