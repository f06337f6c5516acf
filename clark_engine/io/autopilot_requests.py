"""A request the autopilot must answer: the record kept until its answer, and its timing.

Everything the autopilot acknowledges (COMMAND_LONG / COMMAND_INT, PARAM_SET,
PARAM_REQUEST_READ, the stream requests) is a :class:`Request` that the adapter
(:mod:`~clark_engine.io.autopilot`) resends after :data:`ACK_TIMEOUT_S` and gives up on
after :data:`COMMAND_ATTEMPTS` sends; :func:`result_name` and :func:`command_name` name
MAVLink's numbers in the logs and refusals. Separate so that the adapter and its flight
commands (:mod:`~clark_engine.io.autopilot_flight`) share one record of the MAVLink
command protocol without importing each other.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from typing import Any, Final

from pymavlink.dialects.v20 import ardupilotmega as mavlink2

ACK_TIMEOUT_S: Final = 1.0
"""How long an acknowledged request waits for its answer before it is resent."""

COMMAND_ATTEMPTS: Final = 3
"""Sends of one command (the first and two retries) before it is reported unanswered."""


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


def result_name(result: int) -> str:
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
