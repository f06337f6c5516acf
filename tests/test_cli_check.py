"""clark check: the module test tools, against real peers on loopback."""

from __future__ import annotations

import socket
import subprocess
import sys
import threading
from pathlib import Path

from clark_engine.cli import main

ROOT = Path(__file__).resolve().parent.parent
MISSION = ROOT / "missions" / "cooperative_follow.yaml"


def _free_port() -> int:
    sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    sock.bind(("127.0.0.1", 0))
    port = int(sock.getsockname()[1])
    sock.close()
    return port


def _check_station_radio(port: int, seconds: str, *extra: str) -> int:
    """``clark check radio`` for the station on UDP 127.0.0.1:``port``, in this process."""
    return main(
        [
            "check",
            "radio",
            str(MISSION),
            "--agent",
            "mcs",
            "--radio",
            "udp",
            "--radio-address",
            f"127.0.0.1:{port}",
            *extra,
            "--seconds",
            seconds,
        ]
    )


def test_check_radio_hears_a_udp_peer(capsys: object) -> None:
    peer = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    port = _free_port()
    stop = threading.Event()

    def chatter() -> None:
        while not stop.wait(0.1):
            peer.sendto(b"not clarklink", ("127.0.0.1", port))

    thread = threading.Thread(target=chatter)
    thread.start()
    try:
        code = _check_station_radio(port, "1")
    finally:
        stop.set()
        thread.join()
        peer.close()
    out = capsys.readouterr().out  # type: ignore[attr-defined]
    assert code == 0, out
    assert f"own address 127.0.0.1:{port}" in out
    assert "not a ClarkLink packet" in out


def test_usage_errors_exit_2() -> None:
    for argv in (
        ["check", "radio", str(MISSION)],  # no --agent
        ["check", "radio", str(MISSION), "--agent", "nobody"],
        ["run", str(MISSION), "--agent", "slash_b", "--autopilot-connection", "bogus"],
        ["run", "no-such-mission.yaml", "--agent", "mcs"],
        ["check", "autopilot", str(MISSION), "--agent", "mcs"],  # a station has none
    ):
        result = subprocess.run(
            [sys.executable, "-m", "clark_engine", *argv],
            capture_output=True,
            text=True,
            timeout=60,
        )
        assert result.returncode == 2, (argv, result.stderr)
        assert "Traceback" not in result.stderr


def test_check_autopilot_fails_with_1_when_nobody_answers() -> None:
    sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    sock.bind(("127.0.0.1", 0))
    port = sock.getsockname()[1]
    try:
        code = main(
            [
                "check",
                "autopilot",
                str(MISSION),
                "--agent",
                "slash_b",
                "--autopilot-connection",
                f"udpout:127.0.0.1:{port}",
                "--seconds",
                "1",
            ]
        )
    finally:
        sock.close()
    assert code == 1


def test_check_radio_fails_when_an_expected_peer_is_silent(capsys: object) -> None:
    own, silent = _free_port(), _free_port()
    code = _check_station_radio(own, "0.5", "--peer", f"slash_b=127.0.0.1:{silent}")
    out = capsys.readouterr().out  # type: ignore[attr-defined]
    assert code == 1, out
    assert "radio: FAILED: nothing heard in 0.5 s from slash_b" in out


def test_check_radio_says_plainly_when_it_heard_nothing_and_expected_nobody(
    capsys: object,
) -> None:
    code = _check_station_radio(_free_port(), "0.5")
    out = capsys.readouterr().out  # type: ignore[attr-defined]
    assert code == 0, out
    assert "NOTHING was heard" in out and "--peer" in out


def test_a_radio_that_cannot_open_at_start_exits_2() -> None:
    taken = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    taken.bind(("127.0.0.1", 0))
    port = taken.getsockname()[1]
    try:
        result = subprocess.run(
            [
                sys.executable,
                "-m",
                "clark_engine",
                "run",
                str(MISSION),
                "--agent",
                "mcs",
                "--radio",
                "udp",
                "--radio-address",
                f"127.0.0.1:{port}",
                "--no-console",
                "--until",
                "1",
                "--logs",
                "/nonexistent-never-created",
            ],
            capture_output=True,
            text=True,
            timeout=60,
        )
    finally:
        taken.close()
    assert result.returncode == 2, result.stderr
    assert "cannot open mcs's radio" in result.stderr
    assert "--no-radio" in result.stderr
    assert "Traceback" not in result.stderr
