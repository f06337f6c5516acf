"""The ground station's side of a MAVLink mission-protocol upload, for the autopilot adapter.

ArduPilot keeps three item lists (the mission, the fence, the rally points) and takes
each from a ground station the same way (MissionItemProtocol.cpp): the station sends
MISSION_COUNT with the list's length and type; the autopilot asks for each item with
MISSION_REQUEST_INT (or the older MISSION_REQUEST), one after the other; the station
answers each request with that item as MISSION_ITEM_INT; the autopilot ends with
MISSION_ACK, ACCEPTED or why not. A MISSION_COUNT of 0 clears the list (ACCEPTED at
once). The engine uploads fences (:func:`fence_items`), as part of the autopilot's
safety set-up, and missions to fly in AUTO (:func:`mission_items`, a survey's
``fly_as: auto``; :class:`MissionUploads` carries them out for the adapter, one at a
time, after any fence upload under way, and reports how each ended and the mission's
progress).

:class:`MissionUpload` is one such upload, pure like the adapter: it encodes with the
adapter's pymavlink object, is handed the autopilot's mission messages and the time,
and says when it is over. What it does when messages are lost:

- An item request is answered every time it comes, the same item again when ArduPilot
  asks again (it repeats a request after 1 s without the item).
- Nothing from the autopilot for :data:`UPLOAD_SILENCE_S` (no request, no ack): the
  MISSION_COUNT is sent again, which restarts the upload (ArduPilot restarts it for a new
  count from the same station); after :data:`UPLOAD_ATTEMPTS` counts, the upload fails.
"""

from __future__ import annotations

import logging
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import Any, Final

from pymavlink.dialects.v20 import ardupilotmega as mavlink2

from clark_engine.runtime.commands import FenceZone, MissionItem, UploadMission
from clark_engine.runtime.events import MissionProgress, MissionUploadResult
from clark_engine.runtime.log_events import LogEvent

UPLOAD_SILENCE_S: Final = 2.5
"""Silence from the autopilot during an upload after which the count is sent again: more
than two of ArduPilot's 1 s request repeats."""

MAX_WAITING: Final = 4
"""Mission uploads that may wait their turn (behind one under way or a safety set-up)."""

UPLOAD_ATTEMPTS: Final = 3
"""MISSION_COUNTs sent before an upload with no answer is given up."""

FENCE_FRAME: Final = int(mavlink2.MAV_FRAME_GLOBAL)
"""Fence items carry latitude and longitude only; ArduPilot stores them in frame 0."""

FENCE_TYPE: Final = int(mavlink2.MAV_MISSION_TYPE_FENCE)
MISSION_TYPE: Final = int(mavlink2.MAV_MISSION_TYPE_MISSION)


MISSION_FRAME: Final = int(mavlink2.MAV_FRAME_GLOBAL_RELATIVE_ALT_INT)
"""A mission's waypoints carry their height above home (ArduPilot's usual mission frame);
the adapter converts the engine's height above the origin with HOME_POSITION's altitude,
as for a Goto."""

COMMAND_FRAME: Final = int(mavlink2.MAV_FRAME_MISSION)
"""Mission items with no position (DO_CHANGE_SPEED) carry the frame for none."""


@dataclass(frozen=True, slots=True)
class Item:
    """One item of a list to upload, as MISSION_ITEM_INT carries it.

    Attributes:
        command: The MAV_CMD number.
        param1: The command's first parameter (a polygon's vertex count, a circle's
            radius, a waypoint's hold time, a speed change's speed type).
        lat_e7: Latitude in 1e-7 degrees (x).
        lon_e7: Longitude in 1e-7 degrees (y).
        frame: MAV_FRAME the position is in (a fence: MAV_FRAME_GLOBAL).
        param2: The second parameter (a speed change's speed).
        param3: The third (a speed change's throttle, -1 for no change).
        param4: The fourth.
        z: Altitude in ``frame``, metres.
    """

    command: int
    param1: float
    lat_e7: int
    lon_e7: int
    frame: int = int(mavlink2.MAV_FRAME_GLOBAL)
    param2: float = 0.0
    param3: float = 0.0
    param4: float = 0.0
    z: float = 0.0


def fence_items(zones: Sequence[FenceZone]) -> tuple[Item, ...]:
    """ArduPilot's fence items for these zones, in order (AC_PolyFence_loader's format).

    A polygon is one NAV_FENCE_POLYGON_VERTEX_INCLUSION (or _EXCLUSION) per corner, each
    carrying the polygon's corner count in param1; a circle is one
    NAV_FENCE_CIRCLE_INCLUSION (or _EXCLUSION) at its centre with its radius in param1.
    """
    items: list[Item] = []
    for zone in zones:
        if zone.center_deg is not None:
            command = (
                mavlink2.MAV_CMD_NAV_FENCE_CIRCLE_INCLUSION
                if zone.inclusion
                else mavlink2.MAV_CMD_NAV_FENCE_CIRCLE_EXCLUSION
            )
            lat, lon = zone.center_deg
            items.append(Item(int(command), zone.radius_m, round(lat * 1e7), round(lon * 1e7)))
            continue
        command = (
            mavlink2.MAV_CMD_NAV_FENCE_POLYGON_VERTEX_INCLUSION
            if zone.inclusion
            else mavlink2.MAV_CMD_NAV_FENCE_POLYGON_VERTEX_EXCLUSION
        )
        count = float(len(zone.corners_deg))
        items.extend(
            Item(int(command), count, round(lat * 1e7), round(lon * 1e7))
            for lat, lon in zone.corners_deg
        )
    return tuple(items)


def mission_items(
    items: Sequence[MissionItem],
    home: tuple[float, float, float] | None,
    above_home_m: Callable[[float], float],
    *,
    airspeed: bool,
) -> tuple[Item, ...]:
    """ArduPilot's mission list for an :class:`UploadMission`'s items, home first.

    Item 0 of ArduPilot's mission is home, which it keeps itself: the vehicle's home
    goes there (frame 0, its height above mean sea level; zeros before home is known).
    A waypoint is a MAV_CMD_NAV_WAYPOINT in :data:`MISSION_FRAME` (no hold, ArduPilot's
    acceptance radius); a speed is a MAV_CMD_DO_CHANGE_SPEED (airspeed for ArduPlane,
    whose ground-speed type sets only a minimum; ground speed otherwise; throttle
    unchanged), as the adapter changes speed for a Goto.

    Args:
        items: The command's items, in order.
        home: HOME_POSITION (latitude, longitude, metres above mean sea level), or None.
        above_home_m: Converts a height above the origin to one above home.
        airspeed: The speed is an airspeed (ArduPlane).
    """
    lat, lon, alt = home if home is not None else (0.0, 0.0, 0.0)
    out = [Item(int(mavlink2.MAV_CMD_NAV_WAYPOINT), 0.0, round(lat * 1e7), round(lon * 1e7), z=alt)]
    for item in items:
        if item.kind == "speed":
            out.append(
                Item(
                    int(mavlink2.MAV_CMD_DO_CHANGE_SPEED),
                    0.0 if airspeed else 1.0,
                    0,
                    0,
                    frame=COMMAND_FRAME,
                    param2=float(item.speed_m_s),
                    param3=-1.0,
                )
            )
        elif item.kind == "waypoint":
            out.append(
                Item(
                    int(mavlink2.MAV_CMD_NAV_WAYPOINT),
                    0.0,
                    round(item.lat_deg * 1e7),
                    round(item.lon_deg * 1e7),
                    frame=MISSION_FRAME,
                    z=round(above_home_m(item.alt_m), 2),
                )
            )
        else:
            raise ValueError(f"no mission item of kind {item.kind!r}")
    return tuple(out)


def mission_result_name(result: int) -> str:
    """MAV_MISSION_RESULT in words, without its prefix (``ACCEPTED``, ``NO_SPACE``)."""
    entry = mavlink2.enums["MAV_MISSION_RESULT"].get(result)
    name = entry.name if entry is not None else f"MAV_MISSION_{result}"
    return str(name).removeprefix("MAV_MISSION_")


class MissionUpload:
    """One upload of an item list to the autopilot, from MISSION_COUNT to MISSION_ACK.

    Args:
        mav: The adapter's pymavlink encoder (its ids are the station's).
        target: The autopilot's (system, component).
        items: What to upload, in order (none: the list is cleared).
        mission_type: MAV_MISSION_TYPE (the fence: 1).
        now_s: The time the upload starts (MISSION_COUNT is sent now).
    """

    def __init__(
        self,
        mav: Any,
        target: tuple[int, int],
        items: Sequence[Item],
        mission_type: int,
        now_s: float,
    ) -> None:
        self._mav = mav
        self._target = target
        self._items = tuple(items)
        self._type = mission_type
        self._counts = 0
        self._heard_s = now_s
        self.result: int | None = None
        """MAV_MISSION_RESULT once the autopilot acknowledged; None until then, and after
        a give-up (see :attr:`gave_up`)."""
        self.gave_up = False
        """True when the autopilot never finished answering."""
        self._count(now_s)

    @property
    def count(self) -> int:
        """How many items the upload carries."""
        return len(self._items)

    @property
    def done(self) -> bool:
        """The upload is over: acknowledged (see :attr:`result`) or given up."""
        return self.result is not None or self.gave_up

    def _count(self, now_s: float) -> None:
        self._counts += 1
        self._heard_s = now_s
        system, component = self._target
        self._mav.send(
            self._mav.mission_count_encode(system, component, len(self._items), self._type)
        )

    def handle(self, msg: Any, own: tuple[int, int], now_s: float) -> bool:
        """Take one message from the autopilot; True when it belonged to this upload.

        Args:
            msg: A MISSION_REQUEST_INT, MISSION_REQUEST or MISSION_ACK (others are not taken).
            own: The station's (system, component): answers addressed elsewhere are not ours.
            now_s: When it arrived.
        """
        if self.done or int(getattr(msg, "mission_type", 0)) != self._type:
            return False
        if msg.target_system not in (0, own[0]) or msg.target_component not in (0, own[1]):
            return False
        kind = msg.get_type()
        if kind == "MISSION_ACK":
            self.result = int(msg.type)
            return True
        if kind not in ("MISSION_REQUEST_INT", "MISSION_REQUEST"):
            return False
        self._heard_s = now_s
        seq = int(msg.seq)
        if not 0 <= seq < len(self._items):
            return True  # ArduPilot asks only for items it was told of; nothing to send
        item = self._items[seq]
        system, component = self._target
        self._mav.send(
            self._mav.mission_item_int_encode(
                system,
                component,
                seq,
                item.frame,
                item.command,
                0,  # current
                0 if self._type == FENCE_TYPE else 1,  # autocontinue: a mission goes on
                item.param1,
                item.param2,
                item.param3,
                item.param4,
                item.lat_e7,
                item.lon_e7,
                item.z,
                self._type,
            )
        )
        return True

    def poll(self, now_s: float) -> None:
        """Restart a silent upload, or give it up after :data:`UPLOAD_ATTEMPTS` counts."""
        if self.done or now_s - self._heard_s < UPLOAD_SILENCE_S:
            return
        if self._counts >= UPLOAD_ATTEMPTS:
            self.gave_up = True
            return
        self._count(now_s)


MISSION_PROGRESS_MESSAGES: Final = frozenset({"MISSION_ITEM_REACHED", "MISSION_CURRENT"})
"""What ArduPilot says of the mission it flies: an item reached (sent once, to every
ground station), and the item now current (streamed with the extended status, and sent
when it changes)."""


class MissionUploads:
    """The adapter's mission uploads (UploadMission), one at a time, and the progress after.

    Each :class:`UploadMission` waits its turn: behind the one under way, and behind a
    safety set-up under way (which may upload the fence list: ArduPilot takes one upload
    per list from a ground station, and the fence comes first). When its MISSION_ACK
    arrives it is reported as a :class:`MissionUploadResult`; an accepted mission is then
    made current from its first item (MISSION_SET_CURRENT 1), so that AUTO flies it from
    the start even where a mission flown before had stopped half-way (AUTO resumes at the
    current item, MIS_RESTART 0). From then on MISSION_ITEM_REACHED and MISSION_CURRENT
    are reported as :class:`MissionProgress`, counted in the command's items (ArduPilot's
    seq less one: its item 0 is home); MISSION_CURRENT only when it changes, and only once
    one has shown the first item current (or an item was reached): until ArduPilot has
    taken MISSION_SET_CURRENT, its current item may be the one a mission flown before had
    stopped at, which would skip the first lines' pictures.

    Args:
        mav: The adapter's pymavlink encoder.
        target: The autopilot's (system, component).
        encode: The ArduPilot items for a command (:func:`mission_items` with the
            vehicle's home and datum).
        fence_busy: True while a safety set-up is under way (its fence upload first).
        reasons: The autopilot's warnings between two times, joined (a refusal's why).
        emit: Where the events go (the adapter's next :meth:`receive`).
        log: The interface log.
    """

    def __init__(
        self,
        mav: Any,
        target: tuple[int, int],
        encode: Callable[[UploadMission], tuple[Item, ...]],
        fence_busy: Callable[[], bool],
        reasons: Callable[[float, float], str],
        emit: Callable[[MissionUploadResult | MissionProgress], None],
        log: logging.Logger,
    ) -> None:
        self._mav = mav
        self._target = target
        self._encode = encode
        self._fence_busy = fence_busy
        self._reasons = reasons
        self._emit = emit
        self._log = log
        self._queue: list[UploadMission] = []
        self._upload: tuple[UploadMission, MissionUpload, float] | None = None
        self._flying: int | None = None  # items of the mission the autopilot holds from us
        self._current: tuple[int, int | None] | None = None
        self._synced = False  # MISSION_CURRENT is ours (see the class's docstring)

    @property
    def busy(self) -> bool:
        """An upload under way or waiting."""
        return self._upload is not None or bool(self._queue)

    def request(self, command: UploadMission, now_s: float) -> None:
        """Queue an upload; started at once when nothing else uploads.

        At most :data:`MAX_WAITING` wait, in order; beyond that the oldest waiting is
        answered refused (``SUPERSEDED``): the autopilot holds one mission, and a
        behaviour that asks again and again must not grow the queue.
        """
        self._queue.append(command)
        while len(self._queue) > MAX_WAITING:
            self._refuse(self._queue.pop(0), "SUPERSEDED")
        self.poll(now_s)

    def drop_waiting(self) -> None:
        """The autopilot fell silent: an upload still waiting its turn is dropped.

        It is never sent once the link returns (it is answered refused,
        ``AUTOPILOT_LOST``); one under way lapses by itself (:data:`UPLOAD_ATTEMPTS`).
        """
        for waiting in self._queue:
            self._refuse(waiting, "AUTOPILOT_LOST")
        self._queue.clear()

    def _refuse(self, command: UploadMission, result: str) -> None:
        self._log.warning(
            "the mission %s is not uploaded: %s",
            command.what or f"#{command.upload_id}",
            result,
            extra=LogEvent.AUTOPILOT_MISSION.extra,
        )
        self._emit(MissionUploadResult(command.upload_id, False, result))

    def cancel(self) -> None:
        """A clean stop: nothing more is uploaded (an upload under way is left to lapse)."""
        self._queue.clear()
        self._upload = None

    def poll(self, now_s: float) -> None:
        """Restart a silent upload or give it up; start the next when its turn comes."""
        if self._upload is not None:
            upload = self._upload[1]
            upload.poll(now_s)
            if upload.done:
                self._over(now_s)
        if self._upload is None and self._queue and not self._fence_busy():
            command = self._queue.pop(0)
            items = self._encode(command)
            self._log.info(
                "uploading the mission %s: %d item(s) and home",
                command.what or f"#{command.upload_id}",
                len(command.items),
                extra=LogEvent.AUTOPILOT_MISSION.extra,
            )
            self._flying = None  # the autopilot's mission is being replaced
            self._current = None
            self._synced = False
            self._upload = (
                command,
                MissionUpload(self._mav, self._target, items, MISSION_TYPE, now_s),
                now_s,
            )

    def on_answer(self, msg: Any, own: tuple[int, int], now_s: float) -> bool:
        """A MISSION_REQUEST(_INT) or MISSION_ACK; True when the upload under way took it."""
        if self._upload is None:
            return False
        upload = self._upload[1]
        if not upload.handle(msg, own, now_s):
            return False
        if upload.done:
            self._over(now_s)
        return True

    def on_progress(self, msg: Any) -> None:
        """MISSION_ITEM_REACHED or MISSION_CURRENT: a MissionProgress for our mission."""
        if self._flying is None:
            return  # not a mission the engine uploaded (or one being replaced)
        seq = int(msg.seq)
        if seq < 1 or seq > self._flying:
            return  # home, or past the end of ours: no item of ours
        if msg.get_type() == "MISSION_ITEM_REACHED":
            self._synced = True
            self._emit(MissionProgress(seq - 1, self._flying, reached=True))
            return
        if not self._synced and seq != 1:
            return  # not yet the mission made current from its start
        self._synced = True
        total = getattr(msg, "total", None)
        total = int(total) if total is not None and int(total) != 0xFFFF else None
        current = (seq, total)
        if current == self._current:
            return
        self._current = current
        self._emit(MissionProgress(seq - 1, total if total is not None else self._flying))

    def _over(self, now_s: float) -> None:
        assert self._upload is not None
        command, upload, started_s = self._upload
        self._upload = None
        what = command.what or f"#{command.upload_id}"
        if upload.result == mavlink2.MAV_MISSION_ACCEPTED:
            self._flying = len(command.items)
            system, component = self._target
            # ArduPilot answers with MISSION_CURRENT (no acknowledgement).
            self._mav.send(self._mav.mission_set_current_encode(system, component, 1))
            self._log.info(
                "the autopilot accepted the mission %s",
                what,
                extra=LogEvent.AUTOPILOT_MISSION.extra,
            )
            self._emit(MissionUploadResult(command.upload_id, True, "ACCEPTED"))
            return
        reason = self._reasons(started_s, now_s)
        result = "NO_ANSWER" if upload.result is None else mission_result_name(upload.result)
        self._log.error(
            "the autopilot did not take the mission %s: %s%s",
            what,
            result,
            f" ({reason})" if reason else "",
            extra=LogEvent.AUTOPILOT_MISSION.extra,
        )
        self._emit(MissionUploadResult(command.upload_id, False, result, reason))
