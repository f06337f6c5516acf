"""An agent's row, its link and health, a track point, a photo: as the page shows them.

Separate from the live view because the live view (:mod:`clark_engine.station.view_model`,
from the station's fleet table) and the replay (:mod:`clark_engine.station.replay_frames`,
from a run's logs) both build their rows, track points and photos here, so the page
cannot tell them apart.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any, Final

from clark_engine.link.messages import (
    AgentAttitude,
    AgentStatus,
    BehaviorState,
    PictureData,
    VehicleHealth,
)
from clark_engine.mission.geo import Origin, to_local
from clark_engine.runtime.log_lines import line_safe
from clark_engine.station.view_protocol import Json, rounded

GPS_FIX_NAMES: Final = (  # app.js's GPS_FIXES
    "no GPS",
    "no fix",
    "2-D fix",
    "3-D fix",
    "DGPS",
    "RTK float",
    "RTK fixed",
    "static",
    "PPP",
)
"""MAVLink's GPS_FIX_TYPE by number, as the page shows it."""


# -- rows, track points and photos: shared by the live view and the replay --------------------


def mode_name(modes: Mapping[str, int], number: int) -> str | None:
    """The name of a custom mode number in an agent's profile (None when it has none)."""
    return next((name for name, n in modes.items() if n == number), None)


def link_json(
    *,
    packets: int,
    lost_packets: int,
    loss_ratio: float | None,
    latency_mean_ms: float | None,
    bad_tags: int,
    malformed: int,
    duplicates: int,
) -> Json:
    """An agent row's ``link``: packets received from it, their loss and latency."""
    return {
        "packets": packets,
        "lost_packets": lost_packets,
        "loss_ratio": rounded(loss_ratio, 4),
        "latency_mean_ms": rounded(latency_mean_ms, 1),
        "bad_tags": bad_tags,
        "malformed": malformed,
        "duplicates": duplicates,
    }


MAX_ACTIVE_STATES_SHOWN: Final = 32
"""Active states shown per agent: deeper than any mission nests (a forged Behavior State
may name hundreds)."""
MAX_STATE_NAME_CHARS: Final = 100
"""Longest state or event name shown, escaped (a dotted path of a deep state fits)."""


def agent_row(
    info: Mapping[str, Any],
    origin: Origin,
    *,
    heard: bool,
    link: Json | None = None,
    lost: bool = False,
    since_heartbeat_s: float | None = None,
    condition: str | None = None,
    status: AgentStatus | None = None,
    status_age_s: float | None = None,
    mode: str | None = None,
    behavior: BehaviorState | None = None,
    behavior_age_s: float | None = None,
    attitude: AgentAttitude | None = None,
    health: VehicleHealth | None = None,
    health_age_s: float | None = None,
    in_alarm: bool = False,
) -> Json:
    """One agent's row of a ``state`` message (docs/station-view.md, "The protocol").

    The live view (:class:`StationView`, from the station's fleet table) and the replay
    (:mod:`clark_engine.station.replay`, from a run's logs) both build their rows here, so
    the page gets the same shape from either.

    Args:
        info: The agent's entry in ``hello`` (name, id, role, airframe, stale_after_s;
            a null ``stale_after_s`` is never stale).
        origin: The mission's origin, for metres north and east.
        heard: Whether anything was heard from it; when False, the rest is left null.
        link: Its :func:`link_json`, or None when unknown.
        lost: Whether the fleet table counts it lost.
        since_heartbeat_s: Seconds since its latest heartbeat.
        condition: Its heartbeat's condition, lower case (``ok``, ``failsafe``...).
        status: Its latest Agent Status, if any.
        status_age_s: Seconds since that Agent Status arrived.
        mode: The name of ``status.mode`` in its profile, if known.
        behavior: Its latest Behavior State, if any.
        behavior_age_s: Seconds since it arrived (the replay: since the change).
        attitude: Its latest Agent Attitude, if any.
        health: Its latest Vehicle Health, if any (``armed`` comes from it).
        health_age_s: Seconds since that Vehicle Health arrived.
        in_alarm: Whether an alarm in force is about it.
    """
    out: Json = {
        "id": int(info["id"]),
        "name": info["name"],
        "role": info["role"],
        "airframe": info.get("airframe"),
        "heard": heard,
        "lost": False,
        "stale": False,
        "since_heartbeat_s": None,
        "condition": None,
        "position": None,
        "mode": None,
        "armed": None,  # from Vehicle Health; unknown without it
        "behaviour": None,
        "attitude": None,
        "health": None,
        "alarm": in_alarm,
        "link": link,
    }
    if not heard:
        return out
    stale_after = info.get("stale_after_s")
    out["since_heartbeat_s"] = rounded(since_heartbeat_s, 2)
    out["lost"] = lost
    out["stale"] = (
        not lost
        and since_heartbeat_s is not None
        and stale_after is not None
        and since_heartbeat_s > float(stale_after)
    )
    out["condition"] = condition
    if status is not None:
        local = to_local(status.lat_deg, status.lon_deg, status.alt_m, origin)
        out["position"] = {
            "lat": round(status.lat_deg, 7),
            "lon": round(status.lon_deg, 7),
            "north_m": rounded(local.north_m),
            "east_m": rounded(local.east_m),
            "alt_m": rounded(status.alt_m),
            "ground_speed_m_s": rounded(status.ground_speed_m_s),
            "climb_rate_m_s": rounded(status.climb_rate_m_s),
            "heading_deg": rounded(status.heading_deg, 1),
            "age_s": rounded(status_age_s, 2),
        }
        out["mode"] = {"number": status.mode, "name": mode}
    if behavior is not None:
        # Names from the air: a control character or a bidirectional override (U+202E
        # shows the operator a reversed name) is escaped, and a flood of them is cut.
        out["behaviour"] = {
            "active": [
                line_safe(name, MAX_STATE_NAME_CHARS)
                for name in behavior.active_states[:MAX_ACTIVE_STATES_SHOWN]
            ],
            "last_event": line_safe(behavior.last_event, MAX_STATE_NAME_CHARS),
            "age_s": rounded(behavior_age_s, 2),
        }
    if attitude is not None:
        out["attitude"] = {
            "roll_deg": rounded(attitude.roll_deg, 1),
            "pitch_deg": rounded(attitude.pitch_deg, 1),
            "yaw_deg": rounded(attitude.yaw_deg, 1),
        }
    if health is not None:
        out["armed"] = health.armed
        out["health"] = health_json(health, health_age_s)
    return out


def health_json(health: VehicleHealth, age_s: float | None) -> Json:
    """An agent row's ``health``: its latest Vehicle Health, texts escaped and bounded.

    ``text_age_s`` is the text's age now: its age when the vehicle sent the health, plus
    the health's own age at the station. The row's ``armed`` is the health's; the page
    names the fix type (0 no GPS ... 6 RTK fixed, :data:`GPS_FIX_NAMES`). Kept small: a
    state carries one per vehicle, five times a second.
    """
    fix = health.gps_fix_type
    text = line_safe(health.text, 100) if health.text else None
    return {
        "battery_v": rounded(health.battery_v, 2),
        "battery_pct": health.battery_pct,
        "gps_fix_type": fix,
        "satellites": health.satellites,
        "prearm": health.prearm.name.lower(),
        "text": text,
        "text_severity": health.text_severity if text else None,
        "text_age_s": rounded(health.text_age_s + (age_s or 0.0), 1) if text else None,
        "failsafe": line_safe(health.failsafe, 64) or None,
        "autopilot_lost": health.autopilot_lost,
        "age_s": rounded(age_s, 2),
    }


def track_point_json(
    seq: int,
    agent_id: int,
    t_s: float,
    lat_deg: float,
    lon_deg: float,
    alt_m: float,
    origin: Origin,
) -> Json:
    """One track point (an Agent Status received) as the page receives it."""
    local = to_local(lat_deg, lon_deg, alt_m, origin)
    return {
        "seq": seq,
        "agent": agent_id,
        "t": rounded(t_s, 3),
        "north_m": rounded(local.north_m),
        "east_m": rounded(local.east_m),
        "alt_m": rounded(alt_m),
    }


def photo_json(seq: int, agent_id: int, t_s: float, picture: PictureData, origin: Origin) -> Json:
    """One photo (a Picture Data received) as the page receives it."""
    local = to_local(picture.lat_deg, picture.lon_deg, picture.alt_m, origin)
    return {
        "seq": seq,
        "agent": agent_id,
        "t": rounded(t_s, 3),
        "image_index": picture.image_index,
        "gps_time_ms": picture.gps_time_ms,
        "lat": round(picture.lat_deg, 7),
        "lon": round(picture.lon_deg, 7),
        "north_m": rounded(local.north_m),
        "east_m": rounded(local.east_m),
        "alt_m": rounded(picture.alt_m),
    }


__all__ = [
    "GPS_FIX_NAMES",
    "MAX_ACTIVE_STATES_SHOWN",
    "MAX_STATE_NAME_CHARS",
    "agent_row",
    "health_json",
    "link_json",
    "mode_name",
    "photo_json",
    "track_point_json",
]
