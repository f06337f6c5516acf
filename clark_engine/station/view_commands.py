"""The operator's commands from the page: checked, logged, sent, followed until they show.

Separate from what the page shows because a command has a life of its own (docs/station-view.md,
"Commands"): ``pending`` until the target shows that it took effect, then ``done``;
``refused`` when the station will not send it or its runtime says no; ``unanswered``
when nothing showed it within :func:`answer_timeout_s`. :class:`CommandDesk` keeps them;
the live view (:class:`~clark_engine.station.view_model.StationView`) owns one and hands
it each command the server checked (:class:`CommandRequest`).
"""

from __future__ import annotations

import logging
from collections import deque
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Final

from clark_engine.link.fleet import Sample
from clark_engine.link.messages import BehaviorState, Condition
from clark_engine.runtime.command_delivery import took_effect
from clark_engine.runtime.events import StationCommand
from clark_engine.runtime.log_events import LogEvent
from clark_engine.runtime.runtime import AgentRuntime
from clark_engine.station.view_log import MissionLogBuffer
from clark_engine.station.view_protocol import ACTIONS, Json, rounded

MAX_COMMANDS_SHOWN: Final = 50
"""Commands kept with their lifecycle; older ones leave the view."""

MIN_ANSWER_TIMEOUT_S: Final = 5.0
"""The shortest wait before a command with no sign of effect is ``unanswered``."""


def answer_timeout_s(heartbeat_timeout_s: float) -> float:
    """How long a command waits for a sign of effect before it is ``unanswered``.

    Twice the mission's heartbeat timeout, and at least :data:`MIN_ANSWER_TIMEOUT_S`:
    a Behavior State goes out in the tick after a change, a mode shows in the next Agent
    Status and a terminated agent's last heartbeat goes at once, so anything slower is a
    link that is failing, which the heartbeat timeout is the mission's measure of.
    """
    return max(MIN_ANSWER_TIMEOUT_S, 2.0 * heartbeat_timeout_s)


# -- commands --------------------------------------------------------------------------------


@dataclass(frozen=True, slots=True)
class CommandRequest:
    """An operator's command from the page, already checked by the server.

    Attributes:
        id: The server's number for it (the page follows its lifecycle by it).
        action: One of :data:`ACTIONS`.
        target: An agent's name, or ``""`` for every agent.
        mode: The mode's name, for ``mode``.
        operator: The name the page gave, escaped and bounded (may be empty).
        address: The page's remote address as the server saw it.
    """

    id: int
    action: str
    target: str
    mode: str = ""
    operator: str = ""
    address: str = ""


@dataclass(slots=True)
class _Target:
    """One agent a command is aimed at, and what it has shown since."""

    name: str
    agent_id: int
    status: str = "pending"
    behavior: Sample[BehaviorState] | None = None
    mode_number: int | None = None


@dataclass(slots=True)
class _Command:
    request: CommandRequest
    sent_s: float
    status: str
    detail: str = ""
    targets: list[_Target] = field(default_factory=list)
    done_s: float | None = None

    def to_json(self) -> Json:
        return {
            "id": self.request.id,
            "action": self.request.action,
            "target": self.request.target or "all",
            "mode": self.request.mode or None,
            "by": {"name": self.request.operator, "address": self.request.address},
            "sent_s": rounded(self.sent_s, 3),
            "status": self.status,
            "detail": self.detail,
            "targets": {t.name: t.status for t in self.targets},
            "done_s": rounded(self.done_s, 3),
        }


class CommandDesk:
    """The commands of one station's view, with their lifecycles; the newest kept.

    Owned by :class:`~clark_engine.station.view_model.StationView` (a helper it holds
    rather than a part of it: what the page shows and what the operator asks for meet
    only in the ``commands`` of a state). Runs on the station loop's thread.

    Args:
        runtime: The station's runtime.
        hello: The ``hello`` message (the agents and their modes).
        log: The mission-log copy, where the runtime's refusal of a command is read;
            None reads none (such a command ends ``unanswered``).
        answer_timeout_s: Seconds before a command with no sign of effect is
            ``unanswered``.
    """

    def __init__(
        self,
        runtime: AgentRuntime,
        hello: Json,
        log: MissionLogBuffer | None,
        answer_timeout_s: float,
    ) -> None:
        self.runtime = runtime
        self.hello = hello
        self.log = log
        self.answer_timeout_s = answer_timeout_s
        self._by_name = {str(a["name"]): a for a in hello["agents"]}
        self._commands: deque[_Command] = deque(maxlen=MAX_COMMANDS_SHOWN)

    def follow_pending(self, now_s: float) -> None:
        """Look again for each pending command's sign of effect (after every tick)."""
        for command in self._commands:
            if command.status == "pending":
                self._follow(command, now_s)

    def execute(
        self,
        request: CommandRequest,
        deliver: Callable[[StationCommand], None],
        now_s: float,
    ) -> Json:
        """Log, check and send one operator command; returns its lifecycle entry.

        The command is written in the station's mission log with who sent it (the name
        the page gave and its address, both escaped by the logbook), then checked (the
        station still runs; the target is an agent of the mission that has not
        terminated; the mode is one of its profile's), then handed to ``deliver``
        (the shell's :meth:`~clark_engine.shells.realtime.RealtimeShell.deliver`), which
        sends it as ClarkLink through the station's runtime. A warning the runtime logs
        about it while it does is its refusal.
        """
        runtime = self.runtime
        who = request.operator or "(no name)"
        target_text = request.target or "all"
        what = f"{request.action} {target_text}" + (f" {request.mode}" if request.mode else "")
        if not runtime.logbook.closed:
            runtime.logbook.mission.info(
                "view command %d from %s at %s: %s",
                request.id,
                who,
                request.address,
                what,
                extra=LogEvent.VIEW_COMMAND.extra,
            )
        command = _Command(request, now_s, "pending", targets=self._targets(request))
        self._commands.append(command)
        refusal = self._refusal(request, command)
        if refusal is not None:
            return self._refuse(command, refusal, now_s)
        mark = self.log.seq if self.log is not None else 0
        deliver(StationCommand(request.action, request.target, request.mode))
        if self.log is not None:
            for line in self.log.since(mark):
                if line.event == LogEvent.STATION_COMMAND and line.levelno >= logging.WARNING:
                    return self._refuse(command, f"the station's runtime: {line.text}", now_s)
        # A terminate of the whole fleet: the station's runtime keeps listening until every
        # agent confirms (or falls silent), then terminates itself; followed like the rest.
        self._follow(command, now_s)
        return command.to_json()

    def _targets(self, request: CommandRequest) -> list[_Target]:
        if request.target:
            info = self._by_name.get(request.target)
            return [] if info is None else [_Target(request.target, int(info["id"]))]
        vehicles = [a for a in self.hello["agents"] if a["role"] != "mcs"]
        return [_Target(str(a["name"]), int(a["id"])) for a in vehicles]

    def _refusal(self, request: CommandRequest, command: _Command) -> str | None:
        if self.runtime.terminated:
            return "the station has terminated"
        if request.action not in ACTIONS:
            return f"unknown action {request.action!r}"
        if request.target and request.target not in self._by_name:
            return f"no agent {request.target!r} in the mission"
        if request.action == "mode":
            info = self._by_name.get(request.target)
            if info is None:
                return "a mode change needs one agent"
            modes = {m["name"]: m["number"] for m in info["modes"]}
            if request.mode not in modes:
                return f"{request.target} has no mode {request.mode!r}"
            command.targets[0].mode_number = int(modes[request.mode])
        if not command.targets:
            return "no vehicle to command"
        for target in command.targets:
            record = self.runtime.fleet.record(target.agent_id)
            if record is not None and record.condition == Condition.TERMINATED:
                if request.target:
                    return f"{target.name} has terminated"
                target.status = "terminated"  # of every agent: it can answer nothing
            if record is not None:
                sample = record.sample(BehaviorState)
                target.behavior = sample
        if all(t.status == "terminated" for t in command.targets):
            return "every vehicle has terminated"
        return None

    def _refuse(self, command: _Command, reason: str, now_s: float) -> Json:
        command.status = "refused"
        command.detail = reason
        command.done_s = now_s
        for target in command.targets:
            if target.status == "pending":
                target.status = "refused"
        if not self.runtime.logbook.closed:
            self.runtime.logbook.mission.warning(
                "view command %d refused: %s",
                command.request.id,
                reason,
                extra=LogEvent.VIEW_COMMAND.extra,
            )
        return command.to_json()

    def _follow(self, command: _Command, now_s: float) -> None:
        """Look for each target's sign of effect; end the command when all showed one."""
        fleet = self.runtime.fleet
        action = command.request.action
        for target in command.targets:
            if target.status != "pending":
                continue
            record = fleet.record(target.agent_id)
            if record is not None and took_effect(
                action,
                record,
                command.sent_s,
                behavior_before=target.behavior,
                mode_number=target.mode_number,
            ):
                target.status = "done"
        waiting = [t.name for t in command.targets if t.status == "pending"]
        if not waiting:
            command.status = "done"
            command.done_s = now_s
            command.detail = _evidence(action, command.request.mode)
        elif self.runtime.terminated or now_s - command.sent_s >= self.answer_timeout_s:
            # A terminated station hears nothing more: what has not answered never will.
            command.status = "unanswered"
            command.done_s = now_s
            for target in command.targets:
                if target.status == "pending":
                    target.status = "unanswered"
            answered = [t.name for t in command.targets if t.status == "done"]
            waited = (
                "before the station terminated"
                if self.runtime.terminated
                else f"in {self.answer_timeout_s:g} s"
            )
            command.detail = f"no sign of effect from {', '.join(waiting)} {waited}" + (
                f" (done: {', '.join(answered)})" if answered else ""
            )
            if not self.runtime.logbook.closed:
                self.runtime.logbook.mission.warning(
                    "view command %d unanswered: %s",
                    command.request.id,
                    command.detail,
                    extra=LogEvent.VIEW_COMMAND.extra,
                )

    def commands(self) -> list[Json]:
        """Every command kept, oldest first, with its lifecycle."""
        return [c.to_json() for c in self._commands]


def _evidence(action: str, mode: str) -> str:
    return {
        "activate": "its Behavior State shows the activation",
        "deactivate": "its Behavior State shows the deactivation",
        "mode": f"its Agent Status reports {mode}",
        "terminate": "its heartbeat reports it terminated",
    }.get(action, "")


__all__ = [
    "MAX_COMMANDS_SHOWN",
    "MIN_ANSWER_TIMEOUT_S",
    "CommandDesk",
    "CommandRequest",
    "answer_timeout_s",
]
