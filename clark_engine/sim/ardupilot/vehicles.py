"""Point-mass vehicle models for the dry run: multirotor, fixed wing and rover.

Each model is a :class:`~clark_engine.sim.ardupilot.vehicle_model.VehicleModel`: the physics and
the flight-mode logic of one vehicle, limited by its airframe profile and flown
as ArduPilot flies it, with no knowledge of MAVLink. They are point masses with
first-order attitude dynamics: enough to make a behaviour's commands visible (a
guided leg flies to its point, an aileron doublet rolls the aircraft, a rover
stops at its waypoint) and cheap enough that a 50-vehicle dry run at 50 Hz runs
far faster than real time. They are not flight-dynamics models: no
aerodynamic coefficients, no motor or battery model. A declared wind
(:mod:`clark_engine.sim.wind`, :meth:`SimulatedVehicle.set_wind`) enters where the
air's velocity enters each model: a multirotor's drag is on its velocity through
the air and its position controller leans into the wind it has learnt, within its
lean limit (a wind stronger than it can lean into carries it away); a fixed wing
flies its airspeed through the air and steers its track over the ground, banking
within its limit (a loiter circle drifts downwind where the bank cannot hold it);
a rover takes none, as SITL's rover takes none.

The project's promise is that what passes the dry run flies on real ArduPilot,
so a model must never be kinder than ArduPilot: it flies ArduPilot's parameters
(:meth:`SimulatedVehicle.configure`, ArduPilot's names and units, ArduPilot's
defaults until the autopilot layer says otherwise), and where ArduPilot's
behaviour was measured on SITL (the build in ``../shared/ardupilot-sitl``, the
fact sheets of the conformance work) the constants below are fitted to those
measurements and say so. Every other constant is an ArduPilot default or a
stated assumption. New parameter values apply at the next mode entry or target
(a rover's only at the next mode entry: a PARAM_SET of WP_SPEED mid-leg, or
before a new target, changes nothing on ArduRover until GUIDED is re-entered).

Conventions:
    Local frame north/east/up in metres from the mission origin; angles are
    radians inside, degrees in :class:`~clark_engine.sim.ardupilot.vehicle_model.Truth`. Yaw is
    in (-180, 180] (MAVLink ATTITUDE), heading is the same nose direction in
    [0, 360) (what ArduPilot reports in VFR_HUD and GLOBAL_POSITION_INT). RC
    polarity is ArduPilot's: a pulse above trim rolls right, pitches the nose
    UP (the pitch stick pulled back), yaws right, steers right, and on a
    centred rover throttle drives forward. Heights that ArduPilot measures
    above home (RTL_ALT, LAND_ALT_LOW, a takeoff's altitude, TKOFF_ALT,
    RTL_ALTITUDE) are above :attr:`SimulatedVehicle.home_m`; the ground is flat
    at the origin's altitude (up 0).

Mode classification (ArduPilot mode names from the autopilot profile; the
profile's ``guided_mode``, ``hold_mode``, ``rtl_mode``, ``land_mode`` and
``manual_mode`` roles come first, then the names below):

=========== ================================ ======================= ==================
behaviour   multirotor (ArduCopter)          fixed wing (ArduPlane)  rover (ArduRover)
=========== ================================ ======================= ==================
manual      STABILIZE ACRO RATE_ACRO DRIFT   MANUAL STABILIZE        MANUAL ACRO
            ALT_HOLD SPORT FLOWHOLD          TRAINING ACRO FBWA      STEERING SIMPLE
                                             FBWB CRUISE AUTOTUNE
guided      GUIDED                           GUIDED                  GUIDED
auto        AUTO                             AUTO                    AUTO
hold        LOITER BRAKE POSHOLD CIRCLE      LOITER                  HOLD LOITER
rtl         RTL SMART_RTL AUTO_RTL           RTL                     RTL SMART_RTL
land        LAND                             (none)                  (none)
takeoff     (none)                           TAKEOFF                 (none)
refused     (none)                           INITIALISING, Q modes   INITIALISING
                                             but LOITERALTQLAND
=========== ================================ ======================= ==================

Every other mode of the profile (THROW, ZIGZAG, GUIDED_NOGPS, ArduPlane's
CIRCLE, AUTOLAND and LOITERALTQLAND, ArduRover's CIRCLE, ...) is accepted and
flown as the hold mode: the model has no follow target and no landing sequence
for them, so it does what a careful pilot expects of an unmodelled mode, stay
put. ``unsimulated_modes`` lists them (an ArduCopter one that takes the pilot's
throttle as a climb rate, ZIGZAG, AUTOTUNE, SYSTEMID, still does, below). The
autopilot layer refuses, as ArduPilot does, the modes whose start fails on these
vehicles (FLIP, FOLLOW, FLOWHOLD...; :mod:`clark_engine.sim.ardupilot.firmware`).
ArduPlane refuses its Q (quadplane) modes on an aircraft without VTOL motors
(but enters LOITERALTQLAND, whose landing never comes) and nobody can select
INITIALISING, so the models refuse them too. SMART_RTL flies as RTL (straight
home, not back along the path).

Copter throttle (measured on SITL, whose RC throttle rests at its minimum):
STABILIZE, ACRO, RATE_ACRO and DRIFT pass the stick to the motors, mid stick
hovering, so a copter flown only over MAVLink that enters one of them in the
air with the stick at its minimum falls with its motors at idle (SITL hit the
ground at 14.4 m/s from 20 m). ALT_HOLD, SPORT, FLOWHOLD, LOITER, POSHOLD and
CIRCLE take the stick as a climb rate: above and below a dead band around mid
stick (THR_DZ) it climbs at up to PILOT_SPEED_UP and descends at up to
PILOT_SPEED_DN (PILOT_SPEED_UP when 0), so at the minimum they descend at
2.5 m/s until they land (SITL: 2.44 m/s). The rate's change is shaped as
AC_PosControl shapes it (PILOT_ACCEL_Z, PSC_JERK_Z), and with the stick centred a
copter still climbing or sinking (a mode entered during a takeoff's climb) stops
first and holds the height where it stopped. GUIDED, AUTO, RTL, LAND and BRAKE
hold or control their height themselves.

Arming: a vehicle on the ground starts disarmed or armed as its builder says;
a vehicle that starts in the air must start armed. The autopilot layer does the
arming checks and every disarm after a landing (ArduCopter's 2 s after a
touchdown in LAND or RTL, its 10 s idle disarm); the models never disarm
themselves. Disarming in the air is refused unless forced; a forced disarm
stops the motors where the vehicle is: a copter falls (and reports
``on_ground`` at once, as ArduCopter's landed state does), a plane glides.

RC and servos: the pilot's transmitter starts with every mapped channel at its
trim, the throttle at its minimum (copter, plane) or trim (rover, centred),
unmapped channels at 1500 us; a vehicle that starts in the air has a pilot who
is flying it, so its throttle stick starts at hover (mid stick, copter) or at
the level-cruise throttle (plane). An RC override replaces the pilot on its
channel until released (0) or until it lapses after ArduPilot's 3 s
RC_OVERRIDE_TIME. Servo outputs mapped to a control report the autopilot's
demand on it (in a manual mode, the stick passed through); multirotor outputs
1-4 are motors; outputs with no function report what ``set_servo`` last set,
0 before that.

GPS: :meth:`SimulatedVehicle.truth` is exact; :meth:`SimulatedVehicle.gps_fix`
is what a receiver reports: fixes at 5 Hz by default (ArduPilot's GPS_RATE_MS
200 for u-blox receivers; the thesis's LEA-6H ran at 2 Hz and can be modelled
with ``gps_rate_hz=2``), each the true position plus independent Gaussian
errors of 0.5 m per horizontal axis, which reproduces the thesis's static test
(5.1.5: mean error 0.62 m, standard deviation 0.33 m), and 1 m vertically.
Those fixes are what GPS_RAW_INT reports; :meth:`SimulatedVehicle.position_estimate`
is what GLOBAL_POSITION_INT reports, the autopilot's estimate: ArduPilot's EKF passes on
only a smoothed share of the fixes' white noise (about a third, with a memory of about
a second, :data:`EKF_NOISE_TIME_CONSTANT_S`).
"""

from __future__ import annotations

import math
import random
from abc import abstractmethod
from collections import deque
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from enum import Enum
from typing import Any, ClassVar, Final, NamedTuple, Protocol

from clark_engine.errors import ClarkError
from clark_engine.mission.geo import EARTH_RADIUS_M, Origin
from clark_engine.sim.ardupilot.vehicle_model import LandedState, Truth, VehicleModel
from clark_engine.sim.wind import WindField

#: Standard gravity, m/s^2.
G_M_S2 = 9.80665
#: RC input channels reported (RC_CHANNELS carries 18; the profiles use 16).
RC_CHANNEL_COUNT = 16
#: Servo outputs reported (SERVO_OUTPUT_RAW with its extension carries 16).
SERVO_OUTPUT_COUNT = 16
#: Longest integration step; a longer ``step`` is split into equal sub-steps so that
#: accuracy does not depend on the simulator's step.
MAX_SUBSTEP_S = 0.05
#: GPS fix rate when the profile gives none: ArduPilot configures u-blox receivers
#: for 5 Hz (GPS_RATE_MS 200); the thesis's LEA-6H ran at 2 Hz (5.1.5).
DEFAULT_GPS_RATE_HZ = 5.0
#: Per-axis standard deviation of the horizontal GPS error. With 0.5 m on each axis
#: the error's magnitude is Rayleigh distributed with mean 1.2533 * 0.5 = 0.63 m and
#: standard deviation 0.655 * 0.5 = 0.33 m: the thesis's static test (5.1.5: mean
#: 0.62 m, standard deviation 0.33 m), and the mission schema's ``sim.gps_noise_m``.
DEFAULT_GPS_NOISE_M = 0.5
#: Time constant of each of the two first-order lags the reported position's share of the
#: receiver's white noise passes through (:meth:`SimulatedVehicle.position_estimate`):
#: ArduPilot reports its EKF's estimate, which fuses the fixes with the IMU and smooths
#: their noise. A fit to ArduRover SITL at rest fed 0.5 m of white noise per axis at
#: 5 Hz: benchmarks/probe_gps_noise_ekf.py, two runs of 35 s at 5x (GLOBAL_POSITION_INT
#: spread 0.16-0.19 m, autocorrelation 0.76-0.79 after 0.5 s, 0.44-0.53 after 1 s,
#: 0.03-0.07 after 3 s), and tests/conformance/test_gps.py twice (15 s: 0.17 m, 0.77 and
#: 0.79 after 0.5 s), 2026-11-29. Two lags of 0.6 s (with :data:`EKF_NOISE_GAIN`) give,
#: in 35 s windows, 0.165 m, 0.74, 0.41 and -0.04 (medians of 200 seeds). One lag cannot
#: give both the spread and the memory (0.5 s: 0.22 m and 0.38 after 0.5 s).
EKF_NOISE_TIME_CONSTANT_S = 0.6
#: Scale of the smoothed noise: the two lags alone spread 0.14 m in 35 s windows where
#: SITL's estimate spreads 0.16-0.19 m (its EKF is not two fixed lags: its gain follows
#: its covariance); fitted with :data:`EKF_NOISE_TIME_CONSTANT_S`.
EKF_NOISE_GAIN = 1.2
#: Standard deviation of the GPS altitude error: GPS vertical error is typically
#: about twice the per-axis horizontal one.
DEFAULT_GPS_VERTICAL_NOISE_M = 1.0
#: ArduPilot's RC_OVERRIDE_TIME default: an override not refreshed lapses.
DEFAULT_RC_OVERRIDE_TIMEOUT_S = 3.0
#: Pulse width reported for an RC channel the profile does not map (receiver centre).
UNMAPPED_RC_US = 1500

# --- ArduPilot's parameters the models read (names and units as ArduPilot's) -----------

COPTER_DEFAULT_PARAMS: Final[Mapping[str, float]] = {
    "WPNAV_SPEED": 1000.0,  # cm/s, guided/auto horizontal speed
    "WPNAV_ACCEL": 250.0,  # cm/s^2, horizontal acceleration
    "WPNAV_SPEED_UP": 250.0,  # cm/s, climb rate
    "WPNAV_SPEED_DN": 150.0,  # cm/s, descent rate
    "WPNAV_ACCEL_Z": 100.0,  # cm/s^2, vertical acceleration
    "WPNAV_RADIUS": 200.0,  # cm, waypoint radius
    "RTL_ALT": 1500.0,  # cm above home
    "RTL_ALT_FINAL": 0.0,  # cm above home; 0 lands
    "RTL_CLIMB_MIN": 0.0,  # cm
    "RTL_CONE_SLOPE": 3.0,  # RTL climbs at most distance * slope near home
    "RTL_SPEED": 0.0,  # cm/s; 0: WPNAV_SPEED
    "RTL_LOIT_TIME": 5000.0,  # ms above home before descending
    "LAND_SPEED": 50.0,  # cm/s below LAND_ALT_LOW
    "LAND_SPEED_HIGH": 0.0,  # cm/s above LAND_ALT_LOW; 0: WPNAV_SPEED_DN
    "LAND_ALT_LOW": 1000.0,  # cm above home
    "PILOT_SPEED_UP": 250.0,  # cm/s, full-stick climb in the pilot's climb-rate modes
    "PILOT_SPEED_DN": 0.0,  # cm/s; 0: PILOT_SPEED_UP
    "PILOT_ACCEL_Z": 250.0,  # cm/s^2
    "THR_DZ": 100.0,  # dead band around mid stick, in 1/1000 of the throttle range
    "PSC_JERK_Z": 5.0,  # m/s^3, how fast the vertical acceleration target may change
    "CIRCLE_RADIUS": 1000.0,  # cm
    "CIRCLE_RATE": 20.0,  # deg/s, positive clockwise
}
"""ArduCopter's defaults (AC_WPNav, AC_Circle, Copter Parameters.cpp) for what the model
reads; SITL's copter.parm has the same values."""

PLANE_DEFAULT_PARAMS: Final[Mapping[str, float]] = {
    "AIRSPEED_CRUISE": 15.0,  # m/s, guided/auto airspeed
    "AIRSPEED_MIN": 9.0,  # m/s
    "AIRSPEED_MAX": 22.0,  # m/s
    "TKOFF_ALT": 50.0,  # m above home, TAKEOFF mode's climb
    "TKOFF_DIST": 200.0,  # m ahead on the takeoff heading: TAKEOFF mode's loiter point
    "TKOFF_LVL_ALT": 10.0,  # m, wings level below this in a takeoff
    "WP_RADIUS": 90.0,  # m, a waypoint is reached within it
    "WP_LOITER_RAD": 60.0,  # m, the loiter radius
    "RTL_ALTITUDE": 100.0,  # m above home
    "RTL_RADIUS": 0.0,  # m; 0: WP_LOITER_RAD
    "ROLL_LIMIT_DEG": 45.0,  # deg, never above the airframe's max_bank_deg
    "PTCH_LIM_MAX_DEG": 20.0,  # deg, the highest pitch demand (SITL's plane.parm: 25)
    "PTCH_LIM_MIN_DEG": -25.0,  # deg, the lowest (SITL's plane.parm: -20)
    "NAVL1_PERIOD": 17.0,  # s, the L1 navigation period (SITL's plane.parm: 15)
    "NAVL1_DAMPING": 0.75,  # the L1 damping ratio
    "LAND_FLARE_ALT": 3.0,  # m
    "TECS_LAND_SINK": 0.25,  # m/s in the flare
}
"""ArduPlane's defaults (Plane Parameters.cpp, AP_TECS, AP_Landing). SITL's plane.parm
differs (AIRSPEED_CRUISE 22, AIRSPEED_MIN 10, AIRSPEED_MAX 30, WP_RADIUS 50,
WP_LOITER_RAD 80, ROLL_LIMIT_DEG 65): the autopilot layer passes what it holds."""

ROVER_DEFAULT_PARAMS: Final[Mapping[str, float]] = {
    "WP_SPEED": 2.0,  # m/s, guided/auto speed
    "RTL_SPEED": 0.0,  # m/s; 0: WP_SPEED
    "WP_RADIUS": 2.0,  # m, a waypoint is reached within it
    "ATC_ACCEL_MAX": 1.0,  # m/s^2
    "ATC_DECEL_MAX": 0.0,  # m/s^2; 0: ATC_ACCEL_MAX
    "ATC_TURN_MAX_G": 0.6,  # lateral acceleration limit, g
    "TURN_RADIUS": 0.9,  # m, tightest turn
    "WP_JERK": 0.0,  # m/s^3; 0: the acceleration limit's value (AR_WPNav)
}
"""ArduRover's defaults (AR_WPNav, AR_AttitudeControl, Rover Parameters.cpp). SITL's
rover.parm differs (WP_SPEED 5, CRUISE_SPEED 5, WP_RADIUS 3). CRUISE_SPEED is not read:
GUIDED drives at WP_SPEED whatever CRUISE_SPEED says (measured)."""

# --- multirotor constants (measured on ArduCopter SITL unless marked) -----------------

COPTER_RAMP_FRACTION: Final = 0.8
"""Share of WPNAV_ACCEL a copter's horizontal speed ramps up at: SITL's jerk-limited
S-curve went from 0.55 to 8.36 m/s in 3.85 s, about 2.0 of WPNAV_ACCEL's 2.5 m/s^2. It
brakes at the full WPNAV_ACCEL on a square-root profile: with both, legs take 9.9 s for
50 m (SITL: within 0.5 m after 9.38 s), 12.0 s for 70.7 m (11.45 s), 29.9 s for 250 m
(29.85 s) and 22.6 s for 100 m at 5 m/s (21.8 s), never less than SITL."""
COPTER_XY_GAIN_1_S: Final = 1.0
"""Horizontal position gain, 1/s (ArduCopter PSC_POSXY_P)."""
COPTER_Z_BRAKE_FRACTION: Final = 0.6
"""Share of WPNAV_ACCEL_Z a copter brakes at on its square-root approach to a height
(ramping up at the full WPNAV_ACCEL_Z, 1 m/s^2). Fitted with :data:`COPTER_Z_GAIN_1_S` to
SITL's 10 m NAV_TAKEOFF: 2.5 m/s reached after about 2 s, 2.1 m/s at 6 m, 1.2 at 8.6 m, 0.4
at 9.9 m, 9.9 m 6.2-6.5 s after the climb started, no overshoot (the model: 6.8 s)."""
COPTER_Z_GAIN_1_S: Final = 3.0
"""Gain of the last part of a copter's approach to a height, 1/s (fitted, see above)."""
COPTER_WP_DONE_M: Final = 0.5
"""A copter's waypoint is reached within this distance (or WPNAV_RADIUS, if smaller):
ArduCopter's reached_wp_destination needs its S-curve finished, the copter about there."""
COPTER_TAKEOFF_DONE_M: Final = 0.1
"""A takeoff is complete (landed_state IN_AIR) within this height of its altitude."""
COPTER_AUTO_TAKEOFF_DELAY_S: Final = 0.5
"""From MISSION_START to the climb of a copter armed for several seconds: SITL was at
0.29 m climbing 1.18 m/s 1.1 s after MISSION_START (moving from about +0.5 s) and said
"Mission: 2 WP" (the 10 m takeoff done) at +7.3 s; the model: +7.3 s."""
COPTER_FALL_TERMINAL_M_S: Final = 17.0
"""Terminal speed of a copter falling with its motors at idle or stopped, fitted to
SITL's "SIM Hit ground" speeds: 11.85 m/s from 10 m (forced disarm), 14.4 m/s from 20 m
and 15.6 m/s from 30 m (STABILIZE, throttle at minimum). The model gives 11.9, 14.6, 15.9."""
COPTER_MAX_THRUST_RATIO: Final = 2.0
"""Thrust over weight at full throttle in the direct-throttle modes (an assumption, a
typical quadcopter); mid stick hovers, the minimum is motors at idle (no thrust)."""
COPTER_RTL_ALT_MIN_M: Final = 2.0
"""ArduCopter's RTL_ALT_MIN (200 cm): RTL never returns lower."""
COPTER_RTL_MIN_CONE_SLOPE: Final = 0.5
"""ArduCopter's RTL_MIN_CONE_SLOPE: a shallower RTL_CONE_SLOPE turns the cone off."""
COPTER_RTL_SETTLE_S: Final = 2.5
"""Time RTL spends arriving above home before its RTL_LOIT_TIME starts, fitted: SITL
began the final descent 7.5 s after RTL was set directly above home (no climb, no leg,
no turn) and 7.15 s after passing over home on a 50 m return, with RTL_LOIT_TIME 5 s."""
COPTER_RTL_YAW_TOLERANCE_RAD: Final = math.radians(2.0)
#: Time constant over which a copter's position controller learns a changed wind (the
#: velocity controller's integrator, ArduCopter PSC_VELXY_I 1.0 / s with P 2.0): a steady
#: wind is held off after a few seconds, a gust or turbulence pushes it before that.
COPTER_WIND_LEARN_S: Final = 1.0
"""RTL's loiter above home ends only with the nose within 2 degrees of its heading at
arming (ArduCopter's RESET_TO_ARMED_YAW): SITL hovered 5-7 s for a 5 s RTL_LOIT_TIME."""

# --- fixed-wing constants --------------------------------------------------------------

PLANE_TURN_EFFICIENCY: Final = 0.71
"""The share of a coordinated turn's rate (``g tan(bank) / V``) SITL's plane turns at for
its bank in the automatic modes. Measured in its LOITER (NAVL1_PERIOD 17, 15.2 m/s,
WP_LOITER_RAD 60): ATTITUDE's roll equal to NAV_CONTROLLER_OUTPUT's nav_roll, 25.0
degrees, on a 69.1-69.8 m circle, where 25 degrees would turn a 50.5 m one. ArduPlane's L1
loiter asks for the shortfall back in proportion to the distance outside the circle (its
PD term), so the circle settles outside WP_LOITER_RAD where the two balance: 92-93 m for
80 m at 22 m/s with NAVL1_PERIOD 15 (86.6 m at 15 m/s, 98.5 at 28, 101 at 30), 69-70 m
for 60 m at 15 m/s with 17 (:meth:`FixedWing.loiter_radius_m`)."""
PLANE_RC_DEAD_ZONE_US: Final = 30
"""ArduPlane's RCn_DZ for its roll, pitch and rudder sticks (Plane::init_rc_in; SITL
reports 30): what a model never configured from a parameter table reads them with."""
PLANE_STICK_PITCH_GAIN: Final = 2.055
"""Gain of the stick-mixed pitch's band-pass (below) in the automatic modes. A fit, not
ArduPlane's code: ArduPlane adds the elevator stick to TECS's pitch demand
(Plane::stabilize_stick_mixing_fbw), its pitch controller (PTCH2SRV_TCONST 0.25) flies it on
SITL's airframe, and TECS (TECS_TIME_CONST 5, TECS_PTCH_DAMP 0.3) answers the climb and sink
it causes: the pitch answers a sine of elevator as a band-pass, washed out below a few
tenths of a hertz, resonant near 0.8 Hz, cut above 1.2 Hz. Fitted (with the model's own
0.3 s pitch lag) to SITL's pitch in LOITER at 18 m/s, 150 m AMSL, under 100 us elevator
sines (0.19 of the stick, 4.25 degrees of demand; 8 s bursts, runs probe2 and probe3 of
2026-11-28, which two runs reproduced to 0.05 degrees): pitch amplitude 3.06, 3.89, 5.66,
12.91, 10.05, 7.08, 5.91, 2.46 and 1.04 degrees at 0.3, 0.45, 0.6, 0.75, 0.85, 0.95, 1.0,
1.2 and 1.5 Hz; the fit gives 2.91, 4.35, 6.49, 10.68, 10.92, 6.90, 5.39, 2.44 and 1.08
(phases within 16 degrees). Before it, the stick's pitch was a 0.3 s lag: 5.2 degrees at
0.3 Hz falling to 1.9 at 1.5 Hz (2.7 at 1 Hz). SITL's airframe, not the Super Cub's."""
PLANE_STICK_PITCH_WASHOUT_1_S: Final = 5.32
"""The band-pass's wash-out corner, rad/s (the fit above: TECS holding its height)."""
PLANE_STICK_PITCH_MODE_HZ: Final = 0.826
"""Its resonance (the fit above): the pitch loop with TECS on SITL's airframe."""
PLANE_STICK_PITCH_DAMPING: Final = 0.143
"""Its damping ratio (the fit above)."""
PLANE_STICK_PITCH_DELAY_S: Final = 0.12
"""Its delay, s (the fit above; taken in whole physics steps)."""
PLANE_ROLL_COUPLING_S: Final = 0.2
"""Roll per unit of ``sin(bank)`` times the pitch rate (s) that SITL's plane departs from its
roll demand by in the automatic modes: a pull in a bank rolls it further in. A fit, not
ArduPlane's code (what the airframe's roll due to the yaw rate of the tighter turn, against
ArduPlane's roll loop, would give). In LOITER at 18 m/s, bank 32.5 degrees, under the 100 us
elevator sines of :data:`PLANE_STICK_PITCH_GAIN` (probes of 2026-11-28), SITL's bank swung
with its pitch, 0.42-0.56 of the pitch's amplitude at 0.3-1.0 Hz (1.8, 7.05, 5.63, 3.87 and
0.91 degrees at 0.45, 0.75, 0.85, 0.95 and 1.2 Hz), more than its roll demand
(NAV_CONTROLLER_OUTPUT's nav_roll) explains. What is left after the demand's lag is a
second-order, delayed answer to the pitch rate: the mode, damping and delay below, and 0.115
s here, fitted open-loop to SITL's own nav_roll at 0.3-1.5 Hz; in the simulation's closed
loop (its L1 loiter answering its own track) the gain that gives SITL's bank is this one:
1.8-2.2, 5.1, 5.9, 4.8 and 1.8 degrees at those frequencies (0.75 Hz low with the pitch
there, 8.6 degrees against 12.9). With the pull's turn (:meth:`FixedWing._fly`) it is what
tightens SITL's circle at its pitch resonance. SITL's airframe, measured there only."""
PLANE_ROLL_COUPLING_MODE_HZ: Final = 1.09
"""The roll coupling's second-order mode (the fit above)."""
PLANE_ROLL_COUPLING_DAMPING: Final = 0.35
"""Its damping ratio (the fit above)."""
PLANE_ROLL_COUPLING_DELAY_S: Final = 0.14
"""Its delay, s (the fit above; taken in whole physics steps)."""
PLANE_PATH_LAG_S: Final = 0.045
"""How late the flight path follows the pitch attitude, s (a first-order lag: the lift of a
new angle of attack builds up). Measured in SITL's climb rate against its pitch under the
elevator sines above: the flight path's rate lagged the pitch rate by 6-15 degrees at
0.3-1.0 Hz and 27 at 1.5 Hz (0.88-1.0 of its size); this lag gives 5-13 and 23 degrees."""
PLANE_PULL_MAX_G: Final = 2.0
"""The most a pull (or push) adds to the lift, in g: ``V gamma' / g`` for the flight path's
rate gamma'. SITL's plane reached 1.7 at its pitch resonance (0.75 Hz); a step of the elevator
stick, or a climb cut at a limit, asks for more, which no wing gives."""
PLANE_LAUNCH_DELAY_S: Final = 0.2
"""From arming in TAKEOFF (or AUTO with a takeoff) to the launch: ArduPlane's "Armed
AUTO, xaccel = ..., waiting 0.2 sec" then "Triggered AUTO"."""
PLANE_CLIMB_SLEW_M_S2: Final = 2.5
"""How fast the automatic modes change their commanded climb rate (TECS in outline),
fitted to SITL's TAKEOFF: climbing 7-10 m/s through TKOFF_ALT 50 m it peaked at 59.2 m
3 s later, then settled back to 50 m."""
PLANE_LAND_SLOPE_DEG: Final = 3.1
"""Glide slope of a landing with no approach to fit it to: SITL's AUTO landing said
"Landing glide slope 3.1 degrees" (sink 0.8-1.4 m/s at 16 m/s)."""
ISA_SEA_LEVEL_K: Final = 288.15
"""The 1976 standard atmosphere's sea-level temperature, K (15 C)."""
ISA_LAPSE_K_M: Final = 0.0065
"""Its tropospheric lapse rate, K per metre."""
ISA_DENSITY_EXPONENT: Final = G_M_S2 / (ISA_LAPSE_K_M * 287.053) - 1.0
"""rho / rho0 = (T / T0) ** this in the troposphere (g / (L R) - 1, R of dry air)."""


PLANE_AIRSPEED_SENSOR_SCALE: Final = 0.9937
"""What ArduPlane SITL's airspeed sensor reads per m/s of the equivalent airspeed its
simulator flies at (fitted): holding AIRSPEED_CRUISE 18 m/s by it (VFR_HUD airspeed 17.99-
18.01) at 150 m above sea level in still air, SITL's plane flew 18.24-18.25 m/s over the
ground, straight and circling alike (1.0134-1.0138 in two runs, 2026-11-28), where the
standard atmosphere's :func:`eas2tas` gives 1.0072: its simulated analog pitot reads 0.63 %
low. A real aircraft's sensor has its own error (ARSPD_RATIO); this is SITL's."""


def eas2tas(alt_amsl_m: float) -> float:
    """True over equivalent airspeed at ``alt_amsl_m`` in the 1976 standard atmosphere.

    ``sqrt(rho0 / rho)``: the factor ArduPilot SITL's simulator converts its aircraft's
    true airspeed to what the pitot measures with (AP_Baro::get_EAS2TAS_for_alt_amsl,
    called from SITL_State::_update_airspeed), so the EAS ArduPlane holds is flown at
    this times it through the air: 1.0072 at 150 m above sea level. The troposphere's
    law (below 11 km); an altitude below sea level is taken as sea level's density.
    """
    temperature_k = ISA_SEA_LEVEL_K - ISA_LAPSE_K_M * max(alt_amsl_m, 0.0)
    return float((temperature_k / ISA_SEA_LEVEL_K) ** (-0.5 * ISA_DENSITY_EXPONENT))


# --- rover constants (measured on ArduRover SITL) ---------------------------------------

ROVER_APPROACH_DECEL_FRACTION: Final = 0.6
"""Share of the deceleration limit (ATC_DECEL_MAX, or ATC_ACCEL_MAX when 0) the rover
brakes at on its square-root approach to a target. Fitted: on SITL's 40 m GUIDED legs
speed^2 / (2 * distance to the stop) stayed at 0.58-0.63 m/s^2 from 5 m/s down to 1 m/s
(5 m/s to stop in about 8.7 s) with ATC_ACCEL_MAX 1 and ATC_DECEL_MAX 0."""
ROVER_APPROACH_GAIN_1_S: Final = 1.3
"""Gain of the rover's last half metre to a target, 1/s (fitted: 0.78 m/s at 0.66 m from
the stop, 0.57 at 0.45, 0.38 at 0.29)."""
ROVER_STOP_SPEED_M_S: Final = 0.1
"""ArduRover's ATC_STOP_SPEED: at a target, below this it is stopped."""
ROVER_MIN_SPEED_M_S: Final = 0.05
"""AR_WPNav's lowest waypoint speed (SITL with WP_SPEED 0 crawled at 0.04 m/s)."""
ROVER_POS_P_1_S: Final = 0.2
"""ArduRover's AR_PosControl position gain (AR_POSCON_POS_P, 0.2/s): a GUIDED rover is asked
for its shaped target's velocity plus this times its lag behind the shaped position
(square-root limited), so a rover that fell behind closes the last of the gap at this
rate. Measured on SITL (WP_SPEED 3, a 30 m leg begun behind the rover): 2.95 m/s 18 m out,
1.09 m/s 5.5 m out, 0.40 m/s 2.2 m out (tests/conformance/test_guided.py, the tour)."""
ROVER_VEL_P: Final = 1.0
"""AR_PosControl's velocity gain (AR_POSCON_VEL_P): acceleration asked per m/s of velocity
error, on top of the shaped target's own acceleration."""
ROVER_STEER_SPEED_MIN_M_S: Final = 1.0
"""AR_AttitudeControl's AR_ATTCONTROL_STEER_SPEED_MIN: a lateral acceleration is turned
into a turn rate at the desired speed, never below this (no wild rates from rest)."""
ROVER_CORNER_ACCEL_RATIO: Final = 1.0 / math.sqrt(2.0)
"""AP_Math control.cpp's CORNER_ACCELERATION_RATIO: where the shaped velocity's change along
its command dominates, the part across it keeps this share of the acceleration limit
(``limit_accel_corner_xy`` of the SITL build, 2025-07)."""
ROVER_BEHIND_NUDGE: Final = 0.02
"""A FIT, not ArduPilot's code: the share of the acceleration limit a GUIDED rover is turned
with, to its right, when its target lies behind it and nothing asks it to turn either way.
AR_PosControl asks for no lateral acceleration toward a target exactly behind (a vector
straight back has no side); SITL turns round anyway because its estimate is never exactly
straight. With this share the rover turns round as SITL's does in the redirect scenarios
(tests/conformance/test_guided.py)."""
ROVER_START_DELAY_S: Final = 0.84
"""From a new target to the first motion of a rover at rest (SITL: 0.84 s, in every run,
at speedup 1 and 10): its speed controller winding up."""

_TAU = 2.0 * math.pi
_HALF_PI = 0.5 * math.pi
_INF = math.inf

# What a guided/auto command is (VehicleModel.target_reached answers for it).
_CMD_NONE, _CMD_TARGET, _CMD_TAKEOFF, _CMD_LAND = range(4)


class VehicleSetupError(ClarkError):
    """A vehicle cannot be built from this profile or start state."""


class GpsFix(NamedTuple):
    """One GPS fix: position with the receiver's error, as the autopilot reports it.

    Attributes:
        lat_deg: Latitude.
        lon_deg: Longitude.
        alt_m: Altitude above the mission origin (add the origin's altitude for MSL).
    """

    lat_deg: float
    lon_deg: float
    alt_m: float


class ModeBehaviour(Enum):
    """What a flight mode makes the model do."""

    MANUAL = "manual"
    """Fly the RC inputs (the pilot's sticks or an RC override)."""
    GUIDED = "guided"
    """Fly to the last goto target and stop there (loiter around it, fixed wing)."""
    AUTO = "auto"
    """Fly what a mission executor sets: auto_target, auto_takeoff, auto_land."""
    HOLD = "hold"
    """Stay where the mode was entered (loiter around it, fixed wing)."""
    RTL = "rtl"
    """Return home: a copter lands there, a plane circles it, a rover stops there."""
    LAND = "land"
    """Descend where the mode was entered until touchdown (multirotor)."""
    TAKEOFF = "takeoff"
    """ArduPlane's TAKEOFF: launch, climb to TKOFF_ALT, loiter TKOFF_DIST ahead."""


class ChannelLike(Protocol):
    """What a channel from the profile needs (``runtime.config.ChannelSpec`` fits)."""

    @property
    def rc(self) -> int | None:
        """RC input number, 1-based."""

    @property
    def servo(self) -> int | None:
        """Servo output number, 1-based."""

    @property
    def pwm_min_us(self) -> int:
        """Lowest pulse width."""

    @property
    def pwm_trim_us(self) -> int:
        """Pulse width at rest (zero deflection)."""

    @property
    def pwm_max_us(self) -> int:
        """Highest pulse width."""


@dataclass(frozen=True, slots=True)
class AirframeLimits:
    """The airframe profile's performance limits the models obey.

    Attributes:
        airframe_class: ``multirotor``, ``fixed_wing`` or ``rover``.
        cruise_speed_m_s: The speed a pilot cruises at (an aircraft that starts in
            the air flies it); the automatic modes fly ArduPilot's parameters
            (WPNAV_SPEED, AIRSPEED_CRUISE, WP_SPEED) instead.
        max_speed_m_s: Never exceeded (horizontal speed; airspeed, fixed wing).
        min_speed_m_s: Never undershot while flying (fixed wing stall margin).
        max_climb_rate_m_s: Never exceeded upward.
        max_descent_rate_m_s: Never exceeded downward by a fixed wing. A
            multirotor descends as its autopilot's parameters say (WPNAV_SPEED_DN,
            LAND_SPEED, PILOT_SPEED_DN) or, motors at idle, falls: ArduCopter does
            not know this number.
        max_turn_rate_deg_s: Never exceeded yaw rate in a steady turn (a plane's pull in a
            bank adds its load factor's turn on top, within ``PLANE_PULL_MAX_G``).
        max_bank_deg: Largest roll angle (fixed wing; the lean angle of a multirotor
            when given, else ArduCopter's ANGLE_MAX of 30 degrees).
        max_altitude_m: Highest altitude above the origin (0 for rovers).
    """

    airframe_class: str
    cruise_speed_m_s: float
    max_speed_m_s: float
    min_speed_m_s: float
    max_climb_rate_m_s: float
    max_descent_rate_m_s: float
    max_turn_rate_deg_s: float
    max_bank_deg: float | None
    max_altitude_m: float

    @classmethod
    def from_profile(cls, airframe: Mapping[str, Any]) -> AirframeLimits:
        """Read the limits from a resolved airframe profile.

        Raises:
            VehicleSetupError: A limit the models need is missing or not a number.
        """
        required = (
            "cruise_speed_m_s",
            "max_speed_m_s",
            "min_speed_m_s",
            "max_climb_rate_m_s",
            "max_descent_rate_m_s",
            "max_turn_rate_deg_s",
            "max_altitude_m",
        )
        values: dict[str, float] = {}
        for key in required:
            value = airframe.get(key)
            if isinstance(value, bool) or not isinstance(value, int | float):
                raise VehicleSetupError(
                    f"the airframe profile has no number for {key}; the simulator needs it "
                    "to limit the vehicle"
                )
            values[key] = float(value)
        bank = airframe.get("max_bank_deg")
        if values["max_speed_m_s"] <= 0.0:
            raise VehicleSetupError("the airframe profile's max_speed_m_s must be above 0")
        return cls(
            airframe_class=str(airframe.get("class")),
            cruise_speed_m_s=values["cruise_speed_m_s"],
            max_speed_m_s=values["max_speed_m_s"],
            min_speed_m_s=values["min_speed_m_s"],
            max_climb_rate_m_s=values["max_climb_rate_m_s"],
            max_descent_rate_m_s=values["max_descent_rate_m_s"],
            max_turn_rate_deg_s=values["max_turn_rate_deg_s"],
            max_bank_deg=float(bank) if isinstance(bank, int | float) else None,
            max_altitude_m=values["max_altitude_m"],
        )


@dataclass(frozen=True, slots=True)
class _Channel:
    """A control channel's pulse-width range, normalised for the physics."""

    name: str
    rc: int | None
    servo: int | None
    min_us: int
    trim_us: int
    max_us: int

    def deflection(self, pwm_us: int) -> float:
        """-1 (min) .. 0 (trim) .. +1 (max): a control surface or stick."""
        if pwm_us >= self.trim_us:
            span = self.max_us - self.trim_us
            value = (pwm_us - self.trim_us) / span if span > 0 else 0.0
        else:
            span = self.trim_us - self.min_us
            value = (pwm_us - self.trim_us) / span if span > 0 else 0.0
        return -1.0 if value < -1.0 else (1.0 if value > 1.0 else value)

    def deflection_dz(self, pwm_us: int, dead_zone_us: int) -> float:
        """:meth:`deflection` with a dead zone round trim (ArduPilot's norm_input_dz).

        ``dead_zone_us`` either side of trim reads 0, and the rest of each half of the
        range is scaled from the dead zone's edge: RC_Channel::norm_input_dz, with which
        ArduPlane reads the sticks it mixes into its automatic modes (RCn_DZ, 30 us by
        default): 150 us above a 1500 us trim on a 1100-1900 us channel reads 0.324, not
        0.375.
        """
        if dead_zone_us <= 0:
            return self.deflection(pwm_us)
        low, high = self.trim_us - dead_zone_us, self.trim_us + dead_zone_us
        if pwm_us < low and low > self.min_us:
            value = (pwm_us - low) / (low - self.min_us)
        elif pwm_us > high and self.max_us > high:
            value = (pwm_us - high) / (self.max_us - high)
        else:
            return 0.0
        return -1.0 if value < -1.0 else (1.0 if value > 1.0 else value)

    def fraction(self, pwm_us: int) -> float:
        """0 (min) .. 1 (max): a throttle that idles at its minimum."""
        span = self.max_us - self.min_us
        value = (pwm_us - self.min_us) / span if span > 0 else 0.0
        return 0.0 if value < 0.0 else (1.0 if value > 1.0 else value)

    def pwm_from_deflection(self, value: float) -> int:
        """Inverse of :meth:`deflection`."""
        if value >= 0.0:
            return round(self.trim_us + value * (self.max_us - self.trim_us))
        return round(self.trim_us + value * (self.trim_us - self.min_us))

    def pwm_from_fraction(self, value: float) -> int:
        """Inverse of :meth:`fraction`."""
        return round(self.min_us + value * (self.max_us - self.min_us))


def _channel(name: str, spec: ChannelLike | Mapping[str, Any]) -> _Channel:
    if isinstance(spec, Mapping):
        rc, servo = spec.get("rc"), spec.get("servo")
        low, trim, high = spec["pwm_min_us"], spec["pwm_trim_us"], spec["pwm_max_us"]
    else:
        rc, servo = spec.rc, spec.servo
        low, trim, high = spec.pwm_min_us, spec.pwm_trim_us, spec.pwm_max_us
    return _Channel(
        name,
        int(rc) if rc is not None else None,
        int(servo) if servo is not None else None,
        int(low),
        int(trim),
        int(high),
    )


def _stick_mix(value: float) -> float:
    """ArduPlane's FBW stick mixing curve: linear to half stick, then 3x - 1 (to 2 at full).

    Plane::stabilize_stick_mixing_fbw, so that a pilot can turn an automatic mode's
    aircraft any way they want; the demand is clamped to the limit afterwards.
    """
    if value > 0.5:
        return 3.0 * value - 1.0
    if value < -0.5:
        return 3.0 * value + 1.0
    return value


def _clamp(value: float, low: float, high: float) -> float:
    return low if value < low else (high if value > high else value)


def _wrap_pi(angle_rad: float) -> float:
    """An angle in [-pi, pi)."""
    return (angle_rad + math.pi) % _TAU - math.pi


def sqrt_controller(error: float, p_gain: float, accel_max: float, dt_s: float) -> float:
    """ArduPilot's square-root controller: the speed that brakes to a stop at ``error``.

    Linear (``p_gain * error``) near the target, ``sqrt(2 * accel_max * distance)``
    farther out, so that decelerating at ``accel_max`` arrives with zero speed; and
    never more than covers the error in one step, so a discrete step cannot overshoot.
    """
    linear_m = accel_max / (p_gain * p_gain)
    if error > linear_m:
        speed = math.sqrt(2.0 * accel_max * (error - 0.5 * linear_m))
    elif error < -linear_m:
        speed = -math.sqrt(2.0 * accel_max * (-error - 0.5 * linear_m))
    else:
        speed = p_gain * error
    limit = abs(error) / dt_s
    return _clamp(speed, -limit, limit)


def _limit_length(x: float, y: float, limit: float) -> tuple[float, float]:
    """The vector (x, y) shortened to ``limit`` if longer (ArduPilot's Vector2f::limit_length)."""
    length = math.hypot(x, y)
    if length > limit:
        scale = limit / length
        return x * scale, y * scale
    return x, y


def _sqrt_controller_xy(
    x: float, y: float, p_gain: float, accel_max: float, dt_s: float
) -> tuple[float, float]:
    """:func:`sqrt_controller` of a 2-D error, along the error (control.cpp's vector form)."""
    length = math.hypot(x, y)
    if length <= 0.0:
        return 0.0, 0.0
    scale = sqrt_controller(length, p_gain, accel_max, dt_s) / length
    return x * scale, y * scale


def limit_accel_corner_xy(
    vn: float, ve: float, an: float, ae: float, accel_max: float
) -> tuple[float, float]:
    """An acceleration limited to ``accel_max``, keeping a share for the turn.

    AP_Math control.cpp's ``limit_accel_corner_xy`` as the SITL build (ArduPilot master of
    2025-07) has it, about the velocity (vn, ve) the target is asked for: where the part
    across that velocity is at least the part along it, the vector is simply shortened;
    where the part along dominates, the part across keeps
    :data:`ROVER_CORNER_ACCEL_RATIO` of the limit and the part along has what is left.
    (Later ArduPilot splits about the current velocity and gives braking priority: SITL's
    logged shaped target follows this one, to 0.2 m over 5 s after a redirect.)
    """
    speed = math.hypot(vn, ve)
    if speed <= 0.0:
        return _limit_length(an, ae, accel_max)
    un, ue = vn / speed, ve / speed
    along = an * un + ae * ue
    cn, ce = an - un * along, ae - ue * along
    if along * along <= cn * cn + ce * ce:
        return _limit_length(an, ae, accel_max)
    cn, ce = _limit_length(cn, ce, ROVER_CORNER_ACCEL_RATIO * accel_max)
    along_max = math.sqrt(max(accel_max * accel_max - (cn * cn + ce * ce), 0.0))
    along = _clamp(along, -along_max, along_max)
    return cn + un * along, ce + ue * along


def shape_pos_vel_accel_xy(
    error_n_m: float,
    error_e_m: float,
    vn: float,
    ve: float,
    an: float,
    ae: float,
    speed_max: float,
    accel_max: float,
    jerk_max: float,
    dt_s: float,
) -> tuple[float, float]:
    """The next acceleration of a shaped target ``error`` short of a destination at rest.

    AP_Math control.cpp's ``shape_pos_vel_accel_xy`` with ``shape_vel_accel_xy`` as the
    SITL build has them: a velocity toward the destination from a square-root law (gain
    ``0.5 jerk/accel``, braking at half ``accel_max``), capped at ``speed_max``; the
    acceleration toward that velocity from a square-root law on the velocity error (gain
    ``jerk/accel``, limited at ``jerk_max``), held by :func:`limit_accel_corner_xy` about
    the velocity asked, and approached at ``jerk_max``. One 2-D limit for the velocity
    vector: turning 3 m/s through 90 degrees is a 4.2 m/s change, seconds at 1 m/s^2, the
    target slowing on the way. Checked against SITL's own log (PSCN/PSCE): from the same
    state, this target stays within 0.1 m of SITL's over a 40 m leg from rest and within
    0.2-0.3 m over 5 s after a redirect.

    Args:
        error_n_m: Destination minus the shaped position, north.
        error_e_m: The same, east.
        vn: The shaped velocity, north (m/s).
        ve: The same, east.
        an: The shaped acceleration, north (m/s^2).
        ae: The same, east.
        speed_max: The leg speed (m/s).
        accel_max: The acceleration limit (m/s^2).
        jerk_max: The jerk limit (m/s^3).
        dt_s: The step.

    Returns:
        The shaped acceleration (north, east) for the next step.
    """
    tn, te = _sqrt_controller_xy(
        error_n_m, error_e_m, 0.5 * jerk_max / accel_max, 0.5 * accel_max, dt_s
    )
    tn, te = _limit_length(tn, te, speed_max)
    wn, we = _sqrt_controller_xy(tn - vn, te - ve, jerk_max / accel_max, jerk_max, dt_s)
    wn, we = limit_accel_corner_xy(tn, te, wn, we, accel_max)
    dn, de = _limit_length(wn - an, we - ae, jerk_max * dt_s)
    return an + dn, ae + de


class SimulatedVehicle(VehicleModel):
    """What every model shares: modes, arming, parameters, RC, servos, GPS, truth.

    Subclasses supply the physics (``_advance``), what entering a mode sets up
    (``_enter``) and how a target or a speed change is taken (``_set_target``,
    ``_set_speed``). Construct them through :func:`make_vehicle`.

    Attributes:
        modes: Mode name -> ArduPilot custom_mode number, from the autopilot profile.
        mode: The current mode's name.
        armed: True when the motors are armed.
        limits: The airframe's limits.
        origin: The mission origin (latitude, longitude, altitude of 0 m up).
        start_m: The start point (north, east, up).
        home_m: Home (north, east, up): where RTL returns and what heights ArduPilot
            measures above home are measured from. The start point on the ground
            until :meth:`set_home` moves it.
        time_s: Simulated time since the vehicle was built.
        touchdown_s: Time of the last touchdown; None while flying or never flown.
        touchdown_speed_m_s: Descent rate at the last touchdown (SITL's "SIM Hit
            ground at ... m/s"); None before one.
        unsimulated_modes: Modes of the profile flown as the hold mode (see module doc).
        roll_time_constant_s: First-order lag of roll behind its command.
        pitch_time_constant_s: First-order lag of pitch behind its command.
    """

    airframe_class: ClassVar[str] = ""
    #: ArduPilot's parameter defaults for this firmware (what ``configure`` overrides).
    PARAM_DEFAULTS: ClassVar[Mapping[str, float]] = {}
    _MANUAL_MODES: ClassVar[frozenset[str]] = frozenset()
    _HOLD_MODES: ClassVar[frozenset[str]] = frozenset()
    _RTL_MODES: ClassVar[frozenset[str]] = frozenset()
    _LAND_MODES: ClassVar[frozenset[str]] = frozenset()
    _TAKEOFF_MODES: ClassVar[frozenset[str]] = frozenset()
    _AUTO_MODES: ClassVar[frozenset[str]] = frozenset({"AUTO"})
    _REFUSED_MODES: ClassVar[frozenset[str]] = frozenset()
    #: Channel names read as (roll, pitch, yaw, throttle) inputs.
    _CONTROL_NAMES: ClassVar[tuple[str, str, str, str]] = ("", "", "", "")
    #: True when the throttle is centred (rover: trim is stopped, below is reverse).
    _THROTTLE_CENTRED: ClassVar[bool] = False

    roll_time_constant_s: float = 0.2
    pitch_time_constant_s: float = 0.2

    def __init__(
        self,
        *,
        limits: AirframeLimits,
        autopilot: Mapping[str, Any],
        channels: Mapping[str, ChannelLike | Mapping[str, Any]],
        origin: Origin,
        start_m: tuple[float, float, float],
        rng: random.Random,
        gps_noise_m: float,
        gps_vertical_noise_m: float,
        gps_rate_hz: float,
        heading_deg: float,
        armed: bool,
        mode: str | None,
        rc_override_timeout_s: float | None,
    ) -> None:
        if gps_rate_hz <= 0.0:
            raise VehicleSetupError(f"GPS rate must be above 0 Hz, not {gps_rate_hz:g}")
        if gps_noise_m < 0.0 or gps_vertical_noise_m < 0.0:
            raise VehicleSetupError("GPS noise must not be negative")
        self.limits = limits
        self.origin = origin
        self.modes: Mapping[str, int] = {str(k): int(v) for k, v in autopilot["modes"].items()}
        self._behaviours, self.unsimulated_modes = self._classify(autopilot)
        self._rng = rng
        self._gps_noise_m = gps_noise_m
        self._gps_vertical_noise_m = gps_vertical_noise_m
        self._gps_period_s = 1.0 / gps_rate_hz
        self._rc_override_timeout_s = rc_override_timeout_s
        self._m_per_deg_lat = math.radians(1.0) * EARTH_RADIUS_M
        self._m_per_deg_lon = self._m_per_deg_lat * math.cos(math.radians(origin.lat_deg))
        self._max_turn_rad_s = math.radians(limits.max_turn_rate_deg_s)
        self.time_s = 0.0
        self._now_s = 0.0  # start of the sub-step being integrated
        self.touchdown_s: float | None = None
        self.touchdown_speed_m_s: float | None = None
        self._params: dict[str, float] = dict(self.PARAM_DEFAULTS)
        self._configured = False
        self._command = _CMD_NONE
        # The air mass (sim.wind): None in still air, which every model flies unchanged.
        self._wind: WindField | None = None
        self._air_n = self._air_e = 0.0  # its velocity now, m/s (where it blows to)

        # State (subclasses add their own).
        up = start_m[2] if self.airframe_class != "rover" else 0.0
        self.start_m = (float(start_m[0]), float(start_m[1]), float(up))
        self.home_m = (self.start_m[0], self.start_m[1], 0.0)
        self._n, self._e, self._u = self.start_m
        self._vn = self._ve = self._vu = 0.0
        self._roll = self._pitch = 0.0
        self._yaw = _wrap_pi(math.radians(heading_deg))
        self._armed_yaw = self._yaw
        self._thr = 0.0
        # Normalised actuator demands, for the servo outputs: roll/pitch/yaw in
        # [-1, 1]; throttle in [0, 1] ([-1, 1] when centred).
        self._act_roll = self._act_pitch = self._act_yaw = self._act_thr = 0.0

        # RC inputs.
        self._channels = {name: _channel(name, spec) for name, spec in channels.items()}
        self._controls = tuple(self._channels.get(name) for name in self._CONTROL_NAMES)
        self._pilot_us = [UNMAPPED_RC_US] * RC_CHANNEL_COUNT
        for channel in self._channels.values():
            if channel.rc is not None and 1 <= channel.rc <= RC_CHANNEL_COUNT:
                self._pilot_us[channel.rc - 1] = channel.trim_us
        throttle = self._controls[3]
        if throttle is not None and throttle.rc is not None and not self._THROTTLE_CENTRED:
            self._pilot_us[throttle.rc - 1] = throttle.min_us
        self._override_us = [0] * RC_CHANNEL_COUNT
        self._override_until_s = [math.inf] * RC_CHANNEL_COUNT
        self._override_expiry_s = math.inf
        # rc_inputs' last answer, good until an override lapses or the inputs are set.
        self._rc_inputs: tuple[int, ...] | None = None
        self._rc_inputs_until_s = math.inf
        self._rc_stale = True
        self._rc_roll = self._rc_pitch = self._rc_yaw = self._rc_thr = 0.0
        # The roll, pitch and yaw sticks read through their dead zones (RCn_DZ, in us), as
        # ArduPlane reads the sticks it mixes into its automatic modes; 0 reads them
        # plainly (the models that do not mix sticks).
        self._dead_zones_us = (0, 0, 0)
        self._mix_roll = self._mix_pitch = self._mix_yaw = 0.0

        # Servo outputs: output index -> the demand that drives it.
        self._servo_us = [0] * SERVO_OUTPUT_COUNT
        self._servo_functions = self._servo_function_table()

        # Time-step-dependent constants, recomputed when the step changes.
        self._h_s = 0.0
        self._roll_alpha = self._pitch_alpha = 0.0

        self.armed = armed
        start_mode = mode if mode is not None else self._default_mode(autopilot)
        if start_mode not in self._behaviours:
            raise VehicleSetupError(
                f"cannot start in mode {start_mode!r}: "
                + (
                    "the autopilot profile has no such mode"
                    if start_mode not in self.modes
                    else "the autopilot refuses it on this airframe"
                )
            )
        self.mode = start_mode
        self._behaviour = self._behaviours[start_mode]
        self._setup()
        if self.airborne and not armed:
            raise VehicleSetupError(
                "a vehicle that starts in the air must start armed; start it on the ground "
                "(up_m 0) or armed"
            )
        self._enter(self._behaviour)

        # GPS: the receiver's fixes, and the estimate's smoothed share of their white
        # noise (two first-order lags per axis, stepped at every fix).
        self._ekf_keep = math.exp(-self._gps_period_s / EKF_NOISE_TIME_CONSTANT_S)
        self._ekf_lag1 = (0.0, 0.0)
        self._ekf_noise = (0.0, 0.0)
        self._estimate = GpsFix(0.0, 0.0, 0.0)
        self._fix = GpsFix(0.0, 0.0, 0.0)
        self._fix_time_s = 0.0
        self._next_fix_s = 0.0
        self._take_fix()

    # --- construction helpers -------------------------------------------------------------

    def _classify(
        self, autopilot: Mapping[str, Any]
    ) -> tuple[dict[str, ModeBehaviour], frozenset[str]]:
        roles = {
            autopilot.get("guided_mode"): ModeBehaviour.GUIDED,
            autopilot.get("hold_mode"): ModeBehaviour.HOLD,
            autopilot.get("rtl_mode"): ModeBehaviour.RTL,
            autopilot.get("land_mode"): ModeBehaviour.LAND,
            autopilot.get("manual_mode"): ModeBehaviour.MANUAL,
        }
        behaviours: dict[str, ModeBehaviour] = {}
        unsimulated: set[str] = set()
        for name in self.modes:
            if name in roles and not (
                roles[name] is ModeBehaviour.LAND and self.airframe_class != "multirotor"
            ):
                behaviours[name] = roles[name]
            elif name in self._REFUSED_MODES:
                continue
            elif name in self._MANUAL_MODES:
                behaviours[name] = ModeBehaviour.MANUAL
            elif name in self._HOLD_MODES:
                behaviours[name] = ModeBehaviour.HOLD
            elif name in self._RTL_MODES:
                behaviours[name] = ModeBehaviour.RTL
            elif name in self._LAND_MODES:
                behaviours[name] = ModeBehaviour.LAND
            elif name in self._TAKEOFF_MODES:
                behaviours[name] = ModeBehaviour.TAKEOFF
            elif name in self._AUTO_MODES:
                behaviours[name] = ModeBehaviour.AUTO
            elif name == "GUIDED":
                behaviours[name] = ModeBehaviour.GUIDED
            else:
                behaviours[name] = ModeBehaviour.HOLD
                unsimulated.add(name)
        return behaviours, frozenset(unsimulated)

    def _default_mode(self, autopilot: Mapping[str, Any]) -> str:
        """The mission schema's default start mode: hold for aircraft."""
        return str(autopilot.get("hold_mode") or "")

    def _servo_function_table(self) -> list[str | None]:
        table: list[str | None] = [None] * SERVO_OUTPUT_COUNT
        for role, channel in zip(("roll", "pitch", "yaw", "throttle"), self._controls, strict=True):
            servo = channel.servo if channel is not None else None
            if servo is not None and 1 <= servo <= SERVO_OUTPUT_COUNT:
                table[servo - 1] = role
        return table

    def _setup(self) -> None:
        """Subclass state that depends on the start point (called before ``_enter``)."""

    # --- the VehicleModel contract ----------------------------------------------------

    def step(self, dt_s: float) -> None:
        """Advance the physics by ``dt_s`` seconds.

        Steps longer than :data:`MAX_SUBSTEP_S` are split into equal sub-steps, so a
        coarse simulator step costs more but is as accurate as a fine one.

        Raises:
            ValueError: ``dt_s`` is negative.
        """
        if dt_s <= 0.0:
            if dt_s == 0.0:
                return
            raise ValueError(f"cannot step back in time ({dt_s} s)")
        if dt_s > MAX_SUBSTEP_S:
            count = math.ceil(dt_s / MAX_SUBSTEP_S)
            h = dt_s / count
        else:
            count, h = 1, dt_s
        if h != self._h_s:
            self._set_step(h)
        if self._rc_stale or self.time_s >= self._override_expiry_s:
            self._refresh_rc()
        advance = self._advance
        now = self.time_s
        wind = self._wind
        for _ in range(count):
            self._now_s = now
            if wind is not None:
                self._air_n, self._air_e = wind.air_velocity(
                    now, self._u - self.home_m[2], self.airborne
                )
            advance(h)
            now += h
        self.time_s += dt_s
        self._now_s = self.time_s
        if self.time_s >= self._next_fix_s:
            self._take_fix()

    def set_wind(self, wind: WindField | None) -> None:
        """Fly in this air mass from now on (None: still air, the default).

        The wind enters each model where the air's velocity enters its dynamics (see
        each class); a rover ignores it, as ArduPilot SITL's rover does.
        """
        self._wind = wind
        if wind is None:
            self._air_n = self._air_e = 0.0
        else:
            self._air_n, self._air_e = wind.air_velocity(
                self.time_s, self._u - self.home_m[2], self.airborne
            )
        self._wind_changed()

    def _wind_changed(self) -> None:
        """A new air mass was set (a model that estimates the wind starts from it)."""

    def truth(self) -> Truth:
        """The true state now (lat/lon by the engine's equirectangular projection)."""
        yaw_deg = math.degrees(self._yaw)
        ground_speed = math.hypot(self._vn, self._ve)
        return Truth(
            north_m=self._n,
            east_m=self._e,
            up_m=self._u,
            lat_deg=self.origin.lat_deg + self._n / self._m_per_deg_lat,
            lon_deg=self.origin.lon_deg + self._e / self._m_per_deg_lon,
            velocity_north_m_s=self._vn,
            velocity_east_m_s=self._ve,
            climb_rate_m_s=self._vu,
            roll_deg=math.degrees(self._roll),
            pitch_deg=math.degrees(self._pitch),
            yaw_deg=yaw_deg if yaw_deg > -180.0 else yaw_deg + 360.0,
            ground_speed_m_s=ground_speed,
            heading_deg=yaw_deg % 360.0,
            airspeed_m_s=self._airspeed(ground_speed),
            throttle_pct=100.0 * self._thr,
        )

    def set_mode(self, mode: str) -> bool:
        """Switch flight mode; False when the profile has no such mode or it is refused.

        Setting the current mode again changes nothing (as in ArduPilot): a guided
        target is kept, a hold point is not moved. Entering a mode takes the latest
        parameters and resets the leg speed to their default.
        """
        behaviour = self._behaviours.get(mode)
        if behaviour is None:
            return False
        if mode == self.mode:
            return True
        self.mode = mode
        self._behaviour = behaviour
        self._enter(behaviour)
        return True

    def arm(self, armed: bool, force: bool = False) -> bool:
        """Arm, or disarm (refused in the air unless ``force``: then the motors stop there)."""
        if armed:
            if not self.armed:
                self._armed_yaw = self._yaw
            self.armed = True
            return True
        if self.airborne and not force:
            return False
        self.armed = False
        self._disarmed()
        return True

    def configure(self, params: Mapping[str, float]) -> None:
        """Take the autopilot's parameter table (ArduPilot's names and units).

        Only the names in :attr:`PARAM_DEFAULTS` are read; a missing or non-finite
        value keeps ArduPilot's default. The values apply at the next mode entry or
        target; the first call applies to the current mode at once (it is the
        autopilot's table at power-on).
        """
        merged = dict(self.PARAM_DEFAULTS)
        for name, value in params.items():
            if name in merged:
                number = float(value)
                if math.isfinite(number):
                    merged[name] = number
        self._params = merged
        if not self._configured:
            self._configured = True
            self._apply_params_now()

    @property
    def params(self) -> Mapping[str, float]:
        """The parameter values the model holds (ArduPilot's names and units)."""
        return self._params

    def goto(self, lat_deg: float, lon_deg: float, alt_m: float, speed_m_s: float | None) -> bool:
        """Set the guided target; refused (False) outside the guided mode, as ArduPilot does.

        Args:
            lat_deg: Target latitude.
            lon_deg: Target longitude.
            alt_m: Target altitude above the origin; clamped to the airframe's
                ``max_altitude_m``; ignored by rovers.
            speed_m_s: Requested speed (as DO_CHANGE_SPEED: kept for later targets in
                this mode); None, zero or negative keeps the current leg speed.
        """
        if self._behaviour is not ModeBehaviour.GUIDED:
            return False
        return self._take_target(
            (lat_deg - self.origin.lat_deg) * self._m_per_deg_lat,
            (lon_deg - self.origin.lon_deg) * self._m_per_deg_lon,
            alt_m,
            speed_m_s,
        )

    def auto_target(
        self, north_m: float, east_m: float, alt_m: float, speed_m_s: float | None
    ) -> bool:
        """Set the target AUTO flies (a mission executor's waypoint); False outside AUTO.

        Flown as a guided target is; ``alt_m`` is above the origin, ``speed_m_s`` None
        keeps the current leg speed.
        """
        if self._behaviour is not ModeBehaviour.AUTO:
            return False
        return self._take_target(north_m, east_m, alt_m, speed_m_s)

    def _take_target(
        self, north_m: float, east_m: float, alt_m: float, speed_m_s: float | None
    ) -> bool:
        if not (math.isfinite(north_m) and math.isfinite(east_m) and math.isfinite(alt_m)):
            return False
        if speed_m_s is not None and not math.isfinite(speed_m_s):
            return False
        speed = speed_m_s if speed_m_s is not None and speed_m_s > 0.0 else None
        self._set_target(north_m, east_m, min(alt_m, self.limits.max_altitude_m), speed)
        return True

    def set_speed(self, speed_m_s: float) -> None:
        """DO_CHANGE_SPEED as the autopilot layer accepted it: this mode's leg speed.

        Kept for later targets in the same mode, back to the parameter default on
        entering a mode; clamped to the airframe's limits. Zero, negative or
        non-finite speeds are ignored (ArduPilot refuses them).
        """
        if math.isfinite(speed_m_s) and speed_m_s > 0.0:
            self._set_speed(speed_m_s)

    def set_home(self, north_m: float, east_m: float, up_m: float) -> None:
        """Move home (where RTL returns; heights above home are measured from it)."""
        if math.isfinite(north_m) and math.isfinite(east_m) and math.isfinite(up_m):
            self.home_m = (float(north_m), float(east_m), float(up_m))

    def takeoff(self, alt_m: float, delay_s: float) -> bool:
        """A guided takeoff (MAV_CMD_NAV_TAKEOFF); refused unless the model supports it."""
        return False

    def auto_takeoff(self, alt_m: float) -> bool:
        """A mission's takeoff item in AUTO; refused unless the model supports it."""
        return False

    def auto_land(self) -> None:
        """A mission's land item in AUTO (a rover stops where it is)."""

    def set_rc_override(self, pwm_us: Mapping[int, int]) -> None:
        """Override RC inputs (channel -> pulse width; 0 releases the channel to the pilot).

        An override lapses ``rc_override_timeout_s`` after it was last set unless set
        again (ArduPilot's RC_OVERRIDE_TIME), so a mission computer that dies does not
        hold a control surface deflected.

        Raises:
            ValueError: A channel outside 1..16 or a negative pulse width.
        """
        self._rc_inputs = None
        until = (
            math.inf
            if self._rc_override_timeout_s is None
            else self.time_s + self._rc_override_timeout_s
        )
        for channel, value in pwm_us.items():
            index = self._rc_index(channel)
            if value < 0:
                raise ValueError(f"RC override pulse width {value} us is negative")
            self._override_us[index] = int(value)
            self._override_until_s[index] = until if value else math.inf
        self._rc_stale = True

    def set_servo(self, servo: int, pwm_us: int) -> None:
        """Drive an output with no function; an output with one ignores it (ArduPilot).

        :meth:`servo_function` tells which outputs have a function.

        Raises:
            ValueError: An output outside 1..16 or a negative pulse width.
        """
        if not 1 <= servo <= SERVO_OUTPUT_COUNT:
            raise ValueError(f"servo output {servo} is outside 1..{SERVO_OUTPUT_COUNT}")
        if pwm_us < 0:
            raise ValueError(f"servo pulse width {pwm_us} us is negative")
        if self._servo_functions[servo - 1] is None:
            self._servo_us[servo - 1] = int(pwm_us)

    def rc_inputs(self) -> tuple[int, ...]:
        """RC input pulse widths the autopilot sees (override, else pilot), channel 1 first.

        Asked for at the telemetry rate but changing only when a stick or an override
        moves or an override lapses, so the answer is kept until one of those happens.
        """
        now = self.time_s
        if self._rc_inputs is not None and now < self._rc_inputs_until_s:
            return self._rc_inputs
        self._rc_inputs = tuple(
            over if over and now < until else pilot
            for pilot, over, until in zip(
                self._pilot_us, self._override_us, self._override_until_s, strict=True
            )
        )
        self._rc_inputs_until_s = min(
            (
                until
                for over, until in zip(self._override_us, self._override_until_s, strict=True)
                if over and now < until
            ),
            default=math.inf,
        )
        return self._rc_inputs

    def servo_outputs(self) -> tuple[int, ...]:
        """Servo output pulse widths, output 1 first; 0 for an output never driven."""
        out = list(self._servo_us)
        for index, function in enumerate(self._servo_functions):
            if function is not None:
                out[index] = self._function_pwm(function)
        return tuple(out)

    def set_pilot(self, pwm_us: Mapping[int, int]) -> None:
        """Move the pilot's sticks or switches (channel -> pulse width); others stay.

        Raises:
            ValueError: A channel outside 1..16 or a negative pulse width.
        """
        self._rc_inputs = None
        for channel, value in pwm_us.items():
            index = self._rc_index(channel)
            if value < 0:
                raise ValueError(f"pilot pulse width {value} us is negative")
            self._pilot_us[index] = int(value)
        self._rc_stale = True

    # --- extras -----------------------------------------------------------------------

    @property
    def airborne(self) -> bool:
        """True while physically off the ground (a normal disarm is refused then)."""
        return False

    @property
    def landed_state(self) -> LandedState:
        """On the ground, taking off, in the air or landing."""
        return "on_ground"

    @property
    def target_reached(self) -> bool:
        """The current guided/auto command is complete (False with none)."""
        return False

    @property
    def behaviour(self) -> ModeBehaviour:
        """What the current mode makes the model do."""
        return self._behaviour

    def mode_behaviour(self, mode: str) -> ModeBehaviour | None:
        """What ``mode`` would make the model do; None when it is unknown or refused."""
        return self._behaviours.get(mode)

    def servo_function(self, servo: int) -> str | None:
        """The function driving output ``servo`` (``roll``, ``throttle``, ``motor``...).

        None means the output is free for :meth:`set_servo`; the simulated autopilot
        refuses DO_SET_SERVO on the others, as ArduPilot does.
        """
        if not 1 <= servo <= SERVO_OUTPUT_COUNT:
            return None
        return self._servo_functions[servo - 1]

    def shift_estimate(self, north_m: float, east_m: float) -> None:
        """Move the estimate (the model's position) by a change of the GPS error.

        The model's position is what the autopilot believes; the backend keeps the
        truth apart (:mod:`clark_engine.sim.gps_error`). Targets stay where they are,
        so the vehicle flies the estimate back onto them, and truly moves.
        """
        self._n += north_m
        self._e += east_m

    def set_gps_noise(self, noise_m: float, vertical_noise_m: float) -> None:
        """Give the receiver this white noise from its next fix on (``sim.gps_noise_m``).

        For scenarios that compare a noisy GPS with ArduPilot SITL's (the conformance
        suite); a dry run sets the noise when it builds the vehicle.

        Raises:
            VehicleSetupError: A negative noise.
        """
        if noise_m < 0.0 or vertical_noise_m < 0.0:
            raise VehicleSetupError("GPS noise must not be negative")
        self._gps_noise_m = noise_m
        self._gps_vertical_noise_m = vertical_noise_m

    def gps_fix(self) -> GpsFix:
        """The latest GPS fix: the true position at the fix time plus Gaussian error.

        Fixes are taken at the GPS rate (every ``1 / gps_rate_hz`` s of simulated time,
        the first at time 0) and held in between, as a receiver's are. The errors are
        independent between fixes and drawn from the vehicle's seeded generator, so
        the same seed gives the same fixes.
        """
        return self._fix

    def position_estimate(self) -> GpsFix:
        """The position the autopilot reports (GLOBAL_POSITION_INT): its estimate.

        ArduPilot reports its EKF's estimate, not the receiver's fix (GPS_RAW_INT,
        :meth:`gps_fix`): the fixes' white noise reaches it smoothed, about a third of
        it and wandering with a memory of about a second
        (:data:`EKF_NOISE_TIME_CONSTANT_S`). The estimate is the model's position at the
        latest fix plus that smoothed noise; the slow GPS error and glitches
        (:mod:`clark_engine.sim.gps_error`) are in the model's position and pass whole,
        as an EKF follows them. The altitude is the fix's. With no noise it is the fix.
        """
        return self._estimate

    @property
    def gps_fix_time_s(self) -> float:
        """Simulated time of the latest GPS fix."""
        return self._fix_time_s

    # --- internals --------------------------------------------------------------------

    def _rc_index(self, channel: int) -> int:
        if not 1 <= channel <= RC_CHANNEL_COUNT:
            raise ValueError(f"RC channel {channel} is outside 1..{RC_CHANNEL_COUNT}")
        return channel - 1

    def _refresh_rc(self) -> None:
        """Re-read the control channels (after a change, or when an override lapses)."""
        self._rc_inputs = None
        now = self.time_s
        expiry = math.inf
        for index, until in enumerate(self._override_until_s):
            if self._override_us[index]:
                if now >= until:
                    self._override_us[index] = 0
                    self._override_until_s[index] = math.inf
                elif until < expiry:
                    expiry = until
        self._override_expiry_s = expiry
        values = []
        for position, channel in enumerate(self._controls):
            if channel is None or channel.rc is None or not 1 <= channel.rc <= RC_CHANNEL_COUNT:
                values.append(0.0)
                continue
            index = channel.rc - 1
            pwm = self._override_us[index] or self._pilot_us[index]
            if position == 3 and not self._THROTTLE_CENTRED:
                values.append(channel.fraction(pwm))
            else:
                values.append(channel.deflection(pwm))
        self._rc_roll, self._rc_pitch, self._rc_yaw, self._rc_thr = values
        mixed = [values[0], values[1], values[2]]
        for position, dead_zone in enumerate(self._dead_zones_us):
            channel = self._controls[position]
            rc = channel.rc if channel is not None else None
            if dead_zone and channel is not None and rc is not None and 1 <= rc <= RC_CHANNEL_COUNT:
                pwm = self._override_us[rc - 1] or self._pilot_us[rc - 1]
                mixed[position] = channel.deflection_dz(pwm, dead_zone)
        self._mix_roll, self._mix_pitch, self._mix_yaw = mixed
        self._rc_stale = False

    def _function_pwm(self, function: str) -> int:
        index = ("roll", "pitch", "yaw", "throttle").index(function)
        channel = self._controls[index]
        assert channel is not None  # the table names only mapped controls
        if function == "throttle":
            if not self._THROTTLE_CENTRED:
                return channel.pwm_from_fraction(self._act_thr if self.armed else 0.0)
            return channel.pwm_from_deflection(self._act_thr if self.armed else 0.0)
        demand = (self._act_roll, self._act_pitch, self._act_yaw)[index]
        return channel.pwm_from_deflection(demand)

    def _set_step(self, h: float) -> None:
        self._h_s = h
        self._roll_alpha = 1.0 - math.exp(-h / self.roll_time_constant_s)
        self._pitch_alpha = 1.0 - math.exp(-h / self.pitch_time_constant_s)

    def _take_fix(self) -> None:
        """Draw the fix due now and schedule the next one on the fixed GPS grid."""
        gauss = self._rng.gauss
        sigma, sigma_up = self._gps_noise_m, self._gps_vertical_noise_m
        noise_n = gauss(0.0, sigma) if sigma else 0.0
        noise_e = gauss(0.0, sigma) if sigma else 0.0
        up = self._u + (gauss(0.0, sigma_up) if sigma_up else 0.0)
        lat0, lon0 = self.origin.lat_deg, self.origin.lon_deg
        self._fix = GpsFix(
            lat0 + (self._n + noise_n) / self._m_per_deg_lat,
            lon0 + (self._e + noise_e) / self._m_per_deg_lon,
            up,
        )
        lag1, lag2 = self._ekf_lag1, self._ekf_noise
        if sigma or lag1 != (0.0, 0.0) or lag2 != (0.0, 0.0):
            # The estimate's share of the noise: no draws of its own, so a run without
            # noise reports exactly the fixes, as before.
            keep = self._ekf_keep
            take = 1.0 - keep
            lag1 = (keep * lag1[0] + take * noise_n, keep * lag1[1] + take * noise_e)
            lag2 = (keep * lag2[0] + take * lag1[0], keep * lag2[1] + take * lag1[1])
            self._ekf_lag1, self._ekf_noise = lag1, lag2
            self._estimate = GpsFix(
                lat0 + (self._n + EKF_NOISE_GAIN * lag2[0]) / self._m_per_deg_lat,
                lon0 + (self._e + EKF_NOISE_GAIN * lag2[1]) / self._m_per_deg_lon,
                up,
            )
        else:
            self._estimate = self._fix
        # The fix grid is k * period; the small margin keeps float accumulation of
        # the simulator's steps (0.02 * 10 = 0.19999...) from delaying a fix a step.
        index = math.floor(self.time_s / self._gps_period_s + 1e-6)
        self._fix_time_s = self.time_s
        self._next_fix_s = (index + 1) * self._gps_period_s - 1e-9

    def _stopping_point(self, accel_m_s2: float) -> tuple[float, float]:
        """Where braking at ``accel_m_s2`` from the current velocity ends (ArduPilot's)."""
        speed = math.hypot(self._vn, self._ve)
        reach = speed / (2.0 * accel_m_s2)
        return self._n + self._vn * reach, self._e + self._ve * reach

    def _touched_down(self, sink_m_s: float) -> None:
        """Record a touchdown now (the autopilot layer times its disarm from it)."""
        self.touchdown_s = self._now_s
        self.touchdown_speed_m_s = sink_m_s

    def _airspeed(self, ground_speed_m_s: float) -> float:
        return ground_speed_m_s

    # --- subclass hooks ---------------------------------------------------------------

    def _apply_params_now(self) -> None:
        """Take the parameters into the current mode at once (the first ``configure``)."""

    def _disarmed(self) -> None:
        """The motors were stopped (cancel what needed them)."""

    @abstractmethod
    def _advance(self, h: float) -> None:
        """Integrate one sub-step of ``h`` seconds in the current mode."""

    @abstractmethod
    def _enter(self, behaviour: ModeBehaviour) -> None:
        """Set up a newly entered mode (hold point, guided target, RTL target)."""

    @abstractmethod
    def _set_target(
        self, north_m: float, east_m: float, alt_m: float, speed_m_s: float | None
    ) -> None:
        """Take a new guided/auto target (local frame, altitude clamped to the ceiling)."""

    @abstractmethod
    def _set_speed(self, speed_m_s: float) -> None:
        """Take a new leg speed (positive and finite)."""


# Multirotor sub-states: what the automatic controller does now.
(
    _C_MANUAL,  # fly the sticks (STABILIZE and the pilot's climb-rate modes)
    _C_HOLD,  # hold a point in 3-D (BRAKE, guided without a target, after a takeoff)
    _C_LINE,  # fly a straight 3-D line to the target (guided, auto, takeoff)
    _C_PILOT,  # hold the horizontal point, climb as the throttle stick says (LOITER)
    _C_LAND,  # hold the horizontal point, descend as LAND does
    _C_CIRCLE,  # ArduCopter's CIRCLE, climbing as the stick says
    _C_RTL_CLIMB,  # RTL: up to the return altitude
    _C_RTL_RETURN,  # RTL: home at the return altitude
    _C_RTL_LOITER,  # RTL: RTL_LOIT_TIME above home
    _C_RTL_FINAL,  # RTL: down to RTL_ALT_FINAL, then hold
) = range(10)
#: Sub-states that hold a horizontal point and fly a vertical rate.
_C_RATE_SUBS: Final = frozenset({_C_LAND, _C_PILOT, _C_CIRCLE})


class Multirotor(SimulatedVehicle):
    """A multirotor: hovers, leans to accelerate, climbs and descends as ArduCopter flies.

    Automatic modes follow ArduCopter's position controller in outline. A target
    (guided, auto, a takeoff, RTL's legs) is flown as a straight 3-D line, as
    ArduCopter's waypoint navigation flies it: the speed along the line is the
    square-root braking profile toward the target, capped so that its horizontal
    part stays within the leg speed (WPNAV_SPEED, or DO_CHANGE_SPEED's, which may be
    above WPNAV_SPEED but never above the airframe's ``max_speed_m_s``) and its vertical part
    within WPNAV_SPEED_UP (and the airframe's climb limit) or WPNAV_SPEED_DN; it
    ramps up at :data:`COPTER_RAMP_FRACTION` of WPNAV_ACCEL (and WPNAV_ACCEL_Z) and
    brakes at WPNAV_ACCEL (and :data:`COPTER_Z_BRAKE_FRACTION` of WPNAV_ACCEL_Z). So
    it stops at a target without overshoot, taking as long as SITL does (see the
    constants). Roll and pitch are the lean angles that produce the commanded
    acceleration (plus air drag), through a first-order lag; the nose turns toward
    the target at up to ``max_turn_rate_deg_s`` while more than 2 m away.

    On the ground it stays put unless armed and told to leave it: a guided
    :meth:`takeoff` (climbing after its ``delay_s``, the motors' spool-up), AUTO's
    :meth:`auto_takeoff`, or the pilot's throttle (above hover in STABILIZE and
    ACRO, above the dead band in ALT_HOLD, LOITER and the other climb-rate modes).
    A guided target sent on the ground is stored but does not take off (measured);
    a later takeoff climbs straight up and hovers there. A target sent during the
    takeoff climb ends the takeoff (landed_state in_air at once) and is flown as a
    straight line from where the copter is. Hold, BRAKE, RTL and LAND never take off.

    LAND (and AUTO's :meth:`auto_land`) holds the point where it started and descends
    at WPNAV_SPEED_DN (LAND_SPEED_HIGH when set) above LAND_ALT_LOW, blending down to
    LAND_SPEED below it on ArduCopter's square-root profile; landed_state is
    ``landing`` from the moment it starts in the air. RTL is ArduCopter's: the return
    altitude is RTL_ALT, at least the current height (plus RTL_CLIMB_MIN), lowered
    near home by the RTL cone (RTL_CONE_SLOPE times the distance); it climbs there
    over the point where it stopped, flies home at WPNAV_SPEED (RTL_SPEED when set),
    hovers RTL_LOIT_TIME (after :data:`COPTER_RTL_SETTLE_S`) and until its nose is back
    at its heading at arming, then lands as LAND does (landed_state ``landing`` during
    that descent), or with RTL_ALT_FINAL above 0 descends to it and holds. The model
    never disarms: after a touchdown it idles on the ground until the autopilot layer
    disarms it.

    Manual modes fly the sticks: roll and pitch set the lean angle (full stick = the
    max lean), the lean accelerates the vehicle (``g * tan(lean)``) against linear
    drag sized so full lean settles at ``max_speed_m_s``; the yaw stick sets the yaw
    rate. The throttle stick sets the thrust in STABILIZE, ACRO, RATE_ACRO and DRIFT
    (mid stick hovers, full stick :data:`COPTER_MAX_THRUST_RATIO` times the weight,
    the minimum leaves the motors at idle: a free fall with drag toward
    :data:`COPTER_FALL_TERMINAL_M_S`), and a climb rate in ALT_HOLD, SPORT and FLOWHOLD
    (see the module doc). LOITER and POSHOLD hold where they stopped with the sticks
    centred (the model does not fly their roll and pitch sticks) and climb as the
    throttle stick says; CIRCLE flies ArduCopter's circle (CIRCLE_RADIUS around a
    centre that far ahead of the nose, CIRCLE_RATE, the nose on the centre) and climbs
    as the stick says. A copter disarmed in the air (a forced disarm) falls the same way.
    """

    airframe_class = "multirotor"
    PARAM_DEFAULTS = COPTER_DEFAULT_PARAMS
    _MANUAL_MODES = frozenset(
        {"STABILIZE", "ACRO", "RATE_ACRO", "ALT_HOLD", "SPORT", "DRIFT", "FLOWHOLD"}
    )
    _HOLD_MODES = frozenset({"LOITER", "BRAKE", "POSHOLD", "CIRCLE"})
    _RTL_MODES = frozenset({"RTL", "SMART_RTL", "AUTO_RTL"})
    _LAND_MODES = frozenset({"LAND"})
    _CONTROL_NAMES = ("roll", "pitch", "yaw", "throttle")
    #: Modes whose throttle stick is a climb rate (ArduCopter's get_pilot_desired_climb_rate).
    PILOT_CLIMB_MODES: ClassVar[frozenset[str]] = frozenset(
        {
            "ALT_HOLD",
            "SPORT",
            "FLOWHOLD",
            "LOITER",
            "POSHOLD",
            "CIRCLE",
            "ZIGZAG",
            "AUTOTUNE",
            "SYSTEMID",
        }
    )

    #: Lean angle when the profile gives none (ArduCopter ANGLE_MAX).
    default_max_lean_deg: float = 30.0
    #: Throttle that hovers, reported in Truth.throttle_pct.
    hover_throttle: float = 0.5
    #: Motors on outputs 1..4 (a quad, as the profiles' only multirotor is).
    motor_count: int = 4

    def _servo_function_table(self) -> list[str | None]:
        table: list[str | None] = [None] * SERVO_OUTPUT_COUNT
        for index in range(min(self.motor_count, SERVO_OUTPUT_COUNT)):
            table[index] = "motor"
        return table

    def _function_pwm(self, function: str) -> int:
        # MOT_PWM_MIN/MAX defaults 1000/2000; the model does not mix attitude into motors.
        if not self.armed:
            return 1000
        return round(1000 + 1000 * max(self._thr, 0.1 if not self._landed else 0.0))

    def _setup(self) -> None:
        limits = self.limits
        lean_deg = limits.max_bank_deg or self.default_max_lean_deg
        self._max_lean_rad = math.radians(lean_deg)
        self._max_speed = limits.max_speed_m_s
        # Linear drag so that full lean settles at the maximum speed.
        self._drag_1_s = G_M_S2 * math.tan(self._max_lean_rad) / self._max_speed
        # Quadratic vertical drag of a falling copter: g at the terminal speed.
        self._fall_drag_1_m = G_M_S2 / (COPTER_FALL_TERMINAL_M_S * COPTER_FALL_TERMINAL_M_S)
        self._landed = self._u <= 0.0
        self._tn, self._te, self._tu = self._n, self._e, self._u
        self._sub = _C_HOLD
        self._face_target = False
        self._path_speed = 0.0
        self._takeoff_at_s: float | None = None
        self._takeoff_alt = 0.0
        self._taking_off = False
        self._landing = False
        self._speed_set = False
        self._pilot_climb = False
        self._pilot_az = 0.0  # the vertical acceleration the stick's climb rate is shaped with
        self._z_braking = False  # stopping a climb or sink before holding a height
        self._alt_hold = self._u
        self._rtl_alt = self._u
        self._phase_since_s = 0.0
        self._circle_n = self._circle_e = self._circle_angle = 0.0
        self._circle_radius = self._circle_rate = self._circle_rate_max = 0.0
        self._circle_accel = 0.0
        self._wind_est_n = self._wind_est_e = 0.0  # the wind the controller leans into
        self._capture()
        self._leg_speed = self._wp_speed
        if not self._landed:
            self._thr = self.hover_throttle
            # A pilot who is flying holds mid throttle (hover), not the minimum.
            throttle = self._controls[3]
            if throttle is not None and throttle.rc is not None:
                self._pilot_us[throttle.rc - 1] = (throttle.min_us + throttle.max_us) // 2

    def _capture(self) -> None:
        """Read ArduCopter's parameters into SI units (at a mode entry or a target)."""
        p = self._params
        limits = self.limits
        self._wp_speed = _clamp(p["WPNAV_SPEED"] / 100.0, 0.2, limits.max_speed_m_s)
        accel = max(p["WPNAV_ACCEL"] / 100.0, 0.5)
        self._brake_xy = accel
        self._accel_xy = accel * COPTER_RAMP_FRACTION
        self._climb_max = _clamp(p["WPNAV_SPEED_UP"] / 100.0, 0.1, limits.max_climb_rate_m_s)
        self._descent_max = max(abs(p["WPNAV_SPEED_DN"]) / 100.0, 0.1)
        self._accel_z = max(p["WPNAV_ACCEL_Z"] / 100.0, 0.1)
        self._brake_z = self._accel_z * COPTER_Z_BRAKE_FRACTION
        self._reach_m = max(min(p["WPNAV_RADIUS"] / 100.0, COPTER_WP_DONE_M), 0.05)
        self._land_speed = max(abs(p["LAND_SPEED"]) / 100.0, 0.1)
        high = abs(p["LAND_SPEED_HIGH"]) / 100.0 or self._descent_max
        self._land_speed_high = max(high, self._land_speed)  # "don't speed up for landing"
        self._land_alt_low = max(p["LAND_ALT_LOW"] / 100.0, 1.0)
        up = max(p["PILOT_SPEED_UP"] / 100.0, 0.1)
        self._pilot_up = min(up, limits.max_climb_rate_m_s)
        self._pilot_down = abs(p["PILOT_SPEED_DN"]) / 100.0 or up
        self._pilot_accel = max(p["PILOT_ACCEL_Z"] / 100.0, 0.5)
        self._pilot_jerk = _clamp(p["PSC_JERK_Z"], 1.0, 50.0)
        self._thr_dz = _clamp(p["THR_DZ"] / 1000.0, 0.0, 0.3)

    def _default_speed(self) -> float:
        if self._behaviour is ModeBehaviour.RTL and self._params["RTL_SPEED"] > 0.0:
            return _clamp(self._params["RTL_SPEED"] / 100.0, 0.2, self._max_speed)
        return self._wp_speed

    def _apply_params_now(self) -> None:
        self._capture()
        if not self._speed_set:
            self._leg_speed = self._default_speed()

    def _aim(self) -> None:
        """Start a new line: its speed is the velocity's share in the target's direction."""
        dn, de, du = self._tn - self._n, self._te - self._e, self._tu - self._u
        distance = math.sqrt(dn * dn + de * de + du * du)
        along = self._vn * dn + self._ve * de + self._vu * du
        self._path_speed = max(along / distance, 0.0) if distance > 1e-9 else 0.0

    @property
    def airborne(self) -> bool:
        """True unless on the ground."""
        return not self._landed

    @property
    def landed_state(self) -> LandedState:
        """ArduCopter's landed state.

        On the ground (also at once after a forced disarm, while still falling),
        taking off, landing (LAND, RTL's final descent, AUTO's land) or in the air.
        """
        if self._landed or not self.armed:
            return "on_ground"
        if self._taking_off:
            return "taking_off"
        if self._landing:
            return "landing"
        return "in_air"

    @property
    def target_reached(self) -> bool:
        """The target within min(WPNAV_RADIUS, 0.5 m), the takeoff at its altitude, landed."""
        command = self._command
        if command == _CMD_TARGET:
            dn, de, du = self._tn - self._n, self._te - self._e, self._tu - self._u
            return dn * dn + de * de + du * du <= self._reach_m * self._reach_m
        if command == _CMD_TAKEOFF:
            return (
                not self._landed
                and self._takeoff_at_s is None
                and abs(self._u - self._takeoff_alt) <= COPTER_TAKEOFF_DONE_M
            )
        if command == _CMD_LAND:
            return self._landed
        return False

    def takeoff(self, alt_m: float, delay_s: float) -> bool:
        """A guided takeoff to ``alt_m`` above home: climb after ``delay_s``, then hover.

        Refused (False) unless in the guided mode, armed and on the ground (also
        while the climb has started: ArduCopter answers FAILED), or with an altitude
        not above the copter. Sent again before the climb starts, it is accepted
        and the climb starts no later than first planned. The climb is vertical at
        up to WPNAV_SPEED_UP, braking to stop at the altitude without overshoot;
        landed_state is ``taking_off`` from the climb's start until within 0.1 m.
        """
        if self._behaviour is not ModeBehaviour.GUIDED or not self.armed or not self._landed:
            return False
        return self._begin_takeoff(alt_m, delay_s)

    def auto_takeoff(self, alt_m: float, delay_s: float = COPTER_AUTO_TAKEOFF_DELAY_S) -> bool:
        """AUTO's takeoff item (after MISSION_START): climb to ``alt_m`` above home.

        On the ground as :meth:`takeoff` (the climb after ``delay_s``); in the air, a
        climb there if below it. False outside AUTO or disarmed.
        """
        if self._behaviour is not ModeBehaviour.AUTO or not self.armed:
            return False
        if self._landed:
            return self._begin_takeoff(alt_m, delay_s)
        if not math.isfinite(alt_m):
            return False
        self._capture()
        alt = min(max(self.home_m[2] + alt_m, self._u), self.limits.max_altitude_m)
        stop_n, stop_e = self._stopping_point(self._brake_xy)
        self._tn, self._te, self._tu = stop_n, stop_e, alt
        self._takeoff_alt = alt
        self._sub, self._face_target, self._landing = _C_LINE, False, False
        self._command = _CMD_TAKEOFF
        self._aim()
        return True

    def auto_land(self) -> None:
        """AUTO's land item: land where the copter is, as LAND does."""
        if self._behaviour is not ModeBehaviour.AUTO:
            return
        self._command = _CMD_LAND
        self._takeoff_at_s = None
        if self._landed:
            return
        self._capture()
        self._tn, self._te = self._stopping_point(self._brake_xy)
        self._sub, self._face_target = _C_LAND, False
        self._taking_off, self._landing = False, True

    def _begin_takeoff(self, alt_m: float, delay_s: float) -> bool:
        if not (math.isfinite(alt_m) and math.isfinite(delay_s)) or alt_m <= 0.0:
            return False
        alt = min(self.home_m[2] + alt_m, self.limits.max_altitude_m)
        if alt <= self._u + COPTER_TAKEOFF_DONE_M:
            return False
        start = self.time_s + max(delay_s, 0.0)
        if self._takeoff_at_s is not None and self._takeoff_at_s < start:
            start = self._takeoff_at_s
        self._capture()
        self._takeoff_at_s = start
        self._takeoff_alt = alt
        self._tn, self._te, self._tu = self._n, self._e, alt
        self._sub, self._face_target, self._landing = _C_LINE, False, False
        self._command = _CMD_TAKEOFF
        self._path_speed = 0.0
        return True

    def _disarmed(self) -> None:
        self._takeoff_at_s = None
        self._taking_off = False

    def _enter(self, behaviour: ModeBehaviour) -> None:
        self._capture()
        self._speed_set = False
        self._leg_speed = self._default_speed()
        self._takeoff_at_s = None
        self._taking_off = False
        self._landing = False
        self._command = _CMD_NONE
        self._face_target = False
        self._pilot_climb = self.mode in self.PILOT_CLIMB_MODES
        self._pilot_az = 0.0
        self._z_braking = True  # a climb-rate mode first stops where it is going
        self._alt_hold = self._u
        # Automatic modes start by holding where the copter stops, as ArduCopter's do.
        stop_n, stop_e = self._stopping_point(self._brake_xy)
        self._tn, self._te, self._tu = stop_n, stop_e, self._u
        if behaviour is ModeBehaviour.MANUAL:
            self._sub = _C_MANUAL
        elif behaviour is ModeBehaviour.RTL:
            self._start_rtl(stop_n, stop_e)
        elif behaviour is ModeBehaviour.LAND:
            self._sub = _C_LAND
            self._landing = not self._landed
        elif behaviour is ModeBehaviour.HOLD:
            if self.mode == "CIRCLE":
                self._start_circle()
            else:
                self._sub = _C_PILOT if self._pilot_climb else _C_HOLD
        else:
            self._sub = _C_HOLD
            self._face_target = True
        self._aim()

    def _start_rtl(self, origin_n: float, origin_e: float) -> None:
        """ArduCopter's ModeRTL::build_path and compute_return_target."""
        p = self._params
        home_n, home_e, home_u = self.home_m
        current = self._u - home_u
        lowest = max(COPTER_RTL_ALT_MIN_M, current + max(0.0, p["RTL_CLIMB_MIN"] / 100.0))
        target = max(p["RTL_ALT"] / 100.0, lowest)
        if p["RTL_CONE_SLOPE"] >= COPTER_RTL_MIN_CONE_SLOPE:
            distance = math.hypot(origin_n - home_n, origin_e - home_e)
            target = min(target, max(distance * p["RTL_CONE_SLOPE"], lowest))
        target = max(target, current)
        self._rtl_alt = min(home_u + target, self.limits.max_altitude_m)
        self._tn, self._te, self._tu = origin_n, origin_e, self._rtl_alt
        self._sub = _C_RTL_CLIMB

    def _start_circle(self) -> None:
        """ArduCopter's CIRCLE: the centre CIRCLE_RADIUS ahead of the nose."""
        p = self._params
        radius = max(p["CIRCLE_RADIUS"] / 100.0, 0.0)
        rate = math.radians(p["CIRCLE_RATE"])
        yaw = self._yaw
        self._circle_n = self._n + radius * math.cos(yaw)
        self._circle_e = self._e + radius * math.sin(yaw)
        self._circle_radius = radius
        self._circle_angle = yaw + math.pi
        if radius > 0.0:
            # AC_Circle: the rate is limited so the speed stays within WPNAV_SPEED, and
            # it ramps at WPNAV_ACCEL over the radius (at least 2 deg/s^2).
            rate = math.copysign(min(abs(rate), self._wp_speed / radius), rate)
            self._circle_accel = max(self._brake_xy / radius, math.radians(2.0))
        else:
            self._circle_accel = math.radians(90.0)
        self._circle_rate_max = rate
        self._circle_rate = 0.0
        self._tn, self._te = self._n, self._e
        self._sub = _C_CIRCLE

    def _set_target(
        self, north_m: float, east_m: float, alt_m: float, speed_m_s: float | None
    ) -> None:
        self._capture()
        if speed_m_s is not None:
            self._set_speed(speed_m_s)
        elif not self._speed_set:
            self._leg_speed = self._default_speed()
        self._tn, self._te, self._tu = north_m, east_m, max(alt_m, 0.0)
        self._sub, self._face_target, self._landing = _C_LINE, True, False
        self._command = _CMD_TARGET
        self._aim()
        # On the ground (also while spooling up for a takeoff) a target is stored and
        # the copter stays there; in a takeoff climb it ends the takeoff.
        self._takeoff_at_s = None
        self._taking_off = False

    def _set_speed(self, speed_m_s: float) -> None:
        # AC_WPNav::set_speed_xy takes any speed from WPNAV_WP_SPEED_MIN (20 cm/s) up:
        # WPNAV_SPEED is only the default (SITL flew 10.02 m/s asked with WPNAV_SPEED 5).
        # What caps it is the airframe: its lean limit against drag, max_speed_m_s here.
        self._leg_speed = _clamp(speed_m_s, 0.2, self._max_speed)
        self._speed_set = True

    # --- physics ----------------------------------------------------------------------

    def _advance(self, h: float) -> None:
        if self._landed:
            if not self.armed or not self._lift_off_wanted():
                self._thr = 0.0
                return
            self._landed = False
            self.touchdown_s = None
            if self._takeoff_at_s is not None:
                self._takeoff_at_s = None
                self._taking_off = True
            self._alt_hold = self._u
        if not self.armed:
            self._fall(h)
            return
        if self._sub == _C_MANUAL:
            self._advance_manual(h)
        else:
            self._advance_auto(h)
        if self._u >= self.limits.max_altitude_m and self._vu > 0.0:
            self._u = self.limits.max_altitude_m
            self._vu = 0.0

    def _lift_off_wanted(self) -> bool:
        start = self._takeoff_at_s
        if start is not None:
            return self._now_s >= start
        if self._pilot_climb and (self._sub == _C_MANUAL or self._sub == _C_PILOT):
            return self._rc_thr > 0.5 + self._thr_dz
        if self._sub == _C_MANUAL:
            return self._rc_thr > 0.5  # above hover
        return False

    def _touchdown(self) -> None:
        self._touched_down(-self._vu)
        self._u = 0.0
        self._vn = self._ve = self._vu = 0.0
        self._roll = self._pitch = 0.0
        self._thr = 0.0
        self._landed = True
        self._taking_off = False
        self._landing = False

    def _fall(self, h: float) -> None:
        """Motors stopped (or at idle): gravity against quadratic drag, attitude level."""
        vu = self._vu
        vu += (-G_M_S2 - self._fall_drag_1_m * vu * abs(vu)) * h
        decay = 1.0 - self._drag_1_s * h
        if self._wind is None:
            self._vn *= decay
            self._ve *= decay
        else:  # drifting toward the air's velocity
            self._vn = self._air_n + (self._vn - self._air_n) * decay
            self._ve = self._air_e + (self._ve - self._air_e) * decay
        self._vu = vu
        self._n += self._vn * h
        self._e += self._ve * h
        self._u += vu * h
        self._roll -= self._roll * self._roll_alpha
        self._pitch -= self._pitch * self._pitch_alpha
        self._thr = 0.0
        if self._u <= 0.0:
            self._touchdown()

    def _pilot_rate(self) -> float | None:
        """The climb rate the throttle stick asks for; None in the dead band (hold)."""
        stick = self._rc_thr
        top = 0.5 + self._thr_dz
        bottom = 0.5 - self._thr_dz
        if stick > top:
            return self._pilot_up * (stick - top) / (1.0 - top)
        if stick < bottom:
            return -self._pilot_down * (bottom - stick) / bottom
        return None

    def _pilot_vertical(self, h: float) -> float:
        """Climb at the stick's rate, or hold the height where the copter stopped.

        AC_PosControl shapes the climb rate's change: at most PILOT_ACCEL_Z, that
        acceleration itself changing at most PSC_JERK_Z (an S-curve), easing into the
        stick's rate without overshooting it. With the stick in the dead band the rate
        is zero: a copter still climbing or sinking (the stick just centred, the mode
        just entered) is brought to a stop the same way, and holds the height where it
        stopped (SITL, entering LOITER at 14.0 m climbing 1.1 m/s: 14.48 m after 0.7 s).
        """
        rate = self._pilot_rate()
        if rate is None and not self._z_braking:
            want = _clamp(
                sqrt_controller(self._alt_hold - self._u, COPTER_Z_GAIN_1_S, self._brake_z, h),
                -self._pilot_down,
                self._pilot_up,
            )
            step = self._pilot_accel * h
            change = _clamp(want - self._vu, -step, step)
        else:
            self._alt_hold = self._u + self._vu * h
            error = (rate or 0.0) - self._vu
            jerk = self._pilot_jerk
            accel_want = math.copysign(
                min(self._pilot_accel, math.sqrt(2.0 * jerk * abs(error))), error
            )
            accel = self._pilot_az + _clamp(accel_want - self._pilot_az, -jerk * h, jerk * h)
            change = accel * h
            if (error >= 0.0 and change > error) or (error <= 0.0 and change < error):
                change = error
            # Braking to a hold ends once stopped; a rate asked for brakes again after it.
            self._z_braking = rate is not None or abs(self._vu + change) > 0.02
        self._vu += change
        self._pilot_az = change / h
        return change / h

    def _advance_auto(self, h: float) -> None:
        sub = self._sub
        if _C_RTL_CLIMB <= sub <= _C_RTL_LOITER:
            sub = self._rtl_progress()
        n, e, u = self._n, self._e, self._u
        vn, ve, vu = self._vn, self._ve, self._vu
        dn, de = self._tn - n, self._te - e
        if sub in _C_RATE_SUBS:
            # Horizontal: hold the point (or fly the circle); vertical: a rate.
            if sub == _C_CIRCLE:
                want_n, want_e = self._circle_velocity(h)
                dn, de = self._circle_n - n, self._circle_e - e
            else:
                distance = math.sqrt(dn * dn + de * de)
                if distance > 1e-9:
                    speed = sqrt_controller(distance, COPTER_XY_GAIN_1_S, self._brake_xy, h)
                    if speed > self._leg_speed:
                        speed = self._leg_speed
                    want_n, want_e = dn * speed / distance, de * speed / distance
                else:
                    want_n = want_e = 0.0
            dvn, dve = want_n - vn, want_e - ve
            change = math.sqrt(dvn * dvn + dve * dve)
            faster = want_n * want_n + want_e * want_e >= vn * vn + ve * ve
            step = (self._accel_xy if faster else self._brake_xy) * h
            if change > step:
                dvn *= step / change
                dve *= step / change
            if sub == _C_LAND:
                above = u - self.home_m[2] - self._land_alt_low
                rate = self._land_speed
                if above > 0.0:
                    rate = _clamp(
                        sqrt_controller(above, 1.0, self._accel_z, h),
                        self._land_speed,
                        self._land_speed_high,
                    )
                step_z = self._accel_z * h
                change_z = _clamp(-rate - vu, -step_z, step_z)
                self._vu = vu + change_z
                accel_up = change_z / h
            else:
                accel_up = self._pilot_vertical(h)
        else:
            # A straight 3-D line to the target (ArduCopter's waypoint navigation): the
            # speed along the line ramps and brakes within both axes' limits, and each
            # axis follows its share within its own limits (so a line flown from rest
            # stays straight, and a copter already climbing eases onto the new line).
            du = self._tu - u
            flat = dn * dn + de * de
            distance = math.sqrt(flat + du * du)
            path = self._path_speed
            if distance > 1e-9:
                hf = math.sqrt(flat) / distance
                vf = abs(du) / distance
                top = ramp = brake = _INF
                if hf > 1e-9:
                    top = self._leg_speed / hf
                    ramp = self._accel_xy / hf
                    brake = self._brake_xy / hf
                if vf > 1e-9:
                    vertical = self._climb_max if du > 0.0 else self._descent_max
                    top = min(top, vertical / vf)
                    ramp = min(ramp, self._accel_z / vf)
                    brake = min(brake, self._brake_z / vf)
                gain = (COPTER_XY_GAIN_1_S * hf + COPTER_Z_GAIN_1_S * vf) / (hf + vf)
                speed = sqrt_controller(distance, gain, brake, h)
                if speed > top:
                    speed = top
                path = speed if speed < path else min(speed, path + ramp * h)
                scale = path / distance
                want_n, want_e, want_u = dn * scale, de * scale, du * scale
            else:
                path = want_n = want_e = want_u = 0.0
            self._path_speed = path
            dvn, dve = want_n - vn, want_e - ve
            change = math.sqrt(dvn * dvn + dve * dve)
            faster = want_n * want_n + want_e * want_e >= vn * vn + ve * ve
            step = (self._accel_xy if faster else self._brake_xy) * h
            if change > step:
                dvn *= step / change
                dve *= step / change
            step = self._accel_z * h
            dvu = _clamp(want_u - vu, -step, step)
            self._vu = vu + dvu
            accel_up = dvu / h
        if self._wind is not None:
            dvn, dve = self._push(h, vn, ve, dvn, dve)
        vn += dvn
        ve += dve
        n += vn * h
        e += ve * h
        u += self._vu * h
        self._n, self._e, self._u, self._vn, self._ve = n, e, u, vn, ve
        if u <= 0.0 and self._vu <= 0.0:
            # LAND, the pilot's stick, a target on the ground or a slow arrival: landed.
            if sub in _C_RATE_SUBS or self._tu <= 0.0 or vn * vn + ve * ve < 0.25:
                self._touchdown()
                return
            self._u = 0.0
            self._vu = 0.0
        if self._taking_off and abs(self._tu - self._u) <= COPTER_TAKEOFF_DONE_M:
            self._taking_off = False
        # Yaw: toward the target while far from it, the centre of a circle, or (RTL's
        # loiter above home) back to the heading at arming.
        yaw = self._yaw
        if sub == _C_RTL_LOITER:
            error = _wrap_pi(self._armed_yaw - yaw)
        elif sub == _C_CIRCLE or (self._face_target and dn * dn + de * de > 4.0):
            error = _wrap_pi(math.atan2(de, dn) - yaw)
        else:
            error = 0.0
        if error:
            limit = self._max_turn_rad_s
            yaw = _wrap_pi(yaw + _clamp(2.0 * error, -limit, limit) * h)
            self._yaw = yaw
        self._attitude(h, dvn / h, dve / h, accel_up)

    def _circle_velocity(self, h: float) -> tuple[float, float]:
        """The velocity that flies ArduCopter's circle (feed-forward plus position)."""
        step = self._circle_accel * h
        self._circle_rate += _clamp(self._circle_rate_max - self._circle_rate, -step, step)
        angle = self._circle_angle + self._circle_rate * h
        if angle >= math.pi:
            angle -= _TAU
        elif angle < -math.pi:
            angle += _TAU
        self._circle_angle = angle
        radius = self._circle_radius
        cos_a, sin_a = math.cos(angle), math.sin(angle)
        self._tn = self._circle_n + radius * cos_a
        self._te = self._circle_e + radius * sin_a
        tangential = self._circle_rate * radius
        want_n = -tangential * sin_a + COPTER_XY_GAIN_1_S * (self._tn - self._n)
        want_e = tangential * cos_a + COPTER_XY_GAIN_1_S * (self._te - self._e)
        speed = math.sqrt(want_n * want_n + want_e * want_e)
        if speed > self._leg_speed:
            want_n *= self._leg_speed / speed
            want_e *= self._leg_speed / speed
        return want_n, want_e

    def _rtl_progress(self) -> int:
        """Move RTL on: climb -> return -> loiter above home -> land (or final height)."""
        sub = self._sub
        if sub == _C_RTL_LOITER:
            now = self._now_s
            hover_s = max(self._params["RTL_LOIT_TIME"], 0.0) / 1000.0 + COPTER_RTL_SETTLE_S
            done = now - self._phase_since_s >= hover_s
            if done and abs(_wrap_pi(self._yaw - self._armed_yaw)) <= (
                COPTER_RTL_YAW_TOLERANCE_RAD
            ):
                final = self._params["RTL_ALT_FINAL"] / 100.0
                if final > 0.0:
                    self._tu = min(self.home_m[2] + final, self.limits.max_altitude_m)
                    self._aim()
                    sub = _C_RTL_FINAL
                else:
                    sub = _C_LAND
                    self._landing = True
                self._sub = sub
            return sub
        dn, de, du = self._tn - self._n, self._te - self._e, self._tu - self._u
        if dn * dn + de * de + du * du <= self._reach_m * self._reach_m:
            if sub == _C_RTL_CLIMB:
                self._tn, self._te, self._tu = self.home_m[0], self.home_m[1], self._rtl_alt
                self._face_target = True
                self._aim()
                sub = _C_RTL_RETURN
            else:
                self._face_target = False
                self._phase_since_s = self._now_s
                sub = _C_RTL_LOITER
            self._sub = sub
        return sub

    def _wind_changed(self) -> None:
        # A copter already flying has trimmed for the air it flies in; one on the
        # ground learns it after takeoff.
        if self.airborne:
            self._wind_est_n, self._wind_est_e = self._air_n, self._air_e
        else:
            self._wind_est_n = self._wind_est_e = 0.0

    def _push(self, h: float, vn: float, ve: float, dvn: float, dve: float) -> tuple[float, float]:
        """The velocity change the wind leaves of the one commanded, within the lean limit.

        The position controller tilts for the acceleration it wants plus the drag of the
        air it believes it flies through (its estimate, learnt over
        :data:`COPTER_WIND_LEARN_S`), never beyond the lean limit (ANGLE_MAX); the air
        then drags on the true relative velocity. So a steady wind is held off, a change
        of wind pushes the copter until learnt, and a wind it cannot lean into (drag at
        full lean, ``max_speed_m_s`` of airspeed) carries it away.
        """
        drag = self._drag_1_s
        air_n, air_e = self._air_n, self._air_e
        learn = h / COPTER_WIND_LEARN_S if h < COPTER_WIND_LEARN_S else 1.0
        est_n = self._wind_est_n + (air_n - self._wind_est_n) * learn
        est_e = self._wind_est_e + (air_e - self._wind_est_e) * learn
        self._wind_est_n, self._wind_est_e = est_n, est_e
        thrust_n = dvn / h + drag * (vn - est_n)
        thrust_e = dve / h + drag * (ve - est_e)
        thrust = math.sqrt(thrust_n * thrust_n + thrust_e * thrust_e)
        limit = G_M_S2 * math.tan(self._max_lean_rad)
        if thrust > limit:
            thrust_n *= limit / thrust
            thrust_e *= limit / thrust
        return (
            (thrust_n - drag * (vn - air_n)) * h,
            (thrust_e - drag * (ve - air_e)) * h,
        )

    def _attitude(self, h: float, accel_n: float, accel_e: float, accel_up: float) -> None:
        """Lean into the acceleration and hold off the air's drag; throttle pays for it."""
        drag = self._drag_1_s
        accel_n += drag * (self._vn - self._air_n)
        accel_e += drag * (self._ve - self._air_e)
        yaw = self._yaw
        cos_yaw, sin_yaw = math.cos(yaw), math.sin(yaw)
        forward = accel_n * cos_yaw + accel_e * sin_yaw
        right = -accel_n * sin_yaw + accel_e * cos_yaw
        lean = self._max_lean_rad
        pitch_cmd = _clamp(-math.atan(forward / G_M_S2), -lean, lean)
        roll_cmd = _clamp(math.atan(right / G_M_S2), -lean, lean)
        self._roll += (roll_cmd - self._roll) * self._roll_alpha
        self._pitch += (pitch_cmd - self._pitch) * self._pitch_alpha
        self._thr = _clamp(
            self.hover_throttle
            * (1.0 + accel_up / G_M_S2)
            / (math.cos(self._roll) * math.cos(self._pitch)),
            0.0,
            1.0,
        )

    def _advance_manual(self, h: float) -> None:
        lean = self._max_lean_rad
        self._roll += (self._rc_roll * lean - self._roll) * self._roll_alpha
        self._pitch += (self._rc_pitch * lean - self._pitch) * self._pitch_alpha
        yaw = _wrap_pi(self._yaw + self._rc_yaw * self._max_turn_rad_s * h)
        self._yaw = yaw
        # Lean accelerates: pitch up (positive) accelerates backward.
        forward = -G_M_S2 * math.tan(self._pitch)
        right = G_M_S2 * math.tan(self._roll)
        cos_yaw, sin_yaw = math.cos(yaw), math.sin(yaw)
        drag = self._drag_1_s
        air_n, air_e = self._air_n, self._air_e  # the wind's drag: on the relative velocity
        vn = self._vn + (forward * cos_yaw - right * sin_yaw - drag * (self._vn - air_n)) * h
        ve = self._ve + (forward * sin_yaw + right * cos_yaw - drag * (self._ve - air_e)) * h
        rel_n, rel_e = vn - air_n, ve - air_e
        speed = math.sqrt(rel_n * rel_n + rel_e * rel_e)
        if speed > self._max_speed:  # through the air
            vn = air_n + rel_n * self._max_speed / speed
            ve = air_e + rel_e * self._max_speed / speed
        if self._pilot_climb:
            accel_up = self._pilot_vertical(h)
            thrust = self.hover_throttle * (1.0 + accel_up / G_M_S2)
        else:
            # The stick is the thrust (angle boost keeps a hover level when leaning):
            # mid stick hovers, the minimum idles the motors.
            stick = self._rc_thr
            ratio = (
                2.0 * stick
                if stick <= 0.5
                else 1.0 + (stick - 0.5) * 2.0 * (COPTER_MAX_THRUST_RATIO - 1.0)
            )
            vu = self._vu
            accel_up = G_M_S2 * (ratio - 1.0) - self._fall_drag_1_m * vu * abs(vu)
            vu += accel_up * h
            if vu > self.limits.max_climb_rate_m_s:
                vu = self.limits.max_climb_rate_m_s
            self._vu = vu
            thrust = self.hover_throttle * ratio
        self._vn, self._ve = vn, ve
        self._n += vn * h
        self._e += ve * h
        self._u += self._vu * h
        if self._u <= 0.0 and self._vu <= 0.0:
            self._touchdown()
            return
        self._thr = _clamp(thrust / (math.cos(self._roll) * math.cos(self._pitch)), 0.0, 1.0)


# Fixed-wing sub-states.
(
    _P_MANUAL,  # fly the sticks (FBWA and the other pilot modes)
    _P_LOITER,  # loiter around a centre (guided, auto, hold, RTL, after a takeoff)
    _P_LAUNCH,  # on the ground, waiting to launch (TAKEOFF, AUTO's takeoff)
    _P_CLIMB,  # the takeoff climb along the launch heading
    _P_LAND,  # a glide-slope landing straight ahead
) = range(5)


class FixedWing(SimulatedVehicle):
    """A fixed-wing aircraft: never below its minimum speed in the air, cannot hover.

    Lateral: coordinated turns, turn rate ``g * tan(roll) / V``, never above
    ``max_turn_rate_deg_s``; roll follows its command through a first-order lag
    (``roll_time_constant_s``), never beyond the airframe's ``max_bank_deg`` nor
    ArduPlane's ROLL_LIMIT_DEG. The rudder adds a skidding yaw rate of up to half
    the turn-rate limit. A pull in a bank (the flight path's angle rising) turns it
    quicker by ``tan(roll)`` times the flight path's rate, and a push slower (the
    load factor's share of the lift, within :data:`PLANE_PULL_MAX_G`), on top of that
    limit; in the automatic modes the bank also swings with the pitch rate
    (:data:`PLANE_ROLL_COUPLING_S`, SITL's plane's, fitted), so that at the stick-mixed
    pitch's resonance the loiter tightens as SITL's does.

    Longitudinal (an energy model): the flight path follows the pitch attitude
    :data:`PLANE_PATH_LAG_S` late, climb ``V * sin(path)`` within the climb/descent
    limits; pitch follows its command through a first-order lag
    (``pitch_time_constant_s``). Speed obeys
    ``dV/dt = k (V_thr - V) - g * climb / V``: thrust minus drag, linear in speed,
    with ``V_thr`` the level-flight speed the throttle sustains, from ``V_idle``
    (throttle 0) to ``max_speed_m_s`` (full). ``k`` is sized so that full
    throttle at cruise speed climbs at ``max_climb_rate_m_s``, and ``V_idle`` so
    that idle glides at half the descent limit at minimum speed. When the energy
    cannot pay for a climb at minimum speed the climb is cut (the nose drops), so
    the aircraft never flies below ``min_speed_m_s``.

    Automatic modes fly one controller, ArduPlane's L1 loiter
    (:meth:`FixedWing._loiter_roll`): round a centre (the guided or auto target, the
    point where GUIDED, AUTO or LOITER was entered, home for RTL), clockwise for a
    positive WP_LOITER_RAD and counter-clockwise for a negative one, asked for a radius
    of WP_LOITER_RAD (RTL: RTL_RADIUS when set), never tighter than
    ``loiter_radius_factor`` times the tightest turn at the loiter speed (``V^2 / (g
    tan(max bank))`` or ``V / max turn rate``, whichever is larger). In these modes the
    aircraft turns at :data:`PLANE_TURN_EFFICIENCY` of a coordinated turn for its bank,
    as SITL's plane does, so the circle it flies is a little wider
    (:attr:`FixedWing.loiter_radius_m`). From afar it flies straight at the centre
    (L1's capture) and turns onto the circle where the circle's demand takes over. So a guided
    goto flies to the point and then circles it, as ArduPlane's GUIDED does; RTL
    flies home and circles it at RTL_ALTITUDE above home indefinitely (RTL_AUTOLAND
    0). Airspeed: AIRSPEED_CRUISE (or DO_CHANGE_SPEED's) within AIRSPEED_MIN..MAX and
    the airframe's limits, an equivalent airspeed as ArduPlane holds it: what the
    airspeed sensor reads (VFR_HUD), flown at :func:`eas2tas` times it through the air
    (:data:`PLANE_AIRSPEED_SENSOR_SCALE`). Altitude: climb rate proportional to the error
    within the limits, its changes slewed at :data:`PLANE_CLIMB_SLEW_M_S2`; throttle holds
    the speed and pays for the climb. The RC sticks are mixed in (ArduPlane's default
    STICK_MIXING, FBW style, Plane::stabilize_stick_mixing_fbw): the sticks read through
    their dead zones (RCn_DZ), past half stick steeper, times ROLL_LIMIT_DEG (pitch:
    PTCH_LIM_MAX_DEG up, PTCH_LIM_MIN_DEG down) are added to the navigation's demand
    (:meth:`nav_attitude_deg`), so a doublet shows in the attitude in these modes too; the
    pitch's share passes a band-pass fitted to SITL's (:data:`PLANE_STICK_PITCH_GAIN`).

    Takeoff is by mode, as on ArduPlane: armed in TAKEOFF (or armed in AUTO after
    :meth:`auto_takeoff`) on the ground it launches :data:`PLANE_LAUNCH_DELAY_S`
    later: a full-throttle ground roll along its heading, liftoff at minimum speed,
    a full-throttle climb at up to the airframe's climb limit along that heading,
    wings level below TKOFF_LVL_ALT; landed_state ``taking_off`` from the roll to
    TKOFF_ALT (the mission's altitude for AUTO), then ``in_air``, overshooting a
    little as SITL does. TAKEOFF then loiters at TKOFF_ALT around the point
    TKOFF_DIST ahead on the takeoff heading and never ends by itself; AUTO loiters
    where the climb ended until the executor sets a target. Entered in the air,
    TAKEOFF loiters at TKOFF_ALT (or higher) TKOFF_DIST ahead. Every other
    automatic mode armed on the ground stays put with the throttle at 0 (measured);
    ArduPlane's NAV_TAKEOFF command is quadplane-only, so :meth:`takeoff` refuses.

    Landing (AUTO's :meth:`auto_land`): straight ahead along the current course at
    the landing airspeed ((AIRSPEED_MIN + AIRSPEED_CRUISE) / 2, SITL's 16 m/s) down
    a :data:`PLANE_LAND_SLOPE_DEG` glide slope, flaring below LAND_FLARE_ALT to
    touch down at TECS_LAND_SINK; landed_state ``landing`` until the touchdown, then
    it rolls out and stops. ArduPlane has no LAND mode; AUTOLAND is not simulated.

    Manual modes (MANUAL, FBWA and the other pilot modes) all fly as FBWA does:
    the aileron deflection commands a roll angle (full deflection = max bank), the
    elevator a pitch angle (full up +20 degrees, full down -25, ArduPlane's
    LIM_PITCH_MAX/MIN), the rudder a yaw rate, the throttle stick the throttle.
    MANUAL on a real aircraft commands surface deflection, i.e. rates; a
    trimmed, statically stable aircraft settles to an attitude for a held
    deflection, which is what this models, without its rate dynamics. On the
    ground manual throttle accelerates it along its heading, the rudder steers it,
    and at minimum speed up elevator lifts it off. Touching the ground lands it
    (any mode); it then brakes to a stop. Disarmed (a forced disarm in the air) the
    throttle is 0 and it glides.
    """

    airframe_class = "fixed_wing"
    PARAM_DEFAULTS = PLANE_DEFAULT_PARAMS
    _MANUAL_MODES = frozenset(
        {"MANUAL", "STABILIZE", "TRAINING", "ACRO", "FBWA", "FBWB", "CRUISE", "AUTOTUNE"}
    )
    _HOLD_MODES = frozenset({"LOITER"})
    _RTL_MODES = frozenset({"RTL"})
    _TAKEOFF_MODES = frozenset({"TAKEOFF"})
    _REFUSED_MODES = frozenset(
        {
            "INITIALISING",
            "QSTABILIZE",
            "QHOVER",
            "QLOITER",
            "QLAND",
            "QRTL",
            "QAUTOTUNE",
            "QACRO",
        }
    )
    _CONTROL_NAMES = ("aileron", "elevator", "rudder", "throttle")

    roll_time_constant_s = 0.2
    pitch_time_constant_s = 0.3
    #: First-order lag of the rudder's yaw rate.
    yaw_time_constant_s: float = 0.3
    #: Highest and lowest pitch (ArduPlane LIM_PITCH_MAX, LIM_PITCH_MIN).
    max_pitch_deg: float = 20.0
    min_pitch_deg: float = -25.0
    #: The loiter radius is at least this times the tightest turn at the loiter speed.
    loiter_radius_factor: float = 1.5
    #: Time constant of the automatic speed hold.
    speed_time_constant_s: float = 2.0
    #: Climb rate per metre of altitude error in automatic modes, 1/s.
    altitude_gain_1_s: float = 0.4
    #: Turn rate per radian of course error, 1/s.
    course_gain_1_s: float = 1.0
    #: Braking on the ground, m/s^2.
    ground_decel_m_s2: float = 2.0

    def _setup(self) -> None:
        limits = self.limits
        self._v_min = max(limits.min_speed_m_s, 1.0)
        self._v_max = max(limits.max_speed_m_s, self._v_min)
        cruise = _clamp(limits.cruise_speed_m_s, self._v_min, self._v_max)
        self._airframe_bank = math.radians(limits.max_bank_deg if limits.max_bank_deg else 45.0)
        self._max_pitch = math.radians(self.max_pitch_deg)
        self._min_pitch = math.radians(self.min_pitch_deg)
        self._dead_zones_us = (PLANE_RC_DEAD_ZONE_US,) * 3
        self._nav_roll = self._nav_pitch = 0.0
        self._reset_stick_pitch()
        self._reset_roll_coupling()
        self._gamma = 0.0  # the flight path's angle, rad (its rate is the pull)
        self._path = 0.0  # the flight path's angle the climb follows (lagging the pitch)
        self._rudder_rate = 0.5 * self._max_turn_rad_s
        self._max_climb = limits.max_climb_rate_m_s
        self._max_descent = limits.max_descent_rate_m_s
        # Thrust-minus-drag gain and idle speed (see the class docstring).
        headroom = max(self._v_max - cruise, 1.0)
        self._k_1_s = max(G_M_S2 * self._max_climb / (cruise * headroom), 0.05)
        idle_sink = 0.5 * self._max_descent
        self._v_idle = self._v_min - G_M_S2 * idle_sink / (self._v_min * self._k_1_s)
        self._flying = self._u > 0.0
        self._tas_per_eas = self._tas_per_indicated(self._u)
        # The pilot flies the airframe's cruise as the airspeed indicator shows it (EAS).
        self._speed = cruise * self._tas_per_eas if self._flying else 0.0
        self._yaw_rate = 0.0
        self._climb_cmd = 0.0
        self._sub = _P_LOITER
        self._speed_set = False
        self._launch_at_s: float | None = None
        self._launch_n, self._launch_e, self._launch_yaw = self._n, self._e, self._yaw
        self._course = self._yaw
        self._takeoff_alt = 0.0
        self._last_nu = 0.0
        self._capture()
        self._cn, self._ce, self._ch = self._n, self._e, self._u
        self._target_speed = self._auto_speed()
        self._radius_param = self._loiter_rad
        self._guided_radius_m = 0.0  # ModeGuided's active_radius_m: 0 is WP_LOITER_RAD
        self._guided_ccw = False  # the direction set with it
        self._target_ccw = False  # the guided target's own loiter_ccw (DO_REPOSITION param4)
        self._radius = self._loiter_radius(self._target_speed)
        if self._flying:
            # Level flight at cruise; a pilot who is flying holds the cruise throttle.
            self._vn = self._speed * math.cos(self._yaw)
            self._ve = self._speed * math.sin(self._yaw)
            self._thr = (self._speed - self._v_idle) / (self._v_max - self._v_idle)
            self._act_thr = self._thr
            throttle = self._controls[3]
            if throttle is not None and throttle.rc is not None:
                self._pilot_us[throttle.rc - 1] = throttle.pwm_from_fraction(self._thr)

    def _capture(self) -> None:
        """Read ArduPlane's parameters (at a mode entry or a target)."""
        p = self._params
        low = max(self._v_min, p["AIRSPEED_MIN"])
        high = min(self._v_max, p["AIRSPEED_MAX"])
        self._speed_low, self._speed_high = low, max(high, low)
        self._cruise = _clamp(p["AIRSPEED_CRUISE"], self._speed_low, self._speed_high)
        self._loiter_rad = abs(p["WP_LOITER_RAD"])
        self._wp_radius = max(p["WP_RADIUS"], 1.0)
        period = max(p["NAVL1_PERIOD"], 1.0)
        damping = max(p["NAVL1_DAMPING"], 0.1)
        l1_period = period * damping
        self._l1_gain = _TAU / l1_period
        self._l1_distance_s = l1_period / math.pi  # times the speed: L1's distance, m
        # AP_L1_Control::update_loiter's gains: the circle's PD (omega = 2 pi / period)
        # and the capture's L1 gain.
        omega = _TAU / period
        self._loiter_kx = omega * omega
        self._loiter_kv = 2.0 * damping * omega
        self._capture_k = 4.0 * damping * damping
        # WP_LOITER_RAD's sign: clockwise (1) or counter-clockwise (-1), as ArduPlane's.
        self._direction = -1.0 if p["WP_LOITER_RAD"] < 0.0 else 1.0
        limit = math.radians(p["ROLL_LIMIT_DEG"]) if p["ROLL_LIMIT_DEG"] > 0.0 else _INF
        self._max_bank = min(self._airframe_bank, limit)
        up, down = p["PTCH_LIM_MAX_DEG"], p["PTCH_LIM_MIN_DEG"]
        self._max_pitch = math.radians(up if 0.0 < up <= 90.0 else self.max_pitch_deg)
        self._min_pitch = math.radians(down if -90.0 <= down < 0.0 else self.min_pitch_deg)
        self._level_below = max(p["TKOFF_LVL_ALT"], 0.0)
        self._flare_alt = max(p["LAND_FLARE_ALT"], 0.0)
        self._land_sink = max(p["TECS_LAND_SINK"], 0.05)

    def _auto_speed(self) -> float:
        return self._cruise

    def configure(self, params: Mapping[str, float]) -> None:
        """Take the parameter table; also the sticks' dead zones (RCn_DZ of their channels).

        ArduPlane reads the sticks it mixes into its automatic modes through them
        (:meth:`_Channel.deflection_dz`); a channel whose RCn_DZ the table lacks keeps
        :data:`PLANE_RC_DEAD_ZONE_US`.
        """
        super().configure(params)
        zones = []
        for channel in self._controls[:3]:
            value = params.get(f"RC{channel.rc}_DZ") if channel and channel.rc else None
            number = float(value) if value is not None else float(PLANE_RC_DEAD_ZONE_US)
            zones.append(int(_clamp(number, 0.0, 200.0)) if math.isfinite(number) else 0)
        self._dead_zones_us = (zones[0], zones[1], zones[2])
        self._rc_stale = True

    def _set_step(self, h: float) -> None:
        super()._set_step(h)
        self._yaw_alpha = 1.0 - math.exp(-h / self.yaw_time_constant_s)
        self._path_alpha = 1.0 - math.exp(-h / PLANE_PATH_LAG_S)

    @property
    def airborne(self) -> bool:
        """True while flying."""
        return self._flying

    @property
    def landed_state(self) -> LandedState:
        """ArduPlane's landed state.

        Taking off from the launch to the takeoff altitude, landing until the
        touchdown, else in the air or on the ground.
        """
        sub = self._sub
        if not self._flying:
            start = self._launch_at_s
            if sub == _P_LAUNCH and self.armed and start is not None and self.time_s >= start:
                return "taking_off"
            return "on_ground"
        if sub == _P_CLIMB:
            return "taking_off"
        if sub == _P_LAND:
            return "landing"
        return "in_air"

    @property
    def target_reached(self) -> bool:
        """The target within WP_RADIUS, the takeoff climb done, or landed."""
        command = self._command
        if command == _CMD_TARGET:
            dn, de = self._cn - self._n, self._ce - self._e
            return dn * dn + de * de <= self._wp_radius * self._wp_radius
        if command == _CMD_TAKEOFF:
            return self._flying and self._sub != _P_CLIMB and self._sub != _P_LAUNCH
        if command == _CMD_LAND:
            return not self._flying
        return False

    @property
    def loiter_radius_m(self) -> float:
        """Radius of the circle flown round the current loiter centre, in still air.

        ArduPlane's L1 loiter asks for the circle's turn plus ``Kx`` (``(2 pi /
        NAVL1_PERIOD)^2``) per metre outside it; turning at :data:`PLANE_TURN_EFFICIENCY`
        of what it asks, the aircraft settles at the radius ``R`` where ``(1 - c) V^2 / R
        = c Kx (R - r)``, ``r`` being the radius asked for (WP_LOITER_RAD or RTL_RADIUS,
        never tighter than the airframe turns) and ``V`` the loiter airspeed.
        """
        c = PLANE_TURN_EFFICIENCY
        r = self._radius
        speed = self._target_speed * self._tas_per_eas
        gain = c * self._loiter_kx
        return 0.5 * (r + math.sqrt(r * r + 4.0 * (1.0 - c) * speed * speed / gain))

    def _airspeed(self, ground_speed_m_s: float) -> float:
        """What the airspeed sensor reads (VFR_HUD): about the equivalent airspeed."""
        return self._speed / self._tas_per_eas

    def _loiter_radius(self, eas_m_s: float) -> float:
        """The radius the L1 loiter is asked for, never tighter than the airframe turns.

        WP_LOITER_RAD (or RTL_RADIUS); what it flies is :attr:`loiter_radius_m`. The turn
        is the true airspeed's (``eas_m_s``, the loiter's equivalent airspeed, at the
        present altitude).
        """
        speed_m_s = eas_m_s * self._tas_per_eas
        by_bank = speed_m_s * speed_m_s / (G_M_S2 * math.tan(self._max_bank))
        by_rate = speed_m_s / self._max_turn_rad_s if self._max_turn_rad_s > 0 else by_bank
        tightest = self.loiter_radius_factor * max(by_bank, by_rate)
        return max(self._radius_param, tightest)

    def _clamp_altitude(self, alt_m: float) -> float:
        return _clamp(alt_m, 0.0, self.limits.max_altitude_m)

    def _apply_params_now(self) -> None:
        self._capture()
        if not self._speed_set:
            self._target_speed = self._auto_speed()
        if self._behaviour is ModeBehaviour.RTL and self._params["RTL_RADIUS"] > 0.0:
            self._radius_param = abs(self._params["RTL_RADIUS"])
        else:
            self._radius_param = self._loiter_rad
            self._guided_shape()
        self._radius = self._loiter_radius(self._target_speed)
        if self._behaviour is ModeBehaviour.RTL:
            self._ch = self._clamp_altitude(self.home_m[2] + self._params["RTL_ALTITUDE"])

    def _disarmed(self) -> None:
        if not self._flying:
            self._launch_at_s = None

    def _enter(self, behaviour: ModeBehaviour) -> None:
        self._command = _CMD_NONE
        self._launch_at_s = None
        if behaviour is ModeBehaviour.MANUAL:
            self._sub = _P_MANUAL
            return
        self._capture()
        self._speed_set = False
        self._target_speed = self._auto_speed()
        self._radius_param = self._loiter_rad
        # ModeGuided::_enter: "set guided radius to WP_LOITER_RAD on mode change", and its
        # target (where it was entered) has no loiter_ccw
        self._guided_radius_m = 0.0
        self._target_ccw = False
        self._sub = _P_LOITER
        home_n, home_e, home_u = self.home_m
        if behaviour is ModeBehaviour.RTL:
            self._cn, self._ce = home_n, home_e
            self._ch = self._clamp_altitude(home_u + self._params["RTL_ALTITUDE"])
            if self._params["RTL_RADIUS"] > 0.0:
                self._radius_param = abs(self._params["RTL_RADIUS"])
        elif behaviour is ModeBehaviour.TAKEOFF:
            altitude = self._clamp_altitude(home_u + self._params["TKOFF_ALT"])
            self._takeoff_alt = altitude
            if self._flying:
                self._loiter_ahead(self._n, self._e, self._yaw)
                self._ch = max(self._u, altitude)
            else:
                self._sub = _P_LAUNCH
        elif behaviour is ModeBehaviour.LAND and self._flying:
            self._start_landing()
        else:
            self._cn, self._ce, self._ch = self._n, self._e, self._u
        self._radius = self._loiter_radius(self._target_speed)

    def _loiter_ahead(self, north_m: float, east_m: float, yaw_rad: float) -> None:
        """TAKEOFF's loiter: TKOFF_DIST ahead of ``north_m, east_m`` on ``yaw_rad``."""
        distance = max(self._params["TKOFF_DIST"], 0.0)
        self._cn = north_m + distance * math.cos(yaw_rad)
        self._ce = east_m + distance * math.sin(yaw_rad)
        self._ch = self._takeoff_alt
        self._sub = _P_LOITER

    def _start_landing(self) -> None:
        self._course = self._yaw
        self._target_speed = _clamp(
            0.5 * (self._params["AIRSPEED_MIN"] + self._params["AIRSPEED_CRUISE"]),
            self._v_min,
            self._v_max,
        )
        self._sub = _P_LAND

    def guided_loiter(self, radius_m: float, ccw: bool) -> None:
        """DO_REPOSITION's loiter radius (param3) and direction (param4), as ArduPlane takes them.

        GCS_MAVLINK_Plane::handle_command_int_do_reposition: the target's ``loiter_ccw`` is
        param4 (non-zero and not NaN: counter-clockwise), and a param3 above 0 sets
        ModeGuided's active radius and its direction (``set_radius_and_direction``), kept
        for later targets until GUIDED is entered again. Plane::update_loiter flies that
        radius and direction; with none (0, or 1 m and less) WP_LOITER_RAD, counter-clockwise
        when the target's ``loiter_ccw`` is set, else by WP_LOITER_RAD's sign. Called before
        the target it comes with (:meth:`goto`), in GUIDED only.

        Args:
            radius_m: param3 (NaN, or 0 and less: no radius given).
            ccw: param4 asks for counter-clockwise.
        """
        if self._behaviour is not ModeBehaviour.GUIDED:
            return
        self._target_ccw = ccw
        if math.isfinite(radius_m) and radius_m > 0.0:
            self._guided_radius_m = min(float(int(radius_m)), 65535.0)
            self._guided_ccw = ccw

    def _guided_shape(self) -> None:
        """In GUIDED, the radius and direction Plane::update_loiter flies (see guided_loiter)."""
        if self._behaviour is not ModeBehaviour.GUIDED:
            return
        if self._guided_radius_m > 1.0:
            self._radius_param = self._guided_radius_m
            self._direction = -1.0 if self._guided_ccw else 1.0
        elif self._target_ccw:
            self._direction = -1.0

    def _set_target(
        self, north_m: float, east_m: float, alt_m: float, speed_m_s: float | None
    ) -> None:
        self._capture()
        self._radius_param = self._loiter_rad
        self._guided_shape()
        if speed_m_s is not None:
            self._set_speed(speed_m_s)
        elif not self._speed_set:
            self._target_speed = self._auto_speed()
        self._cn, self._ce, self._ch = north_m, east_m, self._clamp_altitude(alt_m)
        self._radius = self._loiter_radius(self._target_speed)
        self._command = _CMD_TARGET
        if self._flying:
            self._sub = _P_LOITER
        elif self._sub == _P_LAUNCH:
            self._launch_at_s = None
            self._sub = _P_LOITER

    def _set_speed(self, speed_m_s: float) -> None:
        self._target_speed = _clamp(speed_m_s, self._v_min, self._v_max)
        self._speed_set = True
        self._radius = self._loiter_radius(self._target_speed)

    def auto_takeoff(self, alt_m: float) -> bool:
        """AUTO's takeoff item: launch and climb to ``alt_m`` above home.

        On the ground the launch starts on arming (at once when armed), as ArduPlane's
        AUTO with a takeoff item does; in the air it climbs there. False outside AUTO.
        """
        if self._behaviour is not ModeBehaviour.AUTO or not math.isfinite(alt_m):
            return False
        self._capture()
        self._takeoff_alt = self._clamp_altitude(self.home_m[2] + alt_m)
        self._command = _CMD_TAKEOFF
        if self._flying:
            self._cn, self._ce = self._n, self._e
            self._ch = max(self._ch, self._takeoff_alt)
            self._sub = _P_LOITER
        else:
            self._sub = _P_LAUNCH
            self._launch_at_s = None
        return True

    def auto_land(self) -> None:
        """AUTO's land item: a glide-slope landing straight ahead."""
        if self._behaviour is not ModeBehaviour.AUTO:
            return
        self._command = _CMD_LAND
        if self._flying:
            self._capture()
            self._start_landing()

    # --- physics ----------------------------------------------------------------------

    def _reset_stick_pitch(self) -> None:
        """Empty the stick-mixed pitch's band-pass (at the start, and once it has settled)."""
        self._sp_washout = self._sp_pitch = self._sp_rate = 0.0
        self._sp_delayed: deque[float] = deque()

    def _stick_pitch(self, h: float, pitch_rad: float) -> float:
        """The pitch the automatic modes add for a stick-mixed pitch demand (band-pass).

        ``pitch_rad`` is ArduPlane's stick-mixing share of nav_pitch; the answer is what
        SITL's plane pitches for it, in the fit of :data:`PLANE_STICK_PITCH_GAIN`: a wash-out
        (``s / (s + a)``), a lightly damped second-order mode and a delay. With the stick
        centred and nothing left ringing, it is exactly 0 (no draw, no change to a flight
        without sticks).
        """
        if pitch_rad == 0.0 and not self._sp_delayed and self._sp_pitch == 0.0:
            return 0.0
        a = PLANE_STICK_PITCH_WASHOUT_1_S
        decay = math.exp(-a * h)
        self._sp_washout = decay * self._sp_washout + (1.0 - decay) / a * pitch_rad
        washed = pitch_rad - a * self._sp_washout
        omega = _TAU * PLANE_STICK_PITCH_MODE_HZ
        self._sp_rate += h * (
            omega * omega * (washed - self._sp_pitch)
            - 2.0 * PLANE_STICK_PITCH_DAMPING * omega * self._sp_rate
        )
        self._sp_pitch += h * self._sp_rate
        delayed = self._sp_delayed
        delayed.append(self._sp_pitch)
        steps = max(round(PLANE_STICK_PITCH_DELAY_S / h), 1)
        out = delayed.popleft() if len(delayed) > steps else 0.0
        settled = (
            pitch_rad == 0.0
            and max(
                abs(self._sp_pitch), abs(self._sp_rate), abs(self._sp_washout), *map(abs, delayed)
            )
            < 1e-9
        )
        if settled:
            self._reset_stick_pitch()  # back to exactly 0
        return PLANE_STICK_PITCH_GAIN * out

    def _reset_roll_coupling(self) -> None:
        """Empty the roll coupling's filter (at the start, on the ground, once settled)."""
        self._rc_bank = self._rc_bank_rate = 0.0
        self._roll_lagged = 0.0  # the roll's lagged demand while a coupling is under way
        self._rc_delayed: deque[float] = deque()

    def _roll_coupling(self, h: float, drive_rad_s: float) -> float:
        """The roll (rad) SITL's plane departs from its demand by for a pull in a bank.

        ``drive_rad_s`` is ``sin(bank)`` times the pitch rate; the answer is the
        second-order, delayed fit of :data:`PLANE_ROLL_COUPLING_S`. Exactly 0 with no pull
        and nothing left ringing (a level, steady flight is unchanged).
        """
        if drive_rad_s == 0.0 and not self._rc_delayed and self._rc_bank == 0.0:
            return 0.0
        delayed = self._rc_delayed
        delayed.append(drive_rad_s)
        steps = max(round(PLANE_ROLL_COUPLING_DELAY_S / h), 1)
        drive = delayed.popleft() if len(delayed) > steps else 0.0
        omega = _TAU * PLANE_ROLL_COUPLING_MODE_HZ
        self._rc_bank_rate += h * (
            omega * omega * (PLANE_ROLL_COUPLING_S * drive - self._rc_bank)
            - 2.0 * PLANE_ROLL_COUPLING_DAMPING * omega * self._rc_bank_rate
        )
        self._rc_bank += h * self._rc_bank_rate
        if (
            max(abs(self._rc_bank), abs(self._rc_bank_rate), *map(abs, delayed)) < 1e-9
            and drive_rad_s == 0.0
        ):
            self._reset_roll_coupling()  # back to exactly 0
        return self._rc_bank

    def nav_attitude_deg(self) -> tuple[float, float]:
        """The roll and pitch demanded (ArduPlane's nav_roll_cd and nav_pitch_cd).

        The automatic modes' navigation plus the pilot's stick mixing, within the
        limits: what NAV_CONTROLLER_OUTPUT reports. SITL's nav_roll stepped by 14.6
        degrees at once for 150 us of aileron in LOITER while its roll lagged.
        """
        return math.degrees(self._nav_roll), math.degrees(self._nav_pitch)

    def _tas_per_indicated(self, up_m: float) -> float:
        """True airspeed per m/s the airspeed sensor reads, ``up_m`` above the origin."""
        return eas2tas(self.origin.alt_amsl_m + up_m) / PLANE_AIRSPEED_SENSOR_SCALE

    def _advance(self, h: float) -> None:
        self._tas_per_eas = self._tas_per_indicated(self._u)
        speed = self._speed
        sub = self._sub
        level = False
        if sub == _P_MANUAL:
            roll_cmd = self._rc_roll * self._max_bank
            elevator = self._rc_pitch
            pitch_cmd = elevator * (self._max_pitch if elevator > 0.0 else -self._min_pitch)
            yaw_rate_cmd = self._rc_yaw * self._rudder_rate
            throttle = self._rc_thr
            lift_off = pitch_cmd > 0.0
            self._climb_cmd = self._vu
        elif not self._flying:
            roll_cmd = pitch_cmd = yaw_rate_cmd = throttle = 0.0
            lift_off = False
            self._climb_cmd = 0.0
            if sub == _P_LAUNCH and self.armed:
                start = self._launch_at_s
                if start is None:
                    self._launch_at_s = self._now_s + PLANE_LAUNCH_DELAY_S
                    self._launch_n, self._launch_e, self._launch_yaw = self._n, self._e, self._yaw
                    self._course = self._yaw
                elif self._now_s >= start:
                    # The ground roll: full throttle, holding the launch heading.
                    throttle = 1.0
                    lift_off = True
                    yaw_rate_cmd = self.course_gain_1_s * _wrap_pi(self._course - self._yaw)
        else:
            if sub == _P_CLIMB:
                # Full throttle at up to the climb limit, holding the launch course.
                roll_cmd = self._course_roll(speed, self._course)
                pitch_cmd = self._pitch_for(h, speed, self._max_climb)
                throttle = 1.0
                level = self._u - self.home_m[2] < self._level_below
            elif sub == _P_LAND:
                roll_cmd = self._course_roll(speed, self._course)
                height = self._u
                sink = speed * math.sin(math.radians(PLANE_LAND_SLOPE_DEG))
                if height < self._flare_alt and self._flare_alt > 0.0:
                    sink = max(self._land_sink, sink * height / self._flare_alt)
                pitch_cmd = self._pitch_for(h, speed, -sink)
                throttle = self._speed_throttle(speed)
                level = height < self._level_below
            else:
                roll_cmd = self._loiter_roll(speed)
                pitch_cmd = self._pitch_for(h, speed, self.altitude_gain_1_s * (self._ch - self._u))
                throttle = self._speed_throttle(speed)
            # FBW stick mixing (Plane::stabilize_stick_mixing_fbw): the sticks read
            # through their dead zones, past half stick steeper (to twice the limit).
            roll_cmd += _stick_mix(self._mix_roll) * self._max_bank
            elevator = _stick_mix(self._mix_pitch)
            stick = elevator * (self._max_pitch if elevator > 0.0 else -self._min_pitch)
            # ... whose pitch the aircraft answers as SITL's does (a fitted band-pass).
            pitch_cmd += self._stick_pitch(h, stick)
            yaw_rate_cmd = self._mix_yaw * self._rudder_rate
            if level:
                roll_cmd = 0.0
            lift_off = True
        if not self.armed:
            throttle = 0.0
        roll_cmd = _clamp(roll_cmd, -self._max_bank, self._max_bank)
        pitch_cmd = _clamp(pitch_cmd, self._min_pitch, self._max_pitch)
        self._nav_roll, self._nav_pitch = roll_cmd, pitch_cmd
        self._act_roll = roll_cmd / self._max_bank
        self._act_pitch = (
            pitch_cmd / self._max_pitch if pitch_cmd > 0.0 else -pitch_cmd / self._min_pitch
        )
        self._act_yaw = yaw_rate_cmd / self._rudder_rate if self._rudder_rate else 0.0
        self._act_thr = throttle
        self._thr = throttle
        if self._flying:
            # SITL's plane turns short of its bank in the automatic modes (where measured).
            efficiency = 1.0 if sub == _P_MANUAL else PLANE_TURN_EFFICIENCY
            self._fly(h, speed, roll_cmd, pitch_cmd, yaw_rate_cmd, throttle, efficiency)
            if not self._flying and self._sub == _P_CLIMB:
                self._sub = _P_LOITER
        else:
            self._roll_on_ground(h, speed, yaw_rate_cmd, throttle, lift_off)
            if self._flying and self._sub == _P_LAUNCH:
                self._sub = _P_CLIMB
        if self._sub == _P_CLIMB and self._u >= self._takeoff_alt:
            # Takeoff complete: TAKEOFF loiters TKOFF_DIST ahead, AUTO where it is.
            if self._behaviour is ModeBehaviour.TAKEOFF:
                self._loiter_ahead(self._launch_n, self._launch_e, self._launch_yaw)
            else:
                self._cn, self._ce, self._ch = self._n, self._e, self._takeoff_alt
                self._sub = _P_LOITER
            self._radius = self._loiter_radius(self._target_speed)

    def _loiter_roll(self, speed: float) -> float:
        """Roll command of ArduPlane's L1 loiter round the centre (AP_L1_Control::update_loiter).

        From outside the circle it flies at the centre by the L1 law (``K_L1 V^2 / L1
        sin(Nu)``, Nu the angle between the ground velocity and the line to the centre)
        until the circle's own demand (a PD on the distance outside the circle and the
        speed away from the centre, plus the centripetal ``V_t^2 / R``) asks for less
        turn; inside it, the circle's demand only. Entered at the centre (LOITER entered
        where the aircraft is), it flies on along its course while the PD's two terms
        cancel, then turns out onto the circle. Everything is over the ground (the
        ground velocity), so in wind the circle is the ground's. Roll = atan(a / (g cos
        pitch)), as ArduPlane's nav_roll_cd; the bank limit clamps it afterwards.
        """
        vn, ve = self._vn, self._ve
        ground = math.sqrt(vn * vn + ve * ve)
        an, ae = self._n - self._cn, self._e - self._ce
        distance = math.sqrt(an * an + ae * ae)
        if distance > 0.1:
            un, ue = an / distance, ae / distance
        elif ground >= 0.1:
            un, ue = vn / ground, ve / ground
        else:
            un, ue = math.cos(self._yaw), math.sin(self._yaw)
        ground = max(ground, 1.0)
        xtrack_vel = un * ve - ue * vn  # across the line to the centre
        ltrack_vel = -(vn * un + ve * ue)  # along it, toward the centre
        nu = math.atan2(xtrack_vel, ltrack_vel)
        last, self._last_nu = self._last_nu, nu
        limit = 0.9 * math.pi
        if abs(nu) > limit and abs(last) > limit and nu * last < 0.0:
            # ArduPlane's _prevent_indecision: flying away from the centre, keep the
            # side it chose to turn to.
            bearing = math.atan2(-ae, -an)
            if abs(_wrap_pi(bearing - self._yaw)) > math.radians(120.0):
                nu = last
        nu = _clamp(nu, -_HALF_PI, _HALF_PI)
        capture = self._capture_k * ground / self._l1_distance_s * math.sin(nu)
        radius = self._radius
        excess = distance - radius
        pd = excess * self._loiter_kx - ltrack_vel * self._loiter_kv
        direction = self._direction
        tangent = xtrack_vel * direction
        if ltrack_vel < 0.0 and tangent < 0.0:
            pd = max(pd, 0.0)
        centripetal = tangent * tangent / max(0.5 * radius, radius + excess)
        circle = direction * (pd + centripetal)
        # Capture only from outside the circle, while it asks for less than the circle.
        captured = excess <= 0.0 or direction * capture >= direction * circle
        accel = circle if captured else capture
        pitch = _clamp(self._pitch, -math.radians(60.0), math.radians(60.0))
        return math.atan(accel / (G_M_S2 * math.cos(pitch)))

    def _ground_track(self) -> tuple[float, float]:
        """Ground speed and track (the velocity over the ground's direction), in wind."""
        vn, ve = self._vn, self._ve
        ground = math.sqrt(vn * vn + ve * ve)
        return ground, (math.atan2(ve, vn) if ground > 0.5 else self._yaw)

    def _l1_turn(self, error: float) -> float:
        """Turn rate (rad/s) toward a course ``error`` radians away, as ArduPlane's L1 turns.

        L1's lateral acceleration is 2 V^2 / L1 sin(eta) with L1 = V NAVL1_PERIOD
        NAVL1_DAMPING / pi, so the turn rate is 2 pi / (NAVL1_PERIOD NAVL1_DAMPING)
        sin(eta), eta capped at 90 degrees: a course error of 30 degrees turns at half
        the rate of one of 90 or more (0.49 rad/s with ArduPlane's defaults).
        """
        return self._l1_gain * math.sin(_clamp(error, -_HALF_PI, _HALF_PI))

    def _course_roll(self, speed: float, course: float) -> float:
        """Roll command that holds a course."""
        limit = self._max_turn_rad_s
        if self._wind is not None:  # hold the track over the ground, crabbing into the wind
            ground, track = self._ground_track()
            turn = _clamp(self._l1_turn(_wrap_pi(course - track)), -limit, limit)
            return math.atan(turn * ground / G_M_S2)
        turn = _clamp(self._l1_turn(_wrap_pi(course - self._yaw)), -limit, limit)
        return math.atan(turn * speed / G_M_S2)

    def _pitch_for(self, h: float, speed: float, climb_m_s: float) -> float:
        """Pitch for a climb rate, the autopilot's climb command slewed (TECS in outline)."""
        want = _clamp(climb_m_s, -self._max_descent, self._max_climb)
        step = PLANE_CLIMB_SLEW_M_S2 * h
        command = self._climb_cmd + _clamp(want - self._climb_cmd, -step, step)
        self._climb_cmd = command
        return math.asin(_clamp(command / speed, -1.0, 1.0))

    def _speed_throttle(self, speed: float) -> float:
        """Throttle that holds the target speed and pays for the current climb.

        The target is an equivalent airspeed (AIRSPEED_CRUISE, DO_CHANGE_SPEED), held as
        ArduPlane's TECS holds what its pitot reads: flown at :func:`eas2tas` times it
        (over :data:`PLANE_AIRSPEED_SENSOR_SCALE`, the sensor's reading).
        """
        accel = (self._target_speed * self._tas_per_eas - speed) / self.speed_time_constant_s
        accel += G_M_S2 * self._vu / speed
        level_speed = speed + accel / self._k_1_s
        return _clamp((level_speed - self._v_idle) / (self._v_max - self._v_idle), 0.0, 1.0)

    def _fly(
        self,
        h: float,
        speed: float,
        roll_cmd: float,
        pitch_cmd: float,
        yaw_rate_cmd: float,
        throttle: float,
        efficiency: float = 1.0,
    ) -> None:
        """One step in the air; the bank turns at ``efficiency`` of a coordinated turn.

        The lift turns the flight path: its horizontal share turns the course at ``tan(bank)
        (g cos(gamma) + V gamma') / (V cos(gamma))`` (gamma the flight path's angle), so a
        pull in a bank (gamma' > 0) turns the aircraft quicker and a push slower. Level, it
        is ``g tan(bank) / V``. In the automatic modes (``efficiency`` below 1) the bank
        also departs from its lagged demand by :meth:`_roll_coupling` of the pitch rate, as
        SITL's plane does; with the two together its circle tightens when its pitch swings
        at its resonance, as SITL's does.
        """
        coupled = self._rc_bank
        # The lagged demand is the roll itself unless a coupling is under way.
        lagged = self._roll_lagged if coupled != 0.0 or self._rc_delayed else self._roll
        lagged += (roll_cmd - lagged) * self._roll_alpha
        self._roll_lagged = lagged
        pitch = self._pitch + (pitch_cmd - self._pitch) * self._pitch_alpha
        if efficiency != 1.0:
            drive = math.sin(lagged) * (pitch - self._pitch) / h
            coupled = self._roll_coupling(h, drive)
        elif coupled != 0.0:
            self._reset_roll_coupling()
            coupled = 0.0
        # Never beyond the airframe's bank (the class's promise; SITL's may be).
        roll = _clamp(lagged + coupled, -self._airframe_bank, self._airframe_bank)
        self._yaw_rate += (yaw_rate_cmd - self._yaw_rate) * self._yaw_alpha
        thrust = self._k_1_s * (self._v_idle + throttle * (self._v_max - self._v_idle) - speed)
        # The flight path follows the attitude a little late (the lift of a new angle of
        # attack): PLANE_PATH_LAG_S.
        path = self._path + (pitch - self._path) * self._path_alpha
        self._path = path
        climb = _clamp(speed * math.sin(path), -self._max_descent, self._max_climb)
        if climb > 0.0 and self._u >= self.limits.max_altitude_m:
            climb = 0.0
        new_speed = speed + (thrust - G_M_S2 * climb / speed) * h
        # The stall margin is an airspeed (EAS, what the wing feels): higher up, a higher
        # true speed.
        v_min = self._v_min * self._tas_per_eas
        if new_speed < v_min:
            # The energy cannot pay for this climb at minimum speed: the nose drops.
            affordable = speed * (thrust - (v_min - speed) / h) / G_M_S2
            if climb > affordable:
                climb = max(affordable, -self._max_descent)
            new_speed = v_min
        elif new_speed > self._v_max:
            new_speed = self._v_max
        limit = self._max_turn_rad_s
        gamma = math.asin(_clamp(climb / new_speed, -1.0, 1.0))
        pull = (gamma - self._gamma) / h  # the flight path's rate, rad/s
        self._gamma = gamma
        bank_turn = efficiency * G_M_S2 * math.tan(roll) / new_speed
        turn = _clamp(bank_turn + self._yaw_rate, -limit, limit)
        if pull != 0.0:
            # The pull's share is the whole of it (SITL's course swings by tan(bank) times
            # its flight path's swing, 0.3-1.5 Hz), not the steady turn's efficiency, and
            # on top of the airframe's turn-rate limit, which is the steady turn's (SITL's
            # course turned at up to 50 deg/s at 0.85 Hz): within PLANE_PULL_MAX_G.
            most = PLANE_PULL_MAX_G * G_M_S2 / new_speed
            turn += math.tan(roll) * _clamp(pull, -most, most) / math.cos(gamma)
        yaw = self._yaw + turn * h
        if yaw >= math.pi:
            yaw -= _TAU
        elif yaw < -math.pi:
            yaw += _TAU
        horizontal = math.sqrt(max(new_speed * new_speed - climb * climb, 0.0))
        # It flies its airspeed through the air; the air carries it (0 in still air).
        vn = horizontal * math.cos(yaw) + self._air_n
        ve = horizontal * math.sin(yaw) + self._air_e
        self._n += vn * h
        self._e += ve * h
        up = self._u + climb * h
        if up > self.limits.max_altitude_m:
            up = self.limits.max_altitude_m
        self._roll, self._pitch, self._yaw = roll, pitch, yaw
        self._speed, self._vn, self._ve, self._vu = new_speed, vn, ve, climb
        self._u = up
        if up <= 0.0 and climb < 0.0:
            # Touchdown: rolling out along the heading, wings and nose level.
            self._touched_down(-climb)
            self._u = 0.0
            self._vu = 0.0
            self._roll = self._pitch = 0.0
            self._gamma = 0.0
            self._reset_roll_coupling()
            self._flying = False

    def _roll_on_ground(
        self, h: float, speed: float, yaw_rate_cmd: float, throttle: float, lift_off: bool
    ) -> None:
        if throttle > 0.05:
            speed += self._k_1_s * (throttle * self._v_max - speed) * h
        else:
            speed = max(speed - self.ground_decel_m_s2 * h, 0.0)
        speed = min(speed, self._v_max)
        # Tail-wheel steering with the rudder, effective once rolling.
        self._yaw_rate = yaw_rate_cmd * min(speed / 5.0, 1.0)
        yaw = _wrap_pi(self._yaw + self._yaw_rate * h)
        self._roll += -self._roll * self._roll_alpha
        self._pitch += -self._pitch * self._pitch_alpha
        vn, ve = speed * math.cos(yaw), speed * math.sin(yaw)
        self._n += vn * h
        self._e += ve * h
        self._yaw, self._speed, self._vn, self._ve, self._vu = yaw, speed, vn, ve, 0.0
        v_min = self._v_min * self._tas_per_eas  # the stall margin is an airspeed
        if lift_off and self.armed and speed >= v_min:
            self._flying = True
            self.touchdown_s = None
            self._speed = max(speed, v_min)


class Rover(SimulatedVehicle):
    """A ground vehicle: drives on the ground (up is always 0), steers within its turn rate.

    Steering follows its command through a first-order lag
    (``roll_time_constant_s``); full steering turns at ``max_turn_rate_deg_s``
    once rolling at ``full_steer_speed_m_s`` or faster (slower, proportionally
    less: a car cannot turn in place), never tighter than TURN_RADIUS and never
    beyond a lateral acceleration of ATC_TURN_MAX_G.

    GUIDED, AUTO and RTL drive at the leg speed (WP_SPEED, or RTL_SPEED for RTL when set,
    or DO_CHANGE_SPEED's; at least :data:`ROVER_MIN_SPEED_M_S`, never above
    ``max_speed_m_s``; the airframe's ``cruise_speed_m_s`` is not read, nor is
    ArduRover's CRUISE_SPEED). It sets off :data:`ROVER_START_DELAY_S` after a target
    reaches it at rest (SITL's speed controller winding up).

    GUIDED is ArduRover's own controller (GUID_OPTIONS 0: AR_WPNav's position-controller
    input shaping, :meth:`_psc_step`): a shaped target (position, velocity, acceleration)
    starts on the rover at its velocity when a target comes and the controller is not
    running, and is pulled toward the destination under one acceleration limit for its
    velocity vector (:func:`shape_pos_vel_accel_xy`); a new target while it runs only
    moves the destination, so a target sent while driving is reached by braking while
    the target's velocity turns, as ArduRover's is. The rover is asked for the shaped
    velocity plus :data:`ROVER_POS_P_1_S` times its lag (so one that fell behind crawls
    its last metres), and turns at the lateral acceleration asked over its speed. It is
    reached (MISSION_ITEM_REACHED) when the shaped target is at the destination and the
    rover within WP_RADIUS of it, and then stops where it is.

    AUTO and RTL steer at a turn rate proportional to the heading error, slowing while
    pointed away; they speed up at ATC_ACCEL_MAX and brake into the target on a
    square-root profile at :data:`ROVER_APPROACH_DECEL_FRACTION` of the deceleration limit
    (ATC_DECEL_MAX, ATC_ACCEL_MAX when 0): SITL's 5 m/s to a stop over about 8.7 s. They
    stop at the target and stay stopped (in their mode, as ArduRover's do); the target
    counts as reached within WP_RADIUS (ArduRover's), where a mission executor moves on.
    A target behind it within WP_RADIUS is reached where it is. Hold (and a guided mode
    entered with no target) stops where it is, braking at the deceleration limit. Manual
    modes: the steering channel steers, the throttle channel (centred) drives forward
    above trim and reverses below it, full stick meaning ``max_speed_m_s`` reached at up
    to ``accel_m_s2``. Roll and pitch are always 0. The throttle in the truth is signed
    (negative in reverse).
    """

    airframe_class = "rover"
    PARAM_DEFAULTS = ROVER_DEFAULT_PARAMS
    _MANUAL_MODES = frozenset({"MANUAL", "ACRO", "STEERING", "SIMPLE"})
    _HOLD_MODES = frozenset({"HOLD", "LOITER"})
    _RTL_MODES = frozenset({"RTL", "SMART_RTL"})
    _REFUSED_MODES = frozenset({"INITIALISING"})
    _CONTROL_NAMES = ("steering", "", "", "throttle")
    _THROTTLE_CENTRED = True

    #: Speed change limit in the manual modes (the motor's, an assumption), m/s^2.
    accel_m_s2: float = 2.5
    #: Speed from which full steering gives the full turn rate.
    full_steer_speed_m_s: float = 1.0
    #: Turn rate per radian of heading error, 1/s.
    heading_gain_1_s: float = 2.0
    #: Lowest speed while turning toward a target behind the rover.
    crawl_speed_m_s: float = 0.5

    def set_wind(self, wind: WindField | None) -> None:
        """Ignored: ArduPilot SITL's rover (SIM_Rover) takes no wind, and neither does this."""

    def _default_mode(self, autopilot: Mapping[str, Any]) -> str:
        """The mission schema's default start mode: manual for rovers."""
        return str(autopilot.get("manual_mode") or "")

    def _setup(self) -> None:
        self._speed = 0.0
        self._steer = 0.0
        self._tn, self._te = self._n, self._e
        self._arrived = True
        self._speed_set = False
        self._wind_up_s = 0.0
        # GUIDED: AR_PosControl's input-shaped target (position, velocity, acceleration,
        # north and east), live while ArduRover's controller would be.
        self._psc = False
        self._psn = self._pse = self._psvn = self._psve = self._psan = self._psae = 0.0
        self._psc_speed = 0.0  # ArduRover's desired speed (its own acceleration limit)
        self._an = self._ae = 0.0  # the rover's own acceleration, for a start (AHRS)
        self._capture()
        self._leg_speed = self._default_speed()

    def _capture(self) -> None:
        """Read ArduRover's parameters (only at a mode entry: ArduRover's own rule)."""
        p = self._params
        self._accel = max(p["ATC_ACCEL_MAX"], 0.1)
        self._decel = max(p["ATC_DECEL_MAX"], 0.0) or self._accel
        self._approach_decel = self._decel * ROVER_APPROACH_DECEL_FRACTION
        self._wp_radius = max(p["WP_RADIUS"], 0.1)
        self._lateral_accel = max(p["ATC_TURN_MAX_G"], 0.05) * G_M_S2
        self._turn_radius = max(p["TURN_RADIUS"], 0.0)
        # AR_WPNav::init and AR_PosControl: one limit for the shaped target's velocity
        # vector, the least of the speed limits and the turn's.
        self._psc_accel = min(self._accel, self._decel, self._lateral_accel)
        wp_accel = p.get("WP_ACCEL", 0.0)
        if wp_accel > 0.0:
            self._psc_accel = min(self._psc_accel, wp_accel)
        self._psc_jerk = max(p["WP_JERK"], 0.0) or min(self._accel, self._decel)

    def _default_speed(self) -> float:
        p = self._params
        speed = p["WP_SPEED"]
        if self._behaviour is ModeBehaviour.RTL and p["RTL_SPEED"] > 0.0:
            speed = p["RTL_SPEED"]
        return _clamp(speed, ROVER_MIN_SPEED_M_S, self.limits.max_speed_m_s)

    def _apply_params_now(self) -> None:
        self._capture()
        if not self._speed_set:
            self._leg_speed = self._default_speed()

    @property
    def target_reached(self) -> bool:
        """ArduRover's reached.

        In GUIDED, the shaped target at the destination and the rover within WP_RADIUS
        of it (AR_WPNav); otherwise stopped at the target, or within WP_RADIUS of it.
        """
        if self._command != _CMD_TARGET:
            return False
        if self._arrived or self._behaviour is ModeBehaviour.GUIDED:
            return self._arrived
        dn, de = self._tn - self._n, self._te - self._e
        return dn * dn + de * de <= self._wp_radius * self._wp_radius

    def _enter(self, behaviour: ModeBehaviour) -> None:
        self._capture()
        self._speed_set = False
        self._leg_speed = self._default_speed()
        self._command = _CMD_NONE
        self._psc = False
        if behaviour is ModeBehaviour.RTL:
            self._tn, self._te = self.home_m[0], self.home_m[1]
            self._arrived = False
            self._command = _CMD_TARGET
        else:
            self._tn, self._te = self._n, self._e
            self._arrived = True

    def _set_target(
        self, north_m: float, east_m: float, alt_m: float, speed_m_s: float | None
    ) -> None:
        # ArduRover takes new parameters only on entering a mode, not with a target.
        if speed_m_s is not None:
            self._set_speed(speed_m_s)
        if self._behaviour is ModeBehaviour.GUIDED and not self._psc:
            # AR_WPNav::set_desired_location_expect_fast_update: the position controller is
            # started afresh when it was not running (GUIDED just entered, or the last
            # target reached); while it runs, a new target only replaces the destination.
            self._psc_start()
        self._tn, self._te = north_m, east_m
        self._arrived = False
        self._command = _CMD_TARGET

    def _psc_start(self) -> None:
        """AR_PosControl::init: the shaped target on the rover, at its velocity and acceleration."""
        self._psc = True
        self._psn, self._pse = self._n, self._e
        self._psvn, self._psve = self._vn, self._ve
        self._psan, self._psae = self._an, self._ae
        self._psc_speed = self._speed  # AR_WPNav::update: from the speed it has

    def _psc_step(self, h: float) -> tuple[float, float]:
        """One step of ArduRover's GUIDED controller: the speed and turn rate it asks for.

        AR_WPNav::update_psc_input_shaping then AR_PosControl::update:

        - ``input_pos_target``: the shaped target moves on by its velocity and
          acceleration, and is pulled toward the destination by
          :func:`shape_pos_vel_accel_xy` (the leg speed, one acceleration limit for the
          velocity vector, WP_JERK);
        - reached once the shaped target is within 1 cm of the destination and the rover
          within WP_RADIUS of it (the controller then stops; a later target starts it
          afresh);
        - the velocity asked is the shaped velocity plus :data:`ROVER_POS_P_1_S` times the
          rover's lag behind the shaped position (square-root limited, the lag held to
          what the leg speed can close: the shaped target is dragged back when the rover
          falls further behind), capped at the leg speed; the acceleration asked,
          :data:`ROVER_VEL_P` times the velocity error plus the shaped acceleration;
        - the speed asked is that velocity's forward part, but not below the least of its
          length and the speed that turns within TURN_RADIUS at half ATC_TURN_MAX_G; it
          changes at ATC_ACCEL_MAX (ATC_DECEL_MAX slowing);
        - the turn rate is the acceleration's lateral part over that speed (never below
          :data:`ROVER_STEER_SPEED_MIN_M_S`). A target dead behind asks for none: the
          rover is turned right at :data:`ROVER_BEHIND_NUDGE` of the limit (a fit).
        """
        accel = self._psc_accel
        jerk = self._psc_jerk
        speed_max = self._leg_speed
        # input_pos_target: move the shaped target on, then shape it toward the destination.
        hh = 0.5 * h * h
        self._psn += self._psvn * h + self._psan * hh
        self._pse += self._psve * h + self._psae * hh
        self._psvn += self._psan * h
        self._psve += self._psae * h
        self._psan, self._psae = shape_pos_vel_accel_xy(
            self._tn - self._psn,
            self._te - self._pse,
            self._psvn,
            self._psve,
            self._psan,
            self._psae,
            speed_max,
            accel,
            jerk,
            h,
        )
        en, ee = self._psn - self._n, self._pse - self._e
        dn, de = self._tn - self._psn, self._te - self._pse
        if dn * dn + de * de < 1e-4 and en * en + ee * ee < self._wp_radius * self._wp_radius:
            self._arrived = True
            self._psc = False
            return 0.0, 0.0
        # AR_PosControl::update (AC_P_2D with its limits: the lag is held to the distance
        # from which the leg speed brakes to a stop).
        gain = ROVER_POS_P_1_S
        p_accel = min(accel, jerk / gain)
        lag_max = (
            speed_max / gain
            if speed_max < p_accel / gain
            else 0.5 * p_accel / (gain * gain) + speed_max * speed_max / (2.0 * p_accel)
        )
        lag = math.hypot(en, ee)
        if lag > lag_max:
            en, ee = en * lag_max / lag, ee * lag_max / lag
            self._psn, self._pse = self._n + en, self._e + ee
        wn, we = _sqrt_controller_xy(en, ee, gain, p_accel, h)
        wn, we = _limit_length(wn + self._psvn, we + self._psve, speed_max)
        an = ROVER_VEL_P * (wn - self._vn) + self._psan
        ae = ROVER_VEL_P * (we - self._ve) + self._psae
        cy, sy = math.cos(self._yaw), math.sin(self._yaw)
        forward = cy * wn + sy * we
        lateral = cy * ae - sy * an
        turn_speed = math.sqrt(0.5 * self._lateral_accel * self._turn_radius)
        wanted = max(min(math.hypot(wn, we), turn_speed), forward)
        if forward < 0.0 and abs(lateral) < ROVER_BEHIND_NUDGE * accel:
            lateral = ROVER_BEHIND_NUDGE * accel
        previous = self._psc_speed
        change = (self._decel if abs(wanted) < abs(previous) else self._accel) * h
        self._psc_speed = _clamp(wanted, previous - change, previous + change)
        rate = lateral / max(abs(self._psc_speed), ROVER_STEER_SPEED_MIN_M_S)
        return self._psc_speed, rate

    def _set_speed(self, speed_m_s: float) -> None:
        self._leg_speed = _clamp(speed_m_s, ROVER_MIN_SPEED_M_S, self.limits.max_speed_m_s)
        self._speed_set = True

    def auto_land(self) -> None:
        """A land item means nothing to a rover: it stops where it is."""
        if self._behaviour is ModeBehaviour.AUTO:
            self._tn, self._te = self._n, self._e
            self._arrived = True
            self._command = _CMD_NONE

    def _advance(self, h: float) -> None:
        behaviour = self._behaviour
        speed = self._speed
        yaw = self._yaw
        up = down = self.accel_m_s2
        if behaviour is ModeBehaviour.MANUAL:
            steer_cmd = self._rc_roll
            speed_cmd = self._rc_thr * self.limits.max_speed_m_s
        else:
            up, down = self._accel, self._decel
            steer_cmd = speed_cmd = 0.0
            if self._arrived or behaviour is ModeBehaviour.HOLD:
                pass
            elif behaviour is ModeBehaviour.GUIDED and not self.armed:
                # AR_WPNav does nothing while disarmed: armed, it starts afresh from here.
                self._psc = False
            elif behaviour is ModeBehaviour.GUIDED:
                if not self._psc:
                    self._psc_start()
                speed_cmd, rate = self._psc_step(h)
                # ArduRover limits the speed it asks for (ATC_ACCEL_MAX); the truck
                # follows it as quickly as its motor can (after a wind-up from rest).
                up = max(up, self.accel_m_s2)
                if not self._arrived:
                    # ArduRover's turn-rate controller steers for the rate it asks.
                    limit = self._max_turn_rad_s
                    reach = limit * _clamp(abs(speed) / self.full_steer_speed_m_s, 0.05, 1.0)
                    steer_cmd = _clamp(rate / reach, -1.0, 1.0) if limit > 0.0 else 0.0
            else:
                dn, de = self._tn - self._n, self._te - self._e
                distance = math.sqrt(dn * dn + de * de)
                error = _wrap_pi(math.atan2(de, dn) - yaw) if distance > 1e-9 else 0.0
                approach = sqrt_controller(
                    distance, ROVER_APPROACH_GAIN_1_S, self._approach_decel, h
                )
                if approach < ROVER_STOP_SPEED_M_S or (
                    distance <= self._wp_radius and abs(error) > _HALF_PI
                ):
                    self._arrived = True
                else:
                    limit = self._max_turn_rad_s
                    rate = _clamp(self.heading_gain_1_s * error, -limit, limit)
                    steer_cmd = rate / limit if limit > 0 else 0.0
                    speed_cmd = min(self._leg_speed, approach)
                    speed_cmd = max(
                        speed_cmd * math.cos(error), min(self.crawl_speed_m_s, speed_cmd)
                    )
            # From rest, the speed controller winds up before the rover moves.
            if speed_cmd > 0.0 and speed < ROVER_MIN_SPEED_M_S and self.armed:
                if self._wind_up_s < ROVER_START_DELAY_S:
                    self._wind_up_s += h
                    speed_cmd = 0.0
            elif speed_cmd <= 0.0:
                self._wind_up_s = 0.0
        if not self.armed:
            speed_cmd = 0.0
        if speed_cmd >= speed:
            speed += min(speed_cmd - speed, up * h)
        else:
            speed -= min(speed - speed_cmd, down * h)
        self._steer += (steer_cmd - self._steer) * self._roll_alpha
        limit = self._max_turn_rad_s
        if speed != 0.0:
            moving = abs(speed)
            lateral = self._lateral_accel / moving
            if lateral < limit:
                limit = lateral
            if self._turn_radius > 0.0 and moving < limit * self._turn_radius:
                limit = moving / self._turn_radius
        scale = _clamp(speed / self.full_steer_speed_m_s, -1.0, 1.0)
        turn = _clamp(self._steer * self._max_turn_rad_s * scale, -limit, limit)
        yaw += turn * h
        if yaw >= math.pi:
            yaw -= _TAU
        elif yaw < -math.pi:
            yaw += _TAU
        vn, ve = speed * math.cos(yaw), speed * math.sin(yaw)
        self._n += vn * h
        self._e += ve * h
        self._an, self._ae = (vn - self._vn) / h, (ve - self._ve) / h
        self._yaw, self._speed, self._vn, self._ve = yaw, speed, vn, ve
        max_speed = self.limits.max_speed_m_s
        self._act_roll = steer_cmd
        self._act_thr = speed_cmd / max_speed
        self._thr = speed / max_speed


_MODELS: dict[str, type[SimulatedVehicle]] = {
    "multirotor": Multirotor,
    "fixed_wing": FixedWing,
    "rover": Rover,
}


def make_vehicle(
    airframe: Mapping[str, Any],
    autopilot: Mapping[str, Any],
    channels: Mapping[str, ChannelLike | Mapping[str, Any]] | None,
    origin: Origin | tuple[float, float, float],
    start: Sequence[float],
    rng: random.Random,
    *,
    gps_noise_m: float = DEFAULT_GPS_NOISE_M,
    gps_vertical_noise_m: float | None = None,
    gps_rate_hz: float | None = None,
    heading_deg: float = 0.0,
    armed: bool = True,
    mode: str | None = None,
    rc_override_timeout_s: float | None = DEFAULT_RC_OVERRIDE_TIMEOUT_S,
) -> SimulatedVehicle:
    """Build the model for an airframe profile's class, flying an autopilot profile.

    Args:
        airframe: The resolved airframe profile (a compiled config's
            ``agent.hardware.airframe``): ``class`` and the limits.
        autopilot: The resolved autopilot profile (``agent.hardware.autopilot``):
            ``modes``, the mode roles, and ``channels`` unless given separately.
        channels: Channel name -> rc/servo number and pulse widths (a config's
            ``AgentConfig.channels`` or the raw mapping); None for the autopilot's.
        origin: The mission origin (an Origin or latitude, longitude, altitude).
        start: Start point (north_m, east_m[, up_m]) from the origin; up_m above 0
            starts an aircraft flying (a fixed wing at cruise speed, level; a
            multirotor hovering); rovers are always on the ground.
        rng: The vehicle's seeded generator (GPS errors); nothing else is random.
        gps_noise_m: Standard deviation of the GPS error on each horizontal axis.
        gps_vertical_noise_m: Standard deviation of the GPS altitude error; None:
            twice ``gps_noise_m`` (a receiver's vertical error is about twice its
            horizontal one: :data:`DEFAULT_GPS_VERTICAL_NOISE_M` by default, none for
            a noise-free GPS).
        gps_rate_hz: GPS fix rate; the autopilot profile's ``gps_rate_hz`` when None,
            else :data:`DEFAULT_GPS_RATE_HZ`.
        heading_deg: Heading at the start.
        armed: Armed at the start (the dry run arms a vehicle its pilot hands over in
            flight; one on the ground is armed later, through its autopilot).
        mode: Mode at the start; the hold mode for aircraft, the manual mode for
            rovers when None (the mission's ``sim.mode`` default).
        rc_override_timeout_s: How long an RC override lasts unless refreshed;
            None: until released.

    Raises:
        VehicleSetupError: The airframe class has no model, a limit is missing,
            the start mode is unknown or refused, or an airborne start is disarmed.
    """
    airframe_class = airframe.get("class")
    model = _MODELS.get(str(airframe_class))
    if model is None:
        raise VehicleSetupError(
            f"no vehicle model for airframe class {airframe_class!r}; "
            f"expected one of {', '.join(sorted(_MODELS))}"
        )
    if not isinstance(autopilot.get("modes"), Mapping) or not autopilot["modes"]:
        raise VehicleSetupError("the autopilot profile lists no modes")
    if len(start) not in (2, 3):
        raise VehicleSetupError(f"a start point is (north_m, east_m[, up_m]), not {start!r}")
    point = (float(start[0]), float(start[1]), float(start[2]) if len(start) == 3 else 0.0)
    if point[2] < 0.0:
        raise VehicleSetupError(f"a vehicle cannot start below the origin (up_m {point[2]:g})")
    if gps_rate_hz is None:
        profile_rate = autopilot.get("gps_rate_hz")
        gps_rate_hz = float(profile_rate) if profile_rate else DEFAULT_GPS_RATE_HZ
    where = origin if isinstance(origin, Origin) else Origin(*origin)
    if gps_vertical_noise_m is None:
        gps_vertical_noise_m = gps_noise_m * DEFAULT_GPS_VERTICAL_NOISE_M / DEFAULT_GPS_NOISE_M
    if channels is None:
        channels = autopilot.get("channels") or {}
    return model(
        limits=AirframeLimits.from_profile(airframe),
        autopilot=autopilot,
        channels=channels,
        origin=where,
        start_m=point,
        rng=rng,
        gps_noise_m=gps_noise_m,
        gps_vertical_noise_m=gps_vertical_noise_m,
        gps_rate_hz=gps_rate_hz,
        heading_deg=heading_deg,
        armed=armed,
        mode=mode,
        rc_override_timeout_s=rc_override_timeout_s,
    )


#: The model classes by airframe class, for documentation and tests.
MODELS: Mapping[str, type[SimulatedVehicle]] = _MODELS
