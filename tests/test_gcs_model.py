"""The station view's model from a real station runtime fed real ClarkLink packets.

cooperative_follow's station (``mcs``) and both Slashes run as real
:class:`~clark_engine.runtime.runtime.AgentRuntime` objects on a virtual clock; every
packet one of them sends is delivered to the others as it would be over the radio. The
Slashes' autopilots are streams of VehicleState events that obey the SetMode the
runtime sends (as tests/test_runtime.py plays them). Nothing sleeps.
"""

from __future__ import annotations

import json
from dataclasses import replace
from pathlib import Path
from typing import Any

import pytest

from clark_engine.link.messages import AgentType, Heartbeat, PictureData
from clark_engine.mission.compiler import agent_config
from clark_engine.mission.geo import LocalPoint, Origin, to_global
from clark_engine.mission.validate import validate_path
from clark_engine.runtime.commands import Command, SendPacket, SetMode
from clark_engine.runtime.config import AgentConfig, config_from_dict
from clark_engine.runtime.events import (
    AutopilotHeartbeat,
    AutopilotStatus,
    LandedState,
    PacketReceived,
    StationCommand,
    VehicleState,
)
from clark_engine.runtime.runtime import AgentRuntime
from clark_engine.station.view_commands import CommandRequest
from clark_engine.station.view_hello import build_hello, plan_of, stale_after_s
from clark_engine.station.view_log import MissionLogBuffer
from clark_engine.station.view_model import StationView

ROOT = Path(__file__).resolve().parent.parent
GPS0 = 1_400_000_000_000
ORIGIN = Origin(30.6372, -96.4787, 90.0)
READY = AutopilotStatus(
    gps_fix_type=3,
    position_ok=True,
    prearm_ok=True,
    home=(30.6372, -96.4787, 90.0),
    landed=LandedState.ON_GROUND,
)
MODES = {"HOLD": 4, "MANUAL": 0, "GUIDED": 15, "AUTO": 10}


def configs(mission_file: str) -> dict[str, AgentConfig]:
    result = validate_path(ROOT / "missions" / mission_file, mission_file)
    assert result.mission is not None
    mission = result.mission
    # The autopilots here are streams of events, which cannot answer the autopilot's safety
    # set-up (tests/test_runtime_autopilot_safety.py): the behaviours start without it.
    return {
        name: replace(config_from_dict(agent_config(mission, agent)), safety_setup=False)
        for name, agent in mission.agents.items()
    }


class Fleet:
    """cooperative_follow's three runtimes, their packets routed as a radio would."""

    def __init__(self) -> None:
        self.configs = configs("cooperative_follow.yaml")
        self.station = AgentRuntime(self.configs["mcs"], gps_epoch_ms=GPS0)
        self.vehicles = {name: AgentRuntime(self.configs[name]) for name in ("slash_a", "slash_b")}
        self.runtimes: dict[str, AgentRuntime] = {"mcs": self.station, **self.vehicles}
        self.mode = {"slash_a": "HOLD", "slash_b": "HOLD"}
        self.position = {"slash_a": LocalPoint(0, 0), "slash_b": LocalPoint(-15, -10)}
        self.silent: set[str] = set()
        self.deaf: set[str] = set()  # agents that hear nothing (their radio's receive fails)
        self.log = MissionLogBuffer()
        self.log.attach(self.station.logbook.mission)
        self.hello = build_hello(self.configs["mcs"], self.configs, plan_source="the mission")
        self.view = StationView(self.station, self.hello, log=self.log)
        self.t = 0.0

    def route(self, sender: str, commands: list[Command], t: float) -> None:
        for command in commands:
            if isinstance(command, SetMode):
                self.mode[sender] = command.mode  # the autopilot obeys
            if not isinstance(command, SendPacket) or sender in self.silent:
                continue
            for name, runtime in self.runtimes.items():
                if name != sender and name not in self.deaf and command.destination in ("", name):
                    self.route(name, runtime.deliver(PacketReceived(command.data), t), t)

    def step(self, seconds: float = 0.1) -> None:
        """Run every agent for ``seconds`` in 0.1 s ticks."""
        for _ in range(round(seconds / 0.1)):
            self.t = round(self.t + 0.1, 3)
            t = self.t
            for name, runtime in self.vehicles.items():
                mode = self.mode[name]
                lat, lon, _ = to_global(self.position[name], ORIGIN)
                state = VehicleState(
                    GPS0 + round(t * 1000),
                    *(lat, lon, 0.0, 1.5, 0.0, 90.0, 0.0, 0.0, 90.0),
                    mode,
                    MODES[mode],
                    True,
                )
                self.route(name, runtime.deliver(READY, t), t)
                self.route(name, runtime.deliver(state, t), t)
                self.route(name, runtime.deliver(AutopilotHeartbeat(mode, MODES[mode], True), t), t)
                self.route(name, runtime.tick(t), t)
            self.route("mcs", self.station.tick(t), t)
            self.view.observe(t)

    def command(self, action: str, target: str, mode: str = "", *, id: int = 1) -> dict[str, Any]:
        request = CommandRequest(id, action, target, mode, "alice", "127.0.0.1")

        def deliver(command: StationCommand) -> None:
            self.route("mcs", self.station.deliver(command, self.t), self.t)

        return self.view.execute(request, deliver, self.t)

    def command_status(self, id: int) -> dict[str, object]:
        (found,) = [c for c in self.view.commands() if c["id"] == id]
        return found


@pytest.fixture
def fleet() -> Fleet:
    return Fleet()


def agent(snapshot: dict[str, object], name: str) -> dict[str, object]:
    agents = snapshot["agents"]
    assert isinstance(agents, list)
    (found,) = [a for a in agents if a["name"] == name]
    return found  # type: ignore[no-any-return]


# -- hello ----------------------------------------------------------------------------------


def test_hello_lists_every_agent_with_its_airframe_modes_and_plan(fleet: Fleet) -> None:
    hello = fleet.hello
    json.dumps(hello)  # JSON-able
    assert hello["mission"]["name"] == "cooperative-follow" and hello["mission"]["id"] == 521
    assert hello["mission"]["origin"] == {"lat": 30.6372, "lon": -96.4787, "alt_amsl_m": 90.0}
    assert hello["station"] == {
        "name": "mcs",
        "id": 1,
        "home": {"north_m": 0.0, "east_m": 0.0, "up_m": 0.0},
    }
    by_name = {a["name"]: a for a in hello["agents"]}
    assert set(by_name) == {"slash_a", "slash_b"}
    slash_b = by_name["slash_b"]
    assert (slash_b["id"], slash_b["role"], slash_b["airframe"]) == (3, "vehicle", "rover")
    modes = [m["name"] for m in slash_b["modes"]]
    assert "GUIDED" in modes and "HOLD" in modes and "INITIALISING" not in modes
    assert {"name": "GUIDED", "number": 15} in slash_b["modes"]
    assert slash_b["home"] == {"north_m": -15.0, "east_m": -10.0, "up_m": 0.0}
    assert slash_b["heartbeat_hz"] == 1.0 and slash_b["stale_after_s"] == 1.5
    (tour,) = hello["plan"]["slash_a"]
    # once round (cooperative_follow keeps Slash A off Slash B parked on its track)
    assert tour["kind"] == "tour" and tour["loop"] is False and tour["survey"] is False
    assert tour["points"][2] == {"north_m": 40.0, "east_m": 10.0, "up_m": 0.0}
    assert len(tour["points"]) == 8
    assert hello["plan"]["slash_b"] == []  # hold and follow_agent: no fixed point
    assert hello["answer_timeout_s"] == 6.0


def test_hello_without_the_fleet_lists_the_station_peers_only() -> None:
    station = configs("cooperative_follow.yaml")["mcs"]
    hello = build_hello(station)
    assert [a["name"] for a in hello["agents"]] == ["slash_a", "slash_b"]
    assert all(a["airframe"] is None and a["home"] is None for a in hello["agents"])
    assert hello["plan"] == {} and hello["plan_source"] == ""


def test_a_tour_beside_a_photo_trigger_is_a_survey_line() -> None:
    fleet = configs("anaconda_survey.yaml")
    (vehicle,) = [c for c in fleet.values() if c.is_vehicle]
    plan = plan_of(vehicle)
    surveys = [item for item in plan if item["kind"] == "tour"]
    assert surveys and all(item["survey"] for item in surveys)
    assert all(len(item["points"]) >= 2 for item in surveys)


def test_stale_rule() -> None:
    assert stale_after_s(1.0, 3.0) == 1.5  # one heartbeat missed
    assert stale_after_s(0.5, 3.0) == 1.5  # at most half the timeout
    assert stale_after_s(10.0, 3.0) == pytest.approx(0.15)
    assert stale_after_s(None, 4.0) == 2.0


# -- state ----------------------------------------------------------------------------------


def test_state_shows_each_agent_from_the_fleet_table(fleet: Fleet) -> None:
    fleet.step(2.0)
    snap = fleet.view.snapshot(fleet.t)
    json.dumps(snap.state)
    slash_b = agent(snap.state, "slash_b")
    assert slash_b["heard"] is True and slash_b["lost"] is False and slash_b["stale"] is False
    assert slash_b["condition"] == "ok"
    # armed from its Vehicle Health (the fleet's autopilots report armed)
    assert slash_b["airframe"] == "rover" and slash_b["armed"] is True
    position = slash_b["position"]
    assert isinstance(position, dict)
    assert position["north_m"] == pytest.approx(-15.0, abs=0.01)
    assert position["east_m"] == pytest.approx(-10.0, abs=0.01)
    assert position["ground_speed_m_s"] == 1.5 and position["heading_deg"] == 90.0
    assert slash_b["mode"] == {"number": 4, "name": "HOLD"}
    assert slash_b["behaviour"]["active"] == ["idle"]  # type: ignore[index]
    link = slash_b["link"]
    assert isinstance(link, dict) and link["packets"] > 0 and link["loss_ratio"] == 0.0
    assert link["latency_mean_ms"] is not None
    assert snap.state["station"]["terminated"] is False  # type: ignore[index]
    assert snap.state["checks"] is None
    assert snap.state["alarms"] == [] and slash_b["alarm"] is False
    # track points: one per Agent Status received, numbered, never sent twice
    assert snap.track and all(p["agent"] in (2, 3) for p in snap.track)
    seqs = [p["seq"] for p in snap.track]
    assert seqs == sorted(seqs) and len(set(seqs)) == len(seqs)
    fleet.step(1.0)
    later = fleet.view.snapshot(fleet.t)
    assert later.track and later.track[0]["seq"] == seqs[-1] + 1
    # the mission log: the station's own lines, numbered
    assert any("found slash_b" in line["text"] for line in snap.log)
    assert all(line["seq"] > snap.log[-1]["seq"] for line in later.log)


def test_an_agent_never_heard_is_listed_as_such(fleet: Fleet) -> None:
    fleet.silent.add("slash_a")
    fleet.step(1.0)
    slash_a = agent(fleet.view.snapshot(fleet.t).state, "slash_a")
    assert slash_a["heard"] is False and slash_a["position"] is None
    assert slash_a["since_heartbeat_s"] is None and slash_a["link"]["packets"] == 0  # type: ignore[index]


def test_a_silent_agent_turns_stale_then_lost(fleet: Fleet) -> None:
    fleet.step(1.05)
    fleet.silent.add("slash_b")
    fleet.step(0.5)
    assert agent(fleet.view.snapshot(fleet.t).state, "slash_b")["stale"] is False
    fleet.step(1.1)  # more than 1.5 s since its last heartbeat
    slash_b = agent(fleet.view.snapshot(fleet.t).state, "slash_b")
    assert slash_b["stale"] is True and slash_b["lost"] is False
    fleet.step(1.5)  # more than the 3 s heartbeat timeout
    slash_b = agent(fleet.view.snapshot(fleet.t).state, "slash_b")
    assert slash_b["lost"] is True and slash_b["stale"] is False
    assert slash_b["since_heartbeat_s"] > 3.0  # type: ignore[operator]
    fleet.silent.clear()
    fleet.step(1.1)
    slash_b = agent(fleet.view.snapshot(fleet.t).state, "slash_b")
    assert slash_b["lost"] is False and slash_b["stale"] is False


def test_photos_come_from_picture_data(fleet: Fleet) -> None:
    fleet.step(0.5)
    camera = fleet.vehicles["slash_a"].codec  # slash_a reports a picture
    lat, lon, _ = to_global(LocalPoint(12.0, 7.0), ORIGIN)
    gps = GPS0 + 600
    (data,) = camera.encode(
        [Heartbeat(2, gps, 521, AgentType.VEHICLE), PictureData(2, gps, lat, lon, 30.0, 4)],
        0,
        256,
    )
    fleet.station.deliver(PacketReceived(data), fleet.t)
    fleet.view.observe(fleet.t)
    (photo,) = fleet.view.snapshot(fleet.t).photos
    assert photo["agent"] == 2 and photo["image_index"] == 4 and photo["seq"] == 1
    assert photo["north_m"] == pytest.approx(12.0, abs=0.01)
    assert photo["east_m"] == pytest.approx(7.0, abs=0.01)
    assert fleet.view.snapshot(fleet.t).photos == []


# -- commands -------------------------------------------------------------------------------


def test_activate_is_pending_until_the_behavior_state_shows_it(fleet: Fleet) -> None:
    fleet.step(1.0)
    entry = fleet.command("activate", "slash_b")
    assert entry["status"] == "pending" and entry["targets"] == {"slash_b": "pending"}
    assert entry["by"] == {"name": "alice", "address": "127.0.0.1"}
    fleet.step(0.3)
    entry = fleet.command_status(1)
    assert entry["status"] == "done", entry
    assert "Behavior State" in str(entry["detail"])
    assert agent(fleet.view.snapshot(fleet.t).state, "slash_b")["behaviour"]["active"] == [  # type: ignore[index]
        "chase"
    ]
    log = fleet.station.logbook.streams.mission.getvalue()  # type: ignore[attr-defined]
    assert "view command 1 from alice at 127.0.0.1: activate slash_b" in log
    assert "operator: activate slash_b" in log


def test_a_periodic_behavior_state_is_not_an_answer(fleet: Fleet) -> None:
    fleet.step(1.0)
    fleet.command("activate", "slash_b", id=1)
    fleet.step(0.3)
    assert fleet.command_status(1)["status"] == "done"
    fleet.command("activate", "slash_b", id=2)  # already chasing: nothing changes
    fleet.step(7.0)
    second = fleet.command_status(2)
    assert second["status"] == "unanswered"
    assert "no sign of effect from slash_b in 6 s" in str(second["detail"])


def test_deactivate_and_activate_all(fleet: Fleet) -> None:
    fleet.step(1.0)
    fleet.command("activate", "", id=1)  # every vehicle; slash_a's tour has no activate
    fleet.step(7.0)
    entry = fleet.command_status(1)
    assert entry["targets"] == {"slash_a": "unanswered", "slash_b": "done"}
    assert entry["status"] == "unanswered" and "(done: slash_b)" in str(entry["detail"])
    fleet.command("deactivate", "slash_b", id=2)
    fleet.step(0.3)
    assert fleet.command_status(2)["status"] == "done"


def test_mode_change_is_done_when_agent_status_reports_it(fleet: Fleet) -> None:
    fleet.step(1.0)
    fleet.command("mode", "slash_b", "MANUAL")
    assert fleet.command_status(1)["status"] == "pending"
    fleet.step(0.6)  # the next Agent Status (2 Hz) after the autopilot switched
    entry = fleet.command_status(1)
    assert entry["status"] == "done" and entry["detail"] == "its Agent Status reports MANUAL"
    assert agent(fleet.view.snapshot(fleet.t).state, "slash_b")["mode"] == {
        "number": 0,
        "name": "MANUAL",
    }


def test_refusals(fleet: Fleet) -> None:
    fleet.step(1.0)
    assert fleet.command("mode", "slash_b", "WARP", id=1)["status"] == "refused"
    assert fleet.command("activate", "nobody", id=2)["status"] == "refused"
    refused = fleet.command("mode", "", "HOLD", id=3)
    assert refused["status"] == "refused" and "one agent" in str(refused["detail"])
    log = fleet.station.logbook.streams.mission.getvalue()  # type: ignore[attr-defined]
    assert "view command 1 refused: slash_b has no mode 'WARP'" in log


def test_terminate_one_agent_is_done_on_its_last_heartbeat(fleet: Fleet) -> None:
    fleet.step(1.0)
    fleet.command("terminate", "slash_b")
    fleet.step(0.1)
    entry = fleet.command_status(1)
    assert entry["status"] == "done" and fleet.vehicles["slash_b"].terminated
    assert agent(fleet.view.snapshot(fleet.t).state, "slash_b")["condition"] == "terminated"
    # a terminated agent is refused further commands
    assert fleet.command("activate", "slash_b", id=2)["status"] == "refused"


def test_terminate_all_terminates_the_fleet_then_the_station(fleet: Fleet) -> None:
    fleet.step(1.0)
    fleet.command("terminate", "")
    # Both vehicles terminated at once and their last heartbeats confirmed it; the
    # station itself terminates in its next tick, after taking those confirmations.
    assert all(runtime.terminated for runtime in fleet.vehicles.values())
    assert not fleet.station.terminated
    fleet.step(0.1)
    entry = fleet.command_status(1)
    assert entry["status"] == "done", entry
    assert entry["targets"] == {"slash_a": "done", "slash_b": "done"}
    assert fleet.station.terminated
    assert fleet.view.snapshot(fleet.t).state["station"]["terminated"] is True  # type: ignore[index]
    log = fleet.station.logbook.streams.mission.getvalue()  # type: ignore[attr-defined]
    assert "terminate: slash_a confirmed" in log and "terminate: slash_b confirmed" in log
    later = fleet.command("activate", "slash_b", id=2)
    assert later["status"] == "refused" and later["detail"] == "the station has terminated"


def test_terminate_all_is_sent_again_to_an_agent_that_missed_it(fleet: Fleet) -> None:
    fleet.step(1.0)
    fleet.deaf.add("slash_a")  # the broadcast never reaches it
    fleet.command("terminate", "")
    fleet.step(0.5)
    assert fleet.vehicles["slash_b"].terminated and not fleet.vehicles["slash_a"].terminated
    assert not fleet.station.terminated  # still waiting for slash_a
    assert fleet.command_status(1)["status"] == "pending"
    # meanwhile nothing else is sent
    busy = fleet.command("activate", "slash_a", id=2)
    assert busy["status"] == "refused" and "terminating" in str(busy["detail"])
    fleet.deaf.clear()
    fleet.step(1.0)  # the next resend (every second) reaches it
    assert fleet.vehicles["slash_a"].terminated and fleet.station.terminated
    assert fleet.command_status(1)["status"] == "done"


def test_terminate_all_gives_up_on_an_agent_that_never_confirms(fleet: Fleet) -> None:
    fleet.step(1.0)
    fleet.deaf.add("slash_a")  # hears nothing, still sends heartbeats: never confirms
    fleet.command("terminate", "")
    fleet.step(4.8)  # the wait is heartbeat_timeout_s (3 s) + 2 s
    assert not fleet.station.terminated
    fleet.step(0.3)
    assert fleet.station.terminated and not fleet.vehicles["slash_a"].terminated
    entry = fleet.command_status(1)
    assert entry["status"] == "unanswered"
    assert entry["targets"] == {"slash_a": "unanswered", "slash_b": "done"}
    assert "slash_a before the station terminated" in str(entry["detail"])
    log = fleet.station.logbook.streams.mission.getvalue()  # type: ignore[attr-defined]
    assert "terminate: no confirmation from slash_a" in log


def test_operator_names_reach_the_log_escaped(fleet: Fleet) -> None:
    fleet.step(0.5)
    request = CommandRequest(9, "activate", "slash_b", "", "eve\n<img src=x>\x1b[2J", "10.0.0.9")
    fleet.view.execute(
        request, lambda c: fleet.route("mcs", fleet.station.deliver(c, fleet.t), fleet.t), fleet.t
    )
    log = fleet.station.logbook.streams.mission.getvalue()  # type: ignore[attr-defined]
    (line,) = [line for line in log.splitlines() if "view command 9" in line]
    assert "\\x0a" in line and "\\x1b" in line
    shown = [entry["text"] for entry in fleet.view.snapshot(fleet.t).log]
    assert any("view command 9 from eve\\x0a<img src=x>\\x1b[2J" in text for text in shown)
    assert not any("\n" in text or "\x1b" in text for text in shown)


def test_the_log_buffer_is_bounded(fleet: Fleet) -> None:
    buffer = MissionLogBuffer(max_lines=5)
    buffer.attach(fleet.station.logbook.mission)
    for k in range(20):
        fleet.station.logbook.mission.info("line %d %s", k, "x" * 2000)
    assert len(buffer.lines) == 5 and buffer.seq == 20
    assert [line.seq for line in buffer.since(17)] == [18, 19, 20]
    assert all(len(line.text) <= 500 for line in buffer.lines)
    buffer.detach()
    fleet.station.logbook.mission.info("after")
    assert buffer.seq == 20


def test_behavior_names_from_the_air_reach_the_page_escaped() -> None:
    """A forged Behavior State: a right-to-left override (U+202E) that would show the
    operator a reversed state name and a terminal escape; each is escaped, and a flood of
    names is cut."""
    from clark_engine.link.messages import BehaviorState
    from clark_engine.station.view_rows import agent_row

    forged = BehaviorState(
        3, 0, ("chase\u202edekrap", "idle\x1b[2J", *[f"s{i}" for i in range(100)]), "done\u202e"
    )
    info = {"name": "slash_b", "id": 3, "role": "vehicle", "home": None}
    row = agent_row(info, ORIGIN, heard=True, behavior=forged, behavior_age_s=0.0)
    shown = row["behaviour"]
    assert shown["active"][:2] == ["chase\\u202edekrap", "idle\\x1b[2J"]
    assert shown["last_event"] == "done\\u202e"
    assert len(shown["active"]) <= 32
    assert not any(not name.isprintable() for name in [*shown["active"], shown["last_event"]])
