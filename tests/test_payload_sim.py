"""`clark payload-sim camera` end to end against the real payload adapters, in a subprocess."""

from __future__ import annotations

import os
import selectors
import signal
import subprocess
import sys
from collections.abc import Callable, Iterator
from contextlib import contextmanager

import pytest

from clark_engine.io.payload import PayloadAdapter, TcpPayloadServer, UdpPayload
from clark_engine.runtime.commands import PayloadCommand
from clark_engine.runtime.events import PayloadEvent

pytestmark = pytest.mark.slow  # starts interpreters

WAIT_S = 10.0


def _wait(
    adapter: PayloadAdapter, until: Callable[[list[PayloadEvent]], bool]
) -> list[PayloadEvent]:
    events: list[PayloadEvent] = []
    fd = adapter.fileno()
    assert fd is not None
    with selectors.DefaultSelector() as selector:
        selector.register(fd, selectors.EVENT_READ)
        events += adapter.receive()
        while not until(events):
            if not selector.select(WAIT_S):
                break
            events += adapter.receive()
    return events


def _clark(*args: str) -> list[str]:
    return [sys.executable, "-m", "clark_engine", *args]


@contextmanager
def _camera(*args: str) -> Iterator[subprocess.Popen[str]]:
    """The camera in a subprocess; stopped with Ctrl-C (SIGINT) and reaped on the way out."""
    env = {**os.environ, "PYTHONUNBUFFERED": "1"}
    process = subprocess.Popen(
        _clark("payload-sim", "camera", *args),
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
        env=env,
    )
    try:
        yield process
    finally:
        if process.poll() is None:
            process.kill()
        process.communicate(timeout=WAIT_S)


def _interrupt(process: subprocess.Popen[str]) -> tuple[int, str, str]:
    process.send_signal(signal.SIGINT)
    out, err = process.communicate(timeout=WAIT_S)
    return process.returncode, out, err


def _capture_all(adapter: PayloadAdapter, request_ids: list[int]) -> list[PayloadEvent]:
    for request_id in request_ids:
        adapter.send(PayloadCommand("camera", "capture", request_id))
    return _wait(adapter, lambda e: len(e) >= len(request_ids))


def test_camera_answers_capture_with_photo_over_tcp_and_reconnects() -> None:
    server = TcpPayloadServer("camera", "127.0.0.1:0")
    server.open()
    address = server.address
    try:
        with _camera("--connect", address, "--capture-delay-s", "0", "--retry-s", "0.05") as cam:
            _wait(server, lambda _e: server.stats.ready >= 1)
            events = _capture_all(server, [1, 2, 3])
            assert [(e.kind, e.request_id) for e in events] == [
                ("captured", 1),
                ("captured", 2),
                ("captured", 3),
            ]
            assert [e.detail for e in events] == ["IMG_0001.jpg", "IMG_0002.jpg", "IMG_0003.jpg"]
            assert not server.stats.dropped

            # The server goes away and comes back on the same port: the camera reconnects.
            server.close()
            server = TcpPayloadServer("camera", address)
            server.open()
            _wait(server, lambda _e: server.stats.ready >= 1)
            assert [e.detail for e in _capture_all(server, [4])] == ["IMG_0004.jpg"]

            code, out, err = _interrupt(cam)
        assert code == 0, err
        assert "Traceback" not in err
        assert "reconnecting" in out and "stopped after 4 pictures" in out
    finally:
        server.close()


def test_camera_over_udp() -> None:
    with UdpPayload("camera", "127.0.0.1:0") as adapter:
        adapter.open()
        with _camera("--connect", adapter.address, "--udp", "--capture-delay-s", "0") as cam:
            _wait(adapter, lambda _e: adapter.connected)
            events = _capture_all(adapter, [7])
            assert [(e.kind, e.request_id, e.detail) for e in events] == [
                ("captured", 7, "IMG_0001.jpg")
            ]
            code, _out, err = _interrupt(cam)
        assert code == 0, err


@pytest.mark.parametrize(
    "args",
    [
        ["camera"],  # --connect missing
        ["camera", "--connect", "nowhere"],
        ["camera", "--connect", "127.0.0.1:0"],
        ["camera", "--connect", "127.0.0.1:5005", "--capture-delay-s", "-1"],
        ["camera", "--connect", "127.0.0.1:5005", "--capture-delay-s", "soon"],
        ["camera", "--connect", "127.0.0.1:5005", "--retry-s", "0"],
        ["lidar", "--connect", "127.0.0.1:5005"],
    ],
)
def test_bad_usage_exits_2_without_traceback(args: list[str]) -> None:
    result = subprocess.run(
        _clark("payload-sim", *args), capture_output=True, text=True, timeout=WAIT_S
    )
    assert result.returncode == 2, result.stderr
    assert "Traceback" not in result.stderr
    assert "error" in result.stderr
