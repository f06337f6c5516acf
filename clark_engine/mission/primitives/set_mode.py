"""set_mode: put the autopilot in a flight mode; done once the autopilot reports it.

The mode is checked against the modes of the agent's autopilot firmware
(thesis 5.2: the Slash switched from MANUAL to AUTO and back).
"""

from __future__ import annotations

from clark_engine.mission.primitives._shared import check_mode
from clark_engine.mission.primitives.base import PrimitiveSpec, raises_done
from clark_engine.mission.schema_source.common import obj, string

SPEC = PrimitiveSpec(
    name="set_mode",
    summary="Set the autopilot's flight mode; done when the autopilot reports it.",
    params=obj(
        "Parameters of set_mode.",
        {"mode": string("Flight mode name of the agent's autopilot firmware (e.g. AUTO).")},
        required=["mode"],
    ),
    events=raises_done,
    check=check_mode,
)
