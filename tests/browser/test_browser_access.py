"""Who may open the station's view, in a real browser (docs/station-view.md, "Security").

Each test starts a real ``clark run`` station (cooperative_follow's ``mcs``, no radio)
serving its view, and opens it in headless Chromium as an operator would, and as another
machine or another site would. The browser reaches loopback only: another machine's
name for the station (the machine's own host name, which the URL a station bound to
0.0.0.0 prints) and other sites' names (``*.test``) resolve to 127.0.0.1 in the browser,
so the requests carry those names in their ``Host`` and ``Origin`` exactly as they would
from elsewhere, and meet the server's real checks.
"""

from __future__ import annotations

import threading
from collections.abc import Iterator
from http.server import BaseHTTPRequestHandler, ThreadingHTTPServer
from pathlib import Path
from typing import Any
from urllib.parse import urlsplit

import pytest
from station_page import MISSION, ServedStation, served_station

sync_api = pytest.importorskip(
    "playwright.sync_api",
    reason="Playwright is not installed (pip install -e '.[test]'; make test does it)",
)
expect = sync_api.expect

pytestmark = [pytest.mark.browser, pytest.mark.xdist_group("browser")]

TOKEN = "browser-test-token-0123456789"
WAIT_MS = 20_000

OPEN_WEBSOCKET = """
url => new Promise(resolve => {
  const ws = new WebSocket(url);
  const done = what => { try { ws.close(); } catch (e) {} resolve(what); };
  ws.onmessage = event => done("message " + JSON.parse(event.data).type);
  ws.onerror = () => done("refused");
  ws.onclose = event => done("closed " + event.code);
  setTimeout(() => done("no answer"), 10000);
})
"""
"""Opens a WebSocket from the page's own origin and says what came of it."""


def _station(tmp_path: Path, *view: str) -> Iterator[ServedStation]:
    argv = [
        "run",
        str(MISSION),
        "--agent",
        "mcs",
        "--no-radio",
        "--plain",
        "--no-console",
        "--until",
        "300",
        "--logs",
        str(tmp_path / "logs"),
        *view,
    ]
    with served_station(argv, tmp_path) as station:
        station.wait_for_url()
        yield station


@pytest.fixture
def lan_station(tmp_path: Path) -> Iterator[ServedStation]:
    """A station serving its view beyond this machine (0.0.0.0), with a token."""
    token_file = tmp_path / "view.token"
    token_file.write_text(TOKEN + "\n", encoding="utf-8")
    yield from _station(tmp_path, "--view", "0.0.0.0:0", "--view-token-file", str(token_file))


@pytest.fixture
def loopback_station(tmp_path: Path) -> Iterator[ServedStation]:
    """A station serving its view on loopback (the default), without a token."""
    yield from _station(tmp_path, "--view", "127.0.0.1:0")


@pytest.fixture
def other_site() -> Iterator[str]:
    """Another site's page on this machine (a plain HTTP server); its address."""

    class Page(BaseHTTPRequestHandler):
        def do_GET(self) -> None:
            body = b"<!doctype html><title>another site</title><p>another site</p>"
            self.send_response(200)
            self.send_header("Content-Type", "text/html")
            self.send_header("Content-Length", str(len(body)))
            self.end_headers()
            self.wfile.write(body)

        def log_message(self, format: str, *args: Any) -> None:
            pass

    server = ThreadingHTTPServer(("127.0.0.1", 0), Page)
    thread = threading.Thread(target=server.serve_forever, daemon=True)
    thread.start()
    try:
        yield f"http://localhost:{server.server_address[1]}/"
    finally:
        server.shutdown()
        server.server_close()
        thread.join()


def _expect_view_loaded(page: Any) -> None:
    """The view is live and lists the mission's agents (none heard: there is no radio)."""
    expect(page.get_by_test_id("connection")).to_have_text("live", timeout=WAIT_MS)
    expect(page.get_by_test_id("mission-name")).to_contain_text("cooperative-follow")
    for name in ("slash_a", "slash_b"):
        row = page.get_by_test_id(f"agent-row-{name}")
        expect(row.locator('[data-field="liveness"]')).to_have_text("not heard")


def test_a_page_from_another_machine_needs_the_token(
    lan_station: ServedStation, page: Any, context: Any, browser: Any
) -> None:
    printed = lan_station.url
    assert printed is not None
    parts = urlsplit(printed)
    assert parts.query == f"token={TOKEN}"  # the station printed the URL with its token
    address = f"http://{parts.netloc}/"  # the station's address from another machine

    for path in ("", "static/app.js", "?token=not-the-token-0123456789"):
        response = page.goto(address + path)
        assert response is not None and response.status == 403, path
        expect(page.locator("body")).to_contain_text("403 Forbidden: a valid token is required")
        expect(page.get_by_test_id("agents")).to_have_count(0)

    response = page.goto(printed)  # the printed URL: the token once, then the cookie
    assert response is not None and response.status == 200
    assert page.url == address  # the token left the address bar
    _expect_view_loaded(page)
    assert TOKEN not in page.evaluate("document.cookie")  # HttpOnly: no script reads it
    (cookie,) = [c for c in context.cookies() if c["value"] == TOKEN]
    assert cookie["httpOnly"] and cookie["sameSite"] == "Strict"

    # another browser, without the cookie: refused again
    stranger = browser.new_context()
    try:
        other = stranger.new_page()
        response = other.goto(address)
        assert response is not None and response.status == 403
        expect(other.locator("body")).to_contain_text("a valid token is required")
    finally:
        stranger.close()


def test_on_loopback_a_page_under_another_name_is_refused(
    loopback_station: ServedStation, page: Any
) -> None:
    printed = loopback_station.url
    assert printed is not None and printed.startswith("http://127.0.0.1:")
    port = urlsplit(printed).port
    # DNS rebinding: another site's name, made to resolve to 127.0.0.1
    response = page.goto(f"http://rebinding.test:{port}/")
    assert response is not None and response.status == 403
    expect(page.locator("body")).to_contain_text(
        "403 Forbidden: this view answers to its own address only"
    )
    expect(page.get_by_test_id("agents")).to_have_count(0)
    for own in (printed, f"http://localhost:{port}/"):
        response = page.goto(own)
        assert response is not None and response.status == 200, own
        _expect_view_loaded(page)


def test_another_sites_page_cannot_open_the_websocket(
    loopback_station: ServedStation, page: Any, other_site: str
) -> None:
    printed = loopback_station.url
    assert printed is not None
    websocket = "ws://" + urlsplit(printed).netloc + "/ws"
    page.goto(printed)
    _expect_view_loaded(page)
    assert page.evaluate(OPEN_WEBSOCKET, websocket) == "message hello"  # from its own page
    page.goto(other_site)
    expect(page.locator("body")).to_have_text("another site")
    assert page.evaluate(OPEN_WEBSOCKET, websocket) == "refused"  # its Origin is not the view's
