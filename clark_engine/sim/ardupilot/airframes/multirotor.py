"""The multirotor model: :class:`Multirotor`, flown as ArduCopter flies.

Apart from the other airframes because everything in it is ArduCopter's: its parameter
defaults, the constants fitted to ArduCopter SITL (the speed ramps, the takeoff, the fall,
RTL's phases), and the controller's sub-states.

Over 800 lines because :class:`Multirotor` is one model whose modes share one state and one
step, and each fitted constant carries the SITL measurement it stands for.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from typing import ClassVar, Final

from clark_engine.sim.ardupilot.airframes.base import (
    CMD_LAND,
    CMD_NONE,
    CMD_TAKEOFF,
    CMD_TARGET,
    G_M_S2,
    SERVO_OUTPUT_COUNT,
    ModeBehavior,
    SimulatedVehicle,
)
from clark_engine.sim.ardupilot.airframes.control import INF, TAU, clamp, sqrt_controller, wrap_pi
from clark_engine.sim.ardupilot.vehicle_model import LandedState

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
"""RTL's loiter above home ends only with the nose within 2 degrees of its heading at
arming (ArduCopter's RESET_TO_ARMED_YAW): SITL hovered 5-7 s for a 5 s RTL_LOIT_TIME."""
COPTER_WIND_LEARN_S: Final = 1.0
"""Time constant over which a copter's position controller learns a changed wind (the
velocity controller's integrator, ArduCopter PSC_VELXY_I 1.0 / s with P 2.0): a steady
wind is held off after a few seconds, a gust or turbulence pushes it before that."""


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
        self._wp_speed = clamp(p["WPNAV_SPEED"] / 100.0, 0.2, limits.max_speed_m_s)
        accel = max(p["WPNAV_ACCEL"] / 100.0, 0.5)
        self._brake_xy = accel
        self._accel_xy = accel * COPTER_RAMP_FRACTION
        self._climb_max = clamp(p["WPNAV_SPEED_UP"] / 100.0, 0.1, limits.max_climb_rate_m_s)
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
        self._pilot_jerk = clamp(p["PSC_JERK_Z"], 1.0, 50.0)
        self._thr_dz = clamp(p["THR_DZ"] / 1000.0, 0.0, 0.3)

    def _default_speed(self) -> float:
        if self._behavior is ModeBehavior.RTL and self._params["RTL_SPEED"] > 0.0:
            return clamp(self._params["RTL_SPEED"] / 100.0, 0.2, self._max_speed)
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
        if command == CMD_TARGET:
            dn, de, du = self._tn - self._n, self._te - self._e, self._tu - self._u
            return dn * dn + de * de + du * du <= self._reach_m * self._reach_m
        if command == CMD_TAKEOFF:
            return (
                not self._landed
                and self._takeoff_at_s is None
                and abs(self._u - self._takeoff_alt) <= COPTER_TAKEOFF_DONE_M
            )
        if command == CMD_LAND:
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
        if self._behavior is not ModeBehavior.GUIDED or not self.armed or not self._landed:
            return False
        return self._begin_takeoff(alt_m, delay_s)

    def auto_takeoff(self, alt_m: float, delay_s: float = COPTER_AUTO_TAKEOFF_DELAY_S) -> bool:
        """AUTO's takeoff item (after MISSION_START): climb to ``alt_m`` above home.

        On the ground as :meth:`takeoff` (the climb after ``delay_s``); in the air, a
        climb there if below it. False outside AUTO or disarmed.
        """
        if self._behavior is not ModeBehavior.AUTO or not self.armed:
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
        self._command = CMD_TAKEOFF
        self._aim()
        return True

    def auto_land(self) -> None:
        """AUTO's land item: land where the copter is, as LAND does."""
        if self._behavior is not ModeBehavior.AUTO:
            return
        self._command = CMD_LAND
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
        self._command = CMD_TAKEOFF
        self._path_speed = 0.0
        return True

    def _disarmed(self) -> None:
        self._takeoff_at_s = None
        self._taking_off = False

    def _enter(self, behavior: ModeBehavior) -> None:
        self._capture()
        self._speed_set = False
        self._leg_speed = self._default_speed()
        self._takeoff_at_s = None
        self._taking_off = False
        self._landing = False
        self._command = CMD_NONE
        self._face_target = False
        self._pilot_climb = self.mode in self.PILOT_CLIMB_MODES
        self._pilot_az = 0.0
        self._z_braking = True  # a climb-rate mode first stops where it is going
        self._alt_hold = self._u
        # Automatic modes start by holding where the copter stops, as ArduCopter's do.
        stop_n, stop_e = self._stopping_point(self._brake_xy)
        self._tn, self._te, self._tu = stop_n, stop_e, self._u
        if behavior is ModeBehavior.MANUAL:
            self._sub = _C_MANUAL
        elif behavior is ModeBehavior.RTL:
            self._start_rtl(stop_n, stop_e)
        elif behavior is ModeBehavior.LAND:
            self._sub = _C_LAND
            self._landing = not self._landed
        elif behavior is ModeBehavior.HOLD:
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
        self._command = CMD_TARGET
        self._aim()
        # On the ground (also while spooling up for a takeoff) a target is stored and
        # the copter stays there; in a takeoff climb it ends the takeoff.
        self._takeoff_at_s = None
        self._taking_off = False

    def _set_speed(self, speed_m_s: float) -> None:
        # AC_WPNav::set_speed_xy takes any speed from WPNAV_WP_SPEED_MIN (20 cm/s) up:
        # WPNAV_SPEED is only the default (SITL flew 10.02 m/s asked with WPNAV_SPEED 5).
        # What caps it is the airframe: its lean limit against drag, max_speed_m_s here.
        self._leg_speed = clamp(speed_m_s, 0.2, self._max_speed)
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
            want = clamp(
                sqrt_controller(self._alt_hold - self._u, COPTER_Z_GAIN_1_S, self._brake_z, h),
                -self._pilot_down,
                self._pilot_up,
            )
            step = self._pilot_accel * h
            change = clamp(want - self._vu, -step, step)
        else:
            self._alt_hold = self._u + self._vu * h
            error = (rate or 0.0) - self._vu
            jerk = self._pilot_jerk
            accel_want = math.copysign(
                min(self._pilot_accel, math.sqrt(2.0 * jerk * abs(error))), error
            )
            accel = self._pilot_az + clamp(accel_want - self._pilot_az, -jerk * h, jerk * h)
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
                    rate = clamp(
                        sqrt_controller(above, 1.0, self._accel_z, h),
                        self._land_speed,
                        self._land_speed_high,
                    )
                step_z = self._accel_z * h
                change_z = clamp(-rate - vu, -step_z, step_z)
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
                top = ramp = brake = INF
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
            dvu = clamp(want_u - vu, -step, step)
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
            error = wrap_pi(self._armed_yaw - yaw)
        elif sub == _C_CIRCLE or (self._face_target and dn * dn + de * de > 4.0):
            error = wrap_pi(math.atan2(de, dn) - yaw)
        else:
            error = 0.0
        if error:
            limit = self._max_turn_rad_s
            yaw = wrap_pi(yaw + clamp(2.0 * error, -limit, limit) * h)
            self._yaw = yaw
        self._attitude(h, dvn / h, dve / h, accel_up)

    def _circle_velocity(self, h: float) -> tuple[float, float]:
        """The velocity that flies ArduCopter's circle (feed-forward plus position)."""
        step = self._circle_accel * h
        self._circle_rate += clamp(self._circle_rate_max - self._circle_rate, -step, step)
        angle = self._circle_angle + self._circle_rate * h
        if angle >= math.pi:
            angle -= TAU
        elif angle < -math.pi:
            angle += TAU
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
            if done and abs(wrap_pi(self._yaw - self._armed_yaw)) <= (COPTER_RTL_YAW_TOLERANCE_RAD):
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
        pitch_cmd = clamp(-math.atan(forward / G_M_S2), -lean, lean)
        roll_cmd = clamp(math.atan(right / G_M_S2), -lean, lean)
        self._roll += (roll_cmd - self._roll) * self._roll_alpha
        self._pitch += (pitch_cmd - self._pitch) * self._pitch_alpha
        self._thr = clamp(
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
        yaw = wrap_pi(self._yaw + self._rc_yaw * self._max_turn_rad_s * h)
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
        self._thr = clamp(thrust / (math.cos(self._roll) * math.cos(self._pitch)), 0.0, 1.0)
