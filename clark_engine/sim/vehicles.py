"""Point-mass vehicle models for the dry run: multirotor, fixed wing and rover.

Each model is a :class:`~clark_engine.sim.model.VehicleModel`: the physics and
the flight-mode logic of one vehicle, limited by its airframe profile, with no
knowledge of MAVLink. They are point masses with first-order attitude dynamics:
enough to make a behaviour's commands visible (a guided leg flies to its point,
an aileron doublet rolls the aircraft, a rover stops at its waypoint) and cheap
enough that a 50-vehicle dry run at 50 Hz runs far faster than real time. They
are not flight-dynamics models: no wind, no aerodynamic coefficients, no
motor or battery model. Every gain and constant below that is not in the
profile is an ArduPilot default or a stated assumption.

Conventions:
    Local frame north/east/up in metres from the mission origin; angles are
    radians inside, degrees in :class:`~clark_engine.sim.model.Truth`. Yaw is
    in (-180, 180] (MAVLink ATTITUDE), heading is the same nose direction in
    [0, 360) (what ArduPilot reports in VFR_HUD and GLOBAL_POSITION_INT). RC
    polarity is ArduPilot's: a pulse above trim rolls right, pitches the nose
    UP (the pitch stick pulled back), yaws right, steers right, and on a
    centred rover throttle drives forward.

Mode classification (ArduPilot mode names from the autopilot profile; the
profile's ``guided_mode``, ``hold_mode``, ``rtl_mode`` and ``manual_mode``
roles come first, then the names below):

=========== ================================ ======================= ==================
behaviour   multirotor (ArduCopter)          fixed wing (ArduPlane)  rover (ArduRover)
=========== ================================ ======================= ==================
manual      STABILIZE ACRO RATE_ACRO         MANUAL STABILIZE        MANUAL ACRO
            ALT_HOLD SPORT DRIFT POSHOLD     TRAINING ACRO FBWA      STEERING SIMPLE
            FLOWHOLD                         FBWB CRUISE AUTOTUNE
guided      GUIDED                           GUIDED                  GUIDED
hold        LOITER BRAKE                     LOITER                  HOLD LOITER
rtl         RTL SMART_RTL AUTO_RTL           RTL                     RTL SMART_RTL
land        LAND                             (none)                  (none)
refused     (none)                           INITIALISING, Q modes   INITIALISING
=========== ================================ ======================= ==================

Every other mode of the profile (AUTO with no mission, CIRCLE, TAKEOFF, FOLLOW,
THROW, ...) is accepted and flown as the hold mode: the model has no mission,
no follow target and no launch detection, so it does what a careful pilot
expects of an unmodelled mode, stay put. ``unsimulated_modes`` lists them.
ArduPlane refuses its Q (quadplane) modes on an aircraft without VTOL motors
and nobody can select INITIALISING, so the models refuse them too.

Arming: a vehicle on the ground starts disarmed or armed as its builder says
(the dry run's default is armed, as the mission's ``sim.armed`` says); a
vehicle that starts in the air must start armed. Disarming is refused while
airborne (ArduCopter refuses it unless forced; the model has no force). A
disarmed vehicle's motors are stopped: on the ground it does not move.
ArduCopter's LAND disarms on touchdown, and so does the model.

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
"""

from __future__ import annotations

import math
import random
from abc import abstractmethod
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from enum import Enum
from typing import Any, ClassVar, NamedTuple, Protocol

from clark_engine.errors import ClarkError
from clark_engine.mission.geo import EARTH_RADIUS_M, Origin
from clark_engine.sim.model import Truth, VehicleModel

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
#: Standard deviation of the GPS altitude error: GPS vertical error is typically
#: about twice the per-axis horizontal one.
DEFAULT_GPS_VERTICAL_NOISE_M = 1.0
#: ArduPilot's RC_OVERRIDE_TIME default: an override not refreshed lapses.
DEFAULT_RC_OVERRIDE_TIMEOUT_S = 3.0
#: Pulse width reported for an RC channel the profile does not map (receiver centre).
UNMAPPED_RC_US = 1500

_TAU = 2.0 * math.pi
_HALF_PI = 0.5 * math.pi


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
    HOLD = "hold"
    """Stay where the mode was entered (loiter around it, fixed wing)."""
    RTL = "rtl"
    """Return to the start point and hold there."""
    LAND = "land"
    """Descend where the mode was entered and disarm on touchdown (multirotor)."""


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
        cruise_speed_m_s: Speed the autopilot flies when no speed is requested.
        max_speed_m_s: Never exceeded (horizontal speed; airspeed, fixed wing).
        min_speed_m_s: Never undershot while flying (fixed wing stall margin).
        max_climb_rate_m_s: Never exceeded upward.
        max_descent_rate_m_s: Never exceeded downward.
        max_turn_rate_deg_s: Never exceeded yaw rate.
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


class SimulatedVehicle(VehicleModel):
    """What every model shares: modes, arming, RC inputs, servo outputs, GPS, truth.

    Subclasses supply the physics (``_advance``) and what entering a mode sets up
    (``_enter``). Construct them through :func:`make_vehicle`.

    Attributes:
        modes: Mode name -> ArduPilot custom_mode number, from the autopilot profile.
        mode: The current mode's name.
        armed: True when the motors are armed.
        limits: The airframe's limits.
        origin: The mission origin (latitude, longitude, altitude of 0 m up).
        start_m: The start point (north, east, up), where RTL returns.
        time_s: Simulated time since the vehicle was built.
        unsimulated_modes: Modes of the profile flown as the hold mode (see module doc).
        roll_time_constant_s: First-order lag of roll behind its command.
        pitch_time_constant_s: First-order lag of pitch behind its command.
    """

    airframe_class: ClassVar[str] = ""
    _MANUAL_MODES: ClassVar[frozenset[str]] = frozenset()
    _HOLD_MODES: ClassVar[frozenset[str]] = frozenset()
    _RTL_MODES: ClassVar[frozenset[str]] = frozenset()
    _LAND_MODES: ClassVar[frozenset[str]] = frozenset()
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

        # State (subclasses add their own).
        up = start_m[2] if self.airframe_class != "rover" else 0.0
        self.start_m = (float(start_m[0]), float(start_m[1]), float(up))
        self._n, self._e, self._u = self.start_m
        self._vn = self._ve = self._vu = 0.0
        self._roll = self._pitch = 0.0
        self._yaw = _wrap_pi(math.radians(heading_deg))
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

        # GPS.
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
            autopilot.get("manual_mode"): ModeBehaviour.MANUAL,
        }
        behaviours: dict[str, ModeBehaviour] = {}
        unsimulated: set[str] = set()
        for name in self.modes:
            if name in roles:
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
        for _ in range(count):
            advance(h)
        self.time_s += dt_s
        if self.time_s >= self._next_fix_s:
            self._take_fix()

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
        target is kept, a hold point is not moved.
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

    def arm(self, armed: bool) -> bool:
        """Arm or disarm; disarming in the air is refused (False)."""
        if not armed and self.airborne:
            return False
        self.armed = armed
        return True

    def goto(self, lat_deg: float, lon_deg: float, alt_m: float, speed_m_s: float | None) -> bool:
        """Set the guided target; refused (False) outside the guided mode, as ArduPilot does.

        Args:
            lat_deg: Target latitude.
            lon_deg: Target longitude.
            alt_m: Target altitude above the origin; clamped to the airframe's
                ``max_altitude_m`` (and for a fixed wing, raised to its lowest
                automatic altitude); ignored by rovers.
            speed_m_s: Requested speed, clamped to the airframe's limits; None or 0
                for the cruise speed.
        """
        if self._behaviour is not ModeBehaviour.GUIDED:
            return False
        if not all(math.isfinite(v) for v in (lat_deg, lon_deg, alt_m)):
            return False
        if speed_m_s is not None and not math.isfinite(speed_m_s):
            return False
        north = (lat_deg - self.origin.lat_deg) * self._m_per_deg_lat
        east = (lon_deg - self.origin.lon_deg) * self._m_per_deg_lon
        alt = min(alt_m, self.limits.max_altitude_m)
        speed = self._speed_request(speed_m_s)
        self._set_target(north, east, alt, speed)
        return True

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
        """True while flying (disarming is refused then)."""
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

    def takeoff(self, alt_m: float) -> bool:
        """Take off to ``alt_m`` (MAV_CMD_NAV_TAKEOFF); refused unless the model supports it."""
        return False

    def gps_fix(self) -> GpsFix:
        """The latest GPS fix: the true position at the fix time plus Gaussian error.

        Fixes are taken at the GPS rate (every ``1 / gps_rate_hz`` s of simulated time,
        the first at time 0) and held in between, as a receiver's are. The errors are
        independent between fixes and drawn from the vehicle's seeded generator, so
        the same seed gives the same fixes.
        """
        return self._fix

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
        north = self._n + (gauss(0.0, sigma) if sigma else 0.0)
        east = self._e + (gauss(0.0, sigma) if sigma else 0.0)
        up = self._u + (gauss(0.0, sigma_up) if sigma_up else 0.0)
        self._fix = GpsFix(
            self.origin.lat_deg + north / self._m_per_deg_lat,
            self.origin.lon_deg + east / self._m_per_deg_lon,
            up,
        )
        # The fix grid is k * period; the small margin keeps float accumulation of
        # the simulator's steps (0.02 * 10 = 0.19999...) from delaying a fix a step.
        index = math.floor(self.time_s / self._gps_period_s + 1e-6)
        self._fix_time_s = self.time_s
        self._next_fix_s = (index + 1) * self._gps_period_s - 1e-9

    def _speed_request(self, speed_m_s: float | None) -> float:
        limits = self.limits
        if speed_m_s is None or speed_m_s <= 0.0:
            return limits.cruise_speed_m_s
        return _clamp(speed_m_s, limits.min_speed_m_s, limits.max_speed_m_s)

    def _stopping_point(self, accel_m_s2: float) -> tuple[float, float]:
        """Where braking at ``accel_m_s2`` from the current velocity ends (ArduPilot's)."""
        speed = math.hypot(self._vn, self._ve)
        reach = speed / (2.0 * accel_m_s2)
        return self._n + self._vn * reach, self._e + self._ve * reach

    def _airspeed(self, ground_speed_m_s: float) -> float:
        return ground_speed_m_s

    # --- subclass hooks ---------------------------------------------------------------

    @abstractmethod
    def _advance(self, h: float) -> None:
        """Integrate one sub-step of ``h`` seconds in the current mode."""

    @abstractmethod
    def _enter(self, behaviour: ModeBehaviour) -> None:
        """Set up a newly entered mode (hold point, guided target, RTL target)."""

    @abstractmethod
    def _set_target(self, north_m: float, east_m: float, alt_m: float, speed_m_s: float) -> None:
        """Take a new guided target (local frame, altitude clamped, speed limited)."""


class Multirotor(SimulatedVehicle):
    """A multirotor: hovers, leans to accelerate, climbs and descends within its limits.

    Automatic modes (guided, hold, RTL, land) follow ArduCopter's position
    controller in outline: the desired velocity is the square-root controller's
    braking profile toward the target (P gain 1/s near it), capped at the
    requested speed (cruise, ArduCopter's WPNAV_SPEED, when none) and at the
    climb/descent limits; the velocity follows it with at most 2.5 m/s^2
    (WPNAV_ACCEL, PILOT_ACCEL_Z). So it stops at a target without overshoot.
    Roll and pitch are the lean angles that produce the commanded acceleration
    (plus air drag), through a first-order lag; the nose turns toward the target
    at up to ``max_turn_rate_deg_s`` while more than 2 m away.

    Manual modes fly the sticks as STABILIZE does: roll and pitch sticks set the
    lean angle (full stick = the max lean), the lean accelerates the vehicle
    (``g * tan(lean)``) against linear drag sized so full lean settles at
    ``max_speed_m_s``; the yaw stick sets the yaw rate; the throttle stick sets
    the climb rate around mid stick (10 % dead band, ArduCopter's THR_DZ), so
    mid stick hovers and minimum throttle descends and stays on the ground.

    On the ground a multirotor stays put unless armed and either told to climb
    (throttle above mid in a manual mode) or given a guided target (or takeoff)
    above it: a guided goto from the ground is flown as takeoff then goto, so a
    mission needs no separate takeoff step. Hold, RTL and land modes never take
    off. LAND descends at the descent limit above 10 m and 0.5 m/s below
    (ArduCopter LAND_SPEED) and disarms on touchdown. RTL climbs to at least
    15 m (ArduCopter RTL_ALT), returns over the start point and holds there
    (ArduCopter would land; RTL_ALT_FINAL > 0 holds as the model does).
    """

    airframe_class = "multirotor"
    _MANUAL_MODES = frozenset(
        {"STABILIZE", "ACRO", "RATE_ACRO", "ALT_HOLD", "SPORT", "DRIFT", "POSHOLD", "FLOWHOLD"}
    )
    _HOLD_MODES = frozenset({"LOITER", "BRAKE"})
    _RTL_MODES = frozenset({"RTL", "SMART_RTL", "AUTO_RTL"})
    _LAND_MODES = frozenset({"LAND"})
    _CONTROL_NAMES = ("roll", "pitch", "yaw", "throttle")

    #: Horizontal acceleration limit in automatic modes (ArduCopter WPNAV_ACCEL).
    accel_xy_m_s2: float = 2.5
    #: Vertical acceleration limit (ArduCopter PILOT_ACCEL_Z / PSC_JERK_Z shaping).
    accel_z_m_s2: float = 2.5
    #: Position P gain, 1/s (ArduCopter PSC_POSXY_P and PSC_POSZ_P).
    position_gain_1_s: float = 1.0
    #: Lean angle when the profile gives none (ArduCopter ANGLE_MAX).
    default_max_lean_deg: float = 30.0
    #: Throttle that hovers, reported in Truth.throttle_pct.
    hover_throttle: float = 0.5
    #: ArduCopter RTL_ALT.
    rtl_altitude_m: float = 15.0
    #: ArduCopter LAND_SPEED and LAND_ALT_LOW.
    land_speed_m_s: float = 0.5
    land_slow_below_m: float = 10.0
    #: Motors on outputs 1..4 (a quad, as the profiles' only multirotor is).
    motor_count: int = 4

    def _default_mode(self, autopilot: Mapping[str, Any]) -> str:
        return str(autopilot.get("hold_mode") or "")

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
        self._max_climb = limits.max_climb_rate_m_s
        self._max_descent = limits.max_descent_rate_m_s
        # Linear drag so that full lean settles at the maximum speed.
        self._drag_1_s = G_M_S2 * math.tan(self._max_lean_rad) / self._max_speed
        self._landed = self._u <= 0.0
        self._tn, self._te, self._tu = self._n, self._e, self._u
        self._target_speed = limits.cruise_speed_m_s
        self._face_target = False
        if not self._landed:
            self._thr = self.hover_throttle
            # A pilot who is flying holds mid throttle (hover), not the minimum.
            throttle = self._controls[3]
            if throttle is not None and throttle.rc is not None:
                self._pilot_us[throttle.rc - 1] = (throttle.min_us + throttle.max_us) // 2

    @property
    def airborne(self) -> bool:
        """True unless on the ground."""
        return not self._landed

    def takeoff(self, alt_m: float) -> bool:
        """Climb straight up to ``alt_m`` in the guided mode (armed, on the ground)."""
        if self._behaviour is not ModeBehaviour.GUIDED or not self.armed or not self._landed:
            return False
        if not math.isfinite(alt_m) or alt_m <= 0.0:
            return False
        self._tn, self._te = self._n, self._e
        self._tu = min(alt_m, self.limits.max_altitude_m)
        return True

    def _enter(self, behaviour: ModeBehaviour) -> None:
        stop_n, stop_e = self._stopping_point(self.accel_xy_m_s2)
        self._target_speed = self.limits.cruise_speed_m_s
        self._face_target = False
        if behaviour is ModeBehaviour.RTL:
            self._tn, self._te = self.start_m[0], self.start_m[1]
            self._tu = min(max(self._u, self.rtl_altitude_m), self.limits.max_altitude_m)
            self._face_target = True
        else:
            # Guided starts by holding where it stops, as ArduCopter's does.
            self._tn, self._te, self._tu = stop_n, stop_e, self._u
            self._face_target = behaviour is ModeBehaviour.GUIDED

    def _set_target(self, north_m: float, east_m: float, alt_m: float, speed_m_s: float) -> None:
        self._tn, self._te, self._tu = north_m, east_m, max(alt_m, 0.0)
        self._target_speed = speed_m_s

    def _advance(self, h: float) -> None:
        behaviour = self._behaviour
        if self._landed:
            if not self.armed:
                return
            if behaviour is ModeBehaviour.MANUAL:
                if self._rc_thr <= 0.6:
                    self._thr = 0.0
                    return
            elif behaviour is ModeBehaviour.GUIDED and self._tu > 0.0:
                pass
            else:
                self._thr = 0.0
                if behaviour is ModeBehaviour.LAND:
                    self.armed = False
                return
            self._landed = False
        if behaviour is ModeBehaviour.MANUAL:
            self._advance_manual(h)
        else:
            self._advance_auto(h, behaviour is ModeBehaviour.LAND)
        if self._u >= self.limits.max_altitude_m and self._vu > 0.0:
            self._u = self.limits.max_altitude_m
            self._vu = 0.0

    def _touchdown(self) -> None:
        self._u = 0.0
        self._vn = self._ve = self._vu = 0.0
        self._roll = self._pitch = 0.0
        self._thr = 0.0
        self._landed = True
        if self._behaviour is ModeBehaviour.LAND:
            self.armed = False

    def _climb_demand(self, h: float, climb_m_s: float) -> float:
        """Change the climb rate toward ``climb_m_s`` at the vertical acceleration limit."""
        step = self.accel_z_m_s2 * h
        change = _clamp(climb_m_s - self._vu, -step, step)
        self._vu += change
        return change / h

    def _advance_auto(self, h: float, landing: bool) -> None:
        n, e, u, vn, ve = self._n, self._e, self._u, self._vn, self._ve
        accel = self.accel_xy_m_s2
        gain = self.position_gain_1_s
        # Horizontal: braking profile toward the target, acceleration-limited.
        dn, de = self._tn - n, self._te - e
        distance = math.sqrt(dn * dn + de * de)
        if distance > 1e-9:
            speed = sqrt_controller(distance, gain, accel, h)
            if speed > self._target_speed:
                speed = self._target_speed
            scale = speed / distance
            want_n, want_e = dn * scale, de * scale
        else:
            want_n = want_e = 0.0
        dvn, dve = want_n - vn, want_e - ve
        change = math.sqrt(dvn * dvn + dve * dve)
        step = accel * h
        if change > step:
            dvn *= step / change
            dve *= step / change
        vn += dvn
        ve += dve
        # Vertical.
        if landing:
            slow = self.land_speed_m_s if u <= self.land_slow_below_m else self._max_descent
            climb = -min(slow, self._max_descent)
        else:
            climb = _clamp(
                sqrt_controller(self._tu - u, gain, self.accel_z_m_s2, h),
                -self._max_descent,
                self._max_climb,
            )
        accel_up = self._climb_demand(h, climb)
        n += vn * h
        e += ve * h
        u += self._vu * h
        self._n, self._e, self._u, self._vn, self._ve = n, e, u, vn, ve
        if u <= 0.0 and climb <= 0.0:
            if landing or vn * vn + ve * ve < 0.25:
                self._touchdown()
                return
            self._u = 0.0
            self._vu = max(self._vu, 0.0)
        # Yaw toward the target while far from it.
        yaw = self._yaw
        if self._face_target and distance > 2.0:
            error = _wrap_pi(math.atan2(de, dn) - yaw)
            limit = self._max_turn_rad_s
            yaw = _wrap_pi(yaw + _clamp(2.0 * error, -limit, limit) * h)
            self._yaw = yaw
        # Attitude: the lean that produces this acceleration (and holds off drag).
        drag = self._drag_1_s
        accel_n = dvn / h + drag * vn
        accel_e = dve / h + drag * ve
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
        vn = self._vn + (forward * cos_yaw - right * sin_yaw - drag * self._vn) * h
        ve = self._ve + (forward * sin_yaw + right * cos_yaw - drag * self._ve) * h
        speed = math.sqrt(vn * vn + ve * ve)
        if speed > self._max_speed:
            vn *= self._max_speed / speed
            ve *= self._max_speed / speed
        # Throttle stick: climb rate around mid stick with a 10 % dead band.
        stick = self._rc_thr
        if stick > 0.6:
            climb = (stick - 0.6) / 0.4 * self._max_climb
        elif stick < 0.4:
            climb = (stick - 0.4) / 0.4 * self._max_descent
        else:
            climb = 0.0
        accel_up = self._climb_demand(h, climb)
        self._vn, self._ve = vn, ve
        self._n += vn * h
        self._e += ve * h
        self._u += self._vu * h
        if self._u <= 0.0 and climb <= 0.0:
            self._touchdown()
            return
        self._u = max(self._u, 0.0)
        self._thr = _clamp(
            self.hover_throttle
            * (1.0 + accel_up / G_M_S2)
            / (math.cos(self._roll) * math.cos(self._pitch)),
            0.0,
            1.0,
        )


class FixedWing(SimulatedVehicle):
    """A fixed-wing aircraft: never below its minimum speed in the air, cannot hover.

    Lateral: coordinated turns, turn rate ``g * tan(roll) / V``, never above
    ``max_turn_rate_deg_s``; roll follows its command through a first-order lag
    (``roll_time_constant_s``). The rudder adds a skidding yaw rate of up to half
    the turn-rate limit.

    Longitudinal (an energy model): the flight path follows the pitch attitude,
    climb ``V * sin(pitch)`` within the climb/descent limits; pitch follows its
    command through a first-order lag (``pitch_time_constant_s``). Speed obeys
    ``dV/dt = k (V_thr - V) - g * climb / V``: thrust minus drag, linear in speed,
    with ``V_thr`` the level-flight speed the throttle sustains, from ``V_idle``
    (throttle 0) to ``max_speed_m_s`` (full). ``k`` is sized so that full
    throttle at cruise speed climbs at ``max_climb_rate_m_s``, and ``V_idle`` so
    that idle glides at half the descent limit at minimum speed. When the energy
    cannot pay for a climb at minimum speed the climb is cut (the nose drops), so
    the aircraft never flies below ``min_speed_m_s``.

    Automatic modes fly one controller: loiter clockwise around a centre (the
    guided target, the hold point, the start point for RTL) at radius
    ``loiter_radius_factor`` times the tightest turn radius at the loiter speed
    (``V^2 / (g tan(max bank))`` or ``V / max turn rate``, whichever is larger),
    with a vector-field course law that flies straight at a far centre and
    settles on the circle near it. So a guided goto flies to the point and then
    circles it, as ArduPlane's GUIDED does. Altitude: climb rate proportional to
    the error within the limits; throttle holds the speed (cruise, or the guided
    request) and pays for the climb. Automatic altitudes are never below
    ``min_auto_altitude_m`` (the model has no landing approach), and the wings
    stay level below 10 m. The RC sticks are mixed in (ArduPlane's default
    STICK_MIXING, FBW style): an aileron deflection adds ``deflection * max
    bank`` to the roll command, elevator likewise to pitch, so a doublet shows
    in the attitude in these modes too.

    Manual modes (MANUAL, FBWA and the other pilot modes) all fly as FBWA does:
    the aileron deflection commands a roll angle (full deflection = max bank), the
    elevator a pitch angle (full up +20 degrees, full down -25, ArduPlane's
    LIM_PITCH_MAX/MIN), the rudder a yaw rate, the throttle stick the throttle.
    MANUAL on a real aircraft commands surface deflection, i.e. rates; a
    trimmed, statically stable aircraft settles to an attitude for a held
    deflection, which is what this models, without its rate dynamics.

    On the ground the aircraft rolls along its heading: manual throttle
    accelerates it, the rudder steers it, and at minimum speed up elevator lifts
    it off. An automatic mode entered on the ground is flown as a runway takeoff
    at full throttle (ArduPlane would need TAKEOFF or an AUTO mission). Touching
    the ground in a manual mode lands it; it then brakes to a stop.
    """

    airframe_class = "fixed_wing"
    _MANUAL_MODES = frozenset(
        {"MANUAL", "STABILIZE", "TRAINING", "ACRO", "FBWA", "FBWB", "CRUISE", "AUTOTUNE"}
    )
    _HOLD_MODES = frozenset({"LOITER"})
    _RTL_MODES = frozenset({"RTL"})
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
            "LOITERALTQLAND",
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
    #: Lowest altitude an automatic mode flies at (about 100 ft).
    min_auto_altitude_m: float = 30.0
    #: Loiter radius over the tightest turn radius at the loiter speed.
    loiter_radius_factor: float = 1.5
    #: Time constant of the automatic speed hold.
    speed_time_constant_s: float = 2.0
    #: Climb rate per metre of altitude error in automatic modes, 1/s.
    altitude_gain_1_s: float = 0.4
    #: Turn rate per radian of course error, 1/s.
    course_gain_1_s: float = 1.0
    #: Vector-field gain: how sharply the course bends onto the loiter circle.
    orbit_gain: float = 2.0
    #: Braking on the ground, m/s^2.
    ground_decel_m_s2: float = 2.0
    #: Below this, automatic modes keep the wings level (ArduPlane's TKOFF_LVL_ALT).
    level_below_m: float = 10.0

    def _setup(self) -> None:
        limits = self.limits
        self._v_min = max(limits.min_speed_m_s, 1.0)
        self._v_max = max(limits.max_speed_m_s, self._v_min)
        cruise = _clamp(limits.cruise_speed_m_s, self._v_min, self._v_max)
        bank_deg = limits.max_bank_deg if limits.max_bank_deg else 45.0
        self._max_bank = math.radians(bank_deg)
        self._max_pitch = math.radians(self.max_pitch_deg)
        self._min_pitch = math.radians(self.min_pitch_deg)
        self._rudder_rate = 0.5 * self._max_turn_rad_s
        self._max_climb = limits.max_climb_rate_m_s
        self._max_descent = limits.max_descent_rate_m_s
        # Thrust-minus-drag gain and idle speed (see the class docstring).
        headroom = max(self._v_max - cruise, 1.0)
        self._k_1_s = max(G_M_S2 * self._max_climb / (cruise * headroom), 0.05)
        idle_sink = 0.5 * self._max_descent
        self._v_idle = self._v_min - G_M_S2 * idle_sink / (self._v_min * self._k_1_s)
        self._flying = self._u > 0.0
        self._speed = cruise if self._flying else 0.0
        self._yaw_rate = 0.0
        self._cn, self._ce, self._ch = self._n, self._e, self._auto_altitude(self._u)
        self._target_speed = cruise
        self._radius = self._loiter_radius(cruise)
        if self._flying:
            # Level flight at cruise; a pilot who is flying holds the cruise throttle.
            self._vn = cruise * math.cos(self._yaw)
            self._ve = cruise * math.sin(self._yaw)
            self._thr = (cruise - self._v_idle) / (self._v_max - self._v_idle)
            self._act_thr = self._thr
            throttle = self._controls[3]
            if throttle is not None and throttle.rc is not None:
                self._pilot_us[throttle.rc - 1] = throttle.pwm_from_fraction(self._thr)

    def _set_step(self, h: float) -> None:
        super()._set_step(h)
        self._yaw_alpha = 1.0 - math.exp(-h / self.yaw_time_constant_s)

    @property
    def airborne(self) -> bool:
        """True while flying."""
        return self._flying

    @property
    def loiter_radius_m(self) -> float:
        """Radius of the current loiter circle."""
        return self._radius

    def _airspeed(self, ground_speed_m_s: float) -> float:
        return self._speed

    def _loiter_radius(self, speed_m_s: float) -> float:
        by_bank = speed_m_s * speed_m_s / (G_M_S2 * math.tan(self._max_bank))
        by_rate = speed_m_s / self._max_turn_rad_s if self._max_turn_rad_s > 0 else by_bank
        return self.loiter_radius_factor * max(by_bank, by_rate)

    def _auto_altitude(self, alt_m: float) -> float:
        return min(max(alt_m, self.min_auto_altitude_m), self.limits.max_altitude_m)

    def _enter(self, behaviour: ModeBehaviour) -> None:
        if behaviour is ModeBehaviour.MANUAL:
            return
        cruise = _clamp(self.limits.cruise_speed_m_s, self._v_min, self._v_max)
        self._target_speed = cruise
        self._radius = self._loiter_radius(cruise)
        self._ch = self._auto_altitude(self._u)
        if behaviour is ModeBehaviour.RTL:
            self._cn, self._ce = self.start_m[0], self.start_m[1]
        else:
            self._cn, self._ce = self._n, self._e

    def _set_target(self, north_m: float, east_m: float, alt_m: float, speed_m_s: float) -> None:
        self._cn, self._ce, self._ch = north_m, east_m, self._auto_altitude(alt_m)
        self._target_speed = _clamp(speed_m_s, self._v_min, self._v_max)
        self._radius = self._loiter_radius(self._target_speed)

    def _advance(self, h: float) -> None:
        speed = self._speed
        if self._behaviour is ModeBehaviour.MANUAL:
            roll_cmd = self._rc_roll * self._max_bank
            elevator = self._rc_pitch
            pitch_cmd = elevator * (self._max_pitch if elevator > 0.0 else -self._min_pitch)
            yaw_rate_cmd = self._rc_yaw * self._rudder_rate
            throttle = self._rc_thr
            lift_off = pitch_cmd > 0.0
        elif self._flying:
            roll_cmd, pitch_cmd, throttle = self._autopilot(speed)
            # FBW stick mixing.
            roll_cmd += self._rc_roll * self._max_bank
            elevator = self._rc_pitch
            pitch_cmd += elevator * (self._max_pitch if elevator > 0.0 else -self._min_pitch)
            yaw_rate_cmd = self._rc_yaw * self._rudder_rate
            if self._u < self.level_below_m:
                roll_cmd = 0.0
            lift_off = True
        else:
            roll_cmd, pitch_cmd, yaw_rate_cmd, throttle = 0.0, 0.0, 0.0, 1.0
            lift_off = True
        if not self.armed:
            throttle = 0.0
        roll_cmd = _clamp(roll_cmd, -self._max_bank, self._max_bank)
        pitch_cmd = _clamp(pitch_cmd, self._min_pitch, self._max_pitch)
        self._act_roll = roll_cmd / self._max_bank
        self._act_pitch = (
            pitch_cmd / self._max_pitch if pitch_cmd > 0.0 else -pitch_cmd / self._min_pitch
        )
        self._act_yaw = yaw_rate_cmd / self._rudder_rate if self._rudder_rate else 0.0
        self._act_thr = throttle
        self._thr = throttle
        if self._flying:
            self._fly(h, speed, roll_cmd, pitch_cmd, yaw_rate_cmd, throttle)
        else:
            self._roll_on_ground(h, speed, yaw_rate_cmd, throttle, lift_off)

    def _autopilot(self, speed: float) -> tuple[float, float, float]:
        """Roll, pitch and throttle commands that loiter around the centre."""
        dn, de = self._n - self._cn, self._e - self._ce
        distance = math.sqrt(dn * dn + de * de)
        radius = self._radius
        bearing = math.atan2(de, dn)
        course = bearing + _HALF_PI + math.atan(self.orbit_gain * (distance - radius) / radius)
        error = _wrap_pi(course - self._yaw)
        feed_forward = speed / (distance if distance > radius else radius)
        limit = self._max_turn_rad_s
        turn = _clamp(self.course_gain_1_s * error + feed_forward, -limit, limit)
        roll_cmd = math.atan(turn * speed / G_M_S2)
        climb = _clamp(
            self.altitude_gain_1_s * (self._ch - self._u), -self._max_descent, self._max_climb
        )
        pitch_cmd = math.asin(_clamp(climb / speed, -1.0, 1.0))
        # Throttle: hold the speed and pay for the current climb (TECS in outline).
        accel = (self._target_speed - speed) / self.speed_time_constant_s
        accel += G_M_S2 * self._vu / speed
        level_speed = speed + accel / self._k_1_s
        throttle = _clamp((level_speed - self._v_idle) / (self._v_max - self._v_idle), 0.0, 1.0)
        return roll_cmd, pitch_cmd, throttle

    def _fly(
        self,
        h: float,
        speed: float,
        roll_cmd: float,
        pitch_cmd: float,
        yaw_rate_cmd: float,
        throttle: float,
    ) -> None:
        roll = self._roll + (roll_cmd - self._roll) * self._roll_alpha
        pitch = self._pitch + (pitch_cmd - self._pitch) * self._pitch_alpha
        self._yaw_rate += (yaw_rate_cmd - self._yaw_rate) * self._yaw_alpha
        thrust = self._k_1_s * (self._v_idle + throttle * (self._v_max - self._v_idle) - speed)
        climb = _clamp(speed * math.sin(pitch), -self._max_descent, self._max_climb)
        if climb > 0.0 and self._u >= self.limits.max_altitude_m:
            climb = 0.0
        new_speed = speed + (thrust - G_M_S2 * climb / speed) * h
        if new_speed < self._v_min:
            # The energy cannot pay for this climb at minimum speed: the nose drops.
            affordable = speed * (thrust - (self._v_min - speed) / h) / G_M_S2
            if climb > affordable:
                climb = max(affordable, -self._max_descent)
            new_speed = self._v_min
        elif new_speed > self._v_max:
            new_speed = self._v_max
        limit = self._max_turn_rad_s
        turn = _clamp(G_M_S2 * math.tan(roll) / new_speed + self._yaw_rate, -limit, limit)
        yaw = self._yaw + turn * h
        if yaw >= math.pi:
            yaw -= _TAU
        elif yaw < -math.pi:
            yaw += _TAU
        horizontal = math.sqrt(max(new_speed * new_speed - climb * climb, 0.0))
        vn = horizontal * math.cos(yaw)
        ve = horizontal * math.sin(yaw)
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
            self._u = 0.0
            self._vu = 0.0
            self._roll = self._pitch = 0.0
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
        if lift_off and self.armed and speed >= self._v_min:
            self._flying = True
            self._speed = max(speed, self._v_min)


class Rover(SimulatedVehicle):
    """A ground vehicle: drives on the ground (up is always 0), steers within its turn rate.

    Speed follows its command at up to ``accel_m_s2``. Steering follows its
    command through a first-order lag (``roll_time_constant_s``); full steering
    turns at ``max_turn_rate_deg_s`` once rolling at ``full_steer_speed_m_s`` or
    faster (slower, proportionally less: a car cannot turn in place), and never
    beyond a lateral acceleration of 0.6 g (ArduRover's ATC_TURN_MAX_G).

    Guided and RTL drive toward the target at the requested (or cruise) speed,
    slowing on the square-root braking profile and while pointed away from it,
    steering at a turn rate proportional to the heading error; within
    ``arrival_radius_m`` (ArduRover's WP_RADIUS default) the rover stops and
    stays stopped. Hold stops where it is (ArduRover's HOLD). Manual modes:
    the steering channel steers, the throttle channel (centred) drives forward
    above trim and reverses below it, full stick meaning ``max_speed_m_s``.
    Roll and pitch are always 0. The throttle in the truth is signed (negative
    in reverse).
    """

    airframe_class = "rover"
    _MANUAL_MODES = frozenset({"MANUAL", "ACRO", "STEERING", "SIMPLE"})
    _HOLD_MODES = frozenset({"HOLD", "LOITER"})
    _RTL_MODES = frozenset({"RTL", "SMART_RTL"})
    _REFUSED_MODES = frozenset({"INITIALISING"})
    _CONTROL_NAMES = ("steering", "", "", "throttle")
    _THROTTLE_CENTRED = True

    #: Speed change limit, m/s^2.
    accel_m_s2: float = 2.5
    #: Lateral acceleration limit (ArduRover ATC_TURN_MAX_G 0.6 g).
    max_lateral_accel_m_s2: float = 0.6 * G_M_S2
    #: Speed from which full steering gives the full turn rate.
    full_steer_speed_m_s: float = 1.0
    #: Distance at which a guided or RTL target counts as reached (ArduRover WP_RADIUS).
    arrival_radius_m: float = 2.0
    #: Turn rate per radian of heading error, 1/s.
    heading_gain_1_s: float = 2.0
    #: Lowest speed while turning toward a target behind the rover.
    crawl_speed_m_s: float = 0.5

    def _default_mode(self, autopilot: Mapping[str, Any]) -> str:
        """The mission schema's default start mode: manual for rovers."""
        return str(autopilot.get("manual_mode") or "")

    def _setup(self) -> None:
        self._speed = 0.0
        self._steer = 0.0
        self._tn, self._te = self._n, self._e
        self._target_speed = self.limits.cruise_speed_m_s
        self._arrived = True

    def _enter(self, behaviour: ModeBehaviour) -> None:
        self._target_speed = self.limits.cruise_speed_m_s
        if behaviour is ModeBehaviour.RTL:
            self._tn, self._te = self.start_m[0], self.start_m[1]
            self._arrived = False
        else:
            self._tn, self._te = self._n, self._e
            self._arrived = True

    def _set_target(self, north_m: float, east_m: float, alt_m: float, speed_m_s: float) -> None:
        self._tn, self._te = north_m, east_m
        self._target_speed = speed_m_s
        self._arrived = False

    def _advance(self, h: float) -> None:
        behaviour = self._behaviour
        speed = self._speed
        yaw = self._yaw
        if behaviour is ModeBehaviour.MANUAL:
            steer_cmd = self._rc_roll
            speed_cmd = self._rc_thr * self.limits.max_speed_m_s
        elif self._arrived or behaviour is ModeBehaviour.HOLD:
            steer_cmd = speed_cmd = 0.0
        else:
            dn, de = self._tn - self._n, self._te - self._e
            distance = math.sqrt(dn * dn + de * de)
            if distance < self.arrival_radius_m:
                self._arrived = True
                steer_cmd = speed_cmd = 0.0
            else:
                error = _wrap_pi(math.atan2(de, dn) - yaw)
                limit = self._max_turn_rad_s
                rate = _clamp(self.heading_gain_1_s * error, -limit, limit)
                steer_cmd = rate / limit if limit > 0 else 0.0
                speed_cmd = min(
                    self._target_speed, sqrt_controller(distance, 1.0, self.accel_m_s2, h)
                )
                speed_cmd = max(speed_cmd * math.cos(error), min(self.crawl_speed_m_s, speed_cmd))
        if not self.armed:
            speed_cmd = 0.0
        step = self.accel_m_s2 * h
        speed += _clamp(speed_cmd - speed, -step, step)
        self._steer += (steer_cmd - self._steer) * self._roll_alpha
        limit = self._max_turn_rad_s
        if speed != 0.0:
            lateral = self.max_lateral_accel_m_s2 / abs(speed)
            if lateral < limit:
                limit = lateral
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
    gps_vertical_noise_m: float = DEFAULT_GPS_VERTICAL_NOISE_M,
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
        gps_vertical_noise_m: Standard deviation of the GPS altitude error.
        gps_rate_hz: GPS fix rate; the autopilot profile's ``gps_rate_hz`` when None,
            else :data:`DEFAULT_GPS_RATE_HZ`.
        heading_deg: Heading at the start.
        armed: Armed at the start (the mission's ``sim.armed``, default true).
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
