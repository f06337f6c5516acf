"""ArduPilot's mission protocol, for the simulated autopilot to delegate to.

:class:`MissionProtocol` answers the MAVLink mission sub-protocol (upload, download,
partial update, clear, current item) for the three item lists ArduPilot keeps: the
mission, the fence and the rally points. It also keeps the mission's execution
cursor (AP_Mission's state and current navigation command), because what a ground
station reads back (MISSION_CURRENT, a download's ``current`` flag, what
MISSION_SET_CURRENT does) depends on it.

It is pure and deterministic: no clock, no socket. The autopilot hands it messages
with :meth:`MissionProtocol.handle` and calls :meth:`MissionProtocol.poll` as time
passes, both with the virtual time; replies are encoded with the autopilot's own
pymavlink ``MAVLink`` object (so they carry its ids and sequence numbers) and
STATUSTEXTs go through the autopilot's ``text`` callable, after the MAVLink replies
of the same step, in the order ArduPilot's queues deliver them.

What it follows was measured on ArduPilot SITL (4.7.0-dev, 90700977, the build in
``../shared/ardupilot-sitl``: copter, plane and rover), and read in ArduPilot's
MissionItemProtocol.cpp, MissionItemProtocol_{Waypoints,Fence,Rally}.cpp,
AP_Mission.cpp and AC_PolyFence_loader.cpp where SITL agreed:

- **Upload**: MISSION_COUNT is answered with MISSION_REQUEST (#40, never
  MISSION_REQUEST_INT), item by item, each request sent as the previous item is
  stored. The list is truncated to the new count as soon as MISSION_COUNT arrives
  (a failed upload leaves the old items beyond what was replaced). The end is
  MISSION_ACK ACCEPTED, then INFO "Flight plan received" (missions), DEBUG "Fence
  Indexed OK" (fences), nothing (rally points). MISSION_COUNT 0 is the same at once.
  An item whose seq is not the one requested: MISSION_ACK INVALID_SEQUENCE, the
  upload goes on. An item or MISSION_COUNT from another system or component during
  an upload: DENIED, the upload goes on; from the uploader, a new MISSION_COUNT
  restarts it. An item ArduPilot refuses (unsupported command or frame, NaN or
  infinite parameter, latitude, longitude or altitude out of range, a DO_JUMP to
  nowhere) ends the upload with that MAV_MISSION_RESULT. More items than storage:
  NO_SPACE and WARNING "Only N items are supported" (ending an upload under way;
  650 mission items on
  ArduCopter, 655 on ArduPlane and ArduRover; fences 70/84; rally points 46/50).
  A legacy MISSION_ITEM is taken (its float latitude and longitude multiplied in
  float32 as ArduPilot does) with WARNING "got MISSION_ITEM; GCS should send
  MISSION_ITEM_INT" once per upload (outside an upload too, with its ERROR).
- **Lost items**: the pending MISSION_REQUEST is sent again once more than 1 s
  passed since the last one; more than 8 s after the last item (or the
  MISSION_COUNT) the upload ends with MISSION_ACK OPERATION_CANCELLED to the
  uploader and WARNING "Mission upload timeout" ("Fence upload timeout", "Rally
  upload timeout"). Measured: requests at +0, 0.96, 2.0, 2.96, ... 6.96 s, the
  cancel at +8.0 s; an item at 7.5 s moves the deadline to 15.5 s.
- **Download**: MISSION_REQUEST_LIST gives MISSION_COUNT (missions: including
  home, 0 until home is set and after a clear). MISSION_REQUEST_INT gives
  MISSION_ITEM_INT; item 0 is always readable and is the current home (frame 0,
  z the home altitude above mean sea level; zeros before home is set). A seq out
  of range gives MISSION_COUNT (to tell the ground station the real size) and
  MISSION_ACK INVALID_SEQUENCE; the legacy MISSION_REQUEST gives MISSION_ITEM
  (float32 degrees), or only the ACK when out of range, with WARNING "got
  MISSION_REQUEST; use MISSION_REQUEST_INT!" once until the next upload. Requests
  during an upload: DENIED. Items come back as ArduPilot stores them, which is
  lossy: each command keeps only some parameters, as integers of a given width,
  altitudes in whole centimetres, frames folded to 0, 3 or 10, autocontinue 1
  (see ``_COMMANDS``, checked against a sweep of every MAV_CMD on SITL); and
  ``current`` is 1 on every item whose *command number* equals the current
  navigation index (ArduPilot compares the command id with the index).
- **Clear**: MISSION_CLEAR_ALL gives MISSION_ACK ACCEPTED and leaves 0 items
  (not 1: home comes back at the next home change). It stops a running mission.
  During an upload, from the uploader it cancels the upload and clears; from
  anyone else it is answered DENIED and then ERROR and the upload goes on.
- **Partial update** (MISSION_WRITE_PARTIAL_LIST): requests start..end; a range
  beyond the list is MISSION_ACK ERROR and WARNING "Flight plan update rejected".
- **Current item**: MISSION_SET_CURRENT is answered with MISSION_CURRENT at once
  (carrying the seq asked for; 0 becomes 1 in the state), nothing when out of
  range. Setting the current item follows AP_Mission::set_current_cmd: it lands on
  the first navigation command at or after the seq, and a stopped or complete
  mission becomes stopped there.
- **MISSION_CURRENT** (seq, total, mission_state, mission_mode): total counts items
  without home; no items: (0, 0, 1, m); otherwise state 2 stopped (also just after
  an upload, seq 0), 3 running, 5 complete, which stays after AUTO is left
  (ArduCopter (2, 2, 5, 0)) and after a new upload; mission_mode is 1 in AUTO.
- **Mission types**: fence (1) and rally (2) are kept apart and never touch the
  mission. A fence is validated when complete as AC_PolyFence_loader does (ERROR
  and its WARNINGs, "Fence validation failed"; the old fence stays). Any other
  type: MISSION_ACK UNSUPPORTED to lists, counts, clears and items, and silence to
  requests.
- **Execution** (AP_Mission): start, resume, stop, reset, advance and DO_JUMP
  counting, with INFO "Mission: N <name>" as each command starts.

Not simulated: MAVLink 1 links (fences and rally points need MAVLink 2; every peer
here speaks it), the request resend slowing down on a congested link, the fence
storage-size check, MAV_CMD_DO_SET_RESUME_REPEAT_DIST's rewinding, the
vehicle-specific start and verify of commands (the autopilot does those; DO
commands are taken to finish at once, so a CONDITION_* item only affects when its
"Mission:" text is printed).

Three modules: this one is the front (the messages dispatched to a list, MISSION_CURRENT, and
AP_Mission's execution cursor); :mod:`~clark_engine.sim.ardupilot.mission_lists` holds the
three lists and the transfer state machine each runs;
:mod:`~clark_engine.sim.ardupilot.mission_items` what an item is, what ArduPilot refuses and
how it stores each command.
"""

from __future__ import annotations

import enum
from collections.abc import Callable, Mapping
from dataclasses import replace
from typing import Any, Final

from pymavlink.dialects.v20 import ardupilotmega as mavlink2

from clark_engine.sim.ardupilot.mission_items import (
    CENTI,
    DO_JUMP,
    ERROR,
    FENCE,
    MISSION,
    RALLY,
    SEVERITY_INFO,
    SEVERITY_WARNING,
    UNSUPPORTED,
    MissionItem,
    MissionItemError,
    command_name,
    f32,
)
from clark_engine.sim.ardupilot.mission_lists import (
    ITEM_LIMITS,
    FenceList,
    ItemLimits,
    ItemList,
    RallyList,
    WaypointList,
)

_JUMP_REPEAT_FOREVER: Final = -1
_JUMP_TIMES_MAX: Final = 32767
_MAX_JUMP_COMMANDS: Final = 100
"""AP_MISSION_MAX_NUM_DO_JUMP_COMMANDS on boards with SITL's memory class."""


class MissionState(enum.IntEnum):
    """AP_Mission's state, numbered as MISSION_CURRENT reports it (MISSION_STATE)."""

    STOPPED = int(mavlink2.MISSION_STATE_NOT_STARTED)
    RUNNING = int(mavlink2.MISSION_STATE_ACTIVE)
    COMPLETE = int(mavlink2.MISSION_STATE_COMPLETE)


class MissionProtocol:
    """ArduPilot's mission, fence and rally point lists and their MAVLink protocol.

    Args:
        mav: The autopilot's pymavlink ``MAVLink`` object; replies are encoded and sent
            with it (``mav.send``), so they carry the autopilot's ids.
        home: Home as (latitude deg, longitude deg, altitude above mean sea level m),
            None before it is set; read whenever item 0 is read, as ArduPilot reads it.
        text: Sends a STATUSTEXT (severity, text), as the autopilot's own texts go.
        firmware: ``arducopter``, ``arduplane`` or ``ardurover`` (storage limits, and
            how ArduPlane stores waypoints).
        in_auto: Whether the vehicle is in AUTO now; only for the MISSION_CURRENT sent at
            once after MISSION_SET_CURRENT (None: never in AUTO).
        limits: Storage limits instead of the firmware's.

    Raises:
        ValueError: Unknown firmware.
    """

    def __init__(
        self,
        mav: Any,
        home: Callable[[], tuple[float, float, float] | None],
        text: Callable[[int, str], None],
        *,
        firmware: str = "arducopter",
        in_auto: Callable[[], bool] | None = None,
        limits: ItemLimits | None = None,
    ) -> None:
        if firmware not in ITEM_LIMITS:
            raise ValueError(f"unknown firmware {firmware!r}; use one of {sorted(ITEM_LIMITS)}")
        self.mav = mav
        self.firmware = firmware
        self._home = home
        self._text = text
        self._in_auto = in_auto
        limits = limits if limits is not None else ITEM_LIMITS[firmware]
        self._waypoints = WaypointList(self, limits.mission)
        self._fence = FenceList(self, limits.fence)
        self._rally = RallyList(self, limits.rally)
        self._lists: dict[int, ItemList] = {
            MISSION: self._waypoints,
            FENCE: self._fence,
            RALLY: self._rally,
        }
        self._texts: list[tuple[int, str]] = []
        # AP_Mission's execution cursor.
        self._state = MissionState.STOPPED
        self._nav_index: int | None = None
        self._nav_loaded = False
        self._do_index: int | None = None
        self._do_loaded = False
        self._do_all_done = False
        self._jumps: dict[int, int] = {}  # DO_JUMP index -> times run
        self._started: list[MissionItem] = []

        self.changed = 0
        """Counts every change of the stored lists, the current item or the mission state;
        the autopilot compares it with the value it last saw to know when to look again."""

    # -- the stored lists -----------------------------------------------------------------------

    @property
    def items(self) -> tuple[MissionItem, ...]:
        """The mission as stored (what a download returns), item 0 the current home."""
        return tuple(self._read(seq) for seq in range(self._waypoints.count()))

    @property
    def count(self) -> int:
        """Mission items including home, as MISSION_COUNT reports them (0 when empty)."""
        return self._waypoints.count()

    @property
    def fence_items(self) -> tuple[MissionItem, ...]:
        """The fence as stored (never used for flying here)."""
        return tuple(self._fence.stored)

    @property
    def rally_items(self) -> tuple[MissionItem, ...]:
        """The rally points as stored (never used for flying here)."""
        return tuple(self._rally.stored)

    def receiving(self, mission_type: int = MISSION) -> bool:
        """Whether an upload of ``mission_type`` is under way."""
        items = self._lists.get(mission_type)
        return items is not None and items.receiving

    def write_home(self) -> None:
        """Home was set (AP_Mission::write_home_to_storage): an empty mission gets item 0.

        Call it wherever ArduPilot sets home (when it first gets one, DO_SET_HOME, a
        copter's arming, a rover's disarming): a mission cleared or emptied by
        MISSION_COUNT 0 counts 0 items until then, 1 after (measured).
        """
        if not self._waypoints.stored:
            self._waypoints.stored.append(self._home_item())
            self._touch()

    def clear(self) -> None:
        """Empty the mission as MISSION_CLEAR_ALL does: no items, stopped, no current item."""
        self._waypoints.stored.clear()
        self._state = MissionState.STOPPED
        self._nav_index = None
        self._do_index = None
        self._nav_loaded = self._do_loaded = False
        self._touch()

    # -- messages ----------------------------------------------------------------------------

    def handle(self, msg: Any, now_s: float) -> bool:
        """Act on a mission-protocol message and answer its sender; False if it is not one.

        A MISSION_ITEM(_INT) of the mission with ``current`` 2 or 3 (a guided-mode target
        or altitude change) is the autopilot's (False), during an upload too, as in
        ArduPilot. Call it with messages already addressed to this autopilot.
        """
        kind = msg.get_type()
        handler = self._handlers.get(kind)
        if handler is None:
            return False
        handled = handler(self, msg, now_s)
        self._flush()
        return handled

    def poll(self, now_s: float) -> None:
        """Re-request a missing item, or give an upload up, as time passes."""
        for items in self._lists.values():
            items.poll(now_s)
        self._flush()

    def _on_item(self, msg: Any, now_s: float) -> bool:
        legacy = msg.get_type() == "MISSION_ITEM"
        mission_type = int(msg.mission_type)
        source = (msg.get_srcSystem(), msg.get_srcComponent())
        try:
            item = (
                MissionItem.from_mission_item(msg)
                if legacy
                else MissionItem.from_mission_item_int(msg)
            )
        except MissionItemError as refused:
            self._ack(source, refused.result, mission_type)
            return True
        if mission_type == MISSION and item.current in (2, 3):
            return False
        items = self._lists.get(mission_type)
        if items is None:
            self._ack(source, UNSUPPORTED, mission_type)
            return True
        if legacy and not items.item_warning_sent:  # (outside an upload too: measured)
            items.item_warning_sent = True
            self._say(SEVERITY_WARNING, "got MISSION_ITEM; GCS should send MISSION_ITEM_INT")
        if not items.receiving:
            self._ack(source, ERROR, mission_type)
        else:
            items.handle_item(msg, item, now_s)
        return True

    def _on_count(self, msg: Any, now_s: float) -> bool:
        items = self._supported_list(msg)
        if items is not None:
            items.handle_count(msg, int(msg.count), now_s)
        return True

    def _on_partial(self, msg: Any, now_s: float) -> bool:
        items = self._supported_list(msg)
        if items is not None:
            items.handle_partial(msg, int(msg.start_index), int(msg.end_index), now_s)
        return True

    def _on_clear_all(self, msg: Any, now_s: float) -> bool:
        items = self._supported_list(msg)
        if items is not None:
            items.handle_clear_all(msg)
        return True

    def _on_request_list(self, msg: Any, now_s: float) -> bool:
        items = self._supported_list(msg)
        if items is not None:
            items.handle_request_list(msg)
        return True

    def _supported_list(self, msg: Any) -> ItemList | None:
        """The list ``msg``'s mission_type names; None (answered UNSUPPORTED) for another type."""
        items = self._lists.get(int(msg.mission_type))
        if items is None:
            self._unsupported(msg)
        return items

    def _on_request(self, msg: Any, now_s: float) -> bool:
        items = self._lists.get(int(msg.mission_type))
        if items is not None:  # other types: no answer at all (measured)
            items.handle_request(msg, legacy=msg.get_type() == "MISSION_REQUEST")
        return True

    def _on_set_current(self, msg: Any, now_s: float) -> bool:
        seq = int(msg.seq)
        self._started = []
        if self._set_current(seq):
            # No ack for this message: ArduPilot sends MISSION_CURRENT at once, with the
            # seq asked for (0 stays 0 there, though the mission goes to 1).
            in_auto = self._in_auto() if self._in_auto is not None else False
            _, total, state, mode = self.mission_current(in_auto)
            self._send(self.mav.mission_current_encode(seq, total, state, mode))
        return True

    def _on_ack(self, msg: Any, now_s: float) -> bool:
        return True  # a ground station's MISSION_ACK needs nothing from ArduPilot

    _handlers: Final[Mapping[str, Callable[[MissionProtocol, Any, float], bool]]] = {
        "MISSION_ITEM": _on_item,
        "MISSION_ITEM_INT": _on_item,
        "MISSION_COUNT": _on_count,
        "MISSION_WRITE_PARTIAL_LIST": _on_partial,
        "MISSION_CLEAR_ALL": _on_clear_all,
        "MISSION_REQUEST_LIST": _on_request_list,
        "MISSION_REQUEST_INT": _on_request,
        "MISSION_REQUEST": _on_request,
        "MISSION_SET_CURRENT": _on_set_current,
        "MISSION_ACK": _on_ack,
    }

    def _unsupported(self, msg: Any) -> None:
        source = (msg.get_srcSystem(), msg.get_srcComponent())
        self._ack(source, UNSUPPORTED, int(msg.mission_type))

    # -- execution (AP_Mission) -----------------------------------------------------------------

    @property
    def state(self) -> MissionState:
        """AP_Mission's state: stopped, running or complete."""
        return self._state

    @property
    def current(self) -> int:
        """The current navigation command's seq as MISSION_CURRENT reports it (0: none)."""
        return 0 if self._nav_index is None else self._nav_index

    @property
    def nav_item(self) -> MissionItem | None:
        """The navigation command being flown (or to resume at), None if there is none."""
        if self._nav_index is None or self._nav_index >= self._waypoints.count():
            return None
        return self._read(self._nav_index)

    def mission_current(self, auto_active: bool) -> tuple[int, int, int, int]:
        """MISSION_CURRENT's (seq, total, mission_state, mission_mode), as ArduPilot fills it.

        ``total`` leaves home out; no items reports (0, 0, 1, mode); mission_mode is 1
        while the vehicle is in AUTO (``auto_active``), whatever the mission's state.
        Measured: (0, 0, 1, 0) empty, (0, N, 2, 0) just uploaded, (n, N, 3, 1) flying,
        (N, N, 5, 1) complete, which stays 5 out of AUTO and across a new upload.
        """
        total = max(self._waypoints.count() - 1, 0)
        state = int(mavlink2.MISSION_STATE_NO_MISSION) if total == 0 else int(self._state)
        return self.current, total, state, 1 if auto_active else 0

    def set_current(self, seq: int) -> bool:
        """Make ``seq`` the current item (AP_Mission::set_current_cmd); False if refused.

        Used for MISSION_SET_CURRENT and MAV_CMD_DO_SET_MISSION_CURRENT (the autopilot
        answers that one ACCEPTED or DENIED, then sends MISSION_CURRENT). Refused beyond
        the list or with home alone; 0 means 1; the index lands on the first navigation
        command at or after ``seq``. A running mission starts that command ("Mission: N
        ..." texts; :attr:`started` lists what started); a stopped or complete one
        becomes stopped there, to resume from it.
        """
        self._started = []
        done = self._set_current(seq)
        self._flush()
        return done

    def start(self) -> list[MissionItem]:
        """Start the mission from its first command (AP_Mission::start; AUTO with MIS_RESTART).

        Returns:
            The commands started, in order (a DO command before the first navigation
            command, that navigation command, the DO commands between), empty when the
            mission has nothing to fly: it is then complete.
        """
        self._started = []
        self._start()
        self._flush()
        return list(self._started)

    def resume(self) -> list[MissionItem]:
        """Go on from where the mission stopped (AP_Mission::resume; AUTO entered).

        A complete mission, or one with no current command or one beyond a shorter new
        mission, starts again from its first command; otherwise the current command
        starts again ("Mission: N WP" on re-entering AUTO, as measured).

        Returns:
            The commands started, as :meth:`start`.
        """
        self._started = []
        if self._state == MissionState.COMPLETE:
            self._start()
        else:
            self._state = MissionState.RUNNING
            nav = self._nav_index
            if nav is None or nav >= self.count:
                self._start()
            elif self._do_loaded and self._do_index is not None:
                self._set_current(self._do_index)
            elif self._nav_loaded:
                self._set_current(nav)
            self._touch()
        self._flush()
        return list(self._started)

    def stop(self) -> None:
        """Stop a running mission where it is (leaving AUTO); a complete one stays complete."""
        if self._state == MissionState.RUNNING:
            self._state = MissionState.STOPPED
            self._touch()

    def reset(self) -> None:
        """Forget the current command (AP_Mission::reset; ArduCopter does it at disarming)."""
        self._nav_index = None
        self._do_index = None
        self._nav_loaded = self._do_loaded = self._do_all_done = False
        self._jumps.clear()
        self._touch()

    def advance(self) -> MissionItem | None:
        """The current navigation command is done: start the next one (AP_Mission::update).

        DO_JUMP items are followed and counted as ArduPilot counts them.

        Returns:
            The navigation command now current, or None when the mission is complete
            (its state is then complete; the vehicle's own end-of-mission behaviour and
            texts are the autopilot's). :attr:`started` lists every command started.
        """
        self._started = []
        if self._state != MissionState.RUNNING:
            return None
        self._nav_loaded = False
        if self._advance_nav(0):
            self._run_do_commands()
        else:
            self._complete()
        self._flush()
        return self.nav_item if self._state == MissionState.RUNNING else None

    @property
    def started(self) -> tuple[MissionItem, ...]:
        """The commands the last start, resume, advance or set_current started, in order."""
        return tuple(self._started)

    def _set_current(self, seq: int) -> bool:
        total = self._waypoints.count()
        if seq < 0 or seq >= total or total == 1:
            return False
        self._do_index = None
        self._do_loaded = self._do_all_done = self._nav_loaded = False
        index = seq
        if index == 0 or self._state == MissionState.COMPLETE:
            self._jumps.clear()
            index = max(index, 1)
        self._touch()
        if self._state == MissionState.RUNNING:
            if self._advance_nav(index):
                self._run_do_commands()
                return True
            self._complete()
            return False
        # Stopped or complete: move the index only, to resume from there.
        while not self._nav_loaded:
            item = self._next_command(index, increment=True)
            if item is None:
                self._nav_index = None
                return False
            if item.is_nav:
                self._nav_index = item.seq
                self._nav_loaded = True
            elif not self._do_loaded:
                self._do_index = item.seq
                self._do_loaded = True
            index = item.seq + 1
        self._do_all_done = not self._do_loaded
        self._state = MissionState.STOPPED
        return True

    def _start(self) -> None:
        self._state = MissionState.RUNNING
        self._nav_index = None
        self._do_index = None
        self._nav_loaded = self._do_loaded = self._do_all_done = False
        self._jumps.clear()
        if not self._advance_nav(0):
            self._complete()
        else:
            self._run_do_commands()
        self._touch()

    def _complete(self) -> None:
        self._state = MissionState.COMPLETE
        self._touch()

    def _start_command(self, item: MissionItem) -> None:
        self._say(SEVERITY_INFO, f"Mission: {item.seq} {command_name(item.command)}")
        self._started.append(item)

    def _advance_nav(self, starting_index: int) -> bool:
        """AP_Mission::advance_current_nav_cmd: find, load and start the next nav command."""
        if self._state != MissionState.RUNNING or self._nav_loaded:
            return False
        self._do_index = None
        self._do_loaded = False
        self._do_all_done = False
        if starting_index > 0:
            index = starting_index
        elif self._nav_index is None:
            index = 1
        else:
            index = self._nav_index + 1
        loops_left = 255
        while not self._nav_loaded:
            item = self._next_command(index, increment=True)
            if item is None:
                return False
            if item.is_nav:
                self._nav_index = item.seq
                self._start_command(item)
                self._nav_loaded = True
            elif not self._do_loaded:
                self._do_index = item.seq
                self._do_loaded = True
                self._start_command(item)
            else:
                if loops_left == 0:
                    return False
                loops_left -= 1
            index = item.seq + 1
        if not self._do_loaded:
            self._do_all_done = True
        self._touch()
        return True

    def _run_do_commands(self) -> None:
        """The DO commands between the current one and the navigation command, each done at once."""
        while self._state == MissionState.RUNNING and not self._do_all_done:
            index = 1 if self._do_index is None else self._do_index + 1
            item = self._next_command(index, increment=False) if index < self.count else None
            if item is None or item.is_nav:
                self._do_all_done = True
                self._do_loaded = False
                return
            self._do_index = item.seq
            self._do_loaded = True
            self._start_command(item)

    def _next_command(self, start: int, increment: bool) -> MissionItem | None:
        """AP_Mission::get_next_cmd: the first non-jump command at or after ``start``."""
        index = start
        jump_index: int | None = None
        loops_left = 64
        total = self._waypoints.count()
        while index < total:
            item = self._read(index)
            if item.command != DO_JUMP:
                return item
            if loops_left == 0:
                return None
            loops_left -= 1
            target, times = int(item.param1), int(item.param2)
            if target >= total or target == 0:
                return None
            if not increment and jump_index == index:
                return None
            if jump_index is None:
                jump_index = index
            if times == _JUMP_REPEAT_FOREVER:
                index = target
                continue
            run = self._jump_times_run(index)
            if run < times:
                if increment:
                    self._jumps[index] = run + 1
                    self._say(SEVERITY_INFO, f"Mission: {index} Jump {run + 1}/{times}")
                index = target
            else:
                index += 1
        return None

    def _jump_times_run(self, index: int) -> int:
        if index in self._jumps:
            return self._jumps[index]
        if len(self._jumps) >= _MAX_JUMP_COMMANDS:
            return _JUMP_TIMES_MAX
        self._jumps[index] = 0
        return 0

    # -- plumbing ---------------------------------------------------------------------------

    def _home_item(self) -> MissionItem:
        """Item 0 as AP_Mission reads it: the AHRS's home, frame 0, altitude in cm."""
        home = self._home()
        if home is None:
            x, y, z = 0, 0, 0.0
        else:
            lat_deg, lon_deg, alt_m = home
            x, y = round(lat_deg * 1e7), round(lon_deg * 1e7)
            z = f32(round(alt_m * 100.0) * CENTI)
        return MissionItem(0, 0, 16, 0, 1, 0.0, 0.0, 0.0, 0.0, x, y, z, MISSION)

    def _read(self, seq: int) -> MissionItem:
        if seq == 0:
            return self._home_item()
        return replace(self._waypoints.stored[seq], seq=seq)

    def _touch(self) -> None:
        self.changed += 1

    def _send(self, msg: Any) -> None:
        self.mav.send(msg)

    def _ack(self, target: tuple[int, int], result: int, mission_type: int) -> None:
        self._send(self.mav.mission_ack_encode(target[0], target[1], result, mission_type))

    def _say(self, severity: int, text: str) -> None:
        """A STATUSTEXT, sent after this step's MAVLink replies (ArduPilot queues its texts)."""
        self._texts.append((severity, text))

    def _flush(self) -> None:
        texts, self._texts = self._texts, []
        for severity, text in texts:
            self._text(severity, text)
