"""A station's command, delivered over a lossy radio and acted on once.

A station sends an operator's ``activate``, ``deactivate`` or mode change to one vehicle
in one packet; a radio in a bad spell loses it, and nothing used to notice: in the
cooperative-follow example's campaign (200 runs, bursty radio) two runs lost the
operator's one ``activate`` and the follower never left idle. So:

- the station sends such a command again, with the same GPS time stamp, every
  :data:`COMMAND_RESEND_S` until the target's own telemetry shows it took (its Behavior
  State naming the event, its Agent Status reporting the mode), :data:`COMMAND_SENDS`
  times at most: a bounded window, so a link that returns later does not bring an old
  command with it;
- a vehicle acts on a command once: a copy of one it acted on (same station, kind,
  target, value and time stamp) is ignored, whichever copy arrives first. Each copy is
  a packet of its own with a fresh counter, so the packet layer's replay window does not
  catch it; this does. A command stamped 0 (a station without a GPS time) is never sent
  again, since its stamp would not tell two commands apart.
"""

from __future__ import annotations

from collections import OrderedDict
from dataclasses import dataclass
from typing import Final

from clark_engine.link.fleet import AgentRecord, Sample
from clark_engine.link.messages import (
    ActivateController,
    AgentStatus,
    BehaviorState,
    Condition,
    ModeChangeRequest,
)

COMMAND_RESEND_S: Final = 1.0
"""An unconfirmed command is sent again this long after the last copy (seconds). The
target's Behavior State goes out as its state changes and its Agent Status at its
telemetry rate (2 Hz in the examples), so a command that took is confirmed sooner."""
COMMAND_SENDS: Final = 4
"""Copies of one command at most: over three seconds, longer than the bad spells of a
bursty radio the examples declare (0.5 s on average) and within a vehicle's station
heartbeat timeout, after which it would be in its failsafe anyway."""
ACTED_ON_KEPT: Final = 64
"""Commands a vehicle remembers having acted on; the oldest is forgotten first. A
station sends a few a minute; a flood of forged ones (only on a mission without a key)
pushes out old keys, never grows the memory."""

CommandKey = tuple[int, str, int, int, int]
"""(station id, kind, target id, value, GPS time stamp in ms) of a command."""


def command_key(sender_id: int, message: ActivateController | ModeChangeRequest) -> CommandKey:
    """What makes a command the same command: its sender, kind, target, value and stamp."""
    if isinstance(message, ActivateController):
        return (sender_id, "activate", message.target_id, int(message.active), message.gps_time_ms)
    return (sender_id, "mode", message.target_id, message.mode, message.gps_time_ms)


class ActedOn:
    """The commands a vehicle acted on, so that a copy of one is not acted on again."""

    def __init__(self, kept: int = ACTED_ON_KEPT) -> None:
        self._kept = kept
        self._keys: OrderedDict[CommandKey, None] = OrderedDict()

    def first_time(self, key: CommandKey) -> bool:
        """Whether this command is new (then it is remembered); False for a copy.

        A command stamped 0 is always new: without a time stamp two commands cannot be
        told apart, and its station never sends copies.
        """
        if key[-1] == 0:
            return True
        if key in self._keys:
            return False
        self._keys[key] = None
        if len(self._keys) > self._kept:
            self._keys.popitem(last=False)
        return True


def took_effect(
    action: str,
    record: AgentRecord,
    sent_s: float,
    *,
    behavior_before: Sample[BehaviorState] | None,
    mode_number: int | None = None,
) -> bool:
    """Whether ``record`` shows, since ``sent_s``, that a command reached its target.

    The one rule by which both the station's runtime (to stop sending a command again)
    and the station's view (to show a command done) judge that a command took:

    - activate / deactivate: a Behavior State received since, naming that event, that
      is not the one known when the command was sent (``behavior_before``) and differs
      from it: a periodic Behavior State repeating an older activation is no answer;
    - mode: an Agent Status received since, reporting ``mode_number``;
    - terminate: the target's heartbeat reports the ``terminated`` condition.
    """
    if action in ("activate", "deactivate"):
        sample = record.sample(BehaviorState)
        if sample is None or sample is behavior_before or sample.received_s < sent_s:
            return False
        value = sample.value
        if value.last_event != action:
            return False
        if behavior_before is None:
            return True
        was = behavior_before.value
        return (was.active_states, was.last_event) != (value.active_states, value.last_event)
    if action == "mode":
        status = record.sample(AgentStatus)
        return (
            status is not None
            and status.received_s >= sent_s
            and mode_number is not None
            and status.value.mode == mode_number
        )
    if action == "terminate":
        return record.condition == Condition.TERMINATED
    return False


@dataclass
class Unconfirmed:
    """A command a station sent and has not yet seen take.

    Attributes:
        message: The command, sent again as it is (the same stamp).
        action: ``activate``, ``deactivate`` or ``mode``.
        target: The target's name (its destination on the radio).
        first_sent_s: When the first copy went (runtime seconds).
        last_sent_s: When the last copy went.
        behaviour_before: The target's Behavior State known when the first copy went.
        sends: Copies sent so far.
    """

    message: ActivateController | ModeChangeRequest
    action: str
    target: str
    first_sent_s: float
    last_sent_s: float
    behavior_before: Sample[BehaviorState] | None = None
    sends: int = 1

    def confirmed_by(self, record: AgentRecord | None) -> bool:
        """Whether the target's telemetry since the first copy shows the command took."""
        if record is None:
            return False
        mode = self.message.mode if isinstance(self.message, ModeChangeRequest) else None
        return took_effect(
            self.action,
            record,
            self.first_sent_s,
            behavior_before=self.behavior_before,
            mode_number=mode,
        )


__all__ = [
    "ACTED_ON_KEPT",
    "COMMAND_RESEND_S",
    "COMMAND_SENDS",
    "ActedOn",
    "CommandKey",
    "Unconfirmed",
    "command_key",
    "took_effect",
]
