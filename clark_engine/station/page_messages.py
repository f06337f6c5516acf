"""The messages a station view's page sends, checked: commands, a replay's controls, their rate.

Separate from the server because every string from a browser is hostile, and the rules
that bound it (known agents and modes only, bounded lengths, ``terminate`` confirmed)
are a protocol of their own, tested without a socket: the server hands each text it
receives to :func:`parse_command` (live) or :func:`parse_replay_control` (replay).
Each client's messages are held to a rate (:class:`RateBucket`, :data:`COMMANDS_PER_S`,
:data:`CONTROLS_PER_S`).
"""

from __future__ import annotations

import json
import math
import time
from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import Any, Final

from clark_engine.station.view_commands import CommandRequest
from clark_engine.station.view_protocol import ACTIONS, agent_names, modes_of
from clark_engine.untrusted import printable

MAX_MESSAGE_BYTES: Final = 16 * 1024
"""Largest WebSocket message accepted from a page; a larger one closes its connection."""

MAX_COMMAND_NAME_CHARS: Final = 64
"""Longest agent or mode name accepted in a command."""

MAX_OPERATOR_CHARS: Final = 40
"""Longest operator name kept (escaped, then cut)."""

MAX_REF_CHARS: Final = 32
"""Longest ``ref`` a page may attach to a command (echoed in the answer)."""

COMMANDS_PER_S: Final = 5.0
"""Sustained commands a client may send; a burst of :data:`COMMAND_BURST` is allowed."""

COMMAND_BURST: Final = 10

CONTROLS_PER_S: Final = 20.0
"""Sustained replay controls (seek, play, pause, speed) a client may send; bursts of
:data:`CONTROLS_BURST` (a dragged slider sends a few a second)."""

CONTROLS_BURST: Final = 40

REPLAY_ACTIONS: Final = ("seek", "play", "pause", "speed")
"""What a replay's page may send."""


@dataclass
class RateBucket:
    """A token bucket: ``rate_per_s`` messages a second, bursts of ``burst``."""

    rate_per_s: float
    burst: float
    tokens: float = -1.0
    refilled_s: float = field(default_factory=time.monotonic)

    def allow(self) -> bool:
        """Whether one more message fits the rate (and take its token)."""
        now = time.monotonic()
        if self.tokens < 0:
            self.tokens = self.burst
        self.tokens = min(self.burst, self.tokens + (now - self.refilled_s) * self.rate_per_s)
        self.refilled_s = now
        if self.tokens < 1.0:
            return False
        self.tokens -= 1.0
        return True


class CommandRejected(ValueError):
    """A message from a page that is not a command the station may send.

    Args:
        reason: Why, in words safe to send back (it quotes nothing the page sent).
        ref: The page's ``ref`` of the message, when it could be read.
    """

    def __init__(self, reason: str, ref: str | int | None = None) -> None:
        super().__init__(reason)
        self.ref = ref


def _json_object(text: str) -> dict[str, Any]:
    """A message from the page as a JSON object, within :data:`MAX_MESSAGE_BYTES`.

    Raises:
        CommandRejected: Too long, not JSON, or not an object.
    """
    if len(text) > MAX_MESSAGE_BYTES:
        raise CommandRejected("message too long")
    try:
        data = json.loads(text)
    except (ValueError, RecursionError):
        raise CommandRejected("not JSON") from None
    if not isinstance(data, dict):
        raise CommandRejected("not a JSON object")
    return data


def _valid_ref(ref: object) -> bool:
    """Whether a message's ``ref`` (echoed to the page) is absent, an int or a short text."""
    return (
        ref is None
        or (isinstance(ref, int) and not isinstance(ref, bool) and abs(ref) < 2**53)
        or (isinstance(ref, str) and len(ref) <= MAX_REF_CHARS and ref.isprintable())
    )


def parse_command(
    text: str, hello: Mapping[str, Any], *, command_id: int, address: str
) -> tuple[CommandRequest, str | int | None]:
    """Check one message from a page; returns the command and the page's ``ref``.

    Everything in it is hostile until checked: it must be a JSON object of at most
    :data:`MAX_MESSAGE_BYTES`, of ``"type": "command"``, with a known action, a target
    that is an agent of the mission or ``"all"``, for ``mode`` a mode of that agent's
    profile, for ``terminate`` ``"confirm": true``; the operator's name is escaped and
    cut to :data:`MAX_OPERATOR_CHARS`.

    Raises:
        CommandRejected: Why it is not accepted (safe to show: it quotes nothing
            longer than the bounds).
    """
    data = _json_object(text)
    ref = data.get("ref")
    if not _valid_ref(ref):
        raise CommandRejected("ref must be a number or a short string")

    def rejected(reason: str) -> CommandRejected:
        return CommandRejected(reason, ref)

    if data.get("type") != "command":
        raise rejected("unknown message type (expected 'command')")
    action = data.get("action")
    if not isinstance(action, str) or action not in ACTIONS:
        raise rejected(f"unknown action; expected one of {', '.join(ACTIONS)}")
    target = data.get("target")
    names = agent_names(hello)
    if not isinstance(target, str) or len(target) > MAX_COMMAND_NAME_CHARS:
        raise rejected("target must be an agent's name or 'all'")
    if target != "all" and target not in names:
        raise rejected(f"no such agent; agents: {', '.join(names)}, all")
    mode = data.get("mode", "")
    if action == "mode":
        if target == "all":
            raise rejected("a mode change names one agent")
        if not isinstance(mode, str) or not mode or len(mode) > MAX_COMMAND_NAME_CHARS:
            raise rejected("mode must be one of the agent's modes")
        if mode not in modes_of(hello).get(target, frozenset()):
            raise rejected(f"{target} has no such mode")
    elif mode not in ("", None):
        raise rejected("mode is only for action 'mode'")
    if action == "terminate" and data.get("confirm") is not True:
        raise rejected('terminate needs "confirm": true')
    operator = data.get("operator", "")
    if operator is None:
        operator = ""
    if not isinstance(operator, str) or len(operator) > 4 * MAX_OPERATOR_CHARS:
        raise rejected("operator must be a short name")
    request = CommandRequest(
        id=command_id,
        action=action,
        target="" if target == "all" else target,
        mode=mode if action == "mode" else "",
        operator=printable(operator.strip(), MAX_OPERATOR_CHARS),
        address=printable(address, 64),
    )
    return request, ref


def parse_replay_control(
    text: str, speeds: tuple[float, ...]
) -> tuple[str, float | None, str | int | None]:
    """Check one message from a replay's page: ``(action, value, ref)``.

    ``{"type": "seek", "t": SECONDS}``, ``{"type": "play"}``, ``{"type": "pause"}``,
    ``{"type": "speed", "speed": X}`` with X one of ``speeds``. A command is refused: a
    replay sends nothing to any vehicle.

    Raises:
        CommandRejected: Why it is not accepted (it quotes nothing the page sent).
    """
    data = _json_object(text)
    ref = data.get("ref")
    if not _valid_ref(ref):
        ref = None
    kind = data.get("type")
    if kind == "command":
        raise CommandRejected("this is a replay of a finished run: it sends no commands", ref)
    if kind not in REPLAY_ACTIONS:
        raise CommandRejected(
            f"unknown message type; expected one of {', '.join(REPLAY_ACTIONS)}", ref
        )
    if kind in ("play", "pause"):
        return kind, None, ref
    key = "t" if kind == "seek" else "speed"
    value = data.get(key)
    if not isinstance(value, int | float) or isinstance(value, bool) or not math.isfinite(value):
        raise CommandRejected(f"{kind} needs a number {key!r}", ref)
    if kind == "speed" and float(value) not in speeds:
        raise CommandRejected(f"speed must be one of {', '.join(f'{x:g}' for x in speeds)}", ref)
    return kind, float(value), ref


__all__ = [
    "COMMANDS_PER_S",
    "COMMAND_BURST",
    "CONTROLS_BURST",
    "CONTROLS_PER_S",
    "MAX_COMMAND_NAME_CHARS",
    "MAX_MESSAGE_BYTES",
    "MAX_OPERATOR_CHARS",
    "MAX_REF_CHARS",
    "REPLAY_ACTIONS",
    "CommandRejected",
    "RateBucket",
    "parse_command",
    "parse_replay_control",
]
