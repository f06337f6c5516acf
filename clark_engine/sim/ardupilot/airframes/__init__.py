"""The simulated ArduPilot's point-mass airframes for the dry run: multirotor, fixed wing, rover.

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

The modules, one concept each (what every model shares, then one per airframe, then the
pieces they are built from):

- ``base``: :class:`SimulatedVehicle`, what every model shares (modes, arming, ArduPilot's
  parameters, RC inputs and overrides, servo outputs, the GPS receiver and the estimate,
  the truth), the shared constants, :class:`GpsFix` and :class:`ModeBehavior`.
- ``multirotor``, ``fixed_wing``, ``rover``: one model each (:class:`Multirotor`,
  :class:`FixedWing`, :class:`Rover`), with the ArduPilot defaults it reads and the
  constants fitted to that firmware's SITL.
- ``factory``: :func:`make_vehicle`, the model for an airframe profile's class.
- ``profile``: the hardware profile as the models read it: the airframe's limits
  (:class:`AirframeLimits`), the control channels' pulse ranges, and the error a profile
  that cannot be flown raises.
- ``control``: ArduPilot's control maths (AP_Math control.cpp: the square-root controller,
  the jerk-limited shaping of a position target), which the models fly.
- ``atmosphere``: the standard atmosphere and SITL's airspeed sensor, how the equivalent
  airspeed ArduPlane holds becomes a true one.
- ``stick_mixing``: ArduPlane's stick mixing in its automatic modes and SITL's plane's
  fitted answer to it (the pitch's band-pass, the bank's coupling to the pitch).
"""
