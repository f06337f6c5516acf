"""Schema of the safety envelope: as a mission writes it, and as a compiled config holds it.

The envelope is where every vehicle may be: between a floor and a ceiling above the
mission origin, inside a geofence, apart from the other vehicles, for no longer than
its endurance. A mission declares it once (``envelope:``) and may narrow it per
vehicle (``agents.<name>.envelope``); every key has a safe default, so a mission that
says nothing still flies inside one (docs/safety.md).
"""

from __future__ import annotations

from clark_engine.behaviors.shared import AGENT_NAME_SCHEMA, POINT_SCHEMA
from clark_engine.mission.envelope import (
    BREACH_ACTIONS,
    DEFAULT_LEGAL_CEILING_M,
    DEFAULT_MARGIN_M,
    DEFAULT_MIN_SEPARATION_M,
    DEFAULT_POSITION_ERROR_M,
    MAX_LEGAL_CEILING_M,
    MAX_POSITION_ERROR_M,
    OUTSIDE_ACTIONS,
)
from clark_engine.mission.schema_source.common import (
    Schema,
    array,
    distance_m,
    number,
    obj,
    string,
    time_s,
)


def _zone() -> Schema:
    polygon = array(
        "Corners of a polygon, in order (the last joins the first): points [north_m, "
        "east_m] or {lat, lon}; heights are ignored.",
        POINT_SCHEMA,
        min_items=3,
    ) | {"maxItems": 100}
    circle = obj(
        "A circle on the ground.",
        {
            "center": POINT_SCHEMA | {"description": "Its centre; a height is ignored."},
            "radius_m": distance_m("Its radius.", exclusive_minimum=0, maximum=100_000),
        },
        required=["center", "radius_m"],
    )
    return obj(
        "One zone of a geofence: a polygon or a circle (exactly one).",
        {"polygon": polygon, "circle": circle},
    ) | {"minProperties": 1, "maxProperties": 1}


def geofence_schema() -> Schema:
    """``geofence:``: inclusion and exclusion zones."""
    return obj(
        "Where on the ground vehicles may be. Without inclusion zones, each vehicle's "
        "default is a circle around its home as wide as its radio's range_m (1000 m for a "
        "radio without one). A vehicle stays inside every inclusion zone and outside every "
        "exclusion zone (ArduPilot's rule).",
        {
            "include": array("Inclusion zones.", {"$ref": "#/$defs/zone"}) | {"maxItems": 20},
            "exclude": array("Exclusion zones.", {"$ref": "#/$defs/zone"}) | {"maxItems": 20},
        },
    )


def _action(what: str, default_words: str) -> Schema:
    return string(
        f"What a vehicle does on {what}: hold where it is, return to launch (rtl) or land; "
        f"{default_words}. Applied once, as a failsafe: the behaviour stops, and a pilot "
        "or the station may take the vehicle from there.",
        enum=list(BREACH_ACTIONS),
    )


def _shared_keys() -> dict[str, Schema]:
    """Keys a mission's envelope and a vehicle's both take."""
    return {
        "ceiling_m": number(
            "Highest altitude above the origin a vehicle may fly at. The mission's defaults "
            "to legal_ceiling_m; each aircraft's is also capped by its airframe's "
            "max_altitude_m; a vehicle's may only lower the mission's.",
            unit="m",
            exclusive_minimum=0,
            maximum=MAX_LEGAL_CEILING_M,
        ),
        "floor_m": number(
            "Lowest altitude above the origin an aircraft in guided flight is sent to or may "
            "sink to (taking off, landing and returning home are exempt).",
            unit="m",
            minimum=0,
            maximum=MAX_LEGAL_CEILING_M,
        ),
        "geofence": geofence_schema(),
        "on_breach": _action(
            "leaving the geofence, crossing the ceiling or the floor, or outliving its endurance",
            "rtl for aircraft and hold for rovers when omitted",
        ),
        "on_near_miss": _action(
            "another vehicle coming inside the minimum separation", "hold when omitted"
        ),
        "position_error_m": number(
            "How far a vehicle's reported horizontal position may be from where it truly "
            "is (its GPS's error, 95 % of the time: 1-4 m for a standalone GPS, a few "
            "centimetres with RTK). The runtime keeps every pair the sum of their two "
            "figures further apart than their separation, on the positions they report, so "
            "that the separation holds on the truth. The mission's applies to every vehicle "
            "that declares none of its own; 0 when omitted (the reports taken as the truth).",
            unit="m",
            minimum=0,
            maximum=MAX_POSITION_ERROR_M,
        ),
        "outside": string(
            "What the runtime does with a target outside the envelope: clamp it to the "
            "nearest point inside (margin_m in), or refuse it (the vehicle keeps its last "
            "target). Either way it is logged and counted, and never sent as asked.",
            enum=list(OUTSIDE_ACTIONS),
        ),
    }


def mission_envelope_schema() -> Schema:
    """The mission's ``envelope:`` section."""
    keys = _shared_keys()
    keys["ceiling_m"]["default"] = DEFAULT_LEGAL_CEILING_M
    keys["floor_m"]["default"] = 0
    keys["outside"]["default"] = OUTSIDE_ACTIONS[0]
    keys["on_near_miss"]["default"] = "hold"
    keys["position_error_m"]["default"] = DEFAULT_POSITION_ERROR_M
    return obj(
        "Where every vehicle may fly, held before flight (clark validate), in flight (the "
        "runtime), by the autopilot's own fence and failsafe, and judged in every dry run. "
        "Every key has a safe default.",
        {
            "legal_ceiling_m": number(
                "The altitude limit above the origin that the law sets where the mission "
                "flies. Raising it above 120 m is the explicit override a waiver allows.",
                unit="m",
                exclusive_minimum=0,
                maximum=MAX_LEGAL_CEILING_M,
                default=DEFAULT_LEGAL_CEILING_M,
            ),
            **keys,
            "margin_m": number(
                "How far inside the envelope the runtime keeps the targets it sends, so "
                "that a vehicle's overshoot is not a breach.",
                unit="m",
                minimum=0,
                maximum=100,
                default=DEFAULT_MARGIN_M,
            ),
            "min_separation_m": number(
                "Smallest 3-D distance between any two vehicles.",
                unit="m",
                minimum=0,
                maximum=1000,
                default=DEFAULT_MIN_SEPARATION_M,
            ),
            "separation": array(
                "Minimum separations for given pairs of vehicles, in place of min_separation_m.",
                obj(
                    "One pair's minimum separation.",
                    {
                        "between": array("Two vehicles.", AGENT_NAME_SCHEMA, min_items=2)
                        | {"maxItems": 2},
                        "min_m": number(
                            "Their smallest 3-D distance.", unit="m", minimum=0, maximum=1000
                        ),
                    },
                    required=["between", "min_m"],
                ),
            ),
        },
    )


def agent_envelope_schema() -> Schema:
    """A vehicle's ``envelope:``: narrows the mission's."""
    return obj(
        "This vehicle's envelope: narrows the mission's (a lower ceiling, a higher floor, "
        "zones of its own added to the mission's), and sets its own actions and endurance.",
        {
            **_shared_keys(),
            "endurance_s": time_s(
                "How long the vehicle may be armed (its battery, with a reserve): past it "
                "the on_breach action brings it back. The airframe's endurance_s when "
                "omitted.",
                exclusive_minimum=0,
                maximum=86400,
            ),
        },
    )


def zone_def() -> Schema:
    """The ``$defs/zone`` entry the geofence schemas refer to."""
    return _zone()
