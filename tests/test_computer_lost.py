"""A vehicle's mission computer killed mid-flight: the autopilot itself reacts in time.

Issue 17's done-when test for item 5. Navigation is streamed guided targets, so when the
mission computer dies the autopilot would fly on to the last target and hold there. Before
the behaviour starts, the engine sets ArduPilot's ground-station failsafe to watch the
mission computer's heartbeat (failsafe.computer_lost, computer_lost_s). Here a copter's
``clark run`` takes off and hovers in GUIDED on ArduCopter SITL served by ``clark
autopilot-sim --autopilot sitl`` (real time), is killed with SIGKILL (no terminate
sequence, no goodbye), and the autopilot's own MAVLink, as ``clark autopilot-sim``
announces it on the pilot's link, shows the reaction: the mission computer's last
heartbeat, then ArduCopter's "GCS Failsafe" text and its mode RTL, all on the autopilot's
clock. Then the same against the simulated autopilot (``clark autopilot-sim --autopilot
sim``, real time), whose port hears ``clark run``'s heartbeats directly.

Every process is a real ``python -m clark_engine`` child; nothing is mocked. Each wait is
for a line, with a timeout.
"""

from __future__ import annotations

import os
import queue
import re
import signal
import subprocess
import sys
import threading
import time
from collections.abc import Iterator
from pathlib import Path

import pytest
from sitl_here import real_install

from clark_engine.sitl.launcher import ENV_SITL

ROOT = Path(__file__).resolve().parent.parent
COMPUTER_LOST_S = 4.0
COPTER_SLACK_S = 0.5
"""ArduCopter checks its ground-station failsafe at 3 Hz (0.33 s, docs/sitl-measurements.md,
section 4), and autopilot-sim reads SITL's clock in 0.05 s steps."""
HEARTBEAT_PERIOD_S = 1.0
"""The mission computer's heartbeat period: its last one came at most this long before the
kill, so the reaction comes at least computer_lost_s less this after the kill."""
START_TIMEOUT_S = 120.0
"""Longest wait for the copter to hover: SITL boots, ArduCopter is ready after ~25 s."""
REACTION_TIMEOUT_S = 30.0
STOP_TIMEOUT_S = 60.0

MISSION = f"""
clark: 1
mission:
  id: 17
  name: computer-lost
  loop_hz: 10
  origin: {{lat: 30.6372, lon: -96.4787, alt_amsl_m: 90}}
agents:
  f450:
    id: 2
    profile: dji_f450
    launch: {{armed_by: engine}}
    failsafe: {{computer_lost: rtl, computer_lost_s: {COMPUTER_LOST_S:g}}}
    behavior:
      initial: climb
      states:
        climb: {{use: takeoff, with: {{alt_m: 10}}, transitions: {{done: hover}}}}
        hover:
          use: waypoint
          with: {{to: [10, 0, 10], tolerance_m: 1}}
          transitions: {{done: hovering}}
        hovering: {{use: wait, final: true}}
"""


SITL = real_install()


class Process:
    """A ``clark`` child whose stdout lines are collected as they come (a reader thread)."""

    def __init__(self, *args: str) -> None:
        env = dict(os.environ)
        if SITL is not None:
            env[ENV_SITL] = str(SITL.folder)
        self.popen = subprocess.Popen(
            [sys.executable, "-m", "clark_engine", *args],
            stdin=subprocess.DEVNULL,
            stdout=subprocess.PIPE,
            stderr=subprocess.STDOUT,  # read with the rest: an unread pipe could fill up
            text=True,
            env=env,
            cwd=ROOT,
        )
        self.lines: queue.Queue[str] = queue.Queue()
        self.seen: list[str] = []
        self._reader = threading.Thread(target=self._read, daemon=True)
        self._reader.start()

    def _read(self) -> None:
        assert self.popen.stdout is not None
        for line in self.popen.stdout:
            self.lines.put(line.rstrip())

    def wait_for(self, pattern: str, timeout_s: float) -> re.Match[str]:
        """The first line from now matching ``pattern``; fails after ``timeout_s``."""
        deadline = time.monotonic() + timeout_s
        while True:
            left = deadline - time.monotonic()
            if left <= 0:
                raise AssertionError(f"no line matching {pattern!r}; seen:\n" + self.tail())
            try:
                line = self.lines.get(timeout=min(left, 1.0))
            except queue.Empty:
                if self.popen.poll() is not None and self.lines.empty():
                    raise AssertionError(
                        f"ended {self.popen.returncode} before {pattern!r}:\n{self.tail()}"
                    ) from None
                continue
            self.seen.append(line)
            match = re.search(pattern, line)
            if match is not None:
                return match

    def wait_for_all(self, patterns: tuple[str, ...], timeout_s: float) -> list[re.Match[str]]:
        """The first line from now matching each pattern, in whatever order they come."""
        deadline = time.monotonic() + timeout_s
        found: dict[str, re.Match[str]] = {}
        while len(found) < len(patterns):
            left = deadline - time.monotonic()
            wanted = "|".join(f"(?:{p})" for p in patterns if p not in found)
            line = self.wait_for(wanted, left).string
            for pattern in patterns:
                match = re.search(pattern, line)
                if pattern not in found and match is not None:
                    found[pattern] = match
        return [found[p] for p in patterns]

    def drain(self) -> None:
        """Take every line already read."""
        while True:
            try:
                self.seen.append(self.lines.get_nowait())
            except queue.Empty:
                return

    def tail(self) -> str:
        return "\n".join(self.seen[-40:])

    def stop(self) -> None:
        if self.popen.poll() is None:
            self.popen.send_signal(signal.SIGTERM)
        try:
            self.popen.wait(timeout=STOP_TIMEOUT_S)
        except subprocess.TimeoutExpired:
            self.popen.kill()
            self.popen.wait()
        self._reader.join(timeout=STOP_TIMEOUT_S)
        assert self.popen.stdout is not None
        self.popen.stdout.close()


@pytest.fixture
def processes() -> Iterator[list[Process]]:
    started: list[Process] = []
    try:
        yield started
    finally:
        for process in reversed(started):
            process.stop()


def wait_for_log(path: Path, needle: str, server: Process, timeout_s: float) -> None:
    """Until ``needle`` is in the log (checked every 0.25 s); fails when the server ends."""
    deadline = time.monotonic() + timeout_s
    while needle not in (path.read_text(encoding="utf-8") if path.exists() else ""):
        if time.monotonic() > deadline or server.popen.poll() is not None:
            log = path.read_text(encoding="utf-8") if path.exists() else "(no log)"
            raise AssertionError(f"no {needle!r} in {path}:\n{log[-3000:]}\n{server.tail()}")
        time.sleep(0.25)


def fly_kill_and_watch(
    tmp_path: Path, processes: list[Process], autopilot: str
) -> tuple[float, float, float]:
    """Hover, kill ``clark run``; (last heartbeat, failsafe text, RTL) on the autopilot's clock."""
    mission = tmp_path / "computer_lost.yaml"
    mission.write_text(MISSION, encoding="utf-8")
    extra = (
        ["--autopilot", "sitl"]
        if autopilot == "sitl"
        else ["--listen", "127.0.0.1:0", "--ready-s", "5"]
    )
    server = Process("autopilot-sim", str(mission), "--agent", "f450", *extra)
    processes.append(server)
    connection = server.wait_for(r"--autopilot-connection (\S+)", START_TIMEOUT_S)[1]
    logs = tmp_path / "logs"
    computer = Process(
        "run", str(mission), "--agent", "f450", "--autopilot-connection", connection,
        "--no-radio", "--no-payload", "--plain", "--logs", str(logs),
    )  # fmt: skip
    processes.append(computer)
    server.wait_for(r"mission computer \(system 255\) heard at", START_TIMEOUT_S)
    mission_log = logs / "f450.mission.log"
    wait_for_log(mission_log, "are set and read back", server, START_TIMEOUT_S)
    wait_for_log(mission_log, "done: hover -> hovering", server, START_TIMEOUT_S)
    server.drain()
    modes = [line for line in server.seen if re.search(r": mode \w+ at", line)]
    assert modes and ": mode GUIDED at" in modes[-1], server.tail()  # GUIDED, not a pilot's mode

    computer.popen.send_signal(signal.SIGKILL)  # a crash: no terminate sequence
    computer.popen.wait(timeout=STOP_TIMEOUT_S)

    last, reacted, rtl = server.wait_for_all(
        (
            r"no heartbeat from the mission computer since ([\d.]+) s",
            r'autopilot says "GCS Failsafe" at ([\d.]+) s',
            r"mode RTL at ([\d.]+) s",
        ),
        REACTION_TIMEOUT_S,
    )
    return float(last[1]), float(reacted[1]), float(rtl[1])


def assert_reacted_in_time(last: float, reacted: float, rtl: float) -> None:
    # Not before the timeout (less the announcements' 0.05 s steps), and not much after.
    assert COMPUTER_LOST_S - 0.1 <= reacted - last <= COMPUTER_LOST_S + COPTER_SLACK_S, (
        last,
        reacted,
    )
    assert reacted <= rtl <= reacted + HEARTBEAT_PERIOD_S + 0.1  # the mode, in its next heartbeat


@pytest.mark.slow
@pytest.mark.sitl
@pytest.mark.skipif(SITL is None, reason=f"no ArduPilot SITL: set {ENV_SITL} to its folder")
def test_arducopter_returns_by_itself_when_clark_run_is_killed(
    tmp_path: Path, processes: list[Process]
) -> None:
    last, reacted, rtl = fly_kill_and_watch(tmp_path, processes, "sitl")
    assert_reacted_in_time(last, reacted, rtl)


@pytest.mark.slow
def test_the_simulated_arducopter_returns_by_itself_when_clark_run_is_killed(
    tmp_path: Path, processes: list[Process]
) -> None:
    last, reacted, rtl = fly_kill_and_watch(tmp_path, processes, "sim")
    assert_reacted_in_time(last, reacted, rtl)
