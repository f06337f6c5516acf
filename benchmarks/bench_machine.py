"""CPU time of the behaviour state machine alone: build, step, dispatch (issue 20 item 6).

What the state machine costs, without the rest of the runtime, with primitives that
do nothing (so what is measured is the machine's own bookkeeping and the library's):

- **build**: :class:`BehaviorMachine` made and started, per agent, for the Super Cub's
  behaviour (9 states, root included) and the anaconda survey's (6, one parallel).
- **step**: one :meth:`~BehaviorMachine.step` with the Super Cub held in a state that
  never finishes (the steady state of every tick: no event, one primitive updated) and
  the survey in its parallel state (two primitives).
- **dispatch**: one event that takes a transition (``activate``/``deactivate`` between
  two states: one state left, one entered), one into a state deep inside a parallel
  state (two more regions to enter), and one that no active state handles (the fast
  path a station's stray ``deactivate`` takes).
- **library share**: the part of the dispatch time spent inside ``transitions``
  (cProfile's own time of its functions, over the total), what an engine-owned machine
  could save at most.

Both variants of ``runtime/machine.py`` can be measured: run it once from each tree
(``PYTHONPATH=<tree> python benchmarks/bench_machine.py``); it prints which module it
measured.

Run: python benchmarks/bench_machine.py
"""

from __future__ import annotations

import cProfile
import pstats
import time
from collections.abc import Callable, Mapping
from pathlib import Path
from typing import Any

from clark_engine.behaviors.base import BehaviorRuntime as Primitive
from clark_engine.link.fleet import FleetTable
from clark_engine.mission.compiler import agent_config
from clark_engine.mission.validate import validate_path
from clark_engine.runtime import machine as machine_module
from clark_engine.runtime.config import AgentConfig, StateSpec, TransitionSpec, config_from_dict
from clark_engine.runtime.context import PrimitiveContext, Status
from clark_engine.runtime.machine import BehaviorMachine

ROOT = Path(__file__).resolve().parent.parent


class Idle(Primitive):
    """A primitive that runs for ever and does nothing: only the machine is measured."""

    name = "idle"

    def update(self, ctx: PrimitiveContext) -> Status:
        return Status.RUNNING


def make(state: StateSpec) -> Primitive:
    return Idle(state.params)


def evaluate(when: Mapping[str, Any], ctx: PrimitiveContext, in_state_s: float) -> bool:
    return True


def compiled(mission_file: str, agent: str) -> AgentConfig:
    validation = validate_path(ROOT / "missions" / mission_file)
    assert validation.ok and validation.mission is not None, mission_file
    mission = validation.mission
    return config_from_dict(agent_config(mission, mission.agents[agent]))


def leaf(path: str, on: Mapping[str, str] | None = None) -> StateSpec:
    return node(path, "primitive", (), on, primitive="idle")


def node(
    path: str,
    kind: str,
    states: tuple[StateSpec, ...],
    on: Mapping[str, str] | None = None,
    *,
    primitive: str | None = None,
    initial: str | None = None,
) -> StateSpec:
    return StateSpec(
        name=path.rsplit(".", 1)[-1],
        path=path,
        kind=kind,
        primitive=primitive,
        params={},
        block=None,
        initial=initial,
        parallel=kind == "parallel",
        finish="all",
        final=False,
        timeout_s=None,
        transitions=tuple(TransitionSpec(e, t, None, "bench") for e, t in (on or {}).items()),
        source="bench",
        states=states,
    )


# idle <-> busy, and from idle into survey.photos.later (survey: two regions).
PING = node(
    "",
    "machine",
    (
        leaf("idle", {"activate": "busy", "mode:AUTO": "survey.photos.later"}),
        leaf("busy", {"deactivate": "idle"}),
        node(
            "survey",
            "parallel",
            (
                node("survey.tour", "machine", (leaf("survey.tour.leg"),), initial="leg"),
                node(
                    "survey.photos",
                    "machine",
                    (leaf("survey.photos.now"), leaf("survey.photos.later")),
                    initial="now",
                ),
            ),
            {"deactivate": "idle"},
        ),
    ),
    initial="idle",
)


def per_call_us(run: Callable[[int], None], count: int) -> float:
    """CPU microseconds per call of ``run(k)``, best of three rounds."""
    best = float("inf")
    for _ in range(3):
        start = time.process_time()
        for k in range(count):
            run(k)
        best = min(best, time.process_time() - start)
    return best / count * 1e6


def machine_for(spec: StateSpec, config: AgentConfig) -> tuple[BehaviorMachine, PrimitiveContext]:
    ctx = PrimitiveContext(config, FleetTable(config.agent_id, config.mission_id, 3.0))
    machine = BehaviorMachine(spec, make, evaluate, lambda change: None)
    machine.start(ctx)
    return machine, ctx


def main() -> None:
    print(f"measured: {machine_module.__file__}")
    cub = compiled("supercub_sysid.yaml", "cub")
    survey = compiled("anaconda_survey.yaml", "anaconda")
    assert cub.machine is not None and survey.machine is not None

    print(f"{'build + start, per agent':<44}{'us':>10}")
    for label, config in (("supercub_sysid cub", cub), ("anaconda_survey anaconda", survey)):
        spec = config.machine
        assert spec is not None
        us = per_call_us(lambda k, s=spec, c=config: machine_for(s, c) and None, 300)
        print(f"  {label:<42}{us:>10.1f}")

    print(f"{'step (no event), per step':<44}{'us':>10}")
    machine, ctx = machine_for(cub.machine, cub)
    machine.dispatch("activate", ctx)  # into the excitation's first state, for ever
    busy = machine.active_paths()

    def step(k: int, m: BehaviorMachine = machine, c: PrimitiveContext = ctx) -> None:
        c.now_s = k * 0.1
        m.step(c)

    print(f"  {'supercub ' + ','.join(busy):<42}{per_call_us(step, 20_000):>10.2f}")
    par, par_ctx = machine_for(PING, cub)
    par.dispatch("mode:AUTO", par_ctx)

    def step_par(k: int, m: BehaviorMachine = par, c: PrimitiveContext = par_ctx) -> None:
        c.now_s = k * 0.1
        m.step(c)

    print(f"  {'two parallel regions':<42}{per_call_us(step_par, 20_000):>10.2f}")

    print(f"{'dispatch, per event':<44}{'us':>10}")
    ping, ping_ctx = machine_for(PING, cub)

    def toggle(k: int, m: BehaviorMachine = ping, c: PrimitiveContext = ping_ctx) -> None:
        m.dispatch("activate" if k % 2 == 0 else "deactivate", c)

    def deep(k: int, m: BehaviorMachine = ping, c: PrimitiveContext = ping_ctx) -> None:
        m.dispatch("mode:AUTO" if k % 2 == 0 else "deactivate", c)

    def stray(k: int, m: BehaviorMachine = ping, c: PrimitiveContext = ping_ctx) -> None:
        m.dispatch("lost:nobody", c)

    for label, run in (
        ("transition (idle <-> busy)", toggle),
        ("deep into a parallel state, and back", deep),
        ("event no state handles", stray),
    ):
        print(f"  {label:<42}{per_call_us(run, 5_000):>10.2f}")
        assert ping.active_paths() == ("idle",)

    profile = cProfile.Profile()
    profile.enable()
    for k in range(5_000):
        toggle(k)
        deep(k)
    profile.disable()
    stats = pstats.Stats(profile)
    total = sum(row[2] for row in stats.stats.values())  # type: ignore[attr-defined]
    library = sum(
        row[2]
        for key, row in stats.stats.items()  # type: ignore[attr-defined]
        if "/transitions/" in key[0]
    )
    print(f"library share of dispatch time (cProfile own time): {library / total:.0%}")


if __name__ == "__main__":
    main()
