"""CPU time per tick of the runtime core, and ticks per second, as the fleet grows.

The agent is the Super Cub of the system-identification mission, activated and
running its elevator frequency sweep (the costliest primitive: a sinusoid
sample and an RC override every tick), with its telemetry (heartbeat 1 Hz,
status 2 Hz, attitude 5 Hz, behaviour state 1 Hz) encoded through ClarkLink.
N peers are in its fleet table, each heard once a second (heartbeat and status
in one packet, decoded by the real codec) so none times out. The Cub is launched
as the mission says (``launch: {airborne: true}``): its autopilot reports itself
ready and in the air, and the pilot has armed it, before the first tick, so the
behaviour starts at once.

Printed: per N, CPU microseconds per tick (tick alone) and per tick including
the peers' packets delivered that tick, and ticks per second of the pure core.
Compare with the thesis: 13 Hz maximum loop on a Raspberry Pi 2 and 98 Hz on an
i5 laptop, two agents (5.1.1).

Then the envelope's share (runtime/envelope_guard.py and envelope_watch.py), measured
apart because it is a few per cent of a tick and a busy machine's noise is more: per N,
the watch's CPU time per tick (the peers' latest reports on the local plane, then the
vehicle and every fresh report against the envelope: what ``AgentRuntime`` runs at the
start of each tick), and the guard's per Goto: one inside the default circle fence, and
one past the edge of a four-corner polygon, moved inside along the line from the
vehicle.

Run: python benchmarks/bench_runtime.py
"""

from __future__ import annotations

import tempfile
import time
from pathlib import Path

from clark_engine.link.codec import Codec
from clark_engine.link.messages import ActivateController, AgentStatus, AgentType, Heartbeat
from clark_engine.mission.compiler import agent_config
from clark_engine.mission.validate import validate_path
from clark_engine.runtime.commands import Goto, SetUpAutopilotSafety
from clark_engine.runtime.config import config_from_dict, envelope_from_dict
from clark_engine.runtime.envelope import PeerPositions
from clark_engine.runtime.envelope_guard import EnvelopeGuard
from clark_engine.runtime.events import (
    AutopilotHeartbeat,
    AutopilotSafetyResult,
    AutopilotStatus,
    LandedState,
    PacketReceived,
    VehicleState,
)
from clark_engine.runtime.runtime import AgentRuntime

ROOT = Path(__file__).resolve().parent.parent
PEER_BASE_ID = 100
# What the Cub's autopilot reports once it is ready (3-D fix, EKF position, pre-arm
# checks passed, home at the origin) and flying: the launch gate's condition.
READY_IN_AIR = AutopilotStatus(
    gps_fix_type=3,
    position_ok=True,
    prearm_ok=True,
    home=(30.6372, -96.4787, 90.0),
    landed=LandedState.IN_AIR,
)

# The Super Cub sweep, long enough to measure: the supercub_sysid mission with the
# excitation replaced by a one-hour elevator sweep.
MISSION = (
    (ROOT / "missions" / "supercub_sysid.yaml")
    .read_text(encoding="utf-8")
    .replace(
        """          use: system_id_sequence
          with: {doublet_amplitude_us: 150, doublet_width_s: 0.5, sweep_f_stop_hz: 2}""",
        """          use: elevator_sweep
          with: {duration_s: 3600, f_stop_hz: 2}""",
    )
    .split("\nchecks:")[0]
)


def cub_runtime(peers: int) -> AgentRuntime:
    """The Super Cub's runtime, with ``peers`` more vehicles in its mission's peer table.

    The peers are added to the compiled config (vehicles sending a heartbeat and a
    status a second, flying in the Cub's own envelope), as a mission naming them
    would: the fleet table keeps records only for the mission's agents, so peers
    outside it would cost nothing here.
    """
    with tempfile.TemporaryDirectory() as tmp:
        path = Path(tmp) / "sweep.yaml"
        path.write_text(MISSION, encoding="utf-8")
        result = validate_path(path, "sweep.yaml")
    assert result.mission is not None, [f.format_text() for f in result.findings]
    mission = result.mission
    compiled = agent_config(mission, mission.agents["cub"])
    compiled["peers"] = [
        *compiled["peers"],
        *(
            {
                "name": f"peer{i}",
                "id": PEER_BASE_ID + i,
                "role": "vehicle",
                "radio_address": f"0013A2004100{i:04X}",
                "sends": {"heartbeat": 1.0, "agent_status": 1.0},
                "modes": {},
                "envelope": compiled["envelope"],
            }
            for i in range(peers)
        ),
    ]
    return AgentRuntime(config_from_dict(compiled))


def vehicle(t: float) -> VehicleState:
    return VehicleState(
        gps_time_ms=1_400_000_000_000 + int(t * 1000),
        lat_deg=30.6372 + t * 1e-6,
        lon_deg=-96.4787,
        alt_m=60.0,
        ground_speed_m_s=18.0,
        climb_rate_m_s=0.0,
        heading_deg=90.0,
        roll_deg=1.0,
        pitch_deg=2.0,
        yaw_deg=90.0,
        mode="FBWA",
        custom_mode=5,
        armed=True,
    )


def peer_packet(codec: Codec, peer_id: int, t: float) -> bytes:
    gps = 1_400_000_000_000 + int(t * 1000)
    heartbeat = Heartbeat(peer_id, gps, mission_id=533, agent_type=AgentType.VEHICLE)
    status = AgentStatus(peer_id, gps, 30.6, -96.4, 50.0, 10.0, 0.0, 45.0, 5)
    (packet,) = codec.encode([heartbeat, status], 0, 256)
    return packet


def measure(peers: int, seconds: float) -> tuple[float, float, float]:
    """(us per tick alone, us per tick with peers' packets, ticks per second)."""
    runtime = cub_runtime(peers)
    loop_hz = runtime.config.loop_hz
    codecs = [Codec(533, PEER_BASE_ID + i) for i in range(peers)]
    runtime.deliver(READY_IN_AIR, 0.0)
    runtime.deliver(vehicle(0.0), 0.0)
    # The autopilot takes the safety set-up the runtime asks for first, as in flight.
    assert any(isinstance(c, SetUpAutopilotSafety) for c in runtime.tick(0.0))
    runtime.deliver(AutopilotSafetyResult(), 0.0)
    # The station (id 1) activates the controller over ClarkLink, as in flight.
    station = Codec(533, 1)
    gps = 1_400_000_000_000
    (activate,) = station.encode([ActivateController(1, gps, 2, True)], 0, 256)
    runtime.deliver(PacketReceived(activate), 0.0)
    ticks = int(seconds * loop_hz)
    tick_cpu = 0.0
    deliver_cpu = 0.0
    for k in range(1, ticks + 1):
        now = k / loop_hz
        start = time.process_time()
        runtime.deliver(AutopilotHeartbeat("FBWA", 5, True), now)
        runtime.deliver(vehicle(now), now)
        for i, codec in enumerate(codecs):
            if (k + i) % int(loop_hz) == 0:  # each peer once a second, spread over ticks
                runtime.deliver(PacketReceived(peer_packet(codec, PEER_BASE_ID + i, now)), now)
        mid = time.process_time()
        runtime.tick(now)
        end = time.process_time()
        deliver_cpu += mid - start
        tick_cpu += end - mid
    assert runtime.machine is not None and runtime.machine.active_paths() == ("excite",), (
        runtime.machine.active_paths() if runtime.machine else None
    )
    per_tick = tick_cpu / ticks
    return per_tick * 1e6, (tick_cpu + deliver_cpu) / ticks * 1e6, 1.0 / per_tick


def measure_envelope(peers: int, ticks: int) -> tuple[float, float, float]:
    """(us per tick of the watch, us per Goto inside, us per Goto clamped at a polygon).

    The peers report from 100 m around the Cub (inside their separation's reach, so no
    distance is skipped), each heard once, fresh for the whole measurement.
    """
    runtime = cub_runtime(peers)
    runtime.deliver(READY_IN_AIR, 0.0)
    state = vehicle(0.0)
    runtime.deliver(state, 0.0)
    gps = 1_400_000_000_000
    for i in range(peers):
        codec = Codec(533, PEER_BASE_ID + i)
        heartbeat = Heartbeat(PEER_BASE_ID + i, gps, mission_id=533, agent_type=AgentType.VEHICLE)
        north = 30.6372 + 0.0009 * ((i % 10) - 5) / 5
        status = AgentStatus(PEER_BASE_ID + i, gps, north, -96.4787, 60.0, 10.0, 0.0, 45.0, 5)
        (packet,) = codec.encode([heartbeat, status], 0, 256)
        runtime.deliver(PacketReceived(packet), 0.0)
    watch = runtime.envelope_watch
    assert watch is not None
    positions = PeerPositions(runtime.config, runtime.fleet)
    assert len(positions.fixes()) == peers
    start = time.process_time()
    for k in range(ticks):
        watch.look(state, positions.fixes(), k * 0.1, guided_flight=False)
    watch_us = (time.process_time() - start) / ticks * 1e6

    config = runtime.config
    assert config.envelope is not None
    guard = EnvelopeGuard(config, config.envelope, runtime.logbook.mission)
    inside = Goto(30.6380, -96.4787, 60.0)
    square = dict(config.envelope.raw)
    square["geofence"] = dict(square["geofence"], default_radius_m=None)
    corners = [(-300.0, -300.0), (300.0, -300.0), (300.0, 300.0), (-300.0, 300.0)]
    home = square["geofence"]["home"]
    square["geofence"]["include"] = [
        {"kind": "polygon", "points": [dict(home, north_m=n, east_m=e) for n, e in corners]}
    ]
    polygon = EnvelopeGuard(config, envelope_from_dict(square), runtime.logbook.mission)
    outside = Goto(30.6372 + 500 / 111_195, -96.4787, 60.0)  # 500 m north: past the edge
    fixes = positions.fixes()
    timed = []
    for guard_, goto in ((guard, inside), (polygon, outside)):
        start = time.process_time()
        for k in range(ticks):
            guard_.check(goto, state, fixes, k * 0.1)
        timed.append((time.process_time() - start) / ticks * 1e6)
    return watch_us, timed[0], timed[1]


def main() -> None:
    print("Super Cub elevator sweep at 10 Hz; CPU time per tick (process time)")
    print(f"{'peers':>6}{'tick us':>10}{'with peers us':>15}{'ticks/s':>10}")
    for peers in (1, 4, 16, 100):
        alone, total, rate = measure(peers, seconds=300.0)
        print(f"{peers:>6}{alone:>10.1f}{total:>15.1f}{rate:>10.0f}")
    print()
    print("The envelope: CPU time of the watch per tick, of the guard per Goto (process time)")
    print(f"{'peers':>6}{'watch us':>10}{'Goto inside us':>16}{'Goto clamped us':>17}")
    for peers in (1, 4, 16, 100):
        watch_us, inside_us, clamped_us = measure_envelope(peers, ticks=3000)
        print(f"{peers:>6}{watch_us:>10.1f}{inside_us:>16.1f}{clamped_us:>17.1f}")


if __name__ == "__main__":
    main()
