"""``clark replay``: each vehicle's health and the station's alarms, from the fleet CSV.

A hand-written station fleet CSV of cooperative_follow (10 Hz rows, as the logbook
writes them): Slash B drives up to 0.5 m of Slash A, inside the 1 m the pair keeps, and
away again (a near miss), then
reports a failsafe in its health; Slash A's autopilot says something hostile. The
replay judges the rows with the live view's alarm watch, so the banner at any time is
what the operator saw then.
"""

from __future__ import annotations

import csv
import json
from pathlib import Path

from test_gcs_replay import FLEET_HEADER, _fleet_row, _mission, _row, _state_at

from clark_engine.mission.geo import LocalPoint, Origin, to_global
from clark_engine.station.alarms import CLEARED_SHOWN_S
from clark_engine.station.replay import load_replay

ORIGIN = Origin(30.6372, -96.4787, 90.0)  # cooperative_follow's


def _at(north_m: float, east_m: float) -> dict[str, str]:
    lat, lon, _ = to_global(LocalPoint(north_m, east_m), ORIGIN)
    return {"lat_deg": f"{lat:.7f}", "lon_deg": f"{lon:.7f}", "alt_m": "0.0", "status_age_s": "0.0"}


HEALTH = {
    "armed": "1",
    "battery_v": "12.6",
    "battery_pct": "87",
    "gps_fix_type": "6",
    "satellites": "10",
    "prearm": "passing",
    "autopilot_lost": "0",
    "health_age_s": "0.5",
}


def _folder(folder: Path) -> Path:
    folder.mkdir()
    rows = [FLEET_HEADER]
    for k in range(0, 201):  # 20 s at 10 Hz
        t = k / 10
        east_b = 20.0 if t < 3.0 or t >= 7.0 else 0.5  # inside 1 m from 3 s to 7 s
        failsafe = "hold: mcs_lost" if t >= 12.0 else ""
        rows.append(
            _fleet_row(
                f"{t:.1f}",
                "slash_a",
                2,
                **_at(0.0, 0.0),
                **HEALTH,
                autopilot_severity="4",
                autopilot_text="GPS Glitch\\x0a<script>alert(1)</script>",
                autopilot_text_age_s="7",
            )
        )
        rows.append(
            _fleet_row(
                f"{t:.1f}",
                "slash_b",
                3,
                **_at(0.0, east_b),
                **HEALTH,
                condition="failsafe" if failsafe else "ok",
                failsafe=failsafe,
            )
        )
    with (folder / "mcs.fleet.csv").open("w", newline="", encoding="utf-8") as stream:
        csv.writer(stream).writerows(rows)
    return folder


def test_health_and_alarms_replayed_from_the_station_s_fleet_csv(tmp_path: Path) -> None:
    replay, load = load_replay(_folder(tmp_path / "logs"), _mission(), mission_source="m")
    assert load.problems == []
    envelopes = {a["name"]: a["envelope"] for a in replay.hello["agents"]}
    assert envelopes["slash_a"]["ceiling_m"] == 120.0  # the page draws them

    calm = _state_at(replay, 2.0)
    assert calm["alarms"] == []
    health = _row(calm, "slash_a")["health"]
    assert (health["battery_v"], health["battery_pct"], health["gps_fix_type"]) == (12.6, 87, 6)
    assert health["prearm"] == "passing" and _row(calm, "slash_a")["armed"] is True
    # a hostile text stays the escaped text the logbook wrote, for the page to write as text
    assert health["text"] == "GPS Glitch\\x0a<script>alert(1)</script>"
    assert health["text_age_s"] == 7.5  # 7 s old when sent, its health 0.5 s old then

    (near,) = _state_at(replay, 5.0)["alarms"]
    assert near["kind"] == "near miss" and near["raised_s"] == 3.0 and near["cleared_s"] is None
    assert _row(_state_at(replay, 5.0), "slash_b")["alarm"] is True
    (cleared,) = _state_at(replay, 8.0)["alarms"]
    assert cleared["id"] == near["id"] and cleared["cleared_s"] == 7.0  # 17 m apart again
    assert _row(_state_at(replay, 8.0), "slash_b")["alarm"] is False

    late = _state_at(replay, 7.0 + CLEARED_SHOWN_S + 0.5)["alarms"]
    assert [(a["kind"], a["agents"], a["cleared_s"]) for a in late] == [
        ("failsafe", ["slash_b"], None)
    ]
    assert late[0]["raised_s"] == 12.0 and late[0]["text"] == "slash_b in failsafe: hold: mcs_lost"
    assert _row(_state_at(replay, 15.0), "slash_b")["health"]["failsafe"] == "hold: mcs_lost"
    json.dumps(replay.frame(13.0, None), allow_nan=False)


def test_without_the_mission_there_is_no_envelope_and_no_alarm(tmp_path: Path) -> None:
    replay, _ = load_replay(_folder(tmp_path / "logs"))
    assert all(a["envelope"] is None for a in replay.hello["agents"])
    state = _state_at(replay, 5.0)
    assert state["alarms"] == []
    assert _row(state, "slash_b")["health"]["battery_v"] == 12.6  # health needs no mission
