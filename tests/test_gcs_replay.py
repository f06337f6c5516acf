"""``clark replay LOGS``: the replay model against a real dry run, hostile logs, the server.

The dry run's report (module scope, 80 s of cooperative_follow: Slash B is activated at
65 s and chases) gives real logs of every agent and the recording they were written
from, which the replay's rows are held to. Hand-written folders carry what a real run
never writes: hostile strings, malformed rows and lines. The server runs on real
loopback sockets with aiohttp clients; nothing sleeps to wait for a moment: each step
waits for a message, with a timeout.
"""

from __future__ import annotations

import asyncio
import csv
import io
import json
import math
import signal
import subprocess
import sys
import time
import urllib.request
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import aiohttp
import pytest

from clark_engine.cli import main
from clark_engine.dryrun.command import run_dry_run
from clark_engine.expectations.from_logs import check_folder
from clark_engine.expectations.recording import Recording
from clark_engine.link.fleet import FleetTable
from clark_engine.mission.model import Mission
from clark_engine.station.page_messages import CommandRejected, parse_replay_control
from clark_engine.station.replay import ReplayError, find_log_files, load_replay
from clark_engine.station.replay_frames import RESET_TRACK_POINTS, Replay
from clark_engine.station.server import ViewServer
from clark_engine.validation import validate_file

ROOT = Path(__file__).resolve().parent.parent
MISSION = ROOT / "missions" / "cooperative_follow.yaml"
UNTIL_S = 80.0
TOKEN = "replay-token-0123456789abcdef"
TIMEOUT_S = 20.0


def _mission(path: Path = MISSION) -> Mission:
    mission = validate_file(path).mission
    assert mission is not None
    return mission


@dataclass(frozen=True)
class DryRun:
    """A dry run's report folder and what the simulation recorded."""

    report: Path
    recording: Recording


@pytest.fixture(scope="module")
def dry_run(tmp_path_factory: pytest.TempPathFactory) -> DryRun:
    report = tmp_path_factory.mktemp("replay") / "report"
    outcome = run_dry_run(
        MISSION,
        seed=None,
        until_s=UNTIL_S,
        report=report,
        speed=None,
        out=io.StringIO(),
        err=io.StringIO(),
        quiet=True,
        command_line=["clark", "dry-run", str(MISSION), "--report", str(report)],
    )
    assert outcome.result is not None
    return DryRun(report, outcome.result.recording)


@pytest.fixture(scope="module")
def replay(dry_run: DryRun) -> Replay:
    loaded, load = load_replay(dry_run.report, _mission(), mission_source="the mission")
    assert load.problems == []
    return loaded


def _row(state: dict[str, Any], name: str) -> dict[str, Any]:
    (row,) = [a for a in state["agents"] if a["name"] == name]
    return row


def _state_at(replay: Replay, t_s: float) -> dict[str, Any]:
    *_, state = replay.frame(t_s, None)
    assert state["type"] == "state"
    return state


# -- against the dry run's recording ---------------------------------------------------------


@pytest.mark.parametrize("t_s", [20.0, 50.0, 66.0, 75.0])
def test_rows_are_what_the_run_recorded(dry_run: DryRun, replay: Replay, t_s: float) -> None:
    state = _state_at(replay, t_s)
    assert state["t"] == t_s
    for name in ("slash_a", "slash_b"):
        row = _row(state, name)
        assert row["heard"] and row["condition"] == "ok" and not row["lost"]
        assert not row["stale"]  # 1 Hz heartbeats on a lossless simulated link
        assert 0.0 <= row["since_heartbeat_s"] <= 1.5
        # the position the station last received: the true one, at most ~1 s old
        truth = dry_run.recording.tracks[name].at(t_s)
        assert truth is not None
        position = row["position"]
        gap_m = math.hypot(position["north_m"] - truth[0], position["east_m"] - truth[1])
        assert gap_m < 5.0, (name, t_s, position, truth)
        assert 0.0 <= position["age_s"] <= 1.5
        assert row["mode"]["name"] is not None and row["airframe"] == "rover"
        assert row["link"]["packets"] > 0 and row["link"]["lost_packets"] == 0
        # the behaviour: the vehicle's latest state change by then, as the run recorded it
        entries = [e for e in dry_run.recording.states[name] if e.time_s <= t_s]
        if entries:
            assert row["behaviour"]["active"] == list(entries[-1].active)
            assert row["behaviour"]["last_event"] == entries[-1].event
        else:
            assert row["behaviour"] is None


def test_slash_b_chases_after_its_activation(replay: Replay) -> None:
    before, after = (
        _row(_state_at(replay, 60.0), "slash_b"),
        _row(_state_at(replay, 75.0), "slash_b"),
    )
    assert before["behaviour"]["active"] == ["idle"]
    assert (
        after["behaviour"]["active"] == ["chase"] and after["behaviour"]["last_event"] == "activate"
    )
    assert after["mode"]["name"] == "GUIDED"


def test_before_anything_was_heard_nobody_is(replay: Replay) -> None:
    state = _state_at(replay, replay.start_s)
    assert [row["heard"] for row in state["agents"]] == [False, False]
    assert state["agents"][0]["position"] is None


def test_the_checks_are_clark_analyzes(dry_run: DryRun, replay: Replay) -> None:
    judged = check_folder(dry_run.report / "logs", _mission()).results
    assert replay.checks is not None
    assert [c["name"] for c in replay.checks] == [r.name for r in judged]
    statuses = {"pass": "passed", "FAIL": "failed", "not evaluated": "not evaluated"}
    assert [c["status"] for c in replay.checks] == [statuses[r.verdict] for r in judged]
    assert _state_at(replay, 10.0)["checks"] == replay.checks


def test_hello_is_the_live_views_with_no_actions(replay: Replay) -> None:
    hello = replay.hello
    assert hello["type"] == "hello" and hello["mode"] == "replay" and hello["actions"] == []
    assert [a["name"] for a in hello["agents"]] == ["slash_a", "slash_b"]
    assert hello["plan"]["slash_a"][0]["kind"] == "tour"
    info = hello["replay"]
    assert info["start_s"] == replay.start_s and info["end_s"] == replay.end_s
    assert UNTIL_S - 1.0 <= replay.end_s <= UNTIL_S and replay.start_s == 0.0
    assert info["observers"] == {"slash_a": "mcs", "slash_b": "mcs"}


# -- time: seeks, deltas and resets ----------------------------------------------------------


def test_a_seek_outside_the_run_is_clamped(replay: Replay) -> None:
    for asked, shown in [
        (-100.0, replay.start_s),
        (1e9, replay.end_s),
        (math.nan, replay.start_s),
        (math.inf, replay.end_s),
        (-math.inf, replay.start_s),
    ]:
        reset, state = replay.frame(asked, None)
        assert reset["type"] == "reset" and reset["t"] == shown
        assert state["t"] == shown and state["replay"]["t"] == shown


def test_forward_is_a_delta_backward_a_reset(replay: Replay) -> None:
    reset, first = replay.frame(30.0, None)
    assert reset["type"] == "reset" and first["track"] == [] and first["log"] == []
    assert reset["track"] and all(p["t"] <= 30.0 for p in reset["track"])
    (step,) = replay.frame(40.0, 30.0)
    assert step["type"] == "state" and step["track"]
    assert all(30.0 < p["t"] <= 40.0 for p in step["track"])
    # what a page holds after the step is what a jump straight to 40 s gives
    held = [p["seq"] for p in reset["track"] + step["track"]]
    jumped = [p["seq"] for p in replay.reset(40.0)["track"]]
    assert len(jumped) < 2 * RESET_TRACK_POINTS  # not thinned here
    assert held == jumped
    back = replay.frame(10.0, 40.0)
    assert [m["type"] for m in back] == ["reset", "state"]
    assert all(p["t"] <= 10.0 for p in back[0]["track"])
    assert all(line["t"] <= 10.0 for line in back[0]["log"])


def test_tracks_are_one_point_per_agent_status(replay: Replay) -> None:
    points = replay.reset(replay.end_s)["track"]
    by_agent: dict[int, list[float]] = {}
    for point in points:
        by_agent.setdefault(point["agent"], []).append(point["t"])
    assert set(by_agent) == {2, 3}
    for times in by_agent.values():
        assert times == sorted(times) and len(set(times)) == len(times)
        # cooperative_follow's rovers send their Agent Status at 2 Hz
        assert 1.5 <= len(times) / (times[-1] - times[0]) <= 2.5


# -- folders and what they hold --------------------------------------------------------------


def test_the_agents_folders_side_by_side(dry_run: DryRun, tmp_path: Path) -> None:
    """A team that gathered each agent's folder from its own machine."""
    for path in (dry_run.report / "logs").iterdir():
        agent = path.name.split(".", 1)[0]
        (tmp_path / agent).mkdir(exist_ok=True)
        (tmp_path / agent / path.name).write_bytes(path.read_bytes())
    notes: list[str] = []
    found = find_log_files(tmp_path, notes)
    assert sorted(found) == ["mcs", "slash_a", "slash_b"] and notes == []
    assert set(found["slash_b"]) == {"mission_log", "interface_log", "fleet_csv", "message_log"}
    loaded, _ = load_replay(tmp_path, _mission())
    assert (
        _state_at(loaded, 70.0)["agents"]
        == _state_at(load_replay(dry_run.report, _mission())[0], 70.0)["agents"]
    )


def test_without_a_mission_the_logs_alone(dry_run: DryRun) -> None:
    loaded, load = load_replay(dry_run.report / "logs")
    assert any("no mission given" in note for note in load.notes)
    hello = loaded.hello
    assert [(a["name"], a["id"]) for a in hello["agents"]] == [("slash_a", 2), ("slash_b", 3)]
    assert hello["plan"] == {} and hello["mission"]["name"] == "cooperative-follow"
    state = _state_at(loaded, 75.0)
    assert loaded.checks is None and state["checks"] is None
    slash_b = _row(state, "slash_b")
    assert slash_b["mode"] == {"number": 15, "name": None}  # no profile: no mode names
    assert slash_b["behaviour"]["active"] == ["chase"]


FLEET_HEADER = ["now_s", *FleetTable.csv_header()]


def _fleet_row(now_s: str, name: str, agent_id: int, **values: str) -> list[str]:
    row = dict.fromkeys(FLEET_HEADER, "")
    row.update(
        now_s=now_s,
        agent_id=str(agent_id),
        name=name,
        agent_type="vehicle",
        condition="ok",
        lost="0",
        since_heartbeat_s="0.2",
        packets="10",
        lost_packets="0",
        loss_ratio="0.0",
    )
    row.update(values)
    return [row[c] for c in FLEET_HEADER]


HEADER_LINE = (
    "t=0.000 gps_ms=1400000000000 INFO log.open: logbook opened: clark_engine=0.1.0 "
    "mission=hand mission_id=9 agent={agent} agent_id={id} role={role} loop_hz=10.0 "
    "period_s=0.1 level=INFO\n"
)


def _hostile_folder(folder: Path) -> Path:
    """A station and a rover that logged hostile text and malformed rows and lines."""
    folder.mkdir()
    at = {"lat_deg": "30.0", "lon_deg": "-96.0", "alt_m": "1.0", "status_age_s": "0.1"}
    rows = [
        FLEET_HEADER,
        _fleet_row("1.0", "rover", 2, **at),
        _fleet_row("2.0", "rover", 2, **at, mode="4"),
        ["2.5", "rover"],  # 2 fields
        _fleet_row("oops", "rover", 2, **at),
        _fleet_row("2.6", "rover", 2, **{**at, "lat_deg": "north"}),
        _fleet_row("2.7", "rover", 2, **at, condition="<b>evil</b>"),
        _fleet_row("2.8", "<img src=x onerror=alert(1)>\x1b[2J", 66, **at),
        _fleet_row("2.9", "x" * 5000, 67, **at),
    ]
    with (folder / "mcs.fleet.csv").open("w", newline="", encoding="utf-8") as stream:
        csv.writer(stream).writerows(rows)
    (folder / "mcs.mission.log").write_text(
        HEADER_LINE.format(agent="mcs", id=1, role="mcs")
        + "t=1.000 gps_ms=1400000001000 INFO fleet.found: found rover\n"
        + "t=2.000 gps_ms=1400000002000 WARNING runtime.x: evil \x1b[2J <script>alert(1)</script>\n"
        + "garbage that is no log line\n"
        + "t=oops gps_ms=- INFO a.b: not a time\n"
        + "t=2.100 gps_ms=1400000002100 INFO runtime.y: long "
        + "z" * 100_000
        + "\n",
        encoding="utf-8",
    )
    (folder / "rover.mission.log").write_text(
        HEADER_LINE.format(agent="rover", id=2, role="vehicle")
        + "t=2.500 gps_ms=1400000002500 INFO behavior.change: activate: idle -> chase "
        "(active: chase)\n",
        encoding="utf-8",
    )
    return folder


def test_hostile_and_malformed_logs_are_data(tmp_path: Path) -> None:
    loaded, load = load_replay(_hostile_folder(tmp_path / "logs"))
    warnings = "\n".join(load.warnings())
    fleet, log = tmp_path / "logs" / "mcs.fleet.csv", tmp_path / "logs" / "mcs.mission.log"
    assert f"{fleet}:4: expected {len(FLEET_HEADER)} fields, found 2; skipped" in warnings
    assert f"{fleet}:5: now_s is 'oops', not a number; skipped" in warnings
    assert f"{fleet}:6: lat_deg is 'north', not a number; skipped" in warnings
    assert f"{fleet}:7: condition '<b>evil</b>' is not a condition; skipped" in warnings
    assert f"{log}:4: not a log line" in warnings and f"{log}:5: t is 'oops'" in warnings
    names = [a["name"] for a in loaded.hello["agents"]]
    assert "rover" in names and len(names) == 3
    for name in names:  # bounded, and no control character reaches the page
        assert len(name) <= 64 and name.isprintable()
    assert "<img src=x onerror=alert(1)>\\x1b[2J" in names  # data, written as text by the page
    state = _state_at(loaded, 2.7)
    rover = _row(state, "rover")
    assert rover["position"]["lat"] == 30.0 and rover["mode"] == {"number": 4, "name": None}
    assert rover["since_heartbeat_s"] == pytest.approx(0.9)  # 0.2 at 2.0 s, grown since
    assert rover["behaviour"] == {"active": ["chase"], "last_event": "activate", "age_s": 0.2}
    assert not rover["stale"]  # without the mission its heartbeat period is unknown
    texts = [line["text"] for line in loaded.reset(loaded.end_s)["log"]]
    evil = next(t for t in texts if "evil" in t)
    assert "\x1b" not in evil and "\\x1b[2J" in evil and "<script>" in evil
    assert all(len(t) <= 500 and t.isprintable() for t in texts)
    json.dumps(loaded.frame(1.5, None), allow_nan=False)  # every figure is JSON


def test_logs_of_another_mission(dry_run: DryRun) -> None:
    with pytest.raises(ReplayError, match="logs are of mission 'cooperative-follow'"):
        load_replay(dry_run.report, _mission(ROOT / "missions" / "fault_station_loss.yaml"))


# -- the server ------------------------------------------------------------------------------


@pytest.fixture
def served(replay: Replay) -> Iterator[ViewServer]:
    server = ViewServer(replay.hello, _no_command, port=0, replay=replay)
    server.start()
    yield server
    server.stop()


def _no_command(request: object) -> None:
    raise AssertionError("a replay handed on a command")


async def _receive(ws: aiohttp.ClientWebSocketResponse) -> dict[str, Any]:
    message = await ws.receive(timeout=TIMEOUT_S)
    assert message.type == aiohttp.WSMsgType.TEXT, message
    return json.loads(message.data)  # type: ignore[no-any-return]


async def _until(
    ws: aiohttp.ClientWebSocketResponse, kind: str, predicate: Any = None
) -> dict[str, Any]:
    deadline = time.monotonic() + TIMEOUT_S
    while time.monotonic() < deadline:
        message = await _receive(ws)
        if message["type"] == kind and (predicate is None or predicate(message)):
            return message
    raise AssertionError(f"no {kind} message")


def test_the_server_serves_the_replay(served: ViewServer, replay: Replay) -> None:
    url = f"http://127.0.0.1:{served.port}/ws"

    async def go() -> None:
        async with aiohttp.ClientSession() as session, session.ws_connect(url) as ws:
            hello = await _receive(ws)
            assert hello["mode"] == "replay" and hello["actions"] == []
            reset = await _receive(ws)
            assert reset["type"] == "reset" and reset["t"] == replay.start_s
            state = await _receive(ws)
            assert state["replay"] == {
                "t": replay.start_s,
                "start_s": replay.start_s,
                "end_s": replay.end_s,
                "playing": False,
                "speed": 1.0,
            }
            await ws.send_str(json.dumps({"type": "seek", "t": 75.0}))
            state = await _until(ws, "state")
            assert state["t"] == 75.0 and _row(state, "slash_b")["behaviour"]["active"] == ["chase"]
            assert state["track"] and all(0.0 < p["t"] <= 75.0 for p in state["track"])
            await ws.send_str(json.dumps({"type": "seek", "t": 20.0}))  # back: a reset
            reset = await _until(ws, "reset")
            assert reset["t"] == 20.0 and all(p["t"] <= 20.0 for p in reset["track"])
            state = await _until(ws, "state")
            assert state["t"] == 20.0 and state["track"] == []
            await ws.send_str(json.dumps({"type": "speed", "speed": 120}))
            await ws.send_str(json.dumps({"type": "play"}))
            playing = await _until(ws, "state", lambda m: m["replay"]["playing"])
            assert playing["replay"]["speed"] == 120.0
            later = await _until(ws, "state", lambda m: m["t"] > playing["t"])
            assert later["replay"]["playing"] or later["t"] == replay.end_s
            await ws.send_str(json.dumps({"type": "pause"}))
            paused = await _until(ws, "state", lambda m: not m["replay"]["playing"])
            assert paused["t"] >= later["t"]
            await ws.send_str(json.dumps({"type": "seek", "t": 1e9}))
            assert (await _until(ws, "state", lambda m: m["t"] == replay.end_s))["t"] > 0

    asyncio.run(go())


def test_the_replay_refuses_commands_and_bad_controls(served: ViewServer) -> None:
    url = f"http://127.0.0.1:{served.port}/ws"
    activate = {"type": "command", "action": "activate", "target": "slash_b", "ref": 4}
    bad = [
        (json.dumps(activate), "sends no commands"),
        ('{"type": "speed", "speed": 3}', "speed must be one of"),
        ('{"type": "seek", "t": "soon"}', "needs a number"),
        ('{"type": "seek", "t": true}', "needs a number"),
        ('{"type": "rewind"}', "unknown message type"),
        ("[1]", "not a JSON object"),
    ]

    async def go() -> None:
        async with aiohttp.ClientSession() as session, session.ws_connect(url) as ws:
            await _receive(ws)
            for text, reason in bad:
                await ws.send_str(text)
                error = await _until(ws, "error")
                assert reason in error["error"]
            assert error["ref"] is None
            await ws.send_str(json.dumps(activate))
            assert (await _until(ws, "error"))["ref"] == 4
            await ws.send_str(json.dumps({"type": "seek", "t": 10}))
            assert (await _until(ws, "state"))["t"] == 10.0  # still serving

    asyncio.run(go())
    assert served.stats["commands"] == 0
    for text, reason in bad:
        with pytest.raises(CommandRejected, match=reason):
            parse_replay_control(text, (1.0, 5.0, 20.0))


def test_a_token_guards_the_replay_too(replay: Replay) -> None:
    server = ViewServer(replay.hello, _no_command, port=0, token=TOKEN, replay=replay)
    server.start()
    base = f"http://127.0.0.1:{server.port}"
    try:

        async def go() -> None:
            async with aiohttp.ClientSession() as session:
                for path in ("/", "/ws", "/static/app.js"):
                    async with session.get(base + path) as response:
                        assert response.status == 403, path
                headers = {"X-Clark-Token": TOKEN}
                async with session.ws_connect(base + "/ws", headers=headers) as ws:
                    assert (await _receive(ws))["mode"] == "replay"

        asyncio.run(go())
    finally:
        server.stop()


# -- the command -----------------------------------------------------------------------------


def test_clark_replay_usage_and_bad_folders(
    tmp_path: Path, dry_run: DryRun, capsys: pytest.CaptureFixture[str]
) -> None:
    cases: list[tuple[list[str], int, str]] = []
    cases.append((["replay", str(tmp_path / "nowhere")], 2, "no such folder"))
    (tmp_path / "empty").mkdir()
    cases.append((["replay", str(tmp_path / "empty")], 1, "no agent's log in it"))
    junk = tmp_path / "junk"
    junk.mkdir()
    (junk / "mcs.fleet.csv").write_text("this,is,not\n1,2,3\n", encoding="utf-8")
    cases.append((["replay", str(junk)], 1, "nothing to replay"))
    invalid = tmp_path / "invalid.yaml"
    invalid.write_text("mission: [\n", encoding="utf-8")
    cases.append((["replay", str(dry_run.report), "--checks", str(invalid)], 1, "invalid"))
    other = str(ROOT / "missions" / "fault_station_loss.yaml")
    cases.append((["replay", str(dry_run.report), "--checks", other], 1, "logs are of mission"))
    cases.append((["replay", str(dry_run.report), "--view", "0.0.0.0:0"], 2, "needs a token"))
    cases.append((["replay", str(dry_run.report), "--view", "http://x"], 2, "must be a number"))
    cases.append((["replay", str(dry_run.report), "--view-token", "short"], 2, "16-256 characters"))
    for argv, code, message in cases:
        assert main(argv) == code, argv
        err = capsys.readouterr().err
        assert message in err, (argv, err)
        assert "Traceback" not in err
    assert main(["replay", str(junk)]) == 1
    err = capsys.readouterr().err
    assert f": {junk / 'mcs.fleet.csv'}: not a fleet CSV (header is 'this,is,not'" in err


def test_clark_replay_serves_until_stopped(dry_run: DryRun) -> None:
    proc = subprocess.Popen(
        [sys.executable, "-m", "clark_engine", "replay", str(dry_run.report), "--view", "0"],
        cwd=ROOT,
        stdin=subprocess.DEVNULL,
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
    )
    try:
        assert proc.stdout is not None
        lines: list[str] = []
        url = None
        while url is None:
            line = proc.stdout.readline()
            assert line, proc.stderr.read() if proc.stderr else "no output"
            lines.append(line)
            if "serving at " in line:
                url = line.split("serving at ", 1)[1].split(";", 1)[0].strip()
        # the report's summary names the mission: its plan and checks come with it
        assert "plan and checks from the mission" in lines[0]
        with urllib.request.urlopen(url, timeout=TIMEOUT_S) as page:
            assert 'data-testid="replay-slider"' in page.read().decode("utf-8")

        async def hello() -> dict[str, Any]:
            async with aiohttp.ClientSession() as session, session.ws_connect(url + "ws") as ws:
                return await _receive(ws)

        assert asyncio.run(hello())["mode"] == "replay"
        proc.send_signal(signal.SIGTERM)
        out, err = proc.communicate(timeout=TIMEOUT_S)
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.wait()
    assert proc.returncode == 0, err
    assert "clark replay: stopped" in out and "Traceback" not in err
