"""How a behaviour declares itself: typed parameters, traits, checks, compile, plan, runtime.

A behaviour (what a mission writes after ``use:``) is one module in
:mod:`clark_engine.behaviors`, and everything the engine knows about it is in the
one :class:`Behavior` that module exports as ``BEHAVIOR``:

- its parameters, ONE frozen dataclass (:class:`Params`) whose fields carry their
  JSON Schema (:func:`param`): the mission schema, the compiled agent-config
  schema, the defaults, the reference documentation and the typed object the
  runtime reads all come from it;
- its pre-flight checks and how the compiler resolves its parameters (points to
  both frames, a channel to its map, an agent to ``{name, id}``);
- its :class:`Traits`, which replace every switch on a behaviour's name (guided,
  takes off, lands, flies, takes pictures, drives a channel...);
- what the dry run, the report and the station draw and judge (its planned
  points, its expected control signal);
- its runtime class (py_trees' Behaviour lifecycle, :mod:`.base`).

This module imports nothing of the runtime, so ``clark validate`` stays fast and
never loads the flight libraries; a behaviour's runtime class imports the
runtime's command and message types where it uses them. For the same reason the
declaration's own types are named tuples, and a behaviour's parameter class
becomes a dataclass only when the runtime first builds one (:meth:`Params.typed`):
``clark validate`` imports every behaviour module, and generating a dataclass's
methods costs about a millisecond each, which thirty of them would add to every
run of it.
"""

from __future__ import annotations

import copy
import inspect
from collections.abc import Callable, Iterable, Mapping, Sequence
from dataclasses import Field, dataclass, field
from typing import TYPE_CHECKING, Any, ClassVar, NamedTuple, TypeVar, dataclass_transform

from clark_engine.mission.findings import Finding, Location

if TYPE_CHECKING:
    from clark_engine.behaviors.base import BehaviorRuntime
    from clark_engine.mission.model import Agent, Mission

Schema = dict[str, Any]
P = TypeVar("P", bound="Params")

_SCHEMA = "clark_schema"
_COMPILED = "clark_compiled"
_CONVERT = "clark_convert"


def param(
    schema: Schema,
    *,
    compiled: Callable[[], Schema] | None = None,
    convert: Callable[[Any], Any] | None = None,
) -> Any:
    """Declare one parameter of a behaviour: a dataclass field that carries its schema.

    The field's default is the schema's ``default`` (a parameter without one is
    required when it is listed in the class's ``REQUIRED``, else None when absent).

    Args:
        schema: The parameter's JSON Schema as a mission writes it (description,
            unit, bounds, default): the one definition of the parameter.
        compiled: The schema of the form the compiler writes it in, when that
            differs (a point in both frames, a channel's map); a function, so that
            validating a mission never pays for building it.
        convert: Turns the compiled JSON value into the typed field's value
            (a point into a :class:`~clark_engine.behaviors.base.Point`...).
    """
    metadata = {_SCHEMA: schema, _COMPILED: compiled, _CONVERT: convert}
    if "default" not in schema:
        return field(default=None, metadata=metadata)
    default = schema["default"]
    if isinstance(default, list | dict):
        value = default
        return field(default_factory=lambda: copy.deepcopy(value), metadata=metadata)
    return field(default=default, metadata=metadata)


@dataclass_transform(kw_only_default=True, frozen_default=True, field_specifiers=(param,))
class Params:
    """Base of every behaviour's typed parameters: a frozen, keyword-only dataclass.

    Subclasses declare their fields with :func:`param`, in the order the reference
    lists them, and name the required ones in ``REQUIRED`` (in the order the schema
    lists them). They are not decorated: the fields are read from the class as
    written, and the class is made a dataclass the first time an instance is built
    (validating a mission needs only the schemas).
    """

    DESCRIPTION: ClassVar[str] = ""
    REQUIRED: ClassVar[tuple[str, ...]] = ()
    _FIELDS: ClassVar[tuple[Field[Any], ...]] = ()

    def __init_subclass__(cls, **kwargs: Any) -> None:
        super().__init_subclass__(**kwargs)
        declared = []
        for name in inspect.get_annotations(cls):
            value = cls.__dict__.get(name)
            if isinstance(value, Field):
                value.name = name
                declared.append(value)
        cls._FIELDS = (*cls._FIELDS, *declared)

    def __new__(cls, *_args: Any, **_kwargs: Any) -> Any:  # noqa: D102
        if "__dataclass_fields__" not in cls.__dict__:
            dataclass(frozen=True, kw_only=True)(cls)
        return super().__new__(cls)

    @classmethod
    def schema(cls) -> Schema:
        """JSON Schema of the ``with:`` mapping, defaults included (the mission side)."""
        return cls._object({f.name: f.metadata[_SCHEMA] for f in cls._FIELDS})

    @classmethod
    def config_schema(cls) -> Schema:
        """JSON Schema of the parameters as a compiled agent config holds them.

        The mission's schema with the parameters the compiler resolves replaced by their
        compiled form. Loading a config validates every state's parameters against it,
        so a hand-edited or version-skewed config is refused before the first tick.
        """
        properties = {}
        for f in cls._FIELDS:
            compiled = f.metadata[_COMPILED]
            properties[f.name] = compiled() if compiled is not None else f.metadata[_SCHEMA]
        return cls._object(properties)

    @classmethod
    def _object(cls, properties: dict[str, Schema]) -> Schema:
        out: Schema = {
            "type": "object",
            "description": cls.DESCRIPTION,
            "properties": properties,
            "additionalProperties": False,
        }
        if cls.REQUIRED:
            out["required"] = list(cls.REQUIRED)
        return out

    @classmethod
    def with_defaults(cls, given: Mapping[str, Any]) -> dict[str, Any]:
        """The parameters with every declared default filled in, in declared order."""
        out: dict[str, Any] = {}
        for f in cls._FIELDS:
            if f.name in given:
                out[f.name] = given[f.name]
            elif "default" in f.metadata[_SCHEMA]:
                out[f.name] = copy.deepcopy(f.metadata[_SCHEMA]["default"])
        out.update({k: v for k, v in given.items() if k not in out})
        return out

    @classmethod
    def from_config(cls: type[P], params: Mapping[str, Any]) -> P:
        """The typed parameters of a compiled state (validated against :meth:`config_schema`)."""
        values: dict[str, Any] = {}
        for f in cls._FIELDS:
            if f.name not in params:
                continue
            convert = f.metadata[_CONVERT]
            raw = params[f.name]
            values[f.name] = convert(raw) if convert is not None and raw is not None else raw
        return cls(**values)


@dataclass(frozen=True, slots=True)
class UseContext:
    """Everything a behaviour's check may look at for one use of it.

    Attributes:
        mission: The resolved mission (loop rate, origin, ceiling, every agent).
        agent: The agent whose behaviour uses it.
        params: The parameters as the mission wrote them, after defaults were applied.
        locate: Where a parameter was written (falls back to the ``use:``).
        use_location: Where the ``use:`` that selected it was written.
    """

    mission: Mission
    agent: Agent
    params: Mapping[str, Any]
    locate: Callable[[str], Location]
    use_location: Location


class CompileContext(NamedTuple):
    """What the compiler gives a behaviour to resolve its parameters for one agent.

    Attributes:
        mission: The resolved mission (origin, agents).
        agent: The agent whose state uses the behaviour.
        point: Resolves a mission point (local or lat/lon) to its compiled form in both
            frames (``{north_m, east_m, up_m, lat, lon, alt_m}``).
    """

    mission: Mission
    agent: Agent
    point: Callable[[Any], dict[str, float]]


class Plan(NamedTuple):
    """Where a behaviour is planned to take its vehicle: its fixed targets, in order.

    Attributes:
        points: (point, parameter): the point as the params hold it (a mission point
            before compiling, ``{north_m, east_m, ...}`` after), and the parameter it
            was written at (``to``, ``waypoints[2]``).
        loop: The points are flown again and again (a looping tour).
        climb_to_m: The height above the origin it climbs to straight up (a takeoff).
        kind: How the station draws the points: ``route`` (a path through them, in
            order; a looping one closes) or ``target`` (one point to reach).
    """

    points: Sequence[tuple[Any, str]] = ()
    loop: bool = False
    climb_to_m: float | None = None
    kind: str = "route"


class Traits(NamedTuple):
    """What the engine's checks, dry run, report and station need to know of a behaviour.

    These replace every switch on a behaviour's name. Attributes:
        guided: Navigates with guided targets (an aircraft must be airborne first).
        takes_off: Takes the vehicle from the ground into the air.
        lands: Ends with the vehicle on the ground (land, RTL, terminate).
        floor_exempt: May fly below the envelope's floor (a climb or a descent).
        flies: Keeps the vehicle moving, so armed, for as long as it runs.
        flies_if_aircraft: Keeps an aircraft flying (a hold: it hovers or circles).
        stays_put: The vehicle stays over the spot it entered the state at.
        stays_put_on_ground: The same, unless the pilot flies it (``launch.airborne``).
        home_when_done: The vehicle is at home when the state is done (return_home).
        takes_pictures: Drives a camera payload.
        drives_channel: Drives a control channel (its ``channel`` and ``via`` parameters).
    """

    guided: bool = False
    takes_off: bool = False
    lands: bool = False
    floor_exempt: bool = False
    flies: bool = False
    flies_if_aircraft: bool = False
    stays_put: bool = False
    stays_put_on_ground: bool = False
    home_when_done: bool = False
    takes_pictures: bool = False
    drives_channel: bool = False


class Sends(NamedTuple):
    """A message a behaviour sends over the radio while it runs, for the link budget.

    Attributes:
        message: The message's name in the link budget (``picture_data``).
        interval_s: Shortest time between two of them.
        to: Agents it goes to; every agent when empty.
    """

    message: str
    interval_s: float
    to: tuple[str, ...] = ()


class DrivenChannel(NamedTuple):
    """The control channel a behaviour drives, as the dry run records it.

    Attributes:
        name: The channel's name.
        via: ``rc_override`` or ``servo``.
        number: The RC input (rc_override) or servo output (servo) it drives.
    """

    name: str
    via: str
    number: int | None

    @property
    def label(self) -> str:
        """How recordings name it: ``rc2``, ``servo9``."""
        return f"rc{self.number}" if self.via == "rc_override" else f"servo{self.number}"


#: Traits of a state that runs no behaviour (or one this engine does not know).
NO_TRAITS = Traits()

CheckFn = Callable[[UseContext], Iterable[Finding]]
EventsFn = Callable[[Mapping[str, Any]], frozenset[str]]
CompileFn = Callable[[dict[str, Any], CompileContext], dict[str, Any]]
PlanFn = Callable[[Mapping[str, Any]], Plan]
SendsFn = Callable[[Mapping[str, Any], Any], Sequence[Sends]]
SignalFn = Callable[[Any, float], list[int]]
WaveformFn = Callable[[Any, float], float]


def _no_checks(_ctx: UseContext) -> Iterable[Finding]:
    return ()


def _as_written(params: dict[str, Any], _ctx: CompileContext) -> dict[str, Any]:
    return params


def _no_plan(_params: Mapping[str, Any]) -> Plan:
    return Plan()


def _sends_nothing(_params: Mapping[str, Any], _agent: Any) -> Sequence[Sends]:
    return ()


def raises_done(_params: Mapping[str, Any]) -> frozenset[str]:
    """For behaviours that always finish."""
    return frozenset({"done"})


def raises_nothing(_params: Mapping[str, Any]) -> frozenset[str]:
    """For behaviours that run until a transition moves the machine on."""
    return frozenset()


class Behavior(NamedTuple):
    """The declaration of one behaviour: everything the engine knows about it.

    Attributes:
        name: What a mission writes after ``use:``.
        summary: One sentence for the language reference, ``clark behaviors`` and
            ``clark explain``.
        parameters: Its typed parameters (the one definition of them).
        runtime: Its runtime class (built from the typed parameters when a config loads).
        events: Events it raises, given its parameters (``done`` when it finishes;
            nothing when it runs until something else moves on).
        needs_autopilot: Only vehicles may use it (the station has no autopilot).
        traits: What checks, dry run, report and station need to know of it.
        check: Pre-flight checks that need the mission and the agent's hardware.
        compile: Resolves its parameters for one agent (defaults already filled in);
            parameters it does not touch are compiled as written.
        plan: Its planned points, from its parameters (mission or compiled form).
        signal: The pulse widths it must command at a loop rate, one per tick, from
            its typed parameters (computed from its definition, independently of
            its runtime class, so that the dry run's checks compare the two); None
            when it drives no channel.
        waveform: The continuous signal it stands for, pulse width from trim at a
            time into the state (before clamping), when its samples can match it
            tick by tick and still lose it (a sweep near the Nyquist limit); from its
            typed parameters.
        sends: The messages it sends while it runs, from its parameters (mission form) and
            the agent that runs it (its hardware: a camera's footprint, a cruise speed).
        agent_params: The parameters that name another agent (compiled as ``{name, id}``);
            loading a config proves each names one of its peers.
        origin: ``built-in``, or the distribution of the plugin that provided it.
    """

    name: str
    summary: str
    parameters: type[Params]
    runtime: type[BehaviorRuntime]
    events: EventsFn
    needs_autopilot: bool = True
    traits: Traits = NO_TRAITS
    check: CheckFn = _no_checks
    compile: CompileFn = _as_written
    plan: PlanFn = _no_plan
    signal: SignalFn | None = None
    waveform: WaveformFn | None = None
    sends: SendsFn = _sends_nothing
    agent_params: tuple[str, ...] = ()
    origin: str = "built-in"

    @property
    def schema(self) -> Schema:
        """JSON Schema of the ``with:`` mapping (the mission side)."""
        return self.parameters.schema()

    def config_params(self) -> Schema:
        """JSON Schema of the parameters in a compiled agent config."""
        return self.parameters.config_schema()

    def with_defaults(self, given: Mapping[str, Any]) -> dict[str, Any]:
        """The parameters with every declared default filled in, in declared order."""
        return self.parameters.with_defaults(given)

    def driven_channel(self, compiled: Mapping[str, Any]) -> DrivenChannel | None:
        """The channel it drives, from a compiled state's parameters; None when none.

        A behaviour with the ``drives_channel`` trait has typed ``channel`` (a
        :class:`~clark_engine.behaviors.base.ChannelMap`) and ``via`` parameters.
        """
        if not self.traits.drives_channel:
            return None
        typed = self.parameters.from_config(compiled)
        channel, via = getattr(typed, "channel"), str(getattr(typed, "via"))  # noqa: B009
        number = channel.rc if via == "rc_override" else channel.servo
        return DrivenChannel(channel.name, via, number)
