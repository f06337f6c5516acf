"""Measure ClarkLink: encode and decode rates, packet sizes, bundling, authentication cost.

Prints:

* encode and decode rates (packets per second) of a typical telemetry packet
  (Heartbeat + Agent Status), with and without a key, best of several runs;
* the bytes of an Agent Status alone, as a message and as a packet;
* a table of bundles of 1 to 8 messages (Agent Status first, then the other
  types in turn): packet bytes and bytes per message, against the thesis's
  design of one message per packet (N packets, each with its own header, and
  its own tag when authenticated);
* what authentication costs: bytes per packet and microseconds per encode and
  decode.

Radio framing (an XBee API frame adds 18 bytes per packet, a UDP/IP datagram 28)
comes on top of every packet, which makes bundling save more than shown here.

Run: python benchmarks/bench_link.py
"""

from __future__ import annotations

import time
from collections.abc import Callable

from clark_engine.link import (
    ActivateController,
    AgentAttitude,
    AgentStatus,
    AgentType,
    BehaviorState,
    Codec,
    Heartbeat,
    Message,
    ModeChangeRequest,
    PictureData,
    Terminate,
)
from clark_engine.link.packet import HEADER_BYTES, TAG_BYTES
from clark_engine.link.wire import encoded_size

MISSION = 7
KEY = bytes(range(32))
GPS_MS = 1_400_000_000_000
PACKETS = 20_000
RUNS = 5

STATUS = AgentStatus(2, GPS_MS, 30.6319123, -96.4826456, 121.5, 17.25, -1.5, 271.3, 10)
HEARTBEAT = Heartbeat(2, GPS_MS, MISSION, AgentType.VEHICLE)
#: Agent Status first, then one of each other type: what bundles of 1..8 hold.
BUNDLE_ORDER: tuple[Message, ...] = (
    STATUS,
    HEARTBEAT,
    AgentAttitude(2, GPS_MS, -12.5, 3.25, 271.3),
    PictureData(2, GPS_MS, 30.6319123, -96.4826456, 80.0, 42),
    BehaviorState(2, GPS_MS, ("survey.leg_2", "photos"), "done"),
    ModeChangeRequest(2, GPS_MS, target_id=3, mode=4),
    ActivateController(2, GPS_MS, target_id=0, active=True),
    Terminate(2, GPS_MS, target_id=0, reason="operator"),
)


def best_rate(run: Callable[[], int]) -> float:
    """Best packets per second over RUNS runs of ``run`` (which returns its packet count)."""
    best = 0.0
    for _ in range(RUNS):
        start = time.perf_counter()
        count = run()
        best = max(best, count / (time.perf_counter() - start))
    return best


def encode_rate(key: bytes | None) -> float:
    codec = Codec(MISSION, 2, key)
    telemetry = [HEARTBEAT, STATUS]

    def run() -> int:
        for _ in range(PACKETS):
            codec.encode(telemetry, destination=0)
        return PACKETS

    return best_rate(run)


def decode_rate(key: bytes | None) -> float:
    sender = Codec(MISSION, 2, key)
    packets = [sender.encode([HEARTBEAT, STATUS], destination=0)[0] for _ in range(PACKETS)]

    def run() -> int:
        receiver = Codec(MISSION, 1, key)  # fresh replay window: every packet is new to it
        for packet in packets:
            receiver.decode(packet)
        return PACKETS

    return best_rate(run)


def packet_bytes(messages: list[Message], key: bytes | None) -> int:
    return sum(len(p) for p in Codec(MISSION, 2, key).encode(messages, destination=0))


def main() -> None:
    print("ClarkLink benchmark (Heartbeat + Agent Status per packet; best of 5 runs)")
    rates: dict[tuple[str, bool], float] = {}
    for keyed in (False, True):
        key = KEY if keyed else None
        rates["encode", keyed] = encode_rate(key)
        rates["decode", keyed] = decode_rate(key)
    print(f"{'':8} {'no key':>14} {'with key':>14}")
    for what in ("encode", "decode"):
        print(
            f"{what:8} {rates[what, False]:>10,.0f} p/s {rates[what, True]:>10,.0f} p/s"
            f"   ({1e6 / rates[what, False]:.1f} / {1e6 / rates[what, True]:.1f} us per packet)"
        )

    print()
    print("Agent Status alone")
    print(f"  message in a bundle:        {encoded_size(STATUS)} B (field tag, length, body)")
    print(f"  packet without key:         {packet_bytes([STATUS], None)} B (16 B header)")
    print(f"  packet with key:            {packet_bytes([STATUS], KEY)} B (16 B header, 12 B tag)")

    print()
    print("Bundles: N messages (Agent Status, then Heartbeat, Attitude, Picture, Behavior State,")
    print("Mode Change, Activate, Terminate) in one packet vs one message per packet (thesis)")
    header = f"{'N':>2} {'bundle B':>9} {'B/msg':>6} {'1-per-pkt B':>12} {'B/msg':>6} {'saved':>6}"
    for keyed in (False, True):
        key = KEY if keyed else None
        print(f"  {'with key' if keyed else 'without key'}:")
        print("  " + header)
        for count in range(1, len(BUNDLE_ORDER) + 1):
            messages = list(BUNDLE_ORDER[:count])
            bundled = packet_bytes(messages, key)
            separate = sum(packet_bytes([m], key) for m in messages)
            print(
                f"  {count:>2} {bundled:>9} {bundled / count:>6.1f} {separate:>12} "
                f"{separate / count:>6.1f} {1 - bundled / separate:>6.0%}"
            )

    print()
    overhead_encode_us = 1e6 / rates["encode", True] - 1e6 / rates["encode", False]
    overhead_decode_us = 1e6 / rates["decode", True] - 1e6 / rates["decode", False]
    typical = packet_bytes([HEARTBEAT, STATUS], None)
    print("Authentication overhead")
    print(
        f"  bytes: {TAG_BYTES} B tag per packet ({TAG_BYTES / typical:.0%} of a {typical} B "
        f"Heartbeat + Agent Status packet; header is {HEADER_BYTES} B either way)"
    )
    print(
        f"  time:  +{overhead_encode_us:.1f} us per encode, +{overhead_decode_us:.1f} us per decode"
    )


if __name__ == "__main__":
    main()
