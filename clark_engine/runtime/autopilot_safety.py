"""What the engine sets on the autopilot so that the envelope survives a dead mission computer.

Navigation is streamed guided targets: when the mission computer dies (a crash, a
cable), ArduPilot flies on to the last target and holds there, wherever that is. So
before the behaviour starts, the runtime has the autopilot set its own fence from the
vehicle's envelope and its own reaction to losing the mission computer, and the
behaviour starts only once every parameter took (docs/safety.md#held-by-the-autopilot).
:func:`safety_setup` works out what to set, per firmware, as one
:class:`~clark_engine.runtime.commands.SetUpAutopilotSafety`; the MAVLink adapter
carries it out and reads every value back.

What is set, and why each value (ArduPilot 4.7 at 90700977, the SITL build measured in
the project's notes; line numbers there):

- **The mission computer becomes the autopilot's ground station**: MAV_GCS_SYSID
  (SYSID_MYGCS before ArduPilot 4.7) is set to the adapter's own system id. ArduPilot's
  ground-station failsafe counts only HEARTBEAT, RC_CHANNELS_OVERRIDE and MANUAL_CONTROL
  from exactly that id (``GCS_MAVLINK::handle_heartbeat``), so the mission computer's
  silence is what it reacts to.
- **The return altitude inside the envelope**: ArduCopter RTL_ALT (cm) and ArduPlane
  RTL_ALTITUDE (m) at most the ceiling less the margin, above home (ArduPlane's default,
  100 m, is above a 60 m ceiling). Only ever lowered: a pilot's lower choice stays.
- **The reaction to the mission computer's silence** (``failsafe.computer_lost``, after
  ``computer_lost_s``): ArduCopter FS_GCS_TIMEOUT and FS_GCS_ENABLE (1 RTL, 5 Land,
  7 Brake or Land); ArduRover FS_GCS_TIMEOUT, FS_ACTION (1 RTL, 2 Hold) and
  FS_GCS_ENABLE 1, acting FS_TIMEOUT (1.5 s) later; ArduPlane FS_LONG_TIMEOUT,
  FS_LONG_ACTN (1 RTL, 5 AUTOLAND) and FS_GCS_ENABL 1. ArduRover's FS_ACTION and
  ArduPlane's FS_LONG_ACTN also decide their radio failsafe's action.
- **The fence, at the envelope itself**: FENCE_ENABLE 0 first, for long enough that
  ArduPilot's 10 Hz ``AC_Fence::update`` sees it (it applies a new FENCE_TYPE only when
  it sees FENCE_ENABLE change); the fence list
  replaced by the envelope's zones (cleared when it declares none); FENCE_TYPE: the
  maximum altitude (aircraft), the circle around home (the envelope's default circle,
  FENCE_RADIUS its radius), the uploaded zones; FENCE_ALT_MAX the ceiling above home;
  FENCE_ACTION from ``on_breach``; FENCE_ENABLE 1 last.
- **Not the floor.** ArduPilot's minimum-altitude fence (FENCE_TYPE bit 3, FENCE_ALT_MIN)
  enables itself once the vehicle climbs past it and then acts in every mode but a
  landing one (``AC_Fence::check``, ``auto_enable_fence_floor``): a safety pilot flying
  an aircraft down by hand in a manual mode, or an ArduPlane landed by hand outside its
  LAND stage, would be thrown into the breach action. The envelope's floor binds only
  guided flight, so it stays the runtime's and the dry run's.

Pure: no clock, no I/O; the above-home conversion uses the home the autopilot reported.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from typing import Any, Final

from clark_engine.runtime.commands import (
    FenceZone,
    Pause,
    SetParam,
    SetUpAutopilotSafety,
    UploadFence,
)
from clark_engine.runtime.config import AgentConfig

GCS_ID_NAMES: Final = ("MAV_GCS_SYSID", "SYSID_MYGCS")
"""The parameter naming the autopilot's ground station: ArduPilot 4.7's name, then the older."""

FENCE_TYPE_ALT_MAX: Final = 1
FENCE_TYPE_CIRCLE: Final = 2
FENCE_TYPE_POLYGON: Final = 4
"""FENCE_TYPE bits (AC_Fence.h): maximum altitude, circle around home, uploaded zones."""

FENCE_ACTIONS: Final[Mapping[str, Mapping[str, int]]] = {
    # 1 RTL or Land, 2 Always Land, 4 Brake or Land (a hold in place)
    "arducopter": {"rtl": 1, "land": 2, "hold": 4},
    # 1 RTL or Hold, 2 Hold; a rover cannot land: it stops
    "ardurover": {"rtl": 1, "land": 2, "hold": 2},
    # 1 RTL, 8 AUTOLAND if possible else RTL; a plane cannot stop: it returns and circles
    "arduplane": {"rtl": 1, "land": 8, "hold": 1},
}
"""FENCE_ACTION per firmware for the envelope's ``on_breach`` (AC_Fence.cpp's @Values)."""

COMPUTER_LOST: Final[Mapping[str, Mapping[str, tuple[tuple[str, float], ...]]]] = {
    # FS_GCS_ENABLE: 1 RTL, 5 Land, 7 Brake or Land
    "arducopter": {
        "rtl": (("FS_GCS_ENABLE", 1),),
        "land": (("FS_GCS_ENABLE", 5),),
        "hold": (("FS_GCS_ENABLE", 7),),
    },
    # FS_ACTION: 1 RTL, 2 Hold (every failsafe's action); FS_GCS_ENABLE 1
    "ardurover": {
        "rtl": (("FS_ACTION", 1), ("FS_GCS_ENABLE", 1)),
        "land": (("FS_ACTION", 2), ("FS_GCS_ENABLE", 1)),
        "hold": (("FS_ACTION", 2), ("FS_GCS_ENABLE", 1)),
    },
    # FS_LONG_ACTN: 1 RTL, 5 AUTOLAND (else RTL); FS_GCS_ENABL 1 (heartbeat)
    "arduplane": {
        "rtl": (("FS_LONG_ACTN", 1), ("FS_GCS_ENABL", 1)),
        "land": (("FS_LONG_ACTN", 5), ("FS_GCS_ENABL", 1)),
        "hold": (("FS_LONG_ACTN", 1), ("FS_GCS_ENABL", 1)),
    },
}
"""The ground-station failsafe's action and switch per firmware, in the order they are set
(the switch last), for ``failsafe.computer_lost``."""

COMPUTER_LOST_TIMEOUT: Final[Mapping[str, str]] = {
    "arducopter": "FS_GCS_TIMEOUT",
    "ardurover": "FS_GCS_TIMEOUT",
    "arduplane": "FS_LONG_TIMEOUT",
}
"""The parameter holding ``computer_lost_s`` per firmware."""

RETURN_ALTITUDE: Final[Mapping[str, tuple[str, float]]] = {
    "arducopter": ("RTL_ALT", 100.0),  # centimetres
    "arduplane": ("RTL_ALTITUDE", 1.0),  # metres
}
"""The return-to-launch altitude above home per aircraft firmware, and its units per metre."""

FENCE_UPDATE_S: Final = 0.3
"""How long FENCE_ENABLE stays 0 before the fence is set: ArduPilot reconfigures its fence
only when its 10 Hz ``AC_Fence::update`` sees FENCE_ENABLE change, so it must see the 0
before the new FENCE_TYPE is switched on, or it keeps the old type."""

_ACTION_WORDS: Final = {"rtl": "return to launch", "land": "land", "hold": "hold"}


class SafetyPlanError(ValueError):
    """The vehicle's config does not say enough to set up its autopilot (said in words)."""


def safety_setup(
    config: AgentConfig, home: tuple[float, float, float] | None
) -> SetUpAutopilotSafety:
    """The autopilot's fence and computer-lost failsafe for this vehicle, per its firmware.

    Args:
        config: The vehicle's compiled config (envelope, failsafe, firmware).
        home: Home as the autopilot reports it (latitude, longitude, altitude above mean
            sea level); None when it has not (then home is taken at the origin's height).

    Raises:
        SafetyPlanError: No firmware, no envelope, or a ceiling too low to return under.
    """
    firmware = config.firmware or ""
    envelope = config.envelope
    if firmware not in FENCE_ACTIONS:
        raise SafetyPlanError(
            f"the autopilot profile names no ArduPilot firmware ({config.firmware!r}), so the "
            "engine cannot tell which parameters hold its fence and failsafe; name its "
            "firmware in the profile"
        )
    if envelope is None:
        raise SafetyPlanError("the config has no envelope; compile the mission again")
    aircraft = firmware != "ardurover"
    home_above_origin_m = 0.0 if home is None else home[2] - config.origin_alt_amsl_m
    ceiling_above_home_m = envelope.ceiling_m - home_above_origin_m
    action = config.failsafe.get("computer_lost") or ("rtl" if aircraft else "hold")
    steps: list[SetParam | UploadFence | Pause] = []
    words: list[str] = []

    if firmware in RETURN_ALTITUDE:
        name, per_m = RETURN_ALTITUDE[firmware]
        cap_m = ceiling_above_home_m - envelope.margin_m
        if cap_m < 1.0:
            raise SafetyPlanError(
                f"the ceiling of {envelope.ceiling_m:g} m above the origin, less the margin "
                f"of {envelope.margin_m:g} m, leaves {cap_m:.1f} m above home to return at; "
                "raise the ceiling"
            )
        value = float(math.floor(cap_m * per_m))
        steps.append(SetParam((name,), value, at_most=True))
        words.append(f"return altitude at most {value / per_m:g} m above home ({name} {value:g})")

    steps.append(SetParam((COMPUTER_LOST_TIMEOUT[firmware],), float(config.computer_lost_s)))
    steps.extend(SetParam((name,), float(value)) for name, value in COMPUTER_LOST[firmware][action])
    words.append(
        f"{_ACTION_WORDS[action]} {config.computer_lost_s:g} s after this computer's last heartbeat"
    )

    zones = _zones(envelope.raw["geofence"])
    fence_type = FENCE_TYPE_ALT_MAX if aircraft else 0
    if envelope.default_radius_m is not None:
        fence_type |= FENCE_TYPE_CIRCLE
    if zones:
        fence_type |= FENCE_TYPE_POLYGON
    fence_action = FENCE_ACTIONS[firmware][envelope.on_breach]
    steps.append(SetParam(("FENCE_ENABLE",), 0.0))
    steps.append(Pause(FENCE_UPDATE_S))
    steps.append(UploadFence(zones))
    steps.append(SetParam(("FENCE_TYPE",), float(fence_type)))
    fence_words = []
    if aircraft:
        alt_max_m = round(ceiling_above_home_m, 2)
        steps.append(SetParam(("FENCE_ALT_MAX",), alt_max_m))
        fence_words.append(f"ceiling {alt_max_m:g} m above home")
    if envelope.default_radius_m is not None:
        steps.append(SetParam(("FENCE_RADIUS",), round(envelope.default_radius_m, 2)))
        fence_words.append(f"circle of {envelope.default_radius_m:g} m around home")
    if zones:
        fence_words.append(f"{len(zones)} zone{'s' if len(zones) > 1 else ''}")
    steps.append(SetParam(("FENCE_ACTION",), float(fence_action)))
    steps.append(SetParam(("FENCE_ENABLE",), 1.0))
    words.insert(
        0, f"fence ({', '.join(fence_words)}; {_ACTION_WORDS[envelope.on_breach]} on a breach)"
    )

    enable = COMPUTER_LOST[firmware][action][-1][0]
    return SetUpAutopilotSafety(
        gcs_id_names=GCS_ID_NAMES,
        steps=tuple(steps),
        on_close=(SetParam((enable,), 0.0),),
        summary="; ".join(words),
    )


def _zones(geofence: Mapping[str, Any]) -> tuple[FenceZone, ...]:
    """The envelope's declared zones (not its default circle) as the autopilot's fence items."""
    zones: list[FenceZone] = []
    for side, inclusion in (("include", True), ("exclude", False)):
        for zone in geofence[side]:
            if zone["kind"] == "circle":
                center = zone["center"]
                zones.append(
                    FenceZone(
                        inclusion,
                        center_deg=(float(center["lat"]), float(center["lon"])),
                        radius_m=float(zone["radius_m"]),
                    )
                )
            else:
                corners = tuple((float(p["lat"]), float(p["lon"])) for p in zone["points"])
                zones.append(FenceZone(inclusion, corners_deg=corners))
    return tuple(zones)
