"""What a dry run flies each vehicle against: a simulated autopilot, or real ArduPilot SITL.

The dry run (:mod:`clark_engine.sim.engine`) drives every vehicle's autopilot
through one interface, :class:`VehicleBackend`: advance it to a time and take the
MAVLink bytes it sent, hand it the bytes the engine's adapter (or the simulated
pilot, or an outside ground station) sends, and read where the vehicle truly is
for the checks, plots and radio ranges. Two backends implement it:

- :class:`SimulatedBackend`: :class:`~clark_engine.sim.autopilot.SimAutopilot`
  in front of a point-mass :class:`~clark_engine.sim.model.VehicleModel`, on the
  dry run's virtual clock (the default; deterministic and fast).
- :class:`~clark_engine.sim.sitl_backend.SitlBackend`: a real ArduPilot SITL
  process (``clark dry-run --autopilot sitl``), whose clock sets the pace.

Both are met by the same engine code, so the flight code path (the runtime, its
MAVLink adapter, the radio, the checks) is the same whichever autopilot flies.
"""

from __future__ import annotations

from abc import ABC, abstractmethod
from collections.abc import Mapping

from clark_engine.sim.autopilot import SimAutopilot
from clark_engine.sim.model import Truth, VehicleModel


class VehicleBackend(ABC):
    """One vehicle's autopilot and physics, as the dry run sees them."""

    @property
    @abstractmethod
    def system_id(self) -> int:
        """The autopilot's MAVLink system id."""

    @abstractmethod
    def step(self, t_s: float, dt_s: float) -> bytes:
        """Advance to time ``t_s`` of the run, ``dt_s`` after the last step.

        Returns:
            The bytes the autopilot sent since the last step.
        """

    @abstractmethod
    def send(self, data: bytes, t_s: float) -> None:
        """Bytes to the autopilot, at time ``t_s`` of the run."""

    @abstractmethod
    def truth(self) -> Truth:
        """Where the vehicle truly is now (the simulator's, not the autopilot's estimate)."""

    @abstractmethod
    def flight_status(self) -> tuple[bool, str]:
        """(armed, flight mode's name) as the autopilot has them now, for the recording.

        The autopilot's own state, not what the engine heard: the safety judgement
        reads it for a vehicle whose mission computer died too.
        """

    @abstractmethod
    def rc_inputs(self) -> tuple[int, ...]:
        """RC input pulse widths the autopilot sees now, channel 1 first (0: none)."""

    @abstractmethod
    def servo_outputs(self) -> tuple[int, ...]:
        """Servo output pulse widths now, output 1 first."""

    @abstractmethod
    def set_pilot(self, pwm_us: Mapping[int, int]) -> None:
        """The pilot moves sticks or switches: RC input channel -> pulse width."""

    @abstractmethod
    def close(self) -> None:
        """Release what the backend holds (a process, a socket)."""


class SimulatedBackend(VehicleBackend):
    """The simulated ArduPilot and its vehicle model, on the dry run's virtual clock.

    Args:
        model: The vehicle's physics and flight modes.
        autopilot: The simulated autopilot flying it.
    """

    def __init__(self, model: VehicleModel, autopilot: SimAutopilot) -> None:
        self.model = model
        self.autopilot = autopilot

    @property
    def system_id(self) -> int:
        """The simulated autopilot's system id."""
        return self.autopilot.sysid

    def step(self, t_s: float, dt_s: float) -> bytes:
        """Step the physics by ``dt_s`` and collect what the autopilot has due by ``t_s``."""
        if dt_s > 0:
            self.model.step(dt_s)
        return self.autopilot.advance(t_s)

    def send(self, data: bytes, t_s: float) -> None:
        """Hand bytes to the simulated autopilot."""
        if data:
            self.autopilot.receive(data, t_s)

    def truth(self) -> Truth:
        """The model's true state."""
        return self.model.truth()

    def flight_status(self) -> tuple[bool, str]:
        """The model's arming and flight mode."""
        return self.model.armed, self.model.mode

    def rc_inputs(self) -> tuple[int, ...]:
        """The model's RC inputs (the pilot's, or an override)."""
        return self.model.rc_inputs()

    def servo_outputs(self) -> tuple[int, ...]:
        """The model's servo outputs."""
        return self.model.servo_outputs()

    def set_pilot(self, pwm_us: Mapping[int, int]) -> None:
        """Move the simulated pilot's transmitter."""
        self.model.set_pilot(pwm_us)

    def close(self) -> None:
        """Nothing to release: the model and autopilot are plain objects."""
