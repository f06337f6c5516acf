"""Time the fleet table's per-packet and per-tick work with 1, 4, 16 and 100 agents.

Prints microseconds per call (best and median of several timing rounds, each
averaging many calls) for:

- receive(): one packet bundling Heartbeat, Agent Status and Agent Attitude from
  a known agent, counters rising, as in flight;
- check_timeouts(): every agent alive (the common tick), so the whole table is
  scanned and nothing is reported;
- csv_rows(): the row per agent the runtime appends each tick.

Run: python benchmarks/bench_fleet.py   (no assertions; figures go to docs/performance.md)
"""

from __future__ import annotations

import statistics
import sys
import time
from collections.abc import Callable

from clark_engine.link.fleet import FleetTable
from clark_engine.link.messages import AgentAttitude, AgentStatus, AgentType, Heartbeat
from clark_engine.link.packet import Packet

MISSION = 7
GPS_MS = 1_400_000_000_000
ROUNDS = 7


def per_call_us(fn: Callable[[], object], calls: int) -> tuple[float, float]:
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


def bundle(agent: int, counter: int) -> Packet:
    """The packet an agent sends on a tick where all three messages are due."""
    t_ms = GPS_MS + counter * 100
    messages = (
        Heartbeat(agent, t_ms, MISSION, AgentType.VEHICLE),
        AgentStatus(agent, t_ms, 30.63, -96.48, 60.0, 14.0, 0.2, 87.5, 10),
        AgentAttitude(agent, t_ms, 2.0, -1.5, 87.5),
    )
    return Packet(MISSION, agent, 0, counter, True, messages, 96)


def fleet(agents: int) -> FleetTable:
    """A table that has heard from ``agents`` peers (ids 2..agents+1)."""
    table = FleetTable(1, MISSION, 3.0, {i: f"v{i:03d}" for i in range(2, agents + 2)})
    for agent in range(2, agents + 2):
        table.receive(bundle(agent, 1), 0.0, GPS_MS + 150)
    return table


def bench(agents: int) -> tuple[tuple[float, float], ...]:
    """Timings of receive, check_timeouts and csv_rows with ``agents`` peers."""
    table = fleet(agents)
    ids = list(range(2, agents + 2))
    # Packets built beforehand, so only receive() is timed; counters keep rising.
    calls = 20_000
    packets = [bundle(ids[i % agents], 2 + i // agents) for i in range(calls * (ROUNDS + 1))]
    feed = iter(packets)

    def receive() -> object:
        return table.receive(next(feed), 1.0, GPS_MS + 180)

    timings = [per_call_us(receive, calls)]
    timings.append(per_call_us(lambda: table.check_timeouts(2.0), max(2_000, 200_000 // agents)))
    timings.append(per_call_us(lambda: table.csv_rows(2.0), max(200, 20_000 // agents)))
    return tuple(timings)


def main() -> None:
    """Print the table of figures."""
    print(f"Python {sys.version.split()[0]}; microseconds per call, best / median of {ROUNDS}")
    print(f"{'agents':>6}  {'receive (3 msgs)':>18}  {'check_timeouts':>16}  {'csv_rows':>16}")
    for agents in (1, 4, 16, 100):
        cells = [f"{best:7.2f} / {median:7.2f}" for best, median in bench(agents)]
        print(f"{agents:>6}  {cells[0]:>18}  {cells[1]:>16}  {cells[2]:>16}")


if __name__ == "__main__":
    main()
