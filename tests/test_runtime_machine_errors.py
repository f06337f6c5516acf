"""The state machine when a primitive raises: one record of the active states, kept whole.

The library's state (``transitions``' model) is the machine's only record of the active
configuration. A primitive that raises while its state is entered or left must not leave
that record half-changed, nor end the agent's loop: a flying vehicle's runtime keeps its
failsafes, heartbeats and station link only while its tick runs. What the machine does:

- ``make_primitive`` or ``start`` raising: the state is entered like any other (the
  transition completes, every other state it enters is started), and its primitive is
  FAILED from the start: reported as a ``failed`` change right after the transition's
  own, never updated, stopped when the state is left (a half-started primitive may hold
  an RC override that its ``stop`` releases).
- ``stop`` raising: the state is left all the same and the transition completes.
- ``update``, ``on_payload`` or ``on_mission`` raising: that state fails (reported as
  a ``failed`` change, never updated again), the other states go on being updated and
  handed the event, and the tick returns.
- :meth:`BehaviorMachine.stop` (terminate, failsafes) stops every other primitive even
  when one raises.
"""

from __future__ import annotations

import logging
from collections.abc import Mapping
from pathlib import Path
from typing import Any

import pytest

from clark_engine.behaviors.base import BehaviorRuntime as Primitive
from clark_engine.behaviors.base import Status
from clark_engine.mission.compiler import agent_config
from clark_engine.mission.validate import validate_path
from clark_engine.runtime.config import AgentConfig, StateSpec, config_from_dict
from clark_engine.runtime.context import PrimitiveContext
from clark_engine.runtime.events import PayloadEvent
from clark_engine.runtime.log_events import RECORD_ATTRIBUTE
from tests.test_runtime_machine import Fake, Harness, leaf, spec

ROOT = Path(__file__).resolve().parent.parent


@pytest.fixture(scope="module")
def config() -> AgentConfig:
    """A compiled config for the context (the Super Cub's; its machine is not used)."""
    validation = validate_path(ROOT / "missions" / "supercub_sysid.yaml")
    assert validation.ok and validation.mission is not None
    mission = validation.mission
    return config_from_dict(agent_config(mission, mission.agents["cub"]))


class Broken(Fake):
    """A fake primitive whose ``start`` or ``stop`` raises, as its params say."""

    def start(self, ctx: PrimitiveContext) -> None:
        super().start(ctx)
        if self.params.get("start_raises"):
            raise RuntimeError(f"{self.path}: the servo channel is gone")

    def stop(self, ctx: PrimitiveContext) -> None:
        super().stop(ctx)
        if self.params.get("stop_raises"):
            raise RuntimeError(f"{self.path}: cannot release the override")

    def update(self, ctx: PrimitiveContext) -> Status:
        status = super().update(ctx)
        if self.params.get("update_raises") == self.updates:
            raise ZeroDivisionError(f"{self.path}: float division by zero")
        return status

    def on_payload(self, ctx: PrimitiveContext, event: PayloadEvent) -> None:
        super().on_payload(ctx, event)
        if self.params.get("payload_raises"):
            raise KeyError(event.payload)


class BrokenHarness(Harness):
    """A harness whose primitives may raise in start or stop, or not be built at all."""

    def make(self, state: StateSpec) -> Primitive:
        if state.params.get("make_raises"):
            raise ValueError(f"{state.path}: no such primitive")
        primitive = Broken(state.params, state.path, self.journal)
        self.instances.append(primitive)
        return primitive


def broken(tree: Mapping[str, Any], config: AgentConfig) -> BrokenHarness:
    return BrokenHarness(spec(tree), config)


def raising(**flags: Any) -> dict[str, Any]:
    """A state whose fake primitive raises as ``flags`` say (never done by itself)."""
    state = leaf()
    state["with"] = {**state["with"], **{k: v for k, v in flags.items() if k != "on"}}
    if "on" in flags:
        state["on"] = flags["on"]
    return state


def test_a_start_that_raises_fails_its_state_and_the_transition_completes(
    config: AgentConfig, caplog: pytest.LogCaptureFixture
) -> None:
    h = broken(
        {
            "initial": "idle",
            "states": {
                "idle": leaf(on={"activate": "par"}),
                "par": {
                    "parallel": True,
                    "on": {"deactivate": "idle"},
                    "states": {"a": raising(start_raises=True), "b": leaf(2)},
                },
            },
        },
        config,
    ).start()
    with caplog.at_level(logging.ERROR):
        assert h.dispatch("activate", 1.0) is True  # no exception out of the agent's tick
    (line,) = [r for r in caplog.records if r.name == h.ctx.log.name]  # the agent's mission log
    assert getattr(line, RECORD_ATTRIBUTE) == "behavior.error"
    assert line.getMessage() == (
        "primitive fake of state par.a raised in start: RuntimeError: par.a: the servo "
        "channel is gone; the state fails"
    )
    assert h.machine.active_paths() == ("par.a", "par.b")
    h.check_library()
    assert [(c.event, c.source, c.target) for c in h.changes[1:]] == [
        ("activate", "idle", "par"),
        ("failed", "par.a", "par.a"),
    ]
    assert h.changes[1].entered == ("par", "par.a", "par.b")
    assert h.machine.last_event == "failed"
    assert h.calls("start") == ["idle", "par.a", "par.b"]  # b still started
    h.step(1.1)
    h.step(1.2)
    assert h.updates_at(1.1) == ["par.b"] and h.updates_at(1.2) == ["par.b"]
    # a failed region never finishes: no done for par; deactivate leaves it as usual
    assert h.dispatch("deactivate", 1.3) is True
    assert h.machine.active_paths() == ("idle",)
    assert h.changes[-1].exited == ("par.a", "par.b", "par")
    assert h.changes[-1].entered == ("idle",)  # nothing of the failed entry left behind
    assert sorted(h.calls("stop")) == ["idle", "par.a", "par.b"]  # a's stop releases it
    h.check_library()


def test_a_start_that_raises_in_the_initial_configuration(config: AgentConfig) -> None:
    h = broken(
        {
            "initial": "spin",
            "states": {
                "spin": raising(start_raises=True, on={"timeout": "rest"}) | {"timeout_s": 1.0},
                "rest": leaf(),
            },
        },
        config,
    ).start()
    assert h.machine.running
    assert [(c.event, c.source) for c in h.changes] == [("start", ""), ("failed", "spin")]
    assert h.machine.active_paths() == ("spin",)
    h.check_library()
    h.step(0.5)
    assert h.calls("update") == []
    h.step(1.0)  # its own timer still moves on from a failed state
    assert h.machine.active_paths() == ("rest",)
    assert h.calls("stop") == ["spin"]
    h.check_library()


def test_a_primitive_that_cannot_be_built_fails_its_state(config: AgentConfig) -> None:
    h = broken(
        {
            "initial": "idle",
            "states": {
                "idle": leaf(on={"activate": "odd"}),
                "odd": raising(make_raises=True, on={"deactivate": "idle"}),
            },
        },
        config,
    ).start()
    assert h.dispatch("activate", 1.0) is True
    assert [(c.event, c.source) for c in h.changes[1:]] == [("activate", "idle"), ("failed", "odd")]
    assert h.machine.active_paths() == ("odd",)
    h.check_library()
    h.step(1.1)
    assert h.dispatch("deactivate", 1.2) is True
    assert h.machine.active_paths() == ("idle",)
    h.check_library()


def test_a_stop_that_raises_still_leaves_its_state(
    config: AgentConfig, caplog: pytest.LogCaptureFixture
) -> None:
    h = broken(
        {
            "initial": "a",
            "states": {"a": raising(stop_raises=True, on={"activate": "b"}), "b": leaf()},
        },
        config,
    ).start()
    with caplog.at_level(logging.ERROR):
        assert h.dispatch("activate", 1.0) is True
    assert "primitive fake of state a raised in stop: RuntimeError: a: cannot release the " in (
        caplog.text
    )
    assert h.machine.active_paths() == ("b",)
    change = h.changes[-1]
    assert (change.event, change.exited, change.entered) == ("activate", ("a",), ("b",))
    assert h.calls("start") == ["a", "b"]
    h.step(1.1)
    assert h.updates_at(1.1) == ["b"]
    h.check_library()


def test_stopping_the_machine_stops_every_primitive_when_one_raises(config: AgentConfig) -> None:
    h = broken(
        {"parallel": True, "states": {"x": raising(stop_raises=True), "y": leaf(), "z": leaf()}},
        config,
    ).start()
    h.machine.stop(h.at(1.0))  # a failsafe must not stop half-way
    assert sorted(h.calls("stop")) == ["x", "y", "z"]
    assert not h.machine.running
    assert h.machine.active_paths() == ("x", "y", "z")


def test_an_update_that_raises_fails_its_state_and_the_others_go_on(
    config: AgentConfig, caplog: pytest.LogCaptureFixture
) -> None:
    h = broken(
        {"parallel": True, "states": {"a": raising(update_raises=2), "b": leaf()}},
        config,
    ).start()
    h.step(0.1)
    with caplog.at_level(logging.ERROR):
        h.step(0.2)  # a raises in its second update: no exception out of the tick
    (line,) = [r for r in caplog.records if r.name == h.ctx.log.name]
    assert getattr(line, RECORD_ATTRIBUTE) == "behavior.error"
    assert line.getMessage() == (
        "primitive fake of state a raised in update: ZeroDivisionError: a: float division "
        "by zero; the state fails"
    )
    assert h.updates_at(0.2) == ["a", "b"]  # b was updated in the same step, after a
    assert [(c.event, c.source) for c in h.changes[1:]] == [("failed", "a")]
    h.step(0.3)
    assert h.updates_at(0.3) == ["b"]  # a failed state is never updated again
    assert h.machine.active_paths() == ("a", "b")
    h.check_library()


def test_a_payload_handler_that_raises_fails_its_state_only(
    config: AgentConfig, caplog: pytest.LogCaptureFixture
) -> None:
    h = broken(
        {"parallel": True, "states": {"a": raising(payload_raises=True), "b": leaf()}},
        config,
    ).start()
    event = PayloadEvent("camera", "captured", 1, "IMG_0001.jpg")
    with caplog.at_level(logging.ERROR):
        h.machine.deliver_payload(h.at(0.5), event)
    (line,) = [r for r in caplog.records if r.name == h.ctx.log.name]
    assert line.getMessage() == (
        "primitive fake of state a raised in on_payload: KeyError: 'camera'; the state fails"
    )
    assert [p.payloads for p in h.instances] == [[event], [event]]  # b still handed it
    assert [(c.event, c.source) for c in h.changes[1:]] == [("failed", "a")]
    h.step(0.6)
    assert h.updates_at(0.6) == ["b"]
    h.check_library()


def test_states_that_finish_as_they_are_entered_in_a_cycle_go_one_lap_per_step(
    config: AgentConfig,
) -> None:
    """Each state finishes at most once per call: the call returns, the cycle goes on."""
    final = {"initial": "end", "states": {"end": {"final": True}}}
    h = broken(
        {
            "initial": "a",
            "states": {"a": final | {"on": {"done": "b"}}, "b": final | {"on": {"done": "a"}}},
        },
        config,
    ).start()  # before, this never returned
    laps = [("start", "", ""), ("done", "a", "b"), ("done", "b", "a")]
    assert [(c.event, c.source, c.target) for c in h.changes] == laps
    assert h.machine.active_paths() == ("a.end",)
    h.step(0.1)
    assert [(c.event, c.source, c.target) for c in h.changes[3:]] == [
        ("done", "a", "b"),
        ("done", "b", "a"),
    ]
    assert h.machine.active_paths() == ("a.end",)
    h.check_library()
