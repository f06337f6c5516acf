"""What the autopilot adapter needs to know about one autopilot, from the agent's profile.

:class:`AutopilotSettings` (its MAVLink ids, its modes, its firmware, the rates asked
for) and the HEARTBEAT vehicle types each ArduPilot firmware reports. Separate from the
adapter (:mod:`~clark_engine.io.autopilot`) because it is read from a profile or a
compiled config, before any byte moves, and checked there.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any, Final

from clark_engine.runtime.config import AgentConfig, ConfigError

FIRMWARE_VEHICLE_TYPES: Final[Mapping[str, frozenset[int]]] = {
    # Numbers, not names: MAVLink renamed the VTOL types 19-25 between releases.
    "arduplane": frozenset({1, *range(19, 26)}),  # FIXED_WING; QuadPlane VTOL types
    # QUADROTOR, COAXIAL, HELICOPTER, HEXAROTOR, OCTOROTOR, TRICOPTER, DODECAROTOR, DECAROTOR
    "arducopter": frozenset({2, 3, 4, 13, 14, 15, 29, 35}),
    "ardurover": frozenset({10, 11}),  # GROUND_ROVER, SURFACE_BOAT
}
"""HEARTBEAT vehicle types each ArduPilot firmware reports; a mismatch with the profile
means the mode numbers would be read in the wrong table."""


@dataclass(frozen=True, slots=True)
class AutopilotSettings:
    """What the adapter needs to know about one autopilot, from the agent's profile.

    Attributes:
        modes: Mode name -> ArduPilot custom_mode number, from the autopilot profile.
        firmware: ``arduplane``, ``arducopter`` or ``ardurover``; decides how a Goto is
            sent and which HEARTBEAT vehicle types are accepted. None: any ArduPilot.
        system_id: The autopilot's MAVLink system id (SYSID_THISMAV).
        component_id: The autopilot's component id (1, MAV_COMP_ID_AUTOPILOT1).
        source_system_id: Ours. The safety set-up makes it the autopilot's ground-station
            id (MAV_GCS_SYSID): ArduPilot takes RC overrides, and counts heartbeats for its
            failsafe, only from that id.
        source_component_id: Ours (191, MAV_COMP_ID_ONBOARD_COMPUTER).
        stream_rate_hz: Rate asked for each of :data:`~.autopilot_streams.STREAMED_MESSAGES`.
        heartbeat_timeout_s: Autopilot silence after which :meth:`AutopilotAdapter.lost`.
        origin_alt_amsl_m: The mission origin's height above mean sea level: altitudes
            above the origin are the autopilot's AMSL altitudes less this.
    """

    modes: Mapping[str, int]
    firmware: str | None = None
    system_id: int = 1
    component_id: int = 1
    source_system_id: int = 255
    source_component_id: int = 191
    stream_rate_hz: float = 10.0
    heartbeat_timeout_s: float = 3.0
    origin_alt_amsl_m: float = 0.0

    def __post_init__(self) -> None:
        for name in ("system_id", "source_system_id"):
            if not 1 <= getattr(self, name) <= 255:
                raise ValueError(f"{name} must be 1..255, not {getattr(self, name)}")
        for name in ("component_id", "source_component_id"):
            if not 0 <= getattr(self, name) <= 255:
                raise ValueError(f"{name} must be 0..255, not {getattr(self, name)}")
        if not self.stream_rate_hz > 0:
            raise ValueError(f"stream_rate_hz must be positive, not {self.stream_rate_hz}")
        if not self.heartbeat_timeout_s > 0:
            raise ValueError(
                f"heartbeat_timeout_s must be positive, not {self.heartbeat_timeout_s}"
            )
        if self.firmware is not None and self.firmware not in FIRMWARE_VEHICLE_TYPES:
            raise ValueError(f"unknown firmware {self.firmware!r}")

    @classmethod
    def from_profile(
        cls, autopilot: Mapping[str, Any], origin_alt_amsl_m: float = 0.0
    ) -> AutopilotSettings:
        """Settings from a resolved autopilot profile (``agent.hardware.autopilot``).

        Args:
            autopilot: The resolved autopilot profile.
            origin_alt_amsl_m: The mission origin's height above mean sea level.
        """
        mav = autopilot.get("mavlink") or {}
        return cls(
            modes=dict(autopilot.get("modes") or {}),
            firmware=autopilot.get("firmware"),
            system_id=int(mav.get("system_id", 1)),
            component_id=int(mav.get("component_id", 1)),
            source_system_id=int(mav.get("source_system_id", 255)),
            source_component_id=int(mav.get("source_component_id", 191)),
            stream_rate_hz=float(autopilot.get("stream_rate_hz", 10.0)),
            heartbeat_timeout_s=float(autopilot.get("heartbeat_timeout_s", 3.0)),
            origin_alt_amsl_m=float(origin_alt_amsl_m),
        )

    @classmethod
    def from_config(cls, config: AgentConfig) -> AutopilotSettings:
        """Settings from a compiled agent config.

        Raises:
            ConfigError: The agent has no autopilot (a station).
        """
        autopilot = (config.raw.get("agent", {}).get("hardware") or {}).get("autopilot")
        if not autopilot:
            raise ConfigError(
                f"agent {config.agent} has no autopilot in its hardware profile; "
                "only vehicles connect to one"
            )
        return cls.from_profile(autopilot, config.origin_alt_amsl_m)
