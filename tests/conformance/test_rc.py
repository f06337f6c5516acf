"""RC_CHANNELS_OVERRIDE: taken from the ground station's system id, lapsing after
RC_OVERRIDE_TIME, released by 0, ignored from anyone else.

Channel 6 is overridden: no function on any of the three firmwares (RCn_OPTION 0), so
nothing but RC_CHANNELS changes. What it reads without an override differs (SITL's RC
input holds 1000 us, the simulated pilot's unmapped sticks 1500 us), so each scenario
compares with what the channel read before.
"""

from __future__ import annotations

from collections.abc import Iterator

import pytest
from harness import GCS_SYSTEM_ID, Peer
from modesweep import Step, arm, set_mode
from pymavlink.dialects.v20 import ardupilotmega as mavlink2

CHANNEL = 6
OVERRIDE_US = 1700
NO_CHANGE = 65535
"""chanN_raw that leaves channels 1-8 as they are (0 releases them)."""
OVERRIDE_TIME_S = 3.0
"""RC_OVERRIDE_TIME on every firmware (ArduPilot's default, SITL's too)."""


def override(peer: Peer, channels: dict[int, int], system_id: int = GCS_SYSTEM_ID) -> float:
    """One RC_CHANNELS_OVERRIDE from ``system_id`` (channels not named: no change).

    Returns the autopilot's time it was sent at: read after what already arrived, since a
    SITL vehicle runs on while nobody reads it (a time read before would be stale by as
    long as the test process was not scheduled).
    """
    values = [channels.get(ch, NO_CHANGE if ch <= 8 else 0) for ch in range(1, 19)]
    mav = mavlink2.MAVLink(None, srcSystem=system_id, srcComponent=190)
    msg = mav.rc_channels_override_encode(peer.spec.system_id, 1, *values)
    peer.sync()
    peer.link.send(msg.pack(mav))
    return peer.now_s


def channel_us(msg: object) -> int:
    return int(getattr(msg, f"chan{CHANNEL}_raw"))


@pytest.fixture
def rc(peer: Peer) -> Iterator[tuple[Peer, int]]:
    """The peer with RC_CHANNELS at 10 Hz, and what the channel reads untouched."""
    peer.message_interval("RC_CHANNELS", 100_000)
    override(peer, {CHANNEL: 0})
    peer.run_for(0.3)
    try:
        yield peer, channel_us(peer.wait_for("RC_CHANNELS", 1.0))
    finally:
        override(peer, {CHANNEL: 0})
        peer.message_interval("RC_CHANNELS", 0)


def rc_time_s(msg: object) -> float:
    return float(msg.time_boot_ms) / 1000.0  # type: ignore[attr-defined]


def test_an_override_lapses_after_rc_override_time(rc: tuple[Peer, int]) -> None:
    peer, untouched = rc
    assert untouched != OVERRIDE_US
    assert peer.param_get("RC_OVERRIDE_TIME").param_value == pytest.approx(OVERRIDE_TIME_S)
    sent_s = override(peer, {CHANNEL: OVERRIDE_US})
    taken = peer.wait_for("RC_CHANNELS", 1.0, where=lambda m: channel_us(m) == OVERRIDE_US)
    assert rc_time_s(taken) - sent_s <= 0.3
    lapsed = peer.wait_for("RC_CHANNELS", 5.0, where=lambda m: channel_us(m) == untouched)
    # SITL: back exactly 3.0 s after the override, within its 10 Hz RC_CHANNELS.
    assert OVERRIDE_TIME_S - 0.15 <= rc_time_s(lapsed) - sent_s <= OVERRIDE_TIME_S + 0.3


def test_an_override_sent_again_holds(rc: tuple[Peer, int]) -> None:
    peer, untouched = rc
    for _ in range(5):
        override(peer, {CHANNEL: OVERRIDE_US})
        seen = peer.run_for(1.0)
        values = [channel_us(m) for m in seen if m.get_type() == "RC_CHANNELS"]
        assert values and values[-1] == OVERRIDE_US, values
    override(peer, {CHANNEL: 0})
    peer.wait_for("RC_CHANNELS", 0.5, where=lambda m: channel_us(m) == untouched)


def test_zero_releases_at_once(rc: tuple[Peer, int]) -> None:
    peer, untouched = rc
    override(peer, {CHANNEL: OVERRIDE_US})
    peer.wait_for("RC_CHANNELS", 1.0, where=lambda m: channel_us(m) == OVERRIDE_US)
    released_s = override(peer, {CHANNEL: 0})
    back = peer.wait_for("RC_CHANNELS", 1.0, where=lambda m: channel_us(m) == untouched)
    assert rc_time_s(back) - released_s <= 0.3


def test_an_override_from_another_system_is_ignored(rc: tuple[Peer, int]) -> None:
    peer, untouched = rc
    override(peer, {CHANNEL: OVERRIDE_US}, system_id=GCS_SYSTEM_ID - 1)
    seen = peer.run_for(1.0)
    values = {channel_us(m) for m in seen if m.get_type() == "RC_CHANNELS"}
    assert values == {untouched}


NOT_AT_ZERO = {
    "rover": {
        "MANUAL": "Arm: Throttle (RC3) is not neutral",
        "GUIDED": "Arm: Throttle (RC3) is not neutral",
    },
    "copter": {
        "STABILIZE": "Arm: Throttle too high",
        "GUIDED": "Arm: Throttle (RC3) is not neutral",
    },
    "plane": {
        "MANUAL": "Arm: Throttle (RC3) is not neutral",
        "GUIDED": "Arm: Throttle (RC3) is not neutral",
    },
}
"""The refusal to arm with the throttle off zero (its minimum; a rover's centre), per mode."""


def test_arming_is_refused_with_the_throttle_overridden(peer: Peer) -> None:
    peer.wait_ready()
    throttle = 3
    refusals = {}
    try:
        for mode in NOT_AT_ZERO[peer.kind]:
            set_mode(peer, mode)
            override(peer, {throttle: 1800})
            peer.run_for(0.3)
            refusals[mode] = arm(peer)
            override(peer, {throttle: 0})
            peer.run_for(0.3)
            if refusals[mode].armed:
                peer.disarm()
    finally:
        override(peer, {throttle: 0})
        set_mode(peer, str(peer.spec.autopilot["manual_mode"]))
    assert refusals == {
        mode: Step(4, mode, False, (f"2:{text}",)) for mode, text in NOT_AT_ZERO[peer.kind].items()
    }
