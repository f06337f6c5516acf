"""Generate docs/reference.md, the mission language reference, from its sources.

The reference is built from what the engine itself reads, so it cannot drift:

* ``schemas/mission.schema.json`` for the file structure, the mission section,
  agents, telemetry, failsafes, dry-run checks, states, transitions and conditions;
* ``clark_engine.behaviors`` (the built-in behaviours' declarations) for each
  primitive's summary, parameters and events, and each module's docstring for its prose;
* ``behaviors/*.yaml`` for the shipped behaviour blocks;
* ``clark_engine.mission.state_checks`` for the event names the engine accepts.

Usage, from the repository root::

    python tools/gen_reference.py           # write docs/reference.md
    python tools/gen_reference.py --check   # exit 1 if docs/reference.md is out of date
    python tools/gen_reference.py --stdout  # print instead of writing

The output is deterministic: the same sources always give the same bytes.
"""

from __future__ import annotations

import ast
import importlib
import inspect
import json
import re
import sys
from collections.abc import Callable, Iterable, Iterator, Mapping, Sequence
from pathlib import Path
from types import ModuleType
from typing import Any

import docgen  # tools/docgen.py, beside this script

from clark_engine.mission.variation import MAX_CHOICES, NORMAL_TAIL_SD

ROOT = Path(__file__).resolve().parents[1]
OUTPUT = ROOT / "docs" / "reference.md"

Schema = Mapping[str, Any]

# Codes look like E-RATE or W-SWEEP-SAMPLES; docs/check-codes.md has one heading per code.
_CODE_RE = re.compile(r'"([EW]-[A-Z0-9-]+)"')
_RST_LITERAL = re.compile(r"``([^`]+)``")
_CODE_SPAN = re.compile(r"(`[^`]*`)")
# Prose writes [[E-RATE]]; the last step turns it into a link to docs/check-codes.md.
_CODE_LINK = re.compile(r"\[\[([EW]-[A-Z0-9-]+)\]\]")

#: Meaning of each event, keyed by the form a mission writes. The generator fails if the
#: engine accepts an event that is not listed here, or this lists one the engine does not know.
EVENTS: tuple[tuple[str, str], ...] = (
    (
        "done",
        "The state finished: its primitive completed (see each primitive's events below), "
        "a machine reached one of its `final: true` children, or parallel regions finished "
        "as `finish:` says.",
    ),
    (
        "timeout",
        "`timeout_s` seconds passed since the state was entered. A state with `timeout_s` "
        "must have a `timeout` transition, and a `timeout` transition needs `timeout_s`.",
    ),
    (
        "activate",
        "The operator at the mission control station activated this agent's controller "
        "(Activate Controller). Needs a station (an agent with role `mcs`) in the mission.",
    ),
    (
        "deactivate",
        "The operator deactivated this agent's controller. Needs a station in the mission.",
    ),
    ("terminate", "The mission is being terminated for this agent (a Terminate request)."),
    (
        "mode:<MODE>",
        "The autopilot reports flight mode `<MODE>` (e.g. `mode:MANUAL`). The name must be one "
        "of the modes of the agent's autopilot profile.",
    ),
    (
        "rc:<channel>:high",
        "The RC input `<channel>` switched high: a named channel of the agent's profile "
        "that has an `rc` number (e.g. `rc:excite_switch:high`), or an RC channel number "
        "(`rc:7:high`). Vehicles only.",
    ),
    ("rc:<channel>:low", "The RC input `<channel>` switched low. Vehicles only."),
    (
        "lost:<agent>",
        "No heartbeat from `<agent>` for `mission.heartbeat_timeout_s`. Names another agent "
        "of the mission, not the agent itself.",
    ),
    ("found:<agent>", "A heartbeat arrived from `<agent>` (first contact, or after it was lost)."),
    (
        "mcs_lost",
        "Every mission control station has been silent for `mission.heartbeat_timeout_s`. "
        "Needs a station in the mission.",
    ),
    ("autopilot_lost", "This vehicle's own autopilot went silent. Vehicles only."),
    (
        "always",
        "Checked every tick: an `always` transition is taken on the first tick its `when:` "
        "holds (it must have one), so a state can wait for another agent's state or "
        "position without a polling state. See [docs/runtime.md](runtime.md#conditions-on-"
        "other-agents).",
    ),
)


# ----------------------------------------------------------------------------- imports


def _import_engine() -> None:
    """Make ``clark_engine`` importable when the script runs from a checkout."""
    try:
        importlib.import_module("clark_engine")
    except ModuleNotFoundError:
        sys.path.insert(0, str(ROOT))
        importlib.import_module("clark_engine")


# ----------------------------------------------------------------------------- text helpers


def md(text: str, *, cell: bool = False) -> str:
    """Escape prose for Markdown: ``<`` and ``>`` outside code spans, ``|`` inside tables.

    Args:
        text: Plain text, possibly with `code spans` or RST ``literals``.
        cell: The text goes into a table cell (newlines become spaces, ``|`` is escaped).
    """
    text = _RST_LITERAL.sub(r"`\1`", text)
    parts = []
    for piece in _CODE_SPAN.split(text):
        if not (piece.startswith("`") and piece.endswith("`") and len(piece) > 1):
            piece = piece.replace("<", "&lt;").replace(">", "&gt;")
        parts.append(piece)
    out = "".join(parts)
    if cell:
        out = " ".join(out.split()).replace("|", "\\|")
    return out


def code(value: Any) -> str:
    """A JSON value as an inline code span (``true``, ``150``, ``"camera"`` as ``camera``)."""
    text = value if isinstance(value, str) else json.dumps(value, ensure_ascii=False)
    return f"`{text}`"


def number_text(value: Any) -> str:
    """A bound as written in the schema (500, 0.5)."""
    return json.dumps(value)


def table(header: Sequence[str], rows: Iterable[Sequence[str]]) -> list[str]:
    """A GitHub-flavoured Markdown table; an empty list when there are no rows."""
    body = [list(r) for r in rows]
    if not body:
        return []
    lines = ["| " + " | ".join(header) + " |", "|" + "|".join("---" for _ in header) + "|"]
    lines.extend("| " + " | ".join(r) + " |" for r in body)
    return lines


def slug(heading: str) -> str:
    """The anchor GitHub gives a heading."""
    text = heading.strip().lower()
    text = re.sub(r"[^\w\- ]", "", text)
    return text.replace(" ", "-")


# ----------------------------------------------------------------------------- schema helpers


def is_point(schema: Schema) -> bool:
    """True for the point schema (a list or one of two mappings)."""
    branches = schema.get("anyOf", [])
    return any(b.get("type") == "array" and "prefixItems" in b for b in branches)


def type_text(schema: Schema) -> str:
    """A short, readable type for a property schema."""
    if "$ref" in schema:
        name = str(schema["$ref"]).rsplit("/", 1)[-1]
        return {
            "state": "state ([States](#states))",
            "condition": "condition ([Conditions](#conditions))",
            "transition": "transition ([Transitions](#transitions))",
            "check": "check ([Dry-run checks](#dry-run-checks))",
            "agent": "agent ([Agents](#agents))",
        }.get(name, name)
    if is_point(schema):
        return "point ([Points](#points))"
    if schema.get("x-varied"):
        return type_text(schema["anyOf"][0]) + " or distribution ([Varied values](#varied-values))"
    if "const" in schema:
        return code(schema["const"])
    if "enum" in schema:
        return "one of " + ", ".join(code(v) for v in schema["enum"])
    if "x-expected" in schema:
        expected = str(schema["x-expected"])
        return re.sub(r"^(a|an) ", "", expected)
    kind = schema.get("type")
    if isinstance(kind, list):
        return " or ".join(type_text({**schema, "type": k}) for k in kind)
    if kind == "array":
        items = schema.get("items")
        if isinstance(items, Mapping) and items:
            return "list of " + _plural(type_text(items))
        return "list"
    if kind == "object":
        extra = schema.get("additionalProperties")
        if isinstance(extra, Mapping) and extra and not schema.get("properties"):
            pattern = str(schema.get("propertyNames", {}).get("pattern", ""))
            key = "event" if ":" in pattern else "name"
            return f"mapping of {key} to " + type_text(extra)
        return "mapping"
    if kind == "string" and schema.get("pattern") == r"^[a-z][a-z0-9_]*$":
        return "name"
    words = {"number": "number", "integer": "integer", "string": "text", "boolean": "boolean"}
    if isinstance(kind, str):
        return words.get(kind, kind)
    if "anyOf" in schema:
        return " or ".join(type_text(b) for b in schema["anyOf"])
    return "any"


def _plural(text: str) -> str:
    """The plural of a type word (``text`` -> ``texts``), for "list of ..."."""
    first, _, rest = text.partition(" ")
    irregular = {"text": "texts", "mapping": "mappings", "name": "names", "point": "points"}
    if first in irregular:
        return " ".join(filter(None, [irregular[first], rest]))
    return text


def range_text(schema: Schema) -> str:
    """The allowed range of a number (``> 0, ≤ 500``), or the count of a list."""
    parts = []
    if "exclusiveMinimum" in schema:
        parts.append("> " + number_text(schema["exclusiveMinimum"]))
    if "minimum" in schema:
        parts.append("≥ " + number_text(schema["minimum"]))
    if "exclusiveMaximum" in schema:
        parts.append("< " + number_text(schema["exclusiveMaximum"]))
    if "maximum" in schema:
        parts.append("≤ " + number_text(schema["maximum"]))
    low_items, high_items = schema.get("minItems"), schema.get("maxItems")
    if low_items is not None and low_items == high_items:
        parts.append(f"exactly {low_items} items")
    else:
        if low_items is not None:
            parts.append(f"{low_items}+ items")
        if high_items is not None:
            parts.append(f"at most {high_items} items")
    if not parts and "anyOf" in schema and not is_point(schema):
        for branch in schema["anyOf"]:
            found = range_text(branch)
            if found:
                return found
    return ", ".join(parts)


def unit_text(schema: Schema) -> str:
    """The unit annotation (``x-unit``)."""
    unit = schema.get("x-unit")
    return str(unit) if unit else ""


def default_text(schema: Schema) -> str:
    """The declared default as a code span, or nothing."""
    return code(schema["default"]) if "default" in schema else ""


def property_rows(
    schema: Schema,
    *,
    prefix: str = "",
    descend: Callable[[str, Schema], bool] | None = None,
) -> Iterator[list[str]]:
    """Rows of key, required, type, unit, range, default and description for a mapping.

    Args:
        schema: An object schema with ``properties``.
        prefix: Dotted path to put before each key (for nested mappings).
        descend: Called with (dotted key, schema) to decide whether a nested mapping's
            own keys get rows too; by default nested mappings with properties do.
    """
    required = set(schema.get("required", []))
    for key, prop in schema.get("properties", {}).items():
        if not isinstance(prop, Mapping):
            continue
        dotted = f"{prefix}{key}"
        yield [
            f"`{dotted}`",
            "yes" if key in required else "",
            md(type_text(prop), cell=True),
            unit_for(key, prop),
            range_text(prop),
            default_text(prop),
            md(describe(prop), cell=True),
        ]
        nested = prop.get("properties")
        wanted = descend(dotted, prop) if descend is not None else True
        if nested and wanted and prop.get("type") == "object":
            yield from property_rows(prop, prefix=dotted + ".", descend=descend)


#: What a ``$ref`` property means when the schema gives it no description of its own.
REF_DESCRIPTIONS = {
    "state": "The agent's behaviour: a state, usually a machine of states; see States.",
    "condition": "Condition that must hold for the transition to be taken; see Conditions.",
}

#: Units implied by a key's suffix, for schemas (block parameters) that omit ``x-unit``.
SUFFIX_UNITS = (
    ("_m_s", "m/s"),
    ("_us", "us"),
    ("_hz", "Hz"),
    ("_deg", "deg"),
    ("_s", "s"),
    ("_m", "m"),
)


def describe(prop: Schema) -> str:
    """A property's description, or what its ``$ref`` target means."""
    if prop.get("description"):
        return str(prop["description"])
    ref = str(prop.get("$ref", "")).rsplit("/", 1)[-1]
    return REF_DESCRIPTIONS.get(ref, "")


def unit_for(key: str, prop: Schema) -> str:
    """The unit of a property: ``x-unit``, else the one its name ends with (numbers only)."""
    if prop.get("x-unit"):
        return str(prop["x-unit"])
    if prop.get("type") in ("number", "integer"):
        for suffix, unit in SUFFIX_UNITS:
            if key.endswith(suffix):
                return unit
    return ""


PROPERTY_HEADER = ("Key", "Required", "Type", "Unit", "Range", "Default", "Description")


def property_table(schema: Schema, **kw: Any) -> list[str]:
    """The property rows of ``schema`` as a Markdown table."""
    return table(PROPERTY_HEADER, property_rows(schema, **kw))


# ----------------------------------------------------------------------------- sections


def intro(sources: Sequence[str]) -> list[str]:
    """Title, provenance and contents."""
    return [
        "# Mission language reference",
        "",
        "<!-- Generated by tools/gen_reference.py; do not edit by hand. -->",
        "",
        "This page is generated from the engine's own sources, so it always matches what "
        "`clark validate` accepts: " + ", ".join(sources) + ". To regenerate it run "
        "`python tools/gen_reference.py` (or `make schemas`); "
        "`python tools/gen_reference.py --check` fails when it is out of date.",
        "",
        "New to the language? Start with the [tutorial](tutorial.md). Every finding code "
        "mentioned here is explained in [check-codes.md](check-codes.md); hardware profiles "
        "have their own guide, [hardware-profiles.md](hardware-profiles.md).",
        "",
        "Conventions used throughout:",
        "",
        "- **Units are in the names**: `_m` metres, `_s` seconds, `_hz` hertz, `_us` "
        "microseconds (PWM pulse widths), `_deg` degrees, `_m_s` metres per second. The "
        "*Unit* column repeats the unit.",
        "- **Names** of agents, states, blocks, profiles, payloads and channels are lower-case "
        "letters, digits and `_`, starting with a letter (`slash_a`, `settle_1`).",
        "- **Plain YAML**: write `true`/`false`, never bare `on`, `off`, `yes` or `no` (YAML "
        "1.1 tools read those as booleans); times are plain numbers of seconds (`90`, never "
        "`1:30`); no key may appear twice in a mapping; no tags beyond YAML's standard ones "
        "(`!include` and `!!binary` are refused).",
        "- **Ranges** read `> 0` (strictly above), `≥ 0` (at least), `≤ 500` (at most). "
        "Every number has one, and every path a length limit ([Limits](#limits)).",
        "",
        "Contents:",
        "",
        "- [Limits](#limits)",
        "- [File structure](#file-structure)",
        "- [The mission section](#the-mission-section)",
        "- [Include](#include)",
        "- [Agents](#agents)",
        "- [Telemetry](#telemetry)",
        "- [Failsafe](#failsafe)",
        "- [Launch](#launch)",
        "- [Envelope](#envelope)",
        "- [Points](#points)",
        "- [Dry-run checks](#dry-run-checks)",
        "- [Dry-run operator, faults and settings](#dry-run-operator-faults-and-settings)",
        "- [Campaigns](#campaigns)",
        "- [States](#states)",
        "- [Transitions](#transitions)",
        "- [Events](#events)",
        "- [Conditions](#conditions)",
        "- [Primitives](#primitives)",
        "- [Behaviour blocks](#behaviour-blocks)",
        "",
    ]


def limits_section() -> list[str]:
    """Every number's physical range and every path's length limit, with the reasons."""
    from clark_engine.mission.schema_source.common import LIMITS

    return [
        "## Limits",
        "",
        "Every number in a mission, a behaviour block or a hardware profile has a range, "
        "and every path a length limit. The ranges are physical: wide enough for any small "
        "unmanned vehicle's mission, narrow enough that nothing `clark validate` accepts can "
        "overflow the arithmetic and the MAVLink fields behind it. A value outside its range "
        "is an [[E-RANGE]] finding with the file, the line and the allowed range; a path too "
        "long, [[E-INCLUDE-PATH]] or [[E-VALUE]]. Each key's own range is in its table below "
        "(many are narrower than their quantity's).",
        "",
        *table(
            ["Quantity", "Keys", "Range", "Why"],
            (
                [md(q, cell=True), md(k, cell=True), md(r, cell=True), md(w, cell=True)]
                for q, k, r, w in LIMITS
            ),
        ),
        "",
    ]


def file_structure(schema: Schema) -> list[str]:
    """The top-level keys of a mission file."""
    lines = [
        "## File structure",
        "",
        "A mission is one YAML document, a mapping with these keys. Unknown keys are errors "
        "(with a *did you mean* when one is close). Put the schema line first so that an "
        "editor with the YAML language server completes keys and shows these descriptions; "
        "`clark schema mission` prints the same schema.",
        "",
        "```yaml",
        "# yaml-language-server: $schema=../schemas/mission.schema.json",
        "clark: 1",
        "mission: {id: 1, name: my-mission, loop_hz: 10,",
        "          origin: {lat: 30.6372, lon: -96.4787, alt_amsl_m: 90}}",
        "agents:",
        "  mcs: {id: 1, profile: mcs_laptop, telemetry: {heartbeat: 1}}",
        "```",
        "",
    ]
    lines += table(
        ("Key", "Required", "Type", "Description"),
        (
            [
                f"`{key}`",
                "yes" if key in schema.get("required", []) else "",
                md(type_text(prop), cell=True),
                md(str(prop.get("description", "")), cell=True),
            ]
            for key, prop in schema["properties"].items()
        ),
    )
    return [*lines, ""]


def mission_section(schema: Schema) -> list[str]:
    """The ``mission:`` mapping."""
    section = schema["properties"]["mission"]
    return [
        "## The mission section",
        "",
        md(str(section["description"])) + " Every agent's compiled config carries these.",
        "",
        *property_table(section),
        "",
        "`loop_hz` must not exceed the measured `max_loop_hz` of any agent's mission computer "
        "([[E-LOOP-HZ]]); every telemetry rate must be at most "
        "`loop_hz` ([[E-RATE]]) and should divide it "
        "([[W-RATE-DIVIDER]]).",
        "",
    ]


def include_section(schema: Schema) -> list[str]:
    """The ``include:`` mapping."""
    section = schema["properties"]["include"]
    return [
        "## Include",
        "",
        md(str(section["description"])) + " A folder that does not exist is an error "
        "([[E-INCLUDE-MISSING]]); a profile or block whose "
        "name is already taken is an error too "
        "([[E-PROFILE-DUPLICATE]], "
        "[[E-BLOCK-DUPLICATE]]).",
        "",
        *property_table(section),
        "",
        "```yaml",
        "include:",
        "  hardware_profiles: [my_profiles]   # my_profiles/ next to the mission file",
        "  behaviors: [my_blocks]",
        "```",
        "",
    ]


def agents_section(schema: Schema) -> list[str]:
    """The ``agents:`` mapping and one agent's keys."""
    agents = schema["properties"]["agents"]
    agent = schema["$defs"]["agent"]
    hardware = agent["properties"]["hardware"]
    lines = [
        "## Agents",
        "",
        md(str(agents["description"]))
        + " Each key under `agents:` is the agent's name (used in transitions, telemetry "
        "destinations, `follow_agent` targets and file names of compiled configs); each value "
        "is a mapping with these keys. " + md(str(agent["description"])),
        "",
        *property_table(agent, descend=lambda key, _prop: key not in ("hardware", "telemetry")),
        "",
        "### Hardware overrides",
        "",
        md(str(hardware.get("description", "")))
        + " Overrides are deep-merged: mappings merge key by key, lists and single values "
        "replace. See [hardware-profiles.md](hardware-profiles.md) for every key of every part.",
        "",
    ]
    lines += table(
        ("Key", "Type", "Description"),
        (
            [
                f"`{key}`",
                md(type_text(prop), cell=True),
                md(str(prop.get("description", "")), cell=True),
            ]
            for key, prop in hardware.get("properties", {}).items()
        ),
    )
    return [*lines, ""]


def telemetry_section(schema: Schema) -> list[str]:
    """The periodic messages an agent may send."""
    telemetry = schema["$defs"]["agent"]["properties"]["telemetry"]
    lines = [
        "## Telemetry",
        "",
        md(str(telemetry["description"]))
        + " Each message takes a rate in Hz (sent to every agent) or `{rate_hz, to}` (sent "
        "only to the listed agents). The loop sends a message every `round(loop_hz / rate)` "
        "ticks, so a rate should divide `loop_hz`.",
        "",
        "```yaml",
        "telemetry:",
        "  heartbeat: 1                                  # 1 Hz to everyone",
        "  agent_status: {rate_hz: 2, to: [slash_b]}     # 2 Hz to slash_b only",
        "```",
        "",
    ]
    rows = []
    for name, prop in telemetry["properties"].items():
        rate = next((b for b in prop.get("anyOf", []) if b.get("type") == "number"), prop)
        rows.append(
            [
                f"`{name}`",
                unit_text(prop) or unit_text(rate),
                range_text(rate),
                md(str(prop.get("description", "")), cell=True),
            ]
        )
    lines += table(("Message", "Unit", "Range", "Description"), rows)
    long_form = next(
        (
            b
            for b in next(iter(telemetry["properties"].values())).get("anyOf", [])
            if b.get("type") == "object"
        ),
        None,
    )
    if long_form is not None:
        lines += ["", "The long form `{rate_hz, to}`:", "", *property_table(long_form)]
    lines += [
        "",
        "Every agent should send `heartbeat` ([[W-NO-HEARTBEAT]]), "
        "at least once per `heartbeat_timeout_s` ([[E-HEARTBEAT-RATE]]). "
        "An agent followed by `follow_agent`, or measured by a `distance_m` condition, must send "
        "`agent_status` to the follower ([[E-FOLLOW-STATUS]]).",
        "",
    ]
    return lines


def failsafe_section(schema: Schema) -> list[str]:
    """The ``failsafe:`` mapping."""
    failsafe = schema["$defs"]["agent"]["properties"]["failsafe"]
    return [
        "## Failsafe",
        "",
        md(str(failsafe["description"]))
        + " `rtl` and `land` need the matching mode in the autopilot profile "
        "([[E-FAILSAFE]]); `mcs_lost` without a station in the "
        "mission is a warning ([[W-NO-STATION]]).",
        "",
        *property_table(failsafe),
        "",
    ]


def launch_section(schema: Schema) -> list[str]:
    """The ``launch:`` mapping: who arms a vehicle and whether it starts flying."""
    launch = schema["$defs"]["agent"]["properties"]["launch"]
    return [
        "## Launch",
        "",
        md(str(launch["description"])),
        "",
        *property_table(launch),
        "",
        "```yaml",
        "agents:",
        "  slash:                         # no launch: on the ground, armed by its pilot",
        "    id: 2",
        "    profile: traxxas_slash",
        "  f450:",
        "    id: 3",
        "    profile: dji_f450",
        "    launch: {armed_by: engine}   # on the ground; the engine arms it to take off",
        "  cub:",
        "    id: 4",
        "    profile: super_cub",
        "    launch: {airborne: true}     # the pilot arms it, takes off and hands it over",
        "    position: [0, 0, 60]         # here, 60 m above the origin",
        "```",
        "",
        "- **`armed_by: pilot`** (the default, as in the thesis's flights): the safety pilot "
        "arms the vehicle, and the engine never does. The behaviour starts once the vehicle "
        "is armed. An aircraft on the ground then takes off in a [`takeoff`](#takeoff) state.",
        "- **`armed_by: engine`**: the engine arms the vehicle when its behaviour first needs "
        "it, on entering a guided state ([`waypoint`](#waypoint), "
        "[`waypoint_tour`](#waypoint_tour), [`follow_agent`](#follow_agent)) or a "
        "[`takeoff`](#takeoff). The behaviour starts once the autopilot is ready (its "
        "profile's `wait_ready`).",
        "- **`airborne: true`** (aircraft only, with `armed_by: pilot`): the pilot arms the "
        "aircraft and takes off before the behaviour starts; the behaviour starts once it "
        "flies. Its `position` gives the height at which the pilot hands it over, and the "
        "dry run starts it there, flying.",
        "",
        "A vehicle without `airborne` starts on the ground, so its `position` has no height "
        "above the origin, and an airborne one needs that height (both "
        "[[E-LAUNCH-HEIGHT]]). A rover is never airborne, and the engine never arms a vehicle "
        "its pilot hands over in flight ([[E-LAUNCH-AIRBORNE]]); a station has no `launch` "
        "([[E-LAUNCH-STATION]]). A multirotor or fixed-wing aircraft that starts on the "
        "ground and flies to guided targets with no `takeoff` state anywhere in its behaviour "
        "is warned about ([[W-TAKEOFF-MISSING]]): ArduCopter ignores guided targets until it "
        "has taken off.",
        "",
        "`launch` replaces the agent's `sim.armed` of earlier versions, which is gone: an agent "
        "that still writes it is reported ([[E-KEY-UNKNOWN]]). Compiled configs carry `launch` "
        "for every vehicle, its defaults filled in (`null` for stations), for the runtime.",
        "",
    ]


def envelope_section(schema: Schema) -> list[str]:
    """The ``envelope:`` section (the mission's) and a vehicle's ``envelope:``."""
    section = schema["properties"]["envelope"]
    agent = schema["$defs"]["agent"]["properties"]["envelope"]
    zone = schema["$defs"]["zone"]
    return [
        "## Envelope",
        "",
        md(str(section["description"])) + " [safety.md](safety.md) says what is held where.",
        "",
        *property_table(section),
        "",
        "A geofence zone is one of:",
        "",
        *property_table(zone),
        "",
        "A vehicle's own `envelope:`, under its agent: " + md(str(agent["description"])),
        "",
        *property_table(agent),
        "",
        "```yaml",
        "envelope:",
        "  ceiling_m: 60                  # above the origin; 120 m when omitted",
        "  geofence:",
        "    include: [{polygon: [[-50, -50], [200, -50], [200, 200], [-50, 200]]}]",
        "    exclude: [{circle: {center: [80, 80], radius_m: 15}}]   # the car park",
        "  separation: [{between: [slash_a, slash_b], min_m: 2}]",
        "agents:",
        "  cub:",
        "    id: 2",
        "    profile: super_cub",
        "    envelope: {floor_m: 30, on_breach: rtl}",
        "```",
        "",
        "Every altitude is metres above the mission origin, whose own height above mean sea "
        "level is `mission.origin.alt_amsl_m`. A vehicle's envelope may only narrow the "
        "mission's ([[E-ENVELOPE-WIDEN]]); the ceiling stays under `legal_ceiling_m` "
        "([[E-CEILING-LEGAL]]), which is 120 m unless the mission raises it "
        "([[W-CEILING-WAIVER]]); a floor lies below its ceiling ([[E-ENVELOPE-FLOOR]]); a "
        "polygon's edges do not cross ([[E-GEOFENCE-POLYGON]]); a separation names two "
        "vehicles ([[E-SEPARATION-AGENT]]); a station has no envelope "
        "([[E-ENVELOPE-STATION]]). `mission.ceiling_m` of earlier versions is now "
        "`envelope.ceiling_m` ([[E-KEY-RENAMED]]). Compiled configs carry each vehicle's "
        "resolved envelope, every default filled in.",
        "",
    ]


def points_section(schema: Schema) -> list[str]:
    """The forms a position may take."""
    point = schema["$defs"]["agent"]["properties"]["position"]
    lines = [
        "## Points",
        "",
        "Waypoints, a station's position and `reached` checks are points, in the mission's "
        "local frame around `mission.origin` (north, east, up in metres) or in latitude and "
        "longitude. Heights are above the origin's altitude. Any of these forms:",
        "",
    ]
    rows = []
    for branch in point.get("anyOf", []):
        if branch.get("type") == "array":
            names = [
                re.sub(r"^Metres (\w+).*$", r"\1", str(p.get("description", "")))
                for p in branch.get("prefixItems", [])
            ]
            keys = ["north_m", "east_m", "up_m"][: len(names)]
            form = "[" + ", ".join(keys[: branch.get("minItems", 2)]) + "]"
            full = "[" + ", ".join(keys) + "]"
            rows.append(
                [
                    f"`{form}` or `{full}`",
                    md(
                        "A list: "
                        + "; ".join(
                            f"{k} = {str(p.get('description', '')).rstrip('.').lower()}"
                            for k, p in zip(keys, branch.get("prefixItems", []), strict=False)
                        )
                        + ". Height 0 when omitted.",
                        cell=True,
                    ),
                ]
            )
        else:
            props = branch.get("properties", {})
            req = set(branch.get("required", []))
            form = "{" + ", ".join(props) + "}"
            rows.append(
                [
                    f"`{form}`",
                    md(
                        "A mapping: "
                        + "; ".join(
                            f"{k} = {str(p.get('description', '')).rstrip('.').lower()}"
                            + (f" ({p['x-unit']})" if "x-unit" in p else "")
                            + ("" if k in req else f", default {json.dumps(p.get('default'))}")
                            for k, p in props.items()
                        )
                        + ".",
                        cell=True,
                    ),
                ]
            )
    lines += table(("Form", "Meaning"), rows)
    lines += [
        "",
        "```yaml",
        "waypoints:",
        "  - [0, 0]                                   # the origin, on the ground",
        "  - [300, 0, 60]                             # 300 m north, 60 m up",
        "  - {north_m: 300, east_m: 60, up_m: 60}",
        "  - {lat: 30.6390, lon: -96.4780, alt_m: 60}",
        "```",
        "",
        "Aircraft waypoints must stay under their vehicle's ceiling (`envelope.ceiling_m`) "
        "and not below the origin ([[E-ALTITUDE-CEILING]]), and over its floor in guided "
        "flight ([[E-ALTITUDE-FLOOR]]); every waypoint must be inside its vehicle's "
        "geofence ([[E-GEOFENCE-POINT]]), far enough inside for the runtime to send it as "
        "written ([[W-ENVELOPE-MARGIN]], [[E-ORBIT-FENCE]]), and within radio range of each "
        "station ([[E-RADIO-RANGE]]); [safety.md](safety.md#what-clark-validate-proves) "
        "lists every check of the envelope.",
        "",
    ]
    return lines


def checks_section(schema: Schema) -> list[str]:
    """The dry-run expectations under ``checks:``."""
    check = schema["$defs"]["check"]
    props = check["properties"]
    common = {k: v for k, v in props.items() if v.get("type") != "object"}
    kinds = {k: v for k, v in props.items() if v.get("type") == "object"}
    lines = [
        "## Dry-run checks",
        "",
        "`checks:` lists what a dry run of the mission must observe. "
        + md(str(check["description"]))
        + " `clark dry-run` evaluates them and exits 1 when one fails "
        "([dry-run.md](dry-run.md)); `clark validate` checks that each item "
        "has one expectation and that the agents and states it names exist "
        "([[E-CHECK-SHAPE]], "
        "[[E-AGENT-UNKNOWN]], "
        "[[E-STATE-UNKNOWN]]).",
        "",
        "```yaml",
        "checks:",
        "  - {name: B ends near A, by_s: 120, distance_m: {between: [slash_b, slash_a], max: 6}}",
        "  - {name: B parks, by_s: 120, state: {agent: slash_b, reached: parked}}",
        "```",
        "",
        "Keys every check may have:",
        "",
        *table(
            ("Key", "Type", "Unit", "Range", "Description"),
            (
                [
                    f"`{k}`",
                    md(type_text(v), cell=True),
                    unit_text(v),
                    range_text(v),
                    md(str(v.get("description", "")), cell=True),
                ]
                for k, v in common.items()
            ),
        ),
        "",
        "And exactly one of these expectations:",
        "",
    ]
    for name, prop in kinds.items():
        lines += [
            f"### `{name}`",
            "",
            md(str(prop.get("description", ""))),
            "",
            *property_table(prop, prefix=""),
            "",
        ]
    return lines


def dry_run_inputs_section(schema: Schema) -> list[str]:
    """What a dry run is told besides the checks: the operator's script, faults, settings."""
    operator = schema["$defs"]["operator"]
    fault = schema["$defs"]["fault"]
    lines = [
        "## Dry-run operator, faults and settings",
        "",
        "Three more top-level sections drive `clark dry-run` ([dry-run.md](dry-run.md)) and "
        "are ignored in flight. `operator:` is the station operator's and the pilots' script. "
        + md(str(operator["description"])),
        "",
        "```yaml",
        "operator:",
        "  - {at_s: 20, activate: slash_b}",
        "  - {at_s: 30, mode: {agent: cub, mode: LOITER}}",
        "  - {at_s: 35, rc: {agent: cub, channel: 7, pwm_us: 1900}}",
        "faults:",
        "  - station_silent: {from_s: 40, to_s: 70}",
        "  - kill: {agent: slash_a, at_s: 30}",
        "sim: {duration_s: 120, seed: 1, radio_loss: 0.05}",
        "```",
        "",
        "### Operator actions",
        "",
        *property_table(operator, prefix=""),
        "",
        "### Faults",
        "",
        md(str(fault["description"])) + " A `--fault` option of `clark dry-run` adds one "
        "from the command line.",
        "",
    ]
    for name, prop in fault["properties"].items():
        lines += [
            f"#### `{name}`",
            "",
            md(str(prop.get("description", ""))),
            "",
            *property_table(prop, prefix=""),
            "",
        ]
    sim = schema["properties"]["sim"]
    lines += [
        "### Simulation settings",
        "",
        "`sim:` " + md(str(sim["description"])) + " An agent's own `sim:` sets where and how "
        "its simulated vehicle starts.",
        "",
        *property_table(sim, prefix=""),
        "",
        "### Varied values",
        "",
        "A number marked *or distribution* above may instead be left to chance: each run "
        "draws it once, from a generator seeded by the run's seed and the value's path, so "
        "that a run is reproduced by its seed (`clark dry-run --seed S`) and declaring one "
        "more varied value leaves the others' draws as they were. `clark dry-run --vary "
        "PATH=VALUE` fixes a value instead (`--vary sim.radio_loss=0.05`, `--vary "
        "faults.0.kill.at_s=52`, `--vary faults.0.kill.injected=false`); every `sim:` value "
        "that may vary can be given that way, drawn or not. The field's range applies to "
        "every number of a distribution.",
        "",
        "| Form | Drawn |",
        "|---|---|",
        "| `{uniform: [LOW, HIGH]}` | evenly between LOW and HIGH (LOW first) |",
        "| `{normal: {mean: M, sd: S}}` | from a normal distribution, kept within "
        f"{NORMAL_TAIL_SD:g} S of M and within the field's range |",
        "| `{choice: [A, B, ...]}` | one of the values, each as likely (at most "
        f"{MAX_CHOICES}) |",
        "",
        "A fault's `chance` (a share) injects it in that share of runs; the drawn outcome is "
        "the path `faults.N.KIND.injected`. A fault window written with distributions must "
        "keep every draw of `from_s` before every draw of `to_s` ([[E-FAULT-WINDOW]]).",
        "",
    ]
    return lines


def campaign_section(schema: Schema) -> list[str]:
    """The mission's ``campaign:``: what clark campaign flies and the pass rates it needs."""
    campaign = schema["properties"]["campaign"]
    return [
        "## Campaigns",
        "",
        "`campaign:` " + md(str(campaign["description"])) + " See [campaigns.md](campaigns.md); "
        "ignored by every other command.",
        "",
        "```yaml",
        "campaign:",
        "  runs: 200",
        "  min_pass_rate: 0.95",
        "  min_pass_rates: {Slash B parks: 0.99, 'safety: slash_a - slash_b': 1.0}",
        "```",
        "",
        *property_table(campaign, prefix=""),
        "",
    ]


def states_section(schema: Schema) -> list[str]:
    """The keys of a behaviour state."""
    state = schema["$defs"]["state"]
    lines = [
        "## States",
        "",
        "An agent's `behavior:` is a state, and so is every entry under `states:`. "
        + md(str(state["description"])),
        "",
        "- **use / with**: the state runs one [primitive](#primitives) or "
        "[behaviour block](#behaviour-blocks), `with:` its parameters. Defaults fill in what "
        "`with:` leaves out.",
        "- **states / initial**: the state is a machine of child states; `initial:` names the "
        "child entered first. A child `final: true` finishes the machine, raising `done` on it.",
        "- **parallel / finish**: `parallel: true` runs every child side by side (no "
        "`initial:`); `finish: all` (default) raises `done` when every region has finished, "
        "`finish: any` when the first one has.",
        "- **final**: an empty state that ends its parent machine; it has no `use:` and no "
        "transitions of its own.",
        "- **timeout_s**: raises `timeout` that long after the state is entered; give it a "
        "`timeout` transition.",
        "- **transitions**: event -> where to go; see [Transitions](#transitions) and "
        "[Events](#events).",
        "",
        "A state has `use:`, or `states:`, or is `final: true`: never `use:` together with "
        "`states:` ([[E-STATE-SHAPE]]), never none of them "
        "([[E-STATE-EMPTY]]). The top of a behaviour has no "
        "`transitions`, `timeout_s` or `final` ([[E-STATE-ROOT]]).",
        "",
        *property_table(state),
        "",
        "```yaml",
        "behavior:",
        "  initial: piloted",
        "  states:",
        "    piloted: {use: wait, transitions: {activate: excite}}",
        "    excite:",
        "      use: aileron_doublet            # a block",
        "      with: {amplitude_us: 120}",
        "      timeout_s: 30",
        "      transitions: {done: piloted, deactivate: piloted, timeout: piloted}",
        "```",
        "",
    ]
    return lines


def transitions_section(schema: Schema) -> list[str]:
    """Transition targets: a name, {to, when}, or a list."""
    transition = schema["$defs"]["transition"]
    state = schema["$defs"]["state"]
    key_pattern = state["properties"]["transitions"].get("propertyNames", {}).get("pattern", "")
    lines = [
        "## Transitions",
        "",
        "`transitions:` maps an [event](#events) to where it leads. "
        + md(str(transition["description"]))
        + " A target is a sibling state, a sibling of an ancestor, or a dotted path down from "
        "one of those (`excite.sweep`); names are resolved when the mission loads "
        "([[E-STATE-UNKNOWN]]). Event keys match `" + key_pattern + "`.",
        "",
    ]
    forms = {
        "string": "a state name: `parked`",
        "object": "`{to: <state>, when: <condition>}`",
        "array": "a list: `[{to: <state>, when: <condition>}, ..., {to: <state>}]`",
    }
    rows = []
    for branch in transition.get("anyOf", []):
        form = forms.get(str(branch.get("type")), md(type_text(branch), cell=True))
        rows.append([form, md(describe(branch), cell=True)])
    lines += table(("Form", "Meaning"), rows)
    lines += [
        "",
        "```yaml",
        "transitions:",
        "  done: parked                                    # a state name",
        "  activate: {to: chase, when: {mode: {is: GUIDED}}}   # only while the condition holds",
        "  lost:slash_a:                                   # a list, tried in order",
        "    - {to: go_home, when: {in_state_s: {gt: 60}}}",
        "    - {to: wait_here}",
        "  \"mode:MANUAL\": ready                            # an event key with ':', quoted",
        "```",
        "",
        "The guarded form `{to, when}`:",
        "",
    ]
    guarded = next((b for b in transition.get("anyOf", []) if b.get("type") == "object"), None)
    if guarded is not None:
        lines += property_table(guarded)
    return [*lines, ""]


def events_section() -> list[str]:
    """Every event name and its meaning, cross-checked against the engine."""
    from clark_engine.mission import state_checks as checks
    from clark_engine.mission.schema_source import states

    documented = {name for name, _ in EVENTS}
    simple = set(checks.SIMPLE_EVENTS)
    patterned = {n for n in documented if "<" in n}
    missing = simple - documented
    extra = documented - simple - patterned
    if missing or extra:
        raise SystemExit(
            "tools/gen_reference.py: the EVENTS table disagrees with the engine "
            f"(undocumented: {sorted(missing)}, unknown: {sorted(extra)}); update EVENTS"
        )
    for name in sorted(documented):
        if name.split(":<", 1)[0] not in states.EVENT_DESCRIPTION:
            raise SystemExit(
                f"tools/gen_reference.py: event {name!r} is not in the schema's event list"
            )
    station = sorted(checks.STATION_EVENTS)
    return [
        "## Events",
        "",
        "Events move a state machine on. A transition's key is the event; the names are "
        "checked when the mission loads ([[E-EVENT-UNKNOWN]]). "
        "Events from the station ("
        + ", ".join(f"`{e}`" for e in station)
        + ") need an agent with role `mcs` in the mission "
        "([[E-NO-STATION]]). [docs/runtime.md](runtime.md) says where the runtime raises each "
        "one. A station's Terminate ends an agent at once (thesis 7.3.5), so a `terminate` "
        "transition is never taken ([[W-TERMINATE-EVENT]]).",
        "",
        *table(("Event", "Meaning"), ([f"`{n}`", md(m, cell=True)] for n, m in EVENTS)),
        "",
        "Event keys that contain `:` may be written plain (`mode:MANUAL: ready`); the shipped "
        'missions quote them (`"mode:MANUAL": ready`), which reads more clearly and is '
        "never wrong.",
        "",
    ]


def conditions_section(schema: Schema) -> list[str]:
    """The structured conditions of guarded transitions."""
    condition = schema["$defs"]["condition"]
    lines = [
        "## Conditions",
        "",
        "A guarded transition's `when:` is structured data, never code. "
        + md(str(condition["description"]))
        + " Agents and modes it names are checked like the rest of the mission.",
        "",
    ]
    rows = []
    for name, prop in condition["properties"].items():
        keys = []
        required = set(prop.get("required", []))
        for sub, sub_schema in prop.get("properties", {}).items():
            unit = unit_text(sub_schema)
            keys.append(
                f"`{sub}`"
                + (f" ({unit})" if unit else "")
                + (" required" if sub in required else "")
            )
        form = ", ".join(keys) if keys else md(type_text(prop), cell=True)
        meaning = describe(prop)
        if name == "not" and not prop.get("description"):
            meaning = "Holds when the condition inside does not hold."
        rows.append([f"`{name}`", form, md(meaning, cell=True)])
    lines += table(("Condition", "Keys", "Meaning"), rows)
    lines += [
        "",
        "`lt` holds while the value is below the bound and `gt` while it is above; give "
        "either or both.",
        "",
        "```yaml",
        "when: {distance_m: {to: slash_a, lt: 10}}",
        "when: {all: [{altitude_m: {gt: 30}}, {in_state_s: {gt: 5}}]}",
        "when: {not: {mode: {is: MANUAL}}}",
        "```",
        "",
        "Conditions on another agent (`agent_state`, `ahead_m`, `behind_m`, `above_m`, "
        "`within_m`) hold only on fresh data: the other agent must send this one its "
        "`behavior_state` (for `agent_state`) or `agent_status` (for the others) in its "
        "`telemetry:` ([E-CONDITION-DATA](check-codes.md#e-condition-data)), and a "
        "message older than three of its periods, or from an agent that is lost, never "
        "satisfies one. With the event `always` a transition is taken as soon as its "
        "condition holds; in a block, any value of a condition may be a parameter "
        "(`gt: $gap_m`). [docs/runtime.md](runtime.md#conditions-on-other-agents) defines "
        "ahead, behind, above and within.",
        "",
        "```yaml",
        "always: {to: advance, when: {agent_state: {agent: rover_b, in: hold}}}",
        "always: {to: hold, when: {ahead_m: {agent: rover_b, lt: -15, bearing_deg: 0}}}",
        "```",
        "",
    ]
    return lines


# ----------------------------------------------------------------------------- primitives


def _shared_codes(module: ModuleType, shared: ModuleType) -> set[str]:
    """Codes a primitive module can emit: its own, and those of the shared checks it uses.

    The shared checks are the functions it imports from ``shared``, and every function
    those call, wherever it is defined (the envelope's checks live in
    ``clark_engine.mission.envelope_checks``).
    """
    source = inspect.getsource(module)
    codes = set(_CODE_RE.findall(source))
    pending: list[Any] = []
    for node in ast.walk(ast.parse(source)):
        if isinstance(node, ast.ImportFrom) and node.module == shared.__name__:
            pending.extend(getattr(shared, alias.name, None) for alias in node.names)
    seen: set[Any] = set()
    while pending:
        func = pending.pop()
        if not inspect.isfunction(func) or func in seen:
            continue
        seen.add(func)
        body = inspect.getsource(func)
        codes.update(_CODE_RE.findall(body))
        pending.extend(func.__globals__.get(n) for n in re.findall(r"\b([A-Za-z_]\w*)\(", body))
    return codes


def _event_variants(spec: Any) -> list[str]:
    """Notes on how the events change with parameters, found by trying them."""
    base = spec.with_defaults({})
    default_events = spec.events(base)
    notes = []
    for key, prop in spec.schema.get("properties", {}).items():
        if not isinstance(prop, Mapping):
            continue
        if prop.get("type") == "boolean":
            value = not prop.get("default", False)
            variant = {**base, key: value}
            shown = f"`{key}: {json.dumps(value)}`"
        elif "default" not in prop and key not in spec.schema.get("required", []):
            sample = prop.get("minimum", prop.get("exclusiveMinimum", 0)) or 1
            variant = {**base, key: sample}
            shown = f"`{key}` is given"
        else:
            continue
        events = spec.events(variant)
        if events == default_events:
            continue
        gained = sorted(events - default_events)
        lost = sorted(default_events - events)
        if gained:
            notes.append(", ".join(f"`{e}`" for e in gained) + f" only when {shown}")
        if lost:
            notes.append("no " + ", ".join(f"`{e}`" for e in lost) + f" when {shown}")
    return notes


def _docstring_body(module: ModuleType) -> str:
    """A module's docstring without its first line (the one-line title)."""
    doc = inspect.cleandoc(module.__doc__ or "")
    first, _, rest = doc.partition("\n")
    rest = rest.strip()
    title = first.split(":", 1)[-1].strip()
    title = title[:1].upper() + title[1:]
    body = " ".join(p for p in [title, " ".join(rest.split())] if p)
    return md(body)


def primitives_section() -> list[str]:
    """One section per built-in behaviour (a primitive, as the language calls them)."""
    from clark_engine.behaviors import built_in

    PRIMITIVES = built_in()
    shared = importlib.import_module("clark_engine.behaviors.shared")
    lines = [
        "## Primitives",
        "",
        "Primitives are the smallest behaviours, built into the engine. A state runs one with "
        "`use: <name>` and `with: {parameters}`; parameters are checked against the tables "
        "below (with the same messages as the rest of the file) and defaults fill in the "
        "rest. Each primitive also has checks that need the agent's hardware or the rest of "
        "the mission, listed under *Checks*.",
        "",
        *table(
            ("Primitive", "Summary", "Done by itself"),
            (
                [
                    f"[`{name}`](#{slug(name)})",
                    md(spec.summary, cell=True),
                    "yes" if "done" in spec.events(spec.with_defaults({})) else "no",
                ]
                for name, spec in PRIMITIVES.items()
            ),
        ),
        "",
        "*Done by itself* is with the default parameters; the sections below say which "
        "parameters change it. A `done` transition on a state that can never finish is a "
        "warning ([[W-DONE-NEVER]]).",
        "",
    ]
    for name, spec in PRIMITIVES.items():
        module = importlib.import_module(spec.runtime.__module__)
        events = sorted(spec.events(spec.with_defaults({})))
        event_text = ", ".join(f"`{e}`" for e in events) if events else "none"
        variants = _event_variants(spec)
        # Its checks may live in a module of its own beside it (survey_checks.py): read
        # that one too (a check taken whole from shared.py is followed as an import).
        codes = _shared_codes(module, shared)
        check_module = getattr(spec.check, "__module__", module.__name__)
        if check_module not in (module.__name__, shared.__name__):
            codes |= _shared_codes(importlib.import_module(check_module), shared)
        lines += [
            f"### {name}",
            "",
            f"**{md(spec.summary)}**",
            "",
            _docstring_body(module),
            "",
            "- **Runs on**: "
            + ("vehicles only." if spec.needs_autopilot else "vehicles and stations."),
            "- **Events** with default parameters: "
            + event_text
            + ("; " + "; ".join(variants) if variants else "")
            + ".",
        ]
        if codes:
            lines.append(
                "- **Checks**: "
                + ", ".join(f"[{c}](check-codes.md#{c.lower()})" for c in sorted(codes))
                + "."
            )
        lines.append("")
        params = property_table(spec.schema)
        lines += params if params else [md(str(spec.schema.get("description", "")))]
        lines.append("")
    return lines


# ----------------------------------------------------------------------------- blocks


def _machine_text(path: Path) -> str:
    """The ``machine:`` part of a block file, verbatim."""
    text = path.read_text(encoding="utf-8")
    match = re.search(r"^machine:.*\Z", text, flags=re.MULTILINE | re.DOTALL)
    return match.group(0).rstrip() if match else ""


def _uses(machine: Any) -> list[str]:
    """Every primitive or block a machine uses, in order, without repeats."""
    found: list[str] = []

    def walk(state: Any) -> None:
        """Collect the ``use:`` of ``state`` and of its children, depth first."""
        if not isinstance(state, Mapping):
            return
        use = state.get("use")
        if isinstance(use, str) and use not in found:
            found.append(use)
        for child in (state.get("states") or {}).values():
            walk(child)

    walk(machine)
    return found


def blocks_section(behavior_schema: Schema) -> list[str]:
    """The block file format and every shipped block."""
    from clark_engine.behaviors import built_in
    from clark_engine.mission.yaml_loader import decode_text, load_yaml

    PRIMITIVES = built_in()

    lines = [
        "## Behaviour blocks",
        "",
        "A block is a reusable behaviour in a YAML file, used like a primitive "
        "(`use: aileron_doublet`, `with: {amplitude_us: 120}`). Blocks live in `behaviors/` "
        "and in the folders a mission lists under `include: {behaviors: [...]}`.",
        "",
        "### Block files",
        "",
        "A block file is named after its block (`aileron_doublet.yaml` holds "
        "`block: aileron_doublet`) and starts with "
        "`# yaml-language-server: $schema=../schemas/behavior.schema.json`. Inside `machine:`, "
        "a value written `$name` inside a `with:` or a transition's `when:` is replaced by "
        "parameter `name`: the value the mission gave, or the parameter's default (a "
        "condition is then checked as a mission's, "
        "[E-BLOCK-WHEN](check-codes.md#e-block-when)). Control channels are named "
        "(`channel: aileron`) and resolved through each agent's profile, so one block serves "
        "every airframe that has that control. `clark validate behaviors/my_block.yaml` checks "
        "a block on its own.",
        "",
        *table(
            ("Key", "Required", "Description"),
            (
                [
                    f"`{k}`",
                    "yes" if k in behavior_schema.get("required", []) else "",
                    md(str(v.get("description", "")), cell=True),
                ]
                for k, v in behavior_schema["properties"].items()
            ),
        ),
        "",
    ]
    files = sorted((ROOT / "behaviors").glob("*.yaml"))
    lines += [
        "### Shipped blocks",
        "",
        *table(
            ("Block", "Description"),
            (
                [
                    f"[`{f.stem}`](#{slug(f.stem)})",
                    md(str(_load(f, decode_text, load_yaml).get("description", "")), cell=True),
                ]
                for f in files
            ),
        ),
        "",
    ]
    for file in files:
        data = _load(file, decode_text, load_yaml)
        params = data.get("parameters") or {}
        uses = _uses(data.get("machine"))
        uses_text = ", ".join(
            f"[`{u}`](#{slug(u)})"
            if u in PRIMITIVES or (ROOT / "behaviors" / f"{u}.yaml").exists()
            else f"`{u}`"
            for u in uses
        )
        lines += [
            f"#### {file.stem}",
            "",
            md(str(data.get("description", ""))),
            "",
            f"File: `behaviors/{file.name}`. Uses: {uses_text}.",
            "",
        ]
        table_lines = property_table(params)
        lines += table_lines if table_lines else ["No parameters."]
        lines += ["", "```yaml", _machine_text(file), "```", ""]
    return lines


def _load(path: Path, decode: Callable[[bytes, str], str], load: Callable[[str, str], Any]) -> Any:
    """A YAML file's data, read with the engine's own strict loader."""
    shown = path.relative_to(ROOT).as_posix()
    return load(decode(path.read_bytes(), shown), shown).data


# ----------------------------------------------------------------------------- main


def generate() -> str:
    """The full text of docs/reference.md."""
    _import_engine()
    mission = json.loads((ROOT / "schemas" / "mission.schema.json").read_text(encoding="utf-8"))
    behavior = json.loads((ROOT / "schemas" / "behavior.schema.json").read_text(encoding="utf-8"))
    sources = [
        "`schemas/mission.schema.json`",
        "`schemas/behavior.schema.json`",
        "the behaviour declarations (`clark_engine/behaviors/`)",
        "the event names of `clark_engine/mission/state_checks.py`",
        "`behaviors/*.yaml`",
    ]
    lines: list[str] = []
    for part in (
        intro(sources),
        limits_section(),
        file_structure(mission),
        mission_section(mission),
        include_section(mission),
        agents_section(mission),
        telemetry_section(mission),
        failsafe_section(mission),
        launch_section(mission),
        envelope_section(mission),
        points_section(mission),
        checks_section(mission),
        dry_run_inputs_section(mission),
        campaign_section(mission),
        states_section(mission),
        transitions_section(mission),
        events_section(),
        conditions_section(mission),
        primitives_section(),
        blocks_section(behavior),
    ):
        lines.extend(part)
    text = "\n".join(lines).rstrip() + "\n"
    text = _CODE_LINK.sub(lambda m: f"[{m[1]}](check-codes.md#{m[1].lower()})", text)
    return re.sub(r"\n{3,}", "\n\n", text)


def main(argv: Sequence[str] | None = None) -> int:
    """Write, print or check docs/reference.md; returns the exit code."""
    return docgen.run(
        OUTPUT,
        generate,
        argv,
        tool="gen_reference.py",
        description="Generate docs/reference.md from its sources.",
    )


if __name__ == "__main__":
    sys.exit(main())
