"""What an agent sends: its telemetry each tick, and every packet it sends, logged.

The runtime's ``telemetry`` phase (thesis 7.3.3-7.3.4): every message due this tick,
built from what the runtime knows now (its vehicle, its behaviour, the autopilot's
health, the failsafe in force), and the messages its primitives and state changes
queued, bundled per destination through ClarkLink, each packet a :class:`SendPacket`
and each message a message-log row. A station's commands and a terminate's last
heartbeat go out through :meth:`Telemetry.send` too.

Separate from :mod:`~clark_engine.runtime.runtime` because it only reads the agent's
state: :class:`Telemetry` is owned by the :class:`~clark_engine.runtime.runtime.
AgentRuntime` it reads (a back-reference), and changes nothing but the runtime's queue
of commands out.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import TYPE_CHECKING

from clark_engine.link.messages import (
    MAX_FAILSAFE_TEXT_BYTES,
    MAX_HEALTH_TEXT_BYTES,
    MESSAGE_NAMES,
    AgentAttitude,
    AgentStatus,
    AgentType,
    BehaviorState,
    Condition,
    Heartbeat,
    Message,
    PrearmState,
    VehicleHealth,
    fit_text,
)
from clark_engine.link.packet import BROADCAST
from clark_engine.mission.model import TELEMETRY_MESSAGES
from clark_engine.runtime.commands import SendPacket
from clark_engine.runtime.events import AutopilotHealth
from clark_engine.runtime.logbook import BROADCAST_PEER

if TYPE_CHECKING:
    from clark_engine.runtime.runtime import AgentRuntime

#: Vehicle Health's figures outside these are sent as unknown (the wire refuses them).
_BATTERY_V_MAX = 65.534
_GPS_FIX_TYPE_MAX = 8
_SATELLITES_MAX = 254


class Telemetry:
    """The agent's telemetry and packets out, built from its runtime's state.

    Args:
        runtime: The runtime that owns it, whose state the messages report.
    """

    def __init__(self, runtime: AgentRuntime) -> None:
        self._runtime = runtime
        self._config = runtime.config
        self._logbook = runtime.logbook
        self._fleet = runtime.fleet
        self._context = runtime.context
        #: The telemetry schedule, each message resolved to its builder once.
        self._plan = self._resolve()
        #: Messages primitives queued (Picture Data), waiting for the telemetry phase.
        self.pending: list[tuple[Message, tuple[str, ...]]] = []
        #: Behaviour State of each state change since the last phase, for the stations.
        self.states: list[BehaviorState] = []

    def phase(self, now_s: float) -> None:
        """The tick's telemetry phase: every message due, bundled per destination, sent."""
        by_destination: dict[str, list[Message]] = {}
        for every_ticks, build, destinations in self._plan:
            if self._runtime._tick % every_ticks:
                continue
            message = build()
            if message is None:
                continue
            for destination in destinations:
                by_destination.setdefault(destination, []).append(message)
        for message, to in self.pending:
            for destination in to or ("",):
                by_destination.setdefault(destination, []).append(message)
        self.pending.clear()
        for state in self.states:
            for station in self._runtime._station_names:
                by_destination.setdefault(station, []).append(state)
        self.states.clear()
        for destination in sorted(by_destination):
            self.send(by_destination[destination], destination, now_s)

    def send(self, messages: list[Message], destination: str, now_s: float) -> None:
        """Encode ``messages`` for ``destination`` (``""``: broadcast), queue the packets, log."""
        peer = self._runtime._peer_by_name.get(destination) if destination else None
        destination_id = peer.id if peer is not None else BROADCAST
        gps = self._runtime._gps_now_ms(now_s)
        for sent in self._runtime.codec.encode_packets(
            messages, destination_id, self._runtime.max_packet_bytes
        ):
            self._runtime._commands.append(
                SendPacket(
                    sent.data, destination, destination_id, peer.radio_address if peer else None
                )
            )
            for message in sent.messages:
                self._logbook.message(
                    "sent",
                    now_s,
                    gps,
                    destination or BROADCAST_PEER,
                    sent.counter,
                    len(sent.data),
                    MESSAGE_NAMES[type(message)],
                    message.gps_time_ms or None,
                    None,
                    "",
                )

    def _resolve(
        self,
    ) -> tuple[tuple[int, Callable[[], Message | None], tuple[str, ...]], ...]:
        """The telemetry schedule with each message resolved to its builder, once.

        Each entry: send every this many ticks, the method that builds the message
        (None when there is nothing to say yet), the destinations (``""``: broadcast).
        """
        builders: dict[str, Callable[[], Message | None]] = {
            "heartbeat": self.heartbeat,
            "agent_status": self._agent_status,
            "agent_attitude": self._agent_attitude,
            "behavior_state": self._behavior_state,
            "vehicle_health": self._health_now,
        }
        if set(builders) != set(TELEMETRY_MESSAGES):  # an engine bug, found by every test
            raise RuntimeError(
                f"telemetry messages without a builder: {set(TELEMETRY_MESSAGES) ^ set(builders)}"
            )
        return tuple(
            (spec.every_ticks, builders[spec.message], spec.to or ("",))
            for spec in self._config.telemetry
        )

    def heartbeat(self) -> Message | None:
        """This agent's Heartbeat now (its condition: ok, degraded, failsafe, terminated)."""
        return Heartbeat(
            agent_id=self._config.agent_id,
            gps_time_ms=self._context.gps_time_ms or 0,
            mission_id=self._config.mission_id,
            agent_type=AgentType.VEHICLE if self._config.is_vehicle else AgentType.MCS,
            condition=self._condition(),
            payload_count=len(self._config.payloads),
        )

    def _agent_status(self) -> Message | None:
        vehicle = self._context.vehicle
        if vehicle is None:
            return None
        return AgentStatus(
            agent_id=self._config.agent_id,
            gps_time_ms=self._context.gps_time_ms or 0,
            lat_deg=vehicle.lat_deg,
            lon_deg=vehicle.lon_deg,
            alt_m=vehicle.alt_m,
            ground_speed_m_s=max(0.0, vehicle.ground_speed_m_s),
            climb_rate_m_s=vehicle.climb_rate_m_s,
            heading_deg=vehicle.heading_deg % 360.0,
            mode=vehicle.custom_mode,
        )

    def _agent_attitude(self) -> Message | None:
        vehicle = self._context.vehicle
        if vehicle is None:
            return None
        return AgentAttitude(
            self._config.agent_id,
            self._context.gps_time_ms or 0,
            vehicle.roll_deg,
            vehicle.pitch_deg,
            vehicle.yaw_deg,
        )

    def _behavior_state(self) -> Message | None:
        if self._runtime.machine is None:
            return None
        return BehaviorState(
            self._config.agent_id,
            self._context.gps_time_ms or 0,
            self._runtime.machine.active_paths(),
            self._runtime.machine.last_event,
        )

    def _health_now(self) -> Message | None:
        if not self._config.is_vehicle:
            return None
        return self._vehicle_health(self._config.agent_id, self._context.gps_time_ms or 0)

    def _vehicle_health(self, me: int, gps: int) -> VehicleHealth:
        """Vehicle Health now: what the autopilot last said, and the failsafe in force.

        Every figure is sent within the wire's range or as unknown (an autopilot's
        garbled figure must not stop the tick: the encoder refuses what is out of
        range), and the texts are cut to their bounds at a character boundary.
        """
        health = self._runtime._health or AutopilotHealth()
        battery_v = health.battery_v
        if battery_v is not None and not 0.0 <= battery_v <= _BATTERY_V_MAX:
            battery_v = None
        pct = health.battery_pct if health.battery_pct in range(101) else None
        satellites = health.satellites
        if satellites is not None and not 0 <= satellites <= _SATELLITES_MAX:
            satellites = None
        severity, text, age_s = 0, "", 0
        if self._runtime._warning is not None:
            said, at_s = self._runtime._warning
            text = fit_text(said.text, MAX_HEALTH_TEXT_BYTES)
            severity = max(0, said.severity) if text else 0
            age_s = max(0, int(self._context.now_s - at_s)) if text else 0
        failsafe = ""
        if self._runtime.failsafe is not None:
            why = f": {self._runtime.failsafe_reason}" if self._runtime.failsafe_reason else ""
            failsafe = fit_text(f"{self._runtime.failsafe}{why}", MAX_FAILSAFE_TEXT_BYTES)
        prearm = {None: PrearmState.UNKNOWN, True: PrearmState.PASSING}.get(
            health.prearm_ok, PrearmState.FAILING
        )
        return VehicleHealth(
            agent_id=me,
            gps_time_ms=gps,
            armed=self._runtime._armed,
            battery_v=battery_v,
            battery_pct=pct,
            gps_fix_type=health.gps_fix_type
            if 0 <= health.gps_fix_type <= _GPS_FIX_TYPE_MAX
            else 0,
            satellites=satellites,
            prearm=prearm,
            text_severity=severity,
            text=text,
            failsafe=failsafe,
            autopilot_lost=self._runtime._autopilot_lost,
            text_age_s=age_s,
        )

    def _condition(self) -> Condition:
        if self._runtime.terminated:
            return Condition.TERMINATED
        if self._runtime.failsafe is not None:
            return Condition.FAILSAFE
        lost = any(r.lost for r in self._fleet.agents())
        return Condition.DEGRADED if self._runtime._autopilot_lost or lost else Condition.OK
