"""Schema of behaviour states, shared by missions and behaviour blocks.

A state is a ``use:`` of a primitive or block, a machine of child ``states:``
(with an ``initial``), parallel regions (``parallel: true``) or an empty
``final`` state; it may time out and moves on named events. The ``with:`` of
each primitive is checked against that primitive's own parameter schema.
"""

from __future__ import annotations

from collections.abc import Callable

from clark_engine.behaviors import in_schemas
from clark_engine.behaviors.shared import AGENT_NAME_SCHEMA
from clark_engine.mission.schema_source.common import (
    NAME_PATTERN,
    Schema,
    altitude_m,
    array,
    boolean,
    distance_m,
    number,
    obj,
    position_m,
    speed_m_s,
    string,
    time_s,
)

STATE_PATH_PATTERN = r"^[a-z][a-z0-9_]*(\.[a-z][a-z0-9_]*)*$"
#: Longest state path a condition on another agent may name: far beyond any behaviour's
#: nesting, and what bounds the comparison with the paths a peer reports over the air.
MAX_STATE_PATH_CHARS = 200
#: A block parameter written in a block's machine: ``$name``.
PARAM_REF_PATTERN = r"^\$[a-z][a-z0-9_]*$"

EVENT_DESCRIPTION = (
    "Event name: done, timeout, activate, deactivate, terminate, mode:<MODE>, "
    "rc:<channel>:high, rc:<channel>:low, lost:<agent>, found:<agent>, mcs_lost, "
    "autopilot_lost, always (taken on the first tick its when: holds)."
)


def _bounds(description: str, quantity: Callable[..., Schema]) -> Schema:
    """``{lt, gt}`` of one quantity, each in that quantity's range."""
    return obj(
        description,
        {
            "lt": quantity("Holds while the value is below this."),
            "gt": quantity("Holds while the value is above this."),
        },
    ) | {"minProperties": 1}


def condition_schema() -> Schema:
    """Structured conditions on transitions (data the schema checks, never code)."""
    return {
        "type": "object",
        "description": "A condition that must hold for the transition to be taken; exactly "
        "one key.",
        "minProperties": 1,
        "maxProperties": 1,
        "additionalProperties": False,
        "properties": {
            "distance_m": obj(
                "Ground distance from this agent to another agent's last reported position.",
                {
                    "to": AGENT_NAME_SCHEMA,
                    "lt": distance_m("Holds while the distance is below this."),
                    "gt": distance_m("Holds while the distance is above this."),
                },
                required=["to"],
            ),
            "altitude_m": _bounds("This agent's altitude above the origin.", altitude_m),
            "speed_m_s": _bounds("This agent's ground speed.", speed_m_s),
            "in_state_s": _bounds("Time since the current state was entered.", time_s),
            "mode": obj(
                "This agent's autopilot mode.",
                {"is": string("Mode name of the agent's autopilot firmware.")},
                required=["is"],
            ),
            **peer_condition_properties(),
            "all": array(
                "Holds when every condition holds.", {"$ref": "#/$defs/condition"}, min_items=1
            ),
            "any": array(
                "Holds when any condition holds.", {"$ref": "#/$defs/condition"}, min_items=1
            ),
            "not": {"$ref": "#/$defs/condition"},
        },
    }


def peer_condition_properties() -> dict[str, Schema]:
    """Conditions on another agent: its behaviour state and where it is relative to this one.

    Each names the other agent by ``agent`` and holds only on fresh data: the peer's
    last Behavior State or Agent Status younger than three of the periods it declares
    sending them to this agent at, and never while the peer is lost (docs/runtime.md).
    """
    agent = AGENT_NAME_SCHEMA | {"description": "The other agent, by its name in agents:."}

    def relative(description: str, quantity: Callable[..., Schema], *extra: str) -> Schema:
        properties: dict[str, Schema] = {
            "agent": agent,
            "lt": quantity("Holds while the figure is below this."),
            "gt": quantity("Holds while the figure is above this."),
        }
        if "bearing_deg" in extra:
            properties["bearing_deg"] = number(
                "Fixed direction of ahead, in degrees clockwise from true north, instead of "
                "this agent's heading (a leapfrog's line of advance, say).",
                unit="deg",
                minimum=0,
                exclusive_maximum=360,
            )
        return obj(description, properties, required=["agent"])

    return {
        "agent_state": obj(
            "Another agent's behaviour is in a state: the state or one of its descendants is "
            "active, by the agent's last Behavior State.",
            {
                "agent": agent,
                "in": string(
                    "Dotted path of a state of that agent's behaviour.",
                    pattern=STATE_PATH_PATTERN,
                )
                | {"maxLength": MAX_STATE_PATH_CHARS},
            },
            required=["agent", "in"],
        ),
        "ahead_m": relative(
            "How far the other agent is ahead of this one, in metres along this agent's "
            "heading (or bearing_deg); negative when it is behind.",
            position_m,
            "bearing_deg",
        ),
        "behind_m": relative(
            "How far the other agent is behind this one, in metres against this agent's "
            "heading (or bearing_deg); negative when it is ahead.",
            position_m,
            "bearing_deg",
        ),
        "above_m": relative(
            "How far the other agent is above this one, in metres: both altitudes above the "
            "mission origin; negative when it is below.",
            position_m,
        ),
        "within_m": relative(
            "Straight-line distance to the other agent in metres (ground distance and height "
            "difference together): within_m: {agent: x, lt: 10} is within 10 m of x.",
            distance_m,
        ),
    }


def with_param_refs(condition: Schema) -> Schema:
    """The condition schema of a block's machine: any value may be a ``$name`` parameter.

    A block's transitions may say ``when: {in_state_s: {gt: $wait_s}}``; the value is
    substituted when the block is used and checked then against :func:`condition_schema`.
    """
    ref = string(
        "A block parameter, $name, replaced by its value where the block is used.",
        pattern=PARAM_REF_PATTERN,
    )
    out = dict(condition)
    properties = {}
    for key, schema in condition["properties"].items():
        if "properties" in schema:
            schema = dict(schema)
            schema["properties"] = {
                name: {"description": leaf.get("description", ""), "anyOf": [leaf, ref]}
                for name, leaf in schema["properties"].items()
            }
        properties[key] = schema
    out["properties"] = properties
    return out


def transition_schema() -> Schema:
    """A transition target: a state name, ``{to, when}``, or a list tried in order."""
    guarded = obj(
        "A transition taken only while its condition holds.",
        {
            "to": string(
                "State to go to (a sibling, an ancestor's sibling, or a dotted path).",
                pattern=STATE_PATH_PATTERN,
            ),
            "when": {"$ref": "#/$defs/condition"},
        },
        required=["to"],
    )
    return {
        "description": "Where the event leads: a state name, {to, when}, or a list of those "
        "tried in order.",
        "x-expected": "a state name, {to: state, when: condition}, or a list of {to, when}",
        "anyOf": [
            string("Name of the state to go to.", pattern=STATE_PATH_PATTERN),
            guarded,
            array(
                "Guarded transitions tried in order; the first whose condition holds is taken.",
                guarded,
                min_items=1,
            ),
        ],
    }


def state_schema(*, check_params: bool = True) -> Schema:
    """One state, recursively; ``with:`` is checked per primitive when ``check_params``.

    Behaviour blocks pass ``check_params=False``: their ``with:`` values may be
    ``$name`` parameter references, checked after substitution instead.
    """
    per_primitive = [
        {
            "if": {"properties": {"use": {"const": name}}, "required": ["use"]},
            "then": {"properties": {"with": {"$ref": f"#/$defs/params_{name}"}}},
        }
        for name in in_schemas()
    ]
    schema = obj(
        "A behaviour state: a use of a primitive or block, a machine of states, parallel "
        "regions, or an empty final state.",
        {
            "description": string("What this state is for, in your words."),
            "use": string(
                "Primitive (" + ", ".join(in_schemas()) + ") or behaviour block to run.",
                pattern=NAME_PATTERN,
            ),
            "with": {"type": "object", "description": "Parameters of the primitive or block."},
            "initial": string("Child state entered first.", pattern=NAME_PATTERN),
            "states": {
                "type": "object",
                "description": "Child states by name.",
                "minProperties": 1,
                "propertyNames": {"pattern": NAME_PATTERN},
                "additionalProperties": {"$ref": "#/$defs/state"},
            },
            "parallel": boolean("Run the child states side by side as regions.", default=False),
            "finish": string(
                "When parallel regions finish the state: all (every region reached a final "
                "state or finished its primitive) or any (the first region to finish stops the "
                "others).",
                enum=["all", "any"],
                default="all",
            ),
            "final": boolean(
                "Reaching this state finishes its parent, raising done on it.", default=False
            ),
            "timeout_s": time_s(
                "Raise the timeout event this long after entering the state.",
                exclusive_minimum=0,
                maximum=86400,
            ),
            "transitions": {
                "type": "object",
                "description": "Event -> where it leads. " + EVENT_DESCRIPTION,
                "propertyNames": {
                    "pattern": r"^[a-z_]+(:[A-Za-z0-9_]+)*$",
                    "description": "An event name such as done, activate, mode:AUTO, "
                    "rc:8:high or lost:slash_a.",
                },
                "additionalProperties": {"$ref": "#/$defs/transition"},
            },
        },
    )
    if check_params:
        schema["allOf"] = per_primitive
    return schema


def state_defs(*, check_params: bool = True) -> dict[str, Schema]:
    """The ``$defs`` every schema that embeds states needs."""
    defs: dict[str, Schema] = {
        "state": state_schema(check_params=check_params),
        "transition": transition_schema(),
        "condition": condition_schema() if check_params else with_param_refs(condition_schema()),
    }
    if check_params:
        for name, spec in in_schemas().items():
            defs[f"params_{name}"] = spec.schema
    return defs
