"""The XBee 900HP emulator: the handshake digi-xbee performs, frames on the wire, the medium."""

from __future__ import annotations

import os
import select
import threading
from collections.abc import Iterator

import pytest
from digi.xbee.devices import DigiMeshDevice
from digi.xbee.models.address import XBee64BitAddress
from digi.xbee.models.protocol import XBeeProtocol
from digi.xbee.models.status import TransmitStatus

from clark_engine.sim.xbee_emulator import (
    BROADCAST_ADDRESS,
    FRAME_AT_RESPONSE,
    FRAME_RECEIVE_PACKET,
    FRAME_TRANSMIT_STATUS,
    STATUS_MAC_ACK_FAILURE,
    STATUS_PAYLOAD_TOO_LARGE,
    STATUS_ROUTE_NOT_FOUND,
    STATUS_SUCCESS,
    XBeeEmulator,
    decode_frames,
    encode_frame,
)

A = 0x0013A20041000001
B = 0x0013A20041000002
C = 0x0013A20041000003
ABSENT = 0x0013A20041009999
WAIT_S = 5.0


class RawPort:
    """The slave side of an emulated radio, read and written as bare bytes."""

    def __init__(self, path: str) -> None:
        self.fd = os.open(path, os.O_RDWR | os.O_NOCTTY)
        self.buffer = bytearray()
        self.frames: list[bytes] = []

    def send(self, payload: bytes) -> None:
        os.write(self.fd, encode_frame(payload))

    def next_frame(self, timeout_s: float = WAIT_S) -> bytes:
        while not self.frames:
            ready, _, _ = select.select([self.fd], [], [], timeout_s)
            if not ready:
                raise TimeoutError("no frame from the emulator")
            self.buffer += os.read(self.fd, 4096)
            self.frames.extend(decode_frames(self.buffer))
        return self.frames.pop(0)

    def quiet(self, timeout_s: float) -> bool:
        """Whether nothing arrives within ``timeout_s``."""
        if self.frames:
            return False
        ready, _, _ = select.select([self.fd], [], [], timeout_s)
        return not ready

    def close(self) -> None:
        os.close(self.fd)


def transmit_request(frame_id: int, destination: int, data: bytes) -> bytes:
    return bytes([0x10, frame_id]) + destination.to_bytes(8, "big") + b"\xff\xfe\x00\x00" + data


@pytest.fixture
def emulator() -> Iterator[XBeeEmulator]:
    emu = XBeeEmulator(throughput_bps=None)
    try:
        yield emu
    finally:
        emu.stop()


@pytest.fixture
def ports(emulator: XBeeEmulator) -> Iterator[dict[int, RawPort]]:
    opened: dict[int, RawPort] = {}
    for address in (A, B, C):
        opened[address] = RawPort(emulator.add_radio(address).port)
    emulator.start()
    try:
        yield opened
    finally:
        for port in opened.values():
            port.close()


def test_frame_encoding_matches_the_api_mode_1_golden_bytes() -> None:
    # AT command NI, frame id 1: the example in Digi's API frame documentation.
    assert encode_frame(bytes.fromhex("08014E49")) == bytes.fromhex("7E000408014E495F")
    buffer = bytearray(b"\x00junk" + bytes.fromhex("7E000408014E495F") + b"\x7e\x00")
    assert decode_frames(buffer) == [bytes.fromhex("08014E49")]
    assert buffer == bytearray(b"\x7e\x00")


def test_digi_xbee_opens_an_emulated_900hp_as_a_digimesh_device() -> None:
    with XBeeEmulator() as emu:
        radio = emu.add_radio(A, node_id="CUB")
        device = DigiMeshDevice(radio.port, 115200)
        try:
            device.open()
            assert device.get_protocol() == XBeeProtocol.DIGI_MESH
            assert str(device.get_64bit_addr()) == "0013A20041000001"
            assert device.get_node_id() == "CUB"
            assert device.get_firmware_version().hex() == "8074"
            assert device.get_parameter("ID") == bytes.fromhex("5ABC")
            assert device.get_parameter("AP") == b"\x01"
        finally:
            device.close()
        asked = {frame[2:4].decode() for frame in radio.received_frames}
        assert {"AP", "HV", "VR", "SH", "SL", "NI", "CE"} <= asked


def test_queued_parameter_waits_for_ac_and_wr_writes_it(emulator: XBeeEmulator) -> None:
    radio = emulator.add_radio(A)
    emulator.start()
    device = DigiMeshDevice(radio.port, 115200)
    try:
        device.open()
        device.set_parameter("NI", b"FOX", apply=False)
        assert radio.settings["NI"] == b" "
        device.apply_changes()
        assert radio.settings["NI"] == b"FOX"
        assert radio.written["NI"] == b" "
        device.write_changes()
        assert radio.written["NI"] == b"FOX"
    finally:
        device.close()


def test_unicast_is_acknowledged_and_delivered_to_the_addressed_radio_only(
    ports: dict[int, RawPort],
) -> None:
    ports[A].send(transmit_request(7, B, b"hello"))
    status = ports[A].next_frame()
    assert status[0] == FRAME_TRANSMIT_STATUS and status[1] == 7
    assert status[5] == STATUS_SUCCESS
    received = ports[B].next_frame()
    assert received[0] == FRAME_RECEIVE_PACKET
    assert int.from_bytes(received[1:9], "big") == A
    assert received[11] & 0x01 and not received[11] & 0x02
    assert received[12:] == b"hello"
    assert ports[C].quiet(0.05)


def test_broadcast_reaches_every_other_radio(ports: dict[int, RawPort]) -> None:
    ports[A].send(transmit_request(1, BROADCAST_ADDRESS, b"all"))
    assert ports[A].next_frame()[5] == STATUS_SUCCESS
    for other in (B, C):
        received = ports[other].next_frame()
        assert received[11] & 0x02
        assert received[12:] == b"all"
    assert ports[A].quiet(0.05)


def test_unicast_to_an_absent_address_reports_route_not_found(
    ports: dict[int, RawPort],
) -> None:
    ports[A].send(transmit_request(9, ABSENT, b"anyone?"))
    status = ports[A].next_frame()
    assert status[0] == FRAME_TRANSMIT_STATUS
    assert status[5] == STATUS_ROUTE_NOT_FOUND


def test_oversized_payload_is_refused(ports: dict[int, RawPort]) -> None:
    ports[A].send(transmit_request(2, B, bytes(257)))
    assert ports[A].next_frame()[5] == STATUS_PAYLOAD_TOO_LARGE


def test_unknown_at_command_is_refused(ports: dict[int, RawPort]) -> None:
    ports[A].send(bytes([0x08, 3]) + b"SS")
    response = ports[A].next_frame()
    assert response[0] == FRAME_AT_RESPONSE and response[4] == 0x02


def test_total_loss_fails_unicast_with_mac_ack_and_silences_broadcast() -> None:
    with XBeeEmulator(loss=1.0, throughput_bps=None) as emu:
        a = RawPort(emu.add_radio(A).port)
        b = RawPort(emu.add_radio(B).port)
        try:
            a.send(transmit_request(1, B, b"x"))
            assert a.next_frame()[5] == STATUS_MAC_ACK_FAILURE
            a.send(transmit_request(2, BROADCAST_ADDRESS, b"y"))
            assert a.next_frame()[5] == STATUS_SUCCESS
            assert b.quiet(0.05)
        finally:
            a.close()
            b.close()


def _losses(seed: int) -> list[tuple[int, ...]]:
    with XBeeEmulator(loss=0.5, throughput_bps=None, seed=seed) as emu:
        a = RawPort(emu.add_radio(A).port)
        emu.add_radio(B)
        emu.add_radio(C)
        try:
            for frame_id in range(1, 21):
                a.send(transmit_request(frame_id, BROADCAST_ADDRESS, b"z"))
                a.next_frame()
        finally:
            a.close()
        return [d.lost_to for d in emu.deliveries]


def test_loss_is_seeded_and_partial() -> None:
    first = _losses(seed=4)
    assert first == _losses(seed=4)
    lost = sum(len(x) for x in first)
    assert 0 < lost < 40


def test_latency_and_shared_channel_throughput_delay_frames() -> None:
    with XBeeEmulator(latency_s=0.02, throughput_bps=33_000) as emu:
        a = RawPort(emu.add_radio(A).port)
        b = RawPort(emu.add_radio(B).port)
        try:
            a.send(transmit_request(1, B, bytes(100)))
            a.send(transmit_request(2, B, bytes(100)))
            for _ in range(2):
                assert a.next_frame()[5] == STATUS_SUCCESS
                b.next_frame()
        finally:
            a.close()
            b.close()
        first, second = emu.deliveries
        airtime = (100 + 18) * 8 / 33_000
        assert first.arrival_s - first.start_s == pytest.approx(airtime + 0.02)
        assert first.start_s >= first.sent_s
        # The second frame waits for the channel: it takes the air when the first leaves it.
        assert second.start_s == pytest.approx(max(second.sent_s, first.start_s + airtime))


def test_unplug_fails_the_line_and_plug_brings_the_radio_back_on_the_same_path() -> None:
    with XBeeEmulator(throughput_bps=None) as emu:
        radio = emu.add_radio(A)
        port = RawPort(radio.port)
        radio.unplug()
        assert not radio.plugged
        ready, _, _ = select.select([port.fd], [], [], WAIT_S)
        assert ready
        with pytest.raises(OSError):
            if not os.read(port.fd, 1):
                raise OSError("end of file")
        port.close()
        radio.plug()
        assert radio.plugged
        again = RawPort(radio.port)
        try:
            again.send(bytes([0x08, 5]) + b"SL")
            assert again.next_frame()[5:] == (A & 0xFFFFFFFF).to_bytes(4, "big")
        finally:
            again.close()


def test_stop_ends_the_thread_and_removes_the_ports() -> None:
    emu = XBeeEmulator()
    radio = emu.add_radio(A)
    emu.start()
    emu.stop()
    emu.stop()
    assert not os.path.exists(radio.port)
    assert not any(t.name == "xbee-emulator" for t in threading.enumerate())


def test_digi_xbee_unicast_status_through_the_emulator() -> None:
    with XBeeEmulator() as emu:
        a = DigiMeshDevice(emu.add_radio(A).port, 115200)
        b = DigiMeshDevice(emu.add_radio(B).port, 115200)
        try:
            a.open()
            b.open()
            status = a.send_data_64(XBee64BitAddress.from_hex_string(f"{B:016X}"), b"hi")
            assert status.transmit_status == TransmitStatus.SUCCESS
            message = b.read_data(WAIT_S)
            assert bytes(message.data) == b"hi"
        finally:
            a.close()
            b.close()
