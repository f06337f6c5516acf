"""The RC and servo bookkeeping every test's fake vehicle model shares.

A :class:`~clark_engine.sim.model.VehicleModel` test double must keep the
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
