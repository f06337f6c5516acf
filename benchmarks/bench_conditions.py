"""Time conditions on other agents: one decision, and a tick's ``always`` dispatch.

Prints microseconds per call (best and median of several timing rounds, each averaging
many calls) for, on Rover A of missions/leapfrog.yaml with fresh data from Rover B:

- each condition's closure as the runtime resolved it (``agent_state``, ``ahead_m``,
  ``within_m``, and the leapfrog's whole ``any``/``all`` guard), against ``distance_m``;
- the machine's ``dispatch("always")`` in a state with an ``always`` transition whose
  guard does not hold, against a dispatch no state handles, and against what the runtime
  does instead each tick (``AlwaysWatch.due``: the guards of the active states only, the
  machine asked only when one holds).

Run: python benchmarks/bench_conditions.py   (no assertions; figures go to
docs/performance.md)
"""

from __future__ import annotations

import json
import statistics
import sys
import time
from collections.abc import Callable
from pathlib import Path

from clark_engine.link.messages import AgentStatus, AgentType, BehaviorState, Heartbeat
from clark_engine.link.packet import Packet
from clark_engine.mission.compiler import compile_mission
from clark_engine.mission.validate import validate_path
from clark_engine.runtime.config import config_from_dict
from clark_engine.runtime.context import offset_position
from clark_engine.runtime.events import VehicleState
from clark_engine.runtime.runtime import AgentRuntime

ROOT = Path(__file__).resolve().parents[1]
ROUNDS = 7
CALLS = 20_000
ORIGIN = (30.6372, -96.4787)


def per_call_us(fn: Callable[[], object], calls: int = CALLS) -> tuple[float, float]:
    """Best and median microseconds per call over ROUNDS rounds of ``calls`` calls."""
    for _ in range(calls // 10 + 1):
        fn()
    rounds = []
    for _ in range(ROUNDS):
        start = time.perf_counter()
        for _ in range(calls):
            fn()
        rounds.append((time.perf_counter() - start) / calls * 1e6)
    return min(rounds), statistics.median(rounds)


def rover_a() -> AgentRuntime:
    """Rover A's runtime, its vehicle at the origin, Rover B heard 20 m north in hold."""
    path = ROOT / "missions" / "leapfrog.yaml"
    result = validate_path(path, "missions/leapfrog.yaml")
    assert result.mission is not None
    config = config_from_dict(json.loads(compile_mission(result.mission, ["rover_a"])["rover_a"]))
    runtime = AgentRuntime(config)
    ctx = runtime.context
    ctx.vehicle = VehicleState(None, *ORIGIN, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, "GUIDED", 15, True)
    lat, lon = offset_position(*ORIGIN, 20.0, 8.0)
    messages = (
        Heartbeat(3, 0, config.mission_id, AgentType.VEHICLE),
        AgentStatus(3, 0, lat, lon, 0.0, 0.0, 0.0, 0.0, 15),
        BehaviorState(3, 0, ("hold",), "always"),
    )
    ctx.fleet.receive(Packet(config.mission_id, 3, 0, 1, False, messages, 60), 0.0, None)
    return runtime


def main() -> int:
    """Print the figures."""
    runtime = rover_a()
    ctx = runtime.context
    resolve = runtime._resolve_condition  # what the machine calls, once per transition
    guards = {
        "distance_m {to, lt}": {"distance_m": {"to": "rover_b", "lt": 30}},
        "agent_state {agent, in}": {"agent_state": {"agent": "rover_b", "in": "hold"}},
        "ahead_m {agent, gt, bearing_deg}": {
            "ahead_m": {"agent": "rover_b", "gt": 10, "bearing_deg": 0}
        },
        "within_m {agent, lt}": {"within_m": {"agent": "rover_b", "lt": 30}},
        "the leapfrog's guard (any/all of three)": {
            "any": [
                {
                    "all": [
                        {"agent_state": {"agent": "rover_b", "in": "hold"}},
                        {"ahead_m": {"agent": "rover_b", "gt": 30, "bearing_deg": 0}},
                    ]
                },
                {"agent_state": {"agent": "rover_b", "in": "parked"}},
            ]
        },
    }
    print(f"Python {sys.version.split()[0]}; us per call, best / median of {ROUNDS} rounds")
    for name, when in guards.items():
        holds = resolve(when)
        best, median = per_call_us(lambda holds=holds: holds(ctx, 1.0))
        print(f"  {name:42s} {best:6.2f} / {median:6.2f}  (holds: {holds(ctx, 1.0)})")
    machine = runtime.machine
    assert machine is not None
    machine.start(ctx)  # Rover A starts in advance: B is 20 m north, 5 short of its guard
    best, median = per_call_us(lambda: machine.dispatch("always", ctx))
    print(f"  {'dispatch(always), guard not holding':42s} {best:6.2f} / {median:6.2f}")
    best, median = per_call_us(lambda: machine.dispatch("activate", ctx))
    print(f"  {'dispatch of an event no state handles':42s} {best:6.2f} / {median:6.2f}")
    watch = runtime._always  # what the runtime asks each tick before it dispatches
    assert watch is not None
    best, median = per_call_us(lambda: watch.due(ctx))
    print(f"  {'AlwaysWatch.due, guard not holding':42s} {best:6.2f} / {median:6.2f}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
