"""A noisy world in the dry run: GPS error, bursty radio loss, jitter (``sim.gps_error``,
``sim.radio_bursts``, ``sim.jitter``; issue 19).

Each feature is seeded and reproducible, changes nothing when a mission does not declare
it (or declares it at zero), and has the statistics it declares. The GPS error moves the
vehicle's TRUE position, since the simulated autopilot flies by its estimate.
"""

from __future__ import annotations

import dataclasses
import math
import random
import statistics
from pathlib import Path
from typing import Any

import pytest
from mission_text import with_sim_keys
from pymavlink.dialects.v20 import ardupilotmega as mavlink2

from clark_engine.dryrun.backend import SimulatedBackend
from clark_engine.dryrun.engine import DryRun, DryRunResult
from clark_engine.dryrun.scenario import jittered_operator
from clark_engine.dryrun.world import build_sitl_vehicle, build_vehicle
from clark_engine.mission.compiler import agent_config
from clark_engine.mission.geo import EARTH_RADIUS_M
from clark_engine.mission.model import Mission
from clark_engine.runtime.config import config_from_dict
from clark_engine.sim.ardupilot.firmware import FIRMWARES
from clark_engine.sim.gps_error import WALK_STEP_S, GpsError, GpsErrorSettings
from clark_engine.sim.radio import RadioMesh
from clark_engine.sim.radio_bursts import BurstChain, BurstSettings
from clark_engine.sitl.launcher import SitlInstall
from clark_engine.validation import validate_file

ROOT = Path(__file__).resolve().parent.parent
MISSIONS = ROOT / "missions"
XBEE = {"throughput_bps": 33_000, "max_packet_bytes": 256, "frame_overhead_bytes": 18}


def load(path: Path) -> Mission:
    validation = validate_file(path, str(path))
    assert validation.mission is not None, [f.format_text() for f in validation.findings]
    return validation.mission


def with_sim(tmp_path: Path, name: str, extra: str) -> Path:
    """Mission ``name`` with ``extra`` added to its ``sim:`` mapping."""
    path = tmp_path / f"{name}.yaml"
    path.write_text(with_sim_keys((MISSIONS / f"{name}.yaml").read_text(), extra))
    return path


def run(path: Path, until_s: float, log_dir: Path | None, seed: int = 1) -> DryRunResult:
    if log_dir is not None:
        log_dir.mkdir(parents=True)
    return DryRun(load(path), path, seed=seed, until_s=until_s, log_dir=log_dir).run()


def files(folder: Path) -> dict[str, bytes]:
    return {
        str(p.relative_to(folder)): p.read_bytes() for p in sorted(folder.rglob("*")) if p.is_file()
    }


# -- declared at zero: the same bytes as undeclared ------------------------------------------

ZERO = (
    "gps_error: {walk_m: 0, glitch_rate_per_h: 0}, "
    "radio_bursts: {good_s: 5, bad_s: 1, loss_good: 0, loss_bad: 0}, "
    "jitter: {operator_s: 0, ready_s: 0, pilot_s: 0}"
)


def test_features_declared_at_zero_change_no_byte(tmp_path: Path) -> None:
    """A burst chain that loses nothing, no walk, no jitter: the same logs as without them.

    The mesh's own draws are untouched by the chains (bursts share the loss uniform), and
    every new draw comes from its own generator.
    """
    plain = MISSIONS / "single_vehicle_mode_change.yaml"
    zero = with_sim(tmp_path, "single_vehicle_mode_change", ZERO)
    one = run(plain, 70.0, tmp_path / "plain")
    two = run(zero, 70.0, tmp_path / "zero")
    assert files(tmp_path / "plain") == files(tmp_path / "zero")
    assert one.recording == two.recording
    assert one.radio.links() == two.radio.links()


NOISY = (
    "gps_error: {walk_m: 3, walk_time_constant_s: 60, glitch_rate_per_h: 120, glitch_m: 8, "
    "glitch_s: 5}, radio_bursts: {good_s: 8, bad_s: 2}, "
    "jitter: {operator_s: 4, ready_s: 5, pilot_s: 3}"
)


def test_a_noisy_world_is_reproduced_by_its_seed(tmp_path: Path) -> None:
    path = with_sim(tmp_path, "single_vehicle_mode_change", NOISY)
    first = run(path, 70.0, tmp_path / "a")
    again = run(path, 70.0, tmp_path / "b")
    other = run(path, 70.0, tmp_path / "c", seed=2)
    assert files(tmp_path / "a") == files(tmp_path / "b")
    assert first.recording == again.recording
    assert first.recording != other.recording
    assert sum(s.lost_burst for s in first.radio.links().values()) > 0


# -- GPS error ---------------------------------------------------------------------------------


def test_the_walk_has_its_declared_size_and_memory() -> None:
    settings = GpsErrorSettings(walk_m=2.0, walk_time_constant_s=2.0)
    error = GpsError(settings, 7, "v1")
    samples = [error.offset_m(k * 0.2) for k in range(20_000)]
    norths = [n for n, _ in samples]
    assert statistics.pstdev(norths) == pytest.approx(2.0, rel=0.1)
    # Lag-2 s autocorrelation of a Gauss-Markov process of time constant 2 s: 1/e.
    lagged = statistics.correlation(norths[:-10], norths[10:])
    assert lagged == pytest.approx(math.exp(-1.0), abs=0.06)
    assert GpsError(settings, 7, "v1").offset_m(500.0) == error_at(settings, 7, "v1", 500.0)


def error_at(settings: GpsErrorSettings, seed: int, agent: str, t_s: float) -> tuple[float, float]:
    """The error at ``t_s`` reached in one call (the grid makes the caller's steps irrelevant)."""
    return GpsError(settings, seed, agent).offset_m(t_s)


@pytest.mark.parametrize("share", [0.0, 0.8])
def test_a_common_share_correlates_two_vehicles(share: float) -> None:
    settings = GpsErrorSettings(walk_m=1.5, walk_time_constant_s=0.5, common_share=share)
    a, b = GpsError(settings, 3, "a"), GpsError(settings, 3, "b")
    pairs = [(a.offset_m(k * 1.0), b.offset_m(k * 1.0)) for k in range(4000)]
    rho = statistics.correlation([p[0][0] for p in pairs], [p[1][0] for p in pairs])
    assert rho == pytest.approx(share, abs=0.06)
    assert statistics.pstdev([p[0][1] for p in pairs]) == pytest.approx(1.5, rel=0.1)


def test_glitches_jump_and_come_back_at_their_rate() -> None:
    settings = GpsErrorSettings(glitch_rate_per_h=60.0, glitch_m=10.0, glitch_s=4.0)
    error = GpsError(settings, 11, "v")
    off = [math.hypot(*error.offset_m(k * WALK_STEP_S)) for k in range(int(10_800 / WALK_STEP_S))]
    assert set(round(x, 6) for x in off) == {0.0, 10.0}  # off by glitch_m, or not at all
    hours = 3.0
    # Poisson: 180 expected in 3 h (less the time spent glitching); 4 sd either side.
    expected = 60.0 * hours * (1 - 4.0 * 60.0 / 3600.0)
    assert abs(len(error.glitches) - expected) < 4 * math.sqrt(expected)
    share = sum(x > 0 for x in off) / len(off)
    assert share == pytest.approx(len(error.glitches) * 4.0 / 10_800, rel=0.02)


def test_a_rover_stops_where_its_estimate_says_the_waypoint_is(tmp_path: Path) -> None:
    """The truth is displaced by the error: the recording (the checks' position) is not the
    autopilot's. A near-constant bias (time constant of a day) makes the figure exact."""
    path = with_sim(
        tmp_path,
        "single_vehicle_mode_change",
        "autopilot_ready_s: 5, gps_noise_m: 0, gps_error: {walk_m: 6, walk_time_constant_s: 86400}",
    )
    result = run(path, 94.0, None, seed=5)
    backend = result.agents["slash"].backend
    assert isinstance(backend, SimulatedBackend)
    error_n, error_e = backend.gps_error_m
    assert math.hypot(error_n, error_e) > 2.0  # this seed's bias is large enough to see
    track = result.recording.tracks["slash"]
    true_n, true_e = track.north_m[-1], track.east_m[-1]
    believed = backend.model.truth()
    # The autopilot believes it is at the waypoint (within WP_RADIUS); truly it is off by -e.
    assert math.hypot(believed.north_m - 30.0, believed.east_m - 20.0) < 2.5
    assert true_n == pytest.approx(believed.north_m - error_n, abs=1e-6)
    assert true_e == pytest.approx(believed.east_m - error_e, abs=1e-6)
    assert math.hypot(true_n - 30.0, true_e - 20.0) > 1.0


def test_a_hovering_copter_truly_wanders_with_the_walk(tmp_path: Path) -> None:
    """A copter handed over in flight holds its point in LOITER: by its estimate. Its true
    position wanders as the error does, the estimate stays put."""
    text = (MISSIONS / "three_vehicles_payload.yaml").read_text()
    text = text.replace("position: [60, 60] ", "position: [60, 60, 15]").replace(
        "launch: {armed_by: engine}", "launch: {airborne: true}  "
    )
    path = tmp_path / "hover.yaml"
    path.write_text(text)
    mission = load(path)
    sim = {**mission.sim, "gps_error": {"walk_m": 4.0, "walk_time_constant_s": 120.0}}
    mission = dataclasses.replace(mission, sim=sim)
    agent = mission.agents["f450"]
    config = config_from_dict(agent_config(mission, agent))
    backend, _ = build_vehicle(mission, agent, config, seed=4)
    assert isinstance(backend, SimulatedBackend)
    truth = backend.truth()
    assert (truth.north_m, truth.east_m, truth.up_m) == pytest.approx((60.0, 60.0, 15.0))
    # It holds where its estimate was when handed over: the truth plus the error then.
    hold = (60.0 + backend.gps_error_m[0], 60.0 + backend.gps_error_m[1])
    worst_error_m = worst_lag_m = 0.0
    for k in range(1, 6000):  # 120 s
        backend.step(k * 0.02, 0.02)
        if k % 50 == 0:
            truth, error_m = backend.truth(), backend.gps_error_m
            # Truly where the hold point less the error is (the estimate chases the error).
            lag_m = math.dist(
                (truth.north_m, truth.east_m), (hold[0] - error_m[0], hold[1] - error_m[1])
            )
            worst_lag_m = max(worst_lag_m, lag_m)
            worst_error_m = max(worst_error_m, math.hypot(*error_m))
            believed = backend.model.truth()
            assert math.dist((believed.north_m, believed.east_m), hold) < 2.0
    assert worst_error_m > 4.0  # it wandered that far
    assert worst_lag_m < 2.0


# -- bursts ------------------------------------------------------------------------------------


def test_a_chain_has_its_declared_burst_lengths_and_share() -> None:
    settings = BurstSettings(good_s=10.0, bad_s=2.0)
    chain = BurstChain(settings, random.Random("9:radio-burst:a:b"))
    step_s, bads, run_s, bad_time = 0.05, [], 0.0, 0
    n = 400_000  # 20,000 s
    for k in range(n):
        bad = chain.loss_at(k * step_s) == 1.0
        if bad:
            run_s += step_s
            bad_time += 1
        elif run_s:
            bads.append(run_s)
            run_s = 0.0
    assert statistics.mean(bads) == pytest.approx(2.0, rel=0.08)
    assert bad_time / n == pytest.approx(settings.bad_share, rel=0.08)


def test_bursts_on_a_long_link_lose_their_share_in_runs() -> None:
    """One packet every 0.1 s for 5,000 s over a link with loss 5 % and bursts."""
    settings = BurstSettings(good_s=5.0, bad_s=1.0, loss_good=0.1, loss_bad=1.0)
    mesh = RadioMesh(random.Random("1:radio"), loss_rate=0.05, bursts=settings, burst_seed=1)
    mesh.add_agent("a", 1, XBEE)
    mesh.add_agent("b", 2, XBEE)
    received: set[int] = set()
    count = 50_000
    for k in range(count):
        mesh.send("a", k.to_bytes(4, "big"), "b", k * 0.1)
        received.update(int.from_bytes(d.packet, "big") for d in mesh.deliveries_until(k * 0.1))
    received.update(int.from_bytes(d.packet, "big") for d in mesh.deliveries_until(math.inf))
    stats = mesh.link_stats("a", "b")
    expected = 0.05 + 0.95 * settings.mean_loss
    lost = stats.lost_random + stats.lost_burst
    assert lost / count == pytest.approx(expected, abs=0.02)
    assert stats.delivered == len(received) == count - lost
    runs, current = [], 0
    for k in range(count):
        if k in received:
            if current:
                runs.append(current)
            current = 0
        else:
            current += 1
    # Independent losses at this share would average 1.4 packets a run; a 1 s burst is 10.
    assert statistics.mean(runs) > 2.0
    assert max(runs) > 30


def test_bursts_keep_the_mesh_draws_and_are_seeded_per_link() -> None:
    def deliveries(seed: int, bursts: BurstSettings | None) -> list[Any]:
        mesh = RadioMesh(
            random.Random(f"{seed}:radio"), loss_rate=0.2, bursts=bursts, burst_seed=seed
        )
        for i, name in enumerate("abc"):
            mesh.add_agent(name, i + 1, XBEE)
        for k in range(2000):
            mesh.send("abc"[k % 3], b"x" * 20, "", k * 0.05)
        return mesh.deliveries_until(math.inf)

    plain = deliveries(1, None)
    idle = deliveries(1, BurstSettings(loss_good=0.0, loss_bad=0.0))
    assert plain == idle  # a chain that loses nothing changes nothing
    bursty = BurstSettings(good_s=3.0, bad_s=1.0)
    assert deliveries(1, bursty) == deliveries(1, bursty)
    assert deliveries(1, bursty) != deliveries(2, bursty)
    assert set(map(id, deliveries(1, bursty))) and len(deliveries(1, bursty)) < len(plain)


# -- jitter ------------------------------------------------------------------------------------


def test_operator_jitter_moves_each_action_and_keeps_their_order() -> None:
    mission = load(MISSIONS / "single_vehicle_mode_change.yaml")
    plain = jittered_operator(mission, 1)
    sim = {**mission.sim, "jitter": {"operator_s": 50.0}}
    jittered = dataclasses.replace(mission, sim=sim)
    for seed in range(20):
        played = jittered_operator(jittered, seed)
        assert [i for _, i, _ in played] == [i for _, i, _ in plain]
        times = [t for t, _, _ in played]
        assert times == sorted(times) and times[0] >= 0
        for (t, _, _), (at, _, _) in zip(played, plain, strict=True):
            assert t <= at + 50.0
    assert jittered_operator(jittered, 3) == jittered_operator(jittered, 3)
    assert jittered_operator(jittered, 3) != jittered_operator(jittered, 4)


def test_readiness_and_pilot_jitter_are_per_vehicle() -> None:
    boot = FIRMWARES["ardurover"].boot
    later = boot.shifted(3.0)
    assert later.position_s == boot.position_s + 3.0
    sooner = boot.shifted(-1000.0)
    assert all(getattr(sooner, f) == 0.0 for f in sooner.__dataclass_fields__)
    mission = load(MISSIONS / "fault_lost_peer.yaml")
    sim = {**mission.sim, "jitter": {"ready_s": 10.0, "pilot_s": 5.0}}
    mission = dataclasses.replace(mission, sim=sim)
    prearm = {}
    reactions = {}
    for name, agent in mission.agents.items():
        if not agent.is_vehicle:
            continue
        config = config_from_dict(agent_config(mission, agent))
        backend, pilot = build_vehicle(mission, agent, config, seed=1)
        assert isinstance(backend, SimulatedBackend)
        prearm[name] = backend.autopilot.boot_times.prearm_s
        reactions[name] = pilot.reaction_s
        assert 0.0 <= pilot.reaction_s <= 5.0
    assert len(set(prearm.values())) == len(prearm) > 1
    assert len(set(reactions.values())) == len(reactions)


@pytest.mark.sitl
def test_sitl_flies_the_same_gps_error_through_its_own_gps_offset(
    sitl_install: SitlInstall, tmp_path: Path
) -> None:
    """--autopilot sitl plays sim.gps_error through SIM_GPS1_GLTCH_X/_Y, as it goes."""
    path = with_sim(
        tmp_path, "copter_takeoff_land", "gps_error: {walk_m: 4, walk_time_constant_s: 60}"
    )
    mission = load(path)
    agent = mission.agents["f450"]
    config = config_from_dict(agent_config(mission, agent))
    backend, _pilot, _plan = build_sitl_vehicle(mission, agent, config, sitl_install, 5.0, 7)
    assert backend.gps_error is not None
    mav = mavlink2.MAVLink(None, srcSystem=255, srcComponent=190)
    parser = mavlink2.MAVLink(None)
    parser.robust_parsing = True
    held: dict[str, float] = {}
    try:
        backend.connect()
        t_s = 0.0
        while t_s < 12.0:
            t_s += 0.5
            for msg in parser.parse_buffer(backend.step(t_s, 0.5)) or []:
                if msg.get_type() == "PARAM_VALUE" and msg.param_id.startswith("SIM_GPS1_GLTCH"):
                    held[msg.param_id] = msg.param_value
            if t_s >= 10.0:  # ask what SITL holds now
                for name in ("SIM_GPS1_GLTCH_X", "SIM_GPS1_GLTCH_Y"):
                    request = mav.param_request_read_encode(
                        backend.system_id, 1, name.encode("ascii"), -1
                    )
                    backend.send(request.pack(mav), t_s)
    finally:
        backend.close()
    north_m, east_m = backend.gps_error.offset_m(t_s)
    per_deg_lat = math.radians(1.0) * EARTH_RADIUS_M
    per_deg_lon = per_deg_lat * math.cos(math.radians(mission.origin.lat_deg))
    assert math.hypot(north_m, east_m) > 0.5  # a walk of 4 m has moved it: not a no-op
    # Within 0.2 m of the error now: the last update was at most half a second ago.
    assert held["SIM_GPS1_GLTCH_X"] * per_deg_lat == pytest.approx(north_m, abs=0.2)
    assert held["SIM_GPS1_GLTCH_Y"] * per_deg_lon == pytest.approx(east_m, abs=0.2)
