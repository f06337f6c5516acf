"""The runtime's safety rules: failsafes, the envelope in flight, the autopilot's set-up.

Thesis 7.3.5 and docs/safety.md: no station heard for the heartbeat timeout once the
behaviour runs raises ``mcs_lost`` and, unless the behaviour handles it, applies the
declared failsafe (the machine stopped, then the action's mode, once, never resumed); an
autopilot silent for its timeout is lost (every vehicle command dropped until its next
VehicleState, and the requests of the states active across the loss void); the envelope's
watch looks at the vehicle and its peers each tick and applies a breach's action as a
failsafe, never fighting a pilot who took the vehicle; the envelope's guard is the last
step before a command leaves; and the autopilot is asked to hold the envelope itself
before the behaviour may start.

Separate from :mod:`~clark_engine.runtime.runtime` so that what keeps the vehicle safe
reads as one piece. :class:`Safety` is owned by the
:class:`~clark_engine.runtime.runtime.AgentRuntime` whose state it acts on (a
back-reference): the failsafe in force, the breach, the autopilot's loss are the
runtime's, which its telemetry reports and its tick reads.
"""

from __future__ import annotations

import logging
from typing import TYPE_CHECKING

from clark_engine.mission.geo import to_local
from clark_engine.runtime.autopilot_safety import SafetyPlanError, safety_setup
from clark_engine.runtime.commands import Arm, Command, Goto, SetMode, Takeoff, UploadMission
from clark_engine.runtime.envelope_watch import Breach
from clark_engine.runtime.events import AutopilotSafetyResult, VehicleState
from clark_engine.runtime.launch import is_airborne
from clark_engine.runtime.log_events import LogEvent
from clark_engine.runtime.mission_envelope import refused_by_envelope

if TYPE_CHECKING:
    from clark_engine.runtime.runtime import AgentRuntime

#: Commands the envelope guard checks as they leave (:meth:`Safety.guard`).
GUARDED = (Goto, Takeoff, UploadMission)
#: The behaviour's one-off requests, not carried out after an autopilot loss by the states
#: that made them before or during it (:meth:`Safety.void_requests`).
_REQUESTS = (SetMode, Arm, Takeoff)
#: An autopilot safety set-up cut short by the autopilot's silence is asked for again no
#: sooner than this after, once the autopilot is back.
SAFETY_RETRY_S = 5.0


class Safety:
    """One runtime's safety rules, acting on its state.

    Args:
        runtime: The runtime that owns it.
    """

    def __init__(self, runtime: AgentRuntime) -> None:
        self._runtime = runtime
        self._config = runtime.config
        self._logbook = runtime.logbook
        self._context = runtime.context
        self._here_cache: tuple[VehicleState, tuple[float, float]] | None = None

    def silences(self, now_s: float) -> None:
        """No station heard for the heartbeat timeout: mcs_lost; the autopilot silent: lost.

        The end of the timeouts phase, after the fleet's timeouts and the station's
        commands.
        """
        silent_since = self._runtime._stations_silent_since_s
        if (
            silent_since is not None
            and self._runtime._started_s is not None
            and not self._runtime._mcs_lost_raised
            and self._runtime._stations
        ):
            # No station in contact: silent since it was last heard, or since the first
            # tick when none ever was; counted from the behaviour's start at the earliest,
            # because before it the behaviour commands nothing a failsafe would stop.
            silent_s = now_s - max(silent_since, self._runtime._started_s)
            if silent_s > self._config.heartbeat_timeout_s:
                self._logbook.mission.error(
                    "no station heard for %.1f s", silent_s, extra=LogEvent.STATION_SILENT.extra
                )
                self._mcs_lost()
        if not self._config.is_vehicle or self._runtime._autopilot_lost:
            return
        seen = self._runtime._autopilot_seen_s
        if seen is None:
            # Counted from the first tick: an autopilot that never speaks is lost too.
            seen = self._runtime._first_tick_s if self._runtime._first_tick_s is not None else now_s
        if now_s - seen > self._config.autopilot_timeout_s:
            self._runtime._autopilot_lost = True
            self._runtime._requests_void = True
            self._runtime._events.append("autopilot_lost")
            if self._runtime._autopilot_connected:
                self._logbook.interface.error(
                    "autopilot silent for %.1f s: lost; no more commands to it",
                    now_s - seen,
                    extra=LogEvent.AUTOPILOT_LOST.extra,
                )
            else:
                self._logbook.interface.info(
                    "no autopilot (testing mode): treated as lost after %.1f s; commands "
                    "to it are dropped",
                    now_s - seen,
                    extra=LogEvent.AUTOPILOT_LOST.extra,
                )

    def _mcs_lost(self) -> None:
        """Queue mcs_lost; the machine phase gives the behaviour the first chance at it."""
        if self._runtime._mcs_lost_raised:
            return
        self._runtime._mcs_lost_raised = True
        self._runtime._events.append("mcs_lost")
        self._logbook.mission.error(
            "every station is silent: mcs_lost", extra=LogEvent.STATION_LOST.extra
        )

    def void_requests(self, commands: list[Command]) -> list[Command]:
        """The behaviour's commands without the requests of states active across a loss.

        A primitive asks for a mode, an arm or a takeoff when its state starts and asks
        again while the vehicle reports what it reported then; a state entered before or
        during an autopilot loss asked while nobody heard, from a view of the vehicle
        that is stale now, so its asking again after the return would carry out a
        request of the silent time. Targets, servos and overrides still go: the
        autopilot acts on a target only in its guided mode, whoever chose it.
        """
        kept: list[Command] = [c for c in commands if not isinstance(c, _REQUESTS)]
        if len(kept) != len(commands) and not self._runtime._autopilot_lost:
            self._logbook.mission.info(
                "not sent, asked for by a state active while the autopilot was lost: %s",
                ", ".join(type(c).__name__ for c in commands if isinstance(c, _REQUESTS)),
                extra=LogEvent.COMMAND_VOIDED.extra,
            )
        return kept

    def apply_failsafe(self, action: str | None = None, *, breach: Breach | None = None) -> None:
        """A failsafe: the machine stopped, then the action's mode; never applied twice.

        Args:
            action: ``hold``, ``rtl``, ``land`` or ``continue``; None: the declared
                mcs_lost failsafe (when the behaviour does not handle the event).
            breach: The envelope breach this failsafe answers. Its mode is sent only
                when the vehicle is in a mode the engine put it in: a pilot, a station
                or the autopilot's own failsafe that took the vehicle is not fought.
        """
        if action is None:
            action = (
                self._config.failsafe.get("mcs_lost", "hold")
                if self._config.is_vehicle
                else "continue"
            )
        # `clark analyze --checks` and `clark replay` read this line (log_checks): keep it.
        self._logbook.mission.error("failsafe %s", action, extra=LogEvent.FAILSAFE_ACT.extra)
        if action == "continue" or self._runtime.failsafe is not None:
            return
        mode = {
            "hold": self._config.hold_mode,
            "rtl": self._config.rtl_mode,
            "land": self._config.land_mode,
        }.get(action)
        self._runtime.failsafe = action
        self._runtime.failsafe_reason = (
            "mcs_lost"
            if breach is None
            else f"{breach.kind} {breach.peer}"
            if breach.peer
            else breach.kind
        )
        if self._runtime.machine is not None:
            self._runtime.machine.stop(self._context)
            self._runtime._collect_outbox()
        if self._runtime.envelope_guard is not None:
            self._runtime.envelope_guard.end_episode()  # the behaviour sends no more targets
        if breach is not None and not self._runtime._modes.engine_holds:
            reported = self._runtime._modes.reported or "an unknown mode"
            self._logbook.mission.warning(
                "failsafe %s: no mode sent: the vehicle is in %s, a mode the engine did not "
                "put it in (its pilot, the station or the autopilot chose it); the "
                "behaviour is stopped",
                action,
                reported,
                extra=LogEvent.FAILSAFE_NO_MODE.extra,
            )
            return
        if mode is not None and mode in self._config.modes:
            command = SetMode(mode, int(self._config.modes[mode]))
            self._runtime._modes.engine_asked(mode)
            self._runtime._commands.append(command)
            if self._runtime._autopilot_lost:
                self._runtime._failsafe_unsent = command  # sent when the autopilot returns

    def here(self, vehicle: VehicleState) -> tuple[float, float]:
        """The vehicle's position on the local plane (north, east), once per state."""
        cached = self._here_cache
        if cached is not None and cached[0] is vehicle:
            return cached[1]
        point = to_local(vehicle.lat_deg, vehicle.lon_deg, 0.0, self._runtime._origin)
        here = (point.north_m, point.east_m)
        self._here_cache = (vehicle, here)
        return here

    def watch(self, now_s: float) -> None:
        """The vehicle and its peers against the envelope; a breach's action, once.

        Run at the start of every tick, before the machine phase. Before the behaviour
        starts the engine commands nothing, so a breach then is logged only; from the
        tick the launch gate opens, the first breach in force (begun then or before)
        applies its action as a failsafe, and any later one is logged only.
        """
        watch, vehicle = self._runtime.envelope_watch, self._context.vehicle
        if watch is None or vehicle is None:
            return
        result = watch.look(
            vehicle,
            self._runtime._peer_positions.fixes(now_s, self.here(vehicle)),
            now_s,
            guided_flight=self._guided_flight(vehicle),
        )
        for ended in result.ended:
            self._logbook.mission.info(
                "envelope breach over: %s",
                ended.describe(),
                extra=LogEvent.ENVELOPE_BREACH_OVER.extra,
            )
        acting = result.active and self._runtime._started and self._runtime.failsafe is None
        act = result.active[0] if acting else None
        if act is not None:
            self._runtime.breach = act
            self._logbook.mission.error(
                "envelope breach: %s: %s",
                act.describe(),
                act.action,
                extra=LogEvent.ENVELOPE_BREACH.extra,
            )
            self.apply_failsafe(act.action, breach=act)
        for breach in result.began:
            if breach is act:
                continue
            if not self._runtime._started:
                self._logbook.mission.warning(
                    "envelope breach: %s: logged only (the behaviour has not started, "
                    "the engine commands nothing)",
                    breach.describe(),
                    extra=LogEvent.ENVELOPE_BREACH.extra,
                )
            else:
                self._logbook.mission.error(
                    "envelope breach: %s: %s not applied (the failsafe %s holds; a failsafe "
                    "is applied once)",
                    breach.describe(),
                    breach.action,
                    self._runtime.failsafe,
                    extra=LogEvent.ENVELOPE_BREACH.extra,
                )

    def _guided_flight(self, vehicle: VehicleState) -> bool:
        """An aircraft in the air, in the guided mode, flying to a Goto (not taking off)."""
        return (
            self._config.is_aircraft
            and vehicle.mode == self._config.guided_mode
            and self._runtime._last_navigation == "goto"
            and is_airborne(self._context.autopilot, vehicle)
        )

    def envelope_summary(self) -> None:
        """The mission log's closing line: what the guard did, and the breach, if any."""
        guard = self._runtime.envelope_guard
        if guard is None:
            return
        guard.end_episode()
        counts = guard.counts
        breach = self._runtime.breach
        self._logbook.mission.log(
            logging.WARNING if counts.clamped or counts.refused or breach else logging.INFO,
            "envelope: %s; %s",
            counts.describe(),
            (
                f"breach at t={breach.began_s:.3f}: {breach.describe()}: {breach.action}"
                if breach is not None
                else "no breach acted on"
            ),
            extra=LogEvent.ENVELOPE_SUMMARY.extra,
        )

    def guard(self, commands: list[Command]) -> list[Command]:
        """The last step before commands leave: every Goto, Takeoff and upload in the envelope.

        A mission upload is refused whole or not at all, and a refusal is told to the
        behaviour that asked for it.
        """
        guard = self._runtime.envelope_guard
        assert guard is not None
        vehicle = self._context.vehicle
        peers = self._runtime._peer_positions.fixes(
            self._context.now_s, self.here(vehicle) if vehicle is not None else None
        )
        out: list[Command] = []
        for command in commands:
            if isinstance(command, GUARDED):
                kept = guard.check(command, self._context.vehicle, peers, self._context.now_s)
                if kept is None:
                    machine = self._runtime.machine
                    if isinstance(command, UploadMission) and machine is not None:
                        machine.deliver_mission(self._context, refused_by_envelope(command))
                    continue
                if not isinstance(kept, UploadMission):
                    self._runtime._last_navigation = "goto" if isinstance(kept, Goto) else "takeoff"
                command = kept
            out.append(command)
        return out

    def set_up_autopilot(self, now_s: float) -> None:
        """Ask the autopilot to hold the envelope itself, once it can (before the start).

        Sent once the vehicle reports where it is and, when the profile waits for
        readiness, its home (FENCE_ALT_MAX and the return altitude are above home): not
        after its pre-arm checks, which a fence left on the autopilot by an earlier
        mission may fail until this set-up replaces it.
        """
        status = self._context.autopilot
        if (
            self._runtime._autopilot_lost
            or self._runtime.terminated
            or self._context.vehicle is None
            or now_s < self._runtime._safety_due_s
            or (self._config.wait_ready and (status is None or status.home is None))
        ):
            return
        try:
            command = safety_setup(self._config, status.home if status is not None else None)
        except SafetyPlanError as exc:
            self._runtime._safety_state = "failed"
            self._runtime.launch.safety_result(str(exc))
            self._logbook.mission.error(
                "the autopilot's safety set-up cannot be made: %s; the behaviour will not start",
                exc,
                extra=LogEvent.SAFETY_SETUP.extra,
            )
            return
        self._runtime._safety_state = "sent"
        self._runtime._commands.append(command)
        self._logbook.mission.info(
            "setting up the autopilot's own safety (the behaviour waits for it): %s",
            command.summary,
            extra=LogEvent.SAFETY_SETUP.extra,
        )

    def set_up_result(self, result: AutopilotSafetyResult, now_s: float) -> None:
        """The adapter's answer: the gate may open, or says why it will not."""
        if self._runtime._safety_state != "sent":
            return  # an answer to nothing asked (a set-up already ended)
        self._runtime.launch.safety_result(result.problem)
        if result.ok:
            self._runtime._safety_state = "done"
            self._logbook.mission.info(
                "the autopilot's fence and its reaction to a dead mission computer are set "
                "and read back",
                extra=LogEvent.SAFETY_SETUP.extra,
            )
            return
        if result.retry:
            self._runtime._safety_state = "due"
            self._runtime._safety_due_s = now_s + SAFETY_RETRY_S
            self._logbook.mission.error(
                "the autopilot's safety set-up was cut short: %s; asked again once the "
                "autopilot is back",
                result.problem,
                extra=LogEvent.SAFETY_SETUP.extra,
            )
            return
        self._runtime._safety_state = "failed"
        self._logbook.mission.error(
            "the autopilot's safety set-up failed: %s; the behaviour will not start: fix "
            "the autopilot (or its profile) and start again",
            result.problem,
            extra=LogEvent.SAFETY_SETUP.extra,
        )
