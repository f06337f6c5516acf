"""Helpers shared by the schema sources: ids, and terse builders for typed properties.

Every property a user sets carries a description; numbers carry their unit
(in the description and in the ``x-unit`` annotation), their range and their
default where they have one, so the language reference and editor hovers can
show all three.

Every number in the language has a physical range, and every path a length limit.
The ranges are declared once per quantity (:func:`altitude_m`, :func:`position_m`,
:func:`time_s`, :func:`rate_hz`...), each wide enough for any small unmanned vehicle's
mission and narrow enough that no value the schema accepts can overflow the arithmetic
behind it: a float, a MAVLink field (int32 latitude and longitude in 1e-7 degrees,
int32 altitude in millimetres), a time in milliseconds. A field may narrow its
quantity's range (``maximum=...``), never widen it. A fuzzer found what happens
without them: ``10**400`` in a position raised ``OverflowError`` in validation, and an
altitude of 4294967295 m validated and then broke the dry run's GLOBAL_POSITION_INT.
"""

from __future__ import annotations

from typing import Any

DIALECT = "https://json-schema.org/draft/2020-12/schema"
NAME_PATTERN = r"^[a-z][a-z0-9_]*$"

Schema = dict[str, Any]


def schema_id(name: str) -> str:
    """The ``$id`` of a shipped schema. A URN: it names the schema, it is not fetched."""
    return f"urn:clark-engine:schema:{name}"


def number(
    description: str,
    *,
    unit: str | None = None,
    minimum: float | None = None,
    maximum: float | None = None,
    exclusive_minimum: float | None = None,
    exclusive_maximum: float | None = None,
    default: float | None = None,
    integer: bool = False,
) -> Schema:
    """A number (or integer) property with its unit, range and default."""
    out: Schema = {"type": "integer" if integer else "number", "description": description}
    if unit is not None:
        out["x-unit"] = unit
    if minimum is not None:
        out["minimum"] = minimum
    if maximum is not None:
        out["maximum"] = maximum
    if exclusive_minimum is not None:
        out["exclusiveMinimum"] = exclusive_minimum
    if exclusive_maximum is not None:
        out["exclusiveMaximum"] = exclusive_maximum
    if default is not None:
        out["default"] = default
    return out


def integer(description: str, **kw: Any) -> Schema:
    """An integer property; same keywords as :func:`number`."""
    return number(description, integer=True, **kw)


# --- Physical quantities -------------------------------------------------------------------
#
# Each limit is a module constant so that checks and messages elsewhere can quote it.

#: Heights above the mission origin (m). 10 km is above any small vehicle's ceiling (and
#: the legal ceilings the envelope allows); 1 km below covers a valley or a quarry under
#: the field. With the origin at most 9 km above sea level, any altitude fits MAVLink's
#: int32 millimetres (2,147 km) a hundred times over.
ALTITUDE_RANGE_M = (-1_000, 10_000)
#: The origin's ground above mean sea level (m): the Dead Sea shore (-430 m) to above any
#: airfield or mountain a small vehicle is flown from.
ORIGIN_AMSL_RANGE_M = (-500, 9_000)
#: North and east of the origin (m), each way. The flat local frame is exact enough within
#: tens of kilometres, and 100 km is beyond any radio the engine drives (an XBee 900HP's
#: 45 km line of sight); latitude and longitude stay far inside int32 1e-7 degrees.
POSITION_LIMIT_M = 100_000
#: A distance between two points of the mission (m): the diagonal of the +-100 km square.
DISTANCE_MAX_M = 300_000
#: A time from the start of a run, or a duration (s): 10^6 s, 11.6 days, is more than any
#: run or battery; in milliseconds it still fits an int32 (24.8 days).
TIME_MAX_S = 1_000_000
#: A rate or frequency (Hz): a mission loop, a telemetry rate, a sweep. 1 kHz is ten times
#: the fastest loop an autopilot link carries.
RATE_MAX_HZ = 1_000
#: A speed (m/s): 200 m/s (720 km/h) is twice the fastest small unmanned aircraft.
SPEED_MAX_M_S = 200
#: A count of things (pictures, bytes, megabytes...): a million is past any mission's.
COUNT_MAX = 1_000_000


def _ranged(
    description: str,
    unit: str | None,
    low: float,
    high: float,
    kw: dict[str, Any],
    *,
    integer: bool = False,
) -> Schema:
    """A number of one quantity: its range unless the field gives a narrower one.

    Raises:
        ValueError: The field's range is wider than its quantity's (a schema bug).
    """
    if "minimum" not in kw and "exclusive_minimum" not in kw:
        kw["minimum"] = low
    if "maximum" not in kw and "exclusive_maximum" not in kw:
        kw["maximum"] = high
    for key in ("minimum", "exclusive_minimum"):
        if kw.get(key) is not None and kw[key] < low:
            raise ValueError(f"{description!r}: {key} {kw[key]} is below {low}")
    for key in ("maximum", "exclusive_maximum"):
        if kw.get(key) is not None and kw[key] > high:
            raise ValueError(f"{description!r}: {key} {kw[key]} is above {high}")
    return number(description, unit=unit, integer=integer, **kw)


def altitude_m(description: str, **kw: Any) -> Schema:
    """A height above the mission origin, in metres (:data:`ALTITUDE_RANGE_M`)."""
    return _ranged(description, "m", *ALTITUDE_RANGE_M, kw)


def origin_amsl_m(description: str, **kw: Any) -> Schema:
    """The origin's height above mean sea level, in metres (:data:`ORIGIN_AMSL_RANGE_M`)."""
    return _ranged(description, "m", *ORIGIN_AMSL_RANGE_M, kw)


def position_m(description: str, **kw: Any) -> Schema:
    """Metres north or east of the origin (or of a target): +-:data:`POSITION_LIMIT_M`."""
    return _ranged(description, "m", -POSITION_LIMIT_M, POSITION_LIMIT_M, kw)


def distance_m(description: str, **kw: Any) -> Schema:
    """A distance, radius or tolerance, in metres: 0 to :data:`DISTANCE_MAX_M`."""
    return _ranged(description, "m", 0, DISTANCE_MAX_M, kw)


def length_m(description: str, **kw: Any) -> Schema:
    """A vehicle's size (wingspan, length, wheelbase), in metres: 0 to 50 m.

    50 m is past the wingspan of the largest unmanned aircraft flying.
    """
    return _ranged(description, "m", 0, 50, kw)


def time_s(description: str, **kw: Any) -> Schema:
    """A time from the start of a run, or a duration, in seconds: 0 to :data:`TIME_MAX_S`."""
    return _ranged(description, "s", 0, TIME_MAX_S, kw)


def rate_hz(description: str, **kw: Any) -> Schema:
    """A rate or frequency, in hertz: 0 to :data:`RATE_MAX_HZ`."""
    return _ranged(description, "Hz", 0, RATE_MAX_HZ, kw)


def speed_m_s(description: str, **kw: Any) -> Schema:
    """A speed or a climb rate, in metres per second: 0 to :data:`SPEED_MAX_M_S`."""
    return _ranged(description, "m/s", 0, SPEED_MAX_M_S, kw)


def mass_kg(description: str, **kw: Any) -> Schema:
    """A mass, in kilograms: 0 to 150 kg, the upper end of light unmanned aircraft."""
    return _ranged(description, "kg", 0, 150, kw)


def count(description: str, *, unit: str | None = None, **kw: Any) -> Schema:
    """A whole number of things: 0 to :data:`COUNT_MAX` unless the field says otherwise."""
    return _ranged(description, unit, 0, COUNT_MAX, kw, integer=True)


def share(description: str, **kw: Any) -> Schema:
    """A share (a probability): 0 to 1."""
    return _ranged(description, None, 0, 1, kw)


#: Longest path a mission may write (characters); Linux's PATH_MAX is 4096 bytes, and a
#: mission's folders are near it. Checked, with :data:`MAX_NAME_BYTES`, before any
#: filesystem call (clark_engine.mission.paths).
MAX_PATH_CHARS = 1024
#: Longest file or folder name (bytes of UTF-8): every common filesystem's limit.
MAX_NAME_BYTES = 255


#: The limits of the language, for docs/reference.md (tools/gen_reference.py): quantity,
#: the keys that carry it, its range, and why the range is what it is.
LIMITS: tuple[tuple[str, str, str, str], ...] = (
    (
        "Altitude above the origin",
        "`up_m`, `alt_m`, `altitude_m` checks and conditions, takeoff `alt_m`",
        f"{ALTITUDE_RANGE_M[0]:,} to {ALTITUDE_RANGE_M[1]:,} m",
        "Above any small vehicle's ceiling (the envelope's legal ceiling is lower still); "
        "1 km below covers a valley under the field. Any altitude fits MAVLink's int32 "
        "millimetres a hundred times over.",
    ),
    (
        "Origin above sea level",
        "`origin.alt_amsl_m`",
        f"{ORIGIN_AMSL_RANGE_M[0]:,} to {ORIGIN_AMSL_RANGE_M[1]:,} m",
        "The Dead Sea shore (-430 m) to above any field a small vehicle flies from.",
    ),
    (
        "Position north or east",
        "`north_m`, `east_m`, points' first two numbers, follow offsets",
        f"±{POSITION_LIMIT_M:,} m",
        "The flat local frame is exact enough within tens of kilometres, and 100 km is "
        "beyond any radio the engine drives.",
    ),
    (
        "Distance",
        "tolerances, separations, radii, check distances, condition `distance_m`",
        f"0 to {DISTANCE_MAX_M:,} m (many keys less)",
        "The diagonal of the ±100 km square.",
    ),
    (
        "Time and duration",
        "`at_s`, `by_s`, `from_s`, `to_s`, `timeout_s`, `duration_s`, `in_state_s`",
        f"0 to {TIME_MAX_S:,} s (many keys less)",
        "11.6 days, longer than any run or battery; in milliseconds it still fits an int32.",
    ),
    (
        "Rate and frequency",
        "`loop_hz`, telemetry rates, `retarget_hz`, sweep frequencies",
        f"0 to {RATE_MAX_HZ:,} Hz (many keys less)",
        "Ten times the fastest loop an autopilot link carries.",
    ),
    (
        "Speed",
        "`speed_m_s`, airframe speeds and climb rates, condition `speed_m_s`",
        f"0 to {SPEED_MAX_M_S} m/s (commanded speeds 100)",
        "Twice the fastest small unmanned aircraft.",
    ),
    (
        "Count",
        "`photos` check, photo_trigger `count`",
        f"0 to {COUNT_MAX:,}",
        "Past any mission's.",
    ),
    (
        "Whole number as written",
        "any",
        "at most 1,000 digits",
        "Refused where it is written ([[E-YAML-VALUE]]): no setting takes more than ten.",
    ),
    (
        "Path",
        "`include` folders, `key_file`",
        f"{MAX_PATH_CHARS:,} characters; {MAX_NAME_BYTES} bytes per file or folder name",
        "What every common filesystem allows; checked before anything is opened.",
    ),
)


def path_string(description: str, **kw: Any) -> Schema:
    """A file or folder a mission names: non-empty, at most :data:`MAX_PATH_CHARS` long."""
    out = string(description, min_length=1, **kw)
    out["maxLength"] = MAX_PATH_CHARS
    return out


def string(
    description: str,
    *,
    pattern: str | None = None,
    enum: list[str] | None = None,
    default: str | None = None,
    min_length: int | None = None,
) -> Schema:
    """A string property, optionally constrained by a pattern or a list of values."""
    out: Schema = {"type": "string", "description": description}
    if pattern is not None:
        out["pattern"] = pattern
    if enum is not None:
        out["enum"] = enum
    if default is not None:
        out["default"] = default
    if min_length is not None:
        out["minLength"] = min_length
    return out


def boolean(description: str, *, default: bool | None = None) -> Schema:
    """A true/false property."""
    out: Schema = {"type": "boolean", "description": description}
    if default is not None:
        out["default"] = default
    return out


def obj(
    description: str,
    properties: dict[str, Schema],
    *,
    required: list[str] | None = None,
    additional: bool | Schema = False,
) -> Schema:
    """A mapping with known keys; unknown keys are rejected unless ``additional`` says so."""
    out: Schema = {
        "type": "object",
        "description": description,
        "properties": properties,
        "additionalProperties": additional,
    }
    if required:
        out["required"] = required
    return out


def array(
    description: str,
    items: Schema,
    *,
    min_items: int | None = None,
    max_items: int | None = None,
    unique: bool = False,
) -> Schema:
    """A list whose items all follow ``items`` (each only once with ``unique``)."""
    out: Schema = {"type": "array", "description": description, "items": items}
    if min_items is not None:
        out["minItems"] = min_items
    if max_items is not None:
        out["maxItems"] = max_items
    if unique:
        out["uniqueItems"] = True
    return out


def resolved_point() -> Schema:
    """A position as a compiled config writes it: in both frames, every field present.

    The one definition of a compiled point: the agent-config schema uses it for homes,
    fence corners and agents' positions, and the behaviours for the points the compiler
    resolves in their parameters (:func:`clark_engine.behaviors.declaration.param`'s
    ``compiled``).
    """
    return obj(
        "A position in both frames.",
        {
            "north_m": number("Metres north of the origin.", unit="m"),
            "east_m": number("Metres east of the origin.", unit="m"),
            "up_m": number("Metres above the origin.", unit="m"),
            "lat": number("Latitude.", unit="deg", minimum=-90, maximum=90),
            "lon": number("Longitude.", unit="deg", minimum=-180, maximum=180),
            "alt_m": number("Metres above the origin's altitude.", unit="m"),
        },
        required=["north_m", "east_m", "up_m", "lat", "lon", "alt_m"],
    )
