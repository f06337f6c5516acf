"""The hardware profile as the models read it: the airframe's limits and the channels.

Apart from the models because it is what they are handed, not how they fly:
:class:`AirframeLimits` from a resolved airframe profile, a control channel's pulse-width
range (:class:`Channel`, from a config's channel or the raw mapping), and
:class:`VehicleSetupError` for a profile or start that cannot be flown.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any, Protocol

from clark_engine.errors import ClarkError


class VehicleSetupError(ClarkError):
    """A vehicle cannot be built from this profile or start state."""


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
class Channel:
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


def read_channel(name: str, spec: ChannelLike | Mapping[str, Any]) -> Channel:
    """The channel ``name`` of a config (:class:`ChannelLike`) or of a raw mapping."""
    if isinstance(spec, Mapping):
        rc, servo = spec.get("rc"), spec.get("servo")
        low, trim, high = spec["pwm_min_us"], spec["pwm_trim_us"], spec["pwm_max_us"]
    else:
        rc, servo = spec.rc, spec.servo
        low, trim, high = spec.pwm_min_us, spec.pwm_trim_us, spec.pwm_max_us
    return Channel(
        name,
        int(rc) if rc is not None else None,
        int(servo) if servo is not None else None,
        int(low),
        int(trim),
        int(high),
    )
