"""When a vehicle's behaviour may start: ready, armed, flying, as the mission declares.

A real ArduPilot needs tens of seconds after power-on before it can fly: its
GPS gets a fix, its EKF an absolute position, its pre-arm checks pass. Someone
then arms it, and an aircraft takes off. The mission says who does what
(``launch``: the safety pilot arms, or the engine does when the behaviour needs
it; the pilot may also take off first), and the autopilot profile says whether
to wait for readiness (``wait_ready``). :class:`LaunchGate` turns that and what
the autopilot reports into one answer: may the behaviour start now? Until it
may, the runtime runs its safety rules and telemetry but no primitive, so
nothing is commanded that the autopilot would refuse or ignore.

A vehicle's gate also waits for the autopilot's safety set-up (its own fence and
its reaction to a dead mission computer, :mod:`clark_engine.runtime.autopilot_safety`)
to have taken, and says what did not when it failed: the behaviour never starts
on an autopilot that would fly on alone if the mission computer stopped.

The gate opens once and stays open: a vehicle disarmed later (by its pilot, or
ArduCopter's auto-disarm after landing) keeps its behaviour; what happens then
is the behaviour's business and the pilot's.
"""

from __future__ import annotations

import logging
from typing import Final

from clark_engine.runtime.config import AgentConfig
from clark_engine.runtime.events import AutopilotStatus, LandedState, VehicleState
from clark_engine.runtime.log_events import LogEvent

AIRBORNE_ALT_M: Final = 2.0
"""Height above the origin that counts as flying when the autopilot gives no landed state."""

DATUM_TOLERANCE_M: Final = 10.0
"""How far from the origin's height a vehicle on the ground may read before its behaviour
is held back: every altitude the engine commands is above the origin, worked out from the
mission's ``origin.alt_amsl_m``, so a wrong one would put every height off by as much.
GPS heights wander by a few metres; ten is well beyond that and well short of a floor."""


def is_airborne(status: AutopilotStatus | None, vehicle: VehicleState | None) -> bool:
    """True when the vehicle flies: by its autopilot's landed state, else armed and up.

    ArduCopter and ArduPlane report a landed state (EXTENDED_SYS_STATE); without
    one, an armed vehicle more than :data:`AIRBORNE_ALT_M` above the origin is flying.
    """
    landed = status.landed if status is not None else LandedState.UNKNOWN
    if landed is not LandedState.UNKNOWN:
        return landed is not LandedState.ON_GROUND
    return vehicle is not None and vehicle.armed and vehicle.alt_m > AIRBORNE_ALT_M


class LaunchGate:
    """Decides when an agent's behaviour starts; logs what it waits for as that changes.

    Stations and vehicles with nothing to wait for open at once.

    Args:
        config: The agent's compiled config (``launch``, ``wait_ready``).
        log: The agent's mission log.
    """

    def __init__(self, config: AgentConfig, log: logging.Logger) -> None:
        self._config = config
        self._log = log
        self._open = not config.is_vehicle
        self._waiting: tuple[str, ...] | None = None
        #: The autopilot's safety set-up is yet to take (vehicles whose profile has it).
        self._safety_due = config.is_vehicle and config.safety_setup
        self._safety_problem = ""

    @property
    def open(self) -> bool:
        """True once the behaviour may start."""
        return self._open

    @property
    def waiting_for(self) -> tuple[str, ...]:
        """What the gate waits for, in words (empty once open)."""
        return () if self._open else (self._waiting or ())

    @property
    def safety_done(self) -> bool:
        """True once the autopilot's safety set-up took, or when none is due."""
        return not self._safety_due

    def safety_result(self, problem: str) -> None:
        """The autopilot's safety set-up ended: took (``problem`` empty) or what did not.

        A set-up asked for again (after a silence) reports its new answer the same way;
        until then the gate says what the last one ended with.
        """
        if problem:
            self._safety_problem = problem
        else:
            self._safety_due = False
            self._safety_problem = ""

    def update(self, status: AutopilotStatus | None, vehicle: VehicleState | None) -> bool:
        """Look again at what the autopilot reports; True when the gate is (now) open."""
        if self._open:
            return True
        missing = self._missing(status, vehicle)
        if not missing:
            self._open = True
            launch = self._config.launch
            how = (
                "armed and flown up by the pilot"
                if launch.airborne
                else "armed by the pilot"
                if not launch.engine_arms
                else "the engine arms it when the behaviour needs it"
            )
            self._log.info(
                "launch: the autopilot is ready; %s; the behaviour starts",
                how,
                extra=LogEvent.LAUNCH_START.extra,
            )
            if self._config.is_vehicle and not self._config.safety_setup:
                self._log.warning(
                    "launch: the autopilot's own fence and its reaction to a dead mission "
                    "computer are NOT set up (its profile says safety_setup: false): if this "
                    "computer stops, the vehicle flies on to its last target",
                    extra=LogEvent.LAUNCH_UNPROTECTED.extra,
                )
            return True
        if missing != self._waiting:
            self._waiting = missing
            self._log.info(
                "launch: the behaviour waits for %s",
                ", ".join(missing),
                extra=LogEvent.LAUNCH_WAIT.extra,
            )
        return False

    def _missing(
        self, status: AutopilotStatus | None, vehicle: VehicleState | None
    ) -> tuple[str, ...]:
        config = self._config
        missing: list[str] = []
        if vehicle is None:
            missing.append("the autopilot's first state")
        if config.wait_ready:
            if status is None:
                missing.append("the autopilot's readiness report")
            else:
                missing.extend(status.waiting_for)
        if self._safety_due:
            missing.append(
                f"the autopilot's safety set-up ({self._safety_problem})"
                if self._safety_problem
                else "the autopilot's safety set-up"
            )
        if not config.launch.engine_arms and (vehicle is None or not vehicle.armed):
            missing.append("the pilot to arm it")
        airborne = is_airborne(status, vehicle)
        if config.launch.airborne and not airborne:
            missing.append("the pilot to take off")
        if vehicle is not None and not airborne and abs(vehicle.alt_m) > DATUM_TOLERANCE_M:
            missing.append(
                f"its height to agree with the origin's: on the ground it reads "
                f"{vehicle.alt_m:+.0f} m from the origin "
                f"({config.origin_alt_amsl_m + vehicle.alt_m:.0f} m above sea level against "
                f"mission.origin.alt_amsl_m {config.origin_alt_amsl_m:g}); correct "
                "alt_amsl_m, or the vehicle's GPS"
            )
        return tuple(missing)
