"""The contract between a simulated vehicle's physics and its simulated autopilot.

A :class:`VehicleModel` is the physics and the flight-mode logic of one vehicle
(multirotor, fixed wing or rover) with its airframe's limits; it knows nothing
of MAVLink. The simulated autopilot (:mod:`clark_engine.sim.ardupilot.autopilot`) wraps a
model and speaks MAVLink as ArduPilot does, so the engine's real autopilot
adapter is what talks to it. Everything advances only when ``step`` is called
with a time step: the simulator owns the (virtual) clock.

The split of work: the autopilot layer decides what ArduPilot accepts (arming
checks, which commands a mode takes, DO_CHANGE_SPEED's rules, the auto-disarm
after a landing, the land detector's lag, texts and acknowledgements); the model
obeys what was accepted and flies it as ArduPilot flies it, from ArduPilot's own
parameters (:meth:`VehicleModel.configure`).
"""

from __future__ import annotations

from abc import ABC, abstractmethod
from collections.abc import Mapping
from typing import Final, Literal, NamedTuple

LandedState = Literal["on_ground", "taking_off", "in_air", "landing"]
"""MAVLink's MAV_LANDED_STATE as the model knows it (UNDEFINED is the autopilot's)."""

LANDED_STATES: Final[tuple[LandedState, ...]] = ("on_ground", "taking_off", "in_air", "landing")
"""Every value :attr:`VehicleModel.landed_state` can take."""


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
    sticks, or an RC override); GUIDED flies to the last goto target; AUTO flies
    what a mission executor sets (:meth:`auto_target`, :meth:`auto_takeoff`,
    :meth:`auto_land`); the hold modes stay put; RTL returns home; LAND descends
    (multirotor); TAKEOFF launches (fixed wing). Modes the model does not
    simulate are accepted and flown as the hold mode, and say so in the
    implementation's docstring.

    Attributes:
        modes: Mode name -> ArduPilot custom_mode number, from the autopilot profile.
        mode: The current mode's name.
        armed: True when the motors are armed.
        touchdown_s: Model time (``step`` seconds since construction) of the last
            touchdown; None while flying or if the vehicle never flew. The
            autopilot layer times its disarm after a landing from it.
    """

    modes: Mapping[str, int]
    mode: str
    armed: bool
    touchdown_s: float | None

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
    def arm(self, armed: bool, force: bool = False) -> bool:
        """Arm or disarm (the autopilot layer has done the checks); False when refused.

        Disarming in the air is refused unless ``force``: a forced disarm stops the
        motors wherever the vehicle is (a copter falls, a plane glides).
        """

    @abstractmethod
    def configure(self, params: Mapping[str, float]) -> None:
        """Take the autopilot's parameter table (ArduPilot's names and units).

        Called once at the start and again whenever a parameter changes. The model
        reads what ArduPilot reads; a parameter missing from ``params`` keeps the
        model's default (ArduPilot's). New values apply at the next mode entry or
        target, as ArduPilot's do; the first call applies at once.
        """

    @abstractmethod
    def goto(self, lat_deg: float, lon_deg: float, alt_m: float, speed_m_s: float | None) -> bool:
        """Set the guided target (flown only in the guided mode); False when refused.

        ``alt_m`` is above the origin; ``speed_m_s`` None keeps the current leg speed.
        """

    @abstractmethod
    def set_speed(self, speed_m_s: float) -> None:
        """DO_CHANGE_SPEED as accepted by the autopilot layer: the guided/auto leg speed.

        Kept for later targets in the same mode; the parameter default again on
        (re-)entering a mode. Clamped to what the airframe (and ArduPilot) can fly.
        """

    @abstractmethod
    def takeoff(self, alt_m: float, delay_s: float) -> bool:
        """A guided takeoff to ``alt_m`` above home, climbing after ``delay_s``.

        False when refused (not a multirotor in its guided mode, armed, on the ground).
        """

    @abstractmethod
    def set_home(self, north_m: float, east_m: float, up_m: float) -> None:
        """Where RTL returns to, in the local frame (the autopilot's home)."""

    @abstractmethod
    def auto_target(
        self, north_m: float, east_m: float, alt_m: float, speed_m_s: float | None
    ) -> bool:
        """Set the target AUTO flies (a mission executor's waypoint); False outside AUTO."""

    def auto_waypoint(
        self, north_m: float, east_m: float, alt_m: float, next_course_rad: float | None
    ) -> bool:
        """AUTO's NAV_WAYPOINT item; False outside AUTO.

        Flown as :meth:`auto_target` unless the model flies a mission leg of its own
        (ArduPlane's: the line from the previous waypoint). ``next_course_rad`` is the
        course of the leg after this one (from this waypoint to the next navigation
        item's place, radians from north), None when the mission has none.
        """
        return self.auto_target(north_m, east_m, alt_m, None)

    def waypoint_outcome(self) -> tuple[bool, float] | None:
        """How the last NAV_WAYPOINT leg ended: (passed its finish line, distance left, m).

        None where the model does not fly its own legs (the autopilot then says its
        firmware's text for a waypoint reached).
        """
        return None

    @abstractmethod
    def auto_takeoff(self, alt_m: float) -> bool:
        """A mission's takeoff item in AUTO, to ``alt_m`` above home; False when refused."""

    @abstractmethod
    def auto_land(self) -> None:
        """A mission's land item in AUTO: land where the vehicle is now."""

    @property
    @abstractmethod
    def landed_state(self) -> LandedState:
        """On the ground, taking off, in the air or landing (a rover is always on the ground)."""

    @property
    @abstractmethod
    def airborne(self) -> bool:
        """True while the vehicle is physically off the ground."""

    @property
    @abstractmethod
    def target_reached(self) -> bool:
        """The current guided/auto command is complete (target reached, takeoff done, landed)."""

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

    def nav_attitude_deg(self) -> tuple[float, float]:
        """The roll and pitch the attitude controller is asked for (NAV_CONTROLLER_OUTPUT).

        ArduPilot reports its demand (nav_roll_cd, nav_pitch_cd: the navigation's plus
        the pilot's stick mixing) there, not the attitude flown; a model that does not
        keep its demand reports the attitude, which the demand settles to.
        """
        truth = self.truth()
        return truth.roll_deg, truth.pitch_deg

    def shift_estimate(self, north_m: float, east_m: float) -> None:
        """Move the position the autopilot believes by (north, east) metres; the truth stays.

        The model's position is the autopilot's estimate: a change of the GPS error
        (:mod:`clark_engine.sim.gps_error`) moves the estimate, never the vehicle, and
        the autopilot then flies the estimate back where it wants it. Models that
        cannot be told (none here) refuse.
        """
        raise NotImplementedError(f"{type(self).__name__} cannot shift its position estimate")
