"""land: land where the vehicle is, in the autopilot's land mode.

The autopilot descends on the spot, detects the touchdown and disarms
(ArduCopter's LAND); ``done`` is raised once the vehicle is on the ground. The
mode comes from the autopilot profile's ``land_mode``. Multirotors only: a
rover never flies, and ArduPlane lands only through a landing sequence in an
AUTO mission, which the engine does not fly, so a fixed-wing aircraft returns
with ``return_home`` and its pilot lands it.
"""

from __future__ import annotations

from collections.abc import Iterator

from clark_engine.mission.findings import Finding
from clark_engine.mission.primitives._shared import check_airframe, check_mode_role
from clark_engine.mission.primitives.base import PrimitiveSpec, UseContext, raises_done
from clark_engine.mission.schema_source.common import obj


def _check(ctx: UseContext) -> Iterator[Finding]:
    refused = list(
        check_airframe(
            ctx,
            "land",
            {
                "rover": "a rover never leaves the ground; stop it with hold",
                "fixed_wing": "ArduPlane lands through a landing sequence in an AUTO mission, "
                "which the engine does not fly; use return_home and let the pilot land",
            },
        )
    )
    yield from refused
    if not refused:
        yield from check_mode_role(ctx, "land", "land_mode", "LAND", "lands on the spot")


SPEC = PrimitiveSpec(
    name="land",
    summary=(
        "Land where the vehicle is in the autopilot's land mode; done once it is on the ground."
    ),
    params=obj("land takes no parameters.", {}),
    events=raises_done,
    check=_check,
)
