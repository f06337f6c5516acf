"""An XBee pulled out and plugged back under a live shell (issue 18, item 7).

The real digi-xbee library against an emulated 900HP on a pty: the emulator's
unplug closes the pty's master, and the library's reader then spins on "device
reports readiness to read but returned no data", as on a pulled USB dongle.
Before the fix one unplug wrote tens of thousands of "Serial exception while
reading" lines from the library's logger, and the interface log said nothing
(its summary: "radio reopened 0").
"""

from __future__ import annotations

import logging
import re
import selectors
from collections import Counter
from collections.abc import Iterator
from pathlib import Path

import pytest

from clark_engine.io.xbee import XBeeRadio
from clark_engine.mission.compiler import agent_config
from clark_engine.runtime.config import AgentConfig, config_from_dict
from clark_engine.runtime.logbook import Logbook
from clark_engine.runtime.runtime import AgentRuntime
from clark_engine.shells.links import RadioLink
from clark_engine.shells.realtime import RealtimeShell
from clark_engine.sim.xbee_emulator import XBeeEmulator
from clark_engine.validation import validate_file

ROOT = Path(__file__).resolve().parent.parent
MISSION = ROOT / "missions" / "cooperative_follow.yaml"
STATION = "0013A20040A1B201"
VEHICLES = ("0013A20040A1B202", "0013A20040A1B203")
LIMIT_S = 15.0
"""A bound on the whole rehearsal (a failing run ends here, not in a hang)."""


class CountingHandler(logging.Handler):
    """Counts what reaches digi-xbee's loggers' handlers (what would be written)."""

    def __init__(self) -> None:
        super().__init__(logging.DEBUG)
        self.lines: Counter[str] = Counter()

    def emit(self, record: logging.LogRecord) -> None:
        self.lines[f"{record.name} {record.levelname} {record.getMessage()[:60]}"] += 1


@pytest.fixture
def library_lines() -> Iterator[CountingHandler]:
    handler = CountingHandler()
    library = logging.getLogger("digi.xbee")
    library.addHandler(handler)
    try:
        yield handler
    finally:
        library.removeHandler(handler)


def _config(agent: str) -> AgentConfig:
    mission = validate_file(MISSION).mission
    assert mission is not None
    return config_from_dict(agent_config(mission, mission.agents[agent]))


def test_an_unplug_is_logged_once_each_way_and_the_library_is_contained(
    library_lines: CountingHandler,
) -> None:
    config = _config("mcs")
    runtime = AgentRuntime(config, logbook=Logbook.in_memory(config), gps_epoch_ms=0)
    with XBeeEmulator(throughput_bps=None) as emulator:
        for address in (STATION, *VEHICLES):
            emulator.add_radio(address)
        port = emulator.radios[int(STATION, 16)].port

        def open_radio() -> XBeeRadio:
            radio = XBeeRadio(port, network_id="5ABC", health_interval_s=0.1)
            radio.open()
            return radio

        link = RadioLink(open_radio, f"xbee {port}")
        link.radio = open_radio()
        shell = RealtimeShell(
            runtime, radio=link, selector=selectors.DefaultSelector(), gc_freeze=False
        )
        emulated = emulator.radios[int(STATION, 16)]
        steps: list[str] = []
        back_tick: list[int] = []

        def rehearse(shell: RealtimeShell, now_s: float) -> None:
            radio = link.radio
            assert isinstance(radio, XBeeRadio)
            if not steps and shell.stats.ticks >= 3:
                emulated.unplug()  # the dongle pulled out...
                steps.append("unplugged")
            elif steps == ["unplugged"] and not radio.link_up:
                emulated.plug()  # ...and back in once the radio noticed
                steps.append("plugged")
            elif steps == ["unplugged", "plugged"] and radio.link_up:
                steps.append("back")
                back_tick.append(shell.stats.ticks)
            elif steps[-1:] == ["back"] and (
                "link back" in _interface(shell) or shell.stats.ticks > back_tick[0] + 10
            ):
                shell.stop("rehearsed")  # the line written, or a second for it to be

        shell.on_tick.append(rehearse)
        assert shell.run(until_s=LIMIT_S) == 0
        assert shell.stopped_by == "rehearsed", steps

    log = _interface(shell)
    lost = [line for line in log.splitlines() if "link lost" in line]
    back = [line for line in log.splitlines() if "link back" in line]
    assert len(lost) == 1 and len(back) == 1, log
    # Each with its time in the runtime's clock, and the loss before the return.
    lost_at = float(re.search(r"link lost at t=(\d+\.\d+)", lost[0]).group(1))  # type: ignore[union-attr]
    back_at = float(re.search(r"link back at t=(\d+\.\d+)", back[0]).group(1))  # type: ignore[union-attr]
    assert 0 < lost_at <= back_at
    assert "s down" in back[0]
    assert shell.stats.radio_failures == 1
    assert shell.stats.radio_reopens == 1
    assert "radio reopened 1" in log
    # The library's noise: a few lines at most, the rest counted in the interface log.
    written = sum(library_lines.lines.values())
    assert written < 10, library_lines.lines.most_common(5)
    # (None when the supervisor's own check saw the path go before the reader spun.)
    counted = re.search(r"digi-xbee logged (\d+) line\(s\)", lost[0])
    assert (int(counted.group(1)) if counted else 0) >= written, lost[0]


def _interface(shell: RealtimeShell) -> str:
    stream = shell.runtime.logbook.streams.interface
    return str(stream.getvalue())  # type: ignore[attr-defined]
