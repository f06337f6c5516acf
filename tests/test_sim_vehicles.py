"""Point-mass vehicle models: limits, modes, RC and servo channels, GPS, determinism."""

from __future__ import annotations

import itertools
import json
import math
import random
import statistics
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import pytest
import yaml

from clark_engine.mission.compiler import compile_mission
from clark_engine.mission.geo import LocalPoint, Origin, to_global, to_local
from clark_engine.mission.validate import validate_path
from clark_engine.runtime.config import config_from_dict
from clark_engine.sim.model import Truth, VehicleModel
from clark_engine.sim.vehicles import (
    DEFAULT_GPS_NOISE_M,
    FixedWing,
    ModeBehaviour,
    Multirotor,
    Rover,
    SimulatedVehicle,
    VehicleSetupError,
    make_vehicle,
)

ROOT = Path(__file__).resolve().parent.parent
PROFILES = ROOT / "hardware_profiles"
ORIGIN = Origin(30.6372, -96.4787, 90.0)
DT_S = 0.02

COPTER = ("dji_f450_airframe", "pixhawk_arducopter")
PLANE = ("anaconda_airframe", "pixhawk_arduplane")
CUB = ("super_cub_airframe", "pixhawk_arduplane")
ROVER = ("traxxas_slash_airframe", "pixhawk_ardurover")


def profile(kind: str, name: str) -> dict[str, Any]:
    data = yaml.safe_load((PROFILES / kind / f"{name}.yaml").read_text(encoding="utf-8"))
    assert isinstance(data, dict)
    return data


def build(
    pair: tuple[str, str],
    start: tuple[float, ...] = (0.0, 0.0, 0.0),
    seed: int = 1,
    **options: Any,
) -> SimulatedVehicle:
    return make_vehicle(
        profile("airframes", pair[0]),
        profile("autopilots", pair[1]),
        None,
        ORIGIN,
        start,
        random.Random(seed),
        **options,
    )


def goto(
    vehicle: VehicleModel, north_m: float, east_m: float, up_m: float, speed: float | None = None
) -> bool:
    lat, lon, alt = to_global(LocalPoint(north_m, east_m, up_m), ORIGIN)
    return vehicle.goto(lat, lon, alt, speed)


def run(vehicle: VehicleModel, seconds: float, dt_s: float = DT_S) -> list[Truth]:
    states = []
    for _ in range(round(seconds / dt_s)):
        vehicle.step(dt_s)
        states.append(vehicle.truth())
    return states


def distance(state: Truth, north_m: float, east_m: float) -> float:
    return math.hypot(state.north_m - north_m, state.east_m - east_m)


def yaw_rates_deg_s(states: list[Truth], dt_s: float) -> Iterator[float]:
    for before, after in itertools.pairwise(states):
        change = (after.yaw_deg - before.yaw_deg + 180.0) % 360.0 - 180.0
        yield abs(change) / dt_s


# --- construction and modes -------------------------------------------------------------


@pytest.mark.parametrize(
    ("pair", "model", "start_mode"),
    [(COPTER, Multirotor, "LOITER"), (PLANE, FixedWing, "LOITER"), (ROVER, Rover, "MANUAL")],
)
def test_the_airframe_class_picks_the_model_and_modes_come_from_the_profile(
    pair: tuple[str, str], model: type[SimulatedVehicle], start_mode: str
) -> None:
    vehicle = build(pair)
    assert type(vehicle) is model
    assert dict(vehicle.modes) == profile("autopilots", pair[1])["modes"]
    # The mission schema's default start: hold mode for aircraft, manual for rovers; armed.
    assert vehicle.mode == start_mode
    assert vehicle.armed


@pytest.mark.parametrize("pair", [COPTER, PLANE, ROVER])
def test_unknown_mode_is_refused_and_the_mode_stays(pair: tuple[str, str]) -> None:
    vehicle = build(pair)
    before = vehicle.mode
    assert not vehicle.set_mode("WARP_DRIVE")
    assert not vehicle.set_mode("guided")  # names are ArduPilot's, upper case
    assert vehicle.mode == before
    assert vehicle.set_mode("GUIDED")
    assert vehicle.mode == "GUIDED"


def test_mode_classification_follows_the_roles_and_documents_the_unsimulated() -> None:
    copter, plane, rover = build(COPTER), build(PLANE), build(ROVER)
    assert copter.mode_behaviour("STABILIZE") is ModeBehaviour.MANUAL
    assert copter.mode_behaviour("ALT_HOLD") is ModeBehaviour.MANUAL
    assert copter.mode_behaviour("BRAKE") is ModeBehaviour.HOLD
    assert copter.mode_behaviour("SMART_RTL") is ModeBehaviour.RTL
    assert copter.mode_behaviour("LAND") is ModeBehaviour.LAND
    assert {"AUTO", "CIRCLE", "THROW"} <= copter.unsimulated_modes
    assert copter.mode_behaviour("AUTO") is ModeBehaviour.HOLD
    assert plane.mode_behaviour("FBWA") is ModeBehaviour.MANUAL
    assert plane.mode_behaviour("TAKEOFF") is ModeBehaviour.HOLD
    assert "TAKEOFF" in plane.unsimulated_modes
    # ArduPlane refuses quadplane modes without VTOL motors; nobody selects INITIALISING.
    assert plane.mode_behaviour("QLOITER") is None
    assert not plane.set_mode("QHOVER")
    assert not plane.set_mode("INITIALISING")
    assert rover.mode_behaviour("HOLD") is ModeBehaviour.HOLD
    assert rover.mode_behaviour("STEERING") is ModeBehaviour.MANUAL
    assert not rover.set_mode("INITIALISING")
    # Only those are refused; every other profile mode has a behaviour.
    quadplane = {"QSTABILIZE", "QHOVER", "QLOITER", "QLAND", "QRTL", "QAUTOTUNE", "QACRO"}
    refused = {
        vehicle.airframe_class: {m for m in vehicle.modes if vehicle.mode_behaviour(m) is None}
        for vehicle in (copter, plane, rover)
    }
    assert refused == {
        "multirotor": set(),
        "fixed_wing": {"INITIALISING", "LOITERALTQLAND", *quadplane},
        "rover": {"INITIALISING"},
    }


def test_setup_errors_name_what_to_change() -> None:
    airframe = profile("airframes", COPTER[0])
    autopilot = profile("autopilots", COPTER[1])
    with pytest.raises(VehicleSetupError, match="airframe class 'blimp'"):
        make_vehicle(
            {**airframe, "class": "blimp"}, autopilot, None, ORIGIN, (0, 0), random.Random()
        )
    without = {k: v for k, v in airframe.items() if k != "max_climb_rate_m_s"}
    with pytest.raises(VehicleSetupError, match="max_climb_rate_m_s"):
        make_vehicle(without, autopilot, None, ORIGIN, (0, 0), random.Random())
    with pytest.raises(VehicleSetupError, match="no such mode"):
        build(COPTER, mode="HOVER")
    with pytest.raises(VehicleSetupError, match="refuses"):
        build(PLANE, mode="QLOITER")
    with pytest.raises(VehicleSetupError, match="must start armed"):
        build(PLANE, (0.0, 0.0, 50.0), armed=False)


# --- guided, hold, RTL, land ----------------------------------------------------------------


def test_copter_guided_goto_takes_off_converges_and_stops_without_overshoot() -> None:
    copter = build(COPTER)
    assert not goto(copter, 100.0, 50.0, 20.0), "a goto outside guided is refused"
    assert copter.set_mode("GUIDED")
    assert goto(copter, 100.0, 50.0, 20.0)
    states = run(copter, 60.0)
    final = states[-1]
    assert distance(final, 100.0, 50.0) < 0.01
    assert final.up_m == pytest.approx(20.0, abs=0.01)
    assert final.ground_speed_m_s < 0.01
    assert abs(final.climb_rate_m_s) < 0.01
    # Along the leg, never beyond the target (square-root braking, no overshoot).
    leg = math.hypot(100.0, 50.0)
    along = [(s.north_m * 100.0 + s.east_m * 50.0) / leg for s in states]
    assert max(along) <= leg + 0.05
    assert max(s.up_m for s in states) <= 20.05
    # It cruised at the profile's cruise speed and leaned into it.
    assert max(s.ground_speed_m_s for s in states) == pytest.approx(5.0, abs=1e-6)
    assert min(s.pitch_deg for s in states) < -5.0
    # It faces where it goes.
    assert final.heading_deg == pytest.approx(math.degrees(math.atan2(50.0, 100.0)), abs=1.0)


def test_copter_requested_speed_is_flown_and_clamped_to_the_limit() -> None:
    copter = build(COPTER, (0.0, 0.0, 30.0), mode="GUIDED")
    assert goto(copter, 500.0, 0.0, 30.0, 8.0)
    assert max(s.ground_speed_m_s for s in run(copter, 40.0)) == pytest.approx(8.0, abs=1e-6)
    assert goto(copter, 0.0, 0.0, 30.0, 99.0)
    assert max(s.ground_speed_m_s for s in run(copter, 60.0)) <= 12.0 + 1e-9


def test_rover_guided_goto_drives_there_and_stops_within_the_arrival_radius() -> None:
    rover = build(ROVER, heading_deg=0.0)
    assert rover.set_mode("GUIDED")
    assert goto(rover, -40.0, 30.0, 25.0)  # behind it; the altitude is ignored
    states = run(rover, 40.0)
    final = states[-1]
    assert distance(final, -40.0, 30.0) < Rover.arrival_radius_m
    assert final.ground_speed_m_s == 0.0
    assert all(s.up_m == 0.0 and s.roll_deg == 0.0 and s.pitch_deg == 0.0 for s in states)
    assert max(s.ground_speed_m_s for s in states) == pytest.approx(3.0, abs=1e-6)
    # Stays stopped.
    assert distance(run(rover, 20.0)[-1], final.north_m, final.east_m) == 0.0


def test_plane_guided_goto_flies_there_and_loiters_around_the_point() -> None:
    plane = build(PLANE, (0.0, 0.0, 60.0), mode="GUIDED")
    assert isinstance(plane, FixedWing)
    assert goto(plane, 400.0, -300.0, 80.0)
    run(plane, 90.0)
    radius = plane.loiter_radius_m
    # 1.5 x the tightest turn at 16 m/s: max(16^2 / (g tan 45), 16 / 35 deg/s) = 26.2 m.
    assert radius == pytest.approx(1.5 * 16.0 / math.radians(35.0), rel=1e-6)
    states = run(plane, 120.0)
    for state in states:
        assert distance(state, 400.0, -300.0) == pytest.approx(radius, abs=1.0)
        assert state.up_m == pytest.approx(80.0, abs=0.5)
        assert state.airspeed_m_s == pytest.approx(16.0, abs=0.1)
    # Clockwise (right turns), banked for a coordinated turn at that radius.
    assert states[-1].roll_deg == pytest.approx(
        math.degrees(math.atan(16.0**2 / (radius * 9.80665))), abs=1.5
    )


def test_plane_guided_speed_request_is_held_within_its_limits() -> None:
    plane = build(PLANE, (0.0, 0.0, 60.0), mode="GUIDED")
    assert goto(plane, 2000.0, 0.0, 60.0, 22.0)
    assert run(plane, 40.0)[-1].airspeed_m_s == pytest.approx(22.0, abs=0.2)
    assert goto(plane, 2000.0, 0.0, 60.0, 5.0)  # below the stall margin: min speed
    assert run(plane, 40.0)[-1].airspeed_m_s == pytest.approx(12.0, abs=0.2)


def test_plane_auto_mode_on_the_ground_takes_off_and_loiters_overhead() -> None:
    plane = build(PLANE)  # on the ground, armed, in LOITER: the dry run's default start
    assert not plane.airborne
    states = run(plane, 90.0)
    assert plane.airborne
    assert states[-1].up_m == pytest.approx(FixedWing.min_auto_altitude_m, abs=0.5)
    assert all(s.up_m < 0.5 or s.roll_deg == pytest.approx(0.0, abs=1.0) for s in states[:50])


@pytest.mark.parametrize("pair", [COPTER, ROVER])
def test_hold_mode_stops_and_stays(pair: tuple[str, str]) -> None:
    start = (0.0, 0.0, 20.0)
    vehicle = build(pair, start, mode="GUIDED")
    assert goto(vehicle, 0.0, 500.0, 20.0)
    moving = run(vehicle, 30.0)[-1]
    assert moving.ground_speed_m_s > 2.5
    hold = "LOITER" if pair is COPTER else "HOLD"
    assert vehicle.set_mode(hold)
    stopped = run(vehicle, 10.0)[-1]
    assert stopped.ground_speed_m_s < 0.01
    # Braked within its stopping distance, then did not move.
    assert 0.0 < stopped.east_m - moving.east_m < 10.0
    for state in run(vehicle, 60.0):
        assert distance(state, stopped.north_m, stopped.east_m) < 0.01
        assert state.up_m == pytest.approx(stopped.up_m, abs=0.01)


def test_plane_hold_loiters_around_where_it_was() -> None:
    plane = build(PLANE, (0.0, 0.0, 100.0), mode="FBWA", heading_deg=90.0)
    assert isinstance(plane, FixedWing)
    run(plane, 5.0)
    entry = plane.truth()
    assert plane.set_mode("LOITER")
    run(plane, 60.0)
    for state in run(plane, 60.0):
        assert distance(state, entry.north_m, entry.east_m) == pytest.approx(
            plane.loiter_radius_m, abs=1.0
        )
        assert state.up_m == pytest.approx(entry.up_m, abs=0.5)


@pytest.mark.parametrize("pair", [COPTER, ROVER, PLANE])
def test_rtl_returns_to_the_start_point_and_holds(pair: tuple[str, str]) -> None:
    start = (20.0, -10.0, 40.0)
    vehicle = build(pair, start, mode="GUIDED")
    assert goto(vehicle, 300.0, 200.0, 40.0)
    run(vehicle, 60.0)
    assert distance(vehicle.truth(), 20.0, -10.0) > 100.0
    assert vehicle.set_mode("RTL")
    run(vehicle, 150.0)
    final = vehicle.truth()
    if isinstance(vehicle, FixedWing):
        for state in run(vehicle, 30.0):
            assert distance(state, 20.0, -10.0) == pytest.approx(vehicle.loiter_radius_m, abs=1.0)
    elif isinstance(vehicle, Rover):
        assert distance(final, 20.0, -10.0) < Rover.arrival_radius_m
        assert final.ground_speed_m_s == 0.0
    else:
        assert distance(final, 20.0, -10.0) < 0.01
        assert final.up_m == pytest.approx(40.0, abs=0.01)


def test_copter_land_descends_and_disarms_on_touchdown() -> None:
    copter = build(COPTER, (0.0, 0.0, 15.0))
    assert not copter.arm(False), "disarming in the air is refused"
    assert copter.set_mode("LAND")
    states = run(copter, 40.0)
    assert states[-1].up_m == 0.0
    assert not copter.armed
    assert not copter.airborne
    descents = [-s.climb_rate_m_s for s in states]
    assert max(descents) <= 1.5 + 1e-9
    # Slow below 10 m (ArduCopter LAND_SPEED 0.5 m/s).
    low = [-s.climb_rate_m_s for s in states if 0.0 < s.up_m < 8.0]
    assert low and max(low) <= 0.5 + 1e-9
    assert all(s.north_m == 0.0 and s.east_m == 0.0 for s in states)


def test_reentering_guided_keeps_the_target_and_entering_it_holds_position() -> None:
    copter = build(COPTER, (0.0, 0.0, 10.0), mode="GUIDED")
    assert goto(copter, 50.0, 0.0, 10.0)
    run(copter, 5.0)
    assert copter.set_mode("GUIDED")  # the same mode again: nothing changes
    assert distance(run(copter, 30.0)[-1], 50.0, 0.0) < 0.01
    # ArduPilot resets the guided target on entering GUIDED from another mode.
    assert copter.set_mode("LOITER")
    assert copter.set_mode("GUIDED")
    assert distance(run(copter, 10.0)[-1], 50.0, 0.0) < 0.01


def test_unsimulated_mode_is_flown_as_hold() -> None:
    copter = build(COPTER, (0.0, 0.0, 10.0))
    assert copter.set_mode("CIRCLE")
    assert copter.behaviour is ModeBehaviour.HOLD
    assert all(distance(s, 0.0, 0.0) < 1e-9 for s in run(copter, 10.0))


# --- arming ----------------------------------------------------------------------------------


def test_disarmed_vehicles_on_the_ground_do_not_move() -> None:
    copter = build(COPTER, mode="STABILIZE", armed=False)
    copter.set_pilot({3: 1900, 1: 1900})
    plane = build(PLANE, armed=False)  # LOITER would take off if armed
    rover = build(ROVER, mode="GUIDED", armed=False)
    assert goto(rover, 30.0, 0.0, 0.0)
    for vehicle in (copter, plane, rover):
        for state in run(vehicle, 10.0):
            assert (state.north_m, state.east_m, state.up_m) == (0.0, 0.0, 0.0)
            assert state.throttle_pct == 0.0
    # Arming lets the same commands move them.
    for vehicle in (copter, plane, rover):
        assert vehicle.arm(True)
        final = run(vehicle, 10.0)[-1]
        assert math.hypot(final.north_m, final.east_m) + final.up_m > 1.0
    # Back on the ground, disarming is accepted.
    assert build(ROVER).arm(False)


# --- limits over a long, varied run ----------------------------------------------------------


def _exercise(vehicle: SimulatedVehicle, seed: int, minutes: float) -> list[Truth]:
    """Random modes, targets and stick inputs every few seconds."""
    rng = random.Random(seed)
    names = list(vehicle.modes)
    states = []
    for _ in range(int(minutes * 60 / 4)):
        choice = rng.random()
        if choice < 0.4:
            vehicle.set_mode("GUIDED")
            goto(
                vehicle,
                rng.uniform(-400, 400),
                rng.uniform(-400, 400),
                rng.uniform(-20, 600),
                rng.choice([None, rng.uniform(0, 40)]),
            )
        elif choice < 0.7:
            vehicle.set_mode(rng.choice(names))
        else:
            vehicle.set_pilot({channel: rng.randint(1000, 2000) for channel in (1, 2, 3, 4)})
            if rng.random() < 0.5:
                vehicle.set_rc_override({1: rng.randint(1100, 1900)})
        vehicle.arm(True)
        states.extend(run(vehicle, 4.0))
    return states


@pytest.mark.parametrize("pair", [COPTER, PLANE, CUB, ROVER])
def test_limits_are_never_exceeded_over_a_long_varied_run(pair: tuple[str, str]) -> None:
    airframe = profile("airframes", pair[0])
    vehicle = build(pair, (0.0, 0.0, 50.0))
    states = _exercise(vehicle, seed=42, minutes=20)
    tiny = 1e-9
    flying = isinstance(vehicle, FixedWing)
    for state in states:
        assert state.ground_speed_m_s <= airframe["max_speed_m_s"] + tiny
        assert state.airspeed_m_s <= airframe["max_speed_m_s"] + tiny
        assert -airframe["max_descent_rate_m_s"] - tiny <= state.climb_rate_m_s
        assert state.climb_rate_m_s <= airframe["max_climb_rate_m_s"] + tiny
        assert 0.0 <= state.up_m <= airframe["max_altitude_m"] + tiny
        if flying and state.up_m > 0.0:
            assert state.airspeed_m_s >= airframe["min_speed_m_s"] - tiny
        if "max_bank_deg" in airframe:
            assert abs(state.roll_deg) <= airframe["max_bank_deg"] + tiny
    rates = list(yaw_rates_deg_s(states, DT_S))
    assert max(rates) <= airframe["max_turn_rate_deg_s"] + 1e-6
    if isinstance(vehicle, Rover):
        assert all(s.up_m == 0.0 and s.climb_rate_m_s == 0.0 for s in states)
    # The run did exercise the limits, not hover politely.
    assert max(s.ground_speed_m_s for s in states) > 0.8 * airframe["cruise_speed_m_s"]
    assert max(rates) > 0.5 * airframe["max_turn_rate_deg_s"]


def test_fixed_wing_is_never_below_min_speed_even_pulling_up_at_idle() -> None:
    plane = build(CUB, (0.0, 0.0, 200.0), mode="MANUAL")
    plane.set_pilot({3: 1100, 2: 1900})  # idle, full up elevator: would stall
    states = run(plane, 60.0)
    assert all(s.airspeed_m_s >= 13.0 - 1e-9 for s in states)
    assert states[-1].climb_rate_m_s < 0.0, "the nose drops: no energy to climb"


# --- RC inputs show in the attitude ----------------------------------------------------------


@pytest.mark.parametrize("mode", ["MANUAL", "FBWA", "LOITER"])
@pytest.mark.parametrize("sign", [1, -1])
def test_aileron_override_step_rolls_with_a_first_order_lag(mode: str, sign: int) -> None:
    plane = build(CUB, (0.0, 0.0, 100.0), mode=mode)
    run(plane, 20.0)  # settle (LOITER: onto its circle, banked)
    before = plane.truth().roll_deg
    tau = FixedWing.roll_time_constant_s
    # trim + 150 us of a 400 us half range, times the 45 degree max bank.
    step_deg = sign * 150.0 / 400.0 * 45.0
    states = []
    for _ in range(round(1.5 / DT_S)):
        plane.set_rc_override({1: 1500 + sign * 150})  # refreshed every step, as the runtime does
        plane.step(DT_S)
        states.append(plane.truth())
    at_tau = states[round(tau / DT_S) - 1].roll_deg - before
    settled = states[-1].roll_deg - before
    if mode == "LOITER":  # the loiter controller fights back; only the direction is certain
        assert sign * at_tau > 0.3 * abs(step_deg)
        return
    assert at_tau == pytest.approx(step_deg * (1.0 - math.exp(-1.0)), rel=0.02)
    assert settled == pytest.approx(step_deg, rel=0.01)
    # Then it turns that way (right for a positive roll).
    assert sign * (states[-1].yaw_deg - states[0].yaw_deg) > 0.0
    # Released: back to level with the same lag.
    plane.set_rc_override({1: 0})
    assert run(plane, 1.5)[-1].roll_deg == pytest.approx(0.0, abs=0.01)


def _pitch_amplitude_deg(frequency_hz: float) -> float:
    plane = build(CUB, (0.0, 0.0, 150.0), mode="MANUAL")
    run(plane, 2.0)
    pitches = []
    cycles = 6
    steps = round(cycles / frequency_hz / DT_S)
    for k in range(steps):
        pwm = round(1500 + 100 * math.sin(2 * math.pi * frequency_hz * k * DT_S))
        plane.set_rc_override({2: pwm})
        plane.step(DT_S)
        pitches.append(plane.truth().pitch_deg)
    tail = pitches[len(pitches) // 2 :]  # after the transient
    return (max(tail) - min(tail)) / 2.0


def test_elevator_sweep_shows_in_pitch_attenuated_as_a_first_order_lag() -> None:
    tau = FixedWing.pitch_time_constant_s
    # 100 us of a 400 us half range: +20 * 0.25 up, -25 * 0.25 down, mean 5.625 degrees.
    command = 100.0 / 400.0 * (20.0 + 25.0) / 2.0
    for frequency in (0.2, 0.5, 1.0, 2.0):
        expected = command / math.sqrt(1.0 + (2.0 * math.pi * frequency * tau) ** 2)
        assert _pitch_amplitude_deg(frequency) == pytest.approx(expected, rel=0.06)
    assert _pitch_amplitude_deg(2.0) < 0.5 * _pitch_amplitude_deg(0.2)


def test_rudder_doublet_shows_in_yaw() -> None:
    plane = build(CUB, (0.0, 0.0, 100.0), mode="MANUAL")
    start = plane.truth().yaw_deg
    for pwm in [1650] * 25 + [1350] * 25:
        plane.set_rc_override({4: pwm})
        plane.step(DT_S)
        if pwm == 1650:
            peak = plane.truth().yaw_deg
    assert peak > start + 1.0
    assert plane.truth().yaw_deg < peak


def test_copter_sticks_lean_and_fly_it() -> None:
    copter = build(COPTER, (0.0, 0.0, 20.0), mode="STABILIZE")
    copter.set_pilot({1: 1900})  # full right roll
    states = run(copter, 20.0)
    assert states[-1].roll_deg == pytest.approx(30.0, abs=0.01)  # ArduCopter ANGLE_MAX
    assert states[-1].ground_speed_m_s == pytest.approx(12.0, abs=0.05)  # settles at max
    assert states[-1].east_m > 100.0  # heading north, rolling right flies east
    assert states[-1].up_m == pytest.approx(20.0, abs=1e-6)  # mid throttle holds altitude
    copter.set_pilot({1: 1500, 3: 1100})  # minimum throttle: descends and lands
    states = run(copter, 40.0)
    assert states[-1].up_m == 0.0
    assert copter.armed  # only LAND disarms


def test_rover_manual_drives_forward_reverses_and_steers() -> None:
    rover = build(ROVER)
    rover.set_pilot({3: 1900})
    assert run(rover, 10.0)[-1].north_m > 40.0
    rover.set_pilot({3: 1100})
    assert run(rover, 10.0)[-1].velocity_north_m_s == pytest.approx(-10.0)
    rover.set_pilot({3: 1700, 1: 1900})
    states = run(rover, 10.0)
    assert states[-1].throttle_pct == pytest.approx(50.0)
    assert states[-1].yaw_deg != states[0].yaw_deg


# --- RC and servo channels ---------------------------------------------------------------------


def test_rc_defaults_overrides_release_and_lapse() -> None:
    plane = build(PLANE)
    pilot = plane.rc_inputs()
    assert len(pilot) == 16
    assert pilot[:4] == (1500, 1500, 1100, 1500)  # trims; throttle at its minimum
    assert pilot[7] == 1500  # mode switch at trim
    assert build(ROVER).rc_inputs()[2] == 1500  # a rover's throttle is centred
    assert build(COPTER).rc_inputs()[2] == 1100
    plane.set_pilot({8: 1900})
    plane.set_rc_override({1: 1650, 3: 1300})
    assert plane.rc_inputs()[:3] == (1650, 1500, 1300)
    assert plane.rc_inputs()[7] == 1900
    plane.set_rc_override({3: 0})  # release: the pilot's stick again
    assert plane.rc_inputs()[2] == 1100
    run(plane, 2.9)
    assert plane.rc_inputs()[0] == 1650
    run(plane, 0.2)  # not refreshed for 3 s: lapsed (ArduPilot RC_OVERRIDE_TIME)
    assert plane.rc_inputs()[0] == 1500
    forever = build(PLANE, rc_override_timeout_s=None)
    forever.set_rc_override({1: 1650})
    run(forever, 10.0)
    assert forever.rc_inputs()[0] == 1650
    with pytest.raises(ValueError, match=r"outside 1\.\.16"):
        plane.set_rc_override({17: 1500})
    with pytest.raises(ValueError, match=r"outside 1\.\.16"):
        plane.set_pilot({0: 1500})


def test_plane_servo_outputs_follow_their_channels_and_free_outputs_take_set_servo() -> None:
    plane = build(CUB, (0.0, 0.0, 100.0), mode="MANUAL")
    outputs = plane.servo_outputs()
    assert len(outputs) == 16
    assert outputs[0] == 1500 and outputs[1] == 1500 and outputs[3] == 1500
    assert 1100 < outputs[2] < 1900  # cruise throttle
    assert outputs[4:] == (0,) * 12  # never driven
    assert plane.servo_function(1) == "roll"
    assert plane.servo_function(3) == "throttle"
    assert plane.servo_function(6) is None
    plane.set_rc_override({1: 1650, 2: 1300})
    plane.step(DT_S)
    assert plane.servo_outputs()[:2] == (1650, 1300)  # MANUAL passes the sticks through
    plane.set_servo(1, 1900)  # has a function: ignored, as ArduPilot does
    plane.set_servo(6, 1234)
    assert plane.servo_outputs()[0] == 1650
    assert plane.servo_outputs()[5] == 1234
    with pytest.raises(ValueError, match=r"outside 1\.\.16"):
        plane.set_servo(17, 1500)
    # In an automatic mode the outputs are the autopilot's demands.
    assert plane.set_mode("LOITER")
    plane.set_rc_override({1: 0, 2: 0})
    run(plane, 20.0)
    assert plane.servo_outputs()[0] > 1500  # banked right around the loiter


def test_copter_motor_outputs_follow_the_throttle() -> None:
    copter = build(COPTER, armed=False)
    assert copter.servo_outputs()[:5] == (1000, 1000, 1000, 1000, 0)
    assert copter.servo_function(4) == "motor" and copter.servo_function(5) is None
    hovering = build(COPTER, (0.0, 0.0, 10.0))
    hovering.step(DT_S)
    assert hovering.servo_outputs()[:4] == (1500, 1500, 1500, 1500)
    assert hovering.truth().throttle_pct == pytest.approx(50.0)


def test_compiled_config_channels_drive_the_model() -> None:
    path = ROOT / "missions" / "three_vehicles_payload.yaml"
    result = validate_path(path, path.name)
    assert result.mission is not None
    for name, text in compile_mission(result.mission).items():
        config = config_from_dict(json.loads(text))
        if not config.is_vehicle:
            continue
        hardware = config.raw["agent"]["hardware"]
        position = config.raw["agent"]["position"]
        vehicle = make_vehicle(
            hardware["airframe"],
            hardware["autopilot"],
            config.channels,
            (config.origin_lat_deg, config.origin_lon_deg, config.origin_alt_m),
            (position["north_m"], position["east_m"], position["up_m"]),
            random.Random(config.agent_id),
        )
        assert dict(vehicle.modes) == dict(config.modes), name
        run(vehicle, 1.0)
        if name == "anaconda":
            # The V-tail's ruddervators mix elevator and rudder: no output of their own.
            assert vehicle.servo_function(1) == "roll"
            assert vehicle.servo_function(2) is None
            assert vehicle.servo_function(4) is None


# --- integration step, determinism and GPS ------------------------------------------------------


@pytest.mark.parametrize("pair", [COPTER, PLANE, ROVER])
def test_the_step_size_does_not_change_the_trajectory(pair: tuple[str, str]) -> None:
    finals = []
    for dt_s in (0.01, 0.02, 0.1, 1.0):
        vehicle = build(pair, (0.0, 0.0, 40.0), mode="GUIDED")
        assert goto(vehicle, 150.0, 80.0, 50.0)
        for _ in range(round(60.0 / dt_s)):
            vehicle.step(dt_s)
        finals.append(vehicle.truth())
    for final in finals[1:]:
        assert distance(final, finals[0].north_m, finals[0].east_m) < 3.0
        assert final.up_m == pytest.approx(finals[0].up_m, abs=0.5)
    with pytest.raises(ValueError, match="back in time"):
        build(pair).step(-0.1)


def _trace(seed: int) -> list[object]:
    vehicle = build(PLANE, (0.0, 0.0, 50.0), seed=seed)
    states = _exercise(vehicle, seed=3, minutes=2)
    fixes: list[object] = []
    for _ in range(100):
        vehicle.step(DT_S)
        fixes.append(vehicle.gps_fix())
    return [*states, *fixes]


def test_same_seed_gives_identical_trajectories_and_fixes() -> None:
    first, second, other = _trace(5), _trace(5), _trace(6)
    assert first == second
    truths = [t for t in first if isinstance(t, Truth)]
    assert truths == [t for t in other if isinstance(t, Truth)]  # only the GPS is random
    assert first != other


def test_gps_noise_matches_the_thesis_static_test() -> None:
    rover = build(ROVER, (12.0, -7.0), armed=False, gps_noise_m=DEFAULT_GPS_NOISE_M)
    north, east, up, errors = [], [], [], []
    for _ in range(20000):
        rover.step(0.2)  # one fix per step at 5 Hz
        fix = rover.gps_fix()
        local = to_local(fix.lat_deg, fix.lon_deg, fix.alt_m, ORIGIN)
        north.append(local.north_m - 12.0)
        east.append(local.east_m + 7.0)
        up.append(local.up_m)
        errors.append(math.hypot(north[-1], east[-1]))
    for axis in (north, east):
        assert abs(statistics.fmean(axis)) < 0.015
        assert statistics.stdev(axis) == pytest.approx(0.5, rel=0.03)
    assert statistics.stdev(up) == pytest.approx(1.0, rel=0.03)
    # Thesis 5.1.5: mean error 0.62 m, standard deviation 0.33 m.
    assert statistics.fmean(errors) == pytest.approx(0.62, abs=0.02)
    assert statistics.stdev(errors) == pytest.approx(0.33, abs=0.02)


def test_gps_fixes_come_at_the_gps_rate_and_truth_is_exact() -> None:
    copter = build(COPTER)
    fixes, times = [copter.gps_fix()], [copter.gps_fix_time_s]
    for _ in range(100):  # 2 s at 50 Hz
        copter.step(DT_S)
        if copter.gps_fix() != fixes[-1]:
            fixes.append(copter.gps_fix())
            times.append(copter.gps_fix_time_s)
    assert len(fixes) == 11  # t = 0, 0.2, ..., 2.0 at 5 Hz
    assert times == pytest.approx([0.2 * k for k in range(11)])
    truth = copter.truth()
    assert (truth.lat_deg, truth.lon_deg, truth.up_m) == (ORIGIN.lat_deg, ORIGIN.lon_deg, 0.0)
    slow = build(COPTER, gps_rate_hz=2.0)
    changes = 0
    last = slow.gps_fix()
    for _ in range(100):
        slow.step(DT_S)
        changes += slow.gps_fix() != last
        last = slow.gps_fix()
    assert changes == 4
    autopilot = {**profile("autopilots", COPTER[1]), "gps_rate_hz": 10.0}
    fast = make_vehicle(
        profile("airframes", COPTER[0]), autopilot, None, ORIGIN, (0, 0), random.Random()
    )
    fast.step(0.1)
    assert fast.gps_fix_time_s == pytest.approx(0.1)
    exact = build(COPTER, gps_noise_m=0.0, gps_vertical_noise_m=0.0)
    assert exact.gps_fix() == (ORIGIN.lat_deg, ORIGIN.lon_deg, 0.0)


def test_takeoff_is_a_multirotor_guided_command() -> None:
    copter = build(COPTER)
    assert not copter.takeoff(10.0), "not in guided"
    assert copter.set_mode("GUIDED")
    assert copter.takeoff(10.0)
    final = run(copter, 20.0)[-1]
    assert final.up_m == pytest.approx(10.0, abs=0.01)
    assert (final.north_m, final.east_m) == (0.0, 0.0)
    assert not copter.takeoff(20.0), "already flying"
    assert not build(ROVER, mode="GUIDED").takeoff(10.0)
