"""``clark run`` as real processes on this machine: latency, loop rate held, CPU per agent.

Every figure comes from ``python -m clark_engine run`` processes started here, with
their autopilots and payloads left out (testing mode: ``--no-autopilot --no-payload``)
so what is measured is the engine and the radio. The missions are generated (one
station ``mcs`` and vehicles ``r2``, ``r3``... on ``traxxas_slash``, behaviour ``hold``,
an inline computer that allows the rate); every agent broadcasts a ``heartbeat`` at
the telemetry rate.

1. **Latency over UDP loopback**, two agents, loop and telemetry at 1, 5, 10 and 50 Hz.
   A message's latency runs from its packing (the sender's tick: the ``sent`` row's
   ``now_s`` and the message's GPS stamp) to its arrival in the receiver's runtime and
   fleet table (the ``received`` row's ``now_s``: the moment the shell handed the
   datagram to the runtime). Two figures:

   - ``analyze``: :func:`clark_engine.analysis.latency.analyze_folder`'s latency, i.e. the
     receiver's ``latency_ms`` column (its GPS time minus the message's GPS stamp). Both
     agents take GPS time from this machine's system clock (no autopilot), but in whole
     milliseconds, each end rounded: 0 means under about 1 ms.
   - ``aligned``: sub-millisecond, from the ``now_s`` columns (the shells' monotonic
     clocks, the same clock in both processes, each minus its own origin). The unknown
     difference of the two origins is bounded as NTP does: no message arrives before it
     left, in either direction. The midpoint is used; the half-width of that bound
     (reported as ``+-``) is the most any latency can be off, and ``p99 max`` is the
     p99 under the worst origin the data allow (an upper bound).

2. **Latency over emulated XBees**: the same, each ``clark run`` on an XBee radio of
   :class:`~clark_engine.sim.xbee_emulator.XBeeEmulator` (pseudo-terminals, the real
   digi-xbee library in each process). ``clark run`` has no device override for an
   XBee radio, so the generated mission names each emulated radio's pty in the agent's
   inline radio connection (``hardware.radio.connection.device``). The air is
   instantaneous by default (engine + digi-xbee + serial path); ``--xbee-air`` models
   the 900HP's shared 33 kbit/s channel.

3. **Loop rate held**, four agents (four processes, UDP loopback, heartbeat at
   ``--hold-telemetry-hz``), at 100, 200, 500 and 1000 Hz for ``--hold-s`` seconds (the
   issue asks 60 s; the default is shorter to keep the run near 5 minutes). The
   overruns are each shell's own (``clark run``'s last line: overruns, deadlines
   skipped, worst lateness, average and longest tick). Held: no agent overran and every
   agent ran at least 99 % of its ticks. The four processes start together, so the
   first loops run while the others still start up (a second of CPU each) and the last
   ones while the first exit; the overruns *with all four running* count only the
   window between (:data:`STEADY_MARGIN_S`, from the interface logs), which is what
   vehicles on their own computers would see.

4. **CPU per agent**: user + system CPU seconds of each process (``/proc/PID/stat``)
   over a window after its loop started, divided by the window's wall seconds; shown
   for every run, 10 Hz being the issue's figure.

5. **The machine's share** (``--baseline``): after each engine run, the same run
   without the engine: *bare loops*, small Python processes (this file with
   ``--bare-agent``) that tick on the same drift-free schedule, wait the same way
   (:func:`select.select`, microseconds), spin a fixed CPU time per tick (the
   engine's average tick, ``--bare-work-ms``; none in the latency runs) and send each
   other a datagram stamped with :func:`time.monotonic_ns` at the telemetry rate.
   What they show (overruns, latency from the stamp to the receiver's wake-up) is
   what the machine does to any loop; the rest is the engine's. Every run also
   reports how busy the machine was (all CPUs, ``/proc/stat``) and the *steal* time
   (a virtual machine's CPUs held back by its host) over the run.

Sample sizes: a latency run lasts long enough for ``--latency-samples`` messages
(both directions pooled; 600 by default: 300 s at 1 Hz, 60 s at 5 Hz) so that the p99
is the 6th largest of 600, not the largest of 63.

Scheduling (``--sched fifo`` or ``both``): once every agent's loop runs, each process
is put under ``SCHED_FIFO`` priority 10 (real time, as ``chrt --fifo -p 10 PID`` does,
where the system permits it) and back under the normal policy half a second before
its run ends; the bare loops do the same to themselves. Only the loops, not start-up
and exit: a whole process under FIFO (``chrt --fifo 10 clark run ...``) holds a CPU
through its start-up (a second of CPU) and its exit, and stalls every other FIFO
agent on that CPU for that long (hundreds of milliseconds). ``normal`` (the default)
is how ``clark run`` runs; it never raises its own priority.

Run: ``python benchmarks/bench_run.py`` (about 15 minutes); ``--hold-s 60`` for the
issue's 60 s holds; ``--only latency|xbee|hold`` for one part. The machine's load
changes every figure: run it on a quiet machine and say how busy it was.
"""

from __future__ import annotations

import argparse
import contextlib
import csv
import json
import os
import re
import select
import signal
import socket
import subprocess
import sys
import tempfile
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
if str(ROOT) not in sys.path:
    sys.path.insert(0, str(ROOT))

from clark_engine.analysis.latency import analyze_folder  # noqa: E402

START_TIMEOUT_S = 30.0
"""Longest wait for a process's loop to start (a loaded machine)."""
LATENCY_RATES_HZ = (1.0, 5.0, 10.0, 50.0)
HOLD_RATES_HZ = (100.0, 200.0, 500.0, 1000.0)
CLK_TCK = os.sysconf("SC_CLK_TCK")
_STOPPED = re.compile(r"(\d+) ticks at .*?(\d+) overrun\(s\) \((\d+) deadline")
_TICK_MS = re.compile(r"ticks ([\d.]+) ms on average")
_OVERRUN = re.compile(r"^t=([\d.]+) .*overrun: tick \d+ started ([\d.]+) ms late", re.MULTILINE)
STEADY_MARGIN_S = (1.0, 0.5)
"""The steady window starts this long after the last loop started, ends this long before the
first one's end: outside it, other agents' start-up (a second of CPU each) and exit share
the two CPUs with the loops, which a vehicle's own mission computer never sees."""
SCHED_FIFO_PRIORITY = 10
"""``SCHED_FIFO`` priority for ``--sched fifo``: low among real-time tasks, above normal ones."""
FIFO_UNTIL_END_S = 0.5
"""Back to the normal policy this long before a run ends (its exit is not the loop's)."""


def set_sched(pid: int, sched: str) -> None:
    """Put process ``pid`` (0: this one) under ``fifo`` or ``normal`` scheduling."""
    fifo = sched == "fifo"
    policy = os.SCHED_FIFO if fifo else os.SCHED_OTHER
    with contextlib.suppress(ProcessLookupError):
        os.sched_setscheduler(pid, policy, os.sched_param(SCHED_FIFO_PRIORITY if fifo else 0))


def fifo_for_the_loop(run: Run, sched: str, seconds: float) -> Callable[[], None]:
    """Every agent of ``run`` under ``sched`` now; returns what puts them back near the end.

    The returned function sleeps until :data:`FIFO_UNTIL_END_S` before the first agent's
    ``--until`` runs out, then puts every agent back under the normal policy.
    """
    if sched != "fifo":
        return lambda: None
    for agent in run.agents:
        set_sched(agent.process.pid, sched)

    def back() -> None:
        time.sleep(max(0.0, run.first_loop_s + seconds - FIFO_UNTIL_END_S - time.monotonic()))
        for agent in run.agents:
            set_sched(agent.process.pid, "normal")

    return back


# -- the machine -----------------------------------------------------------------------------


def cpu_times() -> list[int]:
    """The machine's CPU time counters (user nice system idle iowait irq softirq steal)."""
    return [int(x) for x in Path("/proc/stat").read_text().split("\n", 1)[0].split()[1:9]]


def machine_text(before: list[int], after: list[int]) -> str:
    """How busy every CPU was between two :func:`cpu_times`, and the steal time."""
    delta = [b - a for a, b in zip(before, after, strict=True)]
    total = sum(delta) or 1
    busy = (delta[0] + delta[1] + delta[2] + delta[5] + delta[6]) / total * 100
    steal_ms = delta[7] * 1000 / CLK_TCK
    return f"machine {busy:.0f}% busy, steal {steal_ms:.0f} ms"


# -- missions --------------------------------------------------------------------------------


def mission_text(
    agents: int,
    loop_hz: float,
    telemetry_hz: float,
    radios: Sequence[str] | None = None,
    *,
    xbee_air: bool = False,
) -> str:
    """A mission: station ``mcs`` and vehicles ``r2``...; each broadcasts heartbeats.

    Args:
        agents: How many agents (the station counts).
        loop_hz: ``mission.loop_hz``; every computer is declared to hold it.
        telemetry_hz: Each agent's heartbeat rate.
        radios: Emulated XBee ports, one per agent (None: UDP radios).
        xbee_air: Keep the 900HP's 33 kbit/s; else the radio is declared as fast as the
            emulator's instantaneous air (clark validate's link budget would refuse 50 Hz).
    """
    computer = f"computer: {{max_loop_hz: {max(loop_hz, 1000.0):g}}}"
    lines = [
        "clark: 1",
        "mission:",
        "  id: 4244",
        "  name: bench-run",
        f"  loop_hz: {loop_hz:g}",
        "  heartbeat_timeout_s: 3",
        "  origin: {lat: 30.6372, lon: -96.4787, alt_amsl_m: 90}",
        "agents:",
    ]
    for i in range(1, agents + 1):
        name = agent_name(i)
        if radios is None:
            radio = f'{{profile: udp_lan, address: "127.0.0.1:{16000 + i}"}}'
        else:
            radio = (
                f'{{profile: xbee_pro_900hp, address: "{xbee_address(i)}", '
                f'connection: {{kind: serial, device: "{radios[i - 1]}", baud_bps: 115200}}'
                + ("}" if xbee_air else ", throughput_bps: 10000000}")
            )
        lines += [
            f"  {name}:",
            f"    id: {i}",
            f"    profile: {'mcs_laptop' if i == 1 else 'traxxas_slash'}",
            f"    hardware: {{radio: {radio}, {computer}}}",
            f"    telemetry: {{heartbeat: {telemetry_hz:g}}}",
        ]
        if i > 1:
            lines.append("    behavior: {use: hold}")
    return "\n".join(lines) + "\n"


def agent_name(i: int) -> str:
    return "mcs" if i == 1 else f"r{i}"


def xbee_address(i: int) -> str:
    return f"0013A2004000{i:04X}"


def free_ports(n: int) -> list[int]:
    """``n`` distinct UDP ports free on loopback now (closed again before use)."""
    socks = [socket.socket(socket.AF_INET, socket.SOCK_DGRAM) for _ in range(n)]
    try:
        for sock in socks:
            sock.bind(("127.0.0.1", 0))
        return [sock.getsockname()[1] for sock in socks]
    finally:
        for sock in socks:
            sock.close()


# -- processes -------------------------------------------------------------------------------


@dataclass
class Agent:
    """One ``clark run`` process and what was read from it."""

    name: str
    process: subprocess.Popen[str]
    cpu_start_s: float = 0.0
    cpu_s: float = 0.0
    wall_s: float = 0.0
    last_line: str = ""
    err: str = ""
    loop_s: float = 0.0
    """When its loop was about to start (its first line read), :func:`time.monotonic`."""


@dataclass
class Run:
    """The agents of one run and its logs folder."""

    logs: Path
    agents: list[Agent] = field(default_factory=list)
    first_loop_s: float = 0.0
    """When the first agent's loop started (at the latest), :func:`time.monotonic`."""


def cpu_seconds(pid: int) -> float:
    """User + system CPU seconds of a live process, from /proc."""
    fields = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()
    return (int(fields[11]) + int(fields[12])) / CLK_TCK


def start_agents(
    mission: Path,
    logs: Path,
    agents: int,
    seconds: float,
    *,
    udp: bool,
    loop_hz: float,
) -> Run:
    """Start ``agents`` processes running for ``seconds`` each; wait until each loop runs."""
    run = Run(logs)
    ports = free_ports(agents) if udp else []
    for i in range(1, agents + 1):
        name = agent_name(i)
        args = [
            sys.executable,
            "-m",
            "clark_engine",
            "run",
            str(mission),
            "--agent",
            name,
            "--no-autopilot",
            "--no-payload",
            "--plain",
            "--no-console",
            "--logs",
            str(logs),
            "--until",
            f"{seconds:g}",
            "--loop-hz",
            f"{loop_hz:g}",
        ]
        if udp:
            args += ["--radio", "udp", "--radio-address", f"127.0.0.1:{ports[i - 1]}"]
            for j in range(1, agents + 1):
                if j != i:
                    args += ["--peer", f"{agent_name(j)}=127.0.0.1:{ports[j - 1]}"]
        process = subprocess.Popen(
            args,
            cwd=ROOT,
            stdin=subprocess.DEVNULL,
            stdout=subprocess.PIPE,
            stderr=subprocess.PIPE,
            text=True,
        )
        run.agents.append(Agent(name, process))
    for index, agent in enumerate(run.agents):
        assert agent.process.stdout is not None
        first = agent.process.stdout.readline()  # blocks until the loop is about to start
        agent.loop_s = time.monotonic()
        if index == 0:
            run.first_loop_s = agent.loop_s
        if not first.startswith("clark run: "):
            _out, err = agent.process.communicate(timeout=START_TIMEOUT_S)
            raise RuntimeError(f"{agent.name} did not start: {first}{err}")
    return run


def measure_cpu(run: Run, window_s: float) -> None:
    """CPU seconds of each process over ``window_s`` of wall time from now."""
    t0 = time.monotonic()
    for agent in run.agents:
        agent.cpu_start_s = cpu_seconds(agent.process.pid)
    time.sleep(window_s)
    wall = time.monotonic() - t0
    for agent in run.agents:
        agent.cpu_s = cpu_seconds(agent.process.pid) - agent.cpu_start_s
        agent.wall_s = wall


def finish(run: Run, timeout_s: float) -> None:
    """Wait for every process to end (``--until``); keep its last line and stderr."""
    for agent in run.agents:
        out, err = agent.process.communicate(timeout=timeout_s)
        lines = [line for line in out.splitlines() if line.startswith("clark run: stopped")]
        agent.last_line = lines[-1] if lines else ""
        agent.err = err
        if agent.process.returncode != 0 or "Traceback" in err:
            raise RuntimeError(f"{agent.name} ended {agent.process.returncode}: {err}")


def kill(run: Run | None) -> None:
    """End every process of the run that still lives."""
    if run is None:
        return
    for agent in run.agents:
        if agent.process.poll() is None:
            agent.process.send_signal(signal.SIGKILL)
        agent.process.communicate()


def cpu_text(run: Run) -> str:
    return " ".join(f"{a.name} {a.cpu_s / a.wall_s * 100:.1f}%" for a in run.agents)


# -- latency from the message logs -----------------------------------------------------------


@dataclass
class Latency:
    """One rate's latency figures, in milliseconds."""

    samples: int
    analyze_p50_ms: float
    analyze_p99_ms: float
    analyze_mean_of_means_s: float | None
    aligned_p50_ms: float
    aligned_p99_ms: float
    aligned_p99_max_ms: float
    aligned_max_ms: float
    uncertainty_ms: float
    cpu: str
    machine: str


def read_rows(path: Path) -> list[dict[str, str]]:
    with path.open(encoding="utf-8", newline="") as f:
        return list(csv.DictReader(f))


def percentile(values: Sequence[float], q: float) -> float:
    """The ``q`` quantile (0..1), nearest rank."""
    ordered = sorted(values)
    if not ordered:
        return float("nan")
    index = min(len(ordered) - 1, max(0, round(q * len(ordered) + 0.5) - 1))
    return ordered[index]


def latencies(logs: Path, a: str, b: str, skip_s: float) -> tuple[list[float], ...]:
    """Per message both ways: raw ms (analyze) and the aligned figures.

    Returns ``(analyze_ms, aligned_ms, aligned_upper_ms, [half_width_ms])``.
    """
    rows = {name: read_rows(logs / f"{name}.messages.csv") for name in (a, b)}

    def sent(name: str) -> dict[int, float]:
        return {
            int(r["counter"]): float(r["now_s"])
            for r in rows[name]
            if r["direction"] == "sent" and r["message_type"] == "heartbeat"
        }

    def received(name: str, peer: str) -> list[tuple[int, float, str]]:
        return [
            (int(r["counter"]), float(r["now_s"]), r["latency_ms"])
            for r in rows[name]
            if r["direction"] == "received"
            and r["peer"] == peer
            and r["message_type"] == "heartbeat"
            and float(r["now_s"]) >= skip_s
        ]

    # raw[x] = receive now_s - send now_s, for messages x -> y (each on its own origin)
    raw: dict[str, list[float]] = {}
    analyze_ms: list[float] = []
    for sender, receiver in ((a, b), (b, a)):
        out = sent(sender)
        raw[sender] = []
        for counter, at_s, latency_ms in received(receiver, sender):
            if counter in out:
                raw[sender].append(at_s - out[counter])
            if latency_ms:
                analyze_ms.append(float(latency_ms))
    # true(a->b) = raw_a + d, true(b->a) = raw_b - d, both >= 0: d in [-min raw_a, min raw_b]
    low, high = -min(raw[a]), min(raw[b])
    d = (low + high) / 2
    aligned = [(x + d) * 1000 for x in raw[a]] + [(x - d) * 1000 for x in raw[b]]
    upper = [(x + high) * 1000 for x in raw[a]] + [(x - low) * 1000 for x in raw[b]]
    return analyze_ms, aligned, upper, [(high - low) / 2 * 1000]


def measure_latency(
    rate_hz: float, seconds: float, work: Path, *, xbee: bool, xbee_air: bool, sched: str = "normal"
) -> Latency:
    """Two agents at ``rate_hz`` for ``seconds``; their message logs' latencies."""
    folder = Path(tempfile.mkdtemp(prefix=f"lat-{rate_hz:g}-", dir=work))
    mission = folder / "mission.yaml"
    logs = folder / "logs"
    emulator = None
    run: Run | None = None
    try:
        ports: list[str] | None = None
        if xbee:
            from clark_engine.sim.xbee_emulator import XBeeEmulator

            emulator = (XBeeEmulator() if xbee_air else XBeeEmulator(throughput_bps=None)).start()
            ports = [emulator.add_radio(xbee_address(i)).port for i in (1, 2)]
        mission.write_text(
            mission_text(2, rate_hz, rate_hz, ports, xbee_air=xbee_air), encoding="utf-8"
        )
        warm_s = 1.0
        run = start_agents(mission, logs, 2, seconds + warm_s + 1.0, udp=not xbee, loop_hz=rate_hz)
        back = fifo_for_the_loop(run, sched, seconds + warm_s + 1.0)
        time.sleep(warm_s)
        before = cpu_times()
        measure_cpu(run, seconds)
        machine = machine_text(before, cpu_times())
        back()
        finish(run, START_TIMEOUT_S + seconds)
    finally:
        kill(run)
        if emulator is not None:
            emulator.stop()
    analyze_ms, aligned, upper, width = latencies(logs, "mcs", "r2", warm_s)
    analysis = analyze_folder(logs)
    return Latency(
        samples=len(aligned),
        analyze_p50_ms=percentile(analyze_ms, 0.5),
        analyze_p99_ms=percentile(analyze_ms, 0.99),
        analyze_mean_of_means_s=analysis.mean_of_means_s,
        aligned_p50_ms=percentile(aligned, 0.5),
        aligned_p99_ms=percentile(aligned, 0.99),
        aligned_p99_max_ms=percentile(upper, 0.99),
        aligned_max_ms=max(aligned),
        uncertainty_ms=width[0],
        cpu=cpu_text(run),
        machine=machine,
    )


# -- loop rate held --------------------------------------------------------------------------


@dataclass
class Hold:
    """One rate's four-agent run."""

    rate_hz: float
    held: bool
    lines: list[str]
    cpu: str
    machine: str
    tick_ms: float
    """The agents' average tick, from start to end (their summaries' mean)."""
    steady_s: float
    """How long every agent's loop ran with no other agent starting or ending."""
    steady_overruns: list[int]
    """Each agent's overruns within that window (from its interface log)."""


def parse_stopped(line: str) -> tuple[int, int, int]:
    """(ticks, overruns, skipped) from ``clark run: stopped (...): N ticks at ...``."""
    found = _STOPPED.search(line)
    if found is None:
        raise RuntimeError(f"not a clark run summary: {line!r}")
    return int(found[1]), int(found[2]), int(found[3])


def measure_hold(
    rate_hz: float, seconds: float, telemetry_hz: float, work: Path, *, sched: str = "normal"
) -> Hold:
    folder = Path(tempfile.mkdtemp(prefix=f"hold-{rate_hz:g}-", dir=work))
    mission = folder / "mission.yaml"
    mission.write_text(mission_text(4, rate_hz, telemetry_hz), encoding="utf-8")
    run: Run | None = None
    try:
        before = cpu_times()
        run = start_agents(mission, folder / "logs", 4, seconds, udp=True, loop_hz=rate_hz)
        back = fifo_for_the_loop(run, sched, seconds)
        measure_cpu(run, min(seconds - 1.0, 10.0))
        back()
        finish(run, START_TIMEOUT_S + seconds)
        machine = machine_text(before, cpu_times())
    finally:
        kill(run)
    held = True
    lines = []
    tick_ms: list[float] = []
    for agent in run.agents:
        ticks, overruns, _skipped = parse_stopped(agent.last_line)
        if overruns or ticks < 0.99 * rate_hz * seconds:
            held = False
        lines.append(f"{agent.name}: {agent.last_line.split(': ', 2)[2]}")
        found = _TICK_MS.search(agent.last_line)
        if found:
            tick_ms.append(float(found[1]))
    mean_tick_ms = sum(tick_ms) / len(tick_ms) if tick_ms else float("nan")
    steady_s, steady = steady_overruns(run, seconds)
    return Hold(rate_hz, held, lines, cpu_text(run), machine, mean_tick_ms, steady_s, steady)


def steady_overruns(run: Run, seconds: float) -> tuple[float, list[int]]:
    """The steady window's length and each agent's overruns in it (:data:`STEADY_MARGIN_S`).

    An agent's log times count from its shell's origin, taken just before its first line.
    """
    begin = max(a.loop_s for a in run.agents) + STEADY_MARGIN_S[0]
    end = min(a.loop_s for a in run.agents) + seconds - STEADY_MARGIN_S[1]
    counts = []
    for agent in run.agents:
        text = (run.logs / f"{agent.name}.interface.log").read_text(encoding="utf-8")
        times = (agent.loop_s + float(t) for t, _late in _OVERRUN.findall(text))
        counts.append(sum(1 for t in times if begin <= t <= end))
    return max(0.0, end - begin), counts


# -- bare loops: the same schedule without the engine ----------------------------------------


@dataclass
class Bare:
    """One run of bare loops: per loop, its ticks, overruns and worst lateness; latencies."""

    ticks: list[int]
    overruns: list[int]
    max_late_ms: list[float]
    latencies_ms: list[float]
    machine: str


def bare_agent(spec: dict[str, object]) -> dict[str, object]:
    """One bare loop (a child process): the shell's schedule, wait and overrun rule, no engine.

    ``spec``: ``index``, ``ports`` (every loop's UDP port), ``rate_hz``, ``seconds``,
    ``work_s`` (CPU spun per tick), ``telemetry_hz`` (a stamped datagram to every other
    loop), ``start_ns`` (a common :func:`time.monotonic_ns` to start at), ``sched``
    (the loop's scheduling, as :func:`fifo_for_the_loop` gives the engine's).
    """
    index = int(str(spec["index"]))
    ports = [int(p) for p in str(spec["ports"]).split(",")]
    rate_hz = float(str(spec["rate_hz"]))
    seconds = float(str(spec["seconds"]))
    work_s = float(str(spec["work_s"]))
    every = max(1, round(rate_hz / float(str(spec["telemetry_hz"]))))
    sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    sock.bind(("127.0.0.1", ports[index]))
    sock.setblocking(False)
    peers = [("127.0.0.1", p) for i, p in enumerate(ports) if i != index]
    period = 1.0 / rate_hz
    # Each loop on its own phase of the period, as processes started one after another.
    start = int(str(spec["start_ns"])) / 1e9 + index * period / len(ports)
    k = ticks = overruns = 0
    max_late = 0.0
    latencies: list[float] = []
    set_sched(0, str(spec["sched"]))
    while True:
        deadline = start + k * period
        now = time.monotonic()
        if now - start >= seconds:
            break
        if now < deadline - 1e-6:
            readable, _, _ = select.select([sock], [], [], deadline - now)
            arrived_ns = time.monotonic_ns()
            while readable:
                try:
                    data = sock.recv(256)
                except BlockingIOError:
                    break
                if now - start >= 1.0:  # after a second's warm-up, as the engine's runs
                    latencies.append((arrived_ns - int.from_bytes(data[:8], "little")) / 1e6)
            continue
        late = now - deadline
        max_late = max(max_late, late)
        missed = int(late // period)
        if missed >= 1:
            overruns += 1
            k += missed
        spin_until = time.perf_counter() + work_s
        while time.perf_counter() < spin_until:
            pass
        if k % every == 0:
            stamp = time.monotonic_ns().to_bytes(8, "little") + bytes(40)
            for peer in peers:
                sock.sendto(stamp, peer)
        k += 1
        ticks += 1
    set_sched(0, "normal")
    sock.close()
    return {
        "ticks": ticks,
        "overruns": overruns,
        "max_late_ms": max_late * 1000,
        "latencies_ms": latencies,
    }


def measure_bare(
    loops: int,
    rate_hz: float,
    seconds: float,
    *,
    work_s: float,
    telemetry_hz: float,
    sched: str = "normal",
) -> Bare:
    """``loops`` bare loops (processes) at ``rate_hz`` for ``seconds``."""
    ports = free_ports(loops)
    start_ns = time.monotonic_ns() + 500_000_000  # every loop started by then
    processes = []
    before = cpu_times()
    for index in range(loops):
        spec = {
            "index": index,
            "ports": ",".join(map(str, ports)),
            "rate_hz": rate_hz,
            "seconds": seconds,
            "work_s": work_s,
            "telemetry_hz": telemetry_hz,
            "start_ns": start_ns,
            "sched": sched,
        }
        processes.append(
            subprocess.Popen(
                [sys.executable, __file__, "--bare-agent", json.dumps(spec)],
                stdout=subprocess.PIPE,
                stderr=subprocess.PIPE,
                text=True,
            )
        )
    results = []
    for process in processes:
        out, err = process.communicate(timeout=START_TIMEOUT_S + seconds)
        if process.returncode != 0:
            raise RuntimeError(f"bare loop ended {process.returncode}: {err}")
        results.append(json.loads(out))
    machine = machine_text(before, cpu_times())
    return Bare(
        ticks=[r["ticks"] for r in results],
        overruns=[r["overruns"] for r in results],
        max_late_ms=[r["max_late_ms"] for r in results],
        latencies_ms=[x for r in results for x in r["latencies_ms"]],
        machine=machine,
    )


# -- main ------------------------------------------------------------------------------------


def main(argv: Sequence[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--only", choices=("latency", "xbee", "hold"), help="one part only")
    parser.add_argument("--latency-s", type=float, default=20.0, help="least per rate (20)")
    parser.add_argument(
        "--latency-samples",
        type=int,
        default=600,
        help="messages per latency run, both ways (600: 300 s at 1 Hz)",
    )
    parser.add_argument("--latency-rates", default=",".join(f"{r:g}" for r in LATENCY_RATES_HZ))
    parser.add_argument("--hold-s", type=float, default=20.0, help="per rate (issue: 60)")
    parser.add_argument("--hold-rates", default=",".join(f"{r:g}" for r in HOLD_RATES_HZ))
    parser.add_argument("--hold-telemetry-hz", type=float, default=10.0)
    parser.add_argument("--xbee-air", action="store_true", help="model the 33 kbit/s channel")
    parser.add_argument(
        "--sched",
        choices=("normal", "fifo", "both"),
        default="normal",
        help="run the agents as clark run does (normal) or under chrt --fifo, or both",
    )
    parser.add_argument(
        "--baseline", action="store_true", help="after each run, bare loops the same way"
    )
    parser.add_argument(
        "--bare-work-ms",
        type=float,
        default=None,
        help="CPU per bare-loop tick in the holds (default: the engine's average tick)",
    )
    parser.add_argument("--bare-agent", help=argparse.SUPPRESS)
    args = parser.parse_args(argv)
    if args.bare_agent:
        print(json.dumps(bare_agent(json.loads(args.bare_agent))))
        return 0
    scheds = ("normal", "fifo") if args.sched == "both" else (args.sched,)
    load = os.getloadavg()
    print(
        f"machine: {os.cpu_count()} cores ({len(os.sched_getaffinity(0))} usable here), "
        f"load average {load[0]:.2f} {load[1]:.2f}"
    )
    with tempfile.TemporaryDirectory(prefix="clark-bench-run-") as tmp:
        work = Path(tmp)
        for radio in ("latency", "xbee"):
            if args.only not in (None, radio):
                continue
            xbee = radio == "xbee"
            title = (
                "emulated XBee" + (" (33 kbit/s air)" if args.xbee_air else "") if xbee else "UDP"
            )
            print(
                f"\n1{'b' if xbee else ''}. latency, pack -> receiver's fleet table, over {title}"
            )
            print(
                f"{'rate':>6} {'sched':>6} {'s':>4} {'n':>5} {'analyze p50/p99 ms':>19} "
                f"{'mean of means s':>16} {'aligned p50 ms':>15} {'p99 ms':>7} {'p99 max':>8} "
                f"{'max':>7} {'+-ms':>6}  CPU (user+sys); machine"
            )
            for rate in (float(x) for x in args.latency_rates.split(",")):
                seconds = max(args.latency_s, args.latency_samples / (2 * rate))
                for sched in scheds:
                    r = measure_latency(
                        rate, seconds, work, xbee=xbee, xbee_air=args.xbee_air, sched=sched
                    )
                    mom = f"{r.analyze_mean_of_means_s:.4f}" if r.analyze_mean_of_means_s else "-"
                    print(
                        f"{rate:>4g}Hz {sched:>6} {seconds:>4.0f} {r.samples:>5} "
                        f"{r.analyze_p50_ms:>9.0f}/{r.analyze_p99_ms:<9.0f} "
                        f"{mom:>16} {r.aligned_p50_ms:>15.3f} {r.aligned_p99_ms:>7.3f} "
                        f"{r.aligned_p99_max_ms:>8.3f} {r.aligned_max_ms:>7.2f} "
                        f"{r.uncertainty_ms:>6.3f}  {r.cpu}; {r.machine}",
                        flush=True,
                    )
                    if args.baseline and not xbee:
                        b = measure_bare(
                            2, rate, seconds + 1.0, work_s=0.0, telemetry_hz=rate, sched=sched
                        )
                        lat = b.latencies_ms
                        print(
                            f"{'':>6} {sched:>6} bare loops: n {len(lat)}, stamp -> receiver "
                            f"awake p50 {percentile(lat, 0.5):.3f} p99 "
                            f"{percentile(lat, 0.99):.3f} max {max(lat, default=0):.2f} ms; "
                            f"{b.machine}",
                            flush=True,
                        )
        if args.only in (None, "hold"):
            print(
                f"\n3. loop rate held for {args.hold_s:g} s, four agents, UDP loopback, "
                f"heartbeat {args.hold_telemetry_hz:g} Hz each"
            )
            for rate in (float(x) for x in args.hold_rates.split(",")):
                for sched in scheds:
                    h = measure_hold(rate, args.hold_s, args.hold_telemetry_hz, work, sched=sched)
                    steady_held = not any(h.steady_overruns)
                    print(
                        f"{rate:>6g} Hz {sched}: {'held' if h.held else 'NOT held'}; "
                        f"{h.steady_s:.1f} s with all four running: overruns "
                        f"{', '.join(map(str, h.steady_overruns))} "
                        f"({'held' if steady_held else 'NOT held'}); CPU {h.cpu}; {h.machine}"
                    )
                    for line in h.lines:
                        print(f"          {line}")
                    if args.baseline:
                        work_ms = args.bare_work_ms if args.bare_work_ms is not None else h.tick_ms
                        b = measure_bare(
                            4,
                            rate,
                            args.hold_s,
                            work_s=work_ms / 1000,
                            telemetry_hz=args.hold_telemetry_hz,
                            sched=sched,
                        )
                        print(
                            f"          bare loops ({work_ms:.2f} ms of CPU per tick): "
                            f"overruns {', '.join(map(str, b.overruns))} in "
                            f"{', '.join(map(str, b.ticks))} ticks, worst lateness "
                            f"{max(b.max_late_ms):.1f} ms; {b.machine}"
                        )
                    sys.stdout.flush()
    return 0


if __name__ == "__main__":
    sys.exit(main())
