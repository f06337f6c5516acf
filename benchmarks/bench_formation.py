"""Time follow_agent's goal with an offset in the leader's frame, against a north/east one.

Prints microseconds per call (best and median of several timing rounds, each averaging
many calls) of ``FollowAgent.goal`` and ``FollowAgent.aim`` (what a re-target computes)
for Left of missions/formation_convoy.yaml (``offset: {behind_m: 8, left_m: 8}``) and
for the same follower with the north/east offset it has while the leader drives north
(``{north_m: -8, east_m: -8}``), the leader reported moving, then standing still.

Run: python benchmarks/bench_formation.py   (no assertions; figures go to
docs/performance.md)
"""

from __future__ import annotations

import json
import statistics
import time
from collections.abc import Callable
from pathlib import Path

from clark_engine.behaviors.follow_agent import FollowAgentBehavior
from clark_engine.link.messages import AgentStatus
from clark_engine.mission.compiler import agent_config
from clark_engine.mission.validate import validate_path
from clark_engine.runtime.config import config_from_dict

ROOT = Path(__file__).resolve().parents[1]
ROUNDS = 7
CALLS = 50_000


def timed(call: Callable[[], object]) -> tuple[float, float]:
    """Best and median microseconds per call over the rounds."""
    rounds = []
    for _ in range(ROUNDS):
        start = time.perf_counter()
        for _ in range(CALLS):
            call()
        rounds.append((time.perf_counter() - start) / CALLS * 1e6)
    return min(rounds), statistics.median(rounds)


def main() -> None:
    """Build both followers from the example's compiled config and time them."""
    result = validate_path(ROOT / "missions" / "formation_convoy.yaml")
    assert result.mission is not None
    mission = result.mission
    data = json.loads(json.dumps(agent_config(mission, mission.agents["left"])))
    config = config_from_dict(data)
    assert config.machine is not None
    params = dict(config.machine.params)
    leader_frame = FollowAgentBehavior(params)
    ground = FollowAgentBehavior({**params, "offset": {"north_m": -8, "east_m": -8, "up_m": 0}})
    moving = AgentStatus(2, 0, 30.6375, -96.4787, 0.0, 1.5, 0.0, 90.0, 15)
    still = AgentStatus(2, 0, 30.6375, -96.4787, 0.0, 0.0, 0.0, 211.0, 15)
    print(f"microseconds per call, best / median of {ROUNDS} rounds of {CALLS:,} calls")
    for name, follower in (("north/east", ground), ("leader's frame", leader_frame)):
        for what, status in (("moving", moving), ("standing", still)):
            best, median = timed(lambda f=follower, s=status: f.goal(s))
            print(f"goal  {name:15} leader {what:9} {best:6.2f} / {median:6.2f}")
            best, median = timed(lambda f=follower, s=status: f.aim(s))
            print(f"aim   {name:15} leader {what:9} {best:6.2f} / {median:6.2f}")


if __name__ == "__main__":
    main()
