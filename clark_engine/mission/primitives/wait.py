"""wait: do nothing, for a while or until an event.

With ``duration_s`` it finishes after that time; without, it waits for a
transition's event (e.g. the station's ``activate``). It commands nothing, so a
pilot keeps flying the vehicle meanwhile. The station may use it too.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

from clark_engine.mission.primitives.base import PrimitiveSpec
from clark_engine.mission.schema_source.common import number, obj


def _events(params: Mapping[str, Any]) -> frozenset[str]:
    return frozenset({"done"}) if params.get("duration_s") is not None else frozenset()


SPEC = PrimitiveSpec(
    name="wait",
    summary="Command nothing; done after duration_s, or wait for an event when omitted.",
    params=obj(
        "Parameters of wait.",
        {
            "duration_s": number(
                "How long to wait; until an event when omitted.",
                unit="s",
                exclusive_minimum=0,
                maximum=86400,
            )
        },
    ),
    events=_events,
    needs_autopilot=False,
)
