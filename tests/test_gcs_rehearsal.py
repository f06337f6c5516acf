"""``clark dry-run MISSION --realtime --station``: the station's view over a rehearsal.

The end-to-end test runs the command as a person would (a subprocess, Ctrl-C to end it)
and talks to its page's WebSocket with aiohttp's client, as the page does; the mission is
cooperative_follow with its autopilots ready after 2 s instead of ArduPilot's 40-odd, so
the vehicles drive within seconds. Nothing waits for a moment on the clock: every step
waits for a message, with a timeout. The rest runs the dry run on its virtual clock.
"""

from __future__ import annotations

import asyncio
import dataclasses
import json
import re
import signal
import socket
import subprocess
import sys
import time
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import Any

import aiohttp
import pytest
from mission_text import with_sim_keys
from sitl_here import real_install

from clark_engine.cli import main
from clark_engine.dryrun.engine import DryRun
from clark_engine.expectations.evaluate import evaluate
from clark_engine.runtime.events import StationCommand
from clark_engine.station.rehearsal_view import (
    NOT_EVALUATED,
    PASSED,
    PENDING,
    LiveChecks,
    final_checks,
    live_checks,
)
from clark_engine.validation import validate_file

ROOT = Path(__file__).resolve().parent.parent
MISSION = ROOT / "missions" / "cooperative_follow.yaml"
NO_STATION = ROOT / "tests" / "valid" / "warn_no_station.yaml"
TIMEOUT_S = 30.0
READY_S = 2


def quick_mission(folder: Path) -> Path:
    """cooperative_follow with its autopilots ready after READY_S seconds."""
    text = MISSION.read_text(encoding="utf-8")
    # The operator on time (the example jitters its script by up to 5 s): the tests here
    # act when the script would; and no bad radio spells, in which a command sent at a
    # wall-clock moment could be lost (a campaign measures those).
    quick = with_sim_keys(
        text,
        f"autopilot_ready_s: {READY_S}, jitter: {{operator_s: 0}}, radio_bursts: {{loss_bad: 0}}",
    )
    path = folder / MISSION.name
    path.write_text(quick, encoding="utf-8")
    return path


def load(path: Path) -> Any:
    mission = validate_file(path, str(path)).mission
    assert mission is not None
    return mission


# -- the command end to end ------------------------------------------------------------------


class Rehearsal:
    """``clark dry-run --realtime --station`` running in a subprocess."""

    def __init__(self, args: list[str], cwd: Path) -> None:
        self.process = subprocess.Popen(
            [sys.executable, "-m", "clark_engine.cli", "dry-run", *args],
            cwd=cwd,
            stdout=subprocess.PIPE,
            stderr=subprocess.PIPE,
            text=True,
        )
        self.err_lines: list[str] = []
        assert self.process.stderr is not None
        deadline = time.monotonic() + TIMEOUT_S
        while time.monotonic() < deadline:
            line = self.process.stderr.readline()
            if not line:
                break
            self.err_lines.append(line)
            found = re.search(r"mcs: station view at (http://\S+)", line)
            if found:
                self.url = found.group(1)
                return
        self.process.kill()
        raise AssertionError("no station view announced:\n" + "".join(self.err_lines))

    @property
    def ws_url(self) -> str:
        return self.url.replace("http://", "ws://").rstrip("/") + "/ws"

    def interrupt(self) -> tuple[int, str, str]:
        """Ctrl-C, as a person ends a real-time run; returns (code, stdout, stderr)."""
        self.process.send_signal(signal.SIGINT)
        out, err = self.process.communicate(timeout=TIMEOUT_S)
        return self.process.returncode, out, "".join(self.err_lines) + err

    def kill(self) -> None:
        if self.process.poll() is None:
            self.process.kill()
            self.process.communicate()


@pytest.fixture
def rehearsal(tmp_path: Path) -> Iterator[Rehearsal]:
    mission = quick_mission(tmp_path)
    running = Rehearsal(
        [
            str(mission),
            "--realtime",
            "--station",
            "--view",
            "127.0.0.1:0",
            "--view-hz",
            "10",
            "--no-operator-script",
            "--until",
            "120",
            "--report",
            str(tmp_path / "report"),
            "--quiet",
        ],
        tmp_path,
    )
    yield running
    running.kill()


async def receive(ws: aiohttp.ClientWebSocketResponse) -> dict[str, Any]:
    message = await ws.receive(timeout=TIMEOUT_S)
    assert message.type == aiohttp.WSMsgType.TEXT, message
    return json.loads(message.data)  # type: ignore[no-any-return]


async def state_where(
    ws: aiohttp.ClientWebSocketResponse, predicate: Callable[[dict[str, Any]], bool]
) -> dict[str, Any]:
    """The first ``state`` message for which ``predicate`` holds."""
    deadline = time.monotonic() + TIMEOUT_S
    while time.monotonic() < deadline:
        message = await receive(ws)
        if message["type"] == "state" and predicate(message):
            return message
    raise AssertionError("no such state")


def agent(state: dict[str, Any], name: str) -> dict[str, Any]:
    return next(a for a in state["agents"] if a["name"] == name)


def active(state: dict[str, Any], name: str) -> list[str]:
    behavior = agent(state, name)["behaviour"]
    return list(behavior["active"]) if behavior else []


@pytest.mark.slow
def test_the_page_watches_and_commands_the_rehearsal(rehearsal: Rehearsal, tmp_path: Path) -> None:
    """hello, live states, an activation from the page, the checks pane, Ctrl-C's last state."""
    last: dict[str, Any] = {}

    async def go() -> None:
        async with (
            aiohttp.ClientSession() as session,
            session.ws_connect(rehearsal.ws_url) as ws,
        ):
            hello = await receive(ws)
            assert hello["type"] == "hello"
            # The station's peers, in the mission's order; the station itself apart.
            assert [a["name"] for a in hello["agents"]] == ["slash_a", "slash_b"]
            assert hello["station"]["name"] == "mcs"
            assert hello["plan_source"] == f"the mission {MISSION.name}"
            assert hello["plan"]["slash_a"][0]["kind"] == "tour"

            # Both vehicles heard, with positions, and slash_b's behaviour started (idle):
            # with --no-operator-script nothing activates it but the page.
            ready = await state_where(
                ws,
                lambda s: (
                    all(agent(s, n)["position"] for n in ("slash_a", "slash_b"))
                    and "idle" in active(s, "slash_b")
                ),
            )
            assert agent(ready, "slash_a")["heard"] and not agent(ready, "slash_a")["lost"]
            assert isinstance(agent(ready, "slash_b")["position"]["north_m"], float)
            # The checks pane: every check of the mission, none failed yet.
            checks = ready["checks"]
            assert [c["name"] for c in checks] == [
                "Slash B reaches Slash A",
                "Slash B parks",
                "no failsafe",
            ]
            assert {c["status"] for c in checks} == {PENDING}

            await ws.send_json(
                {"type": "command", "action": "activate", "target": "slash_b", "ref": 1}
            )
            answer = await state_where(ws, lambda s: bool(s["commands"]))
            accepted = answer["commands"][0]
            assert accepted["action"] == "activate" and accepted["target"] == "slash_b"
            assert accepted["status"] == "pending"  # sent; no answer can be there yet
            done = await state_where(ws, lambda s: s["commands"][0]["status"] not in ("pending",))
            assert done["commands"][0]["status"] == "done", done["commands"][0]
            chasing = await state_where(ws, lambda s: "chase" in active(s, "slash_b"))
            assert agent(chasing, "slash_b")["behaviour"]["last_event"] == "activate"

            code, out, err = rehearsal.interrupt()
            last.update(code=code, out=out, err=err)
            # The last state before the server closes carries the run's own verdicts.
            final: dict[str, Any] | None = None
            while True:
                message = await ws.receive(timeout=TIMEOUT_S)
                if message.type != aiohttp.WSMsgType.TEXT:
                    break
                data = json.loads(message.data)
                if data["type"] == "state":
                    final = data
            assert final is not None
            last["final"] = final

    asyncio.run(go())
    assert last["code"] in (0, 1), last["err"]
    assert "Traceback" not in last["err"]
    assert "stopped at" in last["err"] and "(Ctrl-C)" in last["err"]
    assert (tmp_path / "report" / "summary.md").exists()
    # The checks table and the page's last checks agree, row by row.
    checks_out = last["out"].split("\nSafety (judged in every run):", 1)[0]
    rows = [line.split(" | ") for line in checks_out.splitlines() if line.startswith("| ")][1:]
    table = {row[0].lstrip("| "): row[-1].rstrip(" |") for row in rows if "---" not in row[0]}
    page = {c["name"]: c["status"] for c in last["final"]["checks"]}
    # The run's safety judgement comes last, a row per vehicle and per pair.
    safety = [name for name in page if name.startswith("safety: ")]
    assert safety == ["safety: slash_a", "safety: slash_b", "safety: slash_a - slash_b"]
    page = {name: status for name, status in page.items() if name not in safety}
    words = {"pass": PASSED, "FAIL": "failed", "not evaluated": NOT_EVALUATED}
    assert page == {name: words[verdict] for name, verdict in table.items()}
    assert page["no failsafe"] == PASSED


# -- usage errors ----------------------------------------------------------------------------


def test_station_needs_realtime(capsys: pytest.CaptureFixture[str], tmp_path: Path) -> None:
    report = tmp_path / "report"
    assert main(["dry-run", str(MISSION), "--station", "--report", str(report)]) == 2
    assert "--station needs --realtime" in capsys.readouterr().err
    assert main(["dry-run", str(MISSION), "--realtime", "--view", "0"]) == 2
    assert "--view goes with --station" in capsys.readouterr().err
    assert main(["dry-run", str(MISSION), "--no-operator-script"]) == 2
    assert "--no-operator-script goes with --station" in capsys.readouterr().err
    # Without a station, --realtime still needs its MAVLink ports.
    assert main(["dry-run", str(MISSION), "--realtime"]) == 2
    assert "--realtime needs --mavlink-port" in capsys.readouterr().err
    assert not report.exists()


def test_off_loopback_needs_a_token(capsys: pytest.CaptureFixture[str], tmp_path: Path) -> None:
    report = tmp_path / "report"
    args = ["dry-run", str(MISSION), "--realtime", "--station", "--report", str(report)]
    assert main([*args, "--view", "0.0.0.0:0"]) == 2
    assert "needs a token" in capsys.readouterr().err
    assert main([*args, "--view", "0", "--view-token", "short"]) == 2
    assert "16-256 characters" in capsys.readouterr().err
    assert not report.exists()


@pytest.mark.slow
def test_a_port_in_use_is_refused_before_anything_is_written(tmp_path: Path) -> None:
    holder = socket.socket(socket.AF_INET, socket.SOCK_STREAM)
    holder.bind(("127.0.0.1", 0))
    holder.listen(1)
    port = holder.getsockname()[1]
    report = tmp_path / "report"
    try:
        done = subprocess.run(
            [
                sys.executable,
                "-m",
                "clark_engine.cli",
                "dry-run",
                str(MISSION),
                "--realtime",
                "--station",
                "--view",
                f"127.0.0.1:{port}",
                "--report",
                str(report),
                "--quiet",
            ],
            capture_output=True,
            text=True,
            timeout=TIMEOUT_S,
        )
    finally:
        holder.close()
    assert done.returncode == 2, done.stderr
    assert f"--view: cannot serve on 127.0.0.1:{port}" in done.stderr
    assert "Traceback" not in done.stderr
    assert "dry run of" not in done.stderr  # nothing simulated
    assert not report.exists()


def test_a_mission_without_a_station_is_refused(
    capsys: pytest.CaptureFixture[str], tmp_path: Path
) -> None:
    report = tmp_path / "report"
    args = ["dry-run", str(NO_STATION), "--realtime", "--station", "--view", "0", "--quiet"]
    assert main([*args, "--report", str(report)]) == 1
    err = capsys.readouterr().err
    assert "the mission has none: add an agent with role mcs" in err
    assert not report.exists()


# -- the engine's side, on the virtual clock ----------------------------------------------


def test_the_station_commands_what_the_script_no_longer_does() -> None:
    """--no-operator-script: slash_b idles; a command through the station activates it."""
    mission = load(MISSION)
    # The script on time (the example jitters it by up to 5 s), to compare with the command.
    jitter = {**mission.sim.get("jitter", {}), "operator_s": 0}
    mission = dataclasses.replace(mission, sim={**mission.sim, "jitter": jitter})
    quiet = DryRun(mission, MISSION, seed=1, until_s=100.0, operator_script=False).run()
    assert not quiet.recording.entered_by("slash_b", "chase", 100.0)

    run = DryRun(mission, MISSION, seed=1, until_s=100.0, operator_script=False)
    assert run.station is not None and run.station.name == "mcs"
    sent: list[float] = []

    def operator(t_s: float) -> None:
        if not sent and t_s >= 65.0:  # when the mission's script would have
            sent.append(t_s)
            assert run.command_station(StationCommand("activate", "slash_b"), t_s)

    run.on_step = operator
    result = run.run()
    entered = result.recording.entered_by("slash_b", "chase", 100.0)
    assert sent and entered is not None and sent[0] <= entered < sent[0] + 1.0
    # And the script's own run does the same at the same time.
    scripted = DryRun(mission, MISSION, seed=1, until_s=100.0).run()
    assert scripted.recording.entered_by("slash_b", "chase", 100.0) == pytest.approx(
        entered, abs=0.2
    )


def test_live_checks_are_pending_until_decided() -> None:
    mission = load(MISSION)
    checks = [
        *mission.checks,
        {"name": "far apart", "separation_m": {"min": 1000}},
        {"name": "b reaches its start", "reached": {"agent": "slash_b", "to": [-15, -10]}},
    ]
    early = DryRun(mission, MISSION, seed=1, until_s=30.0).run()
    configs = early.configs
    standing = live_checks(checks, early.recording, configs, mission, 30.0, 170.0)
    by_name = {c["name"]: c for c in standing}
    # Not yet due and not held yet: pending, not failed.
    assert by_name["Slash B reaches Slash A"]["status"] == PENDING
    assert "judged at 120 s" in by_name["Slash B reaches Slash A"]["detail"]
    assert by_name["Slash B parks"]["status"] == PENDING
    # Holds so far over the whole run: still pending; broken once: failed for good.
    assert by_name["no failsafe"]["status"] == PENDING
    assert by_name["far apart"]["status"] == "failed"
    # Held already: passed for good.
    assert by_name["b reaches its start"]["status"] == PASSED

    whole = DryRun(mission, MISSION, seed=1, until_s=170.0).run()
    midway = live_checks(checks, whole.recording, whole.configs, mission, 100.0, 170.0)
    assert {c["name"]: c["status"] for c in midway}["Slash B parks"] == PASSED
    at_end = live_checks(checks, whole.recording, whole.configs, mission, 170.0, 170.0)
    final = final_checks(evaluate(checks, whole.recording, whole.configs, mission.origin))
    assert [c["status"] for c in at_end] == [c["status"] for c in final]
    assert [c["status"] for c in final] == [PASSED, PASSED, PASSED, "failed", PASSED]


def test_checks_are_evaluated_about_once_a_second() -> None:
    mission = load(MISSION)
    run = DryRun(mission, MISSION, seed=1, until_s=20.0)
    now = [0.0]
    checks = LiveChecks(run, mission, 170.0, clock=lambda: now[0])
    assert checks.due()
    checks.evaluate(1.0)
    assert not checks.due()
    now[0] = 0.99
    assert not checks.due()
    now[0] = 1.0
    assert checks.due()
    assert checks.evaluations == 1


# -- over ArduPilot SITL ---------------------------------------------------------------------


_SITL = real_install()
SITL_FOLDER = _SITL.folder if _SITL is not None else None
SITL_TIMEOUT_S = 120.0
"""ArduRover SITL at real time: booted, its GPS fixed and its position reported."""


@pytest.mark.slow
@pytest.mark.sitl
@pytest.mark.skipif(
    SITL_FOLDER is None,
    reason="no ArduPilot SITL: set CLARK_SITL to the folder with the `sitl` launcher",
)
def test_the_page_watches_a_rehearsal_on_ardupilot_sitl(tmp_path: Path) -> None:
    """``--autopilot sitl --realtime --station``: the same page, the vehicles real ArduRover."""
    assert SITL_FOLDER is not None
    running = Rehearsal(
        [
            str(MISSION),
            "--realtime",
            "--station",
            "--autopilot",
            "sitl",
            "--sitl",
            str(SITL_FOLDER),
            "--view",
            "127.0.0.1:0",
            "--no-operator-script",
            "--until",
            "150",
            "--report",
            str(tmp_path / "report"),
            "--quiet",
        ],
        tmp_path,
    )
    try:

        async def go() -> dict[str, Any]:
            async with (
                aiohttp.ClientSession() as session,
                session.ws_connect(running.ws_url) as ws,
            ):
                hello = await receive(ws)
                assert [a["name"] for a in hello["agents"]] == ["slash_a", "slash_b"]
                deadline = time.monotonic() + SITL_TIMEOUT_S
                while time.monotonic() < deadline:
                    message = await receive(ws)
                    if message["type"] == "state" and all(
                        agent(message, n)["position"] and agent(message, n)["mode"]
                        for n in ("slash_a", "slash_b")
                    ):
                        return message
                raise AssertionError("no state with both SITL rovers' positions and modes")

        state = asyncio.run(go())
        # The positions are ArduRover's, near the mission's start positions (metres).
        home_b = agent(state, "slash_b")["position"]
        assert abs(home_b["north_m"] - (-15.0)) < 10 and abs(home_b["east_m"] - (-10.0)) < 10
        assert agent(state, "slash_a")["mode"]["name"] in ("HOLD", "MANUAL", "GUIDED")
        code, _, err = running.interrupt()
    finally:
        running.kill()
    assert "Traceback" not in err
    assert code in (0, 1), err  # the checks' verdict, Ctrl-C before their time
    assert (tmp_path / "report" / "summary.md").is_file()
