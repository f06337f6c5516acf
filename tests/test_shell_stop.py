"""The real-time shell's clean stop, and what a second (and third) signal may cut from it.

Issue 18 item 3: a second Ctrl-C during the stop raised ``ShellAborted`` out of the
middle of it (a traceback, exit 1) and skipped the rest: RC overrides not released,
replay marks not saved, links not closed. Here the signals are real (``raise_signal``
through :meth:`RealtimeShell.signals`' handler), raised at the exact moment the stop
first writes to the autopilot, or while it waits for the autopilot's answers; the
autopilot's end of the link is read with pymavlink. The clock and the selector are
fakes, so every wait is instantaneous and deterministic.
"""

from __future__ import annotations

import signal
from collections.abc import Callable
from pathlib import Path
from typing import Any

import pytest
from pymavlink.dialects.v20 import ardupilotmega as mavlink2
from test_shell_realtime import FakeClock, FakeSelector

from clark_engine.io.autopilot import AutopilotAdapter
from clark_engine.io.autopilot_settings import AutopilotSettings
from clark_engine.io.transports import MemoryPipe
from clark_engine.mission.compiler import agent_config
from clark_engine.runtime.commands import RcOverride
from clark_engine.runtime.config import AgentConfig, config_from_dict
from clark_engine.runtime.logbook import Logbook
from clark_engine.runtime.runtime import AgentRuntime
from clark_engine.shells.links import AutopilotLink
from clark_engine.shells.realtime import EXIT_ABORTED, RealtimeShell
from clark_engine.shells.stop import STOP_CONFIRM_S
from clark_engine.validation import validate_file

ROOT = Path(__file__).resolve().parent.parent
MISSION = ROOT / "missions" / "cooperative_follow.yaml"


def _config(agent: str) -> AgentConfig:
    mission = validate_file(MISSION).mission
    assert mission is not None
    return config_from_dict(agent_config(mission, mission.agents[agent]))


class SignallingPipe(MemoryPipe):
    """The engine's end of the autopilot link; raises ``signals`` at its first send once armed."""

    def __init__(self) -> None:
        super().__init__("engine")
        self.armed: list[signal.Signals] = []

    def send(self, data: bytes) -> int:
        sent = super().send(data)
        signals, self.armed = self.armed, []
        for sig in signals:
            signal.raise_signal(sig)  # the handler runs here, mid-stop
        return sent


class HookedSelector(FakeSelector):
    """A fake selector that calls ``on_wait`` at every wait (before the clock moves)."""

    def __init__(self, clock: FakeClock) -> None:
        super().__init__(clock)
        self.on_wait: Callable[[], None] | None = None

    def select(self, timeout: float | None = None) -> list[tuple[Any, int]]:
        if self.on_wait is not None:
            self.on_wait()
        return super().select(timeout)


class Bench:
    """slash_b's shell with an autopilot on a memory pipe, an RC override active."""

    def __init__(self) -> None:
        config = _config("slash_b")
        self.clock = FakeClock()
        self.selector = HookedSelector(self.clock)
        logbook = Logbook.in_memory(config)
        self.runtime = AgentRuntime(config, logbook=logbook)
        self.engine = SignallingPipe()
        self.vehicle = MemoryPipe("vehicle")
        self.engine._peer, self.vehicle._peer = self.vehicle, self.engine
        adapter = AutopilotAdapter(AutopilotSettings.from_config(config), logger=logbook.interface)
        self.shell = RealtimeShell(
            self.runtime,
            autopilot=AutopilotLink(adapter, lambda: self.engine, "memory"),
            clock=self.clock,
            selector=self.selector,
            origin_s=self.clock.t,
        )
        self.shell.on_tick.append(self._on_tick)
        self.said: list[str] = []
        self.shell.announce = self.said.append
        self.first: signal.Signals | None = None
        self.then: list[signal.Signals] = []
        self.hold = int(config.modes["HOLD"])

    def _on_tick(self, shell: RealtimeShell, now_s: float) -> None:
        if shell.stats.ticks == 2:  # the stick held by the behaviour
            link = shell.autopilot
            assert link is not None and link.transport is not None
            link.transport.send(link.adapter.command(RcOverride({1: 1600, 3: 1700}), now_s))
        if shell.stats.ticks == 4 and self.first is not None:
            self.vehicle.receive()  # what was sent before the stop: not looked at
            self.engine.armed = list(self.then)  # the next signals land in the stop
            signal.raise_signal(self.first)

    def run(self, max_ticks: int = 50) -> int:
        with self.shell.signals():
            return self.shell.run(max_ticks=max_ticks)

    def to_autopilot(self) -> list[Any]:
        """Every MAVLink message the stop sent the autopilot."""
        parser = mavlink2.MAVLink(None)
        parser.robust_parsing = True
        return list(parser.parse_buffer(self.vehicle.receive()) or [])

    def interface_log(self) -> str:
        return str(self.runtime.logbook.streams.interface.getvalue())


def _released(messages: list[Any]) -> bool:
    return any(
        m.get_type() == "RC_CHANNELS_OVERRIDE" and m.chan1_raw == 0 and m.chan3_raw == 0
        for m in messages
    )


def _to_hold(messages: list[Any], hold: int) -> bool:
    return any(
        m.get_type() == "COMMAND_LONG"
        and m.command == mavlink2.MAV_CMD_DO_SET_MODE
        and int(m.param2) == hold
        for m in messages
    )


@pytest.mark.parametrize(
    ("first", "then"),
    [
        (signal.SIGINT, [signal.SIGINT]),
        (signal.SIGINT, [signal.SIGINT, signal.SIGINT]),  # a third one likewise
        (signal.SIGTERM, [signal.SIGTERM]),
        (signal.SIGTERM, [signal.SIGINT]),
    ],
)
def test_a_second_signal_in_the_middle_of_the_stop_still_runs_its_safety_steps(
    first: signal.Signals, then: list[signal.Signals]
) -> None:
    """The second signal lands at the stop's first write to the autopilot (the moment
    ``ShellAborted`` used to fly out of): overrides released, HOLD sent, links closed."""
    bench = Bench()
    bench.first, bench.then = first, then
    code = bench.run()  # before: ShellAborted raised out of run()
    assert code == EXIT_ABORTED == 130
    sent = bench.to_autopilot()
    assert _released(sent), [m.get_type() for m in sent]
    assert _to_hold(sent, bench.hold), [m.get_type() for m in sent]
    assert bench.runtime.terminated and bench.runtime.logbook.closed
    log = bench.interface_log()
    assert f"stop shortened by a second {then[0].name}: skipped " in log
    assert "stop: links closed (autopilot)" in log
    assert bench.shell.autopilot is not None and bench.shell.autopilot.transport is None
    said = [line for line in bench.said if "stop shortened" in line]
    assert len(said) == 1 and said[0].startswith(f"stop shortened by a second {then[0].name}")
    mission_log = bench.runtime.logbook.streams.mission.getvalue()
    assert f"real-time shell stopping ({first.name})" in mission_log
    assert "terminated; vehicle to HOLD" in mission_log


def test_the_stop_waits_for_the_autopilots_answers_and_a_second_signal_cuts_the_wait() -> None:
    """A silent autopilot: the stop waits for the HOLD's answer (resending it) until a
    second signal, which skips only that wait; the line says what was skipped."""
    bench = Bench()
    bench.first = signal.SIGINT
    waits: list[float] = []

    def second_after_eight_waits() -> None:
        if bench.shell.stopped_by is not None and not bench.runtime.logbook.closed:
            waits.append(bench.clock.t)
            if len(waits) == 8:  # 0.8 s on the fake clock: past STOP_ANNOUNCE_S
                signal.raise_signal(signal.SIGINT)

    bench.selector.on_wait = second_after_eight_waits
    assert bench.run() == 130
    assert len(waits) == 8  # the stop waited, then stopped waiting at once
    sent = bench.to_autopilot()
    assert _released(sent) and _to_hold(sent, bench.hold)
    log = bench.interface_log()
    assert "stop: waiting up to 3 s for the autopilot to answer " in log
    assert "stop shortened by a second SIGINT: skipped waiting for the autopilot to answer " in log
    assert "stop: links closed (autopilot)" in log
    assert any("Ctrl-C again skips the wait" in line for line in bench.said)


def test_one_signal_waits_for_the_answers_at_most_stop_confirm_s_and_exits_0() -> None:
    """Without a second signal the wait is bounded: a silent autopilot costs
    STOP_CONFIRM_S (on the fake clock), the HOLD resent meanwhile, then exit 0."""
    bench = Bench()
    bench.first = signal.SIGINT
    assert bench.run() == 0
    sent = bench.to_autopilot()
    holds = [
        m
        for m in sent
        if m.get_type() == "COMMAND_LONG" and m.command == mavlink2.MAV_CMD_DO_SET_MODE
    ]
    assert len(holds) >= 2  # resent while waiting
    assert _released(sent)
    log = bench.interface_log()
    assert f"within {STOP_CONFIRM_S:g} s" in log
    assert "stop shortened" not in log
    assert "stop: links closed (autopilot)" in log


def test_a_fault_in_the_loop_still_runs_the_stop() -> None:
    """An exception from inside the loop is raised, after the stop left the vehicle safe."""
    bench = Bench()

    def fault(shell: RealtimeShell, now_s: float) -> None:
        if shell.stats.ticks == 4:
            bench.vehicle.receive()
            raise RuntimeError("a bug in a hook")

    bench.shell.on_tick.append(fault)
    with pytest.raises(RuntimeError, match="a bug in a hook"):
        bench.run()
    sent = bench.to_autopilot()
    assert _released(sent) and _to_hold(sent, bench.hold)
    assert bench.runtime.terminated and bench.runtime.logbook.closed
    assert "stop: links closed (autopilot)" in bench.interface_log()


def test_the_shortened_line_names_only_what_was_done() -> None:
    """An unkeyed mission has no replay marks: the line does not claim them."""
    bench = Bench()
    bench.first, bench.then = signal.SIGINT, [signal.SIGINT]
    assert bench.run() == 130
    (line,) = [line for line in bench.said if "stop shortened" in line]
    assert line.endswith(
        "still done: terminate sequence run (terminal mode, last heartbeat), "
        "RC overrides released, links closed"
    ), line


def test_the_stop_ends_its_wait_as_soon_as_the_autopilot_answers() -> None:
    """An autopilot that answers: the wait ends at its COMMAND_ACK, nothing announced, 0."""
    bench = Bench()
    bench.first = signal.SIGINT
    settings = AutopilotSettings.from_config(bench.runtime.config)
    autopilot = mavlink2.MAVLink(
        MemoryPipe("unused"), srcSystem=settings.system_id, srcComponent=settings.component_id
    )
    parser = mavlink2.MAVLink(None)
    waits: list[float] = []

    def answer() -> None:
        if bench.shell.stopped_by is None or bench.runtime.logbook.closed:
            return
        waits.append(bench.clock.t)
        for msg in parser.parse_buffer(bench.vehicle.receive()) or []:
            if msg.get_type() == "COMMAND_LONG":
                ack = autopilot.command_ack_encode(
                    msg.command,
                    mavlink2.MAV_RESULT_ACCEPTED,
                    target_system=settings.source_system_id,
                    target_component=settings.source_component_id,
                )
                bench.vehicle.send(ack.pack(autopilot))

    bench.selector.on_wait = answer
    assert bench.run() == 0
    log = bench.interface_log()
    assert "stop: waiting up to 3 s for the autopilot to answer SetMode HOLD (4)" in log
    assert "stop: the autopilot answered in 0.100 s" in log  # one wait of the loop's 0.1 s
    assert len(waits) == 1
    assert not any("Ctrl-C again" in line for line in bench.said)


def test_a_first_signal_during_a_stop_it_did_not_start_shortens_it() -> None:
    """The loop ended by itself (max_ticks here, --until in clark run): Ctrl-C during the
    stop's wait shortens it at once, rather than asking for a second one."""
    bench = Bench()  # no first signal: the loop runs its 6 ticks

    def once_in_the_stop() -> None:
        if bench.shell.stopped_by is not None and bench.shell.hurried_by is None:
            signal.raise_signal(signal.SIGINT)

    bench.selector.on_wait = once_in_the_stop
    assert bench.run(max_ticks=6) == 130
    assert bench.shell.stopped_by == "max_ticks"
    (line,) = [line for line in bench.said if "stop shortened" in line]
    assert line.startswith("stop shortened by SIGINT: skipped waiting for the autopilot"), line
    assert _released(bench.to_autopilot())
