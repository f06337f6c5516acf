"""Parameters: reading by name and index, setting, and what is never answered."""

from __future__ import annotations

import pytest
from harness import Peer, backends
from pymavlink.dialects.v20 import ardupilotmega as mavlink2

# Present with the same name, type and default in every firmware and in the simulation.
PARAM = "RC_OVERRIDE_TIME"
PARAM_DEFAULT = 3.0
NO_PARAM_INDEX = 65535  # -1 as the uint16 PARAM_VALUE.param_index


def test_read_by_name(peer: Peer) -> None:
    value = peer.param_get(PARAM)
    assert value.param_value == pytest.approx(PARAM_DEFAULT)
    assert value.param_type == mavlink2.MAV_PARAM_TYPE_REAL32
    assert value.param_count > 0


@backends(
    gaps={
        "sim": "sim: PARAM_VALUE answering a read by name or a PARAM_SET carries the "
        "parameter's index; ArduPilot sends 65535 (the -1 it was asked with)"
    }
)
def test_answers_by_name_carry_no_index(peer: Peer) -> None:
    assert peer.param_get(PARAM).param_index == NO_PARAM_INDEX
    try:
        assert peer.param_set(PARAM, PARAM_DEFAULT).param_index == NO_PARAM_INDEX
    finally:
        peer.param_set(PARAM, PARAM_DEFAULT)


def test_read_by_index(peer: Peer) -> None:
    mark = peer.mark()
    peer.send(mavlink2.MAVLink_param_request_read_message(peer.spec.system_id, 1, b"", 0))
    first = peer.wait_for("PARAM_VALUE", 2.0, since=mark)
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
    answers = [m for _, m in peer.history[mark:] if m.get_type() == "PARAM_VALUE"]
    assert answers == []


@backends(
    gaps={
        "sim": "sim: has ArduPilot 4.5's SYSID_THISMAV and SYSID_MYGCS; this SITL "
        "(4.7) names them MAV_SYSID and MAV_GCS_SYSID"
    }
)
def test_system_ids_by_their_current_names(peer: Peer) -> None:
    assert peer.param_get("MAV_SYSID").param_value == peer.spec.system_id
    assert peer.param_get("MAV_GCS_SYSID").param_value == 255
