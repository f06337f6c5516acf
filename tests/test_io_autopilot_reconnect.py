"""The adapter sends nothing from before an autopilot loss once the autopilot is back.

The runtime drops every vehicle command while the autopilot is lost and replays none
(docs/runtime.md#safety); the adapter must not either: no speed change of a target from
before the loss, no RC override the behaviour set before it, no command still waiting
for its answer. Driven with the lifecycle tests' ArduPilot frames on a virtual clock.
"""

from __future__ import annotations

from typing import Any

from pymavlink.dialects.v20 import ardupilotmega as mavlink2
from test_io_autopilot_lifecycle import bench

from clark_engine.runtime.commands import Goto, RcOverride, SetMode


def commands_heard(messages: list[Any]) -> list[str]:
    """What the adapter commanded: names of overrides, targets and command numbers."""
    names = []
    for m in messages:
        kind = m.get_type()
        if kind == "COMMAND_LONG":
            names.append(f"COMMAND_LONG {m.command}")
        elif kind in ("RC_CHANNELS_OVERRIDE", "SET_POSITION_TARGET_GLOBAL_INT", "COMMAND_INT"):
            names.append(kind)
    return names


def test_nothing_from_before_the_loss_is_sent_after_it() -> None:
    adapter, ap = bench()
    ap.say(ap.heartbeat("GUIDED", armed=True))
    adapter.command(Goto(30.6375, -96.4787, 0.0, 2.0), 0.5)  # a target with a speed
    adapter.command(RcOverride({3: 1700}), 0.5)  # an override the behaviour set
    adapter.command(SetMode("HOLD", 4), 0.6)  # a mode change in flight, unanswered
    # The autopilot falls silent for 20 s.
    sent_while_lost: list[str] = []
    t = 0.6
    while t < 20.0:
        t = round(t + 0.1, 1)
        sent_while_lost += commands_heard(ap.heard(adapter.poll(t)))
    assert adapter.lost(t)
    # ArduPilot's RC_OVERRIDE_TIME hands the channel back 3 s after the last override:
    # the adapter stops keeping it alive once the autopilot is lost.
    assert sent_while_lost.count("RC_CHANNELS_OVERRIDE") <= 8  # 3 s at 2 Hz, then none
    # It comes back, in the pilot's MANUAL.
    ap.now_s = t
    ap.say(ap.heartbeat("MANUAL", armed=True))
    back = ap.heard(adapter.poll(t))
    for _ in range(30):
        t = round(t + 0.1, 1)
        ap.now_s = t
        ap.say(ap.heartbeat("MANUAL", armed=True))
        back += ap.heard(adapter.poll(t))
    kinds = commands_heard(back)
    assert f"COMMAND_LONG {mavlink2.MAV_CMD_DO_CHANGE_SPEED}" not in kinds
    assert f"COMMAND_LONG {mavlink2.MAV_CMD_DO_SET_MODE}" not in kinds
    assert "SET_POSITION_TARGET_GLOBAL_INT" not in kinds
    overrides = [m for m in back if m.get_type() == "RC_CHANNELS_OVERRIDE"]
    # At most one override on the return, and it releases the channel to the pilot.
    assert len(overrides) <= 1
    assert all(m.chan3_raw == 0 for m in overrides)
    assert adapter.active_overrides == {}
