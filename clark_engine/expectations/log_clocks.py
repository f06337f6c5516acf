"""Every agent's clock put on mission time, by the GPS time its log lines carry.

Why separate: the agents of a real run each count from their own start; one rule puts them
on one clock, for ``clark analyze --checks`` and ``clark replay`` alike.

t = 0 is the start of the station's runtime clock (the agent of role ``mcs``): the
operator script counts from it. Every agent's clock is mapped onto it through GPS time:
every text log line reads ``t=... gps_ms=...``, so an agent's offset is the median over
its lines of ``gps_ms - 1000 * t`` (the GPS time at its own t = 0; lines with
``gps_ms=-`` are left out; without any such line, its message log's ``now_s`` and
``gps_time_ms`` are used). An agent's time ``t`` is then
``t + (offset - station's offset) / 1000`` in mission time. Without a station log (or
without GPS time in it), t = 0 is the start of the agent that started first by GPS time;
an agent without any GPS time keeps its own clock, with a warning.
"""

from __future__ import annotations

import statistics
from collections.abc import Mapping
from typing import Final

from clark_engine.expectations.log_readers import AgentLogs

#: Spread (10th to 90th percentile) of an agent's GPS clock offset above which it is noted.
_CLOCK_SPREAD_NOTE_S: Final = 1.0

OTHER_TIME_BASE_S: Final = 6 * 3600.0
"""Agents of one run start within minutes of each other: a GPS time further than this from
the reference's is another time base (a simulated GPS clock against the system clock),
not a late start, and aligning by it would spread the run over days."""


def align_clocks(
    agents: Mapping[str, AgentLogs], roles: Mapping[str, str], notes: list[str]
) -> str:
    """Set every agent's :attr:`AgentLogs.shift_s`; returns what t = 0 is, in words.

    Args:
        agents: The agents' logs, read (their GPS offsets collected).
        roles: Agent -> its role (``mcs`` for a station: t = 0 is a station's start).
        notes: Where the warnings about clocks go.
    """
    offsets: dict[str, float] = {}
    for name, logs in agents.items():
        samples = logs.offsets_ms or logs.message_offsets_ms
        if not samples:
            continue
        offsets[name] = statistics.median(samples)
        if len(samples) >= 10:
            deciles = statistics.quantiles(samples, n=10)
            spread_s = (deciles[-1] - deciles[0]) / 1000
            if spread_s > _CLOCK_SPREAD_NOTE_S:
                notes.append(
                    f"{name}: its GPS time and runtime clock disagree by up to {spread_s:.1f} s "
                    "over the run (a GPS fix taken late, or a clock step); the median is used"
                )
    stations = sorted(n for n in agents if roles.get(n) == "mcs" and n in offsets)
    if stations:
        reference = offsets[stations[0]]
        origin = f"t=0 is the start of station {stations[0]}'s clock"
    elif offsets:
        first = min(offsets, key=lambda n: (offsets[n], n))
        reference = offsets[first]
        has_station = any(roles.get(n) == "mcs" for n in agents)
        why = "its log has no GPS time" if has_station else "no station log in the folder"
        origin = f"t=0 is the start of {first}, the first agent to start by GPS time ({why})"
        notes.append(f"{why}: mission time counts from {first}'s start, not the station's")
    else:
        reference = 0.0
        origin = "each agent's own clock (no GPS time in any log)"
    for name, logs in agents.items():
        if name in offsets and abs(offsets[name] - reference) / 1000 > OTHER_TIME_BASE_S:
            apart_s = abs(offsets[name] - reference) / 1000
            shown = f"{apart_s / 86_400:.0f} days" if apart_s >= 86_400 else f"{apart_s:.0f} s"
            logs.shift_s = 0.0
            logs.clock = "its own clock (its GPS time is on another time base)"
            notes.append(
                f"{name}: its GPS time is {shown} from the reference's, more than agents of "
                "one run start apart: its logs were stamped on another time base "
                "(docs/logs.md#time-bases), so its own start is taken as t=0"
            )
        elif name in offsets:
            logs.shift_s = (offsets[name] - reference) / 1000
            source = "mission and interface logs" if logs.offsets_ms else "message log"
            logs.clock = f"{logs.shift_s:+.3f} s, by GPS time ({source})"
        else:
            logs.shift_s = 0.0
            logs.clock = "its own clock (no GPS time in its logs)"
            notes.append(
                f"{name}: no GPS time in its logs; its own clock is taken as mission time, "
                "so its times may be off by the difference between its start and t=0's"
            )
    return origin
