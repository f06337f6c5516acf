"""Requests the autopilot must answer: tracked until answered, resent, given up, refused.

Everything the autopilot acknowledges (COMMAND_LONG / COMMAND_INT, PARAM_SET,
PARAM_REQUEST_READ, the stream requests) is a :class:`Request` that the
:class:`RequestTracker` sends, resends after :data:`ACK_TIMEOUT_S` and gives up on after
:data:`COMMAND_ATTEMPTS` sends; a COMMAND_ACK answers it (matched first in, first out by
command number, as ArduPilot answers), and a refusal waits :data:`REASON_WAIT_S` for the
STATUSTEXT that gives its reason before it is reported as a
:class:`~clark_engine.runtime.events.CommandRefused`. :func:`command_result_name`,
:func:`command_name`, :func:`message_id` and :func:`param_id_bytes` name MAVLink's numbers.

Separate from the adapter because the MAVLink command protocol is one concern, which the
adapter's flight commands, stream requests and safety set-up all use. The tracker is
owned by the adapter and works through a back-reference: the requests and refusals
waiting are the adapter's, which a reconnection clears.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, replace
from typing import TYPE_CHECKING, Any, Final

from pymavlink.dialects.v20 import ardupilotmega as mavlink2

from clark_engine.io.autopilot_decode import REASON_WINDOW_S, AutopilotEvent
from clark_engine.runtime.events import CommandRefused
from clark_engine.runtime.log_events import LogEvent

if TYPE_CHECKING:
    from clark_engine.io.autopilot import AutopilotAdapter

ACK_TIMEOUT_S: Final = 1.0
"""How long an acknowledged request waits for its answer before it is resent."""

COMMAND_ATTEMPTS: Final = 3
"""Sends of one command (the first and two retries) before it is reported unanswered."""

REASON_WAIT_S: Final = 0.5
"""A refusal waits this long for its STATUSTEXT before it is reported."""


@dataclass(slots=True)
class Request:
    """One request waiting for the autopilot's answer.

    ``key`` is the MAV_CMD number for commands (answered by COMMAND_ACK) and the
    parameter name for parameter requests (answered by PARAM_VALUE). ``build``
    makes the message for a given attempt (1 first). ``setup`` marks the stream
    requests, which are retried for as long as the autopilot is heard. ``answered``,
    when given, hears how it ended (the MAV_RESULT, or None when it was given up
    unanswered) and reports a refusal itself; without it a refusal is reported as
    :class:`CommandRefused`.
    """

    command: str
    key: int | str
    request: str
    build: Callable[[int], Any]
    setup: bool = False
    answered: Callable[[int | None, float], None] | None = None
    attempts: int = 0
    due_s: float = 0.0


def command_result_name(result: int) -> str:
    """A MAV_RESULT's name without its prefix (``DENIED``), or its number's."""
    entry = mavlink2.enums["MAV_RESULT"].get(result)
    name = entry.name if entry is not None else f"MAV_RESULT_{result}"
    return str(name).removeprefix("MAV_RESULT_")


def command_name(command: int) -> str:
    """A MAV_CMD's name (``MAV_CMD_DO_SET_MODE``), or its number's."""
    entry = mavlink2.enums["MAV_CMD"].get(command)
    return str(entry.name) if entry is not None else f"MAV_CMD_{command}"


def param_id_bytes(name: str) -> bytes:
    """A parameter's name as MAVLink's param_id bytes (1-16 ASCII characters)."""
    raw = name.encode("ascii", errors="strict") if name.isascii() else b""
    if not raw or len(raw) > 16:
        raise ValueError(f"parameter name {name!r} must be 1-16 ASCII characters")
    return raw


def message_id(name: str) -> int:
    """A message's id in the ardupilotmega dialect, by name."""
    msg_id = getattr(mavlink2, f"MAVLINK_MSG_ID_{name}", None)
    if not isinstance(msg_id, int):
        raise ValueError(f"{name!r} is not a MAVLink message of the ardupilotmega dialect")
    return msg_id


class RequestTracker:
    """One adapter's requests waiting for the autopilot's answer, and its refusals.

    Args:
        adapter: The adapter that owns it: its MAVLink encoder, its requests and events.
    """

    def __init__(self, adapter: AutopilotAdapter) -> None:
        self._adapter = adapter
        self._settings = adapter.settings
        self._log = adapter._log

    def on_ack(self, msg: Any, now_s: float, events: list[AutopilotEvent]) -> None:
        """A COMMAND_ACK: the request it answers ended, accepted or refused (or still running)."""
        s = self._settings
        if msg.target_system not in (0, s.source_system_id) or msg.target_component not in (
            0,
            s.source_component_id,
        ):
            return  # another ground station's answer
        request = next((r for r in self._adapter._requests if r.key == msg.command), None)
        if request is None:
            return  # the version probe, or a late duplicate of a retried command
        if msg.result == mavlink2.MAV_RESULT_IN_PROGRESS:
            request.due_s = now_s + ACK_TIMEOUT_S  # alive; wait for the final answer
            return
        self._adapter._requests.remove(request)
        if request.answered is not None:
            request.answered(int(msg.result), now_s)
        elif msg.result != mavlink2.MAV_RESULT_ACCEPTED:
            # Reported once its STATUSTEXT, if any, has had time to arrive.
            refusal = CommandRefused(
                request.command, command_result_name(msg.result), request.request
            )
            self._adapter._refusals.append((now_s + REASON_WAIT_S, refusal, now_s))
        if (
            request.setup
            and msg.command == mavlink2.MAV_CMD_SET_MESSAGE_INTERVAL
            and msg.result == mavlink2.MAV_RESULT_UNSUPPORTED
        ):
            self._adapter._legacy_streams_due = True  # firmware older than SET_MESSAGE_INTERVAL

    def release_refusals(self, now_s: float, events: list[AutopilotEvent]) -> None:
        """Report the refusals whose wait for a reason is over, with their reasons."""
        if not self._adapter._refusals or self._adapter._refusals[0][0] > now_s:
            return
        while self._adapter._refusals and self._adapter._refusals[0][0] <= now_s:
            _due, refusal, at_s = self._adapter._refusals.pop(0)
            reason = "; ".join(
                text for t, text in self._adapter._warnings if at_s - REASON_WINDOW_S <= t <= now_s
            )
            self._log.warning(
                "autopilot refused %s (%s): %s%s",
                refusal.request,
                refusal.command,
                refusal.result,
                f": {reason}" if reason else "",
                extra=LogEvent.AUTOPILOT_REFUSED.extra,
            )
            events.append(replace(refusal, reason=reason))

    def long_builder(self, command: int, params: tuple[float, ...]) -> Callable[[int], Any]:
        """Build a COMMAND_LONG for an attempt (``confirmation`` counts up from 0)."""
        s = self._settings
        p = (*params, *(0.0,) * (7 - len(params)))

        def build(attempt: int) -> Any:
            return self._adapter._mav.command_long_encode(
                s.system_id, s.component_id, command, min(attempt - 1, 255), *p
            )

        return build

    def command_long(self, command: int, request: str, now_s: float, *params: float) -> None:
        """Send a COMMAND_LONG now, tracked until answered."""
        self.track(
            Request(command_name(command), command, request, self.long_builder(command, params)),
            now_s,
        )

    def track(self, request: Request, now_s: float) -> None:
        """Send a request's first attempt now and wait for its answer."""
        request.attempts = 1
        request.due_s = now_s + ACK_TIMEOUT_S
        self._adapter._mav.send(request.build(1))
        self._adapter._requests.append(request)

    def send_due(self, now_s: float, *, heard: bool = True) -> None:
        """Resend what waited :data:`ACK_TIMEOUT_S`; give up after :data:`COMMAND_ATTEMPTS`."""
        for request in list(self._adapter._requests):
            if request.due_s > now_s:
                continue
            if request.setup:
                if not heard and request.attempts > 0:
                    continue  # nobody to ask; the setup is redone when it is heard
            elif request.attempts >= COMMAND_ATTEMPTS:
                self._adapter._requests.remove(request)
                self._log.warning(
                    "autopilot did not answer %s (%s) after %d sends",
                    request.request,
                    request.command,
                    request.attempts,
                    extra=LogEvent.AUTOPILOT_UNANSWERED.extra,
                )
                if request.answered is not None:
                    request.answered(None, now_s)
                else:
                    self._adapter._late_events.append(
                        CommandRefused(request.command, "NO_ANSWER", request.request)
                    )
                continue
            request.attempts += 1
            request.due_s = now_s + ACK_TIMEOUT_S
            self._adapter._mav.send(request.build(request.attempts))
