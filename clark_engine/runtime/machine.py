"""One agent's behaviour as a hierarchical state machine (transitions' HierarchicalMachine).

The compiled behaviour (:class:`~clark_engine.runtime.config.StateSpec`, a tree of
states) becomes one ``transitions`` HierarchicalMachine per agent. The library's
state (its model's ``state``) is the one record of the active configuration: what
:meth:`BehaviorMachine.active_paths` says, what a guard checks and what completion
reads all come from it, and only the library changes it, in its own transitions.
The library decides what a transition leaves and enters (parent delegation,
nesting, parallel regions, local and external transitions); this module adds
what a flying behaviour needs on top of it, through the library's extension points
(its state, transition and machine classes, callbacks and conditions), and keeps
the per-tick work out of the library, which only runs on events:

- **Primitives.** Entering a state that ``use:`` s a primitive builds a fresh
  instance (``make_primitive``) and calls its ``start``; leaving it calls ``stop``.
  :meth:`BehaviorMachine.step` updates every active primitive once per tick.
- **Scoped events.** ``done`` and ``timeout`` belong to one state: the library
  sees them as internal triggers named ``done@<path>`` / ``timeout@<path>``
  whose only source is that state, so a child finishing never fires its
  parent's ``done`` and a parent's timer never moves a child. External events
  (``activate``, ``mode:AUTO``, ``lost:slash_a``...) keep their plain names and
  are taken by the innermost active state that has a transition on them.
- **Completion.** A machine whose active child is ``final`` raises ``done`` on
  itself; a parallel state raises ``done`` when all (``finish: all``) or any
  (``finish: any``) of its regions finished. This propagates upward in the
  same call, innermost first.

Timing rules (what makes a doublet's PWM exactly defined per tick):

- A state entered at any moment (during :meth:`~BehaviorMachine.start`, a
  :meth:`~BehaviorMachine.dispatch` or a :meth:`~BehaviorMachine.step`) has its
  primitive started at once and first updated by the *next* ``step`` call, never
  by the step that entered it. The runtime dispatches a tick's events before it
  steps, so a state entered by an event (``activate``) is updated in that same
  tick, and a state entered by a ``done`` or ``timeout`` from the following tick
  on. Either way each primitive is updated exactly once per step from its first
  update until its state is left, and never before ``start``.
- ``timeout_s`` counts on the runtime clock (``ctx.now_s``) from the entry of
  its own state; the timer fires once per entry, at the first ``step`` whose
  ``now_s`` reaches the deadline (1 ns tolerance, so tick times like ``0.1 * k``
  fire on the intended tick).
- One ``step`` runs: timeouts (innermost state first), then the update of every
  active primitive, then the ``done`` of the primitives that finished (in update
  order), each followed by completion. Every event is processed to the end,
  including the ``done`` of parents it causes, before the next one.

Re-entry: a transition to its own source state, or to an ancestor of it, is
*external*: the states are left (primitives stopped) and entered again
(fresh primitives, timers restarted, initial children again). A transition
from a state to one of its own descendants is *local* (the library's
semantics): the state itself stays active and its timer keeps counting; only
its active children are left. A transition to a state deep inside a parallel
state enters the other regions at their initial states too, in the same
transition of the library (:class:`_Transition`), so its state never lacks them.

A primitive that raises: ``make_primitive`` or ``start`` raising (the state's entry)
fails the state as a primitive returning FAILED does (reported as a ``failed`` change
right after the transition's own, never updated, stopped when left), and the
transition completes; ``stop`` raising (the state's exit, or :meth:`BehaviorMachine.stop`)
is logged and the state is left all the same. ``update``, ``on_payload`` or
``on_mission`` raising (a state already active) fails that state the same way, logged
once, and the other states are updated and handed the event as usual. Either way the
library's state and the primitives stay in step, and the agent's tick goes on: its
failsafes, heartbeats and station link run only while the tick does.

Two agents in one process share nothing: the separator ``"."`` is set on a
private NestedState subclass, never on transitions' own class, and every
machine has its own model object.
"""

from __future__ import annotations

import logging
from collections import OrderedDict
from collections.abc import Callable, Mapping
from dataclasses import dataclass
from functools import partial
from typing import Any

from transitions.extensions import HierarchicalMachine
from transitions.extensions.nesting import NestedEventData, NestedState, NestedTransition

from clark_engine.behaviors.base import BehaviorRuntime as Primitive
from clark_engine.runtime.config import ConfigError, StateSpec, TransitionSpec
from clark_engine.runtime.context import PrimitiveContext, Status
from clark_engine.runtime.events import MissionProgress, MissionUploadResult, PayloadEvent
from clark_engine.runtime.log_events import LogEvent

_LOGGER = logging.getLogger(__name__)

#: Events the machine raises itself, scoped to the state they belong to.
SCOPED_EVENTS = frozenset({"done", "timeout"})
#: Tolerance on timeout deadlines: float tick times (0.1 * k) must fire on their tick.
_DEADLINE_EPS_S = 1e-9
#: Names of the two top states in the library: before start, and the behaviour itself.
_IDLE = "idle"
_ROOT = "root"
_START_TRIGGER = "start@"

#: The library's record of a configuration: state names to their active children.
StateTree = OrderedDict[str, Any]

#: Builds the primitive of a state; called once per entry of the state.
MakePrimitive = Callable[[StateSpec], Primitive]
#: Decides a transition's ``when``: (condition, context, seconds since the source
#: state was entered) -> whether it holds.
Evaluate = Callable[[Mapping[str, Any], PrimitiveContext, float], bool]
#: A transition's ``when`` resolved once, when the machine is built: (context, seconds
#: since the source state was entered) -> whether it holds.
Holds = Callable[[PrimitiveContext, float], bool]
#: Resolves a ``when`` into its :data:`Holds` (the runtime's; nothing read by string then).
Resolve = Callable[[Mapping[str, Any]], Holds]


@dataclass(frozen=True, slots=True)
class StateChange:
    """One change of the active states, as the runtime logs it and reports it to the station.

    Attributes:
        time_s: Runtime clock (``ctx.now_s``) when it happened.
        event: Plain event name (``done``, ``timeout``, ``activate``, ``mode:AUTO``...);
            ``start`` for the initial entry; ``failed`` when a primitive reported
            FAILED (nothing exited or entered then).
        source: Path of the state whose transition was taken (``""`` is the root,
            for ``start``); for ``failed``, the state whose primitive failed.
        target: Path the transition names (the same as ``source`` for ``failed``).
        exited: Paths left, innermost first.
        entered: Paths entered, outermost first.
        active: Active leaf paths afterwards (:meth:`BehaviorMachine.active_paths`).
    """

    time_s: float
    event: str
    source: str
    target: str
    exited: tuple[str, ...]
    entered: tuple[str, ...]
    active: tuple[str, ...]


class _State(NestedState):
    """The library's nested state with this engine's separator, without touching the library.

    Setting ``NestedState.separator`` would change every machine in the process
    (the cautionary tale of class-level configuration); a subclass keeps it ours.
    """

    separator = "."


class _Transition(NestedTransition):
    """The library's nested transition, entering every region of a parallel state it enters.

    transitions enters only the path a deep target names (``survey.photos.later``);
    a parallel state runs all its regions, so this class adds the others, at their
    initial states, to the same transition: to the configuration the library then
    records, and to the entries it then calls, after those of the named path. The
    library's state is therefore complete at every moment, with nothing to re-sync.
    """

    def _resolve_transition(
        self, event_data: NestedEventData
    ) -> tuple[StateTree, list[Callable[[], None]], list[Callable[[], Any]]]:
        state_tree, exit_partials, enter_partials = super()._resolve_transition(event_data)
        machine = event_data.machine
        if isinstance(machine, _Machine) and machine.owner is not None and self.dest:
            machine.owner._complete_regions(self.dest, state_tree, enter_partials, event_data)
        return state_tree, exit_partials, enter_partials


class _Machine(HierarchicalMachine):
    """HierarchicalMachine building :class:`_State` and :class:`_Transition`.

    Attributes:
        owner: The behaviour machine whose states these are (for :class:`_Transition`).
    """

    state_cls = _State
    transition_cls = _Transition
    owner: BehaviorMachine | None = None


class _Model:
    """The object the library keeps the current state on (``state``) and binds triggers to.

    One per :class:`BehaviorMachine`, so two agents never share one. Its ``state`` is
    the active configuration: a library name (``root.<path>``), or a list of them (nested
    for parallel states), of the active leaf states; ``idle`` before the start.
    """

    state: str | list[Any]


class _Node:
    """One state of the behaviour with its run-time bookkeeping.

    Whether it is active is not part of it: that is the library's state, read
    through :meth:`BehaviorMachine._active`.

    Attributes:
        spec: The compiled state.
        path: Its dotted path (``""`` for the root).
        name: Its name in the library (``root.<path>``).
        parent: The enclosing state, None for the root.
        children: Child states in document order.
        depth: 0 at the root.
        order: Index in document order (parents first), to break ties deterministically.
        state: The library's state object for it.
        entered_s: Clock at its last entry.
        finished: Whether it finished (primitive done, final reached, regions finished).
        first_step: Index of the first step that updates the primitive.
        running: Whether the primitive is still updated (not yet done or failed).
        deadline_s: When the timeout fires, None when it is not armed.
        events: Trigger names of this state's transitions.
    """

    __slots__ = (
        "children",
        "deadline_s",
        "depth",
        "entered_s",
        "events",
        "finished",
        "first_step",
        "name",
        "order",
        "parent",
        "path",
        "running",
        "spec",
        "state",
    )

    def __init__(self, spec: StateSpec, parent: _Node | None, order: int) -> None:
        self.spec = spec
        self.path = spec.path
        self.name = _hsm_name(spec.path)
        self.parent = parent
        self.children: list[_Node] = []
        self.depth: int = 0 if parent is None else parent.depth + 1
        self.order = order
        self.state: _State | None = None
        self.entered_s = 0.0
        self.finished = False
        self.first_step = 0
        self.running = False
        self.deadline_s: float | None = None
        self.events: set[str] = set()

    def trigger(self, event: str) -> str:
        """The library's trigger name for an event of this state."""
        return f"{event}@{self.path}" if event in SCOPED_EVENTS else event


def _hsm_name(path: str) -> str:
    return f"{_ROOT}.{path}" if path else _ROOT


class BehaviorMachine:
    """The behaviour of one agent: its states, their primitives and the events that move it.

    Not thread-safe and not re-entrant: call it from the agent's loop only, and
    never from inside a primitive or a callback it calls.

    Args:
        spec: The root state of the compiled behaviour (a machine, a parallel
            state or a single primitive).
        make_primitive: Builds a fresh primitive for a state; called on every entry.
        evaluate: Decides a transition's ``when`` condition, given the condition,
            the context and the seconds since the transition's source state (the
            state the transition is written on) was entered, for ``in_state_s``.
        on_change: Called after every change of the active states (and when a
            primitive fails), with what changed.
        resolve: Resolves each transition's ``when`` once, as the machine is built,
            into what decides it each time (the runtime's); ``evaluate`` is then never
            called. None: ``evaluate`` decides the condition as written.

    Raises:
        ConfigError: A machine state without ``initial``, or a transition whose
            target is not a state of this behaviour (a config edited by hand).
    """

    def __init__(
        self,
        spec: StateSpec,
        make_primitive: MakePrimitive,
        evaluate: Evaluate,
        on_change: Callable[[StateChange], None] | None = None,
        *,
        resolve: Resolve | None = None,
    ) -> None:
        self._make_primitive = make_primitive
        self._evaluate = evaluate
        self._resolve = resolve
        self._on_change = on_change
        self._nodes: dict[str, _Node] = {}
        self._root = self._build_nodes(spec, None)
        # run-time state
        self._started = False
        self._stopped = False
        self._step_index = 0
        self._last_event = ""
        self._event = ""
        self._taken = 0
        # Read from the library's state when a change made them stale (None).
        self._active_nodes: frozenset[_Node] | None = frozenset()
        self._paths: tuple[str, ...] | None = ()
        self._primitives: dict[_Node, Primitive] = {}  # active states' primitives, entry order
        self._timed: dict[_Node, None] = {}  # active states with an armed timeout
        self._pending: dict[_Node, None] = {}  # states whose completion must be checked
        # Completions left for the next step: a state that finished once already in one
        # call (a cycle of states that finish as they are entered) goes on a step later.
        self._deferred: dict[_Node, None] = {}
        self._broken: list[_Node] = []  # entered states whose primitive raised, to report
        self._exited: list[str] = []
        self._entered: list[str] = []
        self._by_name = {node.name: node for node in self._nodes.values()}
        self._model = _Model()
        self._machine = _Machine(
            model=self._model,
            states=[_State(_IDLE), self._build_state(self._root)],
            initial=_IDLE,
            auto_transitions=False,
            ignore_invalid_triggers=True,
            send_event=False,
        )
        self._machine.owner = self
        self._machine.add_transition(
            _START_TRIGGER, _IDLE, _ROOT, after=[partial(self._after, self._root, None)]
        )
        for node in self._nodes.values():
            for transition in node.spec.transitions:
                self._add_transition(node, transition)

    # -- building -----------------------------------------------------------------------

    def _build_nodes(self, spec: StateSpec, parent: _Node | None) -> _Node:
        node = _Node(spec, parent, len(self._nodes))
        self._nodes[spec.path] = node
        node.children = [self._build_nodes(child, node) for child in spec.states]
        names = {child.spec.name for child in node.children}
        if names and not spec.parallel and spec.initial not in names:
            raise ConfigError(
                f"behaviour state {spec.path or '(root)'} has no valid initial child "
                f"({spec.initial!r}); compile the mission again with clark compile",
                path=spec.path,
            )
        return node

    def _build_state(self, node: _Node) -> _State:
        state = _State(
            node.spec.name if node.parent is not None else _ROOT,
            on_enter=[partial(self._on_enter, node)],
            on_exit=[partial(self._on_exit, node)],
        )
        node.state = state
        if node.children:
            names = [child.spec.name for child in node.children]
            # A list of initial children is how the library writes parallel regions.
            state.initial = names if node.spec.parallel else node.spec.initial  # type: ignore[assignment]
            state.add_substates([self._build_state(child) for child in node.children])
        return state

    def _add_transition(self, node: _Node, transition: TransitionSpec) -> None:
        if transition.target not in self._nodes:
            raise ConfigError(
                f"behaviour state {node.path or '(root)'}: on {transition.event}, no state "
                f"{transition.target!r}; compile the mission again with clark compile",
                path=node.path,
            )
        trigger = node.trigger(transition.event)
        node.events.add(trigger)
        # First condition: the source is still active. One event may move several
        # parallel regions; the library walks a list of states made before the
        # first move, so a region that move already left must not move again.
        conditions: list[str | Callable[..., bool | None]] = [partial(self._is_active, node)]
        if transition.when is not None:
            if self._resolve is not None:
                conditions.append(partial(_resolved_holds, node, self._resolve(transition.when)))
            else:
                conditions.append(partial(self._holds, node, transition.when))
        self._machine.add_transition(
            trigger,
            node.name,
            _hsm_name(transition.target),
            conditions=conditions,
            after=[partial(self._after, node, transition)],
        )

    # -- public -------------------------------------------------------------------------

    @property
    def last_event(self) -> str:
        """The event of the last change (``""`` before :meth:`start`, then ``start``...)."""
        return self._last_event

    @property
    def running(self) -> bool:
        """Started and not stopped."""
        return self._started and not self._stopped

    def start(self, ctx: PrimitiveContext) -> None:
        """Enter the initial configuration and start the primitives of the states entered.

        Enters the root, each machine's initial child and every region of parallel
        states, outermost first, and reports it as one change with event ``start``.
        The primitives are first updated by the next :meth:`step`.

        Raises:
            RuntimeError: Called twice (a bug in the caller).
        """
        if self._started:
            raise RuntimeError("BehaviorMachine.start called twice")
        self._started = True
        self._fire(_START_TRIGGER, "start", ctx)
        self._settle(ctx)

    def dispatch(self, event: str, ctx: PrimitiveContext) -> bool:
        """Apply an external event (``activate``, ``mode:AUTO``, ``rc:8:high``, ``lost:x``...).

        The innermost active state with a transition on ``event`` takes it; its
        guarded transitions are tried in order and the first whose ``when`` holds
        is taken; when none holds, the event goes on to the enclosing states. In
        parallel states each region may take it (innermost first), unless an
        earlier transition already left that region. ``done`` and ``timeout`` are
        raised by the machine itself and are ignored here, as are events no active
        state handles.

        Returns:
            Whether a transition was taken.
        """
        if not self.running or not any(
            event in node.events for node in self._active() if node.events
        ):
            return False
        taken = self._fire(event, event, ctx)
        self._settle(ctx)
        return taken

    def step(self, ctx: PrimitiveContext) -> None:
        """Run one tick: timeouts, then every active primitive's update, then completions.

        A primitive that returns DONE raises ``done`` on its state; one that returns
        FAILED is no longer updated and is reported through ``on_change`` (event
        ``failed``), without an event. Primitives of states entered during this
        call are first updated by the next one.
        """
        if not self.running:
            return
        self._step_index += 1
        if self._deferred:
            self._pending.update(self._deferred)
            self._deferred.clear()
        if self._timed:
            self._timeouts(ctx)
        finished: list[tuple[_Node, Primitive]] | None = None
        index = self._step_index
        for node, primitive in self._primitives.items():
            if not node.running or node.first_step > index:
                continue
            try:
                status = primitive.update(ctx)
            except Exception as exc:
                self._log_raised(node, "raised in update", "the state fails", exc, ctx)
                status = Status.FAILED
            if status is Status.RUNNING:
                continue
            node.running = False
            if status is Status.DONE:
                if finished is None:
                    finished = []
                finished.append((node, primitive))
            else:
                self._failed(node, ctx)
        if finished is not None:
            for node, primitive in finished:
                # Skip a state an earlier done left (or left and entered again).
                if self._primitives.get(node) is primitive:
                    self._finish(node, ctx)
        if self._pending:
            self._settle(ctx)

    def stop(self, ctx: PrimitiveContext) -> None:
        """Stop every active primitive, innermost first, and stop the machine.

        For terminate and failsafes: the active states stay as they were (so
        :meth:`active_paths` still says where the behaviour stopped), but nothing
        is updated or dispatched any more.
        """
        if not self.running:
            return
        self._stopped = True
        for node in sorted(self._primitives, key=_innermost_first):
            node.running = False
            self._stop_primitive(node, self._primitives[node], ctx)

    def deliver_payload(self, ctx: PrimitiveContext, event: PayloadEvent) -> None:
        """Hand a payload event to the primitive of every active state, in entry order."""
        if not self.running:
            return
        for node, primitive in list(self._primitives.items()):
            try:
                primitive.on_payload(ctx, event)
            except Exception as exc:
                self._handler_raised(node, "raised in on_payload", exc, ctx)

    def deliver_mission(
        self, ctx: PrimitiveContext, event: MissionUploadResult | MissionProgress
    ) -> None:
        """Hand a mission event to the primitive of every active state, in entry order."""
        if not self.running:
            return
        for node, primitive in list(self._primitives.items()):
            try:
                primitive.on_mission(ctx, event)
            except Exception as exc:
                self._handler_raised(node, "raised in on_mission", exc, ctx)

    def _handler_raised(
        self, node: _Node, what: str, exc: Exception, ctx: PrimitiveContext
    ) -> None:
        """A primitive raised while handed an event: its state fails, if it still ran."""
        if not node.running:
            self._log_raised(node, what, "its state had already stopped", exc, ctx)
            return
        self._log_raised(node, what, "the state fails", exc, ctx)
        node.running = False
        self._failed(node, ctx)

    def active_paths(self) -> tuple[str, ...]:
        """Dotted paths of the active leaf states, sorted (``("",)`` for a one-primitive root).

        Read from the library's state (cached until the next change).
        """
        if self._paths is None:
            self._paths = tuple(sorted(n.path for n in self._active() if not n.children))
        return self._paths

    def active_states(self) -> tuple[str, ...]:
        """Dotted paths of every active state, ancestors included, sorted (root ``""`` first)."""
        return tuple(sorted(n.path for n in self._active()))

    def _active(self) -> frozenset[_Node]:
        """The active states, ancestors included: the library's state, read once per change.

        Only the library changes its state, in a transition, between the exit callbacks
        and the entry callbacks; both mark this stale, and nothing reads it in between.
        """
        active = self._active_nodes
        if active is None:
            found: set[_Node] = set()
            for name in _flat(self._model.state):
                node = self._by_name.get(name)  # None for idle, before the start
                while node is not None and node not in found:
                    found.add(node)
                    node = node.parent
            active = self._active_nodes = frozenset(found)
        return active

    def _is_active(self, node: _Node, ctx: PrimitiveContext) -> bool:
        """A transition's first condition: its source is active in the library's state.

        One event may move several parallel regions; the library walks a list of states
        made before the first move, so a region that move already left must not move again.
        """
        return node in self._active()

    # -- events -------------------------------------------------------------------------

    def _fire(self, trigger: str, event: str, ctx: PrimitiveContext) -> bool:
        """Run one trigger through the library; True when it took a transition."""
        self._event = event
        before = self._taken
        self._machine.trigger_event(self._model, trigger, ctx)
        return self._taken > before

    def _holds(self, node: _Node, when: Mapping[str, Any], ctx: PrimitiveContext) -> bool:
        return self._evaluate(when, ctx, ctx.now_s - node.entered_s)

    def _after(self, node: _Node, transition: TransitionSpec | None, ctx: PrimitiveContext) -> None:
        """After each transition: report the change, then the primitives that raised on entry."""
        change = StateChange(
            time_s=ctx.now_s,
            event=self._event,
            source=node.path,
            target=transition.target if transition is not None else node.path,
            exited=tuple(self._exited),
            entered=tuple(self._entered),
            active=self.active_paths(),
        )
        self._exited.clear()
        self._entered.clear()
        self._taken += 1
        self._last_event = self._event
        if self._on_change is not None:
            self._on_change(change)
        if self._broken:
            broken, self._broken = self._broken, []
            for failed in broken:
                self._failed(failed, ctx)

    def _complete_regions(
        self,
        dest: str,
        state_tree: StateTree,
        enter_partials: list[Callable[[], Any]],
        event_data: NestedEventData,
    ) -> None:
        """Add the regions the library left out of the parallel states a deep target enters.

        Called by :class:`_Transition` while the library resolves a transition, before it
        records the new configuration: for each parallel state on the path to ``dest``
        (outermost first), the regions missing from ``state_tree`` are added at their
        initial states, and their entries appended to ``enter_partials``. The regions
        keep document order in the tree, so the library takes an event region by region
        in that order, as it does in a parallel state it entered whole.
        """
        level = state_tree
        scope: list[str] = []
        for name in dest.split(self._machine.state_cls.separator):
            subtree = level.get(name)
            if subtree is None:
                return
            scope.append(name)
            node = self._by_name[".".join(scope)]
            if node.spec.parallel and len(subtree) < len(node.children):
                for region in node.children:
                    if region.spec.name not in subtree:
                        subtree[region.spec.name] = OrderedDict()
                        self._enter_default(
                            region, subtree[region.spec.name], scope, enter_partials, event_data
                        )
                ordered = [(child.spec.name, subtree[child.spec.name]) for child in node.children]
                subtree.clear()
                subtree.update(ordered)
            level = subtree

    def _enter_default(
        self,
        node: _Node,
        subtree: StateTree,
        scope: list[str],
        enter_partials: list[Callable[[], Any]],
        event_data: NestedEventData,
    ) -> None:
        """Add a state and its default descendants (initial child, or every region), depth first."""
        assert node.state is not None
        enter_partials.append(partial(node.state.scoped_enter, event_data, list(scope)))
        inner = [*scope, node.spec.name]
        if node.spec.parallel:
            children = node.children
        elif node.children:
            children = [next(c for c in node.children if c.spec.name == node.spec.initial)]
        else:
            return
        for child in children:
            subtree[child.spec.name] = OrderedDict()
            self._enter_default(child, subtree[child.spec.name], inner, enter_partials, event_data)

    # -- entering and leaving -----------------------------------------------------------

    def _on_enter(self, node: _Node, ctx: PrimitiveContext) -> None:
        node.entered_s = ctx.now_s
        node.finished = node.spec.final
        self._active_nodes = None
        self._paths = None
        self._entered.append(node.path)
        parent = node.parent
        if parent is not None:
            parent.finished = False
            self._pending[parent] = None
        if node.spec.timeout_s is not None and node.trigger("timeout") in node.events:
            node.deadline_s = ctx.now_s + node.spec.timeout_s
            self._timed[node] = None
        if node.spec.primitive is not None:
            node.first_step = self._step_index + 1
            node.running = True
            try:
                primitive = self._make_primitive(node.spec)
            except Exception as exc:
                self._raised(node, "could not be built", exc, ctx)
                return
            self._primitives[node] = primitive
            try:
                primitive.start(ctx)
            except Exception as exc:
                self._raised(node, "raised in start", exc, ctx)

    def _raised(self, node: _Node, what: str, exc: Exception, ctx: PrimitiveContext) -> None:
        """A primitive raised while its state was entered: the state stays, its primitive failed.

        Called from inside the library's transition, so the failure is reported after it
        (:meth:`_after`), never by raising through it: the library would keep a half-made
        configuration, and the agent's tick would stop. The mission log gets one line
        (``behavior.error``); the traceback, for whoever fixes the primitive, goes to
        this module's logger.
        """
        self._log_raised(node, what, "the state fails", exc, ctx)
        node.running = False
        self._broken.append(node)

    def _log_raised(
        self, node: _Node, what: str, outcome: str, exc: Exception, ctx: PrimitiveContext
    ) -> None:
        state = node.path or "(root)"
        ctx.log.error(
            "primitive %s of state %s %s: %s: %s; %s",
            node.spec.primitive,
            state,
            what,
            type(exc).__name__,
            exc,
            outcome,
            extra=LogEvent.BEHAVIOR_ERROR.extra,
        )
        _LOGGER.debug("primitive %s of state %s %s", node.spec.primitive, state, what, exc_info=exc)

    def _on_exit(self, node: _Node, ctx: PrimitiveContext) -> None:
        self._active_nodes = None
        self._paths = None
        self._timed.pop(node, None)
        self._pending.pop(node, None)
        self._deferred.pop(node, None)
        self._exited.append(node.path)
        node.deadline_s = None
        primitive = self._primitives.pop(node, None)
        if primitive is not None:
            node.running = False
            self._stop_primitive(node, primitive, ctx)

    def _stop_primitive(self, node: _Node, primitive: Primitive, ctx: PrimitiveContext) -> None:
        """Stop a primitive; one that raises is logged and its state left all the same."""
        try:
            primitive.stop(ctx)
        except Exception as exc:
            self._log_raised(node, "raised in stop", "it is stopped all the same", exc, ctx)

    # -- per tick -----------------------------------------------------------------------

    def _timeouts(self, ctx: PrimitiveContext) -> None:
        now = ctx.now_s + _DEADLINE_EPS_S
        expired = [n for n in self._timed if n.deadline_s is not None and now >= n.deadline_s]
        if not expired:
            return
        expired.sort(key=_innermost_first)
        for node in expired:
            deadline = node.deadline_s
            if deadline is None or now < deadline:
                continue  # left, or left and entered again, by an earlier timeout
            del self._timed[node]  # a timer fires once per entry
            node.deadline_s = None
            self._fire(node.trigger("timeout"), "timeout", ctx)
            self._settle(ctx)

    def _failed(self, node: _Node, ctx: PrimitiveContext) -> None:
        self._last_event = "failed"
        if self._on_change is None:
            _LOGGER.warning("primitive %s of state %s failed", node.spec.primitive, node.path)
        else:
            self._on_change(
                StateChange(ctx.now_s, "failed", node.path, node.path, (), (), self.active_paths())
            )

    def _finish(self, node: _Node, ctx: PrimitiveContext) -> None:
        """Mark a state finished and raise its ``done``."""
        node.finished = True
        if node.parent is not None:
            self._pending[node.parent] = None
        trigger = node.trigger("done")
        if trigger in node.events:
            self._fire(trigger, "done", ctx)

    def _settle(self, ctx: PrimitiveContext) -> None:
        """Raise ``done`` on every machine or parallel state that has finished, innermost first.

        A state finishes at most once per call: one that finishes again (states whose
        ``done`` transitions lead round to states that finish as they are entered) is
        left for the next step (:attr:`_deferred`), so the call always returns and such
        a cycle goes round one lap per tick, never holding up the agent's loop.
        """
        pending = self._pending
        completed: set[_Node] = set()
        while pending:
            node = min(pending, key=_innermost_first)
            del pending[node]
            active = self._active()
            if node not in active or node.finished or not node.children:
                continue
            if node.spec.parallel:
                if node.spec.finish == "any":
                    complete = any(region.finished for region in node.children)
                else:
                    complete = all(region.finished for region in node.children)
            else:
                child = next((c for c in node.children if c in active), None)
                complete = child is not None and child.spec.final
            if not complete:
                continue
            if node in completed:
                self._deferred[node] = None
                continue
            completed.add(node)
            self._finish(node, ctx)


def _resolved_holds(node: _Node, holds: Holds, ctx: PrimitiveContext) -> bool:
    return holds(ctx, ctx.now_s - node.entered_s)


def _innermost_first(node: _Node) -> tuple[int, int]:
    return (-node.depth, node.order)


def _flat(state: str | list[Any]) -> list[str]:
    """The library's state (a name, or nested lists of names) as a flat list of names."""
    if isinstance(state, str):
        return [state]
    return [name for item in state for name in _flat(item)]
