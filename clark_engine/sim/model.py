"""The contract between a simulated vehicle's physics and its simulated autopilot.

A :class:`VehicleModel` is the physics and the flight-mode logic of one vehicle
(multirotor, fixed wing or rover) with its airframe's limits; it knows nothing
of MAVLink. The simulated autopilot (:mod:`clark_engine.sim.autopilot`) wraps a
model and speaks MAVLink as ArduPilot does, so the engine's real autopilot
adapter is what talks to it. Everything advances only when ``step`` is called
with a time step: the simulator owns the (virtual) clock.
"""

from __future__ import annotations

from abc import ABC, abstractmethod
from collections.abc import Mapping
from typing import NamedTuple


class Truth(NamedTuple):
    """The vehicle's true state (what a perfect sensor would read).

    Positions are in the mission's local frame (metres from the origin) and as
    latitude/longitude; altitude is above the origin (ArduPilot's relative
    altitude, home at the origin's altitude). Angles in degrees.

    An immutable named tuple rather than a frozen dataclass: the simulator reads it
    for every streamed position and every track sample of every vehicle, and a tuple
    is built in one step where a frozen dataclass sets its 15 fields one by one.
    """

    north_m: float
    east_m: float
    up_m: float
    lat_deg: float
    lon_deg: float
    velocity_north_m_s: float
    velocity_east_m_s: float
    climb_rate_m_s: float
    roll_deg: float
    pitch_deg: float
    yaw_deg: float
    ground_speed_m_s: float
    heading_deg: float
    airspeed_m_s: float
    throttle_pct: float


class VehicleModel(ABC):
    """Physics and flight-mode behaviour of one simulated vehicle.

    Modes follow ArduPilot: MANUAL-like modes fly the RC inputs (the pilot's
    sticks, or an RC override); GUIDED flies to the last goto target; the hold
    mode (LOITER, HOLD, BRAKE) stays put; RTL returns to the start point;
    LAND descends (multirotor). Modes the model does not simulate are accepted
    and flown as the hold mode, and say so in their docstring.

    Attributes:
        modes: Mode name -> ArduPilot custom_mode number, from the autopilot profile.
        mode: The current mode's name.
        armed: True when the motors are armed.
    """

    modes: Mapping[str, int]
    mode: str
    armed: bool

    @abstractmethod
    def step(self, dt_s: float) -> None:
        """Advance the physics by ``dt_s`` seconds (the simulator picks the step)."""

    @abstractmethod
    def truth(self) -> Truth:
        """The true state now."""

    @abstractmethod
    def set_mode(self, mode: str) -> bool:
        """Switch flight mode; False when the profile has no such mode."""

    @abstractmethod
    def arm(self, armed: bool) -> bool:
        """Arm or disarm; False when refused."""

    @abstractmethod
    def goto(self, lat_deg: float, lon_deg: float, alt_m: float, speed_m_s: float | None) -> bool:
        """Set the guided target (flown only in the guided mode); False when refused."""

    @abstractmethod
    def set_rc_override(self, pwm_us: Mapping[int, int]) -> None:
        """Override RC inputs (channel -> pulse width; 0 releases the channel to the pilot)."""

    @abstractmethod
    def set_servo(self, servo: int, pwm_us: int) -> None:
        """Drive one servo output directly (an output with no function assigned)."""

    @abstractmethod
    def rc_inputs(self) -> tuple[int, ...]:
        """RC input pulse widths the autopilot sees (pilot, or override), channel 1 first."""

    @abstractmethod
    def servo_outputs(self) -> tuple[int, ...]:
        """Servo output pulse widths the autopilot drives, output 1 first."""

    @abstractmethod
    def set_pilot(self, pwm_us: Mapping[int, int]) -> None:
        """The pilot's transmitter: RC inputs before any override (a switch for rc events)."""
