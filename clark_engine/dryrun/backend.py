"""What a dry run flies each vehicle against: a simulated autopilot, or real ArduPilot SITL.

The dry run (:mod:`clark_engine.dryrun.engine`) drives every vehicle's autopilot
through one interface, :class:`VehicleBackend`: advance it to a time and take the
MAVLink bytes it sent, hand it the bytes the engine's adapter (or the simulated
pilot, or an outside ground station) sends, and read where the vehicle truly is
for the checks, plots and radio ranges. Two backends implement it:

- :class:`SimulatedBackend`: :class:`~clark_engine.sim.ardupilot.autopilot.SimAutopilot`
  in front of a point-mass :class:`~clark_engine.sim.ardupilot.vehicle_model.VehicleModel`, on the
  dry run's virtual clock (the default; deterministic and fast).
- :class:`~clark_engine.dryrun.sitl_backend.SitlBackend`: a real ArduPilot SITL
  process (``clark dry-run --autopilot sitl``), whose clock sets the pace.

Both are met by the same engine code, so the flight code path (the runtime, its
MAVLink adapter, the radio, the checks) is the same whichever autopilot flies.
"""

from __future__ import annotations

import math
from abc import ABC, abstractmethod
from collections.abc import Mapping

from clark_engine.mission.geo import EARTH_RADIUS_M
from clark_engine.sim.ardupilot.autopilot import SimAutopilot
from clark_engine.sim.ardupilot.vehicle_model import Truth, VehicleModel
from clark_engine.sim.gps_error import GpsError

#: Metres per degree of latitude on the engine's sphere (the models' projection).
_M_PER_DEG_LAT = math.radians(1.0) * EARTH_RADIUS_M


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

    The model's position is the autopilot's estimate, what it reports and flies by.
    With a GPS error (``sim.gps_error``) the backend keeps the truth apart: the
    truth is the estimate minus the error, and each step moves the estimate by the
    error's change (:meth:`VehicleModel.shift_estimate`), so the vehicle truly
    wanders as the autopilot flies its estimate onto its targets.

    Args:
        model: The vehicle's physics and flight modes.
        autopilot: The simulated autopilot flying it.
        gps_error: The vehicle's GPS error over time; None: the estimate is the truth.
            The model must start at the true start plus ``gps_error.offset_m(0.0)``.
        origin_lat_deg: The mission origin's latitude (the models' projection), with
            ``gps_error``.
    """

    def __init__(
        self,
        model: VehicleModel,
        autopilot: SimAutopilot,
        gps_error: GpsError | None = None,
        origin_lat_deg: float = 0.0,
    ) -> None:
        self.model = model
        self.autopilot = autopilot
        self.gps_error = gps_error
        self._error_m = (0.0, 0.0)
        self._m_per_deg_lon = _M_PER_DEG_LAT * math.cos(math.radians(origin_lat_deg))
        if gps_error is not None:
            # The model was built where the autopilot believes it starts (build_vehicle):
            # the true start plus this error, so that a hold point set at power-on (an
            # aircraft handed over in flight) is in the estimate's frame too.
            self._error_m = gps_error.offset_m(0.0)

    @property
    def gps_error_m(self) -> tuple[float, float]:
        """The GPS error (north, east) now: the estimate minus the truth, in metres."""
        return self._error_m

    @property
    def system_id(self) -> int:
        """The simulated autopilot's system id."""
        return self.autopilot.sysid

    def step(self, t_s: float, dt_s: float) -> bytes:
        """Step the physics by ``dt_s`` and collect what the autopilot has due by ``t_s``."""
        if dt_s > 0:
            self.model.step(dt_s)
            if self.gps_error is not None:
                north_m, east_m = self.gps_error.offset_m(t_s)
                old_n, old_e = self._error_m
                if north_m != old_n or east_m != old_e:
                    self.model.shift_estimate(north_m - old_n, east_m - old_e)
                    self._error_m = (north_m, east_m)
        return self.autopilot.advance(t_s)

    def send(self, data: bytes, t_s: float) -> None:
        """Hand bytes to the simulated autopilot."""
        if data:
            self.autopilot.receive(data, t_s)

    def truth(self) -> Truth:
        """The vehicle's true state: the model's, less the GPS error when there is one."""
        truth = self.model.truth()
        if self.gps_error is None:
            return truth
        north_m, east_m = self._error_m
        return truth._replace(
            north_m=truth.north_m - north_m,
            east_m=truth.east_m - east_m,
            lat_deg=truth.lat_deg - north_m / _M_PER_DEG_LAT,
            lon_deg=truth.lon_deg - east_m / self._m_per_deg_lon,
        )

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
