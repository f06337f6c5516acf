"""A station's operator commands: sent to their targets, sent again until they take.

At a station (an agent whose role is ``mcs``) the operator's commands
(:class:`~clark_engine.runtime.events.StationCommand`: activate, deactivate, a mode,
terminate) become ClarkLink messages to one agent or every one. A command to one vehicle
is sent again until the vehicle's reports show it took, a few times at most
(:mod:`~clark_engine.runtime.command_delivery`); a terminate of the whole fleet keeps the
station running, commanding nothing else, until every agent it can reach confirms, then
terminates the station itself (thesis 7.3.5).

Separate from :mod:`~clark_engine.runtime.runtime` because it is the station's side of
commanding, which a vehicle never runs. :class:`StationCommands` is owned by the
:class:`~clark_engine.runtime.runtime.AgentRuntime` it sends through (a back-reference).
"""

from __future__ import annotations

from typing import TYPE_CHECKING

from clark_engine.link.messages import (
    ActivateController,
    BehaviorState,
    Condition,
    Message,
    ModeChangeRequest,
    Terminate,
)
from clark_engine.runtime.command_delivery import COMMAND_RESEND_S, COMMAND_SENDS, Unconfirmed
from clark_engine.runtime.events import StationCommand
from clark_engine.runtime.log_events import LogEvent

if TYPE_CHECKING:
    from clark_engine.runtime.runtime import AgentRuntime

#: A station terminating the fleet sends Terminate again to each agent that has not yet
#: confirmed it (a heartbeat with the terminated condition) this often: one broadcast on
#: a lossy radio is not enough to stop every vehicle.
TERMINATE_RESEND_S = 1.0


class StationCommands:
    """A station's operator commands out, and the fleet terminate it runs.

    Args:
        runtime: The runtime that owns it: its config, fleet table, logbook and sender.
    """

    def __init__(self, runtime: AgentRuntime) -> None:
        self._runtime = runtime
        self._config = runtime.config
        self._logbook = runtime.logbook
        self._fleet = runtime.fleet
        # A station: the commands it sent one vehicle and has not seen take, by (target
        # id, activate/deactivate or mode); sent again until they do, a few times at most.
        self.unconfirmed: dict[tuple[int, str], Unconfirmed] = {}
        #: A station's terminate of the whole fleet under way: each agent that has not yet
        #: confirmed -> when Terminate last went to it. None when none is under way.
        self.terminating: dict[int, float] | None = None
        self._terminate_sent_s = 0.0

    def command(self, command: StationCommand, now_s: float) -> None:
        """An operator's command at this station: sent to its targets as ClarkLink."""
        if self._config.is_vehicle:
            self._logbook.mission.warning(
                "station command %s on a vehicle: ignored",
                command.action,
                extra=LogEvent.STATION_COMMAND.extra,
            )
            return
        gps = self._runtime._gps_now_ms(now_s) or 0
        me = self._config.agent_id
        target = self._runtime._peer_by_name.get(command.target) if command.target else None
        if command.target and target is None:
            self._logbook.mission.warning(
                "station command for unknown agent %s",
                command.target,
                extra=LogEvent.STATION_COMMAND.extra,
            )
            return
        target_id = target.id if target is not None else 0
        message: Message
        if command.action in ("activate", "deactivate"):
            message = ActivateController(me, gps, target_id, command.action == "activate")
        elif command.action == "mode" and target is not None and command.mode in target.modes:
            message = ModeChangeRequest(me, gps, target_id, int(target.modes[command.mode]))
        elif command.action == "terminate":
            message = Terminate(me, gps, target_id, "operator")
        else:
            self._logbook.mission.warning(
                "station command %s not understood", command, extra=LogEvent.STATION_COMMAND.extra
            )
            return
        if self.terminating is not None:
            self._logbook.mission.warning(
                "station command %s %s ignored: the fleet is terminating",
                command.action,
                command.target or "all",
                extra=LogEvent.STATION_COMMAND.extra,
            )
            return
        self._logbook.mission.info(
            "operator: %s %s",
            command.action,
            command.target or "all",
            extra=LogEvent.STATION_COMMAND.extra,
        )
        destination = command.target if target is not None else ""
        self._runtime._telemetry.send([message], destination, now_s)
        if target is not None and isinstance(message, ActivateController | ModeChangeRequest):
            # Sent again until the target shows it took (command_delivery.py); a new
            # command of the same family replaces the one before, copies and all.
            family = "mode" if isinstance(message, ModeChangeRequest) else "activate"
            self.unconfirmed.pop((target.id, family), None)
            if message.gps_time_ms:
                record = self._fleet.record(target.id)
                self.unconfirmed[(target.id, family)] = Unconfirmed(
                    message,
                    command.action,
                    target.name,
                    now_s,
                    now_s,
                    behavior_before=None if record is None else record.sample(BehaviorState),
                )
        if command.action == "terminate" and target is None:
            self._begin_terminate_all(now_s)

    def _begin_terminate_all(self, now_s: float) -> None:
        """Terminate the fleet, then this station: the station waits for confirmations.

        The broadcast just sent may not reach every agent, and once the station has
        terminated it hears nothing: so it keeps running (commanding nothing else) until
        every other agent it can reach confirms with a terminated heartbeat, sending
        Terminate again to those that have not every :data:`TERMINATE_RESEND_S`; an agent
        lost, or still silent after :meth:`_terminate_all_wait_s`, is logged unconfirmed.
        Then the station runs its own terminate sequence (thesis 7.3.5).
        """
        waiting: dict[int, float] = {}
        for peer in self._config.peers:
            if peer.id in self._runtime._stations:
                continue
            record = self._fleet.record(peer.id)
            if record is not None and record.condition == Condition.TERMINATED:
                continue  # terminated already (lost since, as it stopped sending)
            if record is None or record.lost:
                self._logbook.mission.warning(
                    "terminate: %s %s: it cannot confirm",
                    peer.name,
                    "never heard" if record is None else "is lost",
                    extra=LogEvent.TERMINATE_FLEET.extra,
                )
            else:
                waiting[peer.id] = now_s
        self.terminating = waiting
        self._terminate_sent_s = now_s
        if waiting:
            self._logbook.mission.info(
                "terminate: waiting for %s to confirm (at most %.1f s)",
                ", ".join(sorted(self._runtime._peer_by_id[i].name for i in waiting)),
                self._terminate_all_wait_s(),
                extra=LogEvent.TERMINATE_FLEET.extra,
            )
        self.terminate_all_progress(now_s)

    def _terminate_all_wait_s(self) -> float:
        """How long a fleet terminate waits for confirmations.

        An agent that terminated but whose last heartbeat was lost is declared lost within
        the heartbeat timeout of its previous one; two resend periods more cover a first
        Terminate lost on the way.
        """
        return self._config.heartbeat_timeout_s + 2 * TERMINATE_RESEND_S

    def terminate_all_progress(self, now_s: float) -> None:
        """Confirmations taken, Terminate sent again where due, the station's own at the end."""
        waiting = self.terminating
        assert waiting is not None
        for agent_id in list(waiting):
            name = self._runtime._peer_by_id[agent_id].name
            record = self._fleet.record(agent_id)
            if record is not None and record.condition == Condition.TERMINATED:
                del waiting[agent_id]
                self._logbook.mission.info(
                    "terminate: %s confirmed", name, extra=LogEvent.TERMINATE_FLEET.extra
                )
            elif record is not None and record.lost:
                del waiting[agent_id]
                self._logbook.mission.warning(
                    "terminate: %s fell silent unconfirmed",
                    name,
                    extra=LogEvent.TERMINATE_FLEET.extra,
                )
        late = now_s - self._terminate_sent_s >= self._terminate_all_wait_s()
        if waiting and late:
            names = ", ".join(sorted(self._runtime._peer_by_id[i].name for i in waiting))
            self._logbook.mission.error(
                "terminate: no confirmation from %s", names, extra=LogEvent.TERMINATE_FLEET.extra
            )
        if not waiting or late:
            self.terminating = None
            self._runtime._terminate(now_s, None)
            return
        gps = self._runtime._gps_now_ms(now_s) or 0
        for agent_id, sent_s in list(waiting.items()):
            if now_s - sent_s >= TERMINATE_RESEND_S - 1e-9:
                waiting[agent_id] = now_s
                message = Terminate(self._config.agent_id, gps, agent_id, "operator")
                self._runtime._telemetry.send(
                    [message], self._runtime._peer_by_id[agent_id].name, now_s
                )

    def resend_unconfirmed(self, now_s: float) -> None:
        """A station's commands not yet seen to take: sent again, or given up after a few."""
        for key, pending in list(self.unconfirmed.items()):
            what = f"{pending.action} {pending.target}"
            if pending.confirmed_by(self._fleet.record(key[0])):
                del self.unconfirmed[key]
                if pending.sends > 1:
                    self._logbook.mission.info(
                        "%s: took after %d sends",
                        what,
                        pending.sends,
                        extra=LogEvent.COMMAND_RESEND.extra,
                    )
            elif now_s - pending.last_sent_s < COMMAND_RESEND_S - 1e-9:
                continue
            elif pending.sends >= COMMAND_SENDS:
                del self.unconfirmed[key]
                self._logbook.mission.warning(
                    "%s: not seen to take after %d sends in %.1f s",
                    what,
                    pending.sends,
                    now_s - pending.first_sent_s,
                    extra=LogEvent.COMMAND_RESEND.extra,
                )
            else:
                pending.sends += 1
                pending.last_sent_s = now_s
                self._logbook.mission.info(
                    "%s: not seen to take yet, sent again (%d of %d)",
                    what,
                    pending.sends,
                    COMMAND_SENDS,
                    extra=LogEvent.COMMAND_RESEND.extra,
                )
                self._runtime._telemetry.send([pending.message], pending.target, now_s)
