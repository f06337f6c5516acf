"""The station's alarms: breach, near miss and failsafe, raised once per episode, cleared.

First the watch alone (:class:`~clark_engine.station.alarms.AlarmWatch`, pure, on made-up
envelopes), then through the station's view over cooperative_follow's three real
runtimes (tests/test_gcs_model.py's ``Fleet``): the envelopes it draws, the vehicles'
health in their rows, and the alarms in the state and, once each, in the mission log.
"""

from __future__ import annotations

import json
from typing import Any

import pytest
from test_gcs_model import Fleet, agent

from clark_engine.mission.fence import Fence, Zone
from clark_engine.mission.geo import LocalPoint
from clark_engine.runtime.config import EnvelopeSpec
from clark_engine.runtime.events import AutopilotHealth, AutopilotText
from clark_engine.station.alarms import (
    BREACH,
    CLEARED_SHOWN_S,
    FAILSAFE,
    NEAR_MISS,
    AlarmWatch,
    failsafe_words,
)


def envelope(
    *, radius_m: float = 100.0, ceiling_m: float = 60.0, separation: dict[str, float] | None = None
) -> EnvelopeSpec:
    return EnvelopeSpec(
        ceiling_m=ceiling_m,
        floor_m=0.0,
        legal_ceiling_m=120.0,
        margin_m=2.0,
        fence=Fence((Zone.circle((0.0, 0.0), radius_m),), (Zone.circle((50.0, 0.0), 10.0),)),
        default_radius_m=None,
        home_north_m=0.0,
        home_east_m=0.0,
        min_separation_m=5.0,
        separation=separation or {},
        on_breach="rtl",
        on_near_miss="hold",
        outside="clamp",
        endurance_s=None,
        raw={},
    )


def watch(**envelopes: EnvelopeSpec) -> AlarmWatch:
    return AlarmWatch(envelopes or {"cub": envelope(), "f450": envelope()}, stale_after_s=3.0)


def kinds(changes: list[Any]) -> list[tuple[str, tuple[str, ...], bool]]:
    return [(c.alarm.kind, c.alarm.agents, c.raised) for c in changes]


# -- the watch alone ------------------------------------------------------------------------


def test_a_fence_breach_is_raised_once_and_cleared_once_with_hysteresis() -> None:
    w = watch()
    raised: list[Any] = []
    for k, north in enumerate([90.0, 99.0, 100.5, 104.0, 101.0, 99.5, 99.2, 98.5, 97.0]):
        t = k * 0.5
        w.see_position("cub", north, 0.0, 30.0, t)
        raised.append((north, kinds(w.evaluate(t))))
    changes = [(north, c) for north, c in raised if c]
    assert changes == [
        (100.5, [(BREACH, ("cub",), True)]),  # out: once, however long it stays out
        (98.5, [(BREACH, ("cub",), False)]),  # back in by the hysteresis, not at 99.5
    ]
    (alarm,) = w.shown(4.0)
    assert alarm.what == "fence" and alarm.cleared_s == 3.5 and alarm.worst == pytest.approx(4.0)
    assert alarm.text == "cub 0.5 m outside its geofence at N 100.5 E 0.0 m"


def test_an_exclusion_zone_and_the_ceiling_are_breaches_of_their_own() -> None:
    w = watch()
    w.see_position("cub", 45.0, 0.0, 61.0, 0.0)  # inside the exclusion circle and too high
    got = sorted((c.alarm.what, c.raised) for c in w.evaluate(0.0))
    assert got == [("ceiling", True), ("fence", True)]
    w.see_position("cub", 45.0, 0.0, 59.5, 0.5)  # 0.5 m under: not yet cleared
    assert w.evaluate(0.5) == []
    w.see_position("cub", 45.0, 0.0, 58.9, 1.0)
    assert [(c.alarm.what, c.raised) for c in w.evaluate(1.0)] == [("ceiling", False)]
    assert [a.what for a in w.active] == ["fence"]


def test_a_near_miss_uses_the_larger_separation_of_the_pair() -> None:
    w = watch(cub=envelope(), f450=envelope(separation={"cub": 12.0}))
    w.see_position("cub", 0.0, 0.0, 30.0, 0.0)
    w.see_position("f450", 0.0, 8.0, 30.0, 0.0)  # 8 m: outside cub's 5, inside f450's 12
    assert kinds(w.evaluate(0.0)) == [(NEAR_MISS, ("cub", "f450"), True)]
    for k in range(1, 10):  # still close, both moving: no second alarm
        w.see_position("cub", 0.0, 0.1 * k, 30.0, k * 0.1)
        assert w.evaluate(k * 0.1) == []
    w.see_position("f450", 0.0, 13.5, 30.0, 1.0)  # 12.6 m: under 12 + 1
    assert w.evaluate(1.0) == []
    w.see_position("f450", 0.0, 14.0, 30.0, 1.1)
    assert kinds(w.evaluate(1.1)) == [(NEAR_MISS, ("cub", "f450"), False)]
    assert w.shown(1.1)[0].worst == pytest.approx(-7.1)  # the closest: 7.1 m, cub moved in


def test_the_separation_is_three_dimensional() -> None:
    w = watch()
    w.see_position("cub", 0.0, 0.0, 10.0, 0.0)
    w.see_position("f450", 0.0, 0.0, 16.0, 0.0)  # right above it, 6 m up
    assert w.evaluate(0.0) == []


def test_a_stale_position_neither_raises_nor_clears() -> None:
    w = watch()
    w.see_position("cub", 0.0, 0.0, 10.0, 0.0)
    w.see_position("f450", 0.0, 2.0, 10.0, 0.0)
    assert len(w.evaluate(0.0)) == 1
    w.see_position("cub", 0.0, 40.0, 10.0, 5.0)  # far now, but f450 silent for 5 s
    assert w.evaluate(5.0) == []
    assert [a.kind for a in w.active] == [NEAR_MISS]  # nothing says it ended
    w.see_position("f450", 0.0, 2.0, 10.0, 10.0)  # a status from 10 s ago: stale
    assert w.evaluate(14.0) == []


def test_a_failsafe_is_an_alarm_until_it_ends() -> None:
    w = watch()
    w.see_condition("cub", failsafe_words("ok", None))
    assert w.evaluate(0.0) == []
    w.see_condition("cub", failsafe_words("failsafe", "hold: mcs_lost"))
    (change,) = w.evaluate(1.0)
    assert change.raised and change.alarm.kind == FAILSAFE
    assert change.alarm.text == "cub in failsafe: hold: mcs_lost"
    for t in (1.5, 2.0):  # the same, tick after tick: nothing new
        w.see_condition("cub", failsafe_words("failsafe", "hold: mcs_lost"))
        assert w.evaluate(t) == []
    w.see_condition("cub", failsafe_words("terminated", "hold: mcs_lost"))
    (change,) = w.evaluate(3.0)
    assert not change.raised
    assert [a.cleared_s for a in w.shown(3.0 + CLEARED_SHOWN_S - 0.1)] == [3.0]
    assert w.shown(3.0 + CLEARED_SHOWN_S) == []


def test_failsafe_words() -> None:
    assert failsafe_words("ok", "") is None
    assert failsafe_words("failsafe", None) == "in force (its heartbeat's condition)"
    assert failsafe_words("degraded", "rtl: fence") == "rtl: fence"
    assert failsafe_words("terminated", "rtl: fence") is None


def test_a_hostile_failsafe_text_is_escaped_in_the_alarm() -> None:
    w = watch()
    w.see_condition("cub", "hold\n2025 INFO forged: line\x1b[2J")
    (change,) = w.evaluate(0.0)
    assert "\n" not in change.alarm.text and "\x1b" not in change.alarm.text
    assert "\\x0a" in change.alarm.text


def test_vehicles_without_an_envelope_and_bad_figures_are_not_judged() -> None:
    w = watch()
    w.see_position("mcs", 1e6, 0.0, 0.0, 0.0)  # a station: no envelope
    w.see_position("cub", float("nan"), 0.0, 0.0, 0.0)
    assert w.evaluate(0.0) == []


# -- through the station's view -------------------------------------------------------------


@pytest.fixture
def fleet() -> Fleet:
    return Fleet()


def alarm_lines(fleet: Fleet) -> list[str]:
    return [line.text for line in fleet.log.lines if "ALARM" in line.text or "alarm " in line.text]


def test_hello_carries_every_vehicle_s_envelope(fleet: Fleet) -> None:
    by_name = {a["name"]: a for a in fleet.hello["agents"]}
    slash_b = by_name["slash_b"]["envelope"]
    json.dumps(slash_b)
    # cooperative_follow declares none: the defaults, a circle of the XBee's range around
    # the vehicle's start, the legal ceiling, 5 m apart
    assert slash_b["default_radius_m"] == pytest.approx(1609.34, abs=0.01)
    assert slash_b["include"] == [
        {"kind": "circle", "center": {"north_m": -15.0, "east_m": -10.0}, "radius_m": 1609.34}
    ]
    assert slash_b["exclude"] == [] and slash_b["ceiling_m"] == 120.0
    assert slash_b["min_separation_m"] == 5.0 and slash_b["on_breach"] == "hold"


def test_each_row_shows_its_vehicle_s_health(fleet: Fleet) -> None:
    fleet.step(0.5)
    slash_b = fleet.vehicles["slash_b"]
    slash_b.deliver(AutopilotHealth(12.4, 81, 6, 10, True), fleet.t)
    slash_b.deliver(AutopilotText(4, "<b>GPS Glitch</b>\n"), fleet.t)
    fleet.step(2.0)
    snap = fleet.view.snapshot(fleet.t).state
    row = agent(snap, "slash_b")
    assert row["armed"] is True
    health = row["health"]
    assert isinstance(health, dict)
    assert (health["battery_v"], health["battery_pct"]) == (12.4, 81)
    assert (health["gps_fix_type"], health["satellites"], health["prearm"]) == (6, 10, "passing")
    assert health["text"] == "<b>GPS Glitch</b>\\x0a"  # escaped, and the page writes text
    assert health["text_severity"] == 4 and health["text_age_s"] is not None
    assert health["failsafe"] is None and health["autopilot_lost"] is False
    assert agent(snap, "slash_a")["health"]["battery_v"] is None  # type: ignore[index]


def of_kind(snap: dict[str, Any], kind: str) -> list[dict[str, Any]]:
    """The alarms of one kind (a vehicle's own runtime may add a failsafe alarm of its own:
    it holds the envelope too)."""
    return [a for a in snap["alarms"] if a["kind"] == kind]


def test_a_near_miss_is_raised_once_in_the_state_and_the_log_then_cleared(fleet: Fleet) -> None:
    fleet.step(2.0)
    assert fleet.view.snapshot(fleet.t).state["alarms"] == []
    # 0.6 m from slash_a: inside the 1 m the two trucks keep (cooperative_follow's pair)
    fleet.position["slash_b"] = LocalPoint(0.0, 0.6)
    fleet.step(5.0)
    snap = fleet.view.snapshot(fleet.t).state
    (alarm,) = of_kind(snap, "near miss")
    assert alarm["agents"] == ["slash_a", "slash_b"]
    assert (
        alarm["cleared_s"] is None and "0.6 m apart, inside their 1 m separation" in alarm["text"]
    )
    assert agent(snap, "slash_b")["alarm"] is True and agent(snap, "slash_a")["alarm"] is True
    fleet.position["slash_b"] = LocalPoint(0.0, 20.0)
    fleet.step(3.0)
    snap = fleet.view.snapshot(fleet.t).state
    (alarm,) = of_kind(snap, "near miss")
    assert alarm["cleared_s"] is not None
    (raised,) = [line for line in alarm_lines(fleet) if " near miss: " in line]
    number = raised.split()[1]  # a failsafe alarm of a vehicle's own may come first
    assert raised.startswith(f"ALARM {number} near miss: slash_a and slash_b 0.6 m apart")
    lines = [line for line in alarm_lines(fleet) if f" {number} " in line]
    assert len(lines) == 2, lines  # raised once, cleared once: never a line per tick
    assert lines[1].startswith(f"alarm {number} cleared after") and "closest 0.6 m" in lines[1]


def test_a_vehicle_out_of_its_fence_is_a_breach(fleet: Fleet) -> None:
    fleet.step(1.0)
    fleet.position["slash_a"] = LocalPoint(1700.0, 0.0)  # beyond the XBee's mile from its start
    fleet.step(2.0)
    (alarm,) = of_kind(fleet.view.snapshot(fleet.t).state, "breach")
    assert (alarm["what"], alarm["agents"]) == ("fence", ["slash_a"])
    (raised,) = [line for line in alarm_lines(fleet) if " breach: " in line]
    assert raised.split(" ", 2)[2].startswith("breach: slash_a 90.7 m outside its geofence")


def test_a_failsafe_shows_from_the_heartbeat_and_the_health(fleet: Fleet) -> None:
    fleet.step(1.0)
    fleet.silent.add("mcs")  # the vehicles no longer hear the station: mcs_lost after 3 s
    fleet.step(6.0)
    snap = fleet.view.snapshot(fleet.t).state
    alarms = {a["agents"][0]: a for a in snap["alarms"] if a["kind"] == "failsafe"}
    assert set(alarms) == {"slash_a", "slash_b"}
    assert alarms["slash_b"]["text"] == "slash_b in failsafe: hold: mcs_lost"
    row = agent(snap, "slash_b")
    assert row["condition"] == "failsafe" and row["health"]["failsafe"] == "hold: mcs_lost"  # type: ignore[index]
    assert sum("ALARM" in line for line in alarm_lines(fleet)) == 2


def test_a_failsafe_s_reason_arriving_after_its_condition_updates_the_alarm() -> None:
    w = watch()
    w.see_condition("cub", failsafe_words("failsafe", None))  # its heartbeat, first
    (change,) = w.evaluate(0.0)
    assert change.alarm.text == "cub in failsafe: in force (its heartbeat's condition)"
    w.see_condition("cub", failsafe_words("failsafe", "rtl: mcs_lost"))  # its health, next
    assert w.evaluate(1.0) == []  # the same episode: nothing raised again
    assert [a.text for a in w.active] == ["cub in failsafe: rtl: mcs_lost"]


@pytest.mark.parametrize("east_m", [5.9, 6.0, 6.1, -0.1, 0.1, 11.9, 12.1, -6.1])
def test_a_near_miss_is_found_across_the_watch_s_cells(east_m: float) -> None:
    # Pairs are looked for among neighbouring cells 6 m wide (5 m and the hysteresis):
    # a pair astride any cell boundary is still judged.
    w = watch()
    w.see_position("cub", 0.0, east_m, 10.0, 0.0)
    w.see_position("f450", 0.0, east_m + 4.0, 10.0, 0.0)
    assert kinds(w.evaluate(0.0)) == [(NEAR_MISS, ("cub", "f450"), True)]


def test_a_near_miss_ends_when_one_of_the_pair_jumps_far_away() -> None:
    w = watch()
    w.see_position("cub", 0.0, 0.0, 10.0, 0.0)
    w.see_position("f450", 0.0, 2.0, 10.0, 0.0)
    assert len(w.evaluate(0.0)) == 1
    w.see_position("f450", 60.0, -60.0, 10.0, 0.5)  # cells away in one report
    assert kinds(w.evaluate(0.5)) == [(NEAR_MISS, ("cub", "f450"), False)]


def test_many_vehicles_apart_cost_no_pair_check_beyond_their_neighbours() -> None:
    envelopes = {f"r{i}": envelope(radius_m=5000.0) for i in range(100)}
    w = AlarmWatch(envelopes, stale_after_s=3.0)
    for i in range(100):  # a 60 m grid: nobody near anybody
        w.see_position(f"r{i}", (i // 10) * 60.0, (i % 10) * 60.0, 10.0, 0.0)
    assert w.evaluate(0.0) == []
    assert all(w._near(f"r{i}") == [] for i in range(100))
