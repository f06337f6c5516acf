"""Helpers of the flight scenarios: positions, targets, tracks and the streams they need.

Positions are GLOBAL_POSITION_INT's (what a ground station sees), stamped with its own
``time_boot_ms``; distances use a flat earth around the first point (legs of a few
hundred metres). Heights are GLOBAL_POSITION_INT.relative_alt, above home.
"""

from __future__ import annotations

import math
import random
import statistics
from collections.abc import Iterator, Mapping
from contextlib import contextmanager
from typing import Any, NamedTuple

from harness import Peer
from pymavlink.dialects.v20 import ardupilotmega as mavlink2

from clark_engine.sim.wind import WindConfig, WindField

EARTH_M_PER_DEG = 111_194.93
"""Metres per degree of latitude (the sphere of radius 6 371 km)."""

POSITION_MASK = 0x0DF8
"""SET_POSITION_TARGET_GLOBAL_INT type_mask: position only (ArduPilot's usual one)."""

FLIGHT_STREAMS: Mapping[str, int] = {
    "GLOBAL_POSITION_INT": 100_000,
    "VFR_HUD": 100_000,
    "EXTENDED_SYS_STATE": 100_000,
    "HEARTBEAT": 100_000,
    "MISSION_CURRENT": 500_000,
    "POSITION_TARGET_GLOBAL_INT": 500_000,
}
"""What a flight scenario watches, and how often (us)."""


class Fix(NamedTuple):
    """One GLOBAL_POSITION_INT: time (s), position, height above home, speeds (m/s)."""

    t_s: float
    lat_deg: float
    lon_deg: float
    up_m: float
    north_m_s: float
    east_m_s: float
    climb_m_s: float

    @property
    def ground_speed_m_s(self) -> float:
        return math.hypot(self.north_m_s, self.east_m_s)


def fix_of(msg: Any) -> Fix:
    return Fix(
        msg.time_boot_ms / 1000.0,
        msg.lat / 1e7,
        msg.lon / 1e7,
        msg.relative_alt / 1000.0,
        msg.vx / 100.0,
        msg.vy / 100.0,
        -msg.vz / 100.0,
    )


def offset_m(lat0: float, lon0: float, lat: float, lon: float) -> tuple[float, float]:
    """(north, east) metres from (lat0, lon0) to (lat, lon)."""
    north = (lat - lat0) * EARTH_M_PER_DEG
    east = (lon - lon0) * EARTH_M_PER_DEG * math.cos(math.radians(lat0))
    return north, east


def distance_m(a: tuple[float, float], b: tuple[float, float]) -> float:
    """Horizontal distance between two (lat, lon)."""
    return math.hypot(*offset_m(a[0], a[1], b[0], b[1]))


def moved(lat0: float, lon0: float, north_m: float, east_m: float) -> tuple[float, float]:
    """(lat, lon) ``north_m``, ``east_m`` from (lat0, lon0)."""
    return (
        lat0 + north_m / EARTH_M_PER_DEG,
        lon0 + east_m / (EARTH_M_PER_DEG * math.cos(math.radians(lat0))),
    )


def here(peer: Peer) -> Fix:
    """The next position report."""
    return fix_of(peer.wait_for("GLOBAL_POSITION_INT", 2.0))


def track(peer: Peer, since: int) -> list[Fix]:
    """Every position report since a mark."""
    return [fix_of(m) for _, m in peer.history[since:] if m.get_type() == "GLOBAL_POSITION_INT"]


def goto(peer: Peer, lat: float, lon: float, up_m: float, mask: int = POSITION_MASK) -> None:
    """SET_POSITION_TARGET_GLOBAL_INT, relative-altitude frame (no answer comes)."""
    peer.send(
        mavlink2.MAVLink_set_position_target_global_int_message(
            0,
            peer.spec.system_id,
            1,
            mavlink2.MAV_FRAME_GLOBAL_RELATIVE_ALT_INT,
            mask,
            round(lat * 1e7),
            round(lon * 1e7),
            up_m,
            0,
            0,
            0,
            0,
            0,
            0,
            0,
            0,
        )
    )


def reposition(peer: Peer, lat: float, lon: float, up_m: float) -> Any:
    """DO_REPOSITION (COMMAND_INT, above home, into GUIDED); returns the COMMAND_ACK."""
    peer.send(
        mavlink2.MAVLink_command_int_message(
            peer.spec.system_id, 1, mavlink2.MAV_FRAME_GLOBAL_RELATIVE_ALT_INT,
            mavlink2.MAV_CMD_DO_REPOSITION, 0, 0, -1,
            mavlink2.MAV_DO_REPOSITION_FLAGS_CHANGE_MODE, 0, 0,
            round(lat * 1e7), round(lon * 1e7), up_m,
        )
    )  # fmt: skip
    return peer.wait_for(
        "COMMAND_ACK", 3.0, where=lambda m: m.command == mavlink2.MAV_CMD_DO_REPOSITION
    )


@contextmanager
def streaming(peer: Peer, streams: Mapping[str, int] = FLIGHT_STREAMS) -> Iterator[Peer]:
    """The peer with ``streams`` at their intervals; the defaults again afterwards."""
    for name, interval_us in streams.items():
        peer.message_interval(name, interval_us)
    try:
        yield peer
    finally:
        for name in streams:
            peer.message_interval(name, 0)


def landed_state(peer: Peer) -> int:
    """EXTENDED_SYS_STATE.landed_state of the next report."""
    return int(peer.wait_for("EXTENDED_SYS_STATE", 1.0).landed_state)


def first(fixes: list[Fix], condition: Any) -> Fix | None:
    """The first fix that meets ``condition``."""
    return next((f for f in fixes if condition(f)), None)


def landed_states(peer: Peer, since: int) -> list[tuple[float, int]]:
    """(time, landed_state) at each change since a mark."""
    states = [
        (peer.time_of(m), int(m.landed_state))
        for _, m in peer.history[since:]
        if m.get_type() == "EXTENDED_SYS_STATE"
    ]
    return [s for i, s in enumerate(states) if i == 0 or s[1] != states[i - 1][1]]


def within(value: float, measured: float, faster: float = 0.9, slower: float = 1.3) -> bool:
    """``value`` is no quicker than ``faster`` x and no slower than ``slower`` x SITL's.

    The simulation may be slower than SITL (its vehicles are not SITL's), never much
    quicker: a mission that keeps to a timing in a dry run must keep to it in flight.
    """
    return faster * measured <= value <= slower * measured


def takeoff(peer: Peer, alt_m: float) -> Any:
    """MAV_CMD_NAV_TAKEOFF to ``alt_m`` above home (COMMAND_LONG); returns the COMMAND_ACK."""
    return peer.command_long(mavlink2.MAV_CMD_NAV_TAKEOFF, 0, 0, 0, math.nan, 0, 0, alt_m)


def disarmed(msg: Any) -> bool:
    """a HEARTBEAT saying disarmed"""
    return not msg.base_mode & mavlink2.MAV_MODE_FLAG_SAFETY_ARMED


ROVER_SPEED_M_S = 3.0
"""WP_SPEED of the rover scenarios (SITL's rover.parm has 5; the Slash's profile 3)."""
COPTER_SPEED_CM_S = 500.0
"""WPNAV_SPEED of the copter scenarios (SITL's copter.parm has 1000; the F450's 500)."""


@contextmanager
def flight_params(peer: Peer, params: Mapping[str, float]) -> Iterator[Peer]:
    """The peer with ``params`` set (on both autopilots alike), put back afterwards."""
    before = {name: peer.param_get(name).param_value for name in params}
    try:
        for name, value in params.items():
            peer.param_set(name, value)
        yield peer
    finally:
        for name, value in before.items():
            peer.param_set(name, value)


@contextmanager
def sim_wind(peer: Peer, params: Mapping[str, float]) -> Iterator[Peer]:
    """The peer's vehicle in the wind ArduPilot SITL's SIM_WIND_* ``params`` describe.

    On SITL the parameters themselves (put back afterwards); on the simulated autopilot
    the same air as the dry run gives it for the equivalent ``sim.wind``
    (:meth:`WindConfig.from_sitl_params`), still air again afterwards.
    """
    model = getattr(peer.link, "model", None)
    if model is None:
        with flight_params(peer, params):
            yield peer
        return
    seed = int(peer.spec.mission.sim.get("seed", 0))
    model.set_wind(WindField(WindConfig.from_sitl_params(params), seed))
    try:
        yield peer
    finally:
        model.set_wind(None)


GPS_FIX_PERIOD_S = 0.2
"""SITL's GPS rate (SIM_GPS1_HZ 5) and the simulated receiver's: a fresh noise per fix."""
GPS_GLITCHES = ("SIM_GPS1_GLTCH_X", "SIM_GPS1_GLTCH_Y")
"""SITL's GPS offset (degrees of latitude and longitude), which its SIM_GPS.cpp adds."""


def gps_glitch(peer: Peer, north_m: float, east_m: float) -> None:
    """Set SITL's GPS offset (metres, sent as degrees), without waiting for the echoes."""
    lat_deg = peer.last["GLOBAL_POSITION_INT"].lat / 1e7
    per_deg_lon = EARTH_M_PER_DEG * math.cos(math.radians(lat_deg))
    for name, value in zip(
        GPS_GLITCHES, (north_m / EARTH_M_PER_DEG, east_m / per_deg_lon), strict=True
    ):
        peer.send(
            mavlink2.MAVLink_param_set_message(
                peer.spec.system_id, 1, name.encode("ascii"), value, mavlink2.MAV_PARAM_TYPE_REAL32
            )
        )


def run_with_gps_noise(peer: Peer, seconds: float, noise_m: float, seed: int) -> None:
    """Run ``seconds`` with white GPS noise of ``noise_m`` per horizontal axis, fresh per fix.

    SITL's GPS has no horizontal noise of its own (SIM_GPS1_NOISE is a slow sine on
    the altitude): every fix's worth of its time it gets a fresh Gaussian offset
    through SIM_GPS1_GLTCH_X/_Y, drawn from ``random.Random(seed)``, and none after.
    The simulated vehicle gets the dry run's ``sim.gps_noise_m`` (horizontal only, its
    own seeded draws), and none after.
    """
    model = getattr(peer.link, "model", None)
    if model is not None:
        model.set_gps_noise(noise_m, 0.0)
        try:
            peer.run_for(seconds)
        finally:
            model.set_gps_noise(0.0, 0.0)
        return
    rng = random.Random(seed)
    t0_s = peer.now_s
    fixes = 0
    try:
        while peer.now_s < t0_s + seconds:
            due_s = t0_s + fixes * GPS_FIX_PERIOD_S
            if due_s > peer.now_s:
                peer.run_for(due_s - peer.now_s)
            gps_glitch(peer, rng.gauss(0.0, noise_m), rng.gauss(0.0, noise_m))
            fixes += 1
    finally:
        gps_glitch(peer, 0.0, 0.0)


def autocorrelation(values: list[float], lag: int) -> float:
    """The autocorrelation of ``values`` after ``lag`` samples (0 for a constant series)."""
    mean = statistics.fmean(values)
    spread = sum((v - mean) ** 2 for v in values)
    if spread == 0.0:
        return 0.0
    return (
        sum((values[i] - mean) * (values[i + lag] - mean) for i in range(len(values) - lag))
        / spread
    )
