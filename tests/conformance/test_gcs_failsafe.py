"""The ground-station failsafe: what each firmware does when MAV_GCS_SYSID falls silent.

The engine uses it as the autopilot's reaction to a dead mission computer (its
heartbeats are the ground station's). Measured on SITL (docs/sitl-measurements.md, section 4):
only HEARTBEATs from exactly MAV_GCS_SYSID count; ArduCopter reacts FS_GCS_TIMEOUT
after the last one (checked at 3 Hz), ArduRover FS_GCS_TIMEOUT + FS_TIMEOUT later
(announced as "Radio Failsafe"), ArduPlane FS_LONG_TIMEOUT later (3 Hz); ArduCopter and
ArduRover never react to a ground station they never heard, ArduPlane counts from its
boot; the failsafe ends with the next heartbeat and the mode stays as the failsafe set
it.

The timeouts are set to 2 s to keep the scenarios short; every parameter is put back.
"""

from __future__ import annotations

from collections.abc import Iterator
from contextlib import contextmanager

from flight import goto, here, moved, takeoff
from harness import GCS_SYSTEM_ID, Peer, backends
from pymavlink.dialects.v20 import ardupilotmega as mavlink2

WARNING, INFO = mavlink2.MAV_SEVERITY_WARNING, mavlink2.MAV_SEVERITY_INFO
TIMEOUT_S = 2.0
OTHER_GCS = 245
"""Another ground station's system id (MAVSDK's)."""

FAILSAFE_PARAMS = {
    "copter": {"FS_GCS_TIMEOUT": TIMEOUT_S, "FS_GCS_ENABLE": 1},
    "rover": {"FS_GCS_TIMEOUT": TIMEOUT_S, "FS_ACTION": 2, "FS_GCS_ENABLE": 1},
    "plane": {"FS_LONG_TIMEOUT": TIMEOUT_S, "FS_LONG_ACTN": 1, "FS_GCS_ENABL": 1},
}
"""The failsafe on, reacting after 2 s: ArduCopter RTL (or LAND), ArduRover HOLD, ArduPlane
RTL."""
DELAY_S = {"copter": TIMEOUT_S, "rover": TIMEOUT_S + 1.5, "plane": TIMEOUT_S}
"""From the last heartbeat to the reaction, at least (ArduRover adds FS_TIMEOUT 1.5)."""
SLACK_S = {"copter": 0.45, "rover": 0.25, "plane": 0.45}
"""And at most this much later: a check period (3 Hz; ArduRover 10 Hz) and the link.
SITL: copter 5.15-5.25 s, rover 6.50-6.56 s, plane 5.1-5.3 s with 5 s timeouts."""
CLOCK_S = 0.1
"""The ground station's clock resolution (SYSTEM_TIME at 10 Hz)."""
ON_TEXT = {"copter": "GCS Failsafe", "rover": "Radio Failsafe", "plane": "GCS Failsafe On: RTL"}
"""The WARNING: ArduRover's says "Radio" (its radio check reaches the shared trigger first)."""
OFF_TEXT = {
    "copter": (WARNING, "GCS Failsafe Cleared"),
    "rover": (INFO, "GCS Failsafe Cleared"),
    "plane": (WARNING, "GCS Failsafe Off"),
}


@contextmanager
def params(peer: Peer, values: dict[str, float]) -> Iterator[Peer]:
    """The parameters set in order, and put back in reverse order (the failsafe first off)."""
    before = {name: peer.param_get(name).param_value for name in values}
    try:
        for name, value in values.items():
            peer.param_set(name, value)
        yield peer
    finally:
        for name in reversed(list(before)):
            peer.param_set(name, before[name])
        peer.heartbeat_from = (GCS_SYSTEM_ID,)


def mode_now(peer: Peer) -> str:
    return peer.mode_name(peer.heartbeat().custom_mode)


def said(peer: Peer, text: str, within_s: float, mark: int) -> object:
    """The STATUSTEXT ``text`` since a mark, waited for."""
    return peer.wait_for("STATUSTEXT", within_s, where=lambda m: m.text == text, since=mark)


def silence_then_failsafe(
    peer: Peer, sysid: int = GCS_SYSTEM_ID, text: str | None = None
) -> tuple[int, float]:
    """Stop ``sysid``'s heartbeats; wait for the failsafe's WARNING and check its delay.

    Returns:
        The history mark taken at the silence, and the failsafe's time.
    """
    peer.heartbeat_from = tuple(s for s in peer.heartbeat_from if s != sysid)
    last_s = peer.heartbeat_sent_s[sysid]
    mark = peer.mark()
    warning = said(peer, text or ON_TEXT[peer.kind], DELAY_S[peer.kind] + 3.0, mark)
    assert warning.severity == WARNING  # type: ignore[attr-defined]
    at_s = peer.time_of(warning)
    delay_s = at_s - last_s
    # (The send is stamped with the autopilot's last reported time: up to a SYSTEM_TIME,
    # 0.1 s, before the autopilot's own clock when it arrives.)
    low_s = DELAY_S[peer.kind] - CLOCK_S
    assert low_s <= delay_s <= DELAY_S[peer.kind] + SLACK_S[peer.kind], delay_s
    return mark, at_s


def heard_again(peer: Peer, mark: int, sysid: int = GCS_SYSTEM_ID) -> None:
    """Heartbeats again: the failsafe ends at once with its text; the mode stays."""
    mode = mode_now(peer)
    peer.heartbeat_from = (*peer.heartbeat_from, sysid)
    severity, text = OFF_TEXT[peer.kind]
    off = said(peer, text, 2.0, mark)
    assert off.severity == severity  # type: ignore[attr-defined]
    peer.run_for(1.0)
    assert mode_now(peer) == mode


def test_only_mav_gcs_sysid_counts_and_a_disarmed_vehicle_reacts(peer: Peer) -> None:
    # MAV_GCS_SYSID 245 while 255 keeps beating: 245's silence is the failsafe. Disarmed,
    # ArduCopter only says so, ArduRover goes to HOLD from MANUAL, ArduPlane to RTL.
    manual = str(peer.spec.autopilot["manual_mode"])
    assert peer.set_mode(manual).result == mavlink2.MAV_RESULT_ACCEPTED
    peer.heartbeat_from = (GCS_SYSTEM_ID, OTHER_GCS)
    peer.run_for(1.5)  # (a ground station heard before the failsafe is on: no surprise)
    try:
        with params(peer, {"MAV_GCS_SYSID": OTHER_GCS, **FAILSAFE_PARAMS[peer.kind]}):
            peer.run_for(1.5)
            mark, _ = silence_then_failsafe(peer, OTHER_GCS)
            peer.run_for(0.5)
            expected = {"copter": manual, "rover": "HOLD", "plane": "RTL"}[peer.kind]
            assert mode_now(peer) == expected
            assert not peer.is_armed()
            heard_again(peer, mark, OTHER_GCS)
    finally:
        peer.set_mode(manual)


@backends(kinds=("copter",))
def test_copter_flying_guided_returns_when_its_ground_station_falls_silent(
    copter: Peer,
) -> None:
    peer = copter
    peer.run_for(1.5)
    with params(peer, FAILSAFE_PARAMS["copter"]):
        assert peer.arm().result == mavlink2.MAV_RESULT_ACCEPTED
        assert takeoff(peer, 10.0).result == mavlink2.MAV_RESULT_ACCEPTED
        peer.wait_for("EXTENDED_SYS_STATE", 25.0, where=lambda m: m.landed_state == 2)
        mark, at_s = silence_then_failsafe(peer)
        rtl = peer.wait_for(
            "HEARTBEAT", 2.0, where=lambda m: peer.mode_name(m.custom_mode) == "RTL", since=mark
        )
        assert peer.time_of(rtl) - at_s <= 1.1
        heard_again(peer, mark)
        assert mode_now(peer) == "RTL"


@backends(kinds=("copter",))
def test_copter_armed_on_the_ground_disarms(copter: Peer) -> None:
    peer = copter
    peer.run_for(1.5)
    with params(peer, FAILSAFE_PARAMS["copter"]):
        assert peer.arm().result == mavlink2.MAV_RESULT_ACCEPTED
        mark, _ = silence_then_failsafe(peer, text="GCS Failsafe - Disarming")
        texts = [(s.severity, s.text) for s in peer.texts_since(mark)]
        assert texts.index((INFO, "Disarming motors")) < texts.index(
            (WARNING, "GCS Failsafe - Disarming")
        )
        assert not peer.is_armed()
        peer.heartbeat_from = (GCS_SYSTEM_ID,)
        said(peer, "GCS Failsafe Cleared", 2.0, mark)


@backends(kinds=("rover",))
def test_rover_driving_guided_holds_when_its_ground_station_falls_silent(rover: Peer) -> None:
    peer = rover
    peer.run_for(1.5)
    start = here(peer)
    with params(peer, FAILSAFE_PARAMS["rover"]):
        assert peer.set_mode("GUIDED").result == mavlink2.MAV_RESULT_ACCEPTED
        assert peer.arm().result == mavlink2.MAV_RESULT_ACCEPTED
        goto(peer, *moved(start.lat_deg, start.lon_deg, 60.0, 0.0), 0.0)
        peer.run_for(2.0)
        mark, at_s = silence_then_failsafe(peer)
        hold = peer.wait_for(
            "HEARTBEAT", 2.0, where=lambda m: peer.mode_name(m.custom_mode) == "HOLD", since=mark
        )
        assert peer.time_of(hold) - at_s <= 1.1
        heard_again(peer, mark)
        assert mode_now(peer) == "HOLD"


@backends("connecting_peer")
def test_a_ground_station_never_heard(connecting_peer: Peer) -> None:
    # Nobody ever sends as MAV_GCS_SYSID 245. ArduCopter and ArduRover never react to a
    # ground station they never heard; ArduPlane counts from its boot and reacts at once.
    peer = connecting_peer
    peer.heartbeat_from = ()
    peer.start()
    peer.param_set("MAV_GCS_SYSID", OTHER_GCS)
    peer.heartbeat_from = (GCS_SYSTEM_ID,)  # (255 is not the ground station now)
    peer.run_for(TIMEOUT_S + 0.5)  # past the plane's timeout since boot
    mark = peer.mark()
    for name, value in FAILSAFE_PARAMS[peer.kind].items():
        peer.param_set(name, value)
    enabled_s = peer.now_s
    peer.run_for(8.0)
    texts = [s.text for s in peer.texts_since(mark)]
    if peer.kind == "plane":
        on = said(peer, ON_TEXT["plane"], 0.0, mark)
        assert peer.time_of(on) - enabled_s <= 1.0
        assert mode_now(peer) == "RTL"
    else:
        assert not [t for t in texts if "Failsafe" in t], texts
