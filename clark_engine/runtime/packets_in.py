"""Packets from the air: decoded, bounded, logged, and a station's commands acted on.

Every packet the radio hands the runtime (:class:`~clark_engine.runtime.events.
PacketReceived`) comes here first: the codec decodes and checks it, a packet holding more
messages than its sender may send is rejected whole (:class:`TooManyMessages`), the rest
go to the fleet table and the message log (within the air's allowance, so a flood writes
a bounded log), and the commands among them are acted on only when they come from a
station of this mission, authenticated when the mission has a key
(docs/runtime.md#commands-from-the-air-are-bounded): a terminate, an activation now or
timed for a GPS time (held, bounded), a mode request (coalesced).

Separate from :mod:`~clark_engine.runtime.runtime` because what arrives over the air is
hostile until proved otherwise, and its rules (who may command, how much one sender may
cost) are one concern. :class:`PacketIntake` is owned by the
:class:`~clark_engine.runtime.runtime.AgentRuntime` it feeds (a back-reference): it queues
the runtime's behaviour events and commands, and keeps the state of the air's bounds.
"""

from __future__ import annotations

import math
from typing import TYPE_CHECKING

from clark_engine.link.errors import ClarkLinkError, MalformedPacket
from clark_engine.link.messages import (
    MESSAGE_NAMES,
    ActivateController,
    ModeChangeRequest,
    PictureData,
    Terminate,
)
from clark_engine.link.packet import BROADCAST, Packet
from clark_engine.runtime.command_delivery import ActedOn, command_key
from clark_engine.runtime.commands import SetMode
from clark_engine.runtime.config import PeerSpec
from clark_engine.runtime.log_events import LogEvent
from clark_engine.runtime.logbook import AIR_LINES_PER_INTERVAL, AIR_SUMMARY_S

if TYPE_CHECKING:
    from clark_engine.runtime.runtime import AgentRuntime

#: Most messages one packet may hold from an agent not in the mission: one of each kind.
_MAX_MESSAGES_UNKNOWN = len(MESSAGE_NAMES)
#: Most activations timed for a GPS time held at once
#: (docs/runtime.md#commands-from-the-air-are-bounded). One per
#: station, kind (activate, deactivate) and target (this agent, every agent) is held
#: (:meth:`PacketIntake._schedule`), so this bounds a mission with four stations or more;
#: beyond it a new one is dropped and the ones held stay.
MAX_SCHEDULED_ACTIVATIONS = 16
#: An activation timed further ahead of this agent's GPS time than this is not held: a
#: synchronised start is seconds away, and a slot held for hours by a forged far-future
#: start would refuse the station's next one as long.
MAX_ACTIVATION_AHEAD_S = 600.0
#: A mode request for the mode one was passed on for less than this ago is not passed on
#: again: the autopilot adapter already sends it until the autopilot answers.
MODE_REQUEST_REPEAT_S = 1.0
#: Message-log rows of a mission agent's packets are written for up to this many times
#: the packets a second its telemetry is configured to send, plus
#: :data:`RECEIVED_ROWS_SPARE_PER_TICK` a tick of the mission's loop (behaviour states,
#: photos, commands: an agent sends at most a packet to each destination a tick, split
#: bundles aside), in each of the logbook's air intervals; beyond, on a mission without a
#: key, someone is sending in its name, and the rest are counted in the summary.
RECEIVED_ROWS_RATE_FACTOR = 2
RECEIVED_ROWS_SPARE_PER_TICK = 2


class TooManyMessages(MalformedPacket):
    """A packet holding more messages than its sender may send in one (a stuffed packet).

    Rejected whole and counted as malformed against its sender: one packet must not
    write hundreds of message-log rows or feed hundreds of messages to the fleet table.
    """


#: Messages that command an agent (a tuple: isinstance checks it faster than a union).
_COMMAND_MESSAGES = (ModeChangeRequest, ActivateController, Terminate)


class PacketIntake:
    """What arrives over the air, for one runtime: checked, logged, commands acted on.

    Args:
        runtime: The runtime that owns it: its codec, fleet table, logbook and queues.
    """

    def __init__(self, runtime: AgentRuntime) -> None:
        self._runtime = runtime
        self._config = runtime.config
        self._logbook = runtime.logbook
        self._fleet = runtime.fleet
        self._context = runtime.context
        # Activations the station timed for a GPS time: (gps ms, event, sender id, target
        # id), at most one per (sender, event, target) and MAX_SCHEDULED_ACTIVATIONS in all.
        self.scheduled: list[tuple[int, str, int, int]] = []
        # Behaviour events from the air (activate, deactivate) queued in _events and not yet
        # dispatched: each is queued once per tick, however many packets ask for it.
        self.air_events: set[str] = set()
        # A vehicle: the station commands it acted on, so that a station's copy of one is
        # not acted on again (runtime/command_delivery.py).
        self._acted_on = ActedOn()
        # When a mode request for each mode was last passed on (runtime s), until the
        # vehicle reports another mode: a repeat sooner than MODE_REQUEST_REPEAT_S is
        # coalesced. At most one entry per mode of the profile.
        self.mode_requests: dict[str, float] = {}
        #: Most messages one packet of each peer may hold: what it is configured to send
        #: (each telemetry message once) and one of every ClarkLink message besides
        #: (Behavior State, Picture Data, a station's command); more is a stuffed packet.
        self._message_caps = {p.id: len(p.sends) + len(MESSAGE_NAMES) for p in runtime.config.peers}
        #: Packets of each peer whose message-log rows are written per air interval.
        self._received_rows_allowance = {
            p.id: math.ceil(
                AIR_SUMMARY_S
                * (
                    RECEIVED_ROWS_RATE_FACTOR * sum(p.sends.values())
                    + RECEIVED_ROWS_SPARE_PER_TICK * runtime.config.loop_hz
                )
            )
            for p in runtime.config.peers
        }

    def receive(self, data: bytes, now_s: float) -> None:
        """One packet's bytes from the radio: decoded, checked, logged, its commands acted on."""
        gps_now = self._context.gps_time_ms  # deliver's _set_time just worked it out
        try:
            packet = self._runtime.codec.decode(data)
        except ClarkLinkError as exc:
            self._rejected(exc, len(data), now_s, gps_now)
            return
        if packet.sender_id == self._config.agent_id:
            return
        if packet.destination_id not in (BROADCAST, self._config.agent_id):
            return
        cap = self._message_caps.get(packet.sender_id, _MAX_MESSAGES_UNKNOWN)
        if len(packet.messages) > cap:
            self._rejected(
                TooManyMessages(
                    f"{len(packet.messages)} messages in one packet; "
                    f"{self._peer_name(packet.sender_id)} sends at most {cap}",
                    sender_id=packet.sender_id,
                    mission_id=packet.mission_id,
                ),
                len(data),
                now_s,
                gps_now,
            )
            return
        found = self._fleet.receive(packet, now_s, gps_now)
        if found:  # rarely: a first heartbeat, a return, another mission
            self._runtime._fleet_events(found)
        if self._logbook.tables:  # a dry run without a report drops these rows: skip their work
            # Rows within the air allowance: a mission agent's at up to twice its
            # configured rate (anyone may send in its name on a mission without a key),
            # an agent not in the mission's a few per interval; the rest are counted.
            sender = packet.sender_id
            allowance = self._received_rows_allowance.get(sender)
            if self._logbook.from_air(
                now_s,
                "unknown" if allowance is None else "received",
                self._peer_name(sender),
                packet.size_bytes,
                "accepted",
                AIR_LINES_PER_INTERVAL if allowance is None else allowance,
            ):
                self._log_received(packet, now_s, gps_now)
        self._commands_in(packet, now_s)

    def _rejected(
        self, exc: ClarkLinkError, size_bytes: int, now_s: float, gps_now: int | None
    ) -> None:
        """A packet not acted on: counted against its claimed sender, logged within bounds."""
        self._runtime._fleet_events(self._fleet.note_error(exc, now_s))
        self._logbook.rejected(
            now_s, gps_now, self._peer_name(exc.sender_id), size_bytes, type(exc).__name__, str(exc)
        )

    def _log_received(self, packet: Packet, now_s: float, gps_now: int | None) -> None:
        """One message-log row per message of an accepted packet."""
        peer = self._peer_name(packet.sender_id)
        for message in packet.messages:
            stamp = message.gps_time_ms or None
            # Picture Data is stamped at capture, not when sent: no latency from it.
            latency = None
            if stamp is not None and gps_now is not None and not isinstance(message, PictureData):
                latency = gps_now - stamp
            self._logbook.message(
                "received",
                now_s,
                gps_now,
                peer,
                packet.counter,
                packet.size_bytes,
                MESSAGE_NAMES[type(message)],
                stamp,
                latency,
                "",
            )

    def _peer_name(self, agent_id: int | None) -> str:
        if agent_id is None:
            return ""
        peer = self._runtime._peer_by_id.get(agent_id)
        return peer.name if peer is not None else f"#{agent_id}"

    def _commands_in(self, packet: Packet, now_s: float) -> None:
        """Act on commands: only from a station of this mission, authenticated when keyed."""
        for message in packet.messages:
            if isinstance(message, _COMMAND_MESSAGES):
                break
        else:
            return  # telemetry only: the usual packet, looked at without building a list
        commands = [m for m in packet.messages if isinstance(m, _COMMAND_MESSAGES)]
        sender = self._runtime._peer_by_id.get(packet.sender_id)
        size = packet.size_bytes
        if sender is None or sender.role != "mcs":
            name = self._peer_name(packet.sender_id)
            if self._logbook.from_air(now_s, "ignored", name, size, "not a station"):
                self._logbook.mission.warning(
                    "ignored %d command(s) from %s: only a station commands",
                    len(commands),
                    name,
                    extra=LogEvent.COMMAND_IGNORED.extra,
                )
            return
        if self._config.authenticated and not packet.authenticated:
            if self._logbook.from_air(now_s, "ignored", sender.name, size, "unauthenticated"):
                self._logbook.mission.warning(
                    "ignored unauthenticated command(s) from %s",
                    sender.name,
                    extra=LogEvent.COMMAND_IGNORED.extra,
                )
            return
        me = self._config.agent_id
        for message in commands:
            if isinstance(message, Terminate) and message.target_id in (0, me):
                self._logbook.mission.warning(
                    "terminate from %s%s",
                    sender.name,
                    f": {message.reason}" if message.reason else "",
                    extra=LogEvent.COMMAND_TERMINATE.extra,
                )
                self._runtime._terminate(now_s, None)
                return
            if isinstance(message, ActivateController | ModeChangeRequest) and (
                message.target_id in (0, me)
                and not self._acted_on.first_time(command_key(sender.id, message))
            ):
                if self._logbook.from_air(now_s, "command", sender.name, size, "copy"):
                    self._logbook.mission.info(
                        "a copy of a command from %s acted on already: ignored",
                        sender.name,
                        extra=LogEvent.COMMAND_IGNORED.extra,
                    )
                continue
            if isinstance(message, ActivateController) and message.target_id in (0, me):
                event = "activate" if message.active else "deactivate"
                gps_now = self._runtime._gps_now_ms(now_s)
                start_ms = message.start_time_ms
                if start_ms and (gps_now is None or start_ms > gps_now):
                    # The station asked for a synchronised start at a GPS time.
                    self._schedule(start_ms, event, sender, message.target_id, gps_now, size)
                else:
                    self._air_event(event, sender.name, size)
            if isinstance(message, ModeChangeRequest) and message.target_id == me:
                self._mode_request(message.mode, sender.name, size)

    def _air_event(self, event: str, sender: str, size_bytes: int) -> None:
        """Queue a station's ``activate`` or ``deactivate`` for the next machine phase, once.

        However many packets ask for it before the tick, the event is dispatched once:
        a flood must not make a tick's work grow. A repeat after the other kind moves it
        behind that one, so the order of the last of each kind is kept (activate,
        deactivate, activate in one tick ends active).
        """
        now_s = self._context.now_s
        if event in self.air_events:
            if self._runtime._events and self._runtime._events[-1] == event:
                if self._logbook.from_air(now_s, "command", sender, size_bytes, "coalesced"):
                    self._logbook.mission.info(
                        "%s from %s: coalesced with the one queued this tick",
                        event,
                        sender,
                        extra=LogEvent.COMMAND_RECEIVED.extra,
                    )
                return
            self._runtime._events.remove(event)
        self.air_events.add(event)
        self._runtime._events.append(event)
        if self._logbook.from_air(now_s, "command", sender, size_bytes, event):
            self._logbook.mission.info(
                "%s from %s", event, sender, extra=LogEvent.COMMAND_RECEIVED.extra
            )

    def _schedule(
        self,
        start_ms: int,
        event: str,
        sender: PeerSpec,
        target_id: int,
        gps_now: int | None,
        size_bytes: int,
    ) -> None:
        """Hold a timed activation, bounded: one per (sender, kind, target), the first kept.

        On a mission without a key nothing tells the station's packets from a forger's
        that claims its id, so what is held must not depend on who sends more: the first
        received of each (sender, kind, target) stands and a later one, a repeat or a
        new time, is dropped (counted, and logged within the air allowance). A forger
        therefore cannot evict a command the station sent before the flood began; at
        worst it holds a free slot for :data:`MAX_ACTIVATION_AHEAD_S`. Keeping the
        earliest due instead would let anyone evict by claiming an earlier time, and
        keeping the latest received would let a flood evict everything. When
        :data:`MAX_SCHEDULED_ACTIVATIONS` are held, a new one is dropped.
        """
        now_s = self._context.now_s
        why = reason = ""
        for held_ms, held_event, held_sender, held_target in self.scheduled:
            if (held_event, held_sender, held_target) == (event, sender.id, target_id):
                why = (
                    "repeated"
                    if held_ms == start_ms
                    else f"one from {sender.name} for GPS time {held_ms} is held"
                )
                reason = "coalesced" if held_ms == start_ms else "one held"
                break
        else:
            if gps_now is not None and start_ms - gps_now > MAX_ACTIVATION_AHEAD_S * 1000:
                why, reason = f"more than {MAX_ACTIVATION_AHEAD_S:g} s ahead", "too far ahead"
            elif len(self.scheduled) >= MAX_SCHEDULED_ACTIVATIONS:
                why = f"{MAX_SCHEDULED_ACTIVATIONS} timed activations held, the most"
                reason = "full"
        if why:
            if self._logbook.from_air(now_s, "command", sender.name, size_bytes, reason):
                self._logbook.mission.warning(
                    "%s from %s at GPS time %d not held: %s",
                    event,
                    sender.name,
                    start_ms,
                    why,
                    extra=LogEvent.COMMAND_SCHEDULED.extra,
                )
            return
        self.scheduled.append((start_ms, event, sender.id, target_id))
        if self._logbook.from_air(now_s, "command", sender.name, size_bytes, f"{event} timed"):
            self._logbook.mission.info(
                "%s from %s at GPS time %d",
                event,
                sender.name,
                start_ms,
                extra=LogEvent.COMMAND_SCHEDULED.extra,
            )

    def _mode_request(self, custom_mode: int, sender: str, size_bytes: int) -> None:
        """A station's mode request, passed on once per mode per :data:`MODE_REQUEST_REPEAT_S`.

        Until the vehicle reports another mode: then a request for any mode is passed on
        at once. A flood of requests for one mode, or for several in turn, reaches the
        autopilot adapter (which tracks each command until answered) a bounded number
        of times.
        """
        now_s = self._context.now_s
        names = [n for n, number in self._config.modes.items() if number == custom_mode]
        if not names or not self._config.is_vehicle:
            if self._logbook.from_air(now_s, "command", sender, size_bytes, "no such mode"):
                self._logbook.mission.warning(
                    "mode request %d from %s: no such mode",
                    custom_mode,
                    sender,
                    extra=LogEvent.COMMAND_MODE_REQUEST.extra,
                )
            return
        mode = names[0]
        last_s = self.mode_requests.get(mode)
        if last_s is not None and 0 <= now_s - last_s < MODE_REQUEST_REPEAT_S:
            if self._logbook.from_air(now_s, "command", sender, size_bytes, "coalesced"):
                self._logbook.mission.info(
                    "mode request %s from %s: coalesced with the one %.1f s ago",
                    mode,
                    sender,
                    now_s - last_s,
                    extra=LogEvent.COMMAND_MODE_REQUEST.extra,
                )
            return
        self.mode_requests[mode] = now_s
        if self._logbook.from_air(now_s, "command", sender, size_bytes, "mode request"):
            self._logbook.mission.info(
                "mode request %s from %s", mode, sender, extra=LogEvent.COMMAND_MODE_REQUEST.extra
            )
        self._runtime._commands.append(SetMode(mode, custom_mode))
