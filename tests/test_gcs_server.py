"""The station view's server over real loopback sockets, fed by a real station shell.

The station is cooperative_follow's ``mcs``: a real runtime in a real
:class:`~clark_engine.shells.realtime.RealtimeShell` (on a thread here, as ``clark run``
runs it on its main thread) with a real UDP radio on 127.0.0.1. A plain UDP socket
plays ``slash_b``: it sends real ClarkLink heartbeats to the station and receives what
the station sends it. Clients are aiohttp's, on real sockets. Nothing sleeps to wait
for a moment: each step waits for a message, with a timeout.
"""

from __future__ import annotations

import asyncio
import json
import select
import socket
import subprocess
import sys
import threading
import time
import urllib.request
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import aiohttp
import pytest

from clark_engine.cli import main
from clark_engine.errors import UsageError
from clark_engine.io.udp_radio import UdpRadio
from clark_engine.link.codec import Codec
from clark_engine.link.messages import ActivateController, AgentType, Heartbeat
from clark_engine.mission.compiler import agent_config
from clark_engine.runtime.config import AgentConfig, config_from_dict
from clark_engine.runtime.runtime import AgentRuntime
from clark_engine.shells.links import RadioLink
from clark_engine.shells.realtime import RealtimeShell
from clark_engine.station.access import parse_view_address
from clark_engine.station.live_view import (
    OpenView,
    StationViewLink,
    ViewSettings,
    fleet_configs,
    open_view,
    view_settings,
)
from clark_engine.station.page_messages import MAX_MESSAGE_BYTES, parse_command
from clark_engine.station.server import ViewServer
from clark_engine.station.view_hello import build_hello
from clark_engine.station.view_model import Snapshot
from clark_engine.validation import validate_file

ROOT = Path(__file__).resolve().parent.parent
MISSION = ROOT / "missions" / "cooperative_follow.yaml"
TOKEN = "test-token-0123456789abcdef"
TIMEOUT_S = 20.0


def _configs() -> dict[str, AgentConfig]:
    mission = validate_file(MISSION).mission
    assert mission is not None
    return {
        name: config_from_dict(agent_config(mission, agent))
        for name, agent in mission.agents.items()
    }


CONFIGS = _configs()


@dataclass
class Station:
    """A running station with its view, and slash_b's socket."""

    shell: RealtimeShell
    served: OpenView
    link: StationViewLink
    slash_b: socket.socket
    thread: threading.Thread

    @property
    def base(self) -> str:
        return f"http://127.0.0.1:{self.served.server.port}"

    def heartbeat(self, codec: Codec, station_address: tuple[str, int]) -> None:
        (data,) = codec.encode(
            [Heartbeat(3, 0, 521, AgentType.VEHICLE)], 0, 256
        )  # unstamped: no latency
        self.slash_b.sendto(data, station_address)


def start_station(token: str | None = None, update_hz: float = 20.0) -> Station:
    config = CONFIGS["mcs"]
    slash_b = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    slash_b.bind(("127.0.0.1", 0))
    slash_b_address = f"127.0.0.1:{slash_b.getsockname()[1]}"

    def open_radio() -> UdpRadio:
        radio = UdpRadio("127.0.0.1:0", peers=[slash_b_address])
        radio.open()
        return radio

    settings = ViewSettings("127.0.0.1", 0, token, update_hz)
    try:
        served = open_view(settings, config, *fleet_configs(str(MISSION), config))
    except BaseException:
        slash_b.close()
        raise
    runtime = AgentRuntime(config, gps_epoch_ms=1_400_000_000_000)
    shell = RealtimeShell(
        runtime,
        radio=RadioLink(open_radio, "udp"),
        peer_addresses={"slash_b": slash_b_address},
        gc_freeze=False,
    )
    link = served.attach(shell)
    thread = threading.Thread(target=shell.run, kwargs={"until_s": 60.0}, daemon=True)
    thread.start()
    return Station(shell, served, link, slash_b, thread)


def stop_station(station: Station) -> None:
    station.shell.stop("test over")
    station.thread.join(TIMEOUT_S)
    station.link.close(station.shell.now())
    station.served.stop()
    station.slash_b.close()


@pytest.fixture
def station() -> Iterator[Station]:
    running = start_station()
    yield running
    stop_station(running)


@pytest.fixture
def guarded() -> Iterator[Station]:
    running = start_station(TOKEN)
    yield running
    stop_station(running)


def station_address(station: Station) -> tuple[str, int]:
    radio = station.shell.radio
    deadline = time.monotonic() + TIMEOUT_S
    while radio is None or radio.radio is None:  # the loop opens it as it starts
        assert time.monotonic() < deadline
        time.sleep(0.01)
        radio = station.shell.radio
    host, port = radio.radio.address.rsplit(":", 1)
    return host, int(port)


async def receive(ws: aiohttp.ClientWebSocketResponse) -> dict[str, Any]:
    message = await ws.receive(timeout=TIMEOUT_S)
    assert message.type == aiohttp.WSMsgType.TEXT, message
    return json.loads(message.data)  # type: ignore[no-any-return]


async def receive_until(
    ws: aiohttp.ClientWebSocketResponse, kind: str, predicate: Any = None
) -> dict[str, Any]:
    deadline = time.monotonic() + TIMEOUT_S
    while time.monotonic() < deadline:
        message = await receive(ws)
        if message["type"] == kind and (predicate is None or predicate(message)):
            return message
    raise AssertionError(f"no {kind} message")


def run(coroutine: Any) -> Any:
    return asyncio.run(coroutine)


# -- addresses and settings -----------------------------------------------------------------


def test_view_addresses() -> None:
    assert parse_view_address("8080") == ("127.0.0.1", 8080)
    assert parse_view_address("0.0.0.0:9000") == ("0.0.0.0", 9000)
    assert parse_view_address("[::1]:0") == ("::1", 0)
    for bad in ("http://x", "host:port", "127.0.0.1:70000", ":80"):
        with pytest.raises(UsageError):
            parse_view_address(bad)


def test_a_token_is_required_off_loopback(tmp_path: Path) -> None:
    hello = build_hello(CONFIGS["mcs"])
    with pytest.raises(UsageError, match="give a token"):
        ViewServer(hello, lambda r: None, host="0.0.0.0", port=0)
    with pytest.raises(UsageError, match="16-256 characters"):
        ViewServer(hello, lambda r: None, host="0.0.0.0", port=0, token="short")
    with pytest.raises(UsageError, match="needs a token"):
        view_settings("0.0.0.0:0", None, None, None, CONFIGS["mcs"])
    with pytest.raises(UsageError, match="is a vehicle"):
        view_settings("0", None, None, None, CONFIGS["slash_b"])
    with pytest.raises(UsageError, match="go with --view"):
        view_settings(None, TOKEN, None, None, CONFIGS["mcs"])
    token_file = tmp_path / "view.token"
    token_file.write_text(TOKEN + "\n", encoding="utf-8")
    settings = view_settings("0.0.0.0:0", None, str(token_file), None, CONFIGS["mcs"])
    assert settings is not None and settings.token == TOKEN and settings.update_hz == 5.0


def test_clark_run_refuses_the_view_off_loopback_without_a_token(
    capsys: pytest.CaptureFixture[str], tmp_path: Path
) -> None:
    base = ["run", str(MISSION), "--no-radio", "--plain", "--logs", str(tmp_path / "logs")]
    assert main([*base, "--agent", "mcs", "--view", "0.0.0.0:0"]) == 2
    assert "needs a token" in capsys.readouterr().err
    assert main([*base, "--agent", "slash_b", "--view", "0"]) == 2
    assert "is a vehicle" in capsys.readouterr().err
    assert not (tmp_path / "logs").exists()  # refused before anything opened


# -- HTTP -----------------------------------------------------------------------------------


def test_page_and_static_files(station: Station) -> None:
    async def go() -> None:
        async with aiohttp.ClientSession() as session:
            async with session.get(station.base + "/") as page:
                assert page.status == 200
                text = await page.text()
                assert 'data-testid="agents"' in text and "static/app.js" in text
                csp = page.headers["Content-Security-Policy"]
                assert "script-src 'self'" in csp and "frame-ancestors 'none'" in csp
                assert page.headers["X-Frame-Options"] == "DENY"
            for path in (
                "/static/app.js",
                "/static/style.css",
                "/static/vendor/leaflet/leaflet.js",
                "/static/vendor/leaflet/leaflet.css",
                "/static/vendor/leaflet/images/marker-icon.png",
            ):
                async with session.get(station.base + path) as response:
                    assert response.status == 200, path
            async with session.get(station.base + "/static/../server.py") as response:
                assert response.status in (403, 404)
            # another site's name resolving to 127.0.0.1 (DNS rebinding) is refused
            host = {"Host": f"attacker.example:{station.served.server.port}"}
            async with session.get(station.base + "/", headers=host) as response:
                assert response.status == 403

    run(go())


def test_with_a_token_every_request_needs_it(guarded: Station) -> None:
    base = guarded.base

    async def go() -> None:
        async with aiohttp.ClientSession() as session:
            for path in ("/", "/static/app.js", "/ws", "/?token=wrong-token-0123456789"):
                async with session.get(base + path) as response:
                    assert response.status == 403, path
            with pytest.raises(aiohttp.WSServerHandshakeError) as refused:
                await session.ws_connect(base + "/ws")
            assert refused.value.status == 403
            headers = {"X-Clark-Token": TOKEN}
            async with session.get(base + "/static/app.js", headers=headers) as response:
                assert response.status == 200
            bearer = {"Authorization": f"Bearer {TOKEN}"}
            async with session.get(base + "/", headers=bearer) as response:
                assert response.status == 200
        # a browser: the token once in the URL, then the cookie
        jar = aiohttp.CookieJar(unsafe=True)  # cookies for an IP address
        async with aiohttp.ClientSession(cookie_jar=jar) as browser:
            async with browser.get(f"{base}/?token={TOKEN}", allow_redirects=False) as moved:
                assert moved.status == 303 and moved.headers["Location"] == "/"
                cookie = moved.cookies[guarded.served.server.cookie_name]
                assert cookie["httponly"] and cookie["samesite"] == "Strict"
            async with browser.get(base + "/") as page:
                assert page.status == 200
            async with browser.get(base + "/static/vendor/leaflet/leaflet.js") as script:
                assert script.status == 200
            async with browser.ws_connect(base + "/ws") as ws:
                assert (await receive(ws))["type"] == "hello"
        async with (
            aiohttp.ClientSession() as tool,
            tool.ws_connect(f"{base}/ws?token={TOKEN}") as ws,
        ):
            assert (await receive(ws))["type"] == "hello"  # a tool's WebSocket: no redirect

    run(go())


# -- the WebSocket --------------------------------------------------------------------------


def test_websocket_sends_hello_then_state(station: Station) -> None:
    codec = Codec(521, 3)
    address = station_address(station)

    async def go() -> None:
        async with (
            aiohttp.ClientSession() as session,
            session.ws_connect(station.base + "/ws") as ws,
        ):
            hello = await receive(ws)
            assert hello["type"] == "hello" and hello["protocol"] == 1
            assert [a["name"] for a in hello["agents"]] == ["slash_a", "slash_b"]
            assert hello["plan"]["slash_a"][0]["kind"] == "tour"
            state = await receive_until(ws, "state")
            assert {a["name"] for a in state["agents"]} == {"slash_a", "slash_b"}
            assert state["checks"] is None and state["station"]["name"] == "mcs"
            station.heartbeat(codec, address)  # slash_b speaks: it shows as heard

            def heard(message: dict[str, Any]) -> bool:
                return any(a["name"] == "slash_b" and a["heard"] for a in message["agents"])

            state = await receive_until(ws, "state", heard)
            (slash_b,) = [a for a in state["agents"] if a["name"] == "slash_b"]
            assert slash_b["condition"] == "ok" and slash_b["link"]["packets"] == 1
            assert any("found slash_b" in line["text"] for line in state["log"])

    run(go())


def test_a_command_reaches_the_shell_and_goes_out_as_clarklink(station: Station) -> None:
    receiver = Codec(521, 3)  # slash_b's own codec, to read what the station sends it

    async def go() -> dict[str, Any]:
        async with (
            aiohttp.ClientSession() as session,
            session.ws_connect(station.base + "/ws") as ws,
        ):
            await receive(ws)  # hello
            command = {
                "type": "command",
                "action": "activate",
                "target": "slash_b",
                "operator": "tess",
                "ref": "a1",
            }
            await ws.send_str(json.dumps(command))
            accepted = await receive_until(ws, "accepted")
            assert accepted["ref"] == "a1" and accepted["id"] == 1

            def listed(message: dict[str, Any]) -> bool:
                return any(c["id"] == 1 for c in message["commands"])

            state = await receive_until(ws, "state", listed)
            (entry,) = [c for c in state["commands"] if c["id"] == 1]
            return entry  # type: ignore[no-any-return]

    entry = run(go())
    assert entry["action"] == "activate" and entry["target"] == "slash_b"
    assert entry["status"] == "pending" and entry["by"] == {"name": "tess", "address": "127.0.0.1"}
    # what slash_b's radio receives: an Activate Controller aimed at it
    deadline = time.monotonic() + TIMEOUT_S
    activations: list[ActivateController] = []
    while not activations and time.monotonic() < deadline:
        ready, _, _ = select.select([station.slash_b], [], [], 1.0)
        if ready:
            packet = receiver.decode(station.slash_b.recv(4096))
            activations = [m for m in packet.messages if isinstance(m, ActivateController)]
    (activation,) = activations
    assert activation.target_id == 3 and activation.active and activation.agent_id == 1
    log = station.shell.runtime.logbook.streams.mission.getvalue()  # type: ignore[attr-defined]
    assert "view command 1 from tess at 127.0.0.1: activate slash_b" in log
    assert "operator: activate slash_b" in log


BAD_MESSAGES = [
    ("not json at all", "not JSON"),
    ("[1, 2]", "not a JSON object"),
    ('{"type": "hello"}', "unknown message type"),
    ('{"type": "command", "action": "explode", "target": "slash_b"}', "unknown action"),
    ('{"type": "command", "action": "activate", "target": "nobody"}', "no such agent"),
    (json.dumps({"type": "command", "action": "activate", "target": "x" * 10_000}), "target"),
    ('{"type": "command", "action": "mode", "target": "slash_b", "mode": "WARP"}', "no such mode"),
    ('{"type": "command", "action": "mode", "target": "slash_b", "mode": "INITIALISING"}', "mode"),
    ('{"type": "command", "action": "mode", "target": "all", "mode": "HOLD"}', "one agent"),
    ('{"type": "command", "action": "terminate", "target": "all"}', "confirm"),
    ('{"type": "command", "action": "terminate", "target": "all", "confirm": "yes"}', "confirm"),
    ('{"type": "command", "action": "activate", "target": 3}', "target"),
    ('{"type": "command", "action": "activate", "target": "slash_b", "ref": [1]}', "ref"),
]


@pytest.mark.parametrize(("text", "reason"), BAD_MESSAGES)
def test_parse_command_refuses(text: str, reason: str) -> None:
    hello = build_hello(CONFIGS["mcs"])
    with pytest.raises(ValueError, match=reason):
        parse_command(text, hello, command_id=1, address="127.0.0.1")


def test_parse_command_bounds_the_operator_name() -> None:
    hello = build_hello(CONFIGS["mcs"])
    text = json.dumps(
        {
            "type": "command",
            "action": "terminate",
            "target": "slash_a",
            "confirm": True,
            "operator": "<b>\n" + "z" * 100,
        }
    )
    request, ref = parse_command(text, hello, command_id=7, address="::1")
    assert (request.id, request.action, request.target, ref) == (7, "terminate", "slash_a", None)
    assert request.operator.startswith("<b>\\x0a") and len(request.operator) <= 40


def test_bad_messages_are_refused_and_the_server_carries_on(station: Station) -> None:
    async def go() -> None:
        async with aiohttp.ClientSession() as session:
            async with session.ws_connect(station.base + "/ws") as ws:
                await receive(ws)
                for text, _reason in BAD_MESSAGES[:9]:
                    await ws.send_str(text)
                    error = await receive_until(ws, "error")
                    assert error["error"]
                await ws.send_bytes(b"\x00\x01")
                assert (await receive_until(ws, "error"))["error"] == "text only"
                # a flood is cut short
                for _ in range(15):
                    await ws.send_str('{"type": "command"}')
                errors = [(await receive_until(ws, "error"))["error"] for _ in range(15)]
                assert "too many commands" in errors
            async with session.ws_connect(station.base + "/ws") as ws:
                await receive(ws)
                await ws.send_str("x" * (MAX_MESSAGE_BYTES + 1))  # too big: the link is closed
                closing = await ws.receive(timeout=TIMEOUT_S)
                while closing.type == aiohttp.WSMsgType.TEXT:  # states sent meanwhile
                    closing = await ws.receive(timeout=TIMEOUT_S)
                assert closing.type in (aiohttp.WSMsgType.CLOSE, aiohttp.WSMsgType.CLOSED)
                assert ws.close_code == 1009  # message too big
            async with session.ws_connect(station.base + "/ws") as ws:
                assert (await receive(ws))["type"] == "hello"  # still serving
        assert station.served.server.stats["commands"] == 0
        assert station.thread.is_alive()

    run(go())


def test_another_sites_page_cannot_open_the_websocket(station: Station) -> None:
    async def go() -> None:
        async with aiohttp.ClientSession() as session:
            with pytest.raises(aiohttp.WSServerHandshakeError) as refused:
                await session.ws_connect(
                    station.base + "/ws", headers={"Origin": "http://attacker.example"}
                )
            assert refused.value.status == 403
            own = {"Origin": station.base}
            async with session.ws_connect(station.base + "/ws", headers=own) as ws:
                assert (await receive(ws))["type"] == "hello"

    run(go())


def test_a_slow_client_skips_states_but_gets_every_track_point() -> None:
    hello = build_hello(CONFIGS["mcs"])
    server = ViewServer(hello, lambda r: None, port=0)
    server.start()
    published = 400
    try:

        async def go() -> tuple[int, list[int]]:
            async with (
                aiohttp.ClientSession() as session,
                session.ws_connect(f"http://127.0.0.1:{server.port}/ws") as ws,
            ):
                await receive(ws)  # hello
                for k in range(1, published + 1):  # faster than anyone reads
                    state = {"type": "state", "t": k, "padding": "p" * 20_000}
                    point = {"seq": k, "agent": 2, "t": k, "north_m": k, "east_m": 0.0}
                    server.publish(Snapshot(state, [point], [], []))
                states = 0
                seqs: list[int] = []
                while not seqs or seqs[-1] < published:
                    message = await receive(ws)
                    states += 1
                    seqs += [p["seq"] for p in message["track"]]
                return states, seqs

        states, seqs = run(go())
    finally:
        server.stop()
    assert seqs == list(range(1, published + 1))  # none lost, none twice
    assert states < published  # the newest state won; the rest were skipped


# -- clark run --view -----------------------------------------------------------------------


def test_clark_run_serves_the_view(tmp_path: Path) -> None:
    proc = subprocess.Popen(
        [
            sys.executable,
            "-m",
            "clark_engine",
            "run",
            str(MISSION),
            "--agent",
            "mcs",
            "--view",
            "127.0.0.1:0",
            "--no-radio",
            "--plain",
            "--until",
            "5",
            "--logs",
            str(tmp_path / "logs"),
        ],
        cwd=tmp_path,
        stdin=subprocess.DEVNULL,
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
    )
    try:
        assert proc.stdout is not None
        url = None
        deadline = time.monotonic() + TIMEOUT_S
        while url is None and time.monotonic() < deadline:
            line = proc.stdout.readline()
            assert line, proc.stderr.read() if proc.stderr else "no output"
            if "station view at " in line:
                url = line.split("station view at ", 1)[1].strip()
        assert url is not None and url.startswith("http://127.0.0.1:")
        with urllib.request.urlopen(url, timeout=TIMEOUT_S) as page:
            assert page.status == 200
            assert "Clark station view" in page.read().decode("utf-8")
        out, err = proc.communicate(timeout=TIMEOUT_S)
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.wait()
    assert proc.returncode == 0, err
    assert "stopped (until)" in out
