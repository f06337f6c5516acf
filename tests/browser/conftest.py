"""Fixtures of the browser tests: one headless Chromium per test module, a page per test.

Every test here is marked ``browser`` and put in the xdist group ``browser`` (each
module's ``pytestmark``), so one worker runs them all, one browser per module. Without
Playwright or without Chromium they skip and say why (``make test`` installs both:
Playwright with the test extra, Debian's chromium through tools/ensure_browser.sh); a
Chromium that is there but does not start fails them.

Each test's page records what it asked of which host, and the uncaught errors of its
script: a test fails if the page reached beyond this machine or its script threw.
"""

from __future__ import annotations

import os
from collections.abc import Iterator
from typing import Any

import pytest
from station_page import (
    CHROMIUM_ENV,
    DEBIAN_CHROMIUM,
    VIEWPORT,
    PageWatch,
    chromium_path,
    launched_browser,
)


@pytest.fixture(scope="module")
def browser() -> Iterator[Any]:
    """Debian's chromium, headless, driven by Playwright (skips without either).

    One per module, not per session: Playwright's synchronous API keeps its asyncio loop
    running while it is started, so every later test of the same worker process that
    calls ``asyncio.run`` (the WebSocket tests) would fail with "cannot be called from a
    running event loop". Stopped at the module's end, it leaves the process as it found it.
    """
    sync_api = pytest.importorskip(
        "playwright.sync_api",
        reason="Playwright is not installed (pip install -e '.[test]'; make test does it)",
    )
    if chromium_path() is None:
        wanted = os.environ.get(CHROMIUM_ENV)
        pytest.skip(
            f"no Chromium at {CHROMIUM_ENV}={wanted}"
            if wanted
            else f"no Chromium at {DEBIAN_CHROMIUM}: Debian's chromium package is not "
            "installed (tools/ensure_browser.sh, run by make test, installs it as root)"
        )
    with sync_api.sync_playwright() as playwright, launched_browser(playwright) as chromium:
        yield chromium


@pytest.fixture
def context(browser: Any) -> Iterator[Any]:
    """A fresh browser context (no cookies, no storage) of 1280x800."""
    ctx = browser.new_context(viewport=VIEWPORT)
    try:
        yield ctx
    finally:
        ctx.close()


@pytest.fixture
def page(context: Any) -> Iterator[Any]:
    """A page that must stay on loopback and whose script must throw nothing."""
    tab = context.new_page()
    watch = PageWatch(tab)
    yield tab
    watch.check()
