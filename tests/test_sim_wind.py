"""Wind (sim.wind): the air mass, its SITL parameters, and what it does to each airframe.

The figures the models are held to are physics and ArduPilot's behaviour: a copter's
position controller holds a point in a wind it can lean into and is carried away by
one it cannot; its ground speed on a leg is at most its airspeed limit minus the
headwind; a plane flies its airspeed through the air (ground speed = airspeed +- wind)
and its loiter holds the circle over the ground while the bank limit allows; a rover
takes no wind (SITL's SIM_Rover takes none). The comparisons with SITL itself are in
tests/conformance/test_wind.py.
"""

from __future__ import annotations

import io
import math
from pathlib import Path
from typing import Any

import pytest
import yaml
from pymavlink.dialects.v20 import ardupilotmega as mavlink2

# The vehicles are built and flown as the point-mass models' own tests build and fly them.
from test_sim_vehicles import COPTER, CUB, DT_S, ROOT, ROVER, build, goto, run

from clark_engine.dryrun.command import run_dry_run
from clark_engine.dryrun.world import build_sitl_vehicle
from clark_engine.mission.compiler import agent_config
from clark_engine.mission.variation import resolve_mission
from clark_engine.runtime.config import config_from_dict
from clark_engine.sim.ardupilot.vehicle_model import Truth, VehicleModel
from clark_engine.sim.wind import (
    SITL_WIND_PARAMS,
    WindConfig,
    WindField,
    sitl_wind_params,
    wind_field,
)
from clark_engine.sitl.launcher import SitlInstall
from clark_engine.validation import validate_file


def steady(speed_mps: float, from_deg: float, **more: Any) -> WindField:
    """A wind the same at every height (SIM_WIND_T 1), no turbulence, no gusts."""
    return WindField(WindConfig(speed_mps=speed_mps, from_deg=from_deg, profile="none", **more), 7)


def leg_time_s(vehicle: VehicleModel, north_m: float, up_m: float) -> float:
    """Seconds until a guided copter is within 1 m of (north_m, 0)."""
    assert goto(vehicle, north_m, 0.0, up_m)
    elapsed = 0.0
    while elapsed < 300.0:
        vehicle.step(DT_S)
        elapsed += DT_S
        truth = vehicle.truth()
        if math.hypot(truth.north_m - north_m, truth.east_m) < 1.0:
            return elapsed
    raise AssertionError("the leg did not end within 300 s")


# --- the air mass --------------------------------------------------------------------


def test_the_wind_blows_from_its_direction_with_sitls_altitude_profile() -> None:
    west = WindField(WindConfig(speed_mps=8.0, from_deg=270.0), 0)  # sqrt profile, 60 m
    north, east = west.air_velocity(10.0, 60.0, True)
    assert north == pytest.approx(0.0, abs=1e-9)
    assert east == pytest.approx(8.0)  # a west wind carries the air east
    assert west.air_velocity(10.0, 15.0, True)[1] == pytest.approx(8.0 * math.sqrt(15 / 60))
    assert west.air_velocity(10.0, 0.0, False) == pytest.approx((0.0, 0.0), abs=1e-12)
    assert west.air_velocity(10.0, 200.0, True)[1] == pytest.approx(8.0)
    linear = WindConfig(speed_mps=5.0, profile="linear", full_alt_m=60.0, linear_mps_per_m=0.05)
    assert linear.speed_at(100.0, 5.0) == pytest.approx(7.0)
    assert linear.speed_at(0.0, 5.0) == pytest.approx(2.0)
    assert linear.speed_at(-100.0, 5.0) == 0.0  # never negative, as SITL's


def test_sitl_parameters_say_the_same_wind_both_ways() -> None:
    sim = {
        "wind": {
            "speed_mps": 6.5,
            "from_deg": 45.0,
            "turbulence_mps": 1.5,
            "profile": {"type": "linear", "full_alt_m": 30.0, "linear_mps_per_m": 0.02},
            "gusts": {"speed_mps": 3.0, "every_s": 20.0, "duration_s": 2.0},
        }
    }
    params = sitl_wind_params(sim)
    assert set(params) == set(SITL_WIND_PARAMS)
    assert params["SIM_WIND_SPD"] == 6.5
    assert params["SIM_WIND_DIR"] == 45.0
    assert params["SIM_WIND_TURB"] == 1.5
    assert params["SIM_WIND_T"] == 2.0
    assert params["SIM_WIND_T_ALT"] == 30.0
    assert params["SIM_WIND_T_COEF"] == 0.02
    back = WindConfig.from_sitl_params(params)
    declared = WindConfig.from_sim(sim)
    assert declared is not None
    # Everything but the gusts (SITL has no gust model) comes back.
    assert back == WindConfig(**_no_gusts(declared))
    assert sitl_wind_params({}) == {}
    assert wind_field({}, 1) is None


def _no_gusts(config: WindConfig) -> dict[str, Any]:
    return {
        "speed_mps": config.speed_mps,
        "from_deg": config.from_deg,
        "turbulence_mps": config.turbulence_mps,
        "profile": config.profile,
        "full_alt_m": config.full_alt_m,
        "linear_mps_per_m": config.linear_mps_per_m,
    }


def test_one_air_mass_the_same_whoever_asks_and_in_whatever_order() -> None:
    config = WindConfig(
        speed_mps=5.0, from_deg=90.0, turbulence_mps=2.0, gust_mps=4.0, gust_every_s=10.0
    )
    first, second = WindField(config, 42), WindField(config, 42)
    times = [0.5 * k for k in range(400)]
    asked_in_order = [first.air_velocity(t, 80.0, True) for t in times]
    # The second copy is asked only now and then, yet agrees where it is asked.
    for k in range(0, 400, 37):
        assert second.air_velocity(times[k], 80.0, True) == asked_in_order[k]
    other_seed = WindField(config, 43)
    assert [other_seed.air_velocity(t, 80.0, True) for t in times] != asked_in_order
    # Turbulence of SITL's strength: about turbulence_mps of horizontal spread.
    dense = WindField(config.__class__(speed_mps=0.0, turbulence_mps=2.0), 3)
    samples = [dense.air_velocity(0.02 * k, 80.0, True) for k in range(20000)]
    mean_square = sum(n * n + e * e for n, e in samples) / len(samples)
    assert math.sqrt(mean_square) == pytest.approx(2.0, rel=0.1)
    assert dense.air_velocity(500.0, 80.0, False) == (0.0, 0.0)  # none on the ground
    # Gusts come and go: some of the time the wind is above its mean, never beyond the peak.
    gusty = WindField(WindConfig(speed_mps=5.0, gust_mps=4.0, gust_every_s=10.0), 9)
    gusts = [gusty.gust_mps(0.1 * k) for k in range(6000)]
    assert max(gusts) == pytest.approx(4.0, abs=0.05)
    assert 0.05 < sum(1 for g in gusts if g > 0.0) / len(gusts) < 0.6


# --- a multirotor ------------------------------------------------------------------


def test_copter_holds_its_point_in_a_wind_it_can_lean_into() -> None:
    copter = build(COPTER, (0.0, 0.0, 30.0), mode="LOITER")
    copter.set_wind(steady(5.0, 0.0))
    states = run(copter, 60.0)
    assert max(math.hypot(s.north_m, s.east_m) for s in states) < 1.0
    # It leans into the north wind (nose north: pitched down) and holds no speed.
    assert states[-1].pitch_deg < -2.0
    assert states[-1].ground_speed_m_s < 0.05


def test_copter_is_pushed_by_a_gust_before_its_controller_learns_it() -> None:
    copter = build(COPTER, (0.0, 0.0, 30.0), mode="LOITER")
    # The wind rises from calm: the controller learns it over about a second.
    copter.set_wind(steady(0.0, 0.0))
    copter.set_wind(steady(8.0, 0.0))
    copter._wind_est_n = copter._wind_est_e = 0.0  # type: ignore[attr-defined]
    states = run(copter, 30.0)
    worst = max(math.hypot(s.north_m, s.east_m) for s in states)
    assert 0.1 < worst < 5.0
    assert math.hypot(states[-1].north_m, states[-1].east_m) < 0.2  # then holds it again


def test_copter_in_a_wind_stronger_than_it_can_fly_drifts_downwind() -> None:
    copter = build(COPTER, (0.0, 0.0, 30.0), mode="LOITER")
    copter.set_wind(steady(16.0, 0.0))  # the F450's limit is 12 m/s through the air
    final = run(copter, 30.0)[-1]
    assert final.north_m < -60.0  # carried south at about 16 - 12 m/s
    assert final.velocity_north_m_s == pytest.approx(-4.0, abs=0.3)
    assert abs(final.pitch_deg) == pytest.approx(30.0, abs=0.5)  # at ANGLE_MAX


def test_copter_leg_takes_longer_upwind_than_downwind() -> None:
    calm = build(COPTER, (0.0, 0.0, 30.0), mode="GUIDED")
    still_s = leg_time_s(calm, 200.0, 30.0)
    windy = build(COPTER, (0.0, 0.0, 30.0), mode="GUIDED")
    windy.set_wind(steady(5.0, 0.0))
    upwind_s = leg_time_s(windy, 200.0, 30.0)
    downwind_s = leg_time_s(windy, 0.0, 30.0)
    # WPNAV_SPEED 10 m/s over the ground: downwind as calm; upwind its 12 m/s airspeed
    # limit leaves 7 m/s over the ground.
    assert downwind_s == pytest.approx(still_s, abs=1.5)
    assert upwind_s > still_s + 5.0
    cruise = [s for s in run_leg_states(windy, 200.0) if s.north_m > 50 and s.north_m < 150]
    assert sum(s.ground_speed_m_s for s in cruise) / len(cruise) == pytest.approx(7.0, abs=0.3)


def run_leg_states(vehicle: VehicleModel, north_m: float) -> list[Truth]:
    assert goto(vehicle, north_m, 0.0, 30.0)
    return run(vehicle, 40.0)


# --- a fixed wing -----------------------------------------------------------------------


def test_plane_ground_speed_is_its_airspeed_plus_or_minus_the_wind() -> None:
    plane = build(CUB, (0.0, 0.0, 100.0), mode="GUIDED", heading_deg=0.0)
    plane.set_wind(steady(6.0, 0.0))  # from the north
    assert goto(plane, 3000.0, 0.0, 100.0)
    upwind = run(plane, 40.0)[-1]
    assert upwind.airspeed_m_s == pytest.approx(15.0, abs=0.2)  # AIRSPEED_CRUISE
    assert upwind.ground_speed_m_s == pytest.approx(9.0, abs=0.3)
    assert goto(plane, -6000.0, 0.0, 100.0)
    downwind = run(plane, 60.0)[-1]
    assert downwind.ground_speed_m_s == pytest.approx(21.0, abs=0.3)
    # A crosswind: it crabs into it and holds its track over the ground.
    plane.set_wind(steady(6.0, 270.0))
    assert goto(plane, -9000.0, -200.0, 100.0)
    states = run(plane, 60.0)[-500:]
    for state in states:
        track = math.degrees(math.atan2(state.velocity_east_m_s, state.velocity_north_m_s))
        assert abs(((track - 180.0) + 180.0) % 360.0 - 180.0) < 3.0
    last = states[-1]
    track = math.degrees(math.atan2(last.velocity_east_m_s, last.velocity_north_m_s))
    crab = ((last.heading_deg - track) + 180.0) % 360.0 - 180.0
    # Nose west of its track, into the west wind.
    assert crab == pytest.approx(math.degrees(math.asin(6.0 / 15.0)), abs=2.0)


def _circle(states: list[Truth]) -> tuple[float, float, float, float]:
    """(centre north, centre east, mean radius, radius spread) of a track."""
    norths, easts = [s.north_m for s in states], [s.east_m for s in states]
    cn, ce = (min(norths) + max(norths)) / 2, (min(easts) + max(easts)) / 2
    radii = [math.hypot(s.north_m - cn, s.east_m - ce) for s in states]
    return cn, ce, sum(radii) / len(radii), max(radii) - min(radii)


def test_plane_loiter_holds_its_circle_over_the_ground_in_wind() -> None:
    plane = build(CUB, (0.0, 0.0, 100.0), mode="LOITER")
    plane.set_wind(steady(6.0, 270.0))
    run(plane, 90.0)
    cn, ce, radius, spread = _circle(run(plane, 120.0))
    # Centred where LOITER was entered, on the circle, a little out of round downwind.
    assert math.hypot(cn, ce) < 25.0
    assert radius == pytest.approx(plane.loiter_radius_m, abs=10.0)  # type: ignore[attr-defined]
    assert spread < 30.0


def test_plane_loiter_drifts_in_a_wind_its_bank_limit_cannot_hold() -> None:
    plane = build(CUB, (0.0, 0.0, 40.0), mode="GUIDED")
    plane.configure({"WP_LOITER_RAD": 40.0})
    assert plane.set_mode("LOITER")
    plane.set_wind(steady(11.0, 270.0))  # close to its 15 m/s airspeed
    run(plane, 60.0)
    states = run(plane, 120.0)
    _cn, ce, radius, spread = _circle(states)
    # Downwind at 26 m/s the 46 m circle needs far more bank than its 45 degrees: the
    # circle is blown downwind (east) and out of round (still air: centred, 0.00 m spread).
    assert ce > 15.0
    assert radius > 50.0
    assert spread > 20.0
    assert max(abs(s.roll_deg) for s in states) == pytest.approx(45.0, abs=1.0)


# --- a rover, and still air ------------------------------------------------------------


def test_a_rover_takes_no_wind_as_sitls_rover_takes_none() -> None:
    calm, windy = build(ROVER, (0.0, 0.0)), build(ROVER, (0.0, 0.0))
    windy.set_wind(steady(15.0, 90.0))
    for rover in (calm, windy):
        assert rover.set_mode("GUIDED")
        assert goto(rover, 40.0, 20.0, 0.0)
    assert run(calm, 40.0) == run(windy, 40.0)


def test_a_calm_declared_wind_is_still_air_for_a_plane() -> None:
    """sim.wind with speed 0 flies as no wind, within centimetres.

    In wind the plane steers by its track over the ground, in still air by its heading;
    the track lags the heading in a turn, which moves it a few centimetres in a minute
    (5 cm here since it turns at L1's rate).

    (A copter in a declared wind also has its acceleration bounded by its lean limit,
    which the still-air model does not apply, so its legs differ a little.)
    """
    calm, windless = build(CUB, (0.0, 0.0, 40.0)), build(CUB, (0.0, 0.0, 40.0))
    calm.set_wind(steady(0.0, 0.0))
    for vehicle in (calm, windless):
        assert vehicle.set_mode("GUIDED")
        assert goto(vehicle, 300.0, 100.0, 50.0)
    for one, other in zip(run(calm, 60.0), run(windless, 60.0), strict=True):
        assert one.north_m == pytest.approx(other.north_m, abs=0.1)
        assert one.east_m == pytest.approx(other.east_m, abs=0.1)


# --- a dry run in wind -------------------------------------------------------------------

COPTER_MISSION = ROOT / "missions" / "copter_takeoff_land.yaml"


def windy_mission(tmp_path: Path, wind: dict[str, Any] | None) -> Path:
    """copter_takeoff_land with ``sim.wind`` (None: still air), its autopilot ready at 5 s."""
    data = yaml.safe_load(COPTER_MISSION.read_text(encoding="utf-8"))
    data["sim"]["autopilot_ready_s"] = 5
    data["sim"]["duration_s"] = 42
    data["operator"] = [{"at_s": 6, "activate": "f450"}]
    data["checks"] = [
        {
            "name": "lands",
            "by_s": 42,
            "sequence": {"agent": "f450", "states": ["climb", "out", "back", "down"]},
        }
    ]
    if wind is not None:
        data["sim"]["wind"] = wind
    path = tmp_path / f"copter_{len(list(tmp_path.iterdir()))}.yaml"
    path.write_text(yaml.safe_dump(data, sort_keys=False), encoding="utf-8")
    return path


def state_times(path: Path, seed: int) -> tuple[dict[str, float], bytes]:
    """First entry of each state of the F450, and its track's bytes."""
    outcome = run_dry_run(
        path,
        seed=seed,
        until_s=None,
        report=None,
        speed=None,
        out=io.StringIO(),
        err=(err := io.StringIO()),
    )
    assert outcome.result is not None, err.getvalue()
    times: dict[str, float] = {}
    for entry in outcome.result.recording.states["f450"]:
        for state in entry.entered:
            times.setdefault(state, entry.time_s)
    track = outcome.result.recording.tracks["f450"]
    return times, repr(track).encode()


def test_a_declared_wind_slows_the_upwind_leg_and_is_reproducible_by_seed(
    tmp_path: Path,
) -> None:
    # The out leg heads 34 degrees (30 m north, 20 m east) at 5 m/s; a 9 m/s wind from
    # there at every height leaves the F450 (12 m/s through the air) 3 m/s over the ground
    # out and 5 m/s back; the mean is drawn once per run from its distribution.
    wind = {
        "speed_mps": {"uniform": [8.5, 9.5]},
        "from_deg": 34,
        "turbulence_mps": 0.5,
        "profile": {"type": "none"},
        "gusts": {"speed_mps": 1.0, "every_s": 15, "duration_s": 3},
    }
    calm, _ = state_times(windy_mission(tmp_path, None), seed=1)
    windy_path = windy_mission(tmp_path, wind)
    windy, track = state_times(windy_path, seed=1)
    out_calm = calm["back"] - calm["out"]
    out_windy = windy["back"] - windy["out"]
    back_calm = calm["down"] - calm["back"]
    back_windy = windy["down"] - windy["back"]
    assert out_windy > out_calm * 1.4  # 36 m at 3 m/s instead of 5
    assert back_windy == pytest.approx(back_calm, abs=2.5)  # downwind: still 5 m/s
    again, track_again = state_times(windy_path, seed=1)
    assert (again, track_again) == (windy, track)
    _other, track_other = state_times(windy_path, seed=2)
    assert track_other != track


# --- ArduPilot SITL gets the same wind ----------------------------------------------------


@pytest.mark.sitl
def test_sitl_gets_the_declared_wind_as_its_own_parameters(
    sitl_install: SitlInstall, tmp_path: Path
) -> None:
    """build_sitl_vehicle (clark dry-run --autopilot sitl) gives SITL sim.wind as SIM_WIND_*."""
    wind = {
        "speed_mps": {"uniform": [6.0, 7.0]},
        "from_deg": 250,
        "turbulence_mps": 1.5,
        "profile": {"type": "linear", "full_alt_m": 30, "linear_mps_per_m": 0.02},
    }
    validation = validate_file(windy_mission(tmp_path, wind))
    assert validation.mission is not None, validation
    mission, drawn = resolve_mission(validation.mission, seed=3)
    speed = drawn["sim.wind.speed_mps"]
    assert 6.0 <= speed <= 7.0
    agent = mission.agents["f450"]
    config = config_from_dict(agent_config(mission, agent))
    backend, _pilot, _plan = build_sitl_vehicle(mission, agent, config, sitl_install, 5.0)
    mav = mavlink2.MAVLink(None, srcSystem=255, srcComponent=190)
    parser = mavlink2.MAVLink(None)
    parser.robust_parsing = True
    want = {
        "SIM_WIND_SPD": speed,
        "SIM_WIND_DIR": 250.0,
        "SIM_WIND_TURB": 1.5,
        "SIM_WIND_T": 2.0,
        "SIM_WIND_T_ALT": 30.0,
        "SIM_WIND_T_COEF": 0.02,
    }
    seen: dict[str, float] = {}
    asked = False  # only answers to our own requests: a value streamed before may be stale
    try:
        backend.connect()
        t_s = 0.0
        while t_s < 20.0 and seen != pytest.approx(want, abs=1e-4):
            t_s += 0.5
            for msg in parser.parse_buffer(backend.step(t_s, 0.5)) or []:
                if asked and msg.get_type() == "PARAM_VALUE" and msg.param_id in want:
                    seen[msg.param_id] = msg.param_value
            if t_s >= 5.0:  # SITL has taken them by now: ask what it holds
                asked = True
                for name in want:
                    request = mav.param_request_read_encode(
                        backend.system_id, 1, name.encode("ascii"), -1
                    )
                    backend.send(request.pack(mav), t_s)
    finally:
        backend.close()
    assert seen == pytest.approx(want, abs=1e-4)
