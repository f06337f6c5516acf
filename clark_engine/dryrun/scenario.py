"""What happens to a dry run from outside: the faults and the operator's script.

The mission's ``faults`` (and those given on the command line) are set on the radio mesh
and the agents before the run; the kills among them, and the operator's actions (moved by
``sim.jitter.operator_s``), are played by the engine at their times. Kept apart from the
engine's loop because they are the scenario a run is given, not how it advances.
"""

from __future__ import annotations

import math
import random
from collections.abc import Mapping, Sequence
from typing import Any

from clark_engine.dryrun.world import SimAgent, Window
from clark_engine.mission.model import Mission
from clark_engine.sim.radio import RadioMesh


def jittered_operator(mission: Mission, seed: int) -> list[tuple[float, int, Mapping[str, Any]]]:
    """The operator script as (time, index, action), in the order it plays.

    With ``sim.jitter.operator_s`` each action moves by a uniform draw within
    +-operator_s (never before 0), drawn in the order the actions are written from
    the run's own generator; an action that would then come before one it followed
    in the script waits for it, so the script's order is kept.
    """
    operator: list[tuple[float, int, Mapping[str, Any]]] = sorted(
        (float(item["at_s"]), index, item) for index, item in enumerate(mission.operator)
    )
    operator_s = float((mission.sim.get("jitter") or {}).get("operator_s", 0.0))
    if operator_s <= 0 or not operator:
        return operator
    rng = random.Random(f"{seed}:jitter:operator")
    shifts = [rng.uniform(-operator_s, operator_s) for _ in mission.operator]
    played: list[tuple[float, int, Mapping[str, Any]]] = []
    last_s = 0.0
    for at_s, index, item in operator:
        last_s = max(last_s, at_s + shifts[index])
        played.append((last_s, index, item))
    return played


def apply_faults(
    faults: Sequence[Mapping[str, Any]],
    *,
    mission: Mission,
    radio: RadioMesh,
    agents: Mapping[str, SimAgent],
) -> list[tuple[float, str]]:
    """Set the faults on the radio mesh and the agents; the kills are left to play.

    Returns:
        The kills, as (time, agent), in time order.
    """
    kills: list[tuple[float, str]] = []
    for fault in faults:
        ((kind, body),) = fault.items()
        start, end = float(body.get("from_s", 0.0)), float(body.get("to_s", math.inf))
        if kind == "kill":
            kills.append((float(body["at_s"]), str(body["agent"])))
        elif kind == "link_drop":
            a, b = (str(n) for n in body["between"])
            radio.drop_link(a, b, start, end)
        elif kind == "station_silent":
            for agent in mission.stations:
                radio.silence(agent.name, start, end)
        elif kind == "autopilot_disconnect":
            agents[str(body["agent"])].autopilot_down.append(Window(start, end))
        elif kind == "corrupt":
            radio.corrupt(float(body["share"]), start, end)
    return sorted(kills)  # (time, agent)
