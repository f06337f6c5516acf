"""Probe: a plane's airspeed against its ground speed, and its answer to stick-mixed sticks.

One flight on the simulated autopilot or ArduPilot SITL (the conformance harness's
backends), the Super Cub of supercub_sysid as ``--autopilot sitl`` gives it to SITL
(AIRSPEED_CRUISE 18, ArduPlane's pitch limits, RC1/RC2 calibrated 1100-1900 us): taken off,
flown straight north at 60 m above home (150 m above sea level), then LOITER. Prints:

- VFR_HUD ground speed over airspeed flying straight and circling (EAS against true);
- NAV_CONTROLLER_OUTPUT's nav_roll just before and 0.1 s into 150 us of aileron either way,
  and the roll's largest excursion within 2 s (the stick's scale, the roll's dynamics);
- for 8 s bursts of a 100 us elevator sine at each ``--freqs`` frequency (4 s apart): the
  pitch's amplitude and phase at that frequency, the bank's mean and s.d., the course's
  rate round the circle and the altitude's range (the band-pass of the pitch, the circle);
  then the bank's swing at that frequency and the course's (GLOBAL_POSITION_INT's velocity)
  against tan(bank) times the flight path's (climb over ground speed): what a pull in a bank
  turns (amplitude in degrees, phase in degrees).

Used to fit the simulated plane's equivalent airspeed, stick mixing and stick-pitch band-pass
(clark_engine/sim/ardupilot/airframes/stick_mixing.py; docs/performance.md, "The plane under
stick mixing").

    PYTHONPATH=.:tests/conformance python benchmarks/probe_plane_stick.py sitl-plane
"""

from __future__ import annotations

import argparse
import math
import statistics
import sys
from pathlib import Path
from typing import Any

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests" / "conformance"))

from flight import FLIGHT_STREAMS, fix_of, flight_params, moved, reposition, streaming
from harness import open_peer
from pymavlink.dialects.v20 import ardupilotmega as mavlink2

PARAMS = {
    "AIRSPEED_CRUISE": 18.0,
    "AIRSPEED_MIN": 13.0,
    "AIRSPEED_MAX": 30.0,
    "WP_LOITER_RAD": 60.0,
    "NAVL1_PERIOD": 17.0,
    "NAVL1_DAMPING": 0.75,
    "ROLL_LIMIT_DEG": 45.0,
    "PTCH_LIM_MAX_DEG": 20.0,
    "PTCH_LIM_MIN_DEG": -25.0,
    "TKOFF_ALT": 60.0,
    "RC1_MIN": 1100,
    "RC1_MAX": 1900,
    "RC2_MIN": 1100,
    "RC2_MAX": 1900,
}


def override(peer: Any, channels: dict[int, int]) -> None:
    """One RC_CHANNELS_OVERRIDE from the ground station (other channels: no change)."""
    values = [channels.get(ch, 65535 if ch <= 8 else 0) for ch in range(1, 19)]
    peer.send(peer._mav.rc_channels_override_encode(peer.spec.system_id, 1, *values))


def seen(peer: Any, since: int, kind: str, start_s: float = -math.inf) -> list[Any]:
    """The messages of one kind since a mark, seen at or after ``start_s``."""
    return [
        m for _, m in peer.history[since:] if m.get_type() == kind and peer.time_of(m) >= start_s
    ]


def hud_ratio(peer: Any, since: int) -> str:
    """Mean VFR_HUD ground speed, airspeed and their ratio since a mark."""
    hud = seen(peer, since, "VFR_HUD")
    ground = statistics.mean(m.groundspeed for m in hud)
    air = statistics.mean(m.airspeed for m in hud)
    return f"ground {ground:.3f} m/s, airspeed {air:.3f} m/s, ratio {ground / air:.4f}"


def course_rate_deg_s(fixes: list[Any]) -> float:
    """How fast the course over the ground turns (deg/s; a least-squares slope)."""
    courses = np.unwrap([math.atan2(f.east_m_s, f.north_m_s) for f in fixes])
    return math.degrees(float(np.polyfit([f.t_s for f in fixes], courses, 1)[0]))


def phasor(times_s: Any, values: Any, frequency_hz: float) -> complex:
    """``values``' component at ``frequency_hz`` as ``amplitude * exp(1j * phase)`` of a sine."""
    omega = 2.0 * math.pi * frequency_hz
    t = np.asarray(times_s)
    basis = np.column_stack([np.sin(omega * t), np.cos(omega * t), np.ones_like(t), t])
    (a, b, _, _), *_ = np.linalg.lstsq(basis, np.asarray(values), rcond=None)
    return complex(a, b)


def swing(z: complex) -> str:
    """A phasor as 'amplitude@phase' (degrees)."""
    return f"{abs(z):.2f}@{math.degrees(math.atan2(z.imag, z.real)):+.0f}"


def main() -> int:
    """Fly the probe on the backend named on the command line; print its figures."""
    parser = argparse.ArgumentParser()
    parser.add_argument("backend")
    parser.add_argument("--freqs", default="0.3,0.6,1.0,1.5", help="elevator sines, Hz")
    args = parser.parse_args()
    frequencies = [float(f) for f in args.freqs.split(",")]
    peer = open_peer(args.backend)
    try:
        peer.wait_ready()
        streams = dict(FLIGHT_STREAMS, ATTITUDE=50_000, NAV_CONTROLLER_OUTPUT=50_000)
        with flight_params(peer, PARAMS), streaming(peer, streams):
            home = peer.wait_for("HOME_POSITION", 5.0, since=0)
            assert peer.set_mode("TAKEOFF").result == mavlink2.MAV_RESULT_ACCEPTED
            assert peer.arm().result == mavlink2.MAV_RESULT_ACCEPTED
            peer.wait_for("EXTENDED_SYS_STATE", 90.0, where=lambda m: m.landed_state == 2)
            far = moved(home.latitude / 1e7, home.longitude / 1e7, 4000.0, 0.0)
            assert reposition(peer, *far, 60.0).result == mavlink2.MAV_RESULT_ACCEPTED
            peer.run_for(30.0)
            mark = peer.mark()
            peer.run_for(20.0)
            print(f"{args.backend} straight: {hud_ratio(peer, mark)}")
            assert peer.set_mode("LOITER").result == mavlink2.MAV_RESULT_ACCEPTED
            peer.run_for(25.0)
            mark = peer.mark()
            peer.run_for(20.0)
            rest = [fix_of(m) for m in seen(peer, mark, "GLOBAL_POSITION_INT")]
            print(f"{args.backend} circling: {hud_ratio(peer, mark)}, course "
                  f"{course_rate_deg_s(rest):.3f} deg/s")  # fmt: skip
            for pwm_us in (1350, 1650):
                before = seen(peer, mark, "NAV_CONTROLLER_OUTPUT")[-1].nav_roll
                roll = seen(peer, mark, "ATTITUDE")[-1].roll
                mark = peer.mark()
                sent_s = peer.now_s
                for _ in range(5):
                    override(peer, {1: pwm_us})
                    peer.run_for(0.2)
                override(peer, {1: 0})
                peer.run_for(1.0)
                nav = seen(peer, mark, "NAV_CONTROLLER_OUTPUT", sent_s + 0.1)[0].nav_roll
                rolls = [m.roll - roll for m in seen(peer, mark, "ATTITUDE")]
                peak = math.degrees(min(rolls) if pwm_us < 1500 else max(rolls))
                print(f"{args.backend} aileron {pwm_us} us: nav_roll {before:.1f} -> {nav:.1f} "
                      f"deg, roll's peak {peak:+.1f} deg within 2 s")  # fmt: skip
                peer.run_for(6.0)
            for frequency_hz in frequencies:
                mark = peer.mark()
                start_s = peer.now_s
                while peer.now_s < start_s + 8.0:
                    phase = 2.0 * math.pi * frequency_hz * (peer.now_s - start_s)
                    override(peer, {2: round(1500 + 100 * math.sin(phase))})
                    peer.run_for(0.04)
                override(peer, {2: 0})
                attitude = seen(peer, mark, "ATTITUDE", start_s + 1.0)
                t = np.array([peer.time_of(m) - start_s for m in attitude])
                pitch = np.degrees([m.pitch for m in attitude])
                bank = np.degrees([m.roll for m in attitude])
                omega = 2.0 * math.pi * frequency_hz
                basis = np.column_stack([np.sin(omega * t), np.cos(omega * t), np.ones_like(t), t])
                (a, b, _, _), *_ = np.linalg.lstsq(basis, pitch, rcond=None)
                fixes = [fix_of(m) for m in seen(peer, mark, "GLOBAL_POSITION_INT", start_s + 1)]
                ups = [f.up_m for f in fixes]
                fix_t = [f.t_s - start_s for f in fixes]
                course = np.degrees(np.unwrap([math.atan2(f.east_m_s, f.north_m_s) for f in fixes]))
                path = [
                    math.degrees(math.atan2(f.climb_m_s, math.hypot(f.north_m_s, f.east_m_s)))
                    for f in fixes
                ]
                pull = math.tan(math.radians(bank.mean())) * phasor(fix_t, path, frequency_hz)
                print(f"{args.backend} elevator {frequency_hz:g} Hz: pitch {math.hypot(a, b):.2f} "
                      f"deg at {math.degrees(math.atan2(b, a)):+.0f} deg, bank {bank.mean():.1f} "
                      f"s.d. {bank.std():.1f} deg, course {course_rate_deg_s(fixes):.2f} deg/s, "
                      f"altitude range {max(ups) - min(ups):.2f} m")  # fmt: skip
                print(f"{args.backend} elevator {frequency_hz:g} Hz: bank swing "
                      f"{swing(phasor(t, bank, frequency_hz))}, course swing "
                      f"{swing(phasor(fix_t, course, frequency_hz))} against tan(bank) x flight "
                      f"path {swing(pull)} deg")  # fmt: skip
                peer.run_for(4.0)
            assert peer.set_mode("RTL").result == mavlink2.MAV_RESULT_ACCEPTED
    finally:
        peer.close()
    return 0


if __name__ == "__main__":
    sys.exit(main())
