"""The ground station's side of a MAVLink mission-protocol upload, for the autopilot adapter.

ArduPilot keeps three item lists (the mission, the fence, the rally points) and takes
each from a ground station the same way (MissionItemProtocol.cpp): the station sends
MISSION_COUNT with the list's length and type; the autopilot asks for each item with
MISSION_REQUEST_INT (or the older MISSION_REQUEST), one after the other; the station
answers each request with that item as MISSION_ITEM_INT; the autopilot ends with
MISSION_ACK, ACCEPTED or why not. A MISSION_COUNT of 0 clears the list (ACCEPTED at
once). The engine uploads only fences (:func:`fence_items`), as part of the
autopilot's safety set-up.

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

from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any, Final

from pymavlink.dialects.v20 import ardupilotmega as mavlink2

from clark_engine.runtime.commands import FenceZone

UPLOAD_SILENCE_S: Final = 2.5
"""Silence from the autopilot during an upload after which the count is sent again: more
than two of ArduPilot's 1 s request repeats."""

UPLOAD_ATTEMPTS: Final = 3
"""MISSION_COUNTs sent before an upload with no answer is given up."""

FENCE_FRAME: Final = int(mavlink2.MAV_FRAME_GLOBAL)
"""Fence items carry latitude and longitude only; ArduPilot stores them in frame 0."""


@dataclass(frozen=True, slots=True)
class Item:
    """One item of a list to upload, as MISSION_ITEM_INT carries it.

    Attributes:
        command: The MAV_CMD number.
        param1: The command's first parameter (a polygon's vertex count, a circle's radius).
        lat_e7: Latitude in 1e-7 degrees.
        lon_e7: Longitude in 1e-7 degrees.
    """

    command: int
    param1: float
    lat_e7: int
    lon_e7: int


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


def result_name(result: int) -> str:
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
                FENCE_FRAME,
                item.command,
                0,  # current
                0,  # autocontinue
                item.param1,
                0,
                0,
                0,
                item.lat_e7,
                item.lon_e7,
                0,
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
