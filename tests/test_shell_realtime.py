"""The real-time shell's loop: deadlines, overruns, testing mode, clean shutdown."""

from __future__ import annotations

import itertools
import selectors
import signal
import subprocess
import sys
from pathlib import Path
from typing import Any

from clark_engine.mission.compiler import agent_config
from clark_engine.runtime.config import AgentConfig, config_from_dict
from clark_engine.runtime.logbook import Logbook
from clark_engine.runtime.runtime import AgentRuntime
from clark_engine.shells.realtime import RealtimeShell
from clark_engine.validation import validate_file

ROOT = Path(__file__).resolve().parent.parent
MISSION = ROOT / "missions" / "cooperative_follow.yaml"


def _config(agent: str) -> AgentConfig:
    mission = validate_file(MISSION).mission
    assert mission is not None
    return config_from_dict(agent_config(mission, mission.agents[agent]))


class FakeClock:
    def __init__(self) -> None:
        self.t = 1000.0  # a monotonic clock is not 0 at boot

    def __call__(self) -> float:
        return self.t


class FakeSelector(selectors.BaseSelector):
    """Waits by moving the fake clock; ``stalls`` adds extra time at given waits."""

    def __init__(self, clock: FakeClock, stalls: dict[int, float] | None = None) -> None:
        self.clock = clock
        self.stalls = stalls or {}
        self.waits: list[float] = []
        self._map: dict[Any, selectors.SelectorKey] = {}

    def register(self, fileobj: Any, events: int, data: Any = None) -> selectors.SelectorKey:
        key = selectors.SelectorKey(fileobj, 0, events, data)
        self._map[fileobj] = key
        return key

    def unregister(self, fileobj: Any) -> selectors.SelectorKey:
        return self._map.pop(fileobj)

    def select(self, timeout: float | None = None) -> list[tuple[selectors.SelectorKey, int]]:
        assert timeout is not None and timeout >= 0
        self.clock.t += timeout + self.stalls.get(len(self.waits), 0.0)
        self.waits.append(timeout)
        return []

    def get_map(self) -> Any:
        return self._map


def _shell(agent: str, clock: FakeClock, selector: FakeSelector) -> RealtimeShell:
    config = _config(agent)
    runtime = AgentRuntime(config, logbook=Logbook.in_memory(config), gps_epoch_ms=0)
    return RealtimeShell(runtime, clock=clock, selector=selector, origin_s=clock.t)


def test_ticks_on_deadlines_from_the_start() -> None:
    clock = FakeClock()
    selector = FakeSelector(clock)
    shell = _shell("mcs", clock, selector)
    times: list[float] = []
    shell.on_tick.append(lambda _shell, now: times.append(now))
    assert shell.run(max_ticks=50) == 0
    assert shell.stats.ticks == 50
    assert shell.stats.overruns == 0
    # Tick k at k periods from the start, never drifting with the waits.
    assert [round(t / shell.period_s, 6) for t in times] == [float(k) for k in range(50)]
    assert shell.runtime.terminated and shell.runtime.logbook.closed


def test_an_overrun_is_counted_and_skips_to_the_next_deadline() -> None:
    clock = FakeClock()
    # At the 10th wait the process stalls for 2.5 periods (0.25 s at 10 Hz).
    selector = FakeSelector(clock, stalls={10: 0.25})
    shell = _shell("mcs", clock, selector)
    times: list[float] = []
    shell.on_tick.append(lambda _shell, now: times.append(now))
    shell.run(max_ticks=20)
    assert shell.stats.overruns == 1
    assert shell.stats.skipped_ticks == 2
    assert 0.25 <= shell.stats.worst_overrun_s < 0.3
    indexes = [t / shell.period_s for t in times]
    # The late tick runs at once (2.5 periods late); the next is on the original grid.
    gaps = [round(b - a, 6) for a, b in itertools.pairwise(indexes)]
    late = gaps.index(3.5)
    assert gaps[late + 1] == 0.5
    assert set(gaps[:late] + gaps[late + 2 :]) == {1.0}
    assert all(abs(i - round(i)) < 1e-6 for i in indexes[late + 2 :])
    log = shell.runtime.logbook.streams.interface.getvalue()
    assert "overrun: tick" in log and "skipped 2 deadline(s)" in log


def test_disabled_interfaces_drop_and_count_their_commands() -> None:
    clock = FakeClock()
    shell = _shell("slash_b", clock, FakeSelector(clock))
    assert shell.autopilot is None and shell.radio is None
    shell.run(max_ticks=5)
    # The vehicle still ticks and sends its heartbeat: to nowhere, counted.
    assert shell.stats.dropped_commands.get("SendPacket", 0) >= 1
    assert shell.runtime.terminated


def test_sigterm_stops_cleanly(tmp_path: Path) -> None:
    logs = tmp_path / "logs"
    process = subprocess.Popen(
        [
            sys.executable,
            "-m",
            "clark_engine",
            "run",
            str(MISSION),
            "--agent",
            "slash_b",
            "--no-radio",
            "--no-autopilot",
            "--logs",
            str(logs),
            "--plain",
        ],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
    )
    try:
        assert process.stdout is not None
        first = process.stdout.readline()
        assert first.startswith("clark run: slash_b"), first
        # The first status line is written by the first tick, inside the signal handlers'
        # block: a SIGTERM sent before then would kill the process, not stop it.
        status = process.stdout.readline()
        assert status.startswith("slash_b (vehicle)"), status
        process.send_signal(signal.SIGTERM)
        out, err = process.communicate(timeout=20)
    finally:
        if process.poll() is None:
            process.kill()
            process.communicate()
    assert process.returncode == 0, err
    assert "stopped (SIGTERM)" in out
    mission_log = (logs / "slash_b.mission.log").read_text()
    assert "real-time shell stopping (SIGTERM)" in mission_log
    assert "terminated; vehicle to HOLD" in mission_log
    assert (tmp_path / "state").exists() is False  # not authenticated: no stores written
