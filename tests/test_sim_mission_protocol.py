"""The simulated ArduPilot's mission protocol, against what ArduPilot SITL (4.7.0-dev) does.

The module is driven by a pymavlink peer: the ground station encodes with its own
MAVLink object (255/190), the frames are parsed on the autopilot side as the
autopilot parses them, and everything the module sends is parsed by a fresh, strict
pymavlink parser (a bad frame raises). Times are virtual. Every expected value here
was measured on SITL (probe scripts and logs kept out of the repository; the facts
are listed in the module's docstring).
"""

from __future__ import annotations

import math
import struct
from collections.abc import Iterator
from dataclasses import replace
from typing import Any

import pytest
from pymavlink.dialects.v20 import ardupilotmega as mavlink2

from clark_engine.sim.ardupilot.mission_items import (
    MissionItem,
    MissionItemError,
    command_name,
    stored_mission_item,
)
from clark_engine.sim.ardupilot.mission_lists import ITEM_LIMITS
from clark_engine.sim.ardupilot.mission_protocol import MissionProtocol, MissionState

HOME = (30.6372, -96.4786999, 90.09)
GCS_IDS = (255, 190)
OTHER_IDS = (255, 77)

ACCEPTED = mavlink2.MAV_MISSION_ACCEPTED
ERROR = mavlink2.MAV_MISSION_ERROR
DENIED = mavlink2.MAV_MISSION_DENIED
INVALID_SEQUENCE = mavlink2.MAV_MISSION_INVALID_SEQUENCE
UNSUPPORTED = mavlink2.MAV_MISSION_UNSUPPORTED
NO_SPACE = mavlink2.MAV_MISSION_NO_SPACE
CANCELLED = mavlink2.MAV_MISSION_OPERATION_CANCELLED
INFO, WARNING, DEBUG = (
    mavlink2.MAV_SEVERITY_INFO,
    mavlink2.MAV_SEVERITY_WARNING,
    mavlink2.MAV_SEVERITY_DEBUG,
)


def f32(value: float) -> float:
    return float(struct.unpack("<f", struct.pack("<f", value))[0])


class Outbox:
    def __init__(self) -> None:
        self.data = bytearray()

    def write(self, data: bytes) -> None:
        self.data += data


class Link:
    """A ground station and the module inside a simulated autopilot, over real frames."""

    def __init__(self, firmware: str = "arducopter", home_set: bool = True) -> None:
        self.outbox = Outbox()
        self.ap_mav = mavlink2.MAVLink(self.outbox, srcSystem=1, srcComponent=1)
        self.ap_parser = mavlink2.MAVLink(None, 1, 1)
        self.home: tuple[float, float, float] | None = HOME if home_set else None
        self.auto = False
        self.protocol = MissionProtocol(
            self.ap_mav,
            lambda: self.home,
            self._text,
            firmware=firmware,
            in_auto=lambda: self.auto,
        )
        if home_set:
            self.protocol.write_home()
        self.stations = {
            ids: mavlink2.MAVLink(None, srcSystem=ids[0], srcComponent=ids[1])
            for ids in (GCS_IDS, OTHER_IDS)
        }
        self.parser = mavlink2.MAVLink(None)  # not robust: a bad frame raises
        self.handled: list[bool] = []

    def _text(self, severity: int, text: str) -> None:
        self.ap_mav.send(self.ap_mav.statustext_encode(severity, text.encode("ascii")[:50]))

    def send(self, msg: Any, now_s: float = 0.0, ids: tuple[int, int] = GCS_IDS) -> list[Any]:
        """Deliver one ground-station message; returns what the autopilot answered."""
        mav = self.stations[ids]
        data = msg.pack(mav)
        mav.seq = (mav.seq + 1) % 256
        for parsed in self.ap_parser.parse_buffer(data) or []:
            self.handled.append(self.protocol.handle(parsed, now_s))
        return self.take()

    def poll(self, now_s: float) -> list[Any]:
        self.protocol.poll(now_s)
        return self.take()

    def take(self) -> list[Any]:
        data, self.outbox.data = bytes(self.outbox.data), bytearray()
        messages: list[Any] = self.parser.parse_buffer(data) or []
        for msg in messages:
            assert msg.get_type() != "BAD_DATA"
            assert (msg.get_srcSystem(), msg.get_srcComponent()) == (1, 1)
        return messages

    @property
    def gcs(self) -> Any:
        return self.stations[GCS_IDS]

    # ground-station conveniences

    def count(self, n: int, mission_type: int = 0, **kw: Any) -> list[Any]:
        return self.send(self.gcs.mission_count_encode(1, 1, n, mission_type), **kw)

    def item(self, it: MissionItem, **kw: Any) -> list[Any]:
        return self.send(it.mission_item_int(self.gcs, 1, 1), **kw)

    def upload(self, items: list[MissionItem], mission_type: int = 0) -> list[Any]:
        """A well-behaved upload: answers each request; returns every reply in order."""
        replies = self.count(len(items), mission_type)
        out = list(replies)
        while requests := [m for m in replies if m.get_type() == "MISSION_REQUEST"]:
            replies = self.item(items[requests[-1].seq])
            out += replies
        return out

    def download(self, mission_type: int = 0) -> list[Any]:
        (count,) = self.send(self.gcs.mission_request_list_encode(1, 1, mission_type))
        assert count.get_type() == "MISSION_COUNT"
        items = []
        for seq in range(count.count):
            (reply,) = self.send(self.gcs.mission_request_int_encode(1, 1, seq, mission_type))
            items.append(reply)
        return items


def wp(
    seq: int, north_m: float = 0.0, alt_m: float = 10.0, *, frame: int = 3, command: int = 16
) -> MissionItem:
    lat = HOME[0] + north_m / 111319.5
    return MissionItem(
        seq, frame, command, 0, 1, 0.0, 0.0, 0.0, 0.0, round(lat * 1e7), round(HOME[1] * 1e7), alt_m
    )


def mission(n: int) -> list[MissionItem]:
    """n items: a bogus home (ArduPilot discards it), then waypoints 20 m apart."""
    bogus_home = MissionItem(0, 0, 16, 0, 1, 0.0, 0.0, 0.0, 0.0, 10_000_000, 10_000_000, 123.0)
    return [bogus_home] + [wp(i, 20.0 * i, 10.0 + i) for i in range(1, n)]


def kinds(messages: list[Any]) -> list[tuple[Any, ...]]:
    """A compact view of an exchange: (type, the fields that matter)."""
    out: list[tuple[Any, ...]] = []
    for m in messages:
        t = m.get_type()
        if t == "MISSION_REQUEST":
            out.append((t, m.seq, m.mission_type))
        elif t == "MISSION_ACK":
            out.append((t, m.type, m.mission_type))
        elif t == "MISSION_COUNT":
            out.append((t, m.count, m.mission_type))
        elif t == "STATUSTEXT":
            out.append((t, m.severity, m.text))
        elif t == "MISSION_CURRENT":
            out.append((t, m.seq, m.total, m.mission_state, m.mission_mode))
        else:
            out.append((t, m.seq))
    return out


def timeline(link: Link, start_s: float, end_s: float) -> Iterator[tuple[float, Any]]:
    """Poll every 10 ms from start (exclusive) to end (inclusive), as the autopilot would."""
    for i in range(1, round((end_s - start_s) / 0.01) + 1):
        now = round(start_s + i * 0.01, 9)
        for msg in link.poll(now):
            yield now, msg


@pytest.fixture
def link() -> Link:
    return Link()


# -- upload ------------------------------------------------------------------------------------


def test_upload_is_requested_item_by_item_with_mission_request(link: Link) -> None:
    replies = link.upload(mission(4))
    assert kinds(replies) == [
        ("MISSION_REQUEST", 0, 0),
        ("MISSION_REQUEST", 1, 0),
        ("MISSION_REQUEST", 2, 0),
        ("MISSION_REQUEST", 3, 0),
        ("MISSION_ACK", ACCEPTED, 0),
        ("STATUSTEXT", INFO, "Flight plan received"),
    ]
    for msg in replies[:-1]:  # requests and the ack go to the uploader
        assert (msg.target_system, msg.target_component) == GCS_IDS
    assert link.protocol.count == 4
    assert all(link.handled)


def test_seq_0_is_discarded_and_downloads_as_the_current_home(link: Link) -> None:
    link.upload(mission(3))
    home = link.download()[0]
    assert (home.seq, home.frame, home.command, home.current, home.autocontinue) == (0, 0, 16, 0, 1)
    assert (home.x, home.y) == (306372000, -964786999)
    assert home.z == pytest.approx(90.08999633789062, abs=0)  # SITL's bytes for 90.09 m
    link.home = (30.6375, -96.4780, 95.5)  # home moves: item 0 follows
    home = link.download()[0]
    assert (home.x, home.y, home.z) == (306375000, -964780000, 95.5)


def test_download_gives_back_what_arducopter_stored(link: Link) -> None:
    sent = MissionItem(1, 6, 16, 0, 0, 2.7, 3.0, 4.0, 45.0, 306380000, -964780000, 10.123456)
    link.upload([mission(1)[0], sent])
    (count,) = link.send(link.gcs.mission_request_list_encode(1, 1, 0))
    assert (count.count, count.mission_type) == (2, 0)
    back = link.download()[1]
    # frame 6 -> 3, delay kept as whole seconds, the other params dropped, altitude in cm
    assert (back.frame, back.param1, back.param2, back.param3, back.param4) == (3, 2, 0, 0, 0)
    assert (back.x, back.y, back.z) == (306380000, -964780000, f32(10.12))
    assert (back.autocontinue, back.current) == (1, 0)


def test_plane_stores_waypoint_radii_not_a_delay() -> None:
    link = Link("arduplane")
    sent = MissionItem(1, 3, 16, 0, 1, 1.7, 2.6, -3.4, 4.5, 306380000, -964780000, 12.345)
    link.upload([mission(1)[0], sent])
    back = link.download()[1]
    assert (back.param1, back.param2, back.param3, back.param4) == (0, 2, 255, 0)


def test_legacy_mission_item_converts_degrees_in_float32_and_warns_once_per_upload(
    link: Link,
) -> None:
    # (sent, what SITL stored): multiplied by 1e7 in float32, then truncated
    measured = [
        ((30.6372123, -96.4787456), (306372128, -964787456)),
        ((-33.8688197, 151.2092955), (-338688192, 1512092928)),
        ((89.9999999, 179.9999999), (900000000, 1800000000)),
        ((0.00000005, -0.00000005), (0, 0)),
    ]
    for _ in range(2):
        replies = link.count(len(measured) + 1)
        out = list(replies)
        while requests := [m for m in replies if m.get_type() == "MISSION_REQUEST"]:
            seq = requests[-1].seq
            lat, lon = (1.0, 1.0) if seq == 0 else measured[seq - 1][0]
            legacy = link.gcs.mission_item_encode(
                1, 1, seq, 3, 16, 0, 1, 0, 0, 0, 0, lat, lon, 10.123456
            )
            replies = link.send(legacy)
            out += replies
        texts = [k for k in kinds(out) if k[0] == "STATUSTEXT"]
        assert texts == [
            ("STATUSTEXT", WARNING, "got MISSION_ITEM; GCS should send MISSION_ITEM_INT"),
            ("STATUSTEXT", INFO, "Flight plan received"),
        ]
        # the warning leaves after the request the first item brought (a queued text)
        assert kinds(out)[1:3] == [
            ("MISSION_REQUEST", 1, 0),
            ("STATUSTEXT", WARNING, "got MISSION_ITEM; GCS should send MISSION_ITEM_INT"),
        ]
    got = [(m.x, m.y) for m in link.download()[1:]]
    assert got == [stored for _, stored in measured]
    bad = link.gcs.mission_item_encode(1, 1, 0, 3, 16, 0, 1, 0, 0, 0, 0, 91.0, 0.0, 0.0)
    link.count(2)
    assert kinds(link.send(bad)) == [("MISSION_ACK", mavlink2.MAV_MISSION_INVALID_PARAM5_X, 0)]
    assert link.protocol.receiving()  # (a refused conversion does not end the upload)


# -- lost, late, out-of-order and concurrent traffic -------------------------------------------


def test_a_lost_item_is_requested_again_after_one_second(link: Link) -> None:
    items = mission(3)
    assert kinds(link.count(3)) == [("MISSION_REQUEST", 0, 0)]
    assert kinds(link.item(items[0])) == [("MISSION_REQUEST", 1, 0)]
    # item 1 is lost on the way; nothing happens until the request is more than 1 s old
    resent = list(timeline(link, 0.0, 1.5))
    assert [(t, kinds([m])[0]) for t, m in resent] == [(1.01, ("MISSION_REQUEST", 1, 0))]
    assert kinds(link.item(items[1], now_s=1.5)) == [("MISSION_REQUEST", 2, 0)]
    assert kinds(link.item(items[2], now_s=1.6))[0] == ("MISSION_ACK", ACCEPTED, 0)
    assert [m.z for m in link.download()[1:]] == [11.0, 12.0]


def test_an_unanswered_upload_is_requested_every_second_then_cancelled_after_8_s(
    link: Link,
) -> None:
    link.upload(mission(3))
    assert kinds(link.count(5)) == [("MISSION_REQUEST", 0, 0)]
    events = [(t, kinds([m])[0]) for t, m in timeline(link, 0.0, 12.0)]
    # SITL: requests at +0.96, 2.0, 2.96, 4.0, 4.96, 6.0, 6.96 (20 ms stamps), then at +8.0
    # MISSION_ACK OPERATION_CANCELLED and the warning; nothing after.
    requests = [t for t, k in events if k[0] == "MISSION_REQUEST"]
    assert len(requests) == 7
    assert requests == pytest.approx([1.0 * k for k in range(1, 8)], abs=0.1)
    assert events[-2:] == [
        (8.01, ("MISSION_ACK", CANCELLED, 0)),
        (8.01, ("STATUSTEXT", WARNING, "Mission upload timeout")),
    ]
    # the count truncated nothing (5 > 3); the old mission is still there
    assert link.protocol.count == 3
    assert not link.protocol.receiving()


def test_each_item_received_moves_the_timeout(link: Link) -> None:
    items = mission(3)
    link.count(3)
    list(timeline(link, 0.0, 7.5))
    assert kinds(link.item(items[0], now_s=7.5)) == [("MISSION_REQUEST", 1, 0)]
    events = [(t, kinds([m])[0]) for t, m in timeline(link, 7.5, 16.0)]
    assert events[-2][1] == ("MISSION_ACK", CANCELLED, 0)
    assert events[-2][0] == pytest.approx(15.5, abs=0.02)  # measured: +8.0 s after item 0


def test_an_item_out_of_sequence_is_refused_and_the_upload_goes_on(link: Link) -> None:
    items = mission(4)
    link.count(4)
    link.item(items[0])
    assert kinds(link.item(items[2])) == [("MISSION_ACK", INVALID_SEQUENCE, 0)]
    assert kinds(link.item(items[0])) == [("MISSION_ACK", INVALID_SEQUENCE, 0)]  # a duplicate
    assert [kinds([m])[0] for _, m in timeline(link, 0.0, 1.05)] == [("MISSION_REQUEST", 1, 0)]
    link.item(items[1], now_s=1.1)
    link.item(items[2], now_s=1.1)
    assert kinds(link.item(items[3], now_s=1.1))[0] == ("MISSION_ACK", ACCEPTED, 0)
    assert link.protocol.count == 4


def test_a_new_count_from_the_uploader_restarts_the_upload(link: Link) -> None:
    items = mission(5)
    link.upload(mission(2))
    link.count(5)
    link.item(items[0])
    link.item(items[1])
    assert kinds(link.count(3)) == [("MISSION_REQUEST", 0, 0)]
    link.item(items[0])
    link.item(items[1])
    assert kinds(link.item(items[2])) == [
        ("MISSION_ACK", ACCEPTED, 0),
        ("STATUSTEXT", INFO, "Flight plan received"),
    ]
    assert link.protocol.count == 3


def test_another_station_is_denied_during_an_upload(link: Link) -> None:
    items = mission(3)
    link.count(3)
    other = link.stations[OTHER_IDS]
    denied = ("MISSION_ACK", DENIED, 0)
    assert kinds(link.send(other.mission_count_encode(1, 1, 2, 0), ids=OTHER_IDS)) == [denied]
    assert kinds(link.send(items[0].mission_item_int(other, 1, 1), ids=OTHER_IDS)) == [denied]
    # clearing from elsewhere: DENIED then ERROR (measured), the upload goes on
    clear = other.mission_clear_all_encode(1, 1, 0)
    assert kinds(link.send(clear, ids=OTHER_IDS)) == [denied, ("MISSION_ACK", ERROR, 0)]
    for reply in link.send(other.mission_clear_all_encode(1, 1, 0), ids=OTHER_IDS):
        assert (reply.target_system, reply.target_component) == OTHER_IDS
    # reading the list being written is refused too, for anyone
    assert kinds(link.send(link.gcs.mission_request_list_encode(1, 1, 0))) == [denied]
    assert kinds(link.send(link.gcs.mission_request_int_encode(1, 1, 0, 0))) == [denied]
    # another list is not busy
    assert kinds(link.send(link.gcs.mission_request_list_encode(1, 1, 1))) == [
        ("MISSION_COUNT", 0, 1)
    ]
    link.item(items[0])
    link.item(items[1])
    assert kinds(link.item(items[2]))[0] == ("MISSION_ACK", ACCEPTED, 0)


def test_clear_all_from_the_uploader_cancels_the_upload(link: Link) -> None:
    link.upload(mission(3))
    link.count(4)
    assert kinds(link.send(link.gcs.mission_clear_all_encode(1, 1, 0))) == [
        ("MISSION_ACK", ACCEPTED, 0)
    ]
    assert link.protocol.count == 0
    # items still on their way are refused as items outside an upload
    assert kinds(link.item(mission(4)[0])) == [("MISSION_ACK", ERROR, 0)]


def test_items_outside_an_upload_are_errors_and_acks_are_ignored(link: Link) -> None:
    assert kinds(link.item(wp(1))) == [("MISSION_ACK", ERROR, 0)]
    assert link.send(link.gcs.mission_ack_encode(1, 1, 0, 0)) == []
    assert link.handled == [True, True]


def test_guided_items_are_left_to_the_autopilot_even_during_an_upload(link: Link) -> None:
    guided = MissionItem(0, 3, 16, 2, 1, 0, 0, 0, 0, 306380000, -964780000, 10.0)
    altitude = MissionItem(0, 3, 16, 3, 1, 0, 0, 0, 0, 0, 0, 20.0)
    assert link.item(guided) == [] and link.item(altitude) == []
    link.count(3)
    link.item(mission(3)[0])
    assert link.item(MissionItem(1, 3, 16, 2, 1, 0, 0, 0, 0, 306380000, -964780000, 10.0)) == []
    assert link.handled == [False, False, True, True, False]
    assert link.protocol.receiving()  # and ArduPilot still waits for a real item 1
    # a fence item with current 2 is no guided target: it is the fence's
    fence = MissionItem(0, 0, 5001, 2, 1, 4, 0, 0, 0, 306380000, -964780000, 0.0, 1)
    assert kinds(link.item(fence)) == [("MISSION_ACK", ERROR, 1)]


# -- refusals ----------------------------------------------------------------------------------

REFUSALS = {
    # name: (item 1 as sent, MAV_MISSION_RESULT measured on SITL)
    "NaN param1": (MissionItem(1, 3, 16, 0, 1, math.nan, 0, 0, 0, 0, 0, 10.0), 6),
    "NaN param2": (MissionItem(1, 3, 16, 0, 1, 0, math.nan, 0, 0, 0, 0, 10.0), 7),
    "inf param4": (MissionItem(1, 3, 16, 0, 1, 0, 0, 0, math.inf, 0, 0, 10.0), 9),
    "command 0": (MissionItem(1, 3, 0, 0, 1, 0, 0, 0, 0, 0, 0, 10.0), 5),
    "command 31000": (MissionItem(1, 3, 31000, 0, 1, 0, 0, 0, 0, 0, 0, 10.0), 3),
    "NAV_ROI": (MissionItem(1, 3, 80, 0, 1, 0, 0, 0, 0, 0, 0, 10.0), 3),
    "frame LOCAL_NED": (MissionItem(1, 1, 16, 0, 1, 0, 0, 0, 0, 0, 0, 10.0), 2),
    "frame 4": (MissionItem(1, 4, 16, 0, 1, 0, 0, 0, 0, 0, 0, 10.0), 2),
    "frame 7": (MissionItem(1, 7, 16, 0, 1, 0, 0, 0, 0, 0, 0, 10.0), 2),
    "latitude 91": (MissionItem(1, 3, 16, 0, 1, 0, 0, 0, 0, 910_000_000, 0, 10.0), 10),
    "longitude 181": (MissionItem(1, 3, 16, 0, 1, 0, 0, 0, 0, 0, 1_810_000_000, 10.0), 11),
    "altitude NaN": (MissionItem(1, 3, 16, 0, 1, 0, 0, 0, 0, 0, 0, math.nan), 12),
    "altitude 83000": (MissionItem(1, 3, 16, 0, 1, 0, 0, 0, 0, 0, 0, 83000.0), 12),
    "jump to 0": (MissionItem(1, 0, 177, 0, 1, 0, 1, 0, 0, 0, 0, 0.0), 1),
    "jump past the end": (MissionItem(1, 0, 177, 0, 1, 5, 1, 0, 0, 0, 0, 0.0), 1),
}


@pytest.mark.parametrize("name", list(REFUSALS))
def test_a_refused_item_ends_the_upload_with_arduPilots_result(link: Link, name: str) -> None:
    item, result = REFUSALS[name]
    link.upload(mission(4))
    replies = link.upload([mission(1)[0], item])
    assert kinds(replies)[-1] == ("MISSION_ACK", result, 0)
    assert not link.protocol.receiving()
    assert list(timeline(link, 0.0, 10.0)) == []  # no more requests, no timeout
    # MISSION_COUNT 2 truncated the old mission; its item 1 is still the old one
    assert link.protocol.count == 2
    assert link.download()[1].z == 11.0


@pytest.mark.parametrize(
    "item",
    [
        MissionItem(1, 3, 16, 0, 1, 0, 0, 0, math.nan, 0, 0, 10.0),  # NaN yaw is allowed
        MissionItem(1, 2, 16, 0, 1, 0, 0, 0, 0, 0, 0, 10.0),  # MAV_FRAME_MISSION
        MissionItem(1, 1, 112, 0, 1, 5, 0, 0, 0, 0, 0, 0.0),  # frames of DO items unchecked
        MissionItem(1, 0, 177, 0, 1, 1, 1, 0, 0, 0, 0, 0.0),  # jump to 1
        MissionItem(1, 3, 16, 0, 1, 0, 0, 0, 0, 0, 0, 82999.99),
    ],
)
def test_items_arducopter_accepts(link: Link, item: MissionItem) -> None:
    assert kinds(link.upload([mission(1)[0], item]))[-2] == ("MISSION_ACK", ACCEPTED, 0)


def test_seq_0_is_checked_like_any_item(link: Link) -> None:
    bad_home = MissionItem(0, 3, 31000, 0, 1, 0, 0, 0, 0, 0, 0, 0.0)
    assert kinds(link.upload([bad_home, wp(1)]))[-1] == ("MISSION_ACK", UNSUPPORTED, 0)


def test_a_refused_count_ends_the_upload_under_way(link: Link) -> None:
    link.count(4)
    assert kinds(link.count(5000))[0] == ("MISSION_ACK", NO_SPACE, 0)
    assert list(timeline(link, 0.0, 10.0)) == []  # no more requests, no timeout
    assert kinds(link.item(mission(4)[0])) == [("MISSION_ACK", ERROR, 0)]


def test_a_legacy_item_outside_an_upload_is_refused_with_the_warning(link: Link) -> None:
    legacy = link.gcs.mission_item_encode(1, 1, 1, 3, 16, 0, 1, 0, 0, 0, 0, 30.1, -96.1, 10.0)
    assert kinds(link.send(legacy)) == [
        ("MISSION_ACK", ERROR, 0),
        ("STATUSTEXT", WARNING, "got MISSION_ITEM; GCS should send MISSION_ITEM_INT"),
    ]


@pytest.mark.parametrize("firmware", sorted(ITEM_LIMITS))
def test_a_mission_too_long_for_storage_is_refused(firmware: str) -> None:
    link = Link(firmware)
    limit = {"arducopter": 650, "arduplane": 655, "ardurover": 655}[firmware]
    assert kinds(link.count(limit)) == [("MISSION_REQUEST", 0, 0)]
    link.count(0)
    assert kinds(link.count(limit + 1)) == [
        ("MISSION_ACK", NO_SPACE, 0),
        ("STATUSTEXT", WARNING, f"Only {limit} items are supported"),
    ]


# -- download ----------------------------------------------------------------------------------


def test_download_out_of_range_tells_the_size_and_refuses(link: Link) -> None:
    link.upload(mission(4))
    for seq in (4, 10):
        assert kinds(link.send(link.gcs.mission_request_int_encode(1, 1, seq, 0))) == [
            ("MISSION_COUNT", 4, 0),
            ("MISSION_ACK", INVALID_SEQUENCE, 0),
        ]
    # the legacy request gets only the refusal
    assert kinds(link.send(link.gcs.mission_request_encode(1, 1, 7, 0))) == [
        ("MISSION_ACK", INVALID_SEQUENCE, 0)
    ]


def test_legacy_request_gets_float_degrees_and_one_warning_until_the_next_upload(
    link: Link,
) -> None:
    sent = MissionItem(1, 3, 16, 0, 1, 0, 0, 0, 0, 306372128, -964787456, 10.12)
    link.upload([mission(1)[0], sent])
    first = link.send(link.gcs.mission_request_encode(1, 1, 1, 0))
    assert kinds(first) == [
        ("MISSION_ITEM", 1),
        ("STATUSTEXT", WARNING, "got MISSION_REQUEST; use MISSION_REQUEST_INT!"),
    ]
    item = first[0]
    assert (item.x, item.y, item.z) == (30.6372127532959, -96.47874450683594, f32(10.12))
    assert kinds(link.send(link.gcs.mission_request_encode(1, 1, 1, 0))) == [("MISSION_ITEM", 1)]
    link.upload([mission(1)[0], sent])
    assert len(link.send(link.gcs.mission_request_encode(1, 1, 1, 0))) == 2


def test_mission_count_before_home_then_with_home() -> None:
    link = Link(home_set=False)
    assert kinds(link.send(link.gcs.mission_request_list_encode(1, 1, 0))) == [
        ("MISSION_COUNT", 0, 0)
    ]
    (home,) = link.send(link.gcs.mission_request_int_encode(1, 1, 0, 0))
    assert (home.seq, home.x, home.y, home.z) == (0, 0, 0, 0.0)
    link.home = HOME
    link.protocol.write_home()
    assert [m.seq for m in link.download()] == [0]


def test_download_flags_every_item_whose_command_number_is_the_current_index(
    link: Link,
) -> None:
    items = mission(22)
    items[20] = MissionItem(20, 0, 20, 0, 1, 0, 0, 0, 0, 0, 0, 0.0)  # RTL
    link.upload(items)
    assert link.protocol.set_current(16)
    # ArduPilot compares the command id (16, NAV_WAYPOINT) with the index: 20 items flagged
    assert [m.seq for m in link.download() if m.current] == [*range(20), 21]
    assert link.protocol.set_current(20)
    assert [m.seq for m in link.download() if m.current] == [20]
    assert link.protocol.set_current(3)
    assert [m.seq for m in link.download() if m.current] == []


# -- clear, count 0, partial update --------------------------------------------------------------


def test_clear_all_leaves_no_items_until_home_is_written_again(link: Link) -> None:
    link.upload(mission(3))
    assert kinds(link.send(link.gcs.mission_clear_all_encode(1, 1, 0))) == [
        ("MISSION_ACK", ACCEPTED, 0)
    ]
    assert kinds(link.send(link.gcs.mission_request_list_encode(1, 1, 0))) == [
        ("MISSION_COUNT", 0, 0)
    ]
    (home,) = link.send(link.gcs.mission_request_int_encode(1, 1, 0, 0))  # always readable
    assert (home.seq, home.x) == (0, 306372000)
    assert link.protocol.mission_current(False) == (0, 0, 1, 0)
    link.protocol.write_home()  # e.g. DO_SET_HOME
    assert link.protocol.count == 1


def test_count_0_is_an_upload_completed_at_once(link: Link) -> None:
    link.upload(mission(3))
    assert kinds(link.count(0)) == [
        ("MISSION_ACK", ACCEPTED, 0),
        ("STATUSTEXT", INFO, "Flight plan received"),
    ]
    assert link.protocol.count == 0


def test_partial_update_replaces_the_range_it_asks_for(link: Link) -> None:
    link.upload(mission(5))
    partial = link.gcs.mission_write_partial_list_encode(1, 1, 2, 3, 0)
    assert kinds(link.send(partial)) == [("MISSION_REQUEST", 2, 0)]
    assert kinds(link.item(wp(2, alt_m=52.0))) == [("MISSION_REQUEST", 3, 0)]
    assert kinds(link.item(wp(3, alt_m=53.0))) == [
        ("MISSION_ACK", ACCEPTED, 0),
        ("STATUSTEXT", INFO, "Flight plan received"),
    ]
    assert [m.z for m in link.download()[1:]] == [11.0, 52.0, 53.0, 14.0]
    for start, end in ((3, 2), (2, 6), (-1, 2)):
        rejected = link.gcs.mission_write_partial_list_encode(1, 1, start, end, 0)
        assert kinds(link.send(rejected)) == [
            ("MISSION_ACK", ERROR, 0),
            ("STATUSTEXT", WARNING, "Flight plan update rejected"),
        ]
    append = link.gcs.mission_write_partial_list_encode(1, 1, 5, 5, 0)
    assert kinds(link.send(append)) == [("MISSION_REQUEST", 5, 0)]


# -- other mission types -------------------------------------------------------------------------


def fence_polygon(kind: int = 5001, vertices: int = 4) -> list[MissionItem]:
    corners = [(100, 100), (100, -100), (-100, -100), (-100, 100)][:vertices]
    return [
        MissionItem(
            i,
            0,
            kind,
            0,
            1,
            float(vertices),
            0,
            0,
            0,
            round((HOME[0] + n / 111319.5) * 1e7),
            round((HOME[1] + e / 95800.0) * 1e7),
            55.5,
            1,
        )
        for i, (n, e) in enumerate(corners)
    ]


def test_fence_upload_download_and_clear(link: Link) -> None:
    poly = fence_polygon()
    ret = MissionItem(4, 3, 5000, 0, 1, 0, 0, 0, 0, 306372000, -964787000, 20.0, 1)
    circle = MissionItem(5, 0, 5003, 0, 1, 50.7, 1, 2, 3, 306372000, -964787000, 0.0, 1)
    replies = link.upload([*poly, ret, circle], mission_type=1)
    assert kinds(replies)[-2:] == [
        ("MISSION_ACK", ACCEPTED, 1),
        ("STATUSTEXT", DEBUG, "Fence Indexed OK"),
    ]
    assert kinds(replies)[0] == ("MISSION_REQUEST", 0, 1)
    back = link.download(1)
    assert [(m.command, m.param1, m.frame, m.z, m.autocontinue) for m in back] == [
        (5001, 4.0, 0, 0.0, 0),
        (5001, 4.0, 0, 0.0, 0),
        (5001, 4.0, 0, 0.0, 0),
        (5001, 4.0, 0, 0.0, 0),
        (5000, 0.0, 0, 0.0, 0),
        (5003, f32(50.7), 0, 0.0, 0),
    ]
    assert all(m.mission_type == 1 for m in back)
    assert link.protocol.count == 1  # the mission is untouched
    assert kinds(link.send(link.gcs.mission_request_int_encode(1, 1, 6, 1))) == [
        ("MISSION_COUNT", 6, 1),
        ("MISSION_ACK", INVALID_SEQUENCE, 1),
    ]
    assert kinds(link.send(link.gcs.mission_clear_all_encode(1, 1, 1))) == [
        ("MISSION_ACK", ACCEPTED, 1),
        ("STATUSTEXT", DEBUG, "Fence Indexed OK"),
    ]
    assert link.protocol.fence_items == ()


def test_fence_is_validated_when_complete_and_the_old_fence_stays(link: Link) -> None:
    good = fence_polygon()
    link.upload(good, mission_type=1)
    circle = MissionItem(0, 0, 5003, 0, 1, 0.0, 0, 0, 0, 306372000, -964787000, 0.0, 1)
    ret = MissionItem(0, 0, 5000, 0, 1, 0, 0, 0, 0, 306372000, -964787000, 0.0, 1)
    cases: list[tuple[list[MissionItem], list[tuple[int, str]]]] = [
        (
            [replace(i, param1=3.0) for i in good],
            [(INFO, "Incorrect item count")],
        ),
        (
            [replace(i, param1=2.0) for i in good[:2]],
            [(WARNING, "Invalid vertex count (2)")],
        ),
        (good[:3], [(INFO, "Incorrect item count")]),
        ([circle], [(WARNING, "Non-positive circle radius")]),
        (
            [ret, replace(ret, seq=1)],
            [(WARNING, "Multiple return points")],
        ),
        (
            good[:2]
            + [replace(circle, seq=2, param1=5.0)]
            + [replace(i, seq=i.seq + 1) for i in good[2:]],
            [(WARNING, "Received incorrect type (want=98 got=92)")],
        ),
        (
            [replace(good[0], x=910_000_000), *good[1:]],
            [(WARNING, "Bad lat or lon")],
        ),
    ]
    for items, texts in cases:
        replies = link.upload(items, mission_type=1)
        assert kinds(replies)[-2 - len(texts) :] == [
            ("MISSION_ACK", ERROR, 1),
            *[("STATUSTEXT", severity, text) for severity, text in texts],
            ("STATUSTEXT", WARNING, "Fence validation failed"),
        ]
        assert len(link.protocol.fence_items) == 4
    # item-level refusals end the upload at once
    assert kinds(link.upload([replace(good[0], frame=1)], 1))[-1] == (
        "MISSION_ACK",
        mavlink2.MAV_MISSION_UNSUPPORTED_FRAME,
        1,
    )
    assert kinds(link.upload([replace(good[0], command=16)], 1))[-1] == (
        "MISSION_ACK",
        UNSUPPORTED,
        1,
    )
    too_many = [replace(i, param1=300.0) for i in good]
    assert kinds(link.upload(too_many, 1))[-1] == ("MISSION_ACK", 6, 1)
    assert kinds(link.count(71, 1)) == [
        ("MISSION_ACK", NO_SPACE, 1),
        ("STATUSTEXT", WARNING, "Only 70 items are supported"),
    ]


def test_fence_partial_update_replaces_one_vertex(link: Link) -> None:
    good = fence_polygon()
    link.upload(good, mission_type=1)
    partial = link.gcs.mission_write_partial_list_encode(1, 1, 2, 2, 1)
    assert kinds(link.send(partial)) == [("MISSION_REQUEST", 2, 1)]
    assert kinds(link.item(replace(good[2], x=good[2].x + 100))) == [
        ("MISSION_ACK", ACCEPTED, 1),
        ("STATUSTEXT", DEBUG, "Fence Indexed OK"),
    ]
    assert [m.x - g.x for m, g in zip(link.download(1), good, strict=True)] == [0, 0, 100, 0]


def test_rally_points_keep_whole_metres_and_their_altitude_frame(link: Link) -> None:
    def rally(seq: int, frame: int, z: float, command: int = 5100) -> MissionItem:
        return MissionItem(seq, frame, command, 0, 1, 1, 2, 3, 4, 306380983, -964776559, z, 2)

    replies = link.upload([rally(0, 3, 123.7), rally(1, 6, -20.2)], mission_type=2)
    assert kinds(replies)[-1] == ("MISSION_ACK", ACCEPTED, 2)  # and no text
    back = link.download(2)
    assert [(m.frame, m.z, m.param1, m.autocontinue) for m in back] == [
        (3, 123.0, 0.0, 0),
        (3, -20.0, 0.0, 0),
    ]
    for frame, folded in ((0, 0), (5, 0), (10, 10), (11, 10)):
        link.upload([rally(0, frame, 1.0)], mission_type=2)
        assert link.download(2)[0].frame == folded
    refused = {
        (2, 1.0, 5100): mavlink2.MAV_MISSION_UNSUPPORTED_FRAME,
        (3, 1.0, 16): UNSUPPORTED,
        (3, 40000.0, 5100): mavlink2.MAV_MISSION_INVALID_PARAM7,
        (3, -32768.5, 5100): mavlink2.MAV_MISSION_INVALID_PARAM7,
    }
    for (frame, z, command), result in refused.items():
        assert kinds(link.upload([rally(0, frame, z, command)], 2))[-1] == (
            "MISSION_ACK",
            result,
            2,
        )
    assert kinds(link.count(47, 2))[0] == ("MISSION_ACK", NO_SPACE, 2)
    assert kinds(link.send(link.gcs.mission_clear_all_encode(1, 1, 2))) == [
        ("MISSION_ACK", ACCEPTED, 2)
    ]
    assert link.protocol.rally_items == ()


@pytest.mark.parametrize(("mission_type", "text"), [(1, "Fence"), (2, "Rally")])
def test_fence_and_rally_uploads_time_out_like_missions(
    link: Link, mission_type: int, text: str
) -> None:
    link.count(2, mission_type)
    events = [kinds([m])[0] for _, m in timeline(link, 0.0, 9.0)]
    assert events[-2:] == [
        ("MISSION_ACK", CANCELLED, mission_type),
        ("STATUSTEXT", WARNING, f"{text} upload timeout"),
    ]


@pytest.mark.parametrize("mission_type", [3, 4, 7, 254, 255])
def test_other_mission_types_are_unsupported(link: Link, mission_type: int) -> None:
    unsupported = [("MISSION_ACK", UNSUPPORTED, mission_type)]
    g = link.gcs
    assert kinds(link.send(g.mission_request_list_encode(1, 1, mission_type))) == unsupported
    assert kinds(link.send(g.mission_clear_all_encode(1, 1, mission_type))) == unsupported
    assert kinds(link.count(2, mission_type)) == unsupported
    item = MissionItem(0, 3, 16, 0, 1, 0, 0, 0, 0, 0, 0, 0.0, mission_type)
    assert kinds(link.item(item)) == unsupported
    # requests for an item get no answer at all
    assert link.send(g.mission_request_int_encode(1, 1, 0, mission_type)) == []
    assert link.send(g.mission_request_encode(1, 1, 0, mission_type)) == []
    partial = g.mission_write_partial_list_encode(1, 1, 1, 1, mission_type)
    assert kinds(link.send(partial)) == unsupported
    assert all(link.handled)


# -- current item and MISSION_CURRENT -------------------------------------------------------------


def test_mission_current_through_a_flight(link: Link) -> None:
    p = link.protocol
    assert p.mission_current(False) == (0, 0, 1, 0)
    link.upload(mission(3))
    assert p.mission_current(False) == (0, 2, 2, 0)
    started = p.start()
    assert [i.seq for i in started] == [1]
    assert p.mission_current(True) == (1, 2, 3, 1)
    assert p.advance() == p.items[2]
    assert p.mission_current(True) == (2, 2, 3, 1)
    assert p.advance() is None
    assert p.state == MissionState.COMPLETE
    assert p.mission_current(True) == (2, 2, 5, 1)
    p.stop()  # leaving AUTO does not undo "complete"
    assert p.mission_current(False) == (2, 2, 5, 0)
    p.reset()  # ArduCopter at disarming
    assert p.mission_current(False) == (0, 2, 5, 0)
    link.upload(mission(4))  # nor does a new upload
    assert p.mission_current(False) == (0, 3, 5, 0)
    link.send(link.gcs.mission_clear_all_encode(1, 1, 0))
    assert p.mission_current(True) == (0, 0, 1, 1)


def test_leaving_auto_stops_and_entering_resumes_at_the_same_item(link: Link) -> None:
    p = link.protocol
    link.upload(mission(4))
    p.start()
    p.advance()
    p.stop()
    assert p.mission_current(False) == (2, 3, 2, 0)
    link.take()
    assert [i.seq for i in p.resume()] == [2]
    assert kinds(link.take()) == [("STATUSTEXT", INFO, "Mission: 2 WP")]


def test_mission_set_current_answers_mission_current_at_once(link: Link) -> None:
    link.upload(mission(5))
    set_current = link.gcs.mission_set_current_encode
    assert kinds(link.send(set_current(1, 1, 2))) == [("MISSION_CURRENT", 2, 4, 2, 0)]
    assert link.send(set_current(1, 1, 9)) == []  # out of range: silence
    assert link.send(set_current(1, 1, 5)) == []
    # 0 restarts at 1, but the reply carries the 0 that was asked for (measured)
    assert kinds(link.send(set_current(1, 1, 0))) == [("MISSION_CURRENT", 0, 4, 2, 0)]
    assert link.protocol.current == 1
    link.auto = True
    assert kinds(link.send(set_current(1, 1, 3))) == [("MISSION_CURRENT", 3, 4, 2, 1)]


def test_set_current_refusals_and_do_items(link: Link) -> None:
    p = link.protocol
    assert not p.set_current(0)  # empty (home only)
    assert not p.set_current(-1)
    items = mission(4)
    items[1] = MissionItem(1, 0, 178, 0, 1, 1, 3, -1, 0, 0, 0, 0.0)  # DO_CHANGE_SPEED
    link.upload(items)
    assert p.set_current(1) and p.current == 2  # lands on the next navigation command
    assert not p.set_current(4)
    assert p.current == 2


def test_commands_start_with_arduPilots_texts(link: Link) -> None:
    p = link.protocol
    items = [
        mission(1)[0],
        MissionItem(1, 3, 22, 0, 1, 0, 0, 0, 0, 0, 0, 10.0),  # takeoff
        MissionItem(2, 0, 178, 0, 1, 1, 4, -1, 0, 0, 0, 0.0),  # change speed
        MissionItem(3, 0, 183, 0, 1, 9, 1500, 0, 0, 0, 0, 0.0),  # set servo
        wp(4, 60.0),
        MissionItem(5, 0, 177, 0, 1, 4, 1, 0, 0, 0, 0, 0.0),  # jump to 4 once
        MissionItem(6, 3, 21, 0, 1, 0, 0, 0, 0, 0, 0, 0.0),  # land
    ]
    link.upload(items)
    link.take()
    assert [i.seq for i in p.start()] == [1]
    assert p.advance() == p.items[4]
    assert [i.seq for i in p.started] == [2, 4, 3]  # ArduPilot's order: first DO, nav, rest
    assert p.advance() == p.items[4]  # the jump back
    assert p.advance() == p.items[6]
    assert p.advance() is None
    assert [k[2] for k in kinds(link.take())] == [
        "Mission: 1 Takeoff",
        "Mission: 2 ChangeSpeed",
        "Mission: 4 WP",
        "Mission: 3 SetServo",
        "Mission: 5 Jump 1/1",
        "Mission: 4 WP",
        "Mission: 6 Land",
    ]
    assert command_name(31000) == "?"


def test_changed_counts_what_the_autopilot_must_look_at_again(link: Link) -> None:
    p = link.protocol
    before = p.changed
    link.send(link.gcs.mission_request_list_encode(1, 1, 0))
    assert p.changed == before  # reading changes nothing
    link.upload(mission(3))
    assert p.changed > before
    before = p.changed
    link.send(link.gcs.mission_set_current_encode(1, 1, 2))
    assert p.changed > before


def test_unknown_firmware_is_refused() -> None:
    with pytest.raises(ValueError, match="unknown firmware"):
        MissionProtocol(None, lambda: None, lambda s, t: None, firmware="px4")


# -- what ArduPilot stores, command by command ---------------------------------------------------

VECTORS: dict[str, tuple[int, tuple[float, float, float, float], int, int, float]] = {
    # name: (frame, params, x, y, z): each uploaded as item 1 to SITL, then downloaded
    "A": (3, (1.7, 2.6, -3.4, 4.5), 306380000, -964780000, 12.345),
    "B": (0, (300.3, -7.6, 0.5, -1.0), -338688197, 1512092955, -7.891),
    "C": (6, (70000.0, 65535.9, -300.7, 2.0), 306380001, -964780001, 0.005),
    "D": (10, (0.0, 0.0, 0.0, 0.0), 306380002, -964780002, 5.0),
    "E": (5, (-1.0, 1.0, 255.0, 256.0), 306380003, -964780003, 82999.99),
}


def sent_item(command: int, vector: str) -> MissionItem:
    frame, (p1, p2, p3, p4), x, y, z = VECTORS[vector]
    return MissionItem(1, frame, command, 0, 1, f32(p1), f32(p2), f32(p3), f32(p4), x, y, f32(z))


def storage_cases(firmware: str) -> list[tuple[int, str, Any]]:
    table = dict(STORED_ARDUCOPTER)
    if firmware == "arduplane":
        table = {key: value for key, value in table.items() if key[0] != 82}
        table.update(STORED_ARDUPLANE)
    return [(command, vector, expected) for (command, vector), expected in table.items()]


@pytest.mark.parametrize("firmware", sorted(ITEM_LIMITS))
def test_every_command_comes_back_as_sitl_gave_it_back(firmware: str) -> None:
    """Over the protocol (DO_JUMP's refusals are the protocol's), for every measured case."""
    link = Link(firmware)
    for command, vector, expected in storage_cases(firmware):
        replies = link.upload([mission(1)[0], sent_item(command, vector)])
        if isinstance(expected, int):
            assert kinds(replies)[-1] == ("MISSION_ACK", expected, 0), (command, vector)
            continue
        back = link.download()[1]
        got = (
            back.frame,
            back.param1,
            back.param2,
            back.param3,
            back.param4,
            back.x,
            back.y,
            back.z,
        )
        assert got == expected, (command, vector)
        assert (back.command, back.autocontinue, back.current) == (command, 1, 0)


@pytest.mark.parametrize("firmware", sorted(ITEM_LIMITS))
def test_every_other_command_is_unsupported(firmware: str) -> None:
    supported = {command for command, _ in STORED_ARDUCOPTER}
    if firmware == "arduplane":
        supported.discard(82)
    for command in mavlink2.enums["MAV_CMD"]:
        if command in supported or command in (0, 1) or command >= 65535:
            continue
        with pytest.raises(MissionItemError) as refused:
            stored_mission_item(sent_item(command, "A"), firmware)
        assert refused.value.result == UNSUPPORTED, command


def test_loiter_turns_radius_over_255_m_loses_a_digit() -> None:
    item = MissionItem(1, 3, 18, 0, 1, 2.0, 0.0, -1234.0, 0.0, 306380000, -964780000, 10.0)
    assert stored_mission_item(item).param3 == -1230.0


# (command, vector): (frame, param1-4, x, y, z) as SITL's download returned it, or the
# MAV_MISSION_RESULT of the upload. ArduCopter and ArduRover gave identical answers.
STORED_ARDUCOPTER: dict[tuple[int, str], Any] = {
    (16, "A"): (3, 1.0, 0.0, 0.0, 0.0, 306380000, -964780000, 12.34000015258789),
    (16, "B"): (0, 300.0, 0.0, 0.0, 0.0, -338688197, 1512092955, -7.889999866485596),
    (16, "C"): (3, 4464.0, 0.0, 0.0, 0.0, 306380001, -964780001, 0.0),
    (16, "D"): (10, 0.0, 0.0, 0.0, 0.0, 306380002, -964780002, 5.0),
    (16, "E"): (0, 65535.0, 0.0, 0.0, 0.0, 306380003, -964780003, 82999.984375),
    (17, "A"): (3, 0.0, 0.0, -3.0, 0.0, 306380000, -964780000, 12.34000015258789),
    (17, "B"): (0, 0.0, 0.0, 0.0, 0.0, -338688197, 1512092955, -7.889999866485596),
    (17, "C"): (3, 0.0, 0.0, -300.0, 0.0, 306380001, -964780001, 0.0),
    (17, "D"): (10, 0.0, 0.0, 0.0, 0.0, 306380002, -964780002, 5.0),
    (17, "E"): (0, 0.0, 0.0, 255.0, 0.0, 306380003, -964780003, 82999.984375),
    (18, "A"): (3, 1.0, 0.0, -3.0, 1.0, 306380000, -964780000, 12.34000015258789),
    (18, "B"): (0, 255.0, 0.0, 0.0, 0.0, -338688197, 1512092955, -7.889999866485596),
    (18, "C"): (3, 255.0, 0.0, -300.0, 1.0, 306380001, -964780001, 0.0),
    (18, "D"): (10, 0.0, 0.0, 0.0, 0.0, 306380002, -964780002, 5.0),
    (18, "E"): (0, 255.0, 0.0, 255.0, 1.0, 306380003, -964780003, 82999.984375),
    (19, "A"): (3, 1.0, 0.0, -1.0, 1.0, 306380000, -964780000, 12.34000015258789),
    (19, "B"): (0, 300.0, 0.0, 1.0, 0.0, -338688197, 1512092955, -7.889999866485596),
    (19, "C"): (3, 4464.0, 0.0, -1.0, 1.0, 306380001, -964780001, 0.0),
    (19, "D"): (10, 0.0, 0.0, 1.0, 0.0, 306380002, -964780002, 5.0),
    (19, "E"): (0, 65535.0, 0.0, 1.0, 1.0, 306380003, -964780003, 82999.984375),
    (20, "A"): (0, 0.0, 0.0, 0.0, 0.0, 0, 0, 0.0),
    (20, "B"): (0, 0.0, 0.0, 0.0, 0.0, 0, 0, 0.0),
    (20, "C"): (0, 0.0, 0.0, 0.0, 0.0, 0, 0, 0.0),
    (20, "D"): (0, 0.0, 0.0, 0.0, 0.0, 0, 0, 0.0),
    (20, "E"): (0, 0.0, 0.0, 0.0, 0.0, 0, 0, 0.0),
    (21, "A"): (3, 1.0, 0.0, 0.0, 1.0, 306380000, -964780000, 12.34000015258789),
    (21, "B"): (0, 300.0, 0.0, 0.0, -1.0, -338688197, 1512092955, -7.889999866485596),
    (21, "C"): (3, 4464.0, 0.0, 0.0, 1.0, 306380001, -964780001, 0.0),
    (21, "D"): (10, 0.0, 0.0, 0.0, 1.0, 306380002, -964780002, 5.0),
    (21, "E"): (0, 65535.0, 0.0, 0.0, 1.0, 306380003, -964780003, 82999.984375),
    (22, "A"): (3, 1.0, 0.0, 0.0, 0.0, 306380000, -964780000, 12.34000015258789),
    (22, "B"): (0, 300.0, 0.0, 0.0, 0.0, -338688197, 1512092955, -7.889999866485596),
    (22, "C"): (3, 4464.0, 0.0, 0.0, 0.0, 306380001, -964780001, 0.0),
    (22, "D"): (10, 0.0, 0.0, 0.0, 0.0, 306380002, -964780002, 5.0),
    (22, "E"): (0, 65535.0, 0.0, 0.0, 0.0, 306380003, -964780003, 82999.984375),
    (30, "A"): (3, 1.0, 0.0, 0.0, 0.0, 306380000, -964780000, 12.34000015258789),
    (30, "B"): (0, 300.0, 0.0, 0.0, 0.0, -338688197, 1512092955, -7.889999866485596),
    (30, "C"): (3, 4464.0, 0.0, 0.0, 0.0, 306380001, -964780001, 0.0),
    (30, "D"): (10, 0.0, 0.0, 0.0, 0.0, 306380002, -964780002, 5.0),
    (30, "E"): (0, 65535.0, 0.0, 0.0, 0.0, 306380003, -964780003, 82999.984375),
    (31, "A"): (3, 0.0, 2.0, 0.0, 1.0, 306380000, -964780000, 12.34000015258789),
    (31, "B"): (0, 0.0, -7.0, 0.0, 0.0, -338688197, 1512092955, -7.889999866485596),
    (31, "C"): (3, 0.0, 65535.0, 0.0, 1.0, 306380001, -964780001, 0.0),
    (31, "D"): (10, 0.0, 0.0, 0.0, 0.0, 306380002, -964780002, 5.0),
    (31, "E"): (0, 0.0, 1.0, 0.0, 1.0, 306380003, -964780003, 82999.984375),
    (82, "A"): (3, 1.0, 0.0, 0.0, 0.0, 306380000, -964780000, 12.34000015258789),
    (82, "B"): (0, 300.0, 0.0, 0.0, 0.0, -338688197, 1512092955, -7.889999866485596),
    (82, "C"): (3, 4464.0, 0.0, 0.0, 0.0, 306380001, -964780001, 0.0),
    (82, "D"): (10, 0.0, 0.0, 0.0, 0.0, 306380002, -964780002, 5.0),
    (82, "E"): (0, 65535.0, 0.0, 0.0, 0.0, 306380003, -964780003, 82999.984375),
    (83, "A"): (0, 1.7000000476837158, 2.5999999046325684, 253.0, 0.0, 0, 0, 0.0),
    (83, "B"): (0, 300.29998779296875, -7.599999904632568, 0.0, 0.0, 0, 0, 0.0),
    (83, "C"): (0, 70000.0, 65535.8984375, 212.0, 0.0, 0, 0, 0.0),
    (83, "D"): (0, 0.0, 0.0, 0.0, 0.0, 0, 0, 0.0),
    (83, "E"): (0, -1.0, 1.0, 255.0, 0.0, 0, 0, 0.0),
    (84, "A"): (3, 0.0, 0.0, 0.0, 0.0, 306380000, -964780000, 12.34000015258789),
    (84, "B"): (0, 0.0, 0.0, 0.0, 0.0, -338688197, 1512092955, -7.889999866485596),
    (84, "C"): (3, 0.0, 0.0, 0.0, 0.0, 306380001, -964780001, 0.0),
    (84, "D"): (10, 0.0, 0.0, 0.0, 0.0, 306380002, -964780002, 5.0),
    (84, "E"): (0, 0.0, 0.0, 0.0, 0.0, 306380003, -964780003, 82999.984375),
    (85, "A"): (3, 1.0, 0.0, 0.0, 0.0, 306380000, -964780000, 12.34000015258789),
    (85, "B"): (0, 300.0, 0.0, 0.0, 0.0, -338688197, 1512092955, -7.889999866485596),
    (85, "C"): (3, 4464.0, 0.0, 0.0, 0.0, 306380001, -964780001, 0.0),
    (85, "D"): (10, 0.0, 0.0, 0.0, 0.0, 306380002, -964780002, 5.0),
    (85, "E"): (0, 65535.0, 0.0, 0.0, 0.0, 306380003, -964780003, 82999.984375),
    (92, "A"): (3, 1.0, 0.0, 0.0, 0.0, 306380000, -964780000, 12.34000015258789),
    (92, "B"): (0, 300.0, 0.0, 0.0, 0.0, -338688197, 1512092955, -7.889999866485596),
    (92, "C"): (3, 4464.0, 0.0, 0.0, 0.0, 306380001, -964780001, 0.0),
    (92, "D"): (10, 0.0, 0.0, 0.0, 0.0, 306380002, -964780002, 5.0),
    (92, "E"): (0, 65535.0, 0.0, 0.0, 0.0, 306380003, -964780003, 82999.984375),
    (93, "A"): (0, 1.7000000476837158, 2.0, -3.0, 4.0, 0, 0, 0.0),
    (93, "B"): (0, 300.29998779296875, -7.0, 0.0, -1.0, 0, 0, 0.0),
    (93, "C"): (0, 70000.0, -1.0, -44.0, 2.0, 0, 0, 0.0),
    (93, "D"): (0, 0.0, 0.0, 0.0, 0.0, 0, 0, 0.0),
    (93, "E"): (0, -1.0, 1.0, -1.0, 0.0, 0, 0, 0.0),
    (94, "A"): (3, 1.6999999284744263, 0.0, 0.0, 0.0, 306380000, -964780000, 12.34000015258789),
    (94, "B"): (0, 300.2900085449219, 0.0, 0.0, 0.0, -338688197, 1512092955, -7.889999866485596),
    (94, "C"): (3, 531.8399658203125, 0.0, 0.0, 0.0, 306380001, -964780001, 0.0),
    (94, "D"): (10, 0.0, 0.0, 0.0, 0.0, 306380002, -964780002, 5.0),
    (94, "E"): (0, 654.3599853515625, 0.0, 0.0, 0.0, 306380003, -964780003, 82999.984375),
    (112, "A"): (0, 1.7000000476837158, 0.0, 0.0, 0.0, 0, 0, 0.0),
    (112, "B"): (0, 300.29998779296875, 0.0, 0.0, 0.0, 0, 0, 0.0),
    (112, "C"): (0, 70000.0, 0.0, 0.0, 0.0, 0, 0, 0.0),
    (112, "D"): (0, 0.0, 0.0, 0.0, 0.0, 0, 0, 0.0),
    (112, "E"): (0, -1.0, 0.0, 0.0, 0.0, 0, 0, 0.0),
    (114, "A"): (0, 1.7000000476837158, 0.0, 0.0, 0.0, 0, 0, 0.0),
    (114, "B"): (0, 300.29998779296875, 0.0, 0.0, 0.0, 0, 0, 0.0),
    (114, "C"): (0, 70000.0, 0.0, 0.0, 0.0, 0, 0, 0.0),
    (114, "D"): (0, 0.0, 0.0, 0.0, 0.0, 0, 0, 0.0),
    (114, "E"): (0, -1.0, 0.0, 0.0, 0.0, 0, 0, 0.0),
    (115, "A"): (0, 1.7000000476837158, 2.5999999046325684, -3.0, 4.0, 0, 0, 0.0),
    (115, "B"): (0, 300.29998779296875, -7.599999904632568, 0.0, 255.0, 0, 0, 0.0),
    (115, "C"): (0, 70000.0, 65535.8984375, -44.0, 2.0, 0, 0, 0.0),
    (115, "D"): (0, 0.0, 0.0, 0.0, 0.0, 0, 0, 0.0),
    (115, "E"): (0, -1.0, 1.0, -1.0, 0.0, 0, 0, 0.0),
    (177, "A"): (0, 1.0, 2.0, 0.0, 0.0, 0, 0, 0.0),
    (177, "B"): 1,
    (177, "C"): 1,
    (177, "D"): 1,
    (177, "E"): 1,
    (178, "A"): (0, 1.0, 2.5999999046325684, -3.4000000953674316, 0.0, 0, 0, 0.0),
    (178, "B"): (0, 44.0, -7.599999904632568, 0.5, 0.0, 0, 0, 0.0),
    (178, "C"): (0, 112.0, 65535.8984375, -300.70001220703125, 0.0, 0, 0, 0.0),
    (178, "D"): (0, 0.0, 0.0, 0.0, 0.0, 0, 0, 0.0),
    (178, "E"): (0, 255.0, 1.0, 255.0, 0.0, 0, 0, 0.0),
    (179, "A"): (3, 1.0, 0.0, 0.0, 0.0, 306380000, -964780000, 12.34000015258789),
    (179, "B"): (0, 300.0, 0.0, 0.0, 0.0, -338688197, 1512092955, -7.889999866485596),
    (179, "C"): (3, 4464.0, 0.0, 0.0, 0.0, 306380001, -964780001, 0.0),
    (179, "D"): (10, 0.0, 0.0, 0.0, 0.0, 306380002, -964780002, 5.0),
    (179, "E"): (0, 65535.0, 0.0, 0.0, 0.0, 306380003, -964780003, 82999.984375),
    (181, "A"): (0, 1.0, 2.0, 0.0, 0.0, 0, 0, 0.0),
    (181, "B"): (0, 44.0, 249.0, 0.0, 0.0, 0, 0, 0.0),
    (181, "C"): (0, 112.0, 255.0, 0.0, 0.0, 0, 0, 0.0),
    (181, "D"): (0, 0.0, 0.0, 0.0, 0.0, 0, 0, 0.0),
    (181, "E"): (0, 255.0, 1.0, 0.0, 0.0, 0, 0, 0.0),
    (182, "A"): (0, 1.0, 2.0, -3.4000000953674316, 0.0, 0, 0, 0.0),
    (182, "B"): (0, 44.0, -7.0, 0.5, 0.0, 0, 0, 0.0),
    (182, "C"): (0, 112.0, -1.0, -300.70001220703125, 0.0, 0, 0, 0.0),
    (182, "D"): (0, 0.0, 0.0, 0.0, 0.0, 0, 0, 0.0),
    (182, "E"): (0, 255.0, 1.0, 255.0, 0.0, 0, 0, 0.0),
    (183, "A"): (0, 1.0, 2.0, 0.0, 0.0, 0, 0, 0.0),
    (183, "B"): (0, 44.0, 65529.0, 0.0, 0.0, 0, 0, 0.0),
    (183, "C"): (0, 112.0, 65535.0, 0.0, 0.0, 0, 0, 0.0),
    (183, "D"): (0, 0.0, 0.0, 0.0, 0.0, 0, 0, 0.0),
    (183, "E"): (0, 255.0, 1.0, 0.0, 0.0, 0, 0, 0.0),
    (184, "A"): (0, 1.0, 2.0, -3.0, 4.5, 0, 0, 0.0),
    (184, "B"): (0, 44.0, 65529.0, 0.0, -1.0, 0, 0, 0.0),
    (184, "C"): (0, 112.0, 65535.0, -300.0, 2.0, 0, 0, 0.0),
    (184, "D"): (0, 0.0, 0.0, 0.0, 0.0, 0, 0, 0.0),
    (184, "E"): (0, 255.0, 1.0, 255.0, 256.0, 0, 0, 0.0),
    (188, "A"): (3, 0.0, 0.0, 0.0, 0.0, 306380000, -964780000, 12.34000015258789),
    (188, "B"): (0, 0.0, 0.0, 0.0, 0.0, -338688197, 1512092955, -7.889999866485596),
    (188, "C"): (3, 0.0, 0.0, 0.0, 0.0, 306380001, -964780001, 0.0),
    (188, "D"): (10, 0.0, 0.0, 0.0, 0.0, 306380002, -964780002, 5.0),
    (188, "E"): (0, 0.0, 0.0, 0.0, 0.0, 306380003, -964780003, 82999.984375),
    (189, "A"): (3, 0.0, 0.0, 0.0, 0.0, 306380000, -964780000, 12.34000015258789),
    (189, "B"): (0, 0.0, 0.0, 0.0, 0.0, -338688197, 1512092955, -7.889999866485596),
    (189, "C"): (3, 0.0, 0.0, 0.0, 0.0, 306380001, -964780001, 0.0),
    (189, "D"): (10, 0.0, 0.0, 0.0, 0.0, 306380002, -964780002, 5.0),
    (189, "E"): (0, 0.0, 0.0, 0.0, 0.0, 306380003, -964780003, 82999.984375),
    (191, "A"): (3, 0.0, 0.0, 0.0, 0.0, 306380000, -964780000, 12.34000015258789),
    (191, "B"): (0, 0.0, 0.0, 0.0, 0.0, -338688197, 1512092955, -7.889999866485596),
    (191, "C"): (3, 0.0, 0.0, 0.0, 0.0, 306380001, -964780001, 0.0),
    (191, "D"): (10, 0.0, 0.0, 0.0, 0.0, 306380002, -964780002, 5.0),
    (191, "E"): (0, 0.0, 0.0, 0.0, 0.0, 306380003, -964780003, 82999.984375),
    (193, "A"): (0, 1.0, 0.0, 0.0, 0.0, 0, 0, 0.0),
    (193, "B"): (0, 300.0, 0.0, 0.0, 0.0, 0, 0, 0.0),
    (193, "C"): (0, 4464.0, 0.0, 0.0, 0.0, 0, 0, 0.0),
    (193, "D"): (0, 0.0, 0.0, 0.0, 0.0, 0, 0, 0.0),
    (193, "E"): (0, 65535.0, 0.0, 0.0, 0.0, 0, 0, 0.0),
    (194, "A"): (0, 1.0, 0.0, 0.0, 0.0, 0, 0, 0.0),
    (194, "B"): (0, 300.0, 0.0, 0.0, 0.0, 0, 0, 0.0),
    (194, "C"): (0, 4464.0, 0.0, 0.0, 0.0, 0, 0, 0.0),
    (194, "D"): (0, 0.0, 0.0, 0.0, 0.0, 0, 0, 0.0),
    (194, "E"): (0, 65535.0, 0.0, 0.0, 0.0, 0, 0, 0.0),
    (195, "A"): (3, 1.0, 0.0, 0.0, 0.0, 306380000, -964780000, 12.34000015258789),
    (195, "B"): (0, 300.0, 0.0, 0.0, 0.0, -338688197, 1512092955, -7.889999866485596),
    (195, "C"): (3, 4464.0, 0.0, 0.0, 0.0, 306380001, -964780001, 0.0),
    (195, "D"): (10, 0.0, 0.0, 0.0, 0.0, 306380002, -964780002, 5.0),
    (195, "E"): (0, 65535.0, 0.0, 0.0, 0.0, 306380003, -964780003, 82999.984375),
    (197, "A"): (0, 1.0, 0.0, 0.0, 0.0, 0, 0, 0.0),
    (197, "B"): (0, 300.0, 0.0, 0.0, 0.0, 0, 0, 0.0),
    (197, "C"): (0, 4464.0, 0.0, 0.0, 0.0, 0, 0, 0.0),
    (197, "D"): (0, 0.0, 0.0, 0.0, 0.0, 0, 0, 0.0),
    (197, "E"): (0, 65535.0, 0.0, 0.0, 0.0, 0, 0, 0.0),
    (201, "A"): (3, 1.0, 0.0, 0.0, 0.0, 306380000, -964780000, 12.34000015258789),
    (201, "B"): (0, 300.0, 0.0, 0.0, 0.0, -338688197, 1512092955, -7.889999866485596),
    (201, "C"): (3, 4464.0, 0.0, 0.0, 0.0, 306380001, -964780001, 0.0),
    (201, "D"): (10, 0.0, 0.0, 0.0, 0.0, 306380002, -964780002, 5.0),
    (201, "E"): (0, 65535.0, 0.0, 0.0, 0.0, 306380003, -964780003, 82999.984375),
    (202, "A"): (0, 1.0, 2.0, 253.0, 4.0, 224, 32, 12.345000267028809),
    (202, "B"): (0, 44.0, 65529.0, 0.0, 65535.0, 59, 27, -7.890999794006348),
    (202, "C"): (0, 112.0, 65535.0, 212.0, 2.0, 225, 31, 0.004999999888241291),
    (202, "D"): (0, 0.0, 0.0, 0.0, 0.0, 226, 30, 5.0),
    (202, "E"): (0, 255.0, 1.0, 255.0, 256.0, 227, 29, 82999.9921875),
    (203, "A"): (0, 1.0, 2.0, -3.0, 4.0, 224, 32, 0.0),
    (203, "B"): (0, 44.0, 249.0, 0.0, 255.0, 59, 27, 0.0),
    (203, "C"): (0, 112.0, 255.0, -44.0, 2.0, 225, 31, 0.0),
    (203, "D"): (0, 0.0, 0.0, 0.0, 0.0, 226, 30, 0.0),
    (203, "E"): (0, 255.0, 1.0, -1.0, 0.0, 227, 29, 0.0),
    (205, "A"): (0, 1.7000000476837158, 2.5999999046325684, -3.4000000953674316, 0.0, 0, 0, 2.0),
    (205, "B"): (0, 300.29998779296875, -7.599999904632568, 0.5, 0.0, 0, 0, 2.0),
    (205, "C"): (0, 70000.0, 65535.8984375, -300.70001220703125, 0.0, 0, 0, 2.0),
    (205, "D"): (0, 0.0, 0.0, 0.0, 0.0, 0, 0, 2.0),
    (205, "E"): (0, -1.0, 1.0, 255.0, 0.0, 0, 0, 2.0),
    (206, "A"): (0, 1.7000000476837158, 0.0, 253.0, 0.0, 0, 0, 0.0),
    (206, "B"): (0, 300.29998779296875, 0.0, 0.0, 0.0, 0, 0, 0.0),
    (206, "C"): (0, 70000.0, 0.0, 212.0, 0.0, 0, 0, 0.0),
    (206, "D"): (0, 0.0, 0.0, 0.0, 0.0, 0, 0, 0.0),
    (206, "E"): (0, -1.0, 0.0, 255.0, 0.0, 0, 0, 0.0),
    (207, "A"): (0, 1.0, 0.0, 0.0, 0.0, 0, 0, 0.0),
    (207, "B"): (0, 300.0, 0.0, 0.0, 0.0, 0, 0, 0.0),
    (207, "C"): (0, 4464.0, 0.0, 0.0, 0.0, 0, 0, 0.0),
    (207, "D"): (0, 0.0, 0.0, 0.0, 0.0, 0, 0, 0.0),
    (207, "E"): (0, 65535.0, 0.0, 0.0, 0.0, 0, 0, 0.0),
    (208, "A"): (0, 1.0, 0.0, 0.0, 0.0, 0, 0, 0.0),
    (208, "B"): (0, 300.0, 0.0, 0.0, 0.0, 0, 0, 0.0),
    (208, "C"): (0, 4464.0, 0.0, 0.0, 0.0, 0, 0, 0.0),
    (208, "D"): (0, 0.0, 0.0, 0.0, 0.0, 0, 0, 0.0),
    (208, "E"): (0, 65535.0, 0.0, 0.0, 0.0, 0, 0, 0.0),
    (210, "A"): (0, 1.0, 0.0, 0.0, 0.0, 0, 0, 0.0),
    (210, "B"): (0, 300.0, 0.0, 0.0, 0.0, 0, 0, 0.0),
    (210, "C"): (0, 4464.0, 0.0, 0.0, 0.0, 0, 0, 0.0),
    (210, "D"): (0, 0.0, 0.0, 0.0, 0.0, 0, 0, 0.0),
    (210, "E"): (0, 65535.0, 0.0, 0.0, 0.0, 0, 0, 0.0),
    (211, "A"): (0, 1.0, 2.0, 0.0, 0.0, 0, 0, 0.0),
    (211, "B"): (0, 44.0, 249.0, 0.0, 0.0, 0, 0, 0.0),
    (211, "C"): (0, 112.0, 255.0, 0.0, 0.0, 0, 0, 0.0),
    (211, "D"): (0, 0.0, 0.0, 0.0, 0.0, 0, 0, 0.0),
    (211, "E"): (0, 255.0, 1.0, 0.0, 0.0, 0, 0, 0.0),
    (212, "A"): (0, 1.0, 0.0, 0.0, 0.0, 0, 0, 0.0),
    (212, "B"): (0, 300.0, 0.0, 0.0, 0.0, 0, 0, 0.0),
    (212, "C"): (0, 4464.0, 0.0, 0.0, 0.0, 0, 0, 0.0),
    (212, "D"): (0, 0.0, 0.0, 0.0, 0.0, 0, 0, 0.0),
    (212, "E"): (0, 65535.0, 0.0, 0.0, 0.0, 0, 0, 0.0),
    (213, "A"): (0, 1.7000000476837158, 2.5999999046325684, 253.0, 0.0, 0, 0, 0.0),
    (213, "B"): (0, 300.29998779296875, -7.599999904632568, 0.0, 0.0, 0, 0, 0.0),
    (213, "C"): (0, 70000.0, 65535.8984375, 212.0, 0.0, 0, 0, 0.0),
    (213, "D"): (0, 0.0, 0.0, 0.0, 0.0, 0, 0, 0.0),
    (213, "E"): (0, -1.0, 1.0, 255.0, 0.0, 0, 0, 0.0),
    (215, "A"): (0, 1.0, 0.0, 0.0, 0.0, 0, 0, 0.0),
    (215, "B"): (0, 300.0, 0.0, 0.0, 0.0, 0, 0, 0.0),
    (215, "C"): (0, 4464.0, 0.0, 0.0, 0.0, 0, 0, 0.0),
    (215, "D"): (0, 0.0, 0.0, 0.0, 0.0, 0, 0, 0.0),
    (215, "E"): (0, 65535.0, 0.0, 0.0, 0.0, 0, 0, 0.0),
    (216, "A"): (0, 1.0, 0.0, 0.0, 0.0, 0, 0, 0.0),
    (216, "B"): (0, 300.0, 0.0, 0.0, 0.0, 0, 0, 0.0),
    (216, "C"): (0, 4464.0, 0.0, 0.0, 0.0, 0, 0, 0.0),
    (216, "D"): (0, 0.0, 0.0, 0.0, 0.0, 0, 0, 0.0),
    (216, "E"): (0, 65535.0, 0.0, 0.0, 0.0, 0, 0, 0.0),
    (217, "A"): (0, 1.0, 2.5999999046325684, -3.4000000953674316, 4.5, 0, 0, 0.0),
    (217, "B"): (0, 300.0, -7.599999904632568, 0.5, -1.0, 0, 0, 0.0),
    (217, "C"): (0, 4464.0, 65535.8984375, -300.70001220703125, 2.0, 0, 0, 0.0),
    (217, "D"): (0, 0.0, 0.0, 0.0, 0.0, 0, 0, 0.0),
    (217, "E"): (0, 65535.0, 1.0, 255.0, 256.0, 0, 0, 0.0),
    (218, "A"): (0, 1.0, 2.0, 0.0, 0.0, 0, 0, 0.0),
    (218, "B"): (0, 300.0, 249.0, 0.0, 0.0, 0, 0, 0.0),
    (218, "C"): (0, 4464.0, 255.0, 0.0, 0.0, 0, 0, 0.0),
    (218, "D"): (0, 0.0, 0.0, 0.0, 0.0, 0, 0, 0.0),
    (218, "E"): (0, 65535.0, 1.0, 0.0, 0.0, 0, 0, 0.0),
    (222, "A"): (0, 1.0, 2.5999999046325684, -3.4000000953674316, 4.5, 0, 0, 0.0),
    (222, "B"): (0, 300.0, -7.599999904632568, 0.5, -1.0, 0, 0, 0.0),
    (222, "C"): (0, 4464.0, 65535.8984375, -300.70001220703125, 2.0, 0, 0, 0.0),
    (222, "D"): (0, 0.0, 0.0, 0.0, 0.0, 0, 0, 0.0),
    (222, "E"): (0, 65535.0, 1.0, 255.0, 256.0, 0, 0, 0.0),
    (223, "A"): (0, 1.0, 1.0, 651.9599609375, 0.0, 0, 0, 0.0),
    (223, "B"): (0, 1.0, 0.0, 0.5, 1.0, 0, 0, 0.0),
    (223, "C"): (0, 1.0, 1.0, 354.6600036621094, 0.0, 0, 0, 0.0),
    (223, "D"): (0, 0.0, 0.0, 0.0, 0.0, 0, 0, 0.0),
    (223, "E"): (0, 0.0, 1.0, 255.0, 0.0, 0, 0, 0.0),
    (531, "A"): (0, 1.0, 2.5999999046325684, 0.0, 0.0, 0, 0, 0.0),
    (531, "B"): (0, 44.0, -7.599999904632568, 0.0, 0.0, 0, 0, 0.0),
    (531, "C"): (0, 112.0, 65535.8984375, 0.0, 0.0, 0, 0, 0.0),
    (531, "D"): (0, 0.0, 0.0, 0.0, 0.0, 0, 0, 0.0),
    (531, "E"): (0, 255.0, 1.0, 0.0, 0.0, 0, 0, 0.0),
    (532, "A"): (0, 1.0, 2.5999999046325684, 0.0, 0.0, 0, 0, 0.0),
    (532, "B"): (0, 44.0, -7.599999904632568, 0.0, 0.0, 0, 0, 0.0),
    (532, "C"): (0, 112.0, 65535.8984375, 0.0, 0.0, 0, 0, 0.0),
    (532, "D"): (0, 0.0, 0.0, 0.0, 0.0, 0, 0, 0.0),
    (532, "E"): (0, 255.0, 1.0, 0.0, 0.0, 0, 0, 0.0),
    (534, "A"): (0, 1.0, 2.0, 253.0, 0.0, 0, 0, 0.0),
    (534, "B"): (0, 44.0, 249.0, 0.0, 0.0, 0, 0, 0.0),
    (534, "C"): (0, 112.0, 255.0, 212.0, 0.0, 0, 0, 0.0),
    (534, "D"): (0, 0.0, 0.0, 0.0, 0.0, 0, 0, 0.0),
    (534, "E"): (0, 255.0, 1.0, 255.0, 0.0, 0, 0, 0.0),
    (600, "A"): (0, 1.0, 0.0, 0.0, 0.0, 0, 0, 0.0),
    (600, "B"): (0, 300.0, 0.0, 0.0, 0.0, 0, 0, 0.0),
    (600, "C"): (0, 4464.0, 0.0, 0.0, 0.0, 0, 0, 0.0),
    (600, "D"): (0, 0.0, 0.0, 0.0, 0.0, 0, 0, 0.0),
    (600, "E"): (0, 65535.0, 0.0, 0.0, 0.0, 0, 0, 0.0),
    (601, "A"): (0, 1.0, 2.0, 0.0, 0.0, 0, 0, 0.0),
    (601, "B"): (0, 300.0, -7.0, 0.0, 0.0, 0, 0, 0.0),
    (601, "C"): (0, 4464.0, -1.0, 0.0, 0.0, 0, 0, 0.0),
    (601, "D"): (0, 0.0, 0.0, 0.0, 0.0, 0, 0, 0.0),
    (601, "E"): (0, 65535.0, 1.0, 0.0, 0.0, 0, 0, 0.0),
    (1000, "A"): (0, 1.0, 2.0, -3.0, 4.0, 224, 0, 12.0),
    (1000, "B"): (0, 44.0, -7.0, 0.0, -1.0, 59, 0, 249.0),
    (1000, "C"): (0, 112.0, -1.0, -44.0, 2.0, 225, 0, 0.0),
    (1000, "D"): (0, 0.0, 0.0, 0.0, 0.0, 226, 0, 5.0),
    (1000, "E"): (0, -1.0, 1.0, -1.0, 0.0, 227, 0, 55.0),
    (2000, "A"): (0, 1.0, 2.5999999046325684, 65533.0, 4.0, 0, 0, 0.0),
    (2000, "B"): (0, 44.0, -7.599999904632568, 0.0, 65535.0, 0, 0, 0.0),
    (2000, "C"): (0, 112.0, 65535.8984375, 65236.0, 2.0, 0, 0, 0.0),
    (2000, "D"): (0, 0.0, 0.0, 0.0, 0.0, 0, 0, 0.0),
    (2000, "E"): (0, 255.0, 1.0, 255.0, 256.0, 0, 0, 0.0),
    (2001, "A"): (0, 1.0, 0.0, 0.0, 0.0, 0, 0, 0.0),
    (2001, "B"): (0, 300.0, 0.0, 0.0, 0.0, 0, 0, 0.0),
    (2001, "C"): (0, 4464.0, 0.0, 0.0, 0.0, 0, 0, 0.0),
    (2001, "D"): (0, 0.0, 0.0, 0.0, 0.0, 0, 0, 0.0),
    (2001, "E"): (0, 65535.0, 0.0, 0.0, 0.0, 0, 0, 0.0),
    (2500, "A"): (0, 1.0, 0.0, 0.0, 0.0, 0, 0, 0.0),
    (2500, "B"): (0, 44.0, 0.0, 0.0, 0.0, 0, 0, 0.0),
    (2500, "C"): (0, 112.0, 0.0, 0.0, 0.0, 0, 0, 0.0),
    (2500, "D"): (0, 0.0, 0.0, 0.0, 0.0, 0, 0, 0.0),
    (2500, "E"): (0, 255.0, 0.0, 0.0, 0.0, 0, 0, 0.0),
    (2501, "A"): (0, 1.0, 0.0, 0.0, 0.0, 0, 0, 0.0),
    (2501, "B"): (0, 44.0, 0.0, 0.0, 0.0, 0, 0, 0.0),
    (2501, "C"): (0, 112.0, 0.0, 0.0, 0.0, 0, 0, 0.0),
    (2501, "D"): (0, 0.0, 0.0, 0.0, 0.0, 0, 0, 0.0),
    (2501, "E"): (0, 255.0, 0.0, 0.0, 0.0, 0, 0, 0.0),
    (3000, "A"): (0, 1.0, 0.0, 0.0, 0.0, 0, 0, 0.0),
    (3000, "B"): (0, 44.0, 0.0, 0.0, 0.0, 0, 0, 0.0),
    (3000, "C"): (0, 112.0, 0.0, 0.0, 0.0, 0, 0, 0.0),
    (3000, "D"): (0, 0.0, 0.0, 0.0, 0.0, 0, 0, 0.0),
    (3000, "E"): (0, 255.0, 0.0, 0.0, 0.0, 0, 0, 0.0),
    (42600, "A"): (0, 1.0, 2.0, -3.4000000953674316, 4.5, 0, 0, 0.0),
    (42600, "B"): (0, 44.0, 249.0, 0.5, -1.0, 0, 0, 0.0),
    (42600, "C"): (0, 112.0, 255.0, -300.70001220703125, 2.0, 0, 0, 0.0),
    (42600, "D"): (0, 0.0, 0.0, 0.0, 0.0, 0, 0, 0.0),
    (42600, "E"): (0, 255.0, 1.0, 255.0, 256.0, 0, 0, 0.0),
    (42702, "A"): (0, 1.0, 2.0, -3.400390625, 4.5, -800, -24544, 0.0),
    (42702, "B"): (0, 44.0, 249.0, 0.5, -1.0, 1851, -19173, 0.0),
    (42702, "C"): (0, 112.0, 255.0, -300.75, 2.0, -799, -24545, 0.0),
    (42702, "D"): (0, 0.0, 0.0, 0.0, 0.0, -798, -24546, 0.0),
    (42702, "E"): (0, 255.0, 1.0, 255.0, 256.0, -797, -24547, 0.0),
    (42703, "A"): (0, 1.0, 2.0, -3.0, 4.0, -800, 0, 0.0),
    (42703, "B"): (0, 300.0, -7.0, 0.0, -1.0, 1851, 0, 0.0),
    (42703, "C"): (0, 65535.0, 0.0, 0.0, 2.0, -799, 0, 0.0),
    (42703, "D"): (0, 0.0, 0.0, 0.0, 0.0, -798, 0, 0.0),
    (42703, "E"): (0, 0.0, 1.0, 0.0, 256.0, -797, 0, 0.0),
}

# ArduPlane: the same, without spline waypoints (UNSUPPORTED), and these waypoints:
STORED_ARDUPLANE: dict[tuple[int, str], Any] = {
    (16, "A"): (3, 0.0, 2.0, 255.0, 0.0, 306380000, -964780000, 12.34000015258789),
    (16, "B"): (0, 0.0, 255.0, 0.0, 0.0, -338688197, 1512092955, -7.889999866485596),
    (16, "C"): (3, 0.0, 255.0, 255.0, 0.0, 306380001, -964780001, 0.0),
    (16, "E"): (0, 0.0, 1.0, 255.0, 0.0, 306380003, -964780003, 82999.984375),
}
