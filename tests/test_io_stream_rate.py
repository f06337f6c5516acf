"""The engine gets the position stream at the rate it asked for, even when powered up with
its autopilot.

ArduRover acknowledges a SET_MESSAGE_INTERVAL sent before its first HEARTBEAT and then
streams GLOBAL_POSITION_INT at its own 1 Hz (measured on SITL, and so simulated). The
adapter asked once, was answered, and drove the whole mission on 1 Hz positions: its
guided targets went up to a second late (found by comparing fault_station_loss's rovers
with ArduRover SITL's). It now counts what comes and asks again while it is under half
the rate (io/autopilot_streams.py, STREAM_RATE_CHECK_S).
"""

from __future__ import annotations

from pathlib import Path

import pytest

from clark_engine.dryrun.engine import DryRun
from clark_engine.io.autopilot_decode import MessageDecoder
from clark_engine.validation import validate_file

ROOT = Path(__file__).resolve().parent.parent
ONE_ROVER = ROOT / "missions" / "single_vehicle_mode_change.yaml"


def test_positions_come_at_the_rate_asked_for_after_a_power_up_together(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    seen_s: list[float] = []
    on_position = MessageDecoder._on_position

    def counted(decoder: MessageDecoder, msg: object, now_s: float) -> object:
        seen_s.append(now_s)
        return on_position(decoder, msg, now_s)

    monkeypatch.setattr(MessageDecoder, "_on_position", counted)
    mission = validate_file(ONE_ROVER).mission
    assert mission is not None
    run = DryRun(mission, ONE_ROVER, seed=1, until_s=15.0)
    run.run()
    adapter = run.agents["slash"].adapter
    assert adapter is not None
    rate_hz = adapter.settings.stream_rate_hz
    late = [t for t in seen_s if 10.0 <= t < 15.0]
    assert len(late) >= 0.9 * 5.0 * rate_hz, (len(late), seen_s[:20])
    log = run.agents["slash"].logbook.streams.interface.getvalue()  # type: ignore[attr-defined]
    assert "asking for the streams again" in log
