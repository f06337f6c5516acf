"""The autopilot adapter's safety set-up: the ground-station id, each parameter set and read
back, the fence list uploaded, and the answer it gives the runtime.

Two peers. A scripted ArduPilot (below) writes the frames the real firmware writes, as
measured on SITL (docs/sitl-measurements.md, section 5): one PARAM_VALUE echo per
accepted PARAM_SET with the value stored in the parameter's own type (integers truncated
and clamped), silence for an unknown name, "Param write denied" and the old value for an
internal one; MISSION_REQUEST_INT per item and MISSION_ACK for a fence upload. Then the
simulated ArduPilot (clark_engine.sim.ardupilot.autopilot), through the same bytes, with the plan
the runtime makes from real compiled missions: what each firmware ends up holding.
"""

from __future__ import annotations

import math
import struct
import subprocess
import sys
from collections.abc import Iterable
from pathlib import Path
from typing import Any

import pytest
from pymavlink.dialects.v20 import ardupilotmega as mavlink2
from sitl_here import real_install

from clark_engine.dryrun.engine import PHYSICS_STEP_S
from clark_engine.dryrun.world import build_vehicle
from clark_engine.io.autopilot import AutopilotAdapter
from clark_engine.io.autopilot_requests import ACK_TIMEOUT_S, COMMAND_ATTEMPTS
from clark_engine.io.autopilot_settings import AutopilotSettings
from clark_engine.io.autopilot_setup import took
from clark_engine.io.mission_upload import UPLOAD_ATTEMPTS, UPLOAD_SILENCE_S
from clark_engine.mission.compiler import agent_config
from clark_engine.mission.variation import resolve_mission
from clark_engine.runtime.autopilot_safety import safety_setup
from clark_engine.runtime.commands import (
    FenceZone,
    Pause,
    SetParam,
    SetUpAutopilotSafety,
    UploadFence,
)
from clark_engine.runtime.config import config_from_dict
from clark_engine.runtime.events import AutopilotSafetyResult
from clark_engine.sitl.launcher import ENV_SITL
from clark_engine.validation import load_mission

ROOT = Path(__file__).resolve().parent.parent
MODES = {"GUIDED": 4, "LOITER": 5, "RTL": 6, "LAND": 9}
INT8, INT16, INT32, REAL32 = (
    mavlink2.MAV_PARAM_TYPE_INT8,
    mavlink2.MAV_PARAM_TYPE_INT16,
    mavlink2.MAV_PARAM_TYPE_INT32,
    mavlink2.MAV_PARAM_TYPE_REAL32,
)
COPTER_PARAMS = {
    "MAV_GCS_SYSID": (255.0, INT16),
    "RTL_ALT": (1500.0, INT32),
    "FS_GCS_TIMEOUT": (5.0, REAL32),
    "FS_GCS_ENABLE": (0.0, INT8),
    "FENCE_ENABLE": (0.0, INT8),
    "FENCE_TYPE": (7.0, INT8),
    "FENCE_ALT_MAX": (100.0, REAL32),
    "FENCE_RADIUS": (150.0, REAL32),
    "FENCE_ACTION": (1.0, INT8),
    "MIS_TOTAL": (0.0, INT16),
}
"""ArduCopter 4.7's parameters the set-up touches, with their SITL defaults and types."""


SITL = real_install()


def f32(value: float) -> float:
    return float(struct.unpack("<f", struct.pack("<f", value))[0])


class ScriptedArduPilot:
    """ArduPilot's side of the link, answering parameters and fence uploads as measured.

    Attributes:
        params: Name -> (value, MAV_PARAM_TYPE); names absent get no answer.
        denied: Internal parameters: "Param write denied" and the old value.
        silent: When True, nothing is answered (a cable out); heartbeats stop too.
        fence: The fence items stored by the last accepted upload.
        fence_result: The MISSION_ACK result an upload ends with.
        drop_requests: The first this many item requests are never sent (lost on the air).
        heard: Every frame the adapter sent, parsed.
    """

    def __init__(self, params: dict[str, tuple[float, int]] | None = None) -> None:
        self.params = dict(COPTER_PARAMS if params is None else params)
        self.denied = {"MIS_TOTAL"}
        self.silent = False
        self.fence: list[Any] = []
        self.fence_result = mavlink2.MAV_MISSION_ACCEPTED
        self.drop_requests = 0
        self.heard: list[Any] = []
        self.timed: list[tuple[float, Any]] = []
        self.now_s = 0.0
        self.sets: list[tuple[str, float]] = []
        self._out = bytearray()
        self.mav = mavlink2.MAVLink(self, srcSystem=1, srcComponent=1)
        self._parser = mavlink2.MAVLink(None, 1, 1)
        self._upload: list[Any] | None = None
        self._station = (255, 190)

    def write(self, data: bytes) -> None:
        self._out += data

    def take(self) -> bytes:
        data, self._out = bytes(self._out), bytearray()
        return data

    def heartbeat(self) -> None:
        if not self.silent:
            self.mav.heartbeat_send(
                mavlink2.MAV_TYPE_QUADROTOR,
                mavlink2.MAV_AUTOPILOT_ARDUPILOTMEGA,
                mavlink2.MAV_MODE_FLAG_CUSTOM_MODE_ENABLED,
                MODES["GUIDED"],
                mavlink2.MAV_STATE_STANDBY,
            )

    def _value(self, name: str) -> None:
        value, kind = self.params[name]
        self.mav.param_value_send(name.encode(), value, kind, 1354, 65535)

    def hear(self, data: bytes) -> None:
        for msg in self._parser.parse_buffer(data) or []:
            self.heard.append(msg)
            self.timed.append((self.now_s, msg))
            if not self.silent:
                self._answer(msg)

    def _answer(self, msg: Any) -> None:
        kind = msg.get_type()
        self._station = (msg.get_srcSystem(), msg.get_srcComponent())
        if kind == "PARAM_REQUEST_READ" and msg.param_id in self.params:
            self._value(msg.param_id)
        elif kind == "PARAM_SET" and msg.param_id in self.params:
            name = msg.param_id
            self.sets.append((name, msg.param_value))
            if name in self.denied:
                self.mav.statustext_send(
                    mavlink2.MAV_SEVERITY_WARNING, f"Param write denied ({name})".encode()
                )
            else:
                _, kind_ = self.params[name]
                self.params[name] = (self._stored(msg.param_value, kind_), kind_)
            self._value(name)
        elif kind == "MISSION_COUNT" and msg.mission_type == mavlink2.MAV_MISSION_TYPE_FENCE:
            self._upload = []
            if msg.count == 0:
                self.fence = []
                self._ack(self.fence_result)
            else:
                self._request(0)
        elif kind == "MISSION_ITEM_INT" and self._upload is not None:
            self._upload.append(msg)
            if len(self._upload) < self._expected:
                self._request(len(self._upload))
            else:
                if self.fence_result == mavlink2.MAV_MISSION_ACCEPTED:
                    self.fence = self._upload
                self._upload = None
                self._ack(self.fence_result)

    @staticmethod
    def _stored(value: float, kind: int) -> float:
        if kind == REAL32:
            return f32(value)
        limit = {INT8: 127, INT16: 32767, INT32: 2**31 - 1}[kind]
        return float(max(-limit - 1, min(limit, math.trunc(value + math.copysign(0.01, value)))))

    @property
    def _expected(self) -> int:
        counts = [m for m in self.heard if m.get_type() == "MISSION_COUNT"]
        return int(counts[-1].count)

    def _request(self, seq: int) -> None:
        if self.drop_requests > 0:
            self.drop_requests -= 1
            return
        self.mav.mission_request_int_send(*self._station, seq, mavlink2.MAV_MISSION_TYPE_FENCE)

    def _ack(self, result: int) -> None:
        self.mav.mission_ack_send(*self._station, result, mavlink2.MAV_MISSION_TYPE_FENCE)


class Bench:
    """An adapter and the scripted ArduPilot, exchanging bytes every 50 ms of virtual time."""

    def __init__(self, peer: ScriptedArduPilot | None = None, source_system_id: int = 245):
        self.peer = peer or ScriptedArduPilot()
        self.adapter = AutopilotAdapter(
            AutopilotSettings(modes=MODES, firmware="arducopter", source_system_id=source_system_id)
        )
        self.now_s = 0.0
        self.events: list[Any] = []
        self.peer.heartbeat()
        self.events += self.adapter.receive(self.peer.take(), 0.0)
        self.peer.hear(self.adapter.start(0.0))
        self.peer.heard.clear()

    def command(self, command: SetUpAutopilotSafety) -> None:
        self.peer.hear(self.adapter.command(command, self.now_s))

    def run(self, duration_s: float) -> list[AutopilotSafetyResult]:
        for _ in range(round(duration_s / 0.05)):
            self.now_s = self.peer.now_s = round(self.now_s + 0.05, 9)
            if round(self.now_s * 20) % 20 == 0:
                self.peer.heartbeat()
            self.events += self.adapter.receive(self.peer.take(), self.now_s)
            self.peer.hear(self.adapter.poll(self.now_s))
        return self.results

    @property
    def results(self) -> list[AutopilotSafetyResult]:
        return [e for e in self.events if isinstance(e, AutopilotSafetyResult)]

    def sent(self, kind: str) -> list[Any]:
        return [m for m in self.peer.heard if m.get_type() == kind]


def command(*steps: SetParam | UploadFence, close: Iterable[SetParam] = ()) -> SetUpAutopilotSafety:
    return SetUpAutopilotSafety(
        ("MAV_GCS_SYSID", "SYSID_MYGCS"), tuple(steps), tuple(close), "test"
    )


SQUARE = FenceZone(
    True, corners_deg=((30.637, -96.479), (30.637, -96.478), (30.638, -96.478), (30.638, -96.479))
)
POND = FenceZone(False, center_deg=(30.6375, -96.4785), radius_m=20.0)


def test_every_step_is_set_and_read_back_in_order_and_the_fence_uploaded() -> None:
    bench = Bench()
    bench.command(
        command(
            SetParam(("FS_GCS_TIMEOUT",), 5.0),
            SetParam(("FS_GCS_ENABLE",), 1.0),
            SetParam(("FENCE_ENABLE",), 0.0),
            UploadFence((SQUARE, POND)),
            SetParam(("FENCE_TYPE",), 5.0),
            SetParam(("FENCE_ALT_MAX",), 58.3),
            SetParam(("FENCE_ENABLE",), 1.0),
        )
    )
    assert bench.run(2.0) == [AutopilotSafetyResult()]
    # The ground station's id first (read both names, set the one that answers), then
    # each step in order, each once the one before it took.
    reads = [m.param_id for m in bench.sent("PARAM_REQUEST_READ")]
    assert reads == ["MAV_GCS_SYSID", "SYSID_MYGCS"]
    assert bench.peer.sets == [
        ("MAV_GCS_SYSID", 245.0),
        ("FS_GCS_TIMEOUT", 5.0),
        ("FS_GCS_ENABLE", 1.0),
        ("FENCE_ENABLE", 0.0),
        ("FENCE_TYPE", 5.0),
        ("FENCE_ALT_MAX", f32(58.3)),
        ("FENCE_ENABLE", 1.0),
    ]
    assert bench.peer.params["FENCE_ALT_MAX"] == (f32(58.3), REAL32)
    # The fence list: the square's four corners, each with the corner count, the pond.
    fence = [(m.command, m.param1, m.x, m.y, m.frame, m.mission_type) for m in bench.peer.fence]
    inclusion = mavlink2.MAV_CMD_NAV_FENCE_POLYGON_VERTEX_INCLUSION
    assert fence == [
        (inclusion, 4.0, 306370000, -964790000, 0, 1),
        (inclusion, 4.0, 306370000, -964780000, 0, 1),
        (inclusion, 4.0, 306380000, -964780000, 0, 1),
        (inclusion, 4.0, 306380000, -964790000, 0, 1),
        (mavlink2.MAV_CMD_NAV_FENCE_CIRCLE_EXCLUSION, 20.0, 306375000, -964785000, 0, 1),
    ]
    # After FENCE_ENABLE 0 and before FENCE_TYPE: ArduPilot applies a new type only when
    # FENCE_ENABLE changes, so the type goes in while the fence is off.
    order = [
        ("set", m.param_id, m.param_value) if m.get_type() == "PARAM_SET" else (m.get_type(),)
        for m in bench.peer.heard
        if m.get_type() in ("PARAM_SET", "MISSION_COUNT")
    ]
    assert order.index(("MISSION_COUNT",)) == order.index(("set", "FENCE_ENABLE", 0.0)) + 1


def test_the_next_step_is_ready_to_send_as_soon_as_an_answer_arrives() -> None:
    """The shells send what receive() queued at once (flush), not at the next poll."""
    bench = Bench()
    bench.command(command(SetParam(("FENCE_ENABLE",), 0.0)))
    bench.adapter.receive(bench.peer.take(), 0.01)  # MAV_GCS_SYSID read: set it now
    bench.peer.hear(bench.adapter.flush())
    assert bench.peer.sets == [("MAV_GCS_SYSID", 245.0)]
    bench.adapter.receive(bench.peer.take(), 0.02)  # its echo: the heartbeat, the next step
    bench.peer.hear(bench.adapter.flush())
    assert bench.peer.sets == [("MAV_GCS_SYSID", 245.0), ("FENCE_ENABLE", 0.0)]
    assert bench.adapter.flush() == b""  # nothing else waits


def test_a_heartbeat_follows_the_ground_station_id_at_once() -> None:
    """ArduPlane's failsafe clock runs from boot: the new id must be heard before it is on."""
    bench = Bench()
    bench.command(command(SetParam(("FS_GCS_ENABLE",), 1.0)))
    bench.run(1.0)
    kinds = [
        m.get_type() if m.get_type() != "PARAM_SET" else m.param_id
        for m in bench.peer.heard
        if m.get_type() in ("HEARTBEAT", "PARAM_SET")
    ]
    assert kinds.index("MAV_GCS_SYSID") + 1 == kinds.index("HEARTBEAT")
    assert kinds.index("HEARTBEAT") < kinds.index("FS_GCS_ENABLE")
    assert all(m.get_srcSystem() == 245 for m in bench.sent("HEARTBEAT"))


def test_the_older_name_is_used_when_only_it_answers() -> None:
    """ArduPilot before 4.7 calls the ground station's id SYSID_MYGCS; 4.7 does not know it."""
    params = dict(COPTER_PARAMS)
    params["SYSID_MYGCS"] = params.pop("MAV_GCS_SYSID")
    bench = Bench(ScriptedArduPilot(params))
    bench.command(command(SetParam(("FS_GCS_ENABLE",), 1.0)))
    # MAV_GCS_SYSID goes unanswered through the adapter's retries first.
    assert bench.run(ACK_TIMEOUT_S * COMMAND_ATTEMPTS + 1.0) == [AutopilotSafetyResult()]
    assert bench.peer.sets == [("SYSID_MYGCS", 245.0), ("FS_GCS_ENABLE", 1.0)]


def test_a_value_that_did_not_take_names_the_parameter_and_stops_the_set_up() -> None:
    bench = Bench()
    bench.peer.params["FENCE_TYPE"] = (7.0, INT8)
    bench.command(
        command(
            SetParam(("FENCE_ENABLE",), 0.0),
            SetParam(("FENCE_TYPE",), 300.0),  # clamped to the int8's 127
            SetParam(("FENCE_ENABLE",), 1.0),
        )
    )
    (result,) = bench.run(2.0)
    assert result == AutopilotSafetyResult(
        "FENCE_TYPE did not take: reads 127, asked 300", "FENCE_TYPE", retry=False
    )
    assert ("FENCE_ENABLE", 1.0) not in bench.peer.sets  # nothing after the failure


def test_a_refused_write_says_ardupilots_reason() -> None:
    bench = Bench()
    bench.command(command(SetParam(("MIS_TOTAL",), 3.0)))
    (result,) = bench.run(2.0)
    assert (
        result.problem
        == "MIS_TOTAL did not take: reads 0, asked 3 (Param write denied (MIS_TOTAL))"
    )
    assert result.parameter == "MIS_TOTAL"


def test_an_unknown_parameter_fails_after_the_retries_while_the_autopilot_is_heard() -> None:
    bench = Bench()
    bench.command(command(SetParam(("FENCE_ALT_MAX",), 58.0), SetParam(("NO_SUCH_PARAM",), 1.0)))
    assert bench.run(1.0) == []
    (result,) = bench.run(ACK_TIMEOUT_S * COMMAND_ATTEMPTS + 0.5)
    assert result.parameter == "NO_SUCH_PARAM"
    assert result.problem == (
        "NO_SUCH_PARAM did not take: the autopilot did not answer for it (1 asked); "
        "it may have no such parameter"
    )
    assert not result.retry
    assert [m.param_id for m in bench.sent("PARAM_SET")].count("NO_SUCH_PARAM") == COMMAND_ATTEMPTS


def test_a_silent_autopilot_cuts_the_set_up_short_to_be_asked_again() -> None:
    bench = Bench()
    bench.command(command(SetParam(("FENCE_ENABLE",), 0.0), SetParam(("FENCE_TYPE",), 1.0)))
    bench.run(0.05)  # the ground station's id took
    bench.peer.silent = True
    (result,) = bench.run(ACK_TIMEOUT_S * COMMAND_ATTEMPTS + 0.5)
    assert result.retry
    assert result.problem.endswith("; the autopilot fell silent")


def test_a_set_up_under_way_ends_when_the_autopilot_is_heard_again_after_a_loss() -> None:
    bench = Bench()
    bench.peer.drop_requests = 10**6  # the fence upload never gets going
    bench.command(command(UploadFence((SQUARE,))))
    bench.run(0.3)
    bench.peer.silent = True
    bench.run(1.0)
    bench.now_s += 5.0  # longer than the heartbeat timeout: a loss
    bench.peer.silent = False
    bench.run(1.0)  # its next heartbeat
    (result,) = bench.results
    assert result == AutopilotSafetyResult(
        "the autopilot went silent during the set-up", None, retry=True
    )


def test_at_most_keeps_a_value_already_low_enough_and_lowers_one_above() -> None:
    bench = Bench()
    bench.command(command(SetParam(("RTL_ALT",), 5800.0, at_most=True)))
    assert bench.run(1.0) == [AutopilotSafetyResult()]
    assert bench.peer.sets == [("MAV_GCS_SYSID", 245.0)]  # 1500 cm stays: already lower
    bench.peer.params["RTL_ALT"] = (9000.0, INT32)
    bench.command(command(SetParam(("RTL_ALT",), 5800.0, at_most=True)))
    bench.run(1.0)
    assert bench.peer.params["RTL_ALT"] == (5800.0, INT32)


def test_a_pause_holds_the_next_step_back() -> None:
    bench = Bench()
    bench.command(
        command(SetParam(("FENCE_ENABLE",), 0.0), Pause(0.5), SetParam(("FENCE_ENABLE",), 1.0))
    )
    bench.run(2.0)
    times = [
        t
        for t, m in bench.peer.timed
        if m.get_type() == "PARAM_SET" and m.param_id == "FENCE_ENABLE"
    ]
    assert times[1] - times[0] >= 0.5


def test_a_refused_fence_list_says_why() -> None:
    bench = Bench()
    bench.peer.fence_result = mavlink2.MAV_MISSION_NO_SPACE
    bench.command(command(UploadFence((SQUARE,)), SetParam(("FENCE_TYPE",), 4.0)))
    (result,) = bench.run(2.0)
    assert result == AutopilotSafetyResult("the autopilot refused the fence list: NO_SPACE")
    assert ("FENCE_TYPE", 4.0) not in bench.peer.sets


def test_an_empty_fence_list_clears_the_autopilots() -> None:
    bench = Bench()
    bench.peer.fence = ["stale"]
    bench.command(command(UploadFence(())))
    assert bench.run(1.0) == [AutopilotSafetyResult()]
    assert bench.peer.fence == []
    assert [m.count for m in bench.sent("MISSION_COUNT")] == [0]


def test_a_lost_item_request_restarts_the_upload() -> None:
    bench = Bench()
    bench.peer.drop_requests = 1
    bench.command(command(UploadFence((SQUARE,))))
    assert bench.run(UPLOAD_SILENCE_S + 1.0) == [AutopilotSafetyResult()]
    assert len(bench.sent("MISSION_COUNT")) == 2
    assert len(bench.peer.fence) == 4


def test_an_upload_nobody_answers_is_given_up() -> None:
    bench = Bench()
    bench.peer.drop_requests = 10**6
    bench.command(command(UploadFence((SQUARE,))))
    (result,) = bench.run(UPLOAD_SILENCE_S * UPLOAD_ATTEMPTS + 1.0)
    assert result == AutopilotSafetyResult("the fence list upload got no answer")
    assert len(bench.sent("MISSION_COUNT")) == UPLOAD_ATTEMPTS


def test_a_clean_stop_turns_off_the_failsafe_the_set_up_switched_on() -> None:
    bench = Bench()
    bench.command(
        command(SetParam(("FS_GCS_ENABLE",), 1.0), close=[SetParam(("FS_GCS_ENABLE",), 0.0)])
    )
    bench.run(1.0)
    bench.peer.hear(bench.adapter.close(bench.now_s))
    assert bench.peer.sets[-1] == ("FS_GCS_ENABLE", 0.0)


def test_a_failed_set_up_turns_off_only_what_it_switched_on() -> None:
    close = [SetParam(("FS_GCS_ENABLE",), 0.0)]
    bench = Bench()  # the failsafe on, then a parameter that does not exist
    bench.command(
        command(SetParam(("FS_GCS_ENABLE",), 1.0), SetParam(("NO_SUCH_PARAM",), 1.0), close=close)
    )
    bench.run(5.0)
    bench.peer.hear(bench.adapter.close(bench.now_s))
    assert bench.peer.sets[-1] == ("FS_GCS_ENABLE", 0.0)
    bench = Bench()  # failed before the failsafe was switched on: nothing to switch off
    bench.command(
        command(SetParam(("NO_SUCH_PARAM",), 1.0), SetParam(("FS_GCS_ENABLE",), 1.0), close=close)
    )
    bench.run(5.0)
    sets = len(bench.peer.sets)
    bench.peer.hear(bench.adapter.close(bench.now_s))
    assert len(bench.peer.sets) == sets


@pytest.mark.parametrize(
    ("asked", "echoed", "kind", "expected"),
    [
        (2.0, 2.0, INT8, True),
        (300.0, 127.0, INT8, False),  # clamped: not what was asked
        (-2.7, -2.0, INT8, True),  # ArduPilot truncates toward zero
        (58.3, f32(58.3), REAL32, True),
        (58.3, 58.3, REAL32, False),  # a float32 cannot hold 58.3 exactly
        (1.0, 0.0, INT8, False),
        (11800.0, 11800.0, INT32, True),
    ],
)
def test_took_compares_as_the_parameter_stores(
    asked: float, echoed: float, kind: int, expected: bool
) -> None:
    assert took(asked, echoed, kind) is expected


# -- against the simulated ArduPilot ---------------------------------------------------------


@pytest.mark.parametrize(
    ("mission", "agent", "expected"),
    [
        (
            "copter_takeoff_land.yaml",
            "f450",
            {
                "MAV_GCS_SYSID": 255,
                "RTL_ALT": 1500,  # ArduCopter's 15 m, under the ceiling: kept
                "FS_GCS_TIMEOUT": 5,
                "FS_GCS_ENABLE": 1,
                "FENCE_TYPE": 3,  # the ceiling and the circle around home
                "FENCE_ALT_MAX": 120,
                "FENCE_RADIUS": f32(1609.34),
                "FENCE_ACTION": 1,
                "FENCE_ENABLE": 1,
            },
        ),
        (
            "cooperative_follow.yaml",
            "slash_b",
            {
                "MAV_GCS_SYSID": 255,
                "FS_GCS_TIMEOUT": 5,
                "FS_ACTION": 2,
                "FS_GCS_ENABLE": 1,
                "FENCE_TYPE": 2,  # a rover: the circle only
                "FENCE_ACTION": 2,
                "FENCE_ENABLE": 1,
            },
        ),
        (
            "supercub_sysid.yaml",
            "cub",
            {
                "MAV_GCS_SYSID": 255,
                "FS_LONG_TIMEOUT": 5,
                "FS_LONG_ACTN": 1,
                "FS_GCS_ENABL": 1,
                "FENCE_TYPE": 3,
                "FENCE_ACTION": 1,
                "FENCE_ENABLE": 1,
            },
        ),
    ],
)
def test_the_simulated_autopilot_holds_what_the_runtime_planned(
    mission: str, agent: str, expected: dict[str, float]
) -> None:
    # Includes resolved, then the world it declares drawn (as a dry run of seed 1 does).
    resolved, _ = resolve_mission(load_mission(str(ROOT / "missions" / mission)), seed=1)
    config = config_from_dict(agent_config(resolved, resolved.agents[agent]))
    backend, _pilot = build_vehicle(resolved, resolved.agents[agent], config, seed=1)
    adapter = AutopilotAdapter(AutopilotSettings.from_config(config))
    events: list[Any] = []
    backend.send(adapter.start(0.0), 0.0)
    plan: SetUpAutopilotSafety | None = None
    for i in range(1, 1200):  # 60 s: a vehicle on the ground gets its home after ~20 s
        now = round(i * PHYSICS_STEP_S, 9)
        events += adapter.receive(backend.step(now, PHYSICS_STEP_S), now)
        if plan is None and adapter.status.home is not None:
            plan = safety_setup(config, adapter.status.home)
            backend.send(adapter.command(plan, now), now)
        backend.send(adapter.poll(now), now)
        if any(isinstance(e, AutopilotSafetyResult) for e in events):
            break
    assert [e for e in events if isinstance(e, AutopilotSafetyResult)] == [AutopilotSafetyResult()]
    sim = backend.autopilot
    held = {name: sim.param(name) for name in expected}
    assert held == pytest.approx(expected)
    assert sim.missions.fence_items == ()  # no zones declared: the default circle only
    # What a return altitude above the ceiling becomes: the ceiling less the margin.
    assert config.envelope is not None
    if config.firmware == "arduplane":
        ceiling_above_home_m = config.envelope.ceiling_m - (
            adapter.status.home[2] - config.origin_alt_amsl_m  # type: ignore[index]
        )
        assert sim.param("RTL_ALTITUDE") == min(
            100.0, math.floor(ceiling_above_home_m - config.envelope.margin_m)
        )


ZONED = """
clark: 1
mission: {id: 3, name: zoned, loop_hz: 10, origin: {lat: 30.6372, lon: -96.4787, alt_amsl_m: 90}}
envelope:
  ceiling_m: 60
  geofence:
    include: [{polygon: [[-50, -50], [200, -50], [200, 200], [-50, 200]]}]
    exclude: [{circle: {center: [100, 100], radius_m: 20}}]
agents:
  f450:
    id: 2
    profile: dji_f450
    telemetry: {heartbeat: 1}
    launch: {armed_by: engine}
    behavior: {use: wait}
sim: {duration_s: 40}
"""


def test_the_simulated_autopilot_takes_declared_zones(tmp_path: Path) -> None:
    path = tmp_path / "zoned.yaml"
    path.write_text(ZONED, encoding="utf-8")
    resolved = load_mission(str(path))
    agent = resolved.agents["f450"]
    config = config_from_dict(agent_config(resolved, agent))
    backend, _pilot = build_vehicle(resolved, agent, config, seed=1)
    adapter = AutopilotAdapter(AutopilotSettings.from_config(config))
    results: list[AutopilotSafetyResult] = []
    backend.send(adapter.start(0.0), 0.0)
    asked = False
    for i in range(1, 1200):
        now = round(i * PHYSICS_STEP_S, 9)
        events = adapter.receive(backend.step(now, PHYSICS_STEP_S), now)
        results += [e for e in events if isinstance(e, AutopilotSafetyResult)]
        backend.send(adapter.flush(), now)
        if not asked and adapter.status.home is not None:
            asked = True
            backend.send(adapter.command(safety_setup(config, adapter.status.home), now), now)
        backend.send(adapter.poll(now), now)
        if results:
            break
    assert results == [AutopilotSafetyResult()]
    sim = backend.autopilot
    stored = [(item.command, item.param1) for item in sim.missions.fence_items]
    assert stored == [(mavlink2.MAV_CMD_NAV_FENCE_POLYGON_VERTEX_INCLUSION, 4.0)] * 4 + [
        (mavlink2.MAV_CMD_NAV_FENCE_CIRCLE_EXCLUSION, 20.0)
    ]
    assert sim.param("FENCE_TYPE") == 5  # the ceiling and the zones; no circle around home
    assert sim.param("FENCE_ALT_MAX") == pytest.approx(60.0, abs=0.5)


@pytest.mark.sitl
@pytest.mark.skipif(SITL is None, reason=f"no ArduPilot SITL: set {ENV_SITL} to its folder")
def test_arducopter_sitl_takes_the_set_up_with_declared_zones(tmp_path: Path) -> None:
    """Real ArduCopter accepts the fence items as the engine writes them, and each value."""
    assert SITL is not None
    path = tmp_path / "zoned.yaml"
    path.write_text(ZONED, encoding="utf-8")
    run = subprocess.run(
        [
            sys.executable, "-m", "clark_engine", "dry-run", str(path), "--autopilot", "sitl",
            "--sitl", str(SITL.folder), "--until", "30", "--report", str(tmp_path / "report"),
        ],
        cwd=ROOT, capture_output=True, text=True, timeout=600, check=False,
    )  # fmt: skip
    interface = (tmp_path / "report" / "logs" / "f450.interface.log").read_text(encoding="utf-8")
    assert "answers: ArduPilot 4." in interface, run.stdout + run.stderr
    assert "safety set-up: fence list of 5 item(s) accepted" in interface
    assert "safety set-up: FENCE_TYPE = 5 (read back)" in interface
    assert "safety set-up: every parameter took" in interface
