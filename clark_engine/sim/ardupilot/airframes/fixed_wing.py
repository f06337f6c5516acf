"""The fixed-wing model: :class:`FixedWing`, flown as ArduPlane flies.

Apart from the other airframes because everything in it is ArduPlane's: its parameter
defaults, the constants fitted to ArduPlane SITL (the turn's efficiency, the flight path's
lag, the launch, the landing), its L1 loiter and its energy model. What the airspeed is
(:mod:`~clark_engine.sim.ardupilot.airframes.atmosphere`) and how the sticks mix into the
automatic modes (:mod:`~clark_engine.sim.ardupilot.airframes.stick_mixing`) are modules of
their own.

Over 800 lines because :class:`FixedWing` is one model whose modes share one state and one
step (the L1 loiter and waypoint laws, the energy model and the launch read each other's
state), and each fitted constant carries the SITL measurement it stands for.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from typing import Final

from clark_engine.sim.ardupilot.airframes.atmosphere import PLANE_AIRSPEED_SENSOR_SCALE, eas2tas
from clark_engine.sim.ardupilot.airframes.base import (
    CMD_LAND,
    CMD_NONE,
    CMD_TAKEOFF,
    CMD_TARGET,
    G_M_S2,
    ModeBehavior,
    SimulatedVehicle,
)
from clark_engine.sim.ardupilot.airframes.control import HALF_PI, INF, TAU, clamp, wrap_pi
from clark_engine.sim.ardupilot.airframes.stick_mixing import (
    PLANE_RC_DEAD_ZONE_US,
    RollCoupling,
    StickPitchBandPass,
    stick_mix,
)
from clark_engine.sim.ardupilot.vehicle_model import LandedState

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


PLANE_TURN_EFFICIENCY: Final = 0.71
"""The share of a coordinated turn's rate (``g tan(bank) / V``) SITL's plane turns at for
its bank in the automatic modes. Measured in its LOITER (NAVL1_PERIOD 17, 15.2 m/s,
WP_LOITER_RAD 60): ATTITUDE's roll equal to NAV_CONTROLLER_OUTPUT's nav_roll, 25.0
degrees, on a 69.1-69.8 m circle, where 25 degrees would turn a 50.5 m one. ArduPlane's L1
loiter asks for the shortfall back in proportion to the distance outside the circle (its
PD term), so the circle settles outside WP_LOITER_RAD where the two balance: 92-93 m for
80 m at 22 m/s with NAVL1_PERIOD 15 (86.6 m at 15 m/s, 98.5 at 28, 101 at 30), 69-70 m
for 60 m at 15 m/s with 17 (:meth:`FixedWing.loiter_radius_m`)."""
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
    0). AUTO's NAV_WAYPOINT legs are the exception, as on ArduPlane: each flies the line
    from the previous waypoint by L1's waypoint law (:meth:`FixedWing.auto_waypoint`,
    :meth:`FixedWing._waypoint_roll`). Airspeed: AIRSPEED_CRUISE (or DO_CHANGE_SPEED's)
    within AIRSPEED_MIN..MAX and the airframe's limits, an equivalent airspeed as ArduPlane
    holds it: what the airspeed sensor reads (VFR_HUD), flown at :func:`eas2tas` times it
    through the air (:data:`PLANE_AIRSPEED_SENSOR_SCALE`). Altitude: climb rate proportional
    to the error within the limits, its changes slewed at :data:`PLANE_CLIMB_SLEW_M_S2`;
    throttle holds the speed and pays for the climb. The RC sticks are mixed in (ArduPlane's
    default STICK_MIXING, FBW style, Plane::stabilize_stick_mixing_fbw): the sticks read
    through their dead zones (RCn_DZ), past half stick steeper, times ROLL_LIMIT_DEG (pitch:
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
        cruise = clamp(limits.cruise_speed_m_s, self._v_min, self._v_max)
        self._airframe_bank = math.radians(limits.max_bank_deg if limits.max_bank_deg else 45.0)
        self._max_pitch = math.radians(self.max_pitch_deg)
        self._min_pitch = math.radians(self.min_pitch_deg)
        self._dead_zones_us = (PLANE_RC_DEAD_ZONE_US,) * 3
        self._nav_roll = self._nav_pitch = 0.0
        self._pitch_band_pass = StickPitchBandPass()
        self._coupling = RollCoupling()
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
        # AUTO's NAV_WAYPOINT leg, as ArduPlane keeps it (see auto_waypoint)
        self._leg = False  # flying a waypoint leg (update_waypoint), not the loiter
        self._leg_crosstrack = False  # auto_state.crosstrack: along the line from prev_WP
        self._next_wp_crosstrack = False  # auto_state.next_wp_crosstrack
        self._prev_n, self._prev_e = self._n, self._e  # prev_WP_loc
        self._turn_angle_deg = 90.0  # auto_state.next_turn_angle
        self._leg_outcome: tuple[bool, float] | None = None
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
        self._cruise = clamp(p["AIRSPEED_CRUISE"], self._speed_low, self._speed_high)
        self._loiter_rad = abs(p["WP_LOITER_RAD"])
        self._wp_radius = max(p["WP_RADIUS"], 1.0)
        period = max(p["NAVL1_PERIOD"], 1.0)
        damping = max(p["NAVL1_DAMPING"], 0.1)
        l1_period = period * damping
        self._l1_gain = TAU / l1_period
        self._l1_distance_s = l1_period / math.pi  # times the speed: L1's distance, m
        # AP_L1_Control::update_loiter's gains: the circle's PD (omega = 2 pi / period)
        # and the capture's L1 gain.
        omega = TAU / period
        self._loiter_kx = omega * omega
        self._loiter_kv = 2.0 * damping * omega
        self._capture_k = 4.0 * damping * damping
        # WP_LOITER_RAD's sign: clockwise (1) or counter-clockwise (-1), as ArduPlane's.
        self._direction = -1.0 if p["WP_LOITER_RAD"] < 0.0 else 1.0
        limit = math.radians(p["ROLL_LIMIT_DEG"]) if p["ROLL_LIMIT_DEG"] > 0.0 else INF
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
        (:meth:`Channel.deflection_dz`); a channel whose RCn_DZ the table lacks keeps
        :data:`PLANE_RC_DEAD_ZONE_US`.
        """
        super().configure(params)
        zones = []
        for channel in self._controls[:3]:
            value = params.get(f"RC{channel.rc}_DZ") if channel and channel.rc else None
            number = float(value) if value is not None else float(PLANE_RC_DEAD_ZONE_US)
            zones.append(int(clamp(number, 0.0, 200.0)) if math.isfinite(number) else 0)
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
        """The target within WP_RADIUS, the takeoff climb done, or landed.

        An AUTO waypoint leg (:meth:`auto_waypoint`) is done as ArduPlane's verify_nav_wp
        says: within its acceptance distance, or past the line's end.
        """
        command = self._command
        if command == CMD_TARGET and self._leg:
            return self._leg_done()
        if command == CMD_TARGET:
            dn, de = self._cn - self._n, self._ce - self._e
            return dn * dn + de * de <= self._wp_radius * self._wp_radius
        if command == CMD_TAKEOFF:
            return self._flying and self._sub != _P_CLIMB and self._sub != _P_LAUNCH
        if command == CMD_LAND:
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
        return clamp(alt_m, 0.0, self.limits.max_altitude_m)

    def _apply_params_now(self) -> None:
        self._capture()
        if not self._speed_set:
            self._target_speed = self._auto_speed()
        if self._behavior is ModeBehavior.RTL and self._params["RTL_RADIUS"] > 0.0:
            self._radius_param = abs(self._params["RTL_RADIUS"])
        else:
            self._radius_param = self._loiter_rad
            self._guided_shape()
        self._radius = self._loiter_radius(self._target_speed)
        if self._behavior is ModeBehavior.RTL:
            self._ch = self._clamp_altitude(self.home_m[2] + self._params["RTL_ALTITUDE"])

    def _disarmed(self) -> None:
        if not self._flying:
            self._launch_at_s = None

    def _enter(self, behavior: ModeBehavior) -> None:
        self._command = CMD_NONE
        self._launch_at_s = None
        # Mode::enter: "don't cross-track when starting a mission"
        self._next_wp_crosstrack = False
        self._leg = False
        if behavior is ModeBehavior.MANUAL:
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
        if behavior is ModeBehavior.RTL:
            self._cn, self._ce = home_n, home_e
            self._ch = self._clamp_altitude(home_u + self._params["RTL_ALTITUDE"])
            if self._params["RTL_RADIUS"] > 0.0:
                self._radius_param = abs(self._params["RTL_RADIUS"])
        elif behavior is ModeBehavior.TAKEOFF:
            altitude = self._clamp_altitude(home_u + self._params["TKOFF_ALT"])
            self._takeoff_alt = altitude
            if self._flying:
                self._loiter_ahead(self._n, self._e, self._yaw)
                self._ch = max(self._u, altitude)
            else:
                self._sub = _P_LAUNCH
        elif behavior is ModeBehavior.LAND and self._flying:
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
        self._target_speed = clamp(
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
        if self._behavior is not ModeBehavior.GUIDED:
            return
        self._target_ccw = ccw
        if math.isfinite(radius_m) and radius_m > 0.0:
            self._guided_radius_m = min(float(int(radius_m)), 65535.0)
            self._guided_ccw = ccw

    def _guided_shape(self) -> None:
        """In GUIDED, the radius and direction Plane::update_loiter flies (see guided_loiter)."""
        if self._behavior is not ModeBehavior.GUIDED:
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
        self._command = CMD_TARGET
        self._leg = False
        if self._flying:
            self._sub = _P_LOITER
        elif self._sub == _P_LAUNCH:
            self._launch_at_s = None
            self._sub = _P_LOITER

    def _set_speed(self, speed_m_s: float) -> None:
        self._target_speed = clamp(speed_m_s, self._v_min, self._v_max)
        self._speed_set = True
        self._radius = self._loiter_radius(self._target_speed)

    def auto_target(
        self, north_m: float, east_m: float, alt_m: float, speed_m_s: float | None
    ) -> bool:
        """AUTO's target (a loiter item's, RTL's): flown by the L1 loiter.

        As ArduPlane's set_next_WP, the waypoint after it tracks the line from it.
        """
        taken = super().auto_target(north_m, east_m, alt_m, speed_m_s)
        if taken:
            self._next_wp_crosstrack = True
        return taken

    def auto_waypoint(
        self, north_m: float, east_m: float, alt_m: float, next_course_rad: float | None
    ) -> bool:
        """AUTO's NAV_WAYPOINT, as ArduPlane flies it (do_nav_wp, verify_nav_wp).

        Plane::set_next_WP: the leg runs from the previous waypoint (prev_WP_loc, the
        target before this one) and is flown along that line by AP_L1_Control's
        update_waypoint (:meth:`_waypoint_roll`); the first leg after entering AUTO or
        after a takeoff does not cross-track: it flies at the waypoint from wherever the
        aircraft is, and its line for "passed" starts where the item began. Starting
        past the line's end, the line starts here. The leg is done within
        AP_L1_Control::turn_distance (WP_RADIUS, times EAS2TAS squared, at most L1's
        distance, scaled by the turn to the next leg, ``next_course_rad``, over 90
        degrees) or past the line's end (past_interval_finish_line).
        """
        prev_n, prev_e = self._cn, self._ce  # next_WP_loc before this one
        if not super().auto_target(north_m, east_m, alt_m, None):
            return False
        if self._next_wp_crosstrack:
            self._prev_n, self._prev_e = prev_n, prev_e
            self._leg_crosstrack = True
        else:
            self._prev_n, self._prev_e = self._n, self._e
            self._next_wp_crosstrack = True
            self._leg_crosstrack = False
        if self._line_proportion() >= 1.0:
            self._prev_n, self._prev_e = self._n, self._e
        # Plane::setup_turn_angle: the turn from this leg's course to the next's
        if next_course_rad is None:
            self._turn_angle_deg = 90.0
        else:
            course = math.atan2(self._ce - self._prev_e, self._cn - self._prev_n)
            self._turn_angle_deg = math.degrees(wrap_pi(next_course_rad - course))
        self._leg = True
        self._leg_outcome = None
        return True

    def waypoint_outcome(self) -> tuple[bool, float] | None:
        """The last waypoint leg's end: (passed the line's end, distance to the waypoint)."""
        return self._leg_outcome

    def _line_proportion(self) -> float:
        """Location::line_path_proportion: how far along prev_WP to next_WP the aircraft is."""
        ln, le = self._cn - self._prev_n, self._ce - self._prev_e
        squared = ln * ln + le * le
        if squared < 0.001:
            return 1.0
        return (ln * (self._n - self._prev_n) + le * (self._e - self._prev_e)) / squared

    def _leg_done(self) -> bool:
        """verify_nav_wp: within the turn distance, or past the line's end (records which)."""
        dn, de = self._cn - self._n, self._ce - self._e
        distance = math.sqrt(dn * dn + de * de)
        ground = max(math.hypot(self._vn, self._ve), 0.1)
        l1_m = self._l1_distance_s * ground
        eas2tas_sq = eas2tas(self.origin.alt_amsl_m + self._u) ** 2
        accept = min(max(self._params["WP_RADIUS"], 0.0) * eas2tas_sq, l1_m)
        turn = abs(self._turn_angle_deg)
        if turn < 90.0:
            accept *= turn / 90.0
        if distance <= accept:
            self._leg_outcome = (False, distance)
            return True
        if self._line_proportion() >= 1.0:
            self._leg_outcome = (True, distance)
            return True
        return False

    def _waypoint_roll(self) -> float:
        """Roll command of ArduPlane's L1 waypoint law (AP_L1_Control::update_waypoint).

        Along the line from A (prev_WP, or the aircraft itself when the leg does not
        cross-track) to B (the waypoint): ``Nu = Nu1 + Nu2``, Nu2 the ground velocity's
        angle to the line and Nu1 ``asin(crosstrack / L1)`` within 45 degrees (the
        capture angle), so an aircraft off the line turns onto it rather than cutting to
        B. Behind A (beyond L1 and outside a +-135 degree arc) it flies at A; 3 s past B,
        at B. Lateral acceleration ``K_L1 V^2 / L1 sin(Nu)``, L1 = V NAVL1_PERIOD
        NAVL1_DAMPING / pi, over the ground; roll ``atan(a / (g cos pitch))``. ArduPlane's
        small crosstrack integrator (NAVL1_XTRACK_I, within 5 degrees of the line) is not
        modelled: still air leaves no steady offset for it to take out.
        """
        n, e = self._n, self._e
        vn, ve = self._vn, self._ve
        ground = math.sqrt(vn * vn + ve * ve)
        if ground < 0.1:
            ground = 0.1
            vn, ve = ground * math.cos(self._yaw), ground * math.sin(self._yaw)
        l1_m = self._l1_distance_s * ground
        bn, be = self._cn, self._ce
        an, ae = (self._prev_n, self._prev_e) if self._leg_crosstrack else (n, e)
        abn, abe = bn - an, be - ae
        ab_length = math.sqrt(abn * abn + abe * abe)
        if ab_length < 1e-6:
            abn, abe = bn - n, be - e
            if math.sqrt(abn * abn + abe * abe) < 1e-6:
                abn, abe = math.cos(self._yaw), math.sin(self._yaw)
        norm = math.sqrt(abn * abn + abe * abe)
        abn, abe = abn / norm, abe / norm
        a_n, a_e = n - an, e - ae  # the aircraft from A
        crosstrack = a_n * abe - a_e * abn
        a_distance = math.sqrt(a_n * a_n + a_e * a_e)
        along = a_n * abn + a_e * abe
        if a_distance > l1_m and along / max(a_distance, 1.0) < -0.7071:
            un, ue = a_n / a_distance, a_e / a_distance  # behind A: at A
            nu = math.atan2(un * ve - ue * vn, -(vn * un + ve * ue))
        elif along > ab_length + ground * 3.0:
            b_n, b_e = n - bn, e - be  # 3 s past B: at B
            b_distance = max(math.sqrt(b_n * b_n + b_e * b_e), 1e-6)
            un, ue = b_n / b_distance, b_e / b_distance
            nu = math.atan2(un * ve - ue * vn, -(vn * un + ve * ue))
        else:
            nu2 = math.atan2(vn * abe - ve * abn, vn * abn + ve * abe)
            nu1 = math.asin(clamp(crosstrack / max(l1_m, 0.1), -0.7071, 0.7071))
            nu = nu1 + nu2
        last = self._last_nu
        limit = 0.9 * math.pi
        if abs(nu) > limit and abs(last) > limit and nu * last < 0.0:
            # _prevent_indecision: heading away from B, keep the side chosen
            bearing = math.atan2(be - e, bn - n)
            if abs(wrap_pi(bearing - self._yaw)) > math.radians(120.0):
                nu = last
        self._last_nu = nu
        nu = clamp(nu, -HALF_PI, HALF_PI)
        accel = self._capture_k * ground * ground / l1_m * math.sin(nu)
        pitch = clamp(self._pitch, -math.radians(60.0), math.radians(60.0))
        return math.atan(accel / (G_M_S2 * math.cos(pitch)))

    def auto_takeoff(self, alt_m: float) -> bool:
        """AUTO's takeoff item: launch and climb to ``alt_m`` above home.

        On the ground the launch starts on arming (at once when armed), as ArduPlane's
        AUTO with a takeoff item does; in the air it climbs there. False outside AUTO.
        """
        if self._behavior is not ModeBehavior.AUTO or not math.isfinite(alt_m):
            return False
        self._capture()
        self._takeoff_alt = self._clamp_altitude(self.home_m[2] + alt_m)
        self._command = CMD_TAKEOFF
        self._leg = False
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
        if self._behavior is not ModeBehavior.AUTO:
            return
        self._command = CMD_LAND
        self._leg = False
        if self._flying:
            self._capture()
            self._start_landing()

    # --- physics ----------------------------------------------------------------------

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
                    yaw_rate_cmd = self.course_gain_1_s * wrap_pi(self._course - self._yaw)
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
                roll_cmd = self._waypoint_roll() if self._leg else self._loiter_roll(speed)
                pitch_cmd = self._pitch_for(h, speed, self.altitude_gain_1_s * (self._ch - self._u))
                throttle = self._speed_throttle(speed)
            # FBW stick mixing (Plane::stabilize_stick_mixing_fbw): the sticks read
            # through their dead zones, past half stick steeper (to twice the limit).
            roll_cmd += stick_mix(self._mix_roll) * self._max_bank
            elevator = stick_mix(self._mix_pitch)
            stick = elevator * (self._max_pitch if elevator > 0.0 else -self._min_pitch)
            # ... whose pitch the aircraft answers as SITL's does (a fitted band-pass).
            pitch_cmd += self._pitch_band_pass.step(h, stick)
            yaw_rate_cmd = self._mix_yaw * self._rudder_rate
            if level:
                roll_cmd = 0.0
            lift_off = True
        if not self.armed:
            throttle = 0.0
        roll_cmd = clamp(roll_cmd, -self._max_bank, self._max_bank)
        pitch_cmd = clamp(pitch_cmd, self._min_pitch, self._max_pitch)
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
            if self._behavior is ModeBehavior.TAKEOFF:
                self._loiter_ahead(self._launch_n, self._launch_e, self._launch_yaw)
            else:
                self._cn, self._ce, self._ch = self._n, self._e, self._takeoff_alt
                self._sub = _P_LOITER
                # verify_takeoff: "don't cross-track on completion of takeoff"
                self._next_wp_crosstrack = False
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
            if abs(wrap_pi(bearing - self._yaw)) > math.radians(120.0):
                nu = last
        nu = clamp(nu, -HALF_PI, HALF_PI)
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
        pitch = clamp(self._pitch, -math.radians(60.0), math.radians(60.0))
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
        return self._l1_gain * math.sin(clamp(error, -HALF_PI, HALF_PI))

    def _course_roll(self, speed: float, course: float) -> float:
        """Roll command that holds a course."""
        limit = self._max_turn_rad_s
        if self._wind is not None:  # hold the track over the ground, crabbing into the wind
            ground, track = self._ground_track()
            turn = clamp(self._l1_turn(wrap_pi(course - track)), -limit, limit)
            return math.atan(turn * ground / G_M_S2)
        turn = clamp(self._l1_turn(wrap_pi(course - self._yaw)), -limit, limit)
        return math.atan(turn * speed / G_M_S2)

    def _pitch_for(self, h: float, speed: float, climb_m_s: float) -> float:
        """Pitch for a climb rate, the autopilot's climb command slewed (TECS in outline)."""
        want = clamp(climb_m_s, -self._max_descent, self._max_climb)
        step = PLANE_CLIMB_SLEW_M_S2 * h
        command = self._climb_cmd + clamp(want - self._climb_cmd, -step, step)
        self._climb_cmd = command
        return math.asin(clamp(command / speed, -1.0, 1.0))

    def _speed_throttle(self, speed: float) -> float:
        """Throttle that holds the target speed and pays for the current climb.

        The target is an equivalent airspeed (AIRSPEED_CRUISE, DO_CHANGE_SPEED), held as
        ArduPlane's TECS holds what its pitot reads: flown at :func:`eas2tas` times it
        (over :data:`PLANE_AIRSPEED_SENSOR_SCALE`, the sensor's reading).
        """
        accel = (self._target_speed * self._tas_per_eas - speed) / self.speed_time_constant_s
        accel += G_M_S2 * self._vu / speed
        level_speed = speed + accel / self._k_1_s
        return clamp((level_speed - self._v_idle) / (self._v_max - self._v_idle), 0.0, 1.0)

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
        also departs from its lagged demand by :class:`RollCoupling` of the pitch rate, as
        SITL's plane does; with the two together its circle tightens when its pitch swings
        at its resonance, as SITL's does.
        """
        coupling = self._coupling
        coupled = coupling.bank
        # The lagged demand is the roll itself unless a coupling is under way.
        lagged = coupling.roll_lagged if coupled != 0.0 or coupling.delayed else self._roll
        lagged += (roll_cmd - lagged) * self._roll_alpha
        coupling.roll_lagged = lagged
        pitch = self._pitch + (pitch_cmd - self._pitch) * self._pitch_alpha
        if efficiency != 1.0:
            drive = math.sin(lagged) * (pitch - self._pitch) / h
            coupled = coupling.step(h, drive)
        elif coupled != 0.0:
            coupling.reset()
            coupled = 0.0
        # Never beyond the airframe's bank (the class's promise; SITL's may be).
        roll = clamp(lagged + coupled, -self._airframe_bank, self._airframe_bank)
        self._yaw_rate += (yaw_rate_cmd - self._yaw_rate) * self._yaw_alpha
        thrust = self._k_1_s * (self._v_idle + throttle * (self._v_max - self._v_idle) - speed)
        # The flight path follows the attitude a little late (the lift of a new angle of
        # attack): PLANE_PATH_LAG_S.
        path = self._path + (pitch - self._path) * self._path_alpha
        self._path = path
        climb = clamp(speed * math.sin(path), -self._max_descent, self._max_climb)
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
        gamma = math.asin(clamp(climb / new_speed, -1.0, 1.0))
        pull = (gamma - self._gamma) / h  # the flight path's rate, rad/s
        self._gamma = gamma
        bank_turn = efficiency * G_M_S2 * math.tan(roll) / new_speed
        turn = clamp(bank_turn + self._yaw_rate, -limit, limit)
        if pull != 0.0:
            # The pull's share is the whole of it (SITL's course swings by tan(bank) times
            # its flight path's swing, 0.3-1.5 Hz), not the steady turn's efficiency, and
            # on top of the airframe's turn-rate limit, which is the steady turn's (SITL's
            # course turned at up to 50 deg/s at 0.85 Hz): within PLANE_PULL_MAX_G.
            most = PLANE_PULL_MAX_G * G_M_S2 / new_speed
            turn += math.tan(roll) * clamp(pull, -most, most) / math.cos(gamma)
        yaw = self._yaw + turn * h
        if yaw >= math.pi:
            yaw -= TAU
        elif yaw < -math.pi:
            yaw += TAU
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
            self._coupling.reset()
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
        yaw = wrap_pi(self._yaw + self._yaw_rate * h)
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
