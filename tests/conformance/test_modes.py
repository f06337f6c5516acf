"""Mode changes that need no GPS, and a mode number no firmware has."""

from __future__ import annotations

from collections.abc import Iterator

import pytest
from harness import Peer
from pymavlink.dialects.v20 import ardupilotmega as mavlink2

# Modes the profiles name that fly without a position estimate.
NO_GPS_MODES = {
    "rover": ("MANUAL", "HOLD"),
    "copter": ("STABILIZE", "ALT_HOLD"),
    "plane": ("MANUAL", "FBWA"),
}
UNKNOWN_MODE = 99


def heartbeat_mode(peer: Peer) -> int:
    """custom_mode of the next HEARTBEAT (one sent after what came before)."""
    return int(peer.wait_for("HEARTBEAT", 2.0).custom_mode)


@pytest.fixture
def restored(peer: Peer) -> Iterator[Peer]:
    """The peer; the vehicle goes back to the mode it was in afterwards (a shared SITL)."""
    before = heartbeat_mode(peer)
    yield peer
    peer.set_mode_number(before)


def test_modes_without_gps_are_accepted(restored: Peer) -> None:
    peer = restored
    for name in NO_GPS_MODES[peer.kind]:
        ack = peer.set_mode(name)
        assert ack.result == mavlink2.MAV_RESULT_ACCEPTED, f"{name}: {ack}"
        assert heartbeat_mode(peer) == peer.spec.modes[name], name


def test_set_mode_message_changes_the_mode(restored: Peer) -> None:
    peer = restored
    for name in reversed(NO_GPS_MODES[peer.kind]):
        number = peer.spec.modes[name]
        peer.send(
            mavlink2.MAVLink_set_mode_message(
                peer.spec.system_id, mavlink2.MAV_MODE_FLAG_CUSTOM_MODE_ENABLED, number
            )
        )
        peer.run_for(0.2)
        assert heartbeat_mode(peer) == number, name


def test_set_mode_message_is_not_acknowledged(restored: Peer) -> None:
    peer = restored
    name = NO_GPS_MODES[peer.kind][1]
    mark = peer.mark()
    peer.send(
        mavlink2.MAVLink_set_mode_message(
            peer.spec.system_id, mavlink2.MAV_MODE_FLAG_CUSTOM_MODE_ENABLED, peer.spec.modes[name]
        )
    )
    peer.run_for(1.5)
    acks = [m for _, m in peer.history[mark:] if m.get_type() == "COMMAND_ACK"]
    assert acks == []


def test_an_unknown_mode_is_refused(peer: Peer) -> None:
    before = heartbeat_mode(peer)
    ack = peer.set_mode_number(UNKNOWN_MODE)
    assert ack.result == mavlink2.MAV_RESULT_FAILED
    assert heartbeat_mode(peer) == before


def test_an_unknown_mode_is_explained(peer: Peer) -> None:
    mark = peer.mark()
    peer.set_mode_number(UNKNOWN_MODE)
    peer.run_for(1.0)
    texts = [(s.severity, s.text) for s in peer.texts_since(mark)]
    assert (mavlink2.MAV_SEVERITY_WARNING, f"No such mode {UNKNOWN_MODE}") in texts, texts
