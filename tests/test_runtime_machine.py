"""The behaviour state machine: entry, scoped done/timeout, completion, events, isolation.

Everything runs on a virtual clock (``ctx.now_s`` set by the test) with fake
primitives that record their calls, so each test states exactly which tick
does what.
"""

from __future__ import annotations

import logging
from collections.abc import Callable, Mapping
from pathlib import Path
from typing import Any

import pytest
from transitions.extensions import HierarchicalMachine
from transitions.extensions.nesting import NestedState

from clark_engine.behaviors.base import BehaviorRuntime as Primitive
from clark_engine.link.fleet import FleetTable
from clark_engine.mission.compiler import agent_config
from clark_engine.mission.validate import validate_path
from clark_engine.runtime.config import (
    AgentConfig,
    ConfigError,
    StateSpec,
    TransitionSpec,
    config_from_dict,
)
from clark_engine.runtime.context import PrimitiveContext, Status
from clark_engine.runtime.events import PayloadEvent
from clark_engine.runtime.machine import BehaviorMachine, StateChange

ROOT = Path(__file__).resolve().parent.parent

# -- building specs ------------------------------------------------------------------------


def spec(tree: Mapping[str, Any], path: str = "") -> StateSpec:
    """A StateSpec from a compact dict, the way the compiler shapes it.

    Keys: use (primitive name), with (params), initial, states, parallel, finish,
    final, timeout_s, on: {event: target | [(target, when), ...]} with full paths.
    """
    children = tuple(
        spec(child, f"{path}.{name}" if path else name)
        for name, child in (tree.get("states") or {}).items()
    )
    transitions: list[TransitionSpec] = []
    for event, targets in (tree.get("on") or {}).items():
        if isinstance(targets, str):
            targets = [(targets, None)]
        for target, when in targets:
            transitions.append(TransitionSpec(event, target, when, "test"))
    primitive = tree.get("use")
    kind = (
        "primitive"
        if primitive
        else ("parallel" if tree.get("parallel") else "machine")
        if children
        else "final"
    )
    return StateSpec(
        name=path.rsplit(".", 1)[-1],
        path=path,
        kind=kind,
        primitive=primitive,
        params=tree.get("with") or {},
        block=None,
        initial=tree.get("initial"),
        parallel=bool(tree.get("parallel")),
        finish=tree.get("finish", "all"),
        final=bool(tree.get("final")),
        timeout_s=tree.get("timeout_s"),
        transitions=tuple(transitions),
        source="test",
        states=children,
    )


def leaf(
    updates: int | None = None, *, fail_after: int | None = None, **rest: Any
) -> dict[str, Any]:
    """A state running a fake primitive: DONE after ``updates`` updates (never when None)."""
    return {"use": "fake", "with": {"updates": updates, "fail_after": fail_after}, **rest}


# -- fakes ---------------------------------------------------------------------------------


class Fake(Primitive):
    """Records every call in a shared journal; DONE after N updates, FAILED after M."""

    name = "fake"

    def __init__(self, params: Mapping[str, Any], path: str, journal: list[tuple[Any, ...]]):
        super().__init__(params)
        self.path = path
        self.journal = journal
        self.updates = 0
        self.payloads: list[PayloadEvent] = []

    def start(self, ctx: PrimitiveContext) -> None:
        self.journal.append(("start", self.path, id(self), ctx.now_s))

    def update(self, ctx: PrimitiveContext) -> Status:
        self.updates += 1
        self.journal.append(("update", self.path, id(self), ctx.now_s))
        if self.params.get("fail_after") is not None and self.updates >= self.params["fail_after"]:
            return Status.FAILED
        if self.params.get("updates") is not None and self.updates >= self.params["updates"]:
            return Status.DONE
        return Status.RUNNING

    def stop(self, ctx: PrimitiveContext) -> None:
        self.journal.append(("stop", self.path, id(self), ctx.now_s))

    def on_payload(self, ctx: PrimitiveContext, event: PayloadEvent) -> None:
        self.payloads.append(event)


@pytest.fixture(scope="module")
def cub_config() -> AgentConfig:
    """The Super Cub's compiled config (its machine, and a config for the context)."""
    validation = validate_path(ROOT / "missions" / "supercub_sysid.yaml")
    assert validation.ok and validation.mission is not None
    mission = validation.mission
    return config_from_dict(agent_config(mission, mission.agents["cub"]))


class Harness:
    """One machine with a virtual clock, a journal of primitive calls and of changes."""

    def __init__(
        self,
        root: StateSpec,
        config: AgentConfig,
        done_after: Callable[[StateSpec], int | None] | None = None,
    ) -> None:
        self.done_after = done_after
        self.journal: list[tuple[Any, ...]] = []
        self.changes: list[StateChange] = []
        self.flags: dict[str, bool] = {}
        self.guards: list[tuple[Mapping[str, Any], float]] = []
        self.instances: list[Fake] = []
        self.ctx = PrimitiveContext(config, FleetTable(config.agent_id, config.mission_id, 3.0))
        self.machine = BehaviorMachine(root, self.make, self.evaluate, self.changes.append)

    def make(self, state: StateSpec) -> Primitive:
        params = state.params
        if self.done_after is not None:
            params = {"updates": self.done_after(state)}
        primitive = Fake(params, state.path, self.journal)
        self.instances.append(primitive)
        return primitive

    def evaluate(self, when: Mapping[str, Any], ctx: PrimitiveContext, in_state_s: float) -> bool:
        self.guards.append((when, in_state_s))
        if "flag" in when:
            return self.flags.get(when["flag"], False)
        if "in_state_s" in when:
            return bool(in_state_s > when["in_state_s"]["gt"])
        raise AssertionError(f"unexpected condition {when}")

    def at(self, now_s: float) -> PrimitiveContext:
        self.ctx.now_s = now_s
        return self.ctx

    def start(self, now_s: float = 0.0) -> Harness:
        self.machine.start(self.at(now_s))
        return self

    def step(self, now_s: float) -> None:
        self.machine.step(self.at(now_s))

    def dispatch(self, event: str, now_s: float) -> bool:
        return self.machine.dispatch(event, self.at(now_s))

    def calls(self, kind: str) -> list[str]:
        return [entry[1] for entry in self.journal if entry[0] == kind]

    def updates_at(self, now_s: float) -> list[str]:
        return [e[1] for e in self.journal if e[0] == "update" and e[3] == now_s]

    def check_library(self) -> None:
        """The library's record of the current states matches the machine's own."""
        state = self.machine._model.state  # type: ignore[attr-defined]

        def flat(value: Any) -> list[str]:
            return [s for v in value for s in flat(v)] if isinstance(value, list) else [value]

        names = sorted(flat(state))
        expected = sorted(f"root.{p}" if p else "root" for p in self.machine.active_paths())
        assert names == expected


def harness(tree: Mapping[str, Any], config: AgentConfig) -> Harness:
    return Harness(spec(tree), config)


# -- entry ---------------------------------------------------------------------------------


def test_start_enters_initial_children_recursively_and_every_region(
    cub_config: AgentConfig,
) -> None:
    h = harness(
        {
            "initial": "outer",
            "states": {
                "outer": {
                    "initial": "inner",
                    "states": {
                        "inner": {
                            "parallel": True,
                            "states": {
                                "left": {"initial": "l1", "states": {"l1": leaf(), "l2": leaf()}},
                                "right": leaf(),
                            },
                        },
                        "other": leaf(),
                    },
                },
                "elsewhere": leaf(),
            },
        },
        cub_config,
    ).start()
    m = h.machine
    assert m.active_paths() == ("outer.inner.left.l1", "outer.inner.right")
    assert m.active_states() == (
        "",
        "outer",
        "outer.inner",
        "outer.inner.left",
        "outer.inner.left.l1",
        "outer.inner.right",
    )
    assert h.calls("start") == ["outer.inner.right", "outer.inner.left.l1"]
    assert h.calls("update") == []  # first updates come with the first step
    (change,) = h.changes
    assert change.event == "start" and change.source == "" and change.target == ""
    assert change.exited == ()
    # outermost first: every state after its parent
    assert change.entered[:3] == ("", "outer", "outer.inner")
    assert set(change.entered) == set(m.active_states())
    assert change.active == m.active_paths()
    assert m.last_event == "start"
    h.check_library()


def test_root_may_be_a_single_primitive(cub_config: AgentConfig) -> None:
    h = harness(leaf(2), cub_config).start()
    assert h.machine.active_paths() == ("",)
    h.step(0.1)
    h.step(0.2)  # done, but the root has nowhere to go
    h.step(0.3)
    assert h.calls("update") == ["", ""]
    assert h.machine.active_paths() == ("",)
    assert h.calls("stop") == []


def test_first_update_is_on_the_step_after_entry(cub_config: AgentConfig) -> None:
    h = harness(
        {
            "initial": "a",
            "states": {
                "a": leaf(1, on={"done": "b", "activate": "c"}),
                "b": leaf(None, on={"activate": "c"}),
                "c": leaf(),
            },
        },
        cub_config,
    ).start()
    h.step(0.1)  # a updates once, is done; b entered during this step
    assert h.updates_at(0.1) == ["a"]
    assert h.machine.active_paths() == ("b",)
    h.step(0.2)
    assert h.updates_at(0.2) == ["b"]
    h.dispatch("activate", 0.25)  # entered between steps
    assert h.updates_at(0.25) == []
    h.step(0.3)
    assert h.updates_at(0.3) == ["c"]


# -- done and timeout belong to their state ------------------------------------------------


def test_done_of_a_child_does_not_fire_the_parents_done(cub_config: AgentConfig) -> None:
    h = harness(
        {
            "initial": "p",
            "states": {
                "p": {
                    "initial": "c1",
                    "on": {"done": "after"},
                    "states": {
                        "c1": leaf(1, on={"done": "p.c2"}),
                        "c2": leaf(None),
                    },
                },
                "after": leaf(),
            },
        },
        cub_config,
    ).start()
    h.step(0.1)
    assert h.machine.active_paths() == ("p.c2",)
    assert [(c.event, c.source, c.target) for c in h.changes[1:]] == [("done", "p.c1", "p.c2")]


def test_a_leaf_done_without_a_transition_is_ignored_and_not_updated_again(
    cub_config: AgentConfig,
) -> None:
    h = harness({"initial": "a", "states": {"a": leaf(1), "b": leaf()}}, cub_config).start()
    h.step(0.1)
    h.step(0.2)
    assert h.calls("update") == ["a"]
    assert h.machine.active_paths() == ("a",)
    assert len(h.changes) == 1


def test_timeouts_are_scoped_to_their_own_state(cub_config: AgentConfig) -> None:
    h = harness(
        {
            "initial": "p",
            "states": {
                "p": {
                    "initial": "c1",
                    "timeout_s": 1.0,
                    "on": {"timeout": "out"},
                    "states": {
                        "c1": leaf(timeout_s=0.3, on={"timeout": "p.c2"}),
                        "c2": leaf(timeout_s=0.3, on={"timeout": "p.c1"}),
                    },
                },
                "out": leaf(),
            },
        },
        cub_config,
    ).start()
    for k in range(1, 12):
        h.step(round(0.1 * k, 10))
    # the child timer restarts on each entry and never fires the parent's
    events = [(c.time_s, c.event, c.source, c.target) for c in h.changes[1:]]
    assert events == [
        (0.3, "timeout", "p.c1", "p.c2"),
        (0.6, "timeout", "p.c2", "p.c1"),
        (0.9, "timeout", "p.c1", "p.c2"),
        (1.0, "timeout", "p", "out"),  # the parent's own timer, counted from its entry
    ]
    assert h.machine.active_paths() == ("out",)


def test_a_parent_timeout_does_not_move_a_child_with_a_longer_timer(
    cub_config: AgentConfig,
) -> None:
    h = harness(
        {
            "initial": "p",
            "states": {
                "p": {
                    "initial": "c",
                    "timeout_s": 0.2,
                    "on": {"timeout": "p"},  # restart itself
                    "states": {"c": leaf(timeout_s=0.5, on={"timeout": "q"})},
                },
                "q": leaf(),
            },
        },
        cub_config,
    ).start()
    for k in range(1, 8):
        h.step(round(0.1 * k, 10))
    # p restarts at 0.2, 0.4, 0.6: c is re-entered each time, so its 0.5 s never elapse
    assert [c.source for c in h.changes[1:]] == ["p", "p", "p"]
    assert h.machine.active_paths() == ("p.c",)


def test_a_timer_fires_once_per_entry_even_when_its_guard_fails(cub_config: AgentConfig) -> None:
    h = harness(
        {
            "initial": "a",
            "states": {
                "a": leaf(timeout_s=0.2, on={"timeout": [("b", {"flag": "go"})]}),
                "b": leaf(),
            },
        },
        cub_config,
    ).start()
    h.step(0.1)
    h.step(0.2)
    h.flags["go"] = True
    h.step(0.3)
    assert h.machine.active_paths() == ("a",)
    assert len(h.guards) == 1


def test_inner_timeouts_fire_before_outer_ones_in_the_same_step(cub_config: AgentConfig) -> None:
    h = harness(
        {
            "initial": "p",
            "states": {
                "p": {
                    "initial": "c",
                    "timeout_s": 0.5,
                    "on": {"timeout": "out"},
                    "states": {"c": leaf(timeout_s=0.5, on={"timeout": "p.d"}), "d": leaf()},
                },
                "out": leaf(),
            },
        },
        cub_config,
    ).start()
    h.step(0.5)
    assert [(c.source, c.target) for c in h.changes[1:]] == [("p.c", "p.d"), ("p", "out")]


# -- completion ----------------------------------------------------------------------------


def test_parallel_finish_all_waits_for_every_region(cub_config: AgentConfig) -> None:
    h = harness(
        {
            "initial": "both",
            "states": {
                "both": {
                    "parallel": True,
                    "on": {"done": "after"},
                    "states": {"fast": leaf(1), "slow": leaf(3)},
                },
                "after": leaf(),
            },
        },
        cub_config,
    ).start()
    h.step(0.1)
    h.step(0.2)
    assert h.machine.active_paths() == ("both.fast", "both.slow")
    h.step(0.3)
    assert h.machine.active_paths() == ("after",)
    assert h.calls("update") == ["both.fast", "both.slow", "both.slow", "both.slow"]
    exited = h.changes[-1].exited
    assert sorted(exited[:2]) == ["both.fast", "both.slow"] and exited[2] == "both"
    h.check_library()


def test_parallel_finish_any_stops_the_other_regions(cub_config: AgentConfig) -> None:
    h = harness(
        {
            "initial": "survey",
            "states": {
                "survey": {
                    "parallel": True,
                    "finish": "any",
                    "on": {"done": "home"},
                    "states": {
                        "tour": leaf(2),
                        "photos": {"initial": "shoot", "states": {"shoot": leaf()}},
                    },
                },
                "home": leaf(),
            },
        },
        cub_config,
    ).start()
    h.step(0.1)
    h.step(0.2)
    assert h.machine.active_paths() == ("home",)
    assert sorted(h.calls("stop")) == ["survey.photos.shoot", "survey.tour"]
    change = h.changes[-1]
    assert (change.event, change.source, change.target) == ("done", "survey", "home")


def test_a_region_that_reaches_a_final_state_counts_as_finished(cub_config: AgentConfig) -> None:
    h = harness(
        {
            "initial": "par",
            "states": {
                "par": {
                    "parallel": True,
                    "on": {"done": "after"},
                    "states": {
                        "seq": {
                            "initial": "work",
                            "states": {
                                "work": leaf(1, on={"done": "par.seq.end"}),
                                "end": {"final": True},
                            },
                        },
                        "mark": {"final": True},
                    },
                },
                "after": leaf(),
            },
        },
        cub_config,
    ).start()
    assert h.machine.active_paths() == ("par.mark", "par.seq.work")
    h.step(0.1)
    assert h.machine.active_paths() == ("after",)


def test_final_states_raise_done_on_every_level_in_one_step(cub_config: AgentConfig) -> None:
    h = harness(
        {
            "initial": "outer",
            "states": {
                "outer": {
                    "initial": "inner",
                    "on": {"done": "after"},
                    "states": {
                        "inner": {
                            "initial": "work",
                            "on": {"done": "outer.fin"},
                            "states": {
                                "work": leaf(1, on={"done": "outer.inner.end"}),
                                "end": {"final": True},
                            },
                        },
                        "fin": {"final": True},
                    },
                },
                "after": leaf(),
            },
        },
        cub_config,
    ).start()
    h.step(0.1)
    assert [(c.event, c.source, c.target) for c in h.changes[1:]] == [
        ("done", "outer.inner.work", "outer.inner.end"),
        ("done", "outer.inner", "outer.fin"),
        ("done", "outer", "after"),
    ]
    assert all(c.time_s == 0.1 for c in h.changes[1:])
    assert h.machine.active_paths() == ("after",)


def test_a_final_state_with_a_primitive_still_runs_it(cub_config: AgentConfig) -> None:
    h = harness(
        {
            "initial": "chase",
            "states": {
                "chase": {
                    "initial": "go",
                    "states": {
                        "go": leaf(1, on={"done": "chase.parked"}),
                        "parked": leaf(final=True),
                    },
                }
            },
        },
        cub_config,
    ).start()
    h.step(0.1)
    h.step(0.2)
    h.step(0.3)
    assert h.machine.active_paths() == ("chase.parked",)
    assert h.calls("update") == ["chase.go", "chase.parked", "chase.parked"]


# -- external events -----------------------------------------------------------------------


def test_guarded_transitions_are_tried_in_order(cub_config: AgentConfig) -> None:
    tree = {
        "initial": "idle",
        "states": {
            "idle": leaf(
                on={
                    "activate": [
                        ("x", {"flag": "first"}),
                        ("y", {"flag": "second"}),
                        ("z", None),
                    ]
                }
            ),
            "x": leaf(),
            "y": leaf(),
            "z": leaf(),
        },
    }
    for flags, expected, guards in (
        ({"first": True, "second": True}, "x", 1),
        ({"second": True}, "y", 2),
        ({}, "z", 2),
    ):
        h = harness(tree, cub_config).start()
        h.flags.update(flags)
        assert h.dispatch("activate", 1.5) is True
        assert h.machine.active_paths() == (expected,)
        assert len(h.guards) == guards


def test_guards_see_the_time_in_their_source_state(cub_config: AgentConfig) -> None:
    h = harness(
        {
            "initial": "p",
            "states": {
                "p": {
                    "initial": "c",
                    "on": {"activate": [("q", {"in_state_s": {"gt": 5}})]},
                    "states": {"c": leaf(on={"deactivate": "p.d"}), "d": leaf()},
                },
                "q": leaf(),
            },
        },
        cub_config,
    ).start(10.0)
    h.dispatch("deactivate", 13.0)  # the child changes; the parent's time keeps counting
    assert h.dispatch("activate", 14.0) is False
    assert h.dispatch("activate", 16.0) is True
    assert [g[1] for g in h.guards] == [4.0, 6.0]


def test_a_failing_guard_lets_the_parent_take_the_event(cub_config: AgentConfig) -> None:
    h = harness(
        {
            "initial": "p",
            "states": {
                "p": {
                    "initial": "c",
                    "on": {"activate": "q"},
                    "states": {
                        "c": leaf(on={"activate": [("p.d", {"flag": "inner"})]}),
                        "d": leaf(),
                    },
                },
                "q": leaf(),
            },
        },
        cub_config,
    ).start()
    assert h.dispatch("activate", 1.0) is True
    assert h.machine.active_paths() == ("q",)


def test_an_event_on_a_parent_is_taken_while_in_a_child(cub_config: AgentConfig) -> None:
    h = harness(
        {
            "initial": "excite",
            "states": {
                "excite": {
                    "initial": "rudder",
                    "on": {"deactivate": "piloted"},
                    "states": {"rudder": leaf(), "other": leaf()},
                },
                "piloted": leaf(),
            },
        },
        cub_config,
    ).start()
    assert h.dispatch("deactivate", 2.0) is True
    change = h.changes[-1]
    assert (change.event, change.source, change.target) == ("deactivate", "excite", "piloted")
    assert change.exited == ("excite.rudder", "excite")
    assert change.entered == ("piloted",)
    assert h.calls("stop") == ["excite.rudder"]


def test_the_innermost_state_takes_an_event_before_its_parent(cub_config: AgentConfig) -> None:
    h = harness(
        {
            "initial": "p",
            "states": {
                "p": {
                    "initial": "c",
                    "on": {"rc:8:high": "q"},
                    "states": {"c": leaf(on={"rc:8:high": "p.d"}), "d": leaf()},
                },
                "q": leaf(),
            },
        },
        cub_config,
    ).start()
    h.dispatch("rc:8:high", 1.0)
    assert h.machine.active_paths() == ("p.d",)
    h.dispatch("rc:8:high", 2.0)  # d has none: the parent takes it
    assert h.machine.active_paths() == ("q",)


def test_unknown_and_unhandled_events_are_ignored(
    cub_config: AgentConfig, caplog: pytest.LogCaptureFixture
) -> None:
    h = harness(
        {
            "initial": "a",
            "states": {"a": leaf(on={"activate": "b"}), "b": leaf(on={"mcs_lost": "a"})},
        },
        cub_config,
    ).start()
    with caplog.at_level(logging.DEBUG, logger="transitions"):
        assert h.dispatch("no_such_event", 1.0) is False
        assert h.dispatch("mcs_lost", 1.0) is False  # known, but not in the active state
        assert h.dispatch("done", 1.0) is False  # raised by the machine only
        assert h.dispatch("timeout", 1.0) is False
    assert not [r for r in caplog.records if r.levelno >= logging.WARNING]
    assert h.machine.active_paths() == ("a",)
    assert len(h.changes) == 1
    assert h.machine.last_event == "start"


def test_one_event_moves_each_parallel_region_that_handles_it(cub_config: AgentConfig) -> None:
    tree = {
        "initial": "par",
        "states": {
            "par": {
                "parallel": True,
                "states": {
                    "a": {
                        "initial": "a1",
                        "states": {"a1": leaf(on={"found:x": "par.a.a2"}), "a2": leaf()},
                    },
                    "b": {
                        "initial": "b1",
                        "states": {"b1": leaf(on={"found:x": "par.b.b2"}), "b2": leaf()},
                    },
                },
            },
        },
    }
    h = harness(tree, cub_config).start()
    assert h.dispatch("found:x", 1.0) is True
    assert h.machine.active_paths() == ("par.a.a2", "par.b.b2")
    assert [c.source for c in h.changes[1:]] == ["par.a.a1", "par.b.b1"]
    h.check_library()


def test_a_region_left_by_an_earlier_transition_does_not_move_again(
    cub_config: AgentConfig,
) -> None:
    tree = {
        "initial": "par",
        "states": {
            "par": {
                "parallel": True,
                "states": {
                    "a": {"initial": "a1", "states": {"a1": leaf(on={"lost:x": "home"})}},
                    "b": {
                        "initial": "b1",
                        "states": {"b1": leaf(on={"lost:x": "par.b.b2"}), "b2": leaf()},
                    },
                },
            },
            "home": leaf(),
        },
    }
    h = harness(tree, cub_config).start()
    assert h.dispatch("lost:x", 1.0) is True
    assert h.machine.active_paths() == ("home",)
    assert len(h.changes) == 2
    assert sorted(h.calls("start")) == ["home", "par.a.a1", "par.b.b1"]
    h.check_library()


# -- targets and re-entry ------------------------------------------------------------------


DEEP = {
    "initial": "a",
    "states": {
        "a": {
            "initial": "b",
            "states": {
                "b": {
                    "initial": "c",
                    "states": {
                        "c": leaf(
                            on={
                                "activate": "x.y.z",
                                "deactivate": "a",
                                "terminate": "a.b.c",
                                "mode:AUTO": "survey.photos.later",
                            }
                        )
                    },
                },
            },
        },
        "x": {
            "initial": "w",
            "states": {
                "w": leaf(),
                "y": {
                    "initial": "v",
                    "states": {"v": leaf(), "z": leaf(timeout_s=1, on={"timeout": "a"})},
                },
            },
        },
        "survey": {
            "parallel": True,
            "states": {
                "tour": {"initial": "leg", "states": {"leg": leaf(), "leg2": leaf()}},
                "photos": {"initial": "now", "states": {"now": leaf(), "later": leaf()}},
            },
        },
    },
}


def test_a_transition_into_a_deep_target_enters_each_level_once(cub_config: AgentConfig) -> None:
    h = harness(DEEP, cub_config).start()
    h.dispatch("activate", 1.0)
    change = h.changes[-1]
    assert change.exited == ("a.b.c", "a.b", "a")
    assert change.entered == ("x", "x.y", "x.y.z")  # not x.w, not x.y.v
    assert h.machine.active_paths() == ("x.y.z",)
    h.step(2.0)  # z's own timer, from its entry at 1.0: back to a
    assert h.machine.active_paths() == ("a.b.c",)
    h.check_library()


def test_a_deep_target_in_a_parallel_state_starts_the_other_regions(
    cub_config: AgentConfig,
) -> None:
    h = harness(DEEP, cub_config).start()
    h.dispatch("mode:AUTO", 1.0)
    assert h.machine.active_paths() == ("survey.photos.later", "survey.tour.leg")
    change = h.changes[-1]
    assert change.entered == (
        "survey",
        "survey.photos",
        "survey.photos.later",
        "survey.tour",
        "survey.tour.leg",
    )
    h.check_library()
    h.step(1.1)
    assert sorted(h.updates_at(1.1)) == ["survey.photos.later", "survey.tour.leg"]


def test_a_transition_to_an_ancestor_leaves_and_enters_it_again(cub_config: AgentConfig) -> None:
    h = harness(DEEP, cub_config).start()
    first = h.instances[-1]
    assert h.dispatch("deactivate", 1.0) is True
    change = h.changes[-1]
    assert change.exited == ("a.b.c", "a.b", "a")
    assert change.entered == ("a", "a.b", "a.b.c")
    assert h.instances[-1] is not first
    assert h.calls("start") == ["a.b.c", "a.b.c"]
    assert h.calls("stop") == ["a.b.c"]


def test_a_transition_to_itself_restarts_the_state(cub_config: AgentConfig) -> None:
    h = harness(DEEP, cub_config).start()
    h.dispatch("terminate", 1.0)
    change = h.changes[-1]
    assert change.exited == ("a.b.c",)
    assert change.entered == ("a.b.c",)
    assert len({entry[2] for entry in h.journal if entry[0] == "start"}) == 2


def test_a_transition_from_a_state_to_its_descendant_is_local(cub_config: AgentConfig) -> None:
    h = harness(
        {
            "initial": "p",
            "states": {
                "p": {
                    "initial": "c",
                    "timeout_s": 1.0,
                    "on": {"activate": "p.d", "timeout": "q"},
                    "states": {"c": leaf(), "d": leaf()},
                },
                "q": leaf(),
            },
        },
        cub_config,
    ).start()
    h.dispatch("activate", 0.5)
    assert h.changes[-1].exited == ("p.c",)
    assert h.changes[-1].entered == ("p.d",)
    h.step(1.0)  # p was not left: its timer still counts from 0
    assert h.machine.active_paths() == ("q",)


# -- primitives ----------------------------------------------------------------------------


def test_primitives_start_and_stop_once_per_entry_with_a_fresh_instance(
    cub_config: AgentConfig,
) -> None:
    h = harness(
        {
            "initial": "a",
            "states": {"a": leaf(2, on={"done": "b"}), "b": leaf(1, on={"done": "a"})},
        },
        cub_config,
    ).start()
    for k in range(1, 10):
        h.step(k)
    starts = [(e[1], e[2]) for e in h.journal if e[0] == "start"]
    stops = [(e[1], e[2]) for e in h.journal if e[0] == "stop"]
    assert [s[0] for s in starts] == ["a", "b", "a", "b", "a", "b", "a"]
    assert len({s[1] for s in starts}) == len(starts)  # a fresh instance per entry
    assert stops == starts[:-1]  # each stopped once, when left
    for instance in h.instances:
        calls = [e[0] for e in h.journal if e[2] == id(instance)]
        assert calls[0] == "start"
        assert calls.count("start") == 1 and calls.count("stop") <= 1
        assert "stop" not in calls[:-1]


def test_a_failed_primitive_is_reported_and_no_longer_updated(cub_config: AgentConfig) -> None:
    h = harness(
        {
            "initial": "par",
            "states": {
                "par": {
                    "parallel": True,
                    "on": {"done": "after"},
                    "states": {"broken": leaf(fail_after=1, on={"done": "after"}), "ok": leaf(1)},
                },
                "after": leaf(),
            },
        },
        cub_config,
    ).start()
    for k in range(1, 4):
        h.step(k)
    assert h.calls("update") == ["par.broken", "par.ok"]  # a failed region never finishes
    assert h.machine.active_paths() == ("par.broken", "par.ok")
    failed = h.changes[-1]
    assert (failed.event, failed.source, failed.target, failed.exited, failed.entered) == (
        "failed",
        "par.broken",
        "par.broken",
        (),
        (),
    )
    assert h.machine.last_event == "failed"


def test_stop_stops_every_active_primitive_and_freezes_the_machine(cub_config: AgentConfig) -> None:
    h = harness(
        {
            "initial": "par",
            "states": {
                "par": {
                    "parallel": True,
                    "states": {"one": leaf(on={"activate": "x"}), "two": leaf()},
                },
                "x": leaf(),
            },
        },
        cub_config,
    ).start()
    h.step(0.1)
    h.machine.stop(h.at(0.2))
    assert sorted(h.calls("stop")) == ["par.one", "par.two"]
    assert not h.machine.running
    h.step(0.3)
    assert h.dispatch("activate", 0.3) is False
    h.machine.stop(h.at(0.4))
    assert len(h.calls("stop")) == 2
    assert h.machine.active_paths() == ("par.one", "par.two")  # where it stopped


def test_payload_events_go_to_every_active_primitive(cub_config: AgentConfig) -> None:
    h = harness(
        {"parallel": True, "states": {"tour": leaf(), "photos": leaf()}},
        cub_config,
    ).start()
    event = PayloadEvent("camera", "captured", 1)
    h.machine.deliver_payload(h.at(1.0), event)
    assert [i.payloads for i in h.instances] == [[event], [event]]


# -- isolation and config errors -----------------------------------------------------------


def test_two_machines_share_nothing(cub_config: AgentConfig) -> None:
    tree = {
        "initial": "idle",
        "states": {"idle": leaf(on={"activate": "busy"}), "busy": leaf(1, on={"done": "idle"})},
    }
    one = harness(tree, cub_config).start()
    two = harness(tree, cub_config).start()
    one.dispatch("activate", 1.0)
    assert one.machine.active_paths() == ("busy",)
    assert two.machine.active_paths() == ("idle",)
    two.step(1.1)
    assert two.calls("update") == ["idle"]
    assert one.calls("update") == []
    one.step(1.1)
    assert one.machine.active_paths() == ("idle",)
    # the library's own class keeps its separator: other machines are unaffected
    assert NestedState.separator == "_"
    plain = HierarchicalMachine(
        states=["a", {"name": "b", "children": ["c"], "initial": "c"}],
        initial="a",
        auto_transitions=False,
    )
    plain.add_transition("go", "a", "b_c")
    plain.go()
    assert plain.state == "b_c"


def test_unknown_targets_and_missing_initials_are_config_errors(cub_config: AgentConfig) -> None:
    with pytest.raises(ConfigError, match="no state 'nowhere'"):
        harness({"initial": "a", "states": {"a": leaf(on={"activate": "nowhere"})}}, cub_config)
    with pytest.raises(ConfigError, match="no valid initial child"):
        harness({"states": {"a": leaf()}}, cub_config)


def test_start_twice_is_a_bug(cub_config: AgentConfig) -> None:
    h = harness(leaf(), cub_config).start()
    with pytest.raises(RuntimeError):
        h.machine.start(h.at(1.0))


# -- the Super Cub -------------------------------------------------------------------------


DONE_AFTER = {"doublet": 3, "wait": 5, "sine_sweep": 4}


def cub_harness(config: AgentConfig) -> Harness:
    """The Super Cub's machine with fakes: piloted waits for ever, the rest end after N."""
    assert config.machine is not None

    def done_after(state: StateSpec) -> int | None:
        return DONE_AFTER.get(state.primitive or "") if state.path != "piloted" else None

    return Harness(config.machine, config, done_after)


def test_the_supercub_sysid_mission_runs_through_its_sequence(cub_config: AgentConfig) -> None:
    h = cub_harness(cub_config).start()
    assert h.machine.active_paths() == ("piloted",)
    h.step(0.1)
    h.dispatch("activate", 0.15)
    tick = 1
    while h.machine.active_paths() != ("piloted",) and tick < 100:
        tick += 1
        h.step(round(0.1 * tick, 10))
    transitions = [(c.event, c.source, c.target) for c in h.changes[1:]]
    assert transitions == [
        ("activate", "piloted", "excite"),
        ("done", "excite.aileron", "excite.settle_1"),
        ("done", "excite.settle_1", "excite.rudder"),
        ("done", "excite.rudder", "excite.settle_2"),
        ("done", "excite.settle_2", "excite.sweep"),
        ("done", "excite.sweep", "excite.finished"),
        ("done", "excite", "piloted"),
    ]
    assert h.changes[1].entered == ("excite", "excite.aileron")
    assert h.changes[-1].exited == ("excite.finished", "excite")
    # finished -> piloted in the step the sweep ends; each primitive's updates are its own count
    assert h.changes[-1].time_s == h.changes[-2].time_s
    counts = {p: h.calls("update").count(p) for p in ("excite.aileron", "excite.sweep")}
    assert counts == {"excite.aileron": 3, "excite.sweep": 4}
    assert tick == 1 + 3 + 5 + 3 + 5 + 4
    h.check_library()


def test_deactivate_aborts_the_supercub_sequence_from_any_step(cub_config: AgentConfig) -> None:
    h = cub_harness(cub_config).start()
    h.dispatch("activate", 0.0)
    for k in range(1, 6):
        h.step(k * 0.1)
    assert h.machine.active_paths() == ("excite.settle_1",)
    assert h.dispatch("deactivate", 0.55) is True
    assert h.machine.active_paths() == ("piloted",)
    assert h.changes[-1].source == "excite"
    assert h.calls("stop")[-1] == "excite.settle_1"


def test_a_done_or_timeout_of_a_state_re_entered_in_the_same_step_is_dropped(
    cub_config: AgentConfig,
) -> None:
    h = harness(
        {
            "initial": "p",
            "states": {
                "p": {
                    "parallel": True,
                    "states": {
                        "a": leaf(1, timeout_s=0.5, on={"done": "p", "timeout": "p"}),
                        "b": leaf(1, timeout_s=0.5, on={"done": "q", "timeout": "q"}),
                    },
                },
                "q": leaf(),
            },
        },
        cub_config,
    ).start()
    for k in range(1, 6):
        h.step(round(0.1 * k, 10))
    # each step both finish; a's done restarts p first, so b's done belongs to a
    # left entry and is dropped: q is never reached
    assert [(c.event, c.source) for c in h.changes[1:]] == [("done", "p.a")] * 5
    assert h.machine.active_paths() == ("p.a", "p.b")
    assert h.calls("update").count("p.b") == 5


def test_timers_of_states_re_entered_by_an_earlier_timeout_start_again(
    cub_config: AgentConfig,
) -> None:
    h = harness(
        {
            "initial": "p",
            "states": {
                "p": {
                    "parallel": True,
                    "states": {
                        "a": leaf(timeout_s=0.5, on={"timeout": "p"}),
                        "b": leaf(timeout_s=0.5, on={"timeout": "q"}),
                    },
                },
                "q": leaf(),
            },
        },
        cub_config,
    ).start()
    h.step(0.5)
    assert [(c.event, c.source) for c in h.changes[1:]] == [("timeout", "p.a")]
    h.step(0.9)
    assert h.machine.active_paths() == ("p.a", "p.b")
    h.step(1.0)
    assert [(c.time_s, c.source) for c in h.changes[1:]] == [(0.5, "p.a"), (1.0, "p.a")]
