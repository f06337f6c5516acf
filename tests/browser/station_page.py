"""Helpers of the browser tests: a station served by a real ``clark`` process, a browser.

Shared by tests/browser and tools/screenshot_station.py. The browser is Debian's chromium
(tools/ensure_browser.sh installs it) driven by Playwright, never a browser of
Playwright's own, with a fresh profile per launch (Playwright's own temporary user data
dir, removed when the browser closes). It reaches this machine's loopback only: the
names that stand for other machines and sites are mapped to 127.0.0.1, and every other
request that is not to loopback goes to a proxy that refuses (a loopback port bound and
never listened on), so a page that tried to load anything from outside would fail, not
leak.
"""

from __future__ import annotations

import os
import signal
import socket
import subprocess
import sys
import threading
import time
from collections.abc import Iterator, Sequence
from contextlib import contextmanager, suppress
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any
from urllib.parse import urlsplit

ROOT = Path(__file__).resolve().parents[2]
MISSION = ROOT / "missions" / "cooperative_follow.yaml"

CHROMIUM_ENV = "CLARK_CHROMIUM"
"""Names another Chromium binary than Debian's."""

DEBIAN_CHROMIUM = Path("/usr/bin/chromium")

CHROMIUM_FLAGS = (
    "--headless",
    "--no-sandbox",
    "--disable-gpu",
    "--disable-quic",
    "--no-first-run",
    "--disable-background-networking",
    "--disable-component-update",
    "--disable-sync",
)
"""Known to work with Debian's chromium under Playwright on this kind of machine."""

OTHER_SITE_SUFFIX = ".test"
"""Names under this suffix (RFC 2606) stand for other machines' and other sites' names;
the browser resolves every one of them to 127.0.0.1."""

VIEWPORT = {"width": 1280, "height": 800}

START_TIMEOUT_S = 60.0
STOP_TIMEOUT_S = 15.0


def chromium_path() -> Path | None:
    """The Chromium to drive ($CLARK_CHROMIUM or Debian's), or None when there is none."""
    chosen = os.environ.get(CHROMIUM_ENV)
    path = Path(chosen) if chosen else DEBIAN_CHROMIUM
    return path if path.is_file() and os.access(path, os.X_OK) else None


def machine_names() -> list[str]:
    """This machine's own host name: the URL a station bound to 0.0.0.0 prints names it."""
    name = socket.gethostname()
    return [name] if name and name != "localhost" else []


def chromium_args(refusing_proxy_port: int) -> list[str]:
    """The flags, plus the rules that keep the browser on loopback.

    Args:
        refusing_proxy_port: A loopback port that refuses connections: every request to
            a name that is neither loopback nor mapped below is sent there, and fails.
    """
    mapped = [f"*{OTHER_SITE_SUFFIX}", *machine_names()]
    rules = ", ".join(f"MAP {name} 127.0.0.1" for name in mapped)
    return [
        *CHROMIUM_FLAGS,
        f"--host-resolver-rules={rules}",
        f"--proxy-server=http://127.0.0.1:{refusing_proxy_port}",
        f"--proxy-bypass-list={';'.join(mapped)}",
    ]


@contextmanager
def refusing_port() -> Iterator[int]:
    """A loopback port bound and never listened on: a connection to it is refused."""
    sock = socket.socket(socket.AF_INET, socket.SOCK_STREAM)
    try:
        sock.bind(("127.0.0.1", 0))
        yield int(sock.getsockname()[1])
    finally:
        sock.close()


@contextmanager
def launched_browser(playwright: Any) -> Iterator[Any]:
    """Debian's chromium, headless, under Playwright; closed on every way out.

    Playwright's ``launch`` gives the browser a fresh profile (user data dir) of its own
    and removes it when the browser closes.

    Raises:
        FileNotFoundError: There is no Chromium (see :func:`chromium_path`).
    """
    path = chromium_path()
    if path is None:
        raise FileNotFoundError(f"no Chromium at {DEBIAN_CHROMIUM} (or ${CHROMIUM_ENV})")
    with refusing_port() as port:
        browser = playwright.chromium.launch(
            executable_path=str(path), headless=True, args=chromium_args(port)
        )
        try:
            yield browser
        finally:
            browser.close()


def _allowed_host(host: str) -> bool:
    return (
        host in ("127.0.0.1", "localhost", "[::1]", "::1")
        or host.endswith(OTHER_SITE_SUFFIX)
        or host in machine_names()
    )


class PageWatch:
    """What a page asked beyond this machine, and what its script threw."""

    def __init__(self, page: Any) -> None:
        self.outside: list[str] = []
        self.errors: list[str] = []
        page.on("request", lambda request: self._record(request.url))
        page.on("websocket", lambda socket: self._record(socket.url))
        page.on("pageerror", lambda error: self.errors.append(str(error)))

    def _record(self, url: str) -> None:
        parts = urlsplit(url)
        if parts.scheme in ("http", "https", "ws", "wss") and not _allowed_host(
            parts.hostname or ""
        ):
            self.outside.append(url)

    def check(self) -> None:
        """Fail if the page reached beyond this machine or its script threw."""
        assert not self.outside, f"the page reached beyond this machine: {self.outside}"
        assert not self.errors, f"the page's script threw: {self.errors}"


@dataclass
class ServedStation:
    """A ``clark`` process serving the station view, and what it printed."""

    proc: subprocess.Popen[str]
    lines: list[str] = field(default_factory=list)
    url: str | None = None
    """The view's address as printed, with the token when there is one."""

    _printed: threading.Condition = field(default_factory=threading.Condition)
    _ended: bool = False

    def _read(self) -> None:
        assert self.proc.stdout is not None
        for line in self.proc.stdout:
            with self._printed:
                self.lines.append(line.rstrip("\n"))
                if self.url is None and "station view at " in line:
                    self.url = line.split("station view at ", 1)[1].strip()
                self._printed.notify_all()
        with self._printed:
            self._ended = True
            self._printed.notify_all()

    def wait_for_url(self, timeout_s: float = START_TIMEOUT_S) -> str:
        """The printed address of the view; fails when the process ends or is silent."""
        deadline = time.monotonic() + timeout_s
        with self._printed:
            while self.url is None and not self._ended:
                left = deadline - time.monotonic()
                if left <= 0:
                    break
                self._printed.wait(left)
            if self.url is None:
                raise AssertionError(f"no station view address printed:\n{self.output()}")
            return self.url

    def wait_for_line(self, text: str, timeout_s: float) -> str:
        """The first line printed that contains ``text``; fails after ``timeout_s``."""
        deadline = time.monotonic() + timeout_s
        with self._printed:
            while True:
                for line in self.lines:
                    if text in line:
                        return line
                left = deadline - time.monotonic()
                if self._ended or left <= 0:
                    raise AssertionError(f"{text!r} never printed:\n{self.output()}")
                self._printed.wait(left)

    def output(self) -> str:
        """Everything printed so far (stdout and stderr together)."""
        with self._printed:
            return "\n".join(self.lines)


@contextmanager
def served_station(argv: Sequence[str], cwd: Path) -> Iterator[ServedStation]:
    """Start ``python -m clark_engine ARGV`` and stop it on every way out.

    It runs in a session of its own, so that it and any process it starts are stopped
    together: SIGINT first (Ctrl-C, which a station answers by stopping cleanly), then
    SIGKILL to its group if it has not ended within :data:`STOP_TIMEOUT_S`.
    """
    proc = subprocess.Popen(
        [sys.executable, "-m", "clark_engine", *argv],
        cwd=cwd,
        stdin=subprocess.DEVNULL,
        stdout=subprocess.PIPE,
        stderr=subprocess.STDOUT,
        text=True,
        start_new_session=True,
        env={**os.environ, "PYTHONUNBUFFERED": "1"},
    )
    served = ServedStation(proc)
    reader = threading.Thread(target=served._read, name="clark-output", daemon=True)
    reader.start()
    try:
        yield served
    finally:
        stop_process(proc)
        reader.join(STOP_TIMEOUT_S)
        if proc.stdout is not None:
            proc.stdout.close()


def stop_process(proc: subprocess.Popen[str]) -> None:
    """Ctrl-C; then SIGKILL to its process group (it leads one of its own).

    The group is killed while its leader is still unreaped (a zombie at worst), so its
    id cannot have passed to another process: only what this process started is hit.
    """
    if proc.returncode is None:
        with suppress(ProcessLookupError):
            proc.send_signal(signal.SIGINT)
        deadline = time.monotonic() + STOP_TIMEOUT_S
        while time.monotonic() < deadline and not _exited(proc.pid):
            time.sleep(0.05)
        with suppress(ProcessLookupError, PermissionError):
            os.killpg(proc.pid, signal.SIGKILL)  # it, if it lingers, and what it left behind
    proc.wait(STOP_TIMEOUT_S)


def _exited(pid: int) -> bool:
    """Whether the child has ended, without reaping it (its pid stays reserved)."""
    try:
        return os.waitid(os.P_PID, pid, os.WEXITED | os.WNOHANG | os.WNOWAIT) is not None
    except ChildProcessError:
        return True
