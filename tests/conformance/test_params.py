"""Parameters: reading by name and index, setting, and what is never answered."""

from __future__ import annotations

import math
from typing import Any

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


# ArduPilot 4.7 renamed the system id parameters and the SRn_* stream rates (MAVn_*). The
# simulation claims the SITL build's version, 4.7.0-dev, and has its names.
NAMES_FROM_4_7 = ("MAV_SYSID", "MAV_GCS_SYSID", "MAV_OPTIONS", "MAV1_EXTRA1")
NAMES_BEFORE_4_7 = ("SYSID_THISMAV", "SYSID_MYGCS", "SYSID_ENFORCE", "SR0_EXTRA1")

_I8, _I16, _I32, _F = (
    mavlink2.MAV_PARAM_TYPE_INT8,
    mavlink2.MAV_PARAM_TYPE_INT16,
    mavlink2.MAV_PARAM_TYPE_INT32,
    mavlink2.MAV_PARAM_TYPE_REAL32,
)
_FENCE = {
    "FENCE_ENABLE": (_I8, 0),
    "FENCE_ACTION": (_I8, 1),
    "FENCE_MARGIN": (_F, 2),
    "FENCE_OPTIONS": (_I16, 0),
}
_AIRCRAFT_FENCE = {
    "FENCE_ALT_MAX": (_F, 100),
    "FENCE_ALT_MIN": (_F, -10),
    "FENCE_AUTOENABLE": (_I8, 0),
}
SAFETY_PARAMETERS: dict[str, dict[str, tuple[int, float | None]]] = {
    "rover": {
        **_FENCE,
        "FENCE_TYPE": (_I8, 6),
        "FENCE_RADIUS": (_F, 300),
        "AVOID_ENABLE": (_I8, 3),
        "FS_GCS_ENABLE": (_I8, 0),
        "FS_GCS_TIMEOUT": (_F, 5),
        "FS_ACTION": (_I8, 2),
        "FS_TIMEOUT": (_F, 1.5),
        "FS_OPTIONS": (_I32, 0),
    },
    "copter": {
        **_FENCE,
        **_AIRCRAFT_FENCE,
        "FENCE_TYPE": (_I8, 7),
        "FENCE_RADIUS": (_F, None),  # SITL's copter.parm sets 150; the firmware's default is 300
        "AVOID_ENABLE": (_I8, 3),
        "FS_GCS_ENABLE": (_I8, 0),
        "FS_GCS_TIMEOUT": (_F, 5),
        "FS_OPTIONS": (_I32, 16),
        "RTL_ALT": (_I32, 1500),
    },
    "plane": {
        **_FENCE,
        **_AIRCRAFT_FENCE,
        "FENCE_TYPE": (_I8, 4),
        "FENCE_RADIUS": (_F, 300),
        "FENCE_OPTIONS": (_I16, 1),
        "FS_GCS_ENABL": (_I8, 0),
        "FS_LONG_ACTN": (_I8, 0),
        "FS_LONG_TIMEOUT": (_F, 5),
        "FS_SHORT_ACTN": (_I8, 0),
        "FS_SHORT_TIMEOUT": (_F, 1.5),
        "RTL_ALTITUDE": (_F, 100),
    },
}
"""The parameters the engine sets for the autopilot's own fence and ground-station failsafe,
with their type and default (None: SITL's parameter file changes it) as read back from each
fresh SITL build (docs/sitl-measurements.md, sections 3 and 4)."""


def claimed_version(peer: Peer) -> int:
    """AUTOPILOT_VERSION.flight_sw_version."""
    mark = peer.mark()
    peer.command_long(mavlink2.MAV_CMD_REQUEST_MESSAGE, mavlink2.MAVLINK_MSG_ID_AUTOPILOT_VERSION)
    return int(peer.wait_for("AUTOPILOT_VERSION", 1.0, since=mark).flight_sw_version)


def unanswered(peer: Peer, names: tuple[str, ...], set_too: bool = False) -> list[str]:
    """Those of ``names`` the autopilot answered within 1.5 s of a read (and a set) of each."""
    mark = peer.mark()
    for name in names:
        peer.send(
            mavlink2.MAVLink_param_request_read_message(
                peer.spec.system_id, 1, name.encode("ascii"), -1
            )
        )
        if set_too:
            peer.send(
                mavlink2.MAVLink_param_set_message(
                    peer.spec.system_id, 1, name.encode("ascii"), 7.0, mavlink2.MAV_PARAM_TYPE_INT16
                )
            )
    peer.run_for(1.5)
    return [
        m.param_id
        for _, m in peer.history[mark:]
        if m.get_type() == "PARAM_VALUE" and m.param_id in names
    ]


def test_the_version_and_names_of_ardupilot_4_7(peer: Peer) -> None:
    version = claimed_version(peer)
    assert (version >> 24 & 0xFF, version >> 16 & 0xFF, version & 0xFF) == (
        4,
        7,
        mavlink2.FIRMWARE_VERSION_TYPE_DEV,
    ), hex(version)
    assert peer.param_get("MAV_SYSID").param_value == peer.spec.system_id
    gcs = peer.param_get("MAV_GCS_SYSID")
    assert (gcs.param_value, gcs.param_type) == (255, mavlink2.MAV_PARAM_TYPE_INT16)
    assert peer.param_get("MAV_OPTIONS").param_value == 0
    # 4.5's names are unknown: no answer to a read, and a set is ignored without a word.
    assert unanswered(peer, NAMES_BEFORE_4_7, set_too=True) == []


def test_fence_and_failsafe_parameters(peer: Peer) -> None:
    for name, (param_type, default) in SAFETY_PARAMETERS[peer.kind].items():
        value = peer.param_get(name)
        assert value.param_type == param_type, name
        if default is not None:
            assert value.param_value == pytest.approx(default), name


def test_the_other_firmwares_failsafe_names_are_unknown(peer: Peer) -> None:
    others = {
        "rover": ("FS_GCS_ENABL",),
        "copter": ("FS_GCS_ENABL", "FS_ACTION"),
        "plane": ("FS_GCS_ENABLE",),
    }
    assert unanswered(peer, others[peer.kind]) == []


@pytest.mark.parametrize(
    ("sent", "sent_type", "stored"),
    [
        (2.7, mavlink2.MAV_PARAM_TYPE_REAL32, 2),  # truncated after adding 0.01
        (-2.7, mavlink2.MAV_PARAM_TYPE_REAL32, -2),
        (300, mavlink2.MAV_PARAM_TYPE_INT8, 127),  # clamped to the int8
    ],
)
def test_an_integer_parameter_truncates_and_clamps(
    peer: Peer, sent: float, sent_type: int, stored: float
) -> None:
    try:
        echo = peer.param_set("FENCE_ACTION", sent, sent_type)
        assert (echo.param_value, echo.param_type) == (stored, mavlink2.MAV_PARAM_TYPE_INT8)
        assert echo.param_index == NO_PARAM_INDEX
        assert peer.param_get("FENCE_ACTION").param_value == stored
    finally:
        peer.param_set("FENCE_ACTION", 1, mavlink2.MAV_PARAM_TYPE_INT8)


def test_no_range_is_enforced_and_nan_is_ignored(peer: Peer) -> None:
    before = peer.param_get("FENCE_RADIUS").param_value
    try:
        assert peer.param_set("FENCE_RADIUS", 5).param_value == 5  # @Range 30-10000
        mark = peer.mark()
        peer.send(
            mavlink2.MAVLink_param_set_message(
                peer.spec.system_id, 1, b"FENCE_RADIUS", math.nan, mavlink2.MAV_PARAM_TYPE_REAL32
            )
        )
        peer.run_for(1.5)
        echoes = [
            m
            for _, m in peer.history[mark:]
            if m.get_type() == "PARAM_VALUE" and m.param_id == "FENCE_RADIUS"
        ]
        assert echoes == []
        assert peer.param_get("FENCE_RADIUS").param_value == 5
    finally:
        peer.param_set("FENCE_RADIUS", before)


# -- the whole list ------------------------------------------------------------------------

WHOLE_LIST: dict[str, tuple[int, str, str]] = {
    "rover": (1240, "FORMAT_VERSION", "MAV3_OPTIONS"),
    "copter": (1354, "FORMAT_VERSION", "MAV3_OPTIONS"),
    "plane": (1406, "FORMAT_VERSION", "MAV3_OPTIONS"),
}
"""Each SITL build's parameter count and its first and last names in index order
(tools/gen_sitl_params.py downloaded them; the simulation ships that list)."""

LIST_SAMPLES: dict[str, dict[str, tuple[int, float]]] = {
    "rover": {
        "ARMING_CHECK": (_I32, 1),
        "LOG_BITMASK": (_I32, 65535),
        "SCHED_LOOP_RATE": (_I16, 50),
        "SERVO1_FUNCTION": (_I16, 26),
        "AHRS_EKF_TYPE": (_I8, 3),
        "SERIAL0_BAUD": (_I32, 115),
    },
    "copter": {
        "ARMING_CHECK": (_I32, 1),
        "LOG_BITMASK": (_I32, 180222),
        "ANGLE_MAX": (_I16, 3000),
        "SCHED_LOOP_RATE": (_I16, 400),
        "ATC_RAT_RLL_P": (_F, 0.135),
        "SERVO1_FUNCTION": (_I16, 33),
    },
    "plane": {
        "ARMING_CHECK": (_I32, 1),
        "PTCH2SRV_TCONST": (_F, 0.25),
        "TRIM_THROTTLE": (_I8, 50),
        "TECS_CLMB_MAX": (_F, 5),
        "ARSPD_TYPE": (_I8, 2),
        "SERVO1_FUNCTION": (_I16, 4),
    },
}
"""Parameters the simulation does not act on, with SITL's type and value: a download must
show them as SITL does (ARMING_CHECK 1: MAVProxy says "Arming checks disabled" otherwise)."""


def download_list(peer: Peer, within_s: float = 30.0) -> dict[int, Any]:
    """PARAM_REQUEST_LIST as a ground station sends it: every PARAM_VALUE by its index.

    ArduPilot also sends PARAM_VALUEs unasked (index 65535): those are left out.
    """
    mark = peer.mark()
    peer.send(mavlink2.MAVLink_param_request_list_message(peer.spec.system_id, 1))
    got: dict[int, Any] = {}
    count = WHOLE_LIST[peer.kind][0]

    def complete(msg: Any) -> bool:
        """the whole list"""
        if msg.param_index != NO_PARAM_INDEX:
            got[msg.param_index] = msg
        return len(got) >= count

    peer.wait_for("PARAM_VALUE", within_s, where=complete, since=mark)
    return got


def test_a_download_lists_every_parameter_in_ardupilots_order(peer: Peer) -> None:
    count, first, last = WHOLE_LIST[peer.kind]
    got = download_list(peer)
    assert sorted(got) == list(range(count))
    assert {m.param_count for m in got.values()} == {count}
    names = [str(got[i].param_id) for i in range(count)]
    assert len(set(names)) == count, "a name is listed twice"
    assert (names[0], names[-1]) == (first, last)
    by_name = {str(m.param_id): m for m in got.values()}
    for name, (param_type, value) in LIST_SAMPLES[peer.kind].items():
        assert (by_name[name].param_type, by_name[name].param_value) == (
            param_type,
            pytest.approx(value),
        ), name
    # The parameters the engine and the simulation use are in the list, with their types.
    for name, (param_type, _default) in SAFETY_PARAMETERS[peer.kind].items():
        if peer.kind == "rover" and name in ("FENCE_ALT_MAX", "FENCE_ALT_MIN", "FENCE_AUTOENABLE"):
            continue
        assert by_name[name].param_type == param_type, name


def read_index(peer: Peer, index: int) -> Any:
    """PARAM_REQUEST_READ by index; the indexed answer, or None within 1.5 s."""
    mark = peer.mark()
    peer.send(mavlink2.MAVLink_param_request_read_message(peer.spec.system_id, 1, b"", index))
    peer.run_for(1.5)
    answers = [
        m
        for _, m in peer.history[mark:]
        if m.get_type() == "PARAM_VALUE" and m.param_index != NO_PARAM_INDEX
    ]
    assert len(answers) <= 1, answers
    return answers[0] if answers else None


def test_read_by_index_reaches_the_whole_list(peer: Peer) -> None:
    count, first, last = WHOLE_LIST[peer.kind]
    assert read_index(peer, 0).param_id == first
    assert read_index(peer, count - 1).param_id == last
    middle = read_index(peer, count // 2)
    assert (middle.param_index, middle.param_count) == (count // 2, count)
    assert peer.param_get(str(middle.param_id)).param_value == middle.param_value
    assert read_index(peer, count) is None


def test_any_listed_parameter_is_set_and_kept(peer: Peer) -> None:
    # One the simulation does not act on: stored, echoed in its own type, read back.
    name = "SCHED_LOOP_RATE"
    before = peer.param_get(name).param_value
    try:
        echo = peer.param_set(name, 123.7)
        assert (echo.param_value, echo.param_type) == (123, _I16)
        assert peer.param_get(name).param_value == 123
    finally:
        peer.param_set(name, before, _I16)
