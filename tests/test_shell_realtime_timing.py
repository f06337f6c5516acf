"""The real-time shell's timing aids: microsecond waits on epoll, the frozen start-up heap,
the longest tick. No assertion here is about wall-clock time."""

from __future__ import annotations

import gc
import select
import selectors
import socket
from pathlib import Path
from typing import Any

import pytest

from clark_engine.mission.compiler import agent_config
from clark_engine.runtime.config import config_from_dict
from clark_engine.runtime.logbook import Logbook
from clark_engine.runtime.runtime import AgentRuntime
from clark_engine.shells import realtime
from clark_engine.shells.realtime import RealtimeShell
from clark_engine.validation import validate_file

ROOT = Path(__file__).resolve().parent.parent
MISSION = ROOT / "missions" / "cooperative_follow.yaml"


class FakeClock:
    def __init__(self) -> None:
        self.t = 1000.0

    def __call__(self) -> float:
        return self.t


class FakeSelector(selectors.BaseSelector):
    """Waits by moving the fake clock."""

    def __init__(self, clock: FakeClock) -> None:
        self.clock = clock
        self._map: dict[Any, selectors.SelectorKey] = {}

    def register(self, fileobj: Any, events: int, data: Any = None) -> selectors.SelectorKey:
        key = selectors.SelectorKey(fileobj, 0, events, data)
        self._map[fileobj] = key
        return key

    def unregister(self, fileobj: Any) -> selectors.SelectorKey:
        return self._map.pop(fileobj)

    def select(self, timeout: float | None = None) -> list[tuple[selectors.SelectorKey, int]]:
        assert timeout is not None
        self.clock.t += timeout
        return []

    def get_map(self) -> Any:
        return self._map


def _runtime(agent: str = "mcs") -> AgentRuntime:
    mission = validate_file(MISSION).mission
    assert mission is not None
    config = config_from_dict(agent_config(mission, mission.agents[agent]))
    return AgentRuntime(config, logbook=Logbook.in_memory(config), gps_epoch_ms=0)


def _fake_shell(**options: Any) -> tuple[RealtimeShell, FakeClock]:
    clock = FakeClock()
    shell = RealtimeShell(
        _runtime(), clock=clock, selector=FakeSelector(clock), origin_s=clock.t, **options
    )
    return shell, clock


# -- microsecond waits on epoll --------------------------------------------------------------


@pytest.mark.skipif(not hasattr(selectors, "EpollSelector"), reason="epoll is Linux's")
def test_precise_wait_returns_the_ready_keys_and_nothing_on_a_timeout() -> None:
    selector = selectors.EpollSelector()
    reader, writer = socket.socketpair()
    try:
        selector.register(reader, selectors.EVENT_READ, "radio")
        assert realtime._precise_wait(selector, 0.0005) == []
        writer.send(b"x")
        ready = realtime._precise_wait(selector, 5.0)  # returns as soon as it is readable
        assert [(key.data, mask) for key, mask in ready] == [("radio", selectors.EVENT_READ)]
    finally:
        selector.close()
        reader.close()
        writer.close()


@pytest.mark.skipif(not hasattr(selectors, "EpollSelector"), reason="epoll is Linux's")
def test_the_shell_waits_on_its_epoll_descriptor_and_falls_back_when_select_cannot(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    calls: list[int] = []
    real_select = select.select

    def counting(r: list[int], w: list[int], x: list[int], timeout: float) -> Any:
        calls.append(len(calls))
        return real_select(r, w, x, timeout)

    monkeypatch.setattr(select, "select", counting)
    shell = RealtimeShell(_runtime(), loop_hz=200, selector=selectors.EpollSelector())
    assert shell.run(max_ticks=3) == 0
    assert shell.stats.ticks == 3 and calls  # the waits between ticks went through select()

    def too_high(r: list[int], w: list[int], x: list[int], timeout: float) -> Any:
        raise ValueError("filedescriptor out of range in select()")

    monkeypatch.setattr(select, "select", too_high)
    shell = RealtimeShell(_runtime(), loop_hz=200, selector=selectors.EpollSelector())
    assert shell.run(max_ticks=3) == 0  # epoll alone, at its millisecond resolution
    assert shell.stats.ticks == 3


def test_other_selectors_are_used_as_they_are() -> None:
    shell, _clock = _fake_shell()
    assert shell.run(max_ticks=5) == 0
    assert shell.stats.ticks == 5


# -- the start-up heap, frozen while the loop runs ---------------------------------------------


def test_the_start_up_heap_is_frozen_while_the_loop_runs_and_released_after() -> None:
    before = gc.get_freeze_count()
    shell, _clock = _fake_shell()
    seen: list[int] = []
    shell.on_tick.append(lambda _shell, _now: seen.append(gc.get_freeze_count()))
    shell.run(max_ticks=3)
    assert seen and min(seen) > before
    assert gc.get_freeze_count() == before


def test_gc_freeze_false_leaves_the_collector_alone() -> None:
    before = gc.get_freeze_count()
    shell, _clock = _fake_shell(gc_freeze=False)
    seen: list[int] = []
    shell.on_tick.append(lambda _shell, _now: seen.append(gc.get_freeze_count()))
    shell.run(max_ticks=3)
    assert seen == [before] * 3


# -- the longest tick ----------------------------------------------------------------------------


def test_the_longest_tick_is_counted_and_summarised() -> None:
    shell, clock = _fake_shell()

    def slow_third_tick(shell: RealtimeShell, _now: float) -> None:
        if shell.stats.ticks == 3:
            clock.t += 0.03  # this tick's work takes 30 ms of the fake clock

    shell.on_tick.append(slow_third_tick)
    shell.run(max_ticks=5)
    assert shell.stats.max_tick_s == pytest.approx(0.03)
    assert shell.stats.tick_s == pytest.approx(0.03)  # the others took no fake time
    assert "ticks 6.00 ms on average, longest 30.0 ms" in shell.summary()
