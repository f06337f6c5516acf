"""Parameters: reading by name and index, setting, and what is never answered."""

from __future__ import annotations

import pytest
from harness import Peer
from pymavlink.dialects.v20 import ardupilotmega as mavlink2

# Present with the same name, type and default in every firmware and in the simulation.
PARAM = "RC_OVERRIDE_TIME"
PARAM_DEFAULT = 3.0
NO_PARAM_INDEX = 65535  # -1 as the uint16 PARAM_VALUE.param_index
ANNOUNCED_AT_BOOT = ("EK3_SRC1_POSXY", "ARSPD_OFFSET")
"""Parameters SITL sets by itself about 4 s after boot and announces (PARAM_VALUE, index
65535) unasked: its EKF source and ArduPlane's airspeed calibration (measured)."""


def test_read_by_name(peer: Peer) -> None:
    value = peer.param_get(PARAM)
    assert value.param_value == pytest.approx(PARAM_DEFAULT)
    assert value.param_type == mavlink2.MAV_PARAM_TYPE_REAL32
    assert value.param_count > 0


def test_answers_by_name_carry_no_index(peer: Peer) -> None:
    assert peer.param_get(PARAM).param_index == NO_PARAM_INDEX
    try:
        assert peer.param_set(PARAM, PARAM_DEFAULT).param_index == NO_PARAM_INDEX
    finally:
        peer.param_set(PARAM, PARAM_DEFAULT)


def test_read_by_index(peer: Peer) -> None:
    mark = peer.mark()
    peer.send(mavlink2.MAVLink_param_request_read_message(peer.spec.system_id, 1, b"", 0))
    # ArduPilot also sends PARAM_VALUE (index 65535) unasked whenever one of its own
    # parameters changes (SITL's statistics, a late echo): the answer is the indexed one.
    first = peer.wait_for(
        "PARAM_VALUE", 2.0, where=lambda m: m.param_index != NO_PARAM_INDEX, since=mark
    )
    assert first.param_index == 0
    again = peer.param_get(str(first.param_id))
    assert again.param_value == first.param_value


def test_set_is_echoed_and_kept(peer: Peer) -> None:
    try:
        echo = peer.param_set(PARAM, 5.0)
        assert echo.param_value == pytest.approx(5.0)
        assert echo.param_type == mavlink2.MAV_PARAM_TYPE_REAL32
        assert peer.param_get(PARAM).param_value == pytest.approx(5.0)
    finally:
        peer.param_set(PARAM, PARAM_DEFAULT)


def test_unknown_names_are_not_answered(peer: Peer) -> None:
    mark = peer.mark()
    peer.send(
        mavlink2.MAVLink_param_request_read_message(peer.spec.system_id, 1, b"NO_SUCH_PARAM", -1)
    )
    peer.send(
        mavlink2.MAVLink_param_set_message(
            peer.spec.system_id, 1, b"NO_SUCH_PARAM", 1.0, mavlink2.MAV_PARAM_TYPE_REAL32
        )
    )
    peer.run_for(1.5)
    # An answer names the parameter asked for. ArduPilot also announces, unasked, the
    # parameters it sets by itself (ANNOUNCED_AT_BOOT at about 4 s on an idle machine;
    # on a loaded one later and others with them): those are not answers.
    values = [m for _, m in peer.history[mark:] if m.get_type() == "PARAM_VALUE"]
    answers = [m.param_id for m in values if m.param_id == "NO_SUCH_PARAM"]
    assert answers == [], f"answered: {[m.param_id for m in values]}"


# ArduPilot 4.7 renamed the system id parameters (and dropped the SRn_* stream rates).
SYSID_NAMES_BEFORE_4_7 = ("SYSID_THISMAV", "SYSID_MYGCS")
SYSID_NAMES_FROM_4_7 = ("MAV_SYSID", "MAV_GCS_SYSID")


def claimed_version(peer: Peer) -> tuple[int, int]:
    """(major, minor) of the ArduPilot release AUTOPILOT_VERSION claims."""
    mark = peer.mark()
    peer.command_long(mavlink2.MAV_CMD_REQUEST_MESSAGE, mavlink2.MAVLINK_MSG_ID_AUTOPILOT_VERSION)
    version = peer.wait_for("AUTOPILOT_VERSION", 1.0, since=mark).flight_sw_version
    return version >> 24 & 0xFF, version >> 16 & 0xFF


def test_system_ids_by_the_names_of_the_claimed_version(peer: Peer) -> None:
    # The simulation claims 4.5.7 and has 4.5's names; the SITL build is 4.7.0-dev. Either
    # way the names must be those of the version claimed, and the other names absent.
    if claimed_version(peer) >= (4, 7):
        (this, gcs), gone = SYSID_NAMES_FROM_4_7, SYSID_NAMES_BEFORE_4_7
    else:
        (this, gcs), gone = SYSID_NAMES_BEFORE_4_7, SYSID_NAMES_FROM_4_7
    assert peer.param_get(this).param_value == peer.spec.system_id
    assert peer.param_get(gcs).param_value == 255
    mark = peer.mark()
    for name in gone:
        peer.send(
            mavlink2.MAVLink_param_request_read_message(
                peer.spec.system_id, 1, name.encode("ascii"), -1
            )
        )
    peer.run_for(1.0)
    answers = [m.param_id for _, m in peer.history[mark:] if m.get_type() == "PARAM_VALUE"]
    assert not set(answers) & set(gone), answers
