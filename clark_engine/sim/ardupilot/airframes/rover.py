"""The ground vehicle model: :class:`Rover`, driven as ArduRover drives.

Apart from the other airframes because everything in it is ArduRover's: its parameter
defaults, the constants fitted to ArduRover SITL (the approach, the start delay, the
position controller's gains) and GUIDED's position-controller input shaping.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from typing import Any, Final

from clark_engine.sim.ardupilot.airframes.base import (
    CMD_NONE,
    CMD_TARGET,
    G_M_S2,
    ModeBehavior,
    SimulatedVehicle,
)
from clark_engine.sim.ardupilot.airframes.control import (
    HALF_PI,
    TAU,
    clamp,
    limit_length,
    shape_pos_vel_accel_xy,
    sqrt_controller,
    sqrt_controller_xy,
    wrap_pi,
)
from clark_engine.sim.wind import WindField

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
        if self._behavior is ModeBehavior.RTL and p["RTL_SPEED"] > 0.0:
            speed = p["RTL_SPEED"]
        return clamp(speed, ROVER_MIN_SPEED_M_S, self.limits.max_speed_m_s)

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
        if self._command != CMD_TARGET:
            return False
        if self._arrived or self._behavior is ModeBehavior.GUIDED:
            return self._arrived
        dn, de = self._tn - self._n, self._te - self._e
        return dn * dn + de * de <= self._wp_radius * self._wp_radius

    def _enter(self, behavior: ModeBehavior) -> None:
        self._capture()
        self._speed_set = False
        self._leg_speed = self._default_speed()
        self._command = CMD_NONE
        self._psc = False
        if behavior is ModeBehavior.RTL:
            self._tn, self._te = self.home_m[0], self.home_m[1]
            self._arrived = False
            self._command = CMD_TARGET
        else:
            self._tn, self._te = self._n, self._e
            self._arrived = True

    def _set_target(
        self, north_m: float, east_m: float, alt_m: float, speed_m_s: float | None
    ) -> None:
        # ArduRover takes new parameters only on entering a mode, not with a target.
        if speed_m_s is not None:
            self._set_speed(speed_m_s)
        if self._behavior is ModeBehavior.GUIDED and not self._psc:
            # AR_WPNav::set_desired_location_expect_fast_update: the position controller is
            # started afresh when it was not running (GUIDED just entered, or the last
            # target reached); while it runs, a new target only replaces the destination.
            self._psc_start()
        self._tn, self._te = north_m, east_m
        self._arrived = False
        self._command = CMD_TARGET

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
        wn, we = sqrt_controller_xy(en, ee, gain, p_accel, h)
        wn, we = limit_length(wn + self._psvn, we + self._psve, speed_max)
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
        self._psc_speed = clamp(wanted, previous - change, previous + change)
        rate = lateral / max(abs(self._psc_speed), ROVER_STEER_SPEED_MIN_M_S)
        return self._psc_speed, rate

    def _set_speed(self, speed_m_s: float) -> None:
        self._leg_speed = clamp(speed_m_s, ROVER_MIN_SPEED_M_S, self.limits.max_speed_m_s)
        self._speed_set = True

    def auto_land(self) -> None:
        """A land item means nothing to a rover: it stops where it is."""
        if self._behavior is ModeBehavior.AUTO:
            self._tn, self._te = self._n, self._e
            self._arrived = True
            self._command = CMD_NONE

    def _advance(self, h: float) -> None:
        behavior = self._behavior
        speed = self._speed
        yaw = self._yaw
        up = down = self.accel_m_s2
        if behavior is ModeBehavior.MANUAL:
            steer_cmd = self._rc_roll
            speed_cmd = self._rc_thr * self.limits.max_speed_m_s
        else:
            up, down = self._accel, self._decel
            steer_cmd = speed_cmd = 0.0
            if self._arrived or behavior is ModeBehavior.HOLD:
                pass
            elif behavior is ModeBehavior.GUIDED and not self.armed:
                # AR_WPNav does nothing while disarmed: armed, it starts afresh from here.
                self._psc = False
            elif behavior is ModeBehavior.GUIDED:
                if not self._psc:
                    self._psc_start()
                speed_cmd, rate = self._psc_step(h)
                # ArduRover limits the speed it asks for (ATC_ACCEL_MAX); the truck
                # follows it as quickly as its motor can (after a wind-up from rest).
                up = max(up, self.accel_m_s2)
                if not self._arrived:
                    # ArduRover's turn-rate controller steers for the rate it asks.
                    limit = self._max_turn_rad_s
                    reach = limit * clamp(abs(speed) / self.full_steer_speed_m_s, 0.05, 1.0)
                    steer_cmd = clamp(rate / reach, -1.0, 1.0) if limit > 0.0 else 0.0
            else:
                dn, de = self._tn - self._n, self._te - self._e
                distance = math.sqrt(dn * dn + de * de)
                error = wrap_pi(math.atan2(de, dn) - yaw) if distance > 1e-9 else 0.0
                approach = sqrt_controller(
                    distance, ROVER_APPROACH_GAIN_1_S, self._approach_decel, h
                )
                if approach < ROVER_STOP_SPEED_M_S or (
                    distance <= self._wp_radius and abs(error) > HALF_PI
                ):
                    self._arrived = True
                else:
                    limit = self._max_turn_rad_s
                    rate = clamp(self.heading_gain_1_s * error, -limit, limit)
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
        scale = clamp(speed / self.full_steer_speed_m_s, -1.0, 1.0)
        turn = clamp(self._steer * self._max_turn_rad_s * scale, -limit, limit)
        yaw += turn * h
        if yaw >= math.pi:
            yaw -= TAU
        elif yaw < -math.pi:
            yaw += TAU
        vn, ve = speed * math.cos(yaw), speed * math.sin(yaw)
        self._n += vn * h
        self._e += ve * h
        self._an, self._ae = (vn - self._vn) / h, (ve - self._ve) / h
        self._yaw, self._speed, self._vn, self._ve = yaw, speed, vn, ve
        max_speed = self.limits.max_speed_m_s
        self._act_roll = steer_cmd
        self._act_thr = speed_cmd / max_speed
        self._thr = speed / max_speed
