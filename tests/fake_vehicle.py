"""The RC and servo bookkeeping every test's fake vehicle model shares.

A :class:`~clark_engine.sim.ardupilot.vehicle_model.VehicleModel` test double must keep the
pilot's sticks, the autopilot's RC overrides (0 releases a channel, as
RC_CHANNELS_OVERRIDE does) and the servo outputs exactly as the real models do;
the fakes differ only in how they move.
"""

from __future__ import annotations

from collections.abc import Mapping


class RcServoBook:
    """Pilot inputs, overrides (every call kept in ``override_calls``) and servo outputs."""

    def __init__(self, pilot: Mapping[int, int], servo_count: int) -> None:
        self.pilot: dict[int, int] = dict(pilot)
        self.overrides: dict[int, int] = {}
        self.override_calls: list[dict[int, int]] = []
        self.servos = [1500] * servo_count

    def set_rc_override(self, pwm_us: Mapping[int, int]) -> None:
        self.override_calls.append(dict(pwm_us))
        for channel, pwm in pwm_us.items():
            if pwm == 0:
                self.overrides.pop(channel, None)
            else:
                self.overrides[channel] = pwm

    def set_servo(self, servo: int, pwm_us: int) -> None:
        self.servos[servo - 1] = pwm_us

    def rc_inputs(self) -> tuple[int, ...]:
        return tuple(self.overrides.get(c, self.pilot.get(c, 0)) for c in range(1, 17))

    def servo_outputs(self) -> tuple[int, ...]:
        return tuple(self.servos)

    def set_pilot(self, pwm_us: Mapping[int, int]) -> None:
        self.pilot.update(pwm_us)


class FakeModelHooks:
    """The rest of a VehicleModel's interface for test doubles that stand still or fly simply.

    What the autopilot layer calls that such a double has no physics for: parameters
    are kept (``params``), speeds and homes recorded, takeoffs and missions refused, and
    the landed state read off ``up_m`` (on the ground at 0).
    """

    up_m: float
    armed: bool

    def __init__(self) -> None:
        self.params: dict[str, float] = {}
        self.speeds: list[float] = []
        self.homes: list[tuple[float, float, float]] = []
        self.touchdown_s: float | None = None

    def configure(self, params: Mapping[str, float]) -> None:
        self.params.update(params)

    def set_speed(self, speed_m_s: float) -> None:
        self.speeds.append(speed_m_s)

    def takeoff(self, alt_m: float, delay_s: float) -> bool:
        return False

    def set_home(self, north_m: float, east_m: float, up_m: float) -> None:
        self.homes.append((north_m, east_m, up_m))

    def auto_target(
        self, north_m: float, east_m: float, alt_m: float, speed_m_s: float | None
    ) -> bool:
        return False

    def auto_takeoff(self, alt_m: float) -> bool:
        return False

    def auto_land(self) -> None:
        pass

    @property
    def airborne(self) -> bool:
        return self.up_m > 0.0

    @property
    def landed_state(self) -> str:
        return "in_air" if self.airborne else "on_ground"

    @property
    def target_reached(self) -> bool:
        return False

    def arm(self, armed: bool, force: bool = False) -> bool:
        if not armed and self.airborne and not force:
            return False
        self.armed = armed
        return True
