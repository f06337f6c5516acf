"""What a primitive declares: its parameters, the events it raises, its own checks.

A primitive is the smallest behaviour a mission can ``use:`` (waypoint, doublet,
sine_sweep, ...). Each lives in its own module beside its parameter schema, as
a :class:`PrimitiveSpec`; :mod:`clark_engine.mission.primitives` collects them
into a registry from which the mission schema is built. The runtime (a later
layer) adds the behaviour class that executes each one; this layer only
declares, resolves and checks.
"""

from __future__ import annotations

from collections.abc import Callable, Iterable, Mapping
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any

from clark_engine.mission.findings import Finding, Location

if TYPE_CHECKING:
    from clark_engine.mission.model import Agent, Mission

Schema = dict[str, Any]


@dataclass(frozen=True, slots=True)
class UseContext:
    """Everything a primitive's check may look at for one use of it.

    Attributes:
        mission: The resolved mission (loop rate, origin, ceiling, every agent).
        agent: The agent whose behaviour uses the primitive.
        params: The parameters after defaults were applied.
        locate: Where a parameter was written (falls back to the ``use:``).
        use_location: Where the ``use:`` that selected the primitive was written.
    """

    mission: Mission
    agent: Agent
    params: Mapping[str, Any]
    locate: Callable[[str], Location]
    use_location: Location


CheckFn = Callable[[UseContext], Iterable[Finding]]
EventsFn = Callable[[Mapping[str, Any]], frozenset[str]]


def _no_checks(_ctx: UseContext) -> Iterable[Finding]:
    return ()


@dataclass(frozen=True, slots=True)
class PrimitiveSpec:
    """The declaration of one primitive.

    Attributes:
        name: What a mission writes after ``use:``.
        summary: One sentence for the language reference and ``clark explain``.
        params: JSON Schema of the ``with:`` mapping, defaults included.
        events: Events the primitive raises, given its parameters (``done`` when
            it finishes; nothing when it runs until something else moves on).
        needs_autopilot: Only vehicles may use it (the station has no autopilot).
        check: Pre-flight checks that need the mission and the agent's hardware.
        compiled: The parameters the compiler writes in another form than the mission
            does (points in both frames, a channel as its resolved map, an agent as
            ``{name, id}``): returns parameter name -> JSON Schema of its compiled form.
            The other parameters are compiled as written, defaults filled in. A
            function, called only when the agent-config schema is generated: validating
            a mission never pays for building these.
    """

    name: str
    summary: str
    params: Schema
    events: EventsFn
    needs_autopilot: bool = True
    check: CheckFn = field(default=_no_checks)
    compiled: Callable[[], Mapping[str, Schema]] = field(default=dict)

    def config_params(self) -> Schema:
        """JSON Schema of the parameters as a compiled agent config holds them.

        The mission's own parameter schema (:attr:`params`, the one definition of the
        primitive's parameters) with the parameters the compiler resolves replaced by
        their compiled form (:attr:`compiled`). Loading a config validates every state's
        parameters against it, so a hand-edited or version-skewed config is refused
        before the first tick rather than when the state is entered.
        """
        properties = dict(self.params.get("properties", {}))
        properties.update(self.compiled())
        return {**self.params, "properties": properties}

    def with_defaults(self, given: Mapping[str, Any]) -> dict[str, Any]:
        """The parameters with every declared default filled in, in declared order."""
        out: dict[str, Any] = {}
        for key, prop in self.params.get("properties", {}).items():
            if key in given:
                out[key] = given[key]
            elif "default" in prop:
                out[key] = prop["default"]
        out.update({k: v for k, v in given.items() if k not in out})
        return out


def raises_done(_params: Mapping[str, Any]) -> frozenset[str]:
    """For primitives that always finish."""
    return frozenset({"done"})


def raises_nothing(_params: Mapping[str, Any]) -> frozenset[str]:
    """For primitives that run until a transition moves the machine on."""
    return frozenset()
