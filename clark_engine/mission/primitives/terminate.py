"""terminate: end this agent's part in the mission.

The agent stops commanding, puts its vehicle in its terminal mode (the
profile's, or ``mode`` here), closes its interfaces and flushes its logs
(thesis 7.3.5). Nothing follows it.
"""

from __future__ import annotations

from clark_engine.mission.primitives._shared import check_mode
from clark_engine.mission.primitives.base import PrimitiveSpec, raises_nothing
from clark_engine.mission.schema_source.common import obj, string

SPEC = PrimitiveSpec(
    name="terminate",
    summary="Stop commanding, switch to the terminal mode, close interfaces and flush logs.",
    params=obj(
        "Parameters of terminate.",
        {"mode": string("Mode to leave the vehicle in; the agent's terminal_mode when omitted.")},
    ),
    events=raises_nothing,
    check=check_mode,
)
