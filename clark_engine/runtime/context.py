"""What a primitive sees of the world: one context object per agent, never globals.

The runtime owns one :class:`PrimitiveContext` per agent and hands it to every
primitive call (``start``, ``update``, ``stop``, ``on_payload``). Through it a
primitive reads the clock, its vehicle, the fleet table and its parameters'
resolved hardware, and queues commands and messages; it never talks to an
interface or another agent directly, so two agents in one process share nothing.
"""

from __future__ import annotations

import logging
import math
from dataclasses import dataclass, field

# What ``update`` reports each tick; declared with the behaviours' lifecycle, kept here too.
from clark_engine.behaviors.base import Status as Status
from clark_engine.link.fleet import FleetTable
from clark_engine.link.messages import AgentStatus, Message
from clark_engine.runtime.commands import Command
from clark_engine.runtime.config import AgentConfig
from clark_engine.runtime.events import AutopilotStatus, VehicleState

EARTH_RADIUS_M = 6_371_008.8


@dataclass(slots=True)
class Outbox:
    """What primitives queued during one call of the runtime."""

    commands: list[Command] = field(default_factory=list)
    messages: list[tuple[Message, tuple[str, ...]]] = field(default_factory=list)


@dataclass(slots=True)
class PrimitiveContext:
    """The world as one agent's primitives see it.

    Attributes:
        config: The agent's compiled config.
        fleet: The agent's fleet table (peers' latest status, attitude, pictures...).
        now_s: The runtime clock: seconds since the runtime started (virtual in a dry run).
        tick: Index of the current tick.
        vehicle: The autopilot's latest state, None until one arrives (and for stations).
        autopilot: The autopilot's latest readiness and landed state, None until reported.
        gps_time_ms: Best estimate of GPS time now (None before the autopilot gave one).
        outbox: Commands and messages queued by primitives in this call.
        terminate_requested: Set by the terminate primitive; the runtime then terminates
            this agent (stop commanding, terminal mode, close interfaces, flush logs).
        terminal_mode: Mode the terminate primitive asked for, None for the config's.
        log: The agent's mission log; primitives log here, never to a global logger.
    """

    config: AgentConfig
    fleet: FleetTable
    now_s: float = 0.0
    tick: int = 0
    vehicle: VehicleState | None = None
    autopilot: AutopilotStatus | None = None
    gps_time_ms: int | None = None
    outbox: Outbox = field(default_factory=Outbox)
    log: logging.Logger = field(default_factory=lambda: logging.getLogger("clark.runtime"))
    terminate_requested: bool = False
    terminal_mode: str | None = None
    _request_id: int = 0

    @property
    def dt_s(self) -> float:
        """Length of one tick."""
        return 1.0 / self.config.loop_hz

    def command(self, command: Command) -> None:
        """Queue a command for the shell to carry out after this call."""
        self.outbox.commands.append(command)

    def send(self, message: Message, to: tuple[str, ...] = ()) -> None:
        """Queue a ClarkLink message; it goes out bundled in this tick's telemetry phase.

        Args:
            message: The message (its agent_id and gps_time_ms set by the caller).
            to: Agent names; empty for every agent.
        """
        self.outbox.messages.append((message, to))

    def request_terminate(self, mode: str | None = None) -> None:
        """Ask the runtime to terminate this agent at the end of this call."""
        self.terminate_requested = True
        self.terminal_mode = mode

    def next_request_id(self) -> int:
        """A fresh id for a payload request (unique for this agent's run)."""
        self._request_id += 1
        return self._request_id

    def peer_status(self, name: str) -> AgentStatus | None:
        """The latest Agent Status a peer sent, without clearing its new-data flag."""
        peer = self.config.peer(name)
        if peer is None:
            return None
        return self.fleet.peek(peer.id, AgentStatus)

    def peer_status_by_id(self, peer_id: int) -> AgentStatus | None:
        """The latest Agent Status of the peer with this id, without clearing its flag.

        For names resolved to ids when the config loaded (a followed agent): no lookup
        by name at flight time.
        """
        return self.fleet.peek(peer_id, AgentStatus)

    def mode_number(self, mode: str) -> int:
        """The custom_mode number of a mode of this agent's autopilot."""
        return int(self.config.modes[mode])

    def distance_to_m(self, lat_deg: float, lon_deg: float) -> float | None:
        """Ground distance from the vehicle to a position, None without a vehicle state."""
        if self.vehicle is None:
            return None
        return ground_distance_m(self.vehicle.lat_deg, self.vehicle.lon_deg, lat_deg, lon_deg)


def ground_distance_m(lat1_deg: float, lon1_deg: float, lat2_deg: float, lon2_deg: float) -> float:
    """Distance over the ground between two positions (equirectangular; metres apart)."""
    mean_lat = math.radians((lat1_deg + lat2_deg) / 2)
    north = math.radians(lat2_deg - lat1_deg) * EARTH_RADIUS_M
    east = math.radians(lon2_deg - lon1_deg) * EARTH_RADIUS_M * math.cos(mean_lat)
    return math.hypot(north, east)


def offset_position(
    lat_deg: float, lon_deg: float, north_m: float, east_m: float
) -> tuple[float, float]:
    """A position moved by metres north and east."""
    lat = lat_deg + math.degrees(north_m / EARTH_RADIUS_M)
    lon = lon_deg + math.degrees(east_m / (EARTH_RADIUS_M * math.cos(math.radians(lat_deg))))
    return lat, lon
