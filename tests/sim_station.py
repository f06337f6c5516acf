"""A ground station on a simulated vehicle, for the simulation's own tests.

The vehicle is built exactly as ``clark dry-run`` builds one (the conformance suite's
missions: a Traxxas Slash, a DJI F450, a Super Cub, GPS noise off) and flown on a
virtual clock by the dry run's physics step; the station talks to its simulated
ArduPilot in MAVLink bytes only, sending its HEARTBEAT once a second from the system
ids in :attr:`Station.heartbeat_from`.
"""

from __future__ import annotations

import math
from pathlib import Path
from typing import Any

from pymavlink.dialects.v20 import ardupilotmega as mavlink2

from clark_engine.dryrun.engine import PHYSICS_STEP_S
from clark_engine.dryrun.world import build_vehicle
from clark_engine.mission.compiler import agent_config
from clark_engine.runtime.config import config_from_dict
from clark_engine.sim.ardupilot.autopilot import SimAutopilot
from clark_engine.sim.ardupilot.vehicle_model import VehicleModel
from clark_engine.validation import validate_file

MISSIONS = Path(__file__).resolve().parent / "conformance" / "missions"
M_PER_DEG = 111_194.93
"""Metres per degree of latitude on the vehicle models' sphere."""


class Station:
    """A ground station (system 255) on one simulated vehicle of ``kind``.

    Attributes:
        autopilot: The simulated ArduPilot.
        model: Its vehicle.
        now_s: The virtual time.
        received: Every message from the autopilot, with its time.
        heartbeat_from: The system ids sending a HEARTBEAT each second (empty: silent).
    """

    def __init__(self, kind: str) -> None:
        mission = validate_file(MISSIONS / f"{kind}.yaml").mission
        assert mission is not None
        agent = mission.agents["vehicle"]
        config = config_from_dict(agent_config(mission, agent))
        backend, _pilot = build_vehicle(mission, agent, config, 0)
        assert backend.autopilot is not None
        self.autopilot: SimAutopilot = backend.autopilot
        self.model: VehicleModel = backend.model
        self.kind = kind
        self.modes = dict(self.autopilot.modes)
        self.now_s = 0.0
        self._steps = 0
        self.received: list[tuple[float, Any]] = []
        self.heartbeat_from: tuple[int, ...] = (255,)
        self._next_heartbeat_s = 0.0
        self._senders: dict[int, Any] = {}
        self._parser = mavlink2.MAVLink(None)
        self._parser.robust_parsing = True
        self._take(self.autopilot.advance(0.0))

    # -- time ------------------------------------------------------------------------------

    def run(self, seconds: float) -> None:
        """Let ``seconds`` of virtual time pass (physics, the autopilot, our heartbeats)."""
        end = self._steps + round(seconds / PHYSICS_STEP_S)
        while self._steps < end:
            self._steps += 1
            self.now_s = self._steps * PHYSICS_STEP_S
            if self.now_s >= self._next_heartbeat_s:
                self._next_heartbeat_s = self.now_s + 1.0
                for sysid in self.heartbeat_from:
                    self._send(sysid, self._sender(sysid).heartbeat_encode(6, 8, 0, 0, 4))
            self.model.step(PHYSICS_STEP_S)
            self._take(self.autopilot.advance(self.now_s))

    def run_until(self, condition: Any, within_s: float) -> float:
        """Run until ``condition()`` holds; its time (fails after ``within_s``)."""
        end_s = self.now_s + within_s
        while not condition():
            assert self.now_s < end_s, f"not within {within_s} s"
            self.run(PHYSICS_STEP_S)
        return self.now_s

    def ready(self) -> None:
        """Until the EKF has a position and the pre-arm checks pass (~42 s after boot)."""
        boot = self.autopilot.boot_times
        self.run(max(boot.position_s, boot.prearm_s) + 1.0 - self.now_s)

    # -- talking ---------------------------------------------------------------------------

    def _sender(self, sysid: int) -> Any:
        if sysid not in self._senders:
            self._senders[sysid] = mavlink2.MAVLink(None, srcSystem=sysid, srcComponent=190)
        return self._senders[sysid]

    def _send(self, sysid: int, msg: Any) -> None:
        self.autopilot.receive(msg.pack(self._sender(sysid)), self.now_s)

    def send(self, msg: Any, sysid: int = 255) -> list[Any]:
        """Send a message; the autopilot's answers (from its next advance)."""
        start = len(self.received)
        self._send(sysid, msg)
        self.run(PHYSICS_STEP_S)
        return [m for _, m in self.received[start:]]

    def _take(self, data: bytes) -> None:
        for msg in self._parser.parse_buffer(data) or []:
            self.received.append((self.now_s, msg))

    def command(self, command: int, *params: float, sysid: int = 255) -> int:
        """COMMAND_LONG; its MAV_RESULT."""
        values = [float(p) for p in params] + [0.0] * (7 - len(params))
        msg = mavlink2.MAVLink_command_long_message(1, 1, command, 0, *values)
        answers = self.send(msg, sysid)
        return next(int(m.result) for m in answers if m.get_type() == "COMMAND_ACK")

    def command_int(
        self, command: int, frame: int, *params: float, x: int, y: int, z: float
    ) -> int:
        """COMMAND_INT; its MAV_RESULT."""
        values = [float(p) for p in params] + [0.0] * (4 - len(params))
        msg = mavlink2.MAVLink_command_int_message(1, 1, frame, command, 0, 0, *values, x, y, z)
        answers = self.send(msg)
        return next(int(m.result) for m in answers if m.get_type() == "COMMAND_ACK")

    def set(self, name: str, value: float) -> None:
        """PARAM_SET, echoed."""
        msg = mavlink2.MAVLink_param_set_message(1, 1, name.encode(), float(value), 9)
        assert any(m.get_type() == "PARAM_VALUE" for m in self.send(msg)), name
        self.run(0.2)  # (ArduPilot looks at FENCE_ENABLE at 10 Hz)

    def mode(self, name: str) -> int:
        """DO_SET_MODE to the profile's mode; its MAV_RESULT."""
        return self.command(mavlink2.MAV_CMD_DO_SET_MODE, 1, self.modes[name])

    def arm(self, arm: bool = True) -> int:
        return self.command(mavlink2.MAV_CMD_COMPONENT_ARM_DISARM, 1 if arm else 0)

    def goto(self, north_m: float, east_m: float, up_m: float) -> None:
        """SET_POSITION_TARGET_GLOBAL_INT above home, (north, east) from the origin."""
        lat, lon = self.latlon(north_m, east_m)
        self.send(
            mavlink2.MAVLink_set_position_target_global_int_message(
                0, 1, 1, 6, 0x0DF8, round(lat * 1e7), round(lon * 1e7), up_m, 0, 0, 0, 0, 0, 0, 0, 0
            )
        )

    def latlon(self, north_m: float, east_m: float) -> tuple[float, float]:
        ap = self.autopilot
        lat = ap.origin_lat_deg + north_m / M_PER_DEG
        lon = ap.origin_lon_deg + east_m / (M_PER_DEG * math.cos(math.radians(ap.origin_lat_deg)))
        return lat, lon

    def upload_fence(self, items: list[tuple[int, float, float, float]]) -> int:
        """The fence list: (MAV_CMD, param1, north_m, east_m) items; the MISSION_ACK's type."""
        fence = mavlink2.MAV_MISSION_TYPE_FENCE
        answers = self.send(mavlink2.MAVLink_mission_count_message(1, 1, len(items), fence))
        for _ in range(len(items) + 1):
            ack = [m for m in answers if m.get_type() == "MISSION_ACK"]
            if ack:
                return int(ack[0].type)
            request = next(m for m in answers if m.get_type().startswith("MISSION_REQUEST"))
            command, param1, north_m, east_m = items[request.seq]
            lat, lon = self.latlon(north_m, east_m)
            item = mavlink2.MAVLink_mission_item_int_message(
                1,
                1,
                request.seq,
                0,
                command,
                0,
                1,
                param1,
                0,
                0,
                0,
                round(lat * 1e7),
                round(lon * 1e7),
                0,
                fence,
            )
            answers = self.send(item)
        raise AssertionError("no MISSION_ACK")

    # -- what it said ----------------------------------------------------------------------

    def texts(self, since_s: float = 0.0) -> list[tuple[int, str]]:
        """STATUSTEXTs (severity, text) since a time."""
        return [
            (int(m.severity), str(m.text))
            for t, m in self.received
            if t >= since_s and m.get_type() == "STATUSTEXT"
        ]

    def text_time(self, text: str, since_s: float = 0.0) -> float | None:
        """When ``text`` was first said since a time; None if it was not."""
        return next(
            (
                t
                for t, m in self.received
                if t >= since_s and m.get_type() == "STATUSTEXT" and m.text == text
            ),
            None,
        )

    @property
    def mode_now(self) -> str:
        return self.model.mode

    @property
    def up_m(self) -> float:
        return self.model.truth().up_m

    def north_m(self) -> float:
        return self.model.truth().north_m
