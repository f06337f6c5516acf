"""ArduPilot's three item lists and the transfer state machine each runs (MissionItemProtocol).

Apart from :class:`~clark_engine.sim.ardupilot.mission_protocol.MissionProtocol` because it
is the per-list protocol: :class:`ItemList` is an upload's and a download's state machine
(requests, resends, timeouts, partial updates, who may interrupt), and its subclasses
store the mission (:class:`WaypointList`), the fence (:class:`FenceList`) and the rally
points (:class:`RallyList`) each their own way, within each firmware's storage limits
(:data:`ITEM_LIMITS`). The protocol object owns one of each and hands them the messages.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, replace
from typing import TYPE_CHECKING, Any, Final

from clark_engine.sim.ardupilot.mission_items import (
    ACCEPTED,
    DENIED,
    DO_JUMP,
    ERROR,
    FENCE,
    INVALID_SEQUENCE,
    MISSION,
    NO_SPACE,
    OPERATION_CANCELLED,
    RALLY,
    SEVERITY_DEBUG,
    SEVERITY_INFO,
    SEVERITY_WARNING,
    MissionItem,
    MissionItemError,
    fence_item,
    fence_problem,
    rally_item,
    stored_mission_item,
)

if TYPE_CHECKING:
    from clark_engine.sim.ardupilot.mission_protocol import MissionProtocol

UPLOAD_TIMEOUT_S: Final = 8.0
"""An upload ends this long after the last item (MissionItemProtocol's upload_timeout_ms)."""
REREQUEST_S: Final = 1.0
"""The pending MISSION_REQUEST is sent again once more than this passed since the last."""


@dataclass(frozen=True, slots=True)
class ItemLimits:
    """How many items of each type a firmware's storage takes (measured on SITL)."""

    mission: int
    """Mission items, home included."""
    fence: int
    """Fence items."""
    rally: int
    """Rally points."""


ITEM_LIMITS: Final[Mapping[str, ItemLimits]] = {
    "arducopter": ItemLimits(mission=650, fence=70, rally=46),
    "arduplane": ItemLimits(mission=655, fence=84, rally=50),
    "ardurover": ItemLimits(mission=655, fence=84, rally=50),
}
"""Storage limits per firmware: what "Only N items are supported" says on SITL."""


@dataclass(slots=True)
class _Upload:
    """One transfer from a ground station (MissionItemProtocol's receiving state)."""

    system_id: int
    component_id: int
    next_seq: int
    last_seq: int
    last_receive_s: float
    last_request_s: float


class ItemList:
    """One of ArduPilot's MissionItemProtocol objects (mission, fence or rally points).

    The generic transfer logic lives here; the subclasses store items their own way.
    """

    mission_type: int
    timeout_text: str

    def __init__(self, owner: MissionProtocol, max_items: int) -> None:
        self.owner = owner
        self.max_items = max_items
        self.upload: _Upload | None = None
        self.item_warning_sent = False
        self.request_warning_sent = False

    # storage, per type

    def count(self) -> int:
        """How many items are stored (what a download counts)."""
        raise NotImplementedError

    def begin(self, count: int) -> None:
        """Resources for a new upload of ``count`` items (allocate_receive_resources)."""

    def begin_update(self) -> None:
        """Resources for a partial update (allocate_update_resources)."""

    def end(self) -> None:
        """Free what begin() took (free_upload_resources)."""

    def truncate(self, count: int) -> None:
        """Keep the first ``count`` items (replace_item's list shortened at MISSION_COUNT)."""
        raise NotImplementedError

    def store(self, item: MissionItem, append: bool) -> int:
        """Store an uploaded item at its seq, or ``append`` it; its MAV_MISSION_RESULT."""
        raise NotImplementedError

    def complete(self) -> int:
        """The upload's last item arrived: take the new list; its MAV_MISSION_RESULT."""
        raise NotImplementedError

    def clear_all(self) -> bool:
        """Empty the list (MISSION_CLEAR_ALL); False when it cannot be cleared."""
        raise NotImplementedError

    def get(self, seq: int) -> MissionItem | None:
        """The stored item ``seq``; None when there is none."""
        raise NotImplementedError

    # the protocol, as MissionItemProtocol.cpp

    @property
    def receiving(self) -> bool:
        """An upload is under way."""
        return self.upload is not None

    def handle_count(self, msg: Any, count: int, now_s: float) -> None:
        """MISSION_COUNT: start (or restart) an upload of ``count`` items."""
        source = (msg.get_srcSystem(), msg.get_srcComponent())
        if self.upload is not None:
            if source != (self.upload.system_id, self.upload.component_id):
                self.owner._ack(source, DENIED, self.mission_type)
                return
            self.upload = None  # the uploader starts again (or gives up, if refused below)
            self.end()
        if count > self.max_items:
            self.owner._ack(source, NO_SPACE, self.mission_type)
            self.owner._say(SEVERITY_WARNING, f"Only {self.max_items} items are supported")
            return
        self.begin(count)
        self.truncate(count)
        if count == 0:
            self._transfer_complete(source)
            return
        self._start_requests(source, 0, count - 1, now_s)

    def handle_partial(self, msg: Any, start: int, end: int, now_s: float) -> None:
        """MISSION_WRITE_PARTIAL_LIST: start an update of items ``start``..``end``."""
        source = (msg.get_srcSystem(), msg.get_srcComponent())
        count = self.count()
        start_u, end_u = start & 0xFFFF, end & 0xFFFF  # int16 compared as unsigned
        if start_u > count or end_u > count or end < start:
            self.owner._say(SEVERITY_WARNING, "Flight plan update rejected")
            self.owner._ack(source, ERROR, self.mission_type)
            return
        self.begin_update()
        self._start_requests(source, start, end, now_s)

    def handle_item(self, msg: Any, item: MissionItem, now_s: float) -> None:
        """MISSION_ITEM(_INT) during an upload: store it, ask for the next or finish."""
        upload = self.upload
        assert upload is not None
        source = (msg.get_srcSystem(), msg.get_srcComponent())
        if item.seq != upload.next_seq:
            self.owner._ack(source, INVALID_SEQUENCE, self.mission_type)
            return
        if source != (upload.system_id, upload.component_id):
            self.owner._ack(source, DENIED, self.mission_type)
            return
        count = self.count()
        if item.seq < count:
            result = self.store(item, append=False)
        elif item.seq == count:
            result = self.store(item, append=True)
        else:
            result = ERROR
        if result != ACCEPTED:
            self.owner._ack(source, result, self.mission_type)
            self.upload = None
            self.end()
            return
        upload.last_receive_s = now_s
        upload.next_seq += 1
        if upload.next_seq > upload.last_seq:
            self._transfer_complete(source)
            return
        self._request(now_s)

    def handle_clear_all(self, msg: Any) -> None:
        """MISSION_CLEAR_ALL: clear, unless someone else's upload is under way."""
        source = (msg.get_srcSystem(), msg.get_srcComponent())
        if self.upload is not None:
            if source != (self.upload.system_id, self.upload.component_id):
                self.owner._ack(source, DENIED, self.mission_type)
                self.owner._ack(source, ERROR, self.mission_type)
                return
            self.upload = None
            self.end()
        self.owner._ack(source, ACCEPTED if self.clear_all() else ERROR, self.mission_type)

    def handle_request_list(self, msg: Any) -> None:
        """MISSION_REQUEST_LIST: answer with MISSION_COUNT."""
        source = (msg.get_srcSystem(), msg.get_srcComponent())
        if self.upload is not None:
            self.owner._ack(source, DENIED, self.mission_type)
            return
        self.owner._send(
            self.owner.mav.mission_count_encode(*source, self.count(), self.mission_type)
        )

    def handle_request(self, msg: Any, legacy: bool) -> None:
        """MISSION_REQUEST(_INT): answer with the item (``legacy``: MISSION_ITEM)."""
        source = (msg.get_srcSystem(), msg.get_srcComponent())
        if self.upload is not None:
            self.owner._ack(source, DENIED, self.mission_type)
            return
        item = self.get(int(msg.seq))
        if item is None:
            if not legacy:  # the size, to set the ground station right (legacy: no)
                self.owner._send(
                    self.owner.mav.mission_count_encode(*source, self.count(), self.mission_type)
                )
            self.owner._ack(source, INVALID_SEQUENCE, self.mission_type)
            return
        item = replace(item, mission_type=int(msg.mission_type))
        if not legacy:
            self.owner._send(item.mission_item_int(self.owner.mav, *source))
            return
        try:
            reply = item.mission_item(self.owner.mav, *source)
        except MissionItemError as refused:
            self.owner._ack(source, refused.result, self.mission_type)
            return
        if not self.request_warning_sent:
            self.request_warning_sent = True
            self.owner._say(SEVERITY_WARNING, "got MISSION_REQUEST; use MISSION_REQUEST_INT!")
        self.owner._send(reply)

    def poll(self, now_s: float) -> None:
        """Ask again for a lost item, or end an upload that timed out."""
        upload = self.upload
        if upload is None:
            return
        if now_s - upload.last_receive_s > UPLOAD_TIMEOUT_S:
            self.upload = None
            self.owner._say(SEVERITY_WARNING, self.timeout_text)
            self.owner._ack(
                (upload.system_id, upload.component_id), OPERATION_CANCELLED, self.mission_type
            )
            self.end()
            return
        if now_s - upload.last_request_s > REREQUEST_S:
            self._request(now_s)

    def _start_requests(self, source: tuple[int, int], first: int, last: int, now_s: float) -> None:
        self.upload = _Upload(source[0], source[1], first, last, now_s, now_s)
        self.item_warning_sent = False
        self.request_warning_sent = False
        self._request(now_s)

    def _request(self, now_s: float) -> None:
        upload = self.upload
        assert upload is not None
        upload.last_request_s = now_s
        self.owner._send(
            self.owner.mav.mission_request_encode(
                upload.system_id, upload.component_id, upload.next_seq, self.mission_type
            )
        )

    def _transfer_complete(self, source: tuple[int, int]) -> None:
        result = self.complete()
        self.owner._ack(source, result, self.mission_type)
        self.end()
        self.upload = None


class WaypointList(ItemList):
    """The mission (MissionItemProtocol_Waypoints over AP_Mission)."""

    mission_type = MISSION
    timeout_text = "Mission upload timeout"

    def __init__(self, owner: MissionProtocol, max_items: int) -> None:
        super().__init__(owner, max_items)
        self.stored: list[MissionItem] = []  # [0] is a placeholder: home is read live

    def count(self) -> int:
        """How many items are stored (what a download counts)."""
        return len(self.stored)

    def truncate(self, count: int) -> None:
        """Keep the first ``count`` items (replace_item's list shortened at MISSION_COUNT)."""
        if len(self.stored) > count:
            del self.stored[count:]
            self.owner._touch()

    def store(self, item: MissionItem, append: bool) -> int:
        """Store an uploaded item at its seq, or ``append`` it; its MAV_MISSION_RESULT."""
        try:
            stored = stored_mission_item(item, self.owner.firmware)
        except MissionItemError as refused:
            return refused.result
        if stored.command == DO_JUMP:
            target = int(stored.param1)
            upload = self.upload
            last_seq = upload.last_seq if upload is not None else 0
            if (target >= self.count() and target > last_seq) or target == 0:
                return ERROR
        if append:
            self.stored.append(stored)
        else:
            self.stored[item.seq] = stored
        self.owner._touch()
        return ACCEPTED

    def complete(self) -> int:
        """The upload's last item arrived: take the new list; its MAV_MISSION_RESULT."""
        self.owner._say(SEVERITY_INFO, "Flight plan received")
        return ACCEPTED

    def clear_all(self) -> bool:
        """Empty the list (MISSION_CLEAR_ALL); False when it cannot be cleared."""
        self.owner.clear()
        return True

    def get(self, seq: int) -> MissionItem | None:
        """The stored item ``seq``; None when there is none."""
        if seq != 0 and seq >= self.count():
            return None
        item = self.owner._read(seq)
        # ArduPilot marks "current" where the command number equals the current index.
        nav = self.owner._nav_index
        current = 1 if nav is not None and item.command == nav else 0
        return replace(item, current=current)


class FenceList(ItemList):
    """The fence (MissionItemProtocol_Fence over AC_PolyFence_loader): staged, then validated."""

    mission_type = FENCE
    timeout_text = "Fence upload timeout"

    def __init__(self, owner: MissionProtocol, max_items: int) -> None:
        super().__init__(owner, max_items)
        self.stored: list[MissionItem] = []
        self.staged: list[MissionItem | None] | None = None

    def count(self) -> int:
        """How many items are stored (what a download counts)."""
        if self.upload is not None and self.staged is not None:
            return len(self.staged)
        return len(self.stored)

    def begin(self, count: int) -> None:
        """Resources for a new upload of ``count`` items (allocate_receive_resources)."""
        self.staged = [None] * count

    def begin_update(self) -> None:
        """Resources for a partial update (allocate_update_resources)."""
        self.staged = list(self.stored)

    def end(self) -> None:
        """Free what begin() took (free_upload_resources)."""
        self.staged = None

    def truncate(self, count: int) -> None:
        """Keep the first ``count`` items (replace_item's list shortened at MISSION_COUNT)."""
        pass  # the fence is replaced whole when the upload completes

    def store(self, item: MissionItem, append: bool) -> int:
        """Store an uploaded item at its seq, or ``append`` it; its MAV_MISSION_RESULT."""
        if self.staged is None:
            return ERROR
        if item.seq >= len(self.staged):
            return INVALID_SEQUENCE
        try:
            self.staged[item.seq] = fence_item(item)
        except MissionItemError as refused:
            return refused.result
        return ACCEPTED

    def complete(self) -> int:
        """The upload's last item arrived: take the new list; its MAV_MISSION_RESULT."""
        staged = self.staged if self.staged is not None else []
        items = [item for item in staged if item is not None]
        if len(items) != len(staged):
            return ERROR
        problem = fence_problem(items)
        if problem is not None:
            severity = SEVERITY_INFO if problem == "Incorrect item count" else SEVERITY_WARNING
            self.owner._say(severity, problem)
            self.owner._say(SEVERITY_WARNING, "Fence validation failed")
            return ERROR
        self.stored = [replace(item, seq=seq) for seq, item in enumerate(items)]
        self.owner._say(SEVERITY_DEBUG, "Fence Indexed OK")
        self.owner._touch()
        return ACCEPTED

    def clear_all(self) -> bool:
        """Empty the list (MISSION_CLEAR_ALL); False when it cannot be cleared."""
        self.stored = []
        self.owner._say(SEVERITY_DEBUG, "Fence Indexed OK")
        self.owner._touch()
        return True

    def get(self, seq: int) -> MissionItem | None:
        """The stored item ``seq``; None when there is none."""
        return self.stored[seq] if 0 <= seq < len(self.stored) else None


class RallyList(ItemList):
    """The rally points (MissionItemProtocol_Rally over AP_Rally)."""

    mission_type = RALLY
    timeout_text = "Rally upload timeout"

    def __init__(self, owner: MissionProtocol, max_items: int) -> None:
        super().__init__(owner, max_items)
        self.stored: list[MissionItem] = []

    def count(self) -> int:
        """How many items are stored (what a download counts)."""
        return len(self.stored)

    def truncate(self, count: int) -> None:
        """Keep the first ``count`` items (replace_item's list shortened at MISSION_COUNT)."""
        if len(self.stored) > count:
            del self.stored[count:]
            self.owner._touch()

    def store(self, item: MissionItem, append: bool) -> int:
        """Store an uploaded item at its seq, or ``append`` it; its MAV_MISSION_RESULT."""
        try:
            stored = rally_item(item)
        except MissionItemError as refused:
            return refused.result
        if append:
            if len(self.stored) >= self.max_items:
                return ERROR
            self.stored.append(stored)
        else:
            self.stored[item.seq] = stored
        self.owner._touch()
        return ACCEPTED

    def complete(self) -> int:
        """The upload's last item arrived: take the new list; its MAV_MISSION_RESULT."""
        return ACCEPTED  # (4.7 prints nothing)

    def clear_all(self) -> bool:
        """Empty the list (MISSION_CLEAR_ALL); False when it cannot be cleared."""
        self.truncate(0)
        return True

    def get(self, seq: int) -> MissionItem | None:
        """The stored item ``seq``; None when there is none."""
        return self.stored[seq] if 0 <= seq < len(self.stored) else None
