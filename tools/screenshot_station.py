"""Screenshot of the station's view during the cooperative-follow rehearsal.

Runs ``clark dry-run missions/cooperative_follow.yaml --realtime --station
--no-operator-script`` (the simulated fleet in real time, the view on a free loopback
port), opens the view in headless Chromium (Debian's, as the browser tests do: see
tests/browser/station_page.py), plays the operator (ana activates slash_b once both
vehicles drive), and saves the page when slash_b has caught up with slash_a: both tracks
on the map, the first check passed in the checks pane. About a minute and a half.

    .venv/bin/python tools/screenshot_station.py            # docs/img/station-view.png

The PNG is reduced to a 256-colour palette (the page has few colours) to stay small.
"""

from __future__ import annotations

import argparse
import io
import sys
import tempfile
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "tests" / "browser"))

from station_page import (  # noqa: E402 (the helpers live beside the browser tests)
    MISSION,
    launched_browser,
    served_station,
)

DEFAULT_OUTPUT = ROOT / "docs" / "img" / "station-view.png"
TIMEOUT_MS = 90_000
MAX_BYTES = 300_000
#: Wide enough for every column of the agents table, tall enough for the mission log.
VIEWPORT = {"width": 1500, "height": 940}


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--output", type=Path, default=DEFAULT_OUTPUT, help="the PNG to write")
    args = parser.parse_args(argv)

    from PIL import Image  # matplotlib's dependency, installed with the engine
    from playwright.sync_api import expect, sync_playwright

    expect.set_options(timeout=TIMEOUT_MS)
    run = ["dry-run", str(MISSION), "--realtime", "--station", "--view", "127.0.0.1:0"]
    run += ["--no-operator-script", "--until", "100", "--quiet"]
    with (
        tempfile.TemporaryDirectory(prefix="clark-screenshot-") as folder,
        served_station(run, Path(folder)) as station,
        sync_playwright() as playwright,
        launched_browser(playwright) as browser,
    ):
        page = browser.new_page(viewport=VIEWPORT)
        page.goto(station.wait_for_url())
        page.get_by_test_id("operator-name").fill("ana")
        behavior = page.get_by_test_id("agent-row-slash_b").locator('[data-field="behaviour"]')
        expect(behavior).to_have_text("idle ← start")  # both vehicles drive now
        page.get_by_test_id("activate-slash_b").click()
        expect(behavior).to_have_text("chase ← activate")
        checks = page.get_by_test_id("checks").locator("li")
        reached = checks.filter(has_text="Slash B reaches Slash A")
        expect(reached).to_have_attribute("data-status", "passed")
        png = page.screenshot()

    image = Image.open(io.BytesIO(png)).convert("RGB").quantize(colors=256)
    args.output.parent.mkdir(parents=True, exist_ok=True)
    image.save(args.output, optimize=True)
    size = args.output.stat().st_size
    print(f"wrote {args.output} ({image.width}x{image.height}, {size // 1000} KB)")
    if size > MAX_BYTES:
        print(f"warning: above {MAX_BYTES // 1000} KB", file=sys.stderr)
        return 1
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
