"""The station's live view under load: update rate achieved and the station's CPU.

Issue 12, item 5: the station as a real ``clark run MISSION --agent mcs --view
127.0.0.1:0 --view-hz 5`` process over the UDP radio, fed by N agents' ClarkLink
traffic, for N = 4 and N = 100, measured for ``--window-s`` seconds (60) after a
warm-up (``--warm-s``, 15):

- **The mission** (generated in a temporary folder): station ``mcs`` (``mcs_laptop``)
  and vehicles ``r2`` ... ``rN`` (``traxxas_slash``), every radio ``udp_lan`` on a
  loopback port of its own, each vehicle's start spread on a 60 m grid and its
  behaviour a looping ``waypoint_tour`` round a 20 m square at its start (so the page
  draws N tours and N tracks), loop 10 Hz, telemetry as the repository's missions
  declare it: heartbeat 1 Hz, Agent Status 2 Hz (``--agent-status-hz``), Behavior
  State 1 Hz, Vehicle Health every 2 s to the station (``--no-health``: none, as before
  issue 17). Every vehicle has the default envelope (a 1000 m circle round its start,
  which the page draws: the UDP radio declares no range). ``--auth`` names a key file
  (``clark keygen``'s format): every packet is then tagged and checked.
- **The agents' traffic** comes from one load-generator process (this file with
  ``--generate``), not N ``clark run`` vehicles: 100 processes do not fit on a 2-core
  machine, and a vehicle in testing mode (``--no-autopilot``) has no vehicle state, so
  it sends no Agent Status at all. The generator binds every vehicle's radio address
  (the station's broadcasts land there and are read and dropped), keeps one
  :class:`~clark_engine.link.codec.Codec` per vehicle (its id, the mission's id and
  key: real packets, counters and tags, packed by the project's own link code) and,
  on a 10 Hz drift-free schedule, packs for each vehicle the messages due at that
  tick into one packet to the station, as a vehicle's runtime bundles its telemetry:
  a Heartbeat, an Agent Status on the vehicle's tour at 2 m/s in GUIDED, and a
  Behavior State (``tour``); and every 2 s a Vehicle Health, in a packet of its own to
  the station, as the repository's missions send it. ``r3`` reports a failsafe in force
  (its heartbeat's condition and its health), so the page shows one alarm throughout.
  The vehicles' phases are spread over the period, as
  agents started one after another are. GPS stamps come from the system clock, as
  the station's own (no autopilot) does, so the station's latency figures mean
  something.
- **The station** is ``clark run`` in testing mode (``--no-autopilot --no-payload``),
  ``--plain --no-console``, stopped with SIGTERM once measured (as Ctrl-C stops it;
  ``--until`` is only a cap). Its CPU is user + system from ``/proc/PID/stat`` over
  the window, as a share of one core, split into its loop's thread (the main thread)
  and the others (the view's server thread); overruns are those its interface log
  records within the window; the average and longest tick are its last line's (the
  whole run, start-up and the clients' connections included).
- **Variants** (``--variants``), the same load each time, so that each part of the
  view's cost shows as a difference: ``noview`` (no ``--view``), ``view-idle`` (the
  view served, nobody connected: the snapshots are built and published anyway),
  ``view-ws`` (the WebSocket client only) and ``view`` (the WebSocket client and the
  browser's page, as an operator watches).
- **A WebSocket client** (aiohttp, no ``Origin``: not a browser; loopback, so no
  token) counts the ``state`` messages it receives in the window, their size and
  their spacing, and checks the last state: agents heard, stale or lost, and the
  mean of the station's receive latencies.
- **A real browser**: headless Debian Chromium (``/usr/bin/chromium``) through
  Playwright, a fresh profile, the page's own URL. Without touching the page's code:
  Playwright's ``framereceived`` counts the state frames the page receives; an
  init script (Chrome DevTools' ``addScriptToEvaluateOnNewDocument``, outside the
  page's Content-Security-Policy) wraps the WebSocket's ``onmessage`` the page sets,
  to time each message's handling (``JSON.parse`` and the page's drawing calls,
  synchronous), counts animation frames and the longest gap between two, and
  observes long tasks (over 50 ms); CDP's ``Performance.getMetrics`` gives the
  renderer's main-thread task, script, layout and style time over the window, its
  JS heap and DOM node count; ``/proc`` gives the CPU of the browser's processes.

Every figure is printed with the machine's load average, how busy its CPUs were and
the steal over the window (:func:`bench_run.machine_text`): the machine is shared.

After the window of a ``view`` run, the page's JavaScript is profiled for
``--profile-page-s`` (10) seconds (CDP ``Profiler``): where its time goes, by function.

Run: ``python benchmarks/bench_station.py`` (N = 4 and 100, ``noview`` and ``view``,
about 7 minutes); ``--variants noview,view-idle,view-ws,view`` for every variant (about
13 minutes); ``--agents 4`` for one size; ``--auth`` for an authenticated mission.
Needs Playwright (``pip install playwright``) and ``/usr/bin/chromium``;
``--no-browser`` without.
"""

from __future__ import annotations

import argparse
import asyncio
import contextlib
import itertools
import json
import math
import os
import queue
import re
import select
import shutil
import signal
import socket
import statistics
import subprocess
import sys
import tempfile
import threading
import time
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

ROOT = Path(__file__).resolve().parent.parent
for _path in (ROOT, Path(__file__).resolve().parent, ROOT / "tests" / "browser"):
    if str(_path) not in sys.path:
        sys.path.insert(0, str(_path))

from bench_run import CLK_TCK, cpu_times, free_ports, machine_text  # noqa: E402
from station_page import CHROMIUM_FLAGS, DEBIAN_CHROMIUM  # noqa: E402 (the browser tests' launch)

MISSION_ID = 4245
LOOP_HZ = 10.0
GRID_M = 60.0
"""Spacing of the vehicles' start positions."""
SQUARE_M = 20.0
"""Side of each vehicle's tour, with its start at a corner."""
SPEED_M_S = 2.0
GUIDED = 15
"""ArduRover's GUIDED mode number (``pixhawk_ardurover``'s modes table)."""
START_TIMEOUT_S = 60.0
PAGE_SETTLE_S = 5.0
"""The window starts at least this long after the page drew its first state."""
VARIANTS = ("noview", "view-idle", "view-ws", "view")
"""The station without the view; with it and nobody connected; with the WebSocket client
only; with the WebSocket client and the browser's page."""
CHROMIUM = str(DEBIAN_CHROMIUM)
_TYPE = re.compile(r"--type=(\S+)")
_URL = re.compile(r"station view at (http://\S+)")
_OVERRUN = re.compile(r"^t=([\d.]+) .*overrun: tick \d+ started ([\d.]+) ms late", re.MULTILINE)
_STATUS_T = re.compile(r"\bt=\s*([\d.]+) s")
_STATUS_TICK = re.compile(r"longest tick ([\d.]+) ms")
_TICKS = re.compile(
    r"(\d+) ticks at .*?(\d+) overrun\(s\).*?ticks ([\d.]+) ms on average, longest ([\d.]+) ms"
)

PAGE_PROBE = """
(() => {
  const probe = {handled: 0, handle_ms: [], frames: 0, max_frame_gap_ms: 0,
                 long_tasks: 0, long_task_ms: 0, last_frame: 0, closes: []};
  window.__clarkProbe = probe;
  const desc = Object.getOwnPropertyDescriptor(WebSocket.prototype, "onmessage");
  Object.defineProperty(WebSocket.prototype, "onmessage", {
    configurable: true, enumerable: true,
    get() { return desc.get.call(this); },
    set(handler) {
      if (typeof handler !== "function") { desc.set.call(this, handler); return; }
      desc.set.call(this, function (event) {
        const t0 = performance.now();
        try { return handler.call(this, event); }
        finally {
          if (typeof event.data === "string" && event.data.startsWith('{"type":"state"')) {
            probe.handled += 1;
            probe.handle_ms.push(performance.now() - t0);
          }
        }
      });
    },
  });
  // Every close of the page's WebSocket, with its code (1006: the connection dropped).
  const closeDesc = Object.getOwnPropertyDescriptor(WebSocket.prototype, "onclose");
  Object.defineProperty(WebSocket.prototype, "onclose", {
    configurable: true, enumerable: true,
    get() { return closeDesc.get.call(this); },
    set(handler) {
      if (typeof handler !== "function") { closeDesc.set.call(this, handler); return; }
      closeDesc.set.call(this, function (event) {
        probe.closes.push({code: event.code, reason: event.reason, at_ms: performance.now()});
        return handler.call(this, event);
      });
    },
  });
  const frame = (t) => {
    if (probe.last_frame) {
      probe.max_frame_gap_ms = Math.max(probe.max_frame_gap_ms, t - probe.last_frame);
    }
    probe.last_frame = t; probe.frames += 1; requestAnimationFrame(frame);
  };
  requestAnimationFrame(frame);
  try {
    new PerformanceObserver((list) => {
      for (const entry of list.getEntries()) {
        probe.long_tasks += 1; probe.long_task_ms += entry.duration;
      }
    }).observe({type: "longtask", buffered: true});
  } catch (e) { probe.long_tasks = -1; }
})();
"""
"""Injected before the page's own script: times the page's handling of each state."""

PROBE_RESET = """
(() => { const p = window.__clarkProbe; const out = {handled: p.handled,
  handle_ms: p.handle_ms, frames: p.frames, max_frame_gap_ms: p.max_frame_gap_ms,
  long_tasks: p.long_tasks, long_task_ms: p.long_task_ms, closes: p.closes,
  nodes: document.getElementsByTagName("*").length};
  p.handled = 0; p.handle_ms = []; p.frames = 0; p.max_frame_gap_ms = 0; p.closes = [];
  p.long_tasks = 0; p.long_task_ms = 0; return out; })()
"""
"""Reads the probe's counts since the last call and starts them again."""


# -- the mission -----------------------------------------------------------------------------


def agent_name(i: int) -> str:
    """``mcs`` for 1, ``r2``, ``r3``... for the vehicles."""
    return "mcs" if i == 1 else f"r{i}"


def start_of(i: int, vehicles: int) -> tuple[float, float]:
    """Vehicle ``i``'s start (north, east metres): a square grid round the origin."""
    side = max(1, math.ceil(math.sqrt(vehicles)))
    k = i - 2
    return (k // side - (side - 1) / 2) * GRID_M, (k % side - (side - 1) / 2) * GRID_M


def tour_of(start: tuple[float, float]) -> list[tuple[float, float]]:
    """A vehicle's tour: a square from its start, counter-clockwise seen from above."""
    n, e = start
    s = SQUARE_M
    return [(n, e), (n + s, e), (n + s, e + s), (n, e + s)]


def mission_text(
    agents: int,
    ports: Sequence[int],
    agent_status_hz: float,
    key_file: str | None,
    health: bool = True,
) -> str:
    """The generated mission: station ``mcs`` and ``agents - 1`` touring rovers on UDP."""
    lines = [
        "clark: 1",
        "mission:",
        f"  id: {MISSION_ID}",
        f"  name: bench-station-{agents}",
        f"  description: the station view's benchmark, {agents} agents.",
        f"  loop_hz: {LOOP_HZ:g}",
        "  heartbeat_timeout_s: 3",
        "  origin: {lat: 30.6372, lon: -96.4787, alt_amsl_m: 90}",
    ]
    if key_file:
        lines.append(f"  key_file: {key_file}")
    lines.append("agents:")
    for i in range(1, agents + 1):
        radio = f'{{profile: udp_lan, address: "127.0.0.1:{ports[i - 1]}"}}'
        lines += [
            f"  {agent_name(i)}:",
            f"    id: {i}",
            f"    profile: {'mcs_laptop' if i == 1 else 'traxxas_slash'}",
            f"    hardware: {{radio: {radio}}}",
        ]
        if i == 1:
            lines.append("    telemetry: {heartbeat: 1}")
            continue
        start = start_of(i, agents - 1)
        points = ", ".join(f"[{n:g}, {e:g}]" for n, e in tour_of(start))
        sends_health = ", vehicle_health: {rate_hz: 0.5, to: [mcs]}" if health else ""
        lines += [
            f"    position: [{start[0]:g}, {start[1]:g}]",
            f"    telemetry: {{heartbeat: 1, agent_status: {agent_status_hz:g}, "
            f"behavior_state: 1{sends_health}}}",
            "    behavior:",
            "      initial: tour",
            "      states:",
            "        tour:",
            "          use: waypoint_tour",
            f"          with: {{loop: true, tolerance_m: 2, speed_m_s: {SPEED_M_S:g}, "
            f"waypoints: [{points}]}}",
            "          transitions: {deactivate: idle}",
            "        idle: {use: hold, transitions: {activate: tour}}",
        ]
    return "\n".join(lines) + "\n"


# -- the load generator (a child process) ----------------------------------------------------


def on_tour(start: tuple[float, float], distance_m: float) -> tuple[float, float, float]:
    """Where a vehicle is after ``distance_m`` round its tour: north, east, heading."""
    s = SQUARE_M
    d = distance_m % (4 * s)
    leg, along = int(d // s), d % s
    n, e = start
    # north, then east, then south, then west
    offsets = ((along, 0.0), (s, along), (s - along, s), (0.0, s - along))
    headings = (0.0, 90.0, 180.0, 270.0)
    dn, de = offsets[leg]
    return n + dn, e + de, headings[leg]


def generate(spec: dict[str, Any]) -> None:
    """The vehicles' traffic to the station until SIGTERM (runs in a child process).

    ``spec``: ``agents`` (station included), ``ports`` (every agent's UDP port, the
    station's first), ``agent_status_hz``, ``key_file`` (None: unauthenticated),
    ``seconds`` (the longest it runs), ``health`` (Vehicle Health every 2 s).
    """
    from clark_engine.io.autopilot_decode import gps_time_ms_from_unix_us
    from clark_engine.link import (
        AgentStatus,
        AgentType,
        BehaviorState,
        Codec,
        Condition,
        Heartbeat,
        Message,
        PrearmState,
        VehicleHealth,
        load_key,
    )
    from clark_engine.mission.geo import LocalPoint, Origin, to_global

    agents = int(spec["agents"])
    ports = [int(p) for p in spec["ports"]]
    key = load_key(spec["key_file"]) if spec.get("key_file") else None
    origin = Origin(30.6372, -96.4787, 90.0)
    station = ("127.0.0.1", ports[0])
    stop = False

    def stopped(_signum: int, _frame: object) -> None:
        nonlocal stop
        stop = True

    signal.signal(signal.SIGTERM, stopped)
    signal.signal(signal.SIGINT, stopped)
    ids = list(range(2, agents + 1))
    socks: dict[int, socket.socket] = {}
    codecs: dict[int, Codec] = {}
    for i in ids:
        sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        sock.bind(("127.0.0.1", ports[i - 1]))
        sock.setblocking(False)
        socks[i] = sock
        codecs[i] = Codec(MISSION_ID, i, key)
    every = {
        "heartbeat": round(LOOP_HZ / 1.0),
        "agent_status": max(1, round(LOOP_HZ / float(spec["agent_status_hz"]))),
        "behavior_state": round(LOOP_HZ / 1.0),
        "vehicle_health": round(LOOP_HZ / 0.5),
    }
    health = bool(spec.get("health", True))
    in_failsafe = 3  # r3: its failsafe in force all along, one alarm on the page
    starts = {i: start_of(i, agents - 1) for i in ids}
    period = 1.0 / LOOP_HZ
    t0 = time.monotonic()
    readers = list(socks.values())
    sent = packets_bytes = received = tick = 0
    print(json.dumps({"ready": True}), flush=True)
    while not stop and time.monotonic() - t0 < float(spec["seconds"]):
        deadline = t0 + tick * period
        while not stop:
            wait = deadline - time.monotonic()
            if wait <= 0:
                break
            readable, _, _ = select.select(readers, [], [], wait)
            for sock in readable:
                with contextlib.suppress(BlockingIOError, ConnectionRefusedError):
                    while sock.recv(65536):
                        received += 1
        if stop:
            break
        now_s = time.monotonic() - t0
        gps = gps_time_ms_from_unix_us(time.time_ns() // 1000)
        for index, i in enumerate(ids):
            phase = tick + index  # agents started one after another: spread phases
            messages: list[Message] = []
            failsafe = health and i == in_failsafe
            condition = Condition.FAILSAFE if failsafe else Condition.OK
            if phase % every["heartbeat"] == 0:
                messages.append(Heartbeat(i, gps, MISSION_ID, AgentType.VEHICLE, condition))
            if phase % every["agent_status"] == 0:
                north, east, heading = on_tour(starts[i], SPEED_M_S * now_s + index * 7.0)
                lat, lon, _ = to_global(LocalPoint(north, east, 0.0), origin)
                messages.append(AgentStatus(i, gps, lat, lon, 0.0, SPEED_M_S, 0.0, heading, GUIDED))
            if phase % every["behavior_state"] == 0:
                messages.append(BehaviorState(i, gps, ("tour",), ""))
            packets = codecs[i].encode(messages, 0) if messages else []
            if health and phase % every["vehicle_health"] == 0:
                vehicle = VehicleHealth(
                    i,
                    gps,
                    armed=True,
                    battery_v=12.6,
                    battery_pct=max(0, 100 - int(now_s / 36)),
                    gps_fix_type=3,
                    satellites=10,
                    prearm=PrearmState.PASSING,
                    failsafe="hold: mcs_lost" if failsafe else "",
                )
                packets += codecs[i].encode([vehicle], 1)  # to the station alone
            for data in packets:
                with contextlib.suppress(BlockingIOError, ConnectionRefusedError):
                    socks[i].sendto(data, station)
                sent += 1
                packets_bytes += len(data)
        tick += 1
    for sock in socks.values():
        sock.close()
    print(
        json.dumps({"packets": sent, "bytes": packets_bytes, "received": received, "ticks": tick}),
        flush=True,
    )


# -- processes -------------------------------------------------------------------------------


def thread_cpu_s(pid: int) -> tuple[float, float]:
    """User + system CPU seconds of a process: its main thread's and the other threads'."""
    main = other = 0.0
    for task in Path(f"/proc/{pid}/task").iterdir():
        with contextlib.suppress(FileNotFoundError, ProcessLookupError):
            fields = (task / "stat").read_text().rsplit(")", 1)[1].split()
            seconds = (int(fields[11]) + int(fields[12])) / CLK_TCK
            if int(task.name) == pid:
                main += seconds
            else:
                other += seconds
    return main, other


def process_cpu_s(pid: int) -> float:
    """User + system CPU seconds of a live process (all its threads), from /proc."""
    fields = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()
    return (int(fields[11]) + int(fields[12])) / CLK_TCK


def browser_pids(user_data_dir: str) -> dict[int, str]:
    """Chromium's processes of this profile: pid -> kind (browser, renderer, gpu-process...).

    The browser process is the one whose command line names the profile; the others are
    its descendants (the zygote's children do not repeat ``--user-data-dir``).
    """
    parents: dict[int, int] = {}
    kinds: dict[int, str] = {}
    roots: set[int] = set()
    for entry in Path("/proc").iterdir():
        if not entry.name.isdigit():
            continue
        try:
            # Chromium rewrites its command line as one string: search it as text.
            text = (entry / "cmdline").read_bytes().replace(b"\0", b" ").decode(errors="replace")
            stat = (entry / "stat").read_text().rsplit(")", 1)[1].split()
        except OSError:
            continue
        pid = int(entry.name)
        parents[pid] = int(stat[1])
        found_type = _TYPE.search(text)
        kinds[pid] = found_type[1] if found_type else "browser"
        if found_type is None and f"--user-data-dir={user_data_dir}" in text:
            roots.add(pid)
    found: dict[int, str] = {}
    for pid in kinds:
        ancestor = pid
        for _ in range(16):
            if ancestor in roots:
                found[pid] = kinds[pid]
                break
            ancestor = parents.get(ancestor, 0)
            if ancestor <= 1:
                break
    return found


def browser_cpu_s(pids: dict[int, str]) -> dict[str, float]:
    """CPU seconds by kind of process (processes that ended are left out)."""
    out: dict[str, float] = {}
    for pid, kind in pids.items():
        with contextlib.suppress(OSError, IndexError):
            out[kind] = out.get(kind, 0.0) + process_cpu_s(pid)
    return out


def rss_mb(pid: int) -> float:
    """A process's resident memory in MB (VmRSS)."""
    for line in Path(f"/proc/{pid}/status").read_text().splitlines():
        if line.startswith("VmRSS:"):
            return int(line.split()[1]) / 1024
    return float("nan")


class Drain:
    """Reads a child's stdout and stderr on threads as they come, so a pipe never fills.

    ``clark run --plain`` writes a status line every 5 s, one peer per part (100 agents:
    about 8 kB a line); a pipe nobody reads fills, and the station's loop would block
    writing to it.
    """

    def __init__(self, process: subprocess.Popen[str]) -> None:
        self.process = process
        self.out: list[str] = []
        self.err: list[str] = []
        self._lines: queue.Queue[str] = queue.Queue()
        self._threads = [
            threading.Thread(target=self._read, args=(process.stdout, True), daemon=True),
            threading.Thread(target=self._read, args=(process.stderr, False), daemon=True),
        ]
        for thread in self._threads:
            thread.start()

    def _read(self, stream: Any, is_out: bool) -> None:
        for line in stream:
            (self.out if is_out else self.err).append(line)
            if is_out:
                self._lines.put(line)
        if is_out:
            self._lines.put("")

    async def line(self, timeout_s: float = START_TIMEOUT_S) -> str:
        """The next stdout line ("" at its end)."""
        try:
            return await asyncio.to_thread(self._lines.get, True, timeout_s)
        except queue.Empty:
            return ""

    async def wait_for(
        self, pattern: re.Pattern[str], timeout_s: float = START_TIMEOUT_S
    ) -> re.Match[str] | None:
        """The first line of either stream that matches, as it comes (None: not in time)."""
        deadline = time.monotonic() + timeout_s
        while time.monotonic() < deadline:
            for line in (*self.out, *self.err):
                found = pattern.search(line)
                if found is not None:
                    return found
            if self.process.poll() is not None and not any(t.is_alive() for t in self._threads):
                return None
            await asyncio.sleep(0.1)
        return None

    def join(self, timeout_s: float = 10.0) -> None:
        """Wait for both streams to end."""
        for thread in self._threads:
            thread.join(timeout_s)


def stop_process(process: subprocess.Popen[str] | None, grace_s: float = 10.0) -> None:
    """SIGTERM, then SIGKILL after ``grace_s``: this process's own children only."""
    if process is None or process.poll() is not None:
        return
    process.send_signal(signal.SIGTERM)
    try:
        process.wait(grace_s)
    except subprocess.TimeoutExpired:
        process.kill()
        process.wait()


# -- one run ---------------------------------------------------------------------------------


def percentile(values: Sequence[float], q: float) -> float:
    """The ``q`` quantile (0..1), nearest rank; NaN for no values."""
    ordered = sorted(values)
    if not ordered:
        return float("nan")
    return ordered[min(len(ordered) - 1, max(0, math.ceil(q * len(ordered)) - 1))]


@dataclass
class Result:
    """What one run measured (the window's figures unless said otherwise)."""

    agents: int
    variant: str
    window_s: float = 0.0
    station_cpu: float = 0.0
    """Share of one core, all threads."""
    loop_cpu: float = 0.0
    other_cpu: float = 0.0
    generator_cpu: float = 0.0
    station_rss_mb: float = 0.0
    overruns: int = 0
    overrun_worst_ms: float = 0.0
    overrun_times: list[tuple[float, float]] = field(default_factory=list)
    """Every overrun of the run: (its time on the station's clock, how late, ms)."""
    window_from_s: float = 0.0
    """When the window began, on the station's clock."""
    longest_tick_steps: list[tuple[float, float]] = field(default_factory=list)
    """When the longest tick so far grew: (the status line's time, the new longest, ms)."""
    summary: str = ""
    tick_avg_ms: float = float("nan")
    tick_max_ms: float = float("nan")
    ws_states: int = 0
    ws_bytes: list[int] = field(default_factory=list)
    ws_gaps_ms: list[float] = field(default_factory=list)
    hello_bytes: int = 0
    ws_closed: str = ""
    warm_closes: list[int] = field(default_factory=list)
    """Close codes of the page's WebSocket during the warm-up (it reconnects after each)."""
    """How the WebSocket client's connection ended before the end, if it did."""
    heard: int = 0
    stale_or_lost: int = 0
    latency_ms: float = float("nan")
    page: dict[str, Any] = field(default_factory=dict)
    machine: str = ""
    load: tuple[float, float, float] = (0.0, 0.0, 0.0)
    generator: dict[str, Any] = field(default_factory=dict)


async def ws_client(url: str, result: Result, window: asyncio.Event, done: asyncio.Event) -> None:
    """Read the view's WebSocket as a tool would; count states while ``window`` is set."""
    import aiohttp

    ws_url = url.split("?", 1)[0].rstrip("/").replace("http://", "ws://") + "/ws"
    last: float | None = None
    async with aiohttp.ClientSession() as session, session.ws_connect(ws_url) as ws:
        while not done.is_set():
            try:
                message = await asyncio.wait_for(ws.receive(), 0.5)
            except TimeoutError:
                continue
            if message.type != aiohttp.WSMsgType.TEXT:
                if not done.is_set():
                    result.ws_closed = f"{message.type.name} {ws.close_code}"
                break
            text = message.data
            if text.startswith('{"type":"hello"'):
                result.hello_bytes = len(text.encode())
                continue
            if not text.startswith('{"type":"state"'):
                continue
            now = time.monotonic()
            if window.is_set():
                result.ws_states += 1
                result.ws_bytes.append(len(text.encode()))
                if last is not None:
                    result.ws_gaps_ms.append((now - last) * 1000)
                state = json.loads(text)
                agents = [a for a in state["agents"] if a["role"] != "mcs"]
                result.heard = sum(1 for a in agents if a["heard"])
                result.stale_or_lost = sum(1 for a in agents if a["stale"] or a["lost"])
                latencies = [
                    a["link"]["latency_mean_ms"]
                    for a in agents
                    if a.get("link") and a["link"].get("latency_mean_ms") is not None
                ]
                if latencies:
                    result.latency_ms = statistics.fmean(latencies)
            last = now


async def measure(
    agents: int,
    variant: str,
    work: Path,
    *,
    warm_s: float,
    window_s: float,
    agent_status_hz: float,
    auth: bool,
    browser: bool,
    profile_s: float = 0.0,
    view_hz: float = 5.0,
    health: bool = True,
) -> Result:
    """One run: the station (with or without the view) under N agents' traffic.

    With ``profile_s``, the page's JavaScript is then profiled for that long (after the
    window, so the profiler's cost is not in its figures).
    """
    folder = Path(tempfile.mkdtemp(prefix=f"station-{agents}-{variant}-", dir=work))
    ports = free_ports(agents)
    key_file = None
    if auth:
        from clark_engine.link import generate_key_file

        generate_key_file(folder / "mission.key")
        key_file = "mission.key"
    mission = folder / "mission.yaml"
    mission.write_text(
        mission_text(agents, ports, agent_status_hz, key_file, health), encoding="utf-8"
    )
    if variant not in VARIANTS:
        raise ValueError(f"variant {variant!r}: one of {', '.join(VARIANTS)}")
    view = variant != "noview"
    browser = browser and variant == "view"
    client = variant in ("view", "view-ws")
    # A cap only: the run is ended by SIGTERM once measured, as an operator's Ctrl-C.
    until_s = warm_s + window_s + profile_s + 300.0
    args = [
        sys.executable,
        "-m",
        "clark_engine",
        "run",
        str(mission),
        "--agent",
        "mcs",
        "--no-autopilot",
        "--no-payload",
        "--plain",
        "--no-console",
        "--logs",
        str(folder / "logs"),
        "--until",
        f"{until_s:g}",
    ]
    if view:
        args += ["--view", "127.0.0.1:0", "--view-hz", f"{view_hz:g}"]
    result = Result(agents, variant)
    station: subprocess.Popen[str] | None = None
    generator: subprocess.Popen[str] | None = None
    playwright_cm: Any = None
    browser_obj: Any = None
    user_data = tempfile.mkdtemp(prefix="chromium-", dir=work)
    window = asyncio.Event()
    done = asyncio.Event()
    ws_task: asyncio.Task[None] | None = None
    try:
        station = subprocess.Popen(
            args,
            cwd=ROOT,
            stdin=subprocess.DEVNULL,
            stdout=subprocess.PIPE,
            stderr=subprocess.PIPE,
            text=True,
        )
        station_io = Drain(station)
        first = await station_io.line()
        loop_start = time.monotonic()
        if not first.startswith("clark run: "):
            station_io.join()
            raise RuntimeError(f"the station did not start: {first}{''.join(station_io.err)}")
        url = ""
        if view:
            line = await station_io.line()
            found = _URL.search(line)
            if found is None:
                raise RuntimeError(f"no view URL in {line!r}")
            url = found[1]
        spec = {
            "agents": agents,
            "ports": ports,
            "agent_status_hz": agent_status_hz,
            "key_file": str(folder / key_file) if key_file else None,
            "seconds": until_s + 10.0,
            "health": health,
        }
        generator = subprocess.Popen(
            [sys.executable, __file__, "--generate", json.dumps(spec)],
            cwd=ROOT,
            stdout=subprocess.PIPE,
            stderr=subprocess.PIPE,
            text=True,
        )
        generator_io = Drain(generator)
        ready = await generator_io.line()
        if "ready" not in ready:
            generator_io.join()
            raise RuntimeError(f"the generator did not start: {ready}{''.join(generator_io.err)}")
        page = None
        cdp = None
        page_ready = 0.0
        frames: list[float] = []
        connections: list[float] = []
        if client:
            ws_task = asyncio.create_task(ws_client(url, result, window, done))
        if browser:
            from playwright.async_api import async_playwright

            playwright_cm = async_playwright()
            pw = await playwright_cm.__aenter__()
            # A persistent context is Playwright's way to a --user-data-dir of one's own.
            browser_obj = await pw.chromium.launch_persistent_context(
                user_data,
                executable_path=CHROMIUM,
                args=list(CHROMIUM_FLAGS),
                viewport={"width": 1400, "height": 900},
            )
            page = browser_obj.pages[0] if browser_obj.pages else await browser_obj.new_page()
            await page.add_init_script(PAGE_PROBE)

            def on_websocket(ws: Any) -> None:
                connections.append(time.monotonic())

                def on_frame(payload: str | bytes) -> None:
                    state = isinstance(payload, str) and payload.startswith('{"type":"state"')
                    if window.is_set() and state:
                        frames.append(time.monotonic())

                ws.on("framereceived", on_frame)

            page.on("websocket", on_websocket)
            await page.goto(url)
            cdp = await page.context.new_cdp_session(page)
            await cdp.send("Performance.enable")
            await page.wait_for_function("window.__clarkProbe.handled > 0", timeout=60_000)
            page_ready = time.monotonic()
        # warm-up: every agent heard, the page drawn, start-up's CPU left out
        begin = max(loop_start + warm_s, page_ready + PAGE_SETTLE_S if page else 0.0)
        await asyncio.sleep(max(0.0, begin - time.monotonic()))
        pids = browser_pids(user_data) if page is not None else {}
        metrics0: dict[str, float] = {}
        if page is not None and cdp is not None:
            warm = await page.evaluate(PROBE_RESET)
            result.warm_closes = [int(c["code"]) for c in warm["closes"]]
            metrics0 = {
                m["name"]: m["value"] for m in (await cdp.send("Performance.getMetrics"))["metrics"]
            }
        browser0 = browser_cpu_s(pids)
        load = os.getloadavg()
        machine0 = cpu_times()
        main0, other0 = thread_cpu_s(station.pid)
        gen0 = process_cpu_s(generator.pid)
        t0 = time.monotonic()
        window_from_s = t0 - loop_start
        connections_before = len(connections)
        window.set()
        await asyncio.sleep(window_s)
        window.clear()
        wall = time.monotonic() - t0
        main1, other1 = thread_cpu_s(station.pid)
        gen1 = process_cpu_s(generator.pid)
        result.machine = machine_text(machine0, cpu_times())
        load1 = os.getloadavg()
        result.load = (max(load[0], load1[0]), load1[1], load1[2])
        result.window_s = wall
        result.loop_cpu = (main1 - main0) / wall
        result.other_cpu = (other1 - other0) / wall
        result.station_cpu = result.loop_cpu + result.other_cpu
        result.generator_cpu = (gen1 - gen0) / wall
        result.station_rss_mb = rss_mb(station.pid)
        if page is not None and cdp is not None:
            probe = await page.evaluate(PROBE_RESET)
            metrics1 = {
                m["name"]: m["value"] for m in (await cdp.send("Performance.getMetrics"))["metrics"]
            }
            browser1 = browser_cpu_s(pids)
            result.page = {
                "connections": len(connections) - connections_before,
                "closes": probe["closes"],
                "frames": len(frames),
                "frame_rate": len(frames) / wall,
                "frame_gap_max_ms": max((b - a) * 1000 for a, b in itertools.pairwise(frames))
                if len(frames) > 1
                else float("nan"),
                "handled": probe["handled"],
                "handle_p50_ms": percentile(probe["handle_ms"], 0.5),
                "handle_p99_ms": percentile(probe["handle_ms"], 0.99),
                "handle_max_ms": max(probe["handle_ms"], default=float("nan")),
                "animation_fps": probe["frames"] / wall,
                "animation_gap_max_ms": probe["max_frame_gap_ms"],
                "long_tasks": probe["long_tasks"],
                "long_task_ms": probe["long_task_ms"],
                "nodes": probe["nodes"],
                "layouts_per_state": (
                    metrics1.get("LayoutCount", 0) - metrics0.get("LayoutCount", 0)
                )
                / max(1, probe["handled"]),
                "styles_per_state": (
                    metrics1.get("RecalcStyleCount", 0) - metrics0.get("RecalcStyleCount", 0)
                )
                / max(1, probe["handled"]),
                "heap_mb": metrics1.get("JSHeapUsedSize", 0) / 1e6,
                "busy": {
                    name: (metrics1.get(name, 0.0) - metrics0.get(name, 0.0)) / wall
                    for name in (
                        "TaskDuration",
                        "ScriptDuration",
                        "LayoutDuration",
                        "RecalcStyleDuration",
                    )
                },
                "cpu": {
                    kind: (browser1.get(kind, 0.0) - browser0.get(kind, 0.0)) / wall
                    for kind in browser1
                },
            }
            if profile_s:
                before = len(connections)
                result.page["profile"] = await profile_page(cdp, profile_s)
                result.page["profile"]["reconnections"] = len(connections) - before
        done.set()
        if ws_task is not None:
            await ws_task
            ws_task = None
        station.send_signal(signal.SIGTERM)
        await asyncio.to_thread(station.wait, START_TIMEOUT_S)
        station_io.join()
        err = "".join(station_io.err)
        if station.returncode != 0 or "Traceback" in err:
            raise RuntimeError(f"the station ended {station.returncode}: {err[-2000:]}")
        summary = [line for line in station_io.out if line.startswith("clark run: stopped")]
        result.summary = summary[-1].strip() if summary else ""
        found_ticks = _TICKS.search(result.summary)
        if found_ticks:
            result.tick_avg_ms = float(found_ticks[3])
            result.tick_max_ms = float(found_ticks[4])
        text = (folder / "logs" / "mcs.interface.log").read_text(encoding="utf-8")
        late = [
            float(ms)
            for t, ms in _OVERRUN.findall(text)
            if window_from_s <= float(t) <= window_from_s + wall
        ]
        result.overruns = len(late)
        result.overrun_worst_ms = max(late, default=0.0)
        result.overrun_times = [(float(t), float(ms)) for t, ms in _OVERRUN.findall(text)]
        result.longest_tick_steps = longest_tick_steps(station_io.out)
        result.window_from_s = window_from_s
        stop_process(generator)
        generator_io.join()
        lines = [line for line in generator_io.out if line.startswith("{")]
        if lines:
            result.generator = json.loads(lines[-1])
        return result
    finally:
        done.set()
        if ws_task is not None:
            ws_task.cancel()
            with contextlib.suppress(BaseException):
                await ws_task
        if browser_obj is not None:
            with contextlib.suppress(Exception):
                await browser_obj.close()
        if playwright_cm is not None:
            with contextlib.suppress(Exception):
                await playwright_cm.__aexit__(None, None, None)
        stop_process(generator)
        stop_process(station)
        shutil.rmtree(user_data, ignore_errors=True)


async def profile_page(cdp: Any, seconds: float) -> dict[str, Any]:
    """The page's JavaScript sampled for ``seconds`` (CDP Profiler), by function.

    Returns ``{"seconds", "self": [(name, ms per s)], "total": [(name, ms per s)]}``:
    self time (the function's own code, and the browser's work it asked for synchronously,
    such as a forced layout) and total time (with everything it called) for the
    functions of the page's own script, busiest first.
    """
    await cdp.send("Profiler.enable")
    await cdp.send("Profiler.setSamplingInterval", {"interval": 500})
    await cdp.send("Profiler.start")
    await asyncio.sleep(seconds)
    profile = (await cdp.send("Profiler.stop"))["profile"]
    await cdp.send("Profiler.disable")
    nodes = {node["id"]: node for node in profile["nodes"]}
    self_us: dict[int, float] = {}
    for node_id, delta in zip(profile["samples"], profile["timeDeltas"], strict=True):
        self_us[node_id] = self_us.get(node_id, 0.0) + delta

    def name_of(node: dict[str, Any]) -> str:
        frame = node["callFrame"]
        where = frame.get("url", "").rsplit("/", 1)[-1]
        name = frame.get("functionName") or "(anonymous)"
        return f"{name} {where}:{frame.get('lineNumber', -1) + 1}" if where else name

    def subtree_us(node_id: int) -> float:
        node = nodes[node_id]
        return self_us.get(node_id, 0.0) + sum(subtree_us(c) for c in node.get("children", ()))

    by_self: dict[str, float] = {}
    by_total: dict[str, float] = {}
    for node_id, node in nodes.items():
        name = name_of(node)
        by_self[name] = by_self.get(name, 0.0) + self_us.get(node_id, 0.0)
        if "app.js" in node["callFrame"].get("url", ""):
            by_total[name] = by_total.get(name, 0.0) + subtree_us(node_id)
    scale = 1 / 1000 / seconds

    def top(table: dict[str, float]) -> list[tuple[str, float]]:
        ranked = sorted(table.items(), key=lambda item: -item[1])[:12]
        return [(name, us * scale) for name, us in ranked]

    return {"seconds": seconds, "self": top(by_self), "total": top(by_total)}


def longest_tick_steps(lines: Sequence[str]) -> list[tuple[float, float]]:
    """From ``--plain`` status lines (``t=  12.3 s`` ... ``longest tick 4.2 ms``): each
    time the longest tick so far grew, (the line's time, the new longest)."""
    steps: list[tuple[float, float]] = []
    for line in lines:
        found_t, found_tick = _STATUS_T.search(line), _STATUS_TICK.search(line)
        if found_t is None or found_tick is None:
            continue
        longest = float(found_tick[1])
        if not steps or longest > steps[-1][1]:
            steps.append((float(found_t[1]), longest))
    return steps


def report(r: Result) -> None:
    """Print one run's figures, the machine's load beside them."""
    load = f"load {r.load[0]:.2f} {r.load[1]:.2f}; {r.machine}"
    print(
        f"\nN={r.agents} {r.variant}: station CPU {r.station_cpu * 100:.1f}% of a core "
        f"(loop thread {r.loop_cpu * 100:.1f}%, other threads {r.other_cpu * 100:.1f}%), "
        f"RSS {r.station_rss_mb:.0f} MB; generator {r.generator_cpu * 100:.1f}%; "
        f"{r.window_s:.0f} s window; {load}",
        flush=True,
    )
    print(
        f"  loop: {r.overruns} overrun(s) in the window (worst {r.overrun_worst_ms:.1f} ms); "
        f"whole run: ticks {r.tick_avg_ms:.2f} ms on average, longest {r.tick_max_ms:.1f} ms"
    )
    if r.longest_tick_steps:
        print(
            "  longest tick so far, by the status lines (every 5 s): "
            + ", ".join(f"{ms:.1f} ms by t={t:.0f} s" for t, ms in r.longest_tick_steps)
        )
    if r.overrun_times:
        print(
            f"  overruns of the whole run (window {r.window_from_s:.1f}-"
            f"{r.window_from_s + r.window_s:.1f} s): "
            + ", ".join(f"t={t:.1f} s {ms:.0f} ms late" for t, ms in r.overrun_times)
        )
    print(f"  {r.summary}")
    if r.generator:
        g = r.generator
        print(
            f"  generator: {g.get('packets')} packets ({g.get('bytes')} bytes) in "
            f"{g.get('ticks')} ticks; {g.get('received')} datagrams from the station read"
        )
    if r.ws_states:
        sizes = r.ws_bytes
        print(
            f"  WebSocket client: {r.ws_states} states, {r.ws_states / r.window_s:.2f}/s; "
            f"size mean {statistics.fmean(sizes) / 1024:.1f} KiB, max {max(sizes) / 1024:.1f} "
            f"KiB ({sum(sizes) / r.window_s / 1024:.0f} KiB/s); spacing p50 "
            f"{percentile(r.ws_gaps_ms, 0.5):.0f} ms, p99 {percentile(r.ws_gaps_ms, 0.99):.0f} "
            f"ms, max {max(r.ws_gaps_ms, default=float('nan')):.0f} ms; hello "
            f"{r.hello_bytes / 1024:.1f} KiB; last state: {r.heard} of {r.agents - 1} vehicles "
            f"heard, {r.stale_or_lost} stale or lost, mean latency {r.latency_ms:.1f} ms"
            + (f"; CLOSED early: {r.ws_closed}" if r.ws_closed else "")
        )
    p = r.page
    if p:
        busy = p["busy"]
        cpu = ", ".join(f"{k} {v * 100:.1f}%" for k, v in sorted(p["cpu"].items()))
        print(
            f"  browser page: {p['connections']} WebSocket(s) opened in the window"
            + (
                " (closed with code " + ", ".join(str(c["code"]) for c in p["closes"]) + ")"
                if p["closes"]
                else ""
            )
            + ", "
            f"{p['frames']} state frames received, {p['frame_rate']:.2f}/s "
            f"(longest gap {p['frame_gap_max_ms']:.0f} ms); {p['handled']} handled, "
            f"handling p50 {p['handle_p50_ms']:.1f} ms, p99 {p['handle_p99_ms']:.1f} ms, max "
            f"{p['handle_max_ms']:.1f} ms; main thread busy {busy['TaskDuration'] * 100:.1f}% "
            f"(script {busy['ScriptDuration'] * 100:.1f}%, layout "
            f"{busy['LayoutDuration'] * 100:.1f}%, style "
            f"{busy['RecalcStyleDuration'] * 100:.1f}%); "
            f"long tasks {p['long_tasks']} ({p['long_task_ms']:.0f} ms); animation frames "
            f"{p['animation_fps']:.0f}/s, longest gap {p['animation_gap_max_ms']:.0f} ms; "
            f"JS heap {p['heap_mb']:.1f} MB, {p['nodes']} DOM nodes; layouts "
            f"{p['layouts_per_state']:.0f} and style recalculations {p['styles_per_state']:.0f} "
            "per state handled"
        )
        print(f"  browser CPU (share of a core): {cpu}")
        if r.warm_closes:
            print(f"  the page's WebSocket closed during the warm-up: codes {r.warm_closes}")
        if "profile" in p:
            prof = p["profile"]
            print(
                f"  the page's JavaScript over {prof['seconds']:g} s after the window, ms per s "
                f"(WebSockets opened meanwhile: {prof['reconnections']}):"
            )
            print("    self: " + "; ".join(f"{n} {ms:.1f}" for n, ms in prof["self"]))
            print("    total (app.js): " + "; ".join(f"{n} {ms:.1f}" for n, ms in prof["total"]))
    sys.stdout.flush()


async def run_all(args: argparse.Namespace) -> None:
    """Every size and variant asked, in order, each printed as it ends."""
    with tempfile.TemporaryDirectory(prefix="clark-bench-station-") as tmp:
        work = Path(tmp)
        for agents in (int(x) for x in args.agents.split(",")):
            for variant in args.variants.split(","):
                result = await measure(
                    agents,
                    variant,
                    work,
                    warm_s=args.warm_s,
                    window_s=args.window_s,
                    agent_status_hz=args.agent_status_hz,
                    auth=args.auth,
                    browser=not args.no_browser,
                    profile_s=args.profile_page_s,
                    view_hz=args.view_hz,
                    health=not args.no_health,
                )
                report(result)


def main(argv: Sequence[str] | None = None) -> int:
    """Parse the options; run the benchmark (or, in a child, the load generator)."""
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--agents", default="4,100", help="agent counts, station included")
    parser.add_argument(
        "--variants",
        default="noview,view",
        help=f"of {', '.join(VARIANTS)} (view: the WebSocket client and the browser)",
    )
    parser.add_argument("--warm-s", type=float, default=15.0)
    parser.add_argument("--window-s", type=float, default=60.0)
    parser.add_argument("--agent-status-hz", type=float, default=2.0)
    parser.add_argument("--view-hz", type=float, default=5.0, help="the view's --view-hz (5)")
    parser.add_argument("--auth", action="store_true", help="an authenticated mission")
    parser.add_argument("--no-browser", action="store_true", help="the WebSocket client only")
    parser.add_argument(
        "--no-health", action="store_true", help="no Vehicle Health (as before issue 17)"
    )
    parser.add_argument(
        "--profile-page-s",
        type=float,
        default=10.0,
        help="after the window, profile the page's JavaScript this long (0: not)",
    )
    parser.add_argument("--generate", help=argparse.SUPPRESS)
    args = parser.parse_args(argv)
    if args.generate:
        generate(json.loads(args.generate))
        return 0
    load = os.getloadavg()
    print(
        f"machine: {os.cpu_count()} cores ({len(os.sched_getaffinity(0))} usable here), "
        f"load average {load[0]:.2f} {load[1]:.2f} {load[2]:.2f}; "
        f"{'authenticated' if args.auth else 'unauthenticated'} mission, Agent Status "
        f"{args.agent_status_hz:g} Hz, Vehicle Health {'none' if args.no_health else '0.5 Hz'}, "
        f"view {args.view_hz:g} Hz, loop {LOOP_HZ:g} Hz",
        flush=True,
    )
    asyncio.run(run_all(args))
    return 0


if __name__ == "__main__":
    sys.exit(main())
