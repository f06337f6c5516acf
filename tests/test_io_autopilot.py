"""The autopilot adapter against the simulated ArduPilot, over every transport backend.

The contract tests run twice, through a parametrised fixture: over an in-memory
pipe (as the dry run drives it) and over UDP on 127.0.0.1 (as a real link or
SITL does). Time is virtual throughout; the UDP link waits only until the bytes
it knows it sent have arrived, so both backends see the same conversation.
"""

from __future__ import annotations

import logging
import math
import os
import random
import select
import socket
from collections.abc import Iterator, Mapping
from pathlib import Path
from typing import Any

import pytest
import yaml
from fake_vehicle import FakeModelHooks, RcServoBook
from hypothesis import given, settings
from hypothesis import strategies as st
from pymavlink.dialects.v20 import ardupilotmega as mavlink2

from clark_engine.io.autopilot import AutopilotAdapter
from clark_engine.io.autopilot_decode import (
    AutopilotEvent,
    AutopilotMessage,
    ParamValue,
    gps_time_ms_from_unix_us,
)
from clark_engine.io.autopilot_flight import POSITION_ONLY_TYPE_MASK, POSITION_VELOCITY_TYPE_MASK
from clark_engine.io.autopilot_requests import ACK_TIMEOUT_S, COMMAND_ATTEMPTS, REASON_WAIT_S
from clark_engine.io.autopilot_settings import AutopilotSettings
from clark_engine.io.transports import (
    MemoryPipe,
    SerialTransport,
    TcpTransport,
    Transport,
    TransportError,
    UdpTransport,
    open_transport,
    parse_address,
)
from clark_engine.runtime.commands import (
    CloseInterfaces,
    Goto,
    PayloadCommand,
    RcOverride,
    SendPacket,
    SetMode,
    SetServo,
)
from clark_engine.runtime.config import ConfigError, load_config
from clark_engine.runtime.events import AutopilotHeartbeat, CommandRefused, RcChannels, VehicleState
from clark_engine.sim.ardupilot.autopilot import SimAutopilot
from clark_engine.sim.ardupilot.vehicle_model import Truth, VehicleModel

ROOT = Path(__file__).resolve().parent.parent
HOME = (30.6319, -96.4826, 90.0)
START_UNIX_US = 1_700_000_000_123_456  # 2023-11-14 22:13:20.123456 UTC
STEP_S = 0.05
BOOTED_S = 100.0  # how long before time 0 the simulated autopilots powered on


def profile(name: str) -> dict[str, Any]:
    with (ROOT / "hardware_profiles" / "autopilots" / f"{name}.yaml").open(encoding="utf-8") as f:
        data: dict[str, Any] = yaml.safe_load(f)
    return data


PLANE_MODES: dict[str, int] = profile("pixhawk_arduplane")["modes"]
COPTER_MODES: dict[str, int] = profile("pixhawk_arducopter")["modes"]
ROVER_MODES: dict[str, int] = profile("pixhawk_ardurover")["modes"]
MODES = {"arduplane": PLANE_MODES, "arducopter": COPTER_MODES, "ardurover": ROVER_MODES}
METRES_PER_DEG = 111_320.0


class FakeModel(FakeModelHooks, RcServoBook, VehicleModel):
    """A kinematic point: flies straight at the guided target at its speed, nothing else."""

    def __init__(self, modes: Mapping[str, int], *, mode: str = "MANUAL") -> None:
        self.modes = dict(modes)
        self.mode = mode
        self.armed = False
        self.north_m = self.east_m = self.up_m = 0.0
        self.velocity_m_s = (0.0, 0.0, 0.0)
        self.target: tuple[float, float, float] | None = None
        self.speed_m_s = 10.0
        self.gotos: list[tuple[float, float, float, float | None]] = []
        self.loiters: list[tuple[float, bool]] = []
        FakeModelHooks.__init__(self)
        RcServoBook.__init__(self, pilot={3: 1100}, servo_count=16)
        self.roll_deg, self.pitch_deg, self.yaw_deg = 5.0, -2.0, 30.0

    def guided_loiter(self, radius_m: float, ccw: bool) -> None:
        """ArduPlane's DO_REPOSITION loiter radius and direction, as received."""
        self.loiters.append((radius_m, ccw))

    def _cos(self) -> float:
        return math.cos(math.radians(HOME[0]))

    def step(self, dt_s: float) -> None:
        self.velocity_m_s = (0.0, 0.0, 0.0)
        if self.mode != "GUIDED" or self.target is None:
            return
        lat, lon, alt = self.target
        dn = (lat - HOME[0]) * METRES_PER_DEG - self.north_m
        de = (lon - HOME[1]) * METRES_PER_DEG * self._cos() - self.east_m
        du = alt - self.up_m
        distance = math.sqrt(dn * dn + de * de + du * du)
        if distance < 1e-9:
            return
        k = min(1.0, self.speed_m_s * dt_s / distance)
        self.north_m += dn * k
        self.east_m += de * k
        self.up_m += du * k
        self.velocity_m_s = (dn * k / dt_s, de * k / dt_s, du * k / dt_s)

    def truth(self) -> Truth:
        vn, ve, vu = self.velocity_m_s
        speed = math.hypot(vn, ve)
        course = math.degrees(math.atan2(ve, vn)) % 360.0 if speed else self.yaw_deg
        return Truth(
            north_m=self.north_m,
            east_m=self.east_m,
            up_m=self.up_m,
            lat_deg=HOME[0] + self.north_m / METRES_PER_DEG,
            lon_deg=HOME[1] + self.east_m / (METRES_PER_DEG * self._cos()),
            velocity_north_m_s=vn,
            velocity_east_m_s=ve,
            climb_rate_m_s=vu,
            roll_deg=self.roll_deg,
            pitch_deg=self.pitch_deg,
            yaw_deg=self.yaw_deg,
            ground_speed_m_s=speed,
            heading_deg=course,
            airspeed_m_s=speed,
            throttle_pct=40.0,
        )

    def set_mode(self, mode: str) -> bool:
        if mode not in self.modes:
            return False
        self.mode = mode
        return True

    def set_speed(self, speed_m_s: float) -> None:
        self.speed_m_s = speed_m_s

    def goto(self, lat_deg: float, lon_deg: float, alt_m: float, speed_m_s: float | None) -> bool:
        self.target = (lat_deg, lon_deg, alt_m)
        self.gotos.append((lat_deg, lon_deg, alt_m, speed_m_s))
        if speed_m_s:
            self.speed_m_s = speed_m_s
        return True


class Link:
    """Two transport ends and the bytes in flight to each, so a receive can wait for them."""

    def __init__(self, engine: Transport, vehicle: Transport) -> None:
        self.engine, self.vehicle = engine, vehicle
        self._in_flight = {id(engine): 0, id(vehicle): 0}

    def send(self, end: Transport, data: bytes) -> None:
        other = self.vehicle if end is self.engine else self.engine
        self._in_flight[id(other)] += end.send(data)

    def receive(self, end: Transport) -> bytes:
        chunks = [end.receive()]
        got = len(chunks[0])
        fd = end.fileno()
        for _ in range(100):  # at most ~1 s, only if loopback is slow to deliver
            if got >= self._in_flight[id(end)] or fd is None:
                break
            select.select([fd], [], [], 0.01)
            chunks.append(end.receive())
            got += len(chunks[-1])
        self._in_flight[id(end)] -= got
        return b"".join(chunks)

    def close(self) -> None:
        self.engine.close()
        self.vehicle.close()


def make_link(kind: str) -> Link:
    if kind == "memory":
        engine, vehicle = MemoryPipe.pair()
        return Link(engine, vehicle)
    # The engine listens, as the profile's udp address says; the vehicle sends to it.
    listener = UdpTransport(bind=("127.0.0.1", 0))
    return Link(listener, UdpTransport(bind=("127.0.0.1", 0), remote=listener.address))


class Bench:
    """One adapter and one simulated autopilot on a link, stepped on a virtual clock."""

    def __init__(
        self,
        link: Link,
        *,
        firmware: str = "arduplane",
        system_id: int = 1,
        start_time_unix_us: int | None = START_UNIX_US,
    ) -> None:
        self.link = link
        modes = MODES[firmware]
        self.model = FakeModel(modes)
        self.sim = SimAutopilot(
            self.model,
            firmware=firmware,
            system_id=system_id,
            origin_lat_deg=HOME[0],
            origin_lon_deg=HOME[1],
            origin_alt_amsl_m=HOME[2],
            start_time_unix_us=start_time_unix_us,
            boot_s=-BOOTED_S,  # powered on long ago: ready, as the contract tests assume
        )
        self.adapter = AutopilotAdapter(
            AutopilotSettings(
                modes=modes, firmware=firmware, system_id=system_id, origin_alt_amsl_m=HOME[2]
            )
        )
        self.now_s = 0.0
        self.events: list[tuple[float, AutopilotEvent]] = []
        self.truths: dict[float, Truth] = {}
        self.link.send(link.engine, self.adapter.start(0.0))

    def step(self, *, poll: bool = True, vehicle: bool = True) -> list[AutopilotEvent]:
        self.now_s = round(self.now_s + STEP_S, 9)
        self.model.step(STEP_S)
        incoming = self.link.receive(self.link.vehicle)
        if vehicle:
            self.sim.receive(incoming, self.now_s)
            self.link.send(self.link.vehicle, self.sim.advance(self.now_s))
        self.truths[self.now_s] = self.model.truth()
        events = self.adapter.receive(self.link.receive(self.link.engine), self.now_s)
        self.events.extend((self.now_s, e) for e in events)
        if poll:
            self.link.send(self.link.engine, self.adapter.poll(self.now_s))
        return events

    def run(self, duration_s: float, **kwargs: bool) -> list[AutopilotEvent]:
        events: list[AutopilotEvent] = []
        for _ in range(round(duration_s / STEP_S)):
            events += self.step(**kwargs)
        return events

    def send(self, data: bytes) -> None:
        self.link.send(self.link.engine, data)

    def command(self, *commands: Any) -> None:
        for cmd in commands:
            self.send(self.adapter.command(cmd, self.now_s))

    def of(self, kind: type[Any], since_s: float = -1.0) -> list[Any]:
        return [e for t, e in self.events if isinstance(e, kind) and t > since_s]


@pytest.fixture(params=["memory", "udp"])
def backend(request: pytest.FixtureRequest) -> str:
    return str(request.param)


@pytest.fixture
def links(backend: str) -> Iterator[list[Link]]:
    made: list[Link] = []
    yield made
    for link in made:
        link.close()


@pytest.fixture
def bench_for(backend: str, links: list[Link]) -> Any:
    def build(**kwargs: Any) -> Bench:
        link = make_link(backend)
        links.append(link)
        return Bench(link, **kwargs)

    return build


@pytest.fixture
def bench(bench_for: Any) -> Bench:
    b: Bench = bench_for()
    b.run(2.5)  # over UDP the first requests find no peer yet; retries within 1 s
    return b


# -- the contract: every backend ----------------------------------------------------------


def test_connection_is_verified(bench: Bench) -> None:
    assert bench.adapter.verified
    assert bench.adapter.problem is None
    assert bench.adapter.flight_sw_version == "4.7.0"
    assert not bench.adapter.lost(bench.now_s)
    assert (255, 191) in bench.sim.gcs_peers
    assert bench.of(AutopilotHeartbeat)[-1] == AutopilotHeartbeat("MANUAL", 0, False)


def test_streams_come_at_the_profiles_rate(bench: Bench) -> None:
    since = bench.now_s
    bench.run(2.0)
    states = bench.of(VehicleState, since)
    assert len(states) in (20, 21)  # 10 Hz
    assert len(bench.of(RcChannels, since)) in (20, 21)
    assert bench.adapter.latest("SERVO_OUTPUT_RAW") is not None
    assert bench.adapter.latest("GPS_RAW_INT") is not None
    assert bench.adapter.latest("SYS_STATUS") is not None
    assert not bench.of(CommandRefused)


def test_vehicle_state_fields(bench: Bench) -> None:
    bench.command(SetMode("GUIDED", 15))
    bench.send(bench.adapter.arm(True, bench.now_s))
    bench.command(Goto(HOME[0] + 0.003, HOME[1], 30.0, 8.0))  # due north, climbing
    bench.run(3.0)
    time_s, state = next((t, e) for t, e in reversed(bench.events) if isinstance(e, VehicleState))
    truth = bench.truths[time_s]  # what the autopilot sampled
    assert truth.ground_speed_m_s > 5.0
    assert state.lat_deg == pytest.approx(truth.lat_deg, abs=1e-7)
    assert state.lon_deg == pytest.approx(truth.lon_deg, abs=1e-7)
    assert state.alt_m == pytest.approx(truth.up_m, abs=1e-3)
    assert state.ground_speed_m_s == pytest.approx(truth.ground_speed_m_s, abs=1e-3)
    assert state.climb_rate_m_s == pytest.approx(truth.climb_rate_m_s, abs=1e-3)
    assert state.heading_deg == pytest.approx(0.0, abs=0.5) or state.heading_deg > 359.5
    assert (state.roll_deg, state.pitch_deg, state.yaw_deg) == pytest.approx(
        (5.0, -2.0, 30.0), abs=1e-4
    )
    assert (state.mode, state.custom_mode, state.armed) == ("GUIDED", 15, True)
    # GPS time: SYSTEM_TIME's Unix time moved to GPS time, exact to the millisecond.
    assert state.gps_time_ms == gps_time_ms_from_unix_us(START_UNIX_US) + round(time_s * 1000)


def test_heading_is_yaw_at_rest(bench: Bench) -> None:
    state = bench.of(VehicleState)[-1]
    assert state.ground_speed_m_s == 0.0
    assert state.heading_deg == pytest.approx(30.0, abs=1e-4)


def test_gps_time_is_none_without_gps_time(bench_for: Any) -> None:
    bench = bench_for(start_time_unix_us=None)
    bench.run(2.0)
    states = bench.of(VehicleState)
    assert states
    assert all(s.gps_time_ms is None for s in states)


@pytest.mark.parametrize("firmware", ["arduplane", "arducopter", "ardurover"])
def test_goto_sets_the_guided_target(bench_for: Any, firmware: str) -> None:
    bench = bench_for(firmware=firmware)
    bench.run(2.5)
    bench.command(SetMode("GUIDED", MODES[firmware]["GUIDED"]), Goto(30.6329, -96.4816, 25.0))
    bench.run(0.5)
    assert bench.model.mode == "GUIDED"
    lat, lon, alt, _speed = bench.model.gotos[-1]
    assert (lat, lon, alt) == pytest.approx((30.6329, -96.4816, 25.0), abs=1e-7)
    assert not bench.of(CommandRefused)


def test_a_plane_goto_carries_its_loiter_radius_and_direction(bench: Bench) -> None:
    # DO_REPOSITION param3 (radius; 0: ArduPlane keeps its own) and param4 (NaN: clockwise)
    bench.command(SetMode("GUIDED", MODES["arduplane"]["GUIDED"]), Goto(30.6329, -96.4816, 25.0))
    bench.run(0.5)
    bench.command(Goto(30.6329, -96.4816, 25.0, None, None, None, 120.0, True))
    bench.run(0.5)
    assert bench.model.loiters == [(0.0, False), (120.0, True)]
    assert len(bench.model.gotos) == 2 and not bench.of(CommandRefused)


def test_goto_speed_is_sent_once_per_change(bench: Bench) -> None:
    bench.command(SetMode("GUIDED", 15), Goto(HOME[0] + 0.001, HOME[1], 20.0, 12.0))
    bench.run(0.5)
    assert bench.model.speed_m_s == 12.0
    gotos = len(bench.model.gotos)
    bench.command(Goto(HOME[0] + 0.002, HOME[1], 20.0, 12.0))  # same speed: no DO_CHANGE_SPEED
    bench.run(0.5)
    assert len(bench.model.gotos) == gotos + 1


def test_goto_outside_guided_is_ignored_as_by_arducopter(bench_for: Any) -> None:
    bench = bench_for(firmware="arducopter")
    bench.run(2.5)
    bench.command(Goto(30.6329, -96.4816, 25.0))
    bench.run(0.5)
    assert bench.model.gotos == []


def test_goto_outside_guided_is_refused_by_arduplane(bench: Bench) -> None:
    bench.command(Goto(30.6329, -96.4816, 25.0))
    bench.run(1.0)  # a refusal waits REASON_WAIT_S for ArduPilot's reason
    assert bench.model.gotos == []
    refused = bench.of(CommandRefused)
    assert refused[-1].command == "MAV_CMD_DO_REPOSITION"
    assert refused[-1].result == "FAILED"


def test_set_mode_changes_the_mode(bench: Bench) -> None:
    since = bench.now_s
    bench.command(SetMode("LOITER", 12))
    bench.run(1.5)
    assert bench.model.mode == "LOITER"
    assert bench.of(AutopilotHeartbeat, since)[-1].mode == "LOITER"
    assert bench.of(VehicleState, since)[-1].mode == "LOITER"


def test_refused_command_is_reported(bench: Bench) -> None:
    bench.command(SetMode("NO_SUCH_MODE", 99))
    bench.run(1.0)  # a refusal waits REASON_WAIT_S for ArduPilot's reason, and has it
    assert bench.of(CommandRefused) == [
        CommandRefused(
            "MAV_CMD_DO_SET_MODE", "FAILED", "SetMode NO_SUCH_MODE (99)", "No such mode 99"
        )
    ]
    assert bench.model.mode == "MANUAL"


def test_set_servo(bench: Bench) -> None:
    bench.command(SetServo(9, 1700))
    bench.run(0.5)
    assert bench.model.servos[8] == 1700
    assert bench.adapter.latest("SERVO_OUTPUT_RAW")["servo9_raw"] == 1700  # type: ignore[index]


def test_arm_and_disarm(bench: Bench) -> None:
    bench.send(bench.adapter.arm(True, bench.now_s))
    bench.run(1.5)
    assert bench.model.armed
    assert bench.of(AutopilotHeartbeat)[-1].armed
    bench.send(bench.adapter.arm(False, bench.now_s))
    bench.run(1.5)
    assert not bench.model.armed


def test_rc_override_applied_kept_alive_and_released(bench: Bench) -> None:
    bench.command(RcOverride({1: 1600, 10: 1200}))
    bench.run(0.5)
    assert bench.model.rc_inputs()[0] == 1600
    assert bench.model.rc_inputs()[9] == 1200
    assert bench.of(RcChannels)[-1].pwm_us[:3] == (1600, 0, 1100)
    bench.run(8.0)  # well past RC_OVERRIDE_TIME: poll refreshes every 0.5 s
    assert bench.model.overrides == {1: 1600, 10: 1200}
    bench.command(RcOverride({1: 0}))  # channels 1-8 release with 0
    bench.run(0.5)
    assert bench.model.overrides == {10: 1200}
    bench.command(RcOverride({10: 0}))  # channels 9-18 release with UINT16_MAX - 1
    bench.run(0.5)
    assert bench.model.overrides == {}
    assert bench.adapter.active_overrides == {}


def test_rc_override_times_out_without_poll(bench: Bench) -> None:
    bench.command(RcOverride({2: 1700}))
    bench.run(0.5, poll=False)
    assert bench.model.overrides == {2: 1700}
    bench.run(3.5, poll=False)  # ArduPilot's RC_OVERRIDE_TIME is 3 s
    assert bench.model.overrides == {}


def test_close_releases_overrides(bench: Bench) -> None:
    bench.command(RcOverride({1: 1600, 12: 1300}))
    bench.run(0.5)
    bench.send(bench.adapter.close(bench.now_s))
    bench.run(0.1, poll=False)
    assert bench.model.overrides == {}


def test_param_get_and_set(bench: Bench) -> None:
    bench.send(bench.adapter.param_request("RC_OVERRIDE_TIME", bench.now_s))
    bench.run(0.5)
    value = bench.of(ParamValue)[-1]
    assert (value.name, value.value, value.param_type) == (
        "RC_OVERRIDE_TIME",
        3.0,
        mavlink2.MAV_PARAM_TYPE_REAL32,
    )
    assert value.index == 65535  # ArduPilot's index for an answer by name
    bench.send(bench.adapter.param_set("WP_RADIUS", 120, bench.now_s))
    bench.run(0.5)
    assert bench.of(ParamValue)[-1].name == "WP_RADIUS"
    assert bench.of(ParamValue)[-1].value == 120.0
    assert bench.sim.param("WP_RADIUS") == 120.0


def test_unanswered_param_is_reported_after_retries(bench: Bench) -> None:
    bench.send(bench.adapter.param_request("NO_SUCH_PARAM", bench.now_s))
    bench.run(ACK_TIMEOUT_S * COMMAND_ATTEMPTS + 0.5)
    assert bench.of(CommandRefused)[-1] == CommandRefused(
        "PARAM_REQUEST_READ", "NO_ANSWER", "read NO_SUCH_PARAM"
    )


def test_request_message(bench: Bench) -> None:
    bench.send(bench.adapter.request_message("HOME_POSITION", bench.now_s))
    bench.run(0.5)
    (answer,) = bench.of(AutopilotMessage)
    assert answer.name == "HOME_POSITION"
    assert answer.fields["latitude"] == round(HOME[0] * 1e7)
    assert answer.fields["altitude"] == round(HOME[2] * 1000)


def test_lost_after_silence_and_set_up_again(bench: Bench) -> None:
    bench.run(3.5, vehicle=False)  # the autopilot says nothing
    assert bench.adapter.lost(bench.now_s)
    bench.sim.receive(b"", bench.now_s)
    bench.run(2.5)  # heard again: verified anew, streams asked for again
    assert not bench.adapter.lost(bench.now_s)
    assert bench.adapter.verified
    since = bench.now_s
    bench.run(1.0)
    assert len(bench.of(VehicleState, since)) >= 9


def test_reboot_is_noticed_and_streams_asked_for_again(
    bench: Bench, caplog: pytest.LogCaptureFixture
) -> None:
    since = bench.now_s
    # The autopilot reboots: a new boot clock, default streams, no memory of our requests.
    bench.sim = SimAutopilot(
        bench.model,
        firmware="arduplane",
        origin_lat_deg=HOME[0],
        origin_lon_deg=HOME[1],
        origin_alt_amsl_m=HOME[2],
        start_time_unix_us=START_UNIX_US,
        boot_s=bench.now_s,
    )
    with caplog.at_level(logging.WARNING):
        bench.run(12.0)  # as ArduPlane: streams after 2.5 s, positions after its GPS fix
    assert "rebooted; setting it up again" in caplog.text  # the boot clock ran backwards
    assert bench.adapter.verified
    recent = bench.now_s - 1.0
    assert len(bench.of(VehicleState, recent)) in (10, 11)  # 10 Hz again, not the default 4
    assert len(bench.of(VehicleState, since)) > 0


def test_other_commands_are_not_the_autopilots(bench: Bench) -> None:
    for cmd in (CloseInterfaces(), SendPacket(b"x"), PayloadCommand("camera", "capture", 1)):
        assert bench.adapter.command(cmd, bench.now_s) == b""


def test_two_benches_in_one_process_are_independent(bench_for: Any) -> None:
    first: Bench = bench_for(system_id=1)
    second: Bench = bench_for(system_id=2, firmware="arducopter")
    for _ in range(50):
        first.step()
        second.step()
    first.command(SetMode("GUIDED", 15), RcOverride({1: 1900}))
    second.command(SetMode("LOITER", 5))
    for _ in range(20):
        first.step()
        second.step()
    assert (first.model.mode, second.model.mode) == ("GUIDED", "LOITER")
    assert first.model.overrides == {1: 1900}
    assert second.model.overrides == {}
    assert first.adapter.verified and second.adapter.verified
    assert first.of(VehicleState)[-1].mode == "GUIDED"
    assert second.of(VehicleState)[-1].mode == "LOITER"
    assert second.of(AutopilotHeartbeat)[-1].custom_mode == 5


# -- the adapter alone: parsing -------------------------------------------------------------


def sim_stream(system_id: int = 1, seconds: float = 1.5) -> bytes:
    model = FakeModel(PLANE_MODES)
    sim = SimAutopilot(
        model,
        firmware="arduplane",
        system_id=system_id,
        origin_lat_deg=HOME[0],
        origin_lon_deg=HOME[1],
        start_time_unix_us=START_UNIX_US,
        boot_s=-BOOTED_S,
    )
    return b"".join(sim.advance(i * 0.25) for i in range(round(seconds / 0.25) + 1))


def fresh_adapter(system_id: int = 1) -> AutopilotAdapter:
    return AutopilotAdapter(
        AutopilotSettings(modes=PLANE_MODES, firmware="arduplane", system_id=system_id)
    )


def test_any_chunking_gives_the_same_events() -> None:
    stream = sim_stream()
    stream = stream[:150] + b"\x00garbage\xfe\x01" + stream[150:] + b"\xfd\x05\x00"
    whole = fresh_adapter().receive(stream, 1.0)
    assert any(isinstance(e, VehicleState) for e in whole)
    for offset in range(len(stream) + 1):
        adapter = fresh_adapter()
        split = adapter.receive(stream[:offset], 1.0) + adapter.receive(stream[offset:], 1.0)
        assert split == whole, offset
    adapter = fresh_adapter()
    one_by_one = [e for i in range(len(stream)) for e in adapter.receive(stream[i : i + 1], 1.0)]
    assert one_by_one == whole


def test_garbage_never_raises_and_is_counted() -> None:
    rng = random.Random(7)
    adapter = fresh_adapter()
    for _ in range(50):
        adapter.receive(bytes(rng.randrange(256) for _ in range(1000)), 0.0)
    assert adapter.bad_frames > 0
    good = sim_stream(seconds=2.0)
    events = adapter.receive(b"\x00" * 300 + good, 1.0)  # resynchronises on good frames
    assert any(isinstance(e, AutopilotHeartbeat) for e in events)


@settings(max_examples=200, deadline=None)
@given(st.binary(max_size=600), st.integers(min_value=0, max_value=600))
def test_fuzzed_bytes_never_raise(junk: bytes, cut: int) -> None:
    adapter = fresh_adapter()
    stream = sim_stream()
    adapter.receive(stream[:cut] + junk + stream[cut:], 1.0)


def test_corrupted_frame_is_dropped_not_misread() -> None:
    stream = bytearray(sim_stream())
    stream[20] ^= 0xFF  # inside the first frame (a HEARTBEAT): its checksum fails
    adapter = fresh_adapter()
    events = adapter.receive(bytes(stream), 1.0)
    assert adapter.bad_frames >= 1
    assert all(e.mode == "MANUAL" for e in events if isinstance(e, AutopilotHeartbeat))


def test_a_parser_failure_is_contained(caplog: pytest.LogCaptureFixture) -> None:
    adapter = fresh_adapter()

    class Broken:
        def parse_buffer(self, data: bytes) -> None:
            raise IndexError("a pymavlink bug")

    adapter._parser = Broken()
    with caplog.at_level(logging.ERROR):
        assert adapter.receive(b"\xfd\x09", 0.0) == []
    assert "parser failed" in caplog.text
    assert any(isinstance(e, AutopilotHeartbeat) for e in adapter.receive(sim_stream(), 1.0))


def test_messages_from_other_systems_are_ignored() -> None:
    ours, theirs = sim_stream(system_id=1), sim_stream(system_id=2)
    adapter = fresh_adapter(system_id=1)
    gcs = mavlink2.MAVLink(None, 255, 190)
    ground_station = gcs.heartbeat_encode(6, 8, 0, 0, 4).pack(gcs)
    events = adapter.receive(theirs + ground_station + ours + theirs, 1.0)
    alone = fresh_adapter(system_id=1).receive(ours, 1.0)
    assert events == alone
    assert adapter.foreign_messages > 0


def test_wrong_firmware_is_not_verified() -> None:
    adapter = AutopilotAdapter(AutopilotSettings(modes=COPTER_MODES, firmware="arducopter"))
    adapter.start(0.0)
    adapter.receive(sim_stream(), 0.5)  # a plane's heartbeat
    assert adapter.problem is not None and "arducopter" in adapter.problem
    assert not adapter.verified


def test_unknown_mode_number_is_named() -> None:
    adapter = AutopilotAdapter(AutopilotSettings(modes={"MANUAL": 1}))
    (beat,) = [e for e in adapter.receive(sim_stream(), 0.0) if isinstance(e, AutopilotHeartbeat)][
        :1
    ]
    assert beat.mode == "UNKNOWN_0"


def test_no_state_before_heartbeat_and_attitude() -> None:
    frames = mavlink2.MAVLink(None, 1, 1)
    position = frames.global_position_int_encode(0, 1, 2, 3, 4, 5, 6, 7, 8).pack(frames)
    assert fresh_adapter().receive(position, 0.0) == []


# -- the adapter alone: encoding --------------------------------------------------------------


def decode(data: bytes) -> list[Any]:
    parser = mavlink2.MAVLink(None)
    return parser.parse_buffer(data) or []


def test_start_sends_heartbeat_streams_and_version_request() -> None:
    adapter = fresh_adapter()
    messages = decode(adapter.start(0.0))
    heartbeat = messages[0]
    assert heartbeat.get_type() == "HEARTBEAT"
    assert (heartbeat.type, heartbeat.autopilot) == (
        mavlink2.MAV_TYPE_GCS,
        mavlink2.MAV_AUTOPILOT_INVALID,
    )
    assert (heartbeat.get_srcSystem(), heartbeat.get_srcComponent()) == (255, 191)
    intervals = {
        mavlink2.mavlink_map[int(m.param1)].msgname: m.param2
        for m in messages
        if m.get_type() == "COMMAND_LONG" and m.command == mavlink2.MAV_CMD_SET_MESSAGE_INTERVAL
    }
    # what the loop needs at the stream rate; clock, health, readiness and raw GPS slower
    assert intervals == {
        "GLOBAL_POSITION_INT": 100_000.0,
        "ATTITUDE": 100_000.0,
        "VFR_HUD": 100_000.0,
        "RC_CHANNELS": 100_000.0,
        "SYSTEM_TIME": 1_000_000.0,
        "SYS_STATUS": 1_000_000.0,
        "SERVO_OUTPUT_RAW": 500_000.0,
        "GPS_RAW_INT": 500_000.0,
        "EKF_STATUS_REPORT": 1_000_000.0,  # readiness
        "EXTENDED_SYS_STATE": 1_000_000.0,  # landed or flying
    }
    version = [m for m in messages if getattr(m, "command", None) == 512]
    assert version[0].param1 == mavlink2.MAVLINK_MSG_ID_AUTOPILOT_VERSION


def test_goto_frames() -> None:
    copter = AutopilotAdapter(AutopilotSettings(modes=COPTER_MODES, firmware="arducopter"))
    copter.start(0.0)
    (target,) = decode(copter.command(Goto(30.1234567, -96.7654321, 42.5), 1.0))
    assert target.get_type() == "SET_POSITION_TARGET_GLOBAL_INT"
    # Above sea level: the origin's alt_amsl_m (0 here) plus the height above the origin.
    assert target.coordinate_frame == mavlink2.MAV_FRAME_GLOBAL_INT
    assert target.type_mask == POSITION_ONLY_TYPE_MASK == 0x0DF8
    assert (target.lat_int, target.lon_int, target.alt) == (301234567, -967654321, 42.5)
    assert (target.target_system, target.target_component, target.time_boot_ms) == (1, 1, 1000)
    # The speed after the target: ArduRover refuses a speed before its guided target.
    target, speed = decode(copter.command(Goto(30.0, -96.0, 10.0, 7.5), 1.0))
    assert target.get_type() == "SET_POSITION_TARGET_GLOBAL_INT"
    assert (speed.command, speed.param1, speed.param2, speed.param3) == (178, 1, 7.5, -1)
    # A moving target carries its velocity (ArduCopter moves it on with it).
    (moving,) = decode(copter.command(Goto(30.0, -96.0, 10.0, 7.5, 1.5, -2.0), 1.0))
    assert moving.type_mask == POSITION_VELOCITY_TYPE_MASK == 0x0DC0
    assert (moving.vx, moving.vy, moving.vz) == (1.5, -2.0, 0.0)
    plane = AutopilotAdapter(
        AutopilotSettings(modes=PLANE_MODES, firmware="arduplane", origin_alt_amsl_m=90.0)
    )
    plane.start(0.0)
    (reposition,) = decode(plane.command(Goto(30.1234567, -96.7654321, 42.5), 1.0))
    assert (reposition.get_type(), reposition.command) == ("COMMAND_INT", 192)
    assert (reposition.frame, reposition.x, reposition.y, reposition.z) == (
        mavlink2.MAV_FRAME_GLOBAL_INT,
        301234567,
        -967654321,
        132.5,
    )
    assert reposition.param2 == 0  # no mode change: the runtime owns the mode


def test_rc_override_frame_values() -> None:
    adapter = fresh_adapter()
    (frame,) = decode(adapter.command(RcOverride({3: 1400, 9: 1234}), 0.0))
    values = [getattr(frame, f"chan{i}_raw") for i in range(1, 19)]
    assert values == [65535, 65535, 1400, 65535, 65535, 65535, 65535, 65535, 1234] + [65535] * 9
    (frame,) = decode(adapter.command(RcOverride({3: 0, 9: 0}), 0.5))
    values = [getattr(frame, f"chan{i}_raw") for i in range(1, 19)]
    assert values[2] == 0 and values[8] == 65534
    assert set(values[:2] + values[3:8] + values[9:]) == {65535}
    assert adapter.active_overrides == {}


def test_rc_override_out_of_range_is_ignored(caplog: pytest.LogCaptureFixture) -> None:
    adapter = fresh_adapter()
    with caplog.at_level(logging.ERROR):
        assert adapter.command(RcOverride({19: 1500, 2: 70000}), 0.0) == b""
    assert "outside" in caplog.text


def test_set_mode_uses_the_profiles_number(caplog: pytest.LogCaptureFixture) -> None:
    adapter = fresh_adapter()
    with caplog.at_level(logging.WARNING):
        (frame,) = decode(adapter.command(SetMode("GUIDED", 4), 0.0))
    assert (frame.command, frame.param1, frame.param2) == (176, 1, 15)
    assert "profile says 15" in caplog.text


def test_command_retries_count_confirmation_then_give_up() -> None:
    adapter = fresh_adapter()
    adapter.start(0.0)
    first = decode(adapter.command(SetServo(5, 1500), 0.0))[0]
    sends = [first] + [
        m
        for t in (1.0, 2.0, 3.0)
        for m in decode(adapter.poll(t))
        if getattr(m, "command", None) == mavlink2.MAV_CMD_DO_SET_SERVO
    ]
    assert [m.confirmation for m in sends] == [0, 1, 2]
    assert adapter.receive(b"", 3.0) == [
        CommandRefused("MAV_CMD_DO_SET_SERVO", "NO_ANSWER", "SetServo 5 1500 us")
    ]


def test_ack_for_another_ground_station_is_not_ours() -> None:
    adapter = fresh_adapter()
    adapter.start(0.0)
    adapter.command(SetServo(5, 1500), 0.0)
    mav = mavlink2.MAVLink(None, 1, 1)
    theirs = mav.command_ack_encode(183, mavlink2.MAV_RESULT_FAILED, 0, 0, 254, 190).pack(mav)
    assert adapter.receive(theirs, 0.1) == []
    ours = mav.command_ack_encode(183, mavlink2.MAV_RESULT_DENIED, 0, 0, 255, 191).pack(mav)
    assert adapter.receive(ours, 0.2) == []  # reported once its reason had time to come
    assert adapter.receive(b"", 0.2 + REASON_WAIT_S) == [
        CommandRefused("MAV_CMD_DO_SET_SERVO", "DENIED", "SetServo 5 1500 us")
    ]


def test_old_firmware_gets_request_data_stream() -> None:
    adapter = fresh_adapter()
    adapter.start(0.0)
    mav = mavlink2.MAVLink(None, 1, 1)
    beat = mav.heartbeat_encode(1, 3, 1, 0, 3).pack(mav)
    refusal = mav.command_ack_encode(511, mavlink2.MAV_RESULT_UNSUPPORTED, 0, 0, 255, 191)
    adapter.receive(beat + refusal.pack(mav), 0.1)
    events = adapter.receive(b"", 0.1 + REASON_WAIT_S)
    assert events[-1] == CommandRefused(
        "MAV_CMD_SET_MESSAGE_INTERVAL", "UNSUPPORTED", "stream GLOBAL_POSITION_INT every 100000 us"
    )
    (request,) = [m for m in decode(adapter.poll(0.2)) if m.get_type() == "REQUEST_DATA_STREAM"]
    assert (request.req_stream_id, request.req_message_rate, request.start_stop) == (0, 10, 1)


def test_poll_heartbeat_rate_and_override_refresh() -> None:
    adapter = fresh_adapter()
    adapter.start(0.0)
    adapter.command(RcOverride({1: 1500}), 0.0)
    kinds: list[str] = []
    for i in range(1, 41):
        kinds += [m.get_type() for m in decode(adapter.poll(i * 0.05))]
    assert kinds.count("HEARTBEAT") == 2  # t = 1 and t = 2
    assert kinds.count("RC_CHANNELS_OVERRIDE") == 4  # every 0.5 s


def test_parameter_name_is_checked() -> None:
    with pytest.raises(ValueError, match="1-16 ASCII"):
        fresh_adapter().param_set("A_NAME_FAR_TOO_LONG", 1.0, 0.0)
    with pytest.raises(ValueError, match="not a MAVLink message"):
        fresh_adapter().request_message("NO_SUCH_MESSAGE", 0.0)


def test_lost_counts_from_start() -> None:
    adapter = fresh_adapter()
    assert not adapter.lost(100.0)  # not started
    adapter.start(10.0)
    assert not adapter.lost(12.9)
    assert adapter.lost(13.1)


def test_gps_time_conversion_known_value() -> None:
    # 2017-01-01 00:00:00 UTC is GPS week 1930 + 18 s: 1930 * 604800 + 18 seconds.
    assert gps_time_ms_from_unix_us(1_483_228_800_000_000) == (1930 * 604_800 + 18) * 1000
    assert gps_time_ms_from_unix_us(315_964_800_000_000) == 18_000  # the GPS epoch, in UTC


def test_settings_from_profile_and_config(tmp_path: Path) -> None:
    plane = profile("pixhawk") | profile("pixhawk_arduplane")
    settings_ = AutopilotSettings.from_profile(plane)
    assert (settings_.firmware, settings_.system_id, settings_.source_system_id) == (
        "arduplane",
        1,
        255,
    )
    assert (settings_.stream_rate_hz, settings_.heartbeat_timeout_s) == (10.0, 3.0)
    assert settings_.modes["GUIDED"] == 15
    with pytest.raises(ValueError, match="stream_rate_hz"):
        AutopilotSettings(modes={}, stream_rate_hz=0)
    with pytest.raises(ValueError, match="firmware"):
        AutopilotSettings(modes={}, firmware="px4")


def test_settings_from_compiled_config(tmp_path: Path) -> None:
    from clark_engine.cli import main

    out = tmp_path / "build"
    assert main(["compile", str(ROOT / "missions" / "anaconda_survey.yaml"), "-o", str(out)]) == 0
    configs = {p.stem: load_config(p) for p in out.rglob("*.json")}
    vehicle = next(c for c in configs.values() if c.is_vehicle)
    station = next(c for c in configs.values() if not c.is_vehicle)
    settings_ = AutopilotSettings.from_config(vehicle)
    assert settings_.firmware == "arduplane"
    assert dict(settings_.modes) == dict(vehicle.modes)
    with pytest.raises(ConfigError, match="no autopilot"):
        AutopilotSettings.from_config(station)


# -- transports ------------------------------------------------------------------------------


def test_memory_pipe() -> None:
    a, b = MemoryPipe.pair()
    assert a.fileno() is None
    assert a.send(b"abc") == 3
    a.send(b"def")
    assert b.receive() == b"abcdef"
    assert b.receive() == b""
    b.send(b"back")
    assert a.receive() == b"back"
    b.close()
    with pytest.raises(TransportError, match="other end is closed"):
        a.send(b"x")
    with pytest.raises(TransportError, match="closed pipe"):
        b.receive()


def wait_readable(transport: Transport) -> None:
    fd = transport.fileno()
    assert fd is not None
    select.select([fd], [], [], 1.0)


def test_udp_listener_answers_every_peer() -> None:
    with UdpTransport(bind=("127.0.0.1", 0)) as listener:
        assert isinstance(listener, UdpTransport)
        assert listener.send(b"nobody yet") == 0
        one = UdpTransport(remote=listener.address)
        two = UdpTransport(remote=listener.address)
        try:
            one.send(b"from one")
            two.send(b"from two")
            data = b""
            for _ in range(10):
                wait_readable(listener)
                data += listener.receive()
                if len(data) == 16:
                    break
            assert sorted([data[:8], data[8:]]) == [b"from one", b"from two"]
            assert len(listener.peers) == 2
            listener.send(b"to all")
            for peer in (one, two):
                wait_readable(peer)
                assert peer.receive() == b"to all"
        finally:
            one.close()
            two.close()


def test_tcp_client_round_trip_and_peer_close() -> None:
    server = socket.create_server(("127.0.0.1", 0))
    try:
        transport = TcpTransport(server.getsockname()[:2])
        conn, _ = server.accept()
        with conn, transport:
            assert transport.receive() == b""
            transport.send(b"\xfd" * 5000)
            received = b""
            while len(received) < 5000:
                received += conn.recv(65536)
            assert received == b"\xfd" * 5000
            conn.sendall(b"hello")
            wait_readable(transport)
            assert transport.receive() == b"hello"
            conn.shutdown(socket.SHUT_WR)
            wait_readable(transport)
            with pytest.raises(TransportError, match="closed the connection"):
                transport.receive()
    finally:
        server.close()


def test_tcp_refused_is_a_transport_error() -> None:
    spare = socket.socket()
    spare.bind(("127.0.0.1", 0))
    port = spare.getsockname()[1]
    spare.close()  # nobody listens there now
    with pytest.raises(TransportError, match="cannot connect"):
        TcpTransport(("127.0.0.1", port), connect_timeout_s=1.0)


@pytest.fixture
def pty_pair() -> Iterator[tuple[int, str]]:
    controller, device = os.openpty()
    name = os.ttyname(device)
    yield controller, name
    os.close(device)
    os.close(controller)


def test_serial_over_a_pseudo_terminal(pty_pair: tuple[int, str]) -> None:
    controller, name = pty_pair
    with SerialTransport(name, 57600) as serial_:
        assert serial_.receive() == b""
        frames = sim_stream()
        os.write(controller, frames)
        wait_readable(serial_)
        data = b""
        for _ in range(20):
            data += serial_.receive()
            if len(data) == len(frames):
                break
            wait_readable(serial_)
        assert data == frames  # raw: no byte translated (0x0d, 0x11, 0x13 pass)
        serial_.send(b"\x0d\x0a\x11\x13\x03")
        select.select([controller], [], [], 1.0)
        assert os.read(controller, 100) == b"\x0d\x0a\x11\x13\x03"


def test_serial_adapter_reads_the_sim_through_a_pty(pty_pair: tuple[int, str]) -> None:
    controller, name = pty_pair
    adapter = fresh_adapter()
    with SerialTransport(name) as serial_:
        os.write(controller, sim_stream())
        wait_readable(serial_)
        events: list[AutopilotEvent] = []
        for _ in range(20):
            events += adapter.receive(serial_.receive(), 1.0)
            if any(isinstance(e, VehicleState) for e in events):
                break
            wait_readable(serial_)
        assert any(isinstance(e, VehicleState) for e in events)


def test_serial_errors(tmp_path: Path) -> None:
    with pytest.raises(TransportError, match="cannot open"):
        SerialTransport(str(tmp_path / "ttyNONE"))
    plain = tmp_path / "file"
    plain.write_bytes(b"")
    with pytest.raises(TransportError, match="not a serial line"):
        SerialTransport(str(plain))
    with pytest.raises(TransportError, match="standard serial rate"):
        SerialTransport("/dev/null", 12345)


def test_open_transport_from_profile_connections(pty_pair: tuple[int, str]) -> None:
    _controller, name = pty_pair
    with open_transport({"kind": "serial", "device": name, "baud_bps": 115200}) as serial_:
        assert isinstance(serial_, SerialTransport)
    with open_transport({"kind": "udp", "address": "127.0.0.1:0"}) as udp:
        assert isinstance(udp, UdpTransport)
        assert udp.address[0] == "127.0.0.1" and udp.address[1] > 0
    server = socket.create_server(("127.0.0.1", 0))
    with server:
        port = server.getsockname()[1]
        with open_transport({"kind": "tcp", "address": f"127.0.0.1:{port}"}) as tcp:
            assert isinstance(tcp, TcpTransport)
    for bad, match in (
        ({"kind": "radio"}, "unknown connection kind"),
        ({"kind": "serial"}, "without a device"),
        ({"kind": "udp"}, "without an address"),
        ({"kind": "udp", "address": "localhost"}, "not host:port"),
    ):
        with pytest.raises(TransportError, match=match):
            open_transport(bad)
    assert parse_address("[::1]:14550") == ("[::1]", 14550)
