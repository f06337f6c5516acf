"""What every point-mass model shares: :class:`SimulatedVehicle` and its vocabulary.

The base class holds what does not depend on the airframe (the flight modes' roles, arming,
ArduPilot's parameter table, RC inputs and overrides, servo outputs, the GPS receiver's
fixes and the autopilot's smoothed estimate, the truth) and leaves the physics to one
subclass per airframe (``multirotor``, ``fixed_wing``, ``rover``): a newcomer reads here
what a model promises, there how each flies. The package's docstring states the
conventions (frames, units, RC polarity, the mode classification) all of them keep.

Over 800 lines because :class:`SimulatedVehicle` is one class whose parts (RC, servos, GPS,
modes) share one state and one step, and the constants it reads carry their measurements.
"""

from __future__ import annotations

import math
import random
from abc import abstractmethod
from collections.abc import Mapping
from enum import Enum
from typing import Any, ClassVar, NamedTuple

from clark_engine.mission.geo import EARTH_RADIUS_M, Origin
from clark_engine.sim.ardupilot.airframes.control import wrap_pi
from clark_engine.sim.ardupilot.airframes.profile import (
    AirframeLimits,
    ChannelLike,
    VehicleSetupError,
    read_channel,
)
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

# What a guided/auto command is (VehicleModel.target_reached answers for it).
CMD_NONE, CMD_TARGET, CMD_TAKEOFF, CMD_LAND = range(4)


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


class ModeBehavior(Enum):
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
        self._behaviors, self.unsimulated_modes = self._classify(autopilot)
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
        self._command = CMD_NONE
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
        self._yaw = wrap_pi(math.radians(heading_deg))
        self._armed_yaw = self._yaw
        self._thr = 0.0
        # Normalised actuator demands, for the servo outputs: roll/pitch/yaw in
        # [-1, 1]; throttle in [0, 1] ([-1, 1] when centred).
        self._act_roll = self._act_pitch = self._act_yaw = self._act_thr = 0.0

        # RC inputs.
        self._channels = {name: read_channel(name, spec) for name, spec in channels.items()}
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
        if start_mode not in self._behaviors:
            raise VehicleSetupError(
                f"cannot start in mode {start_mode!r}: "
                + (
                    "the autopilot profile has no such mode"
                    if start_mode not in self.modes
                    else "the autopilot refuses it on this airframe"
                )
            )
        self.mode = start_mode
        self._behavior = self._behaviors[start_mode]
        self._setup()
        if self.airborne and not armed:
            raise VehicleSetupError(
                "a vehicle that starts in the air must start armed; start it on the ground "
                "(up_m 0) or armed"
            )
        self._enter(self._behavior)

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
    ) -> tuple[dict[str, ModeBehavior], frozenset[str]]:
        roles = {
            autopilot.get("guided_mode"): ModeBehavior.GUIDED,
            autopilot.get("hold_mode"): ModeBehavior.HOLD,
            autopilot.get("rtl_mode"): ModeBehavior.RTL,
            autopilot.get("land_mode"): ModeBehavior.LAND,
            autopilot.get("manual_mode"): ModeBehavior.MANUAL,
        }
        behaviors: dict[str, ModeBehavior] = {}
        unsimulated: set[str] = set()
        for name in self.modes:
            if name in roles and not (
                roles[name] is ModeBehavior.LAND and self.airframe_class != "multirotor"
            ):
                behaviors[name] = roles[name]
            elif name in self._REFUSED_MODES:
                continue
            elif name in self._MANUAL_MODES:
                behaviors[name] = ModeBehavior.MANUAL
            elif name in self._HOLD_MODES:
                behaviors[name] = ModeBehavior.HOLD
            elif name in self._RTL_MODES:
                behaviors[name] = ModeBehavior.RTL
            elif name in self._LAND_MODES:
                behaviors[name] = ModeBehavior.LAND
            elif name in self._TAKEOFF_MODES:
                behaviors[name] = ModeBehavior.TAKEOFF
            elif name in self._AUTO_MODES:
                behaviors[name] = ModeBehavior.AUTO
            elif name == "GUIDED":
                behaviors[name] = ModeBehavior.GUIDED
            else:
                behaviors[name] = ModeBehavior.HOLD
                unsimulated.add(name)
        return behaviors, frozenset(unsimulated)

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
        behavior = self._behaviors.get(mode)
        if behavior is None:
            return False
        if mode == self.mode:
            return True
        self.mode = mode
        self._behavior = behavior
        self._enter(behavior)
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
        if self._behavior is not ModeBehavior.GUIDED:
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
        if self._behavior is not ModeBehavior.AUTO:
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
    def behavior(self) -> ModeBehavior:
        """What the current mode makes the model do."""
        return self._behavior

    def mode_behavior(self, mode: str) -> ModeBehavior | None:
        """What ``mode`` would make the model do; None when it is unknown or refused."""
        return self._behaviors.get(mode)

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
    def _enter(self, behavior: ModeBehavior) -> None:
        """Set up a newly entered mode (hold point, guided target, RTL target)."""

    @abstractmethod
    def _set_target(
        self, north_m: float, east_m: float, alt_m: float, speed_m_s: float | None
    ) -> None:
        """Take a new guided/auto target (local frame, altitude clamped to the ceiling)."""

    @abstractmethod
    def _set_speed(self, speed_m_s: float) -> None:
        """Take a new leg speed (positive and finite)."""
