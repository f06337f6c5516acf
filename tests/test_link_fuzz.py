"""Fuzzing decode: whatever arrives, it returns a Packet or raises a ClarkLinkError.

Random bytes, random bundles behind a valid header, and mutations of valid
packets (bit flips, truncation, extension, overwritten header fields, and
re-signing so that mutated bundles reach the parser under a key). Bounded and
derandomised so the suite stays fast and CI deterministic; benchmarks/fuzz_link.py
runs a million inputs.
"""

from __future__ import annotations

import hashlib
import hmac

from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from clark_engine.link import (
    ActivateController,
    AgentAttitude,
    AgentStatus,
    AgentType,
    BehaviorState,
    ClarkLinkError,
    Codec,
    Condition,
    Heartbeat,
    Message,
    ModeChangeRequest,
    Packet,
    PictureData,
    Terminate,
)
from clark_engine.link.packet import HEADER_BYTES, TAG_BYTES

MISSION = 7
KEY = bytes(range(32))
FUZZ = settings(
    max_examples=100,
    derandomize=True,
    deadline=None,
    database=None,
    suppress_health_check=[HealthCheck.too_slow],
)

SENDER = 2
U64 = st.integers(0, (1 << 64) - 1)
U32 = st.integers(0, (1 << 32) - 1)
TARGET = st.integers(0, 65535)
TEXT = st.text(max_size=20)


def _floats(low: float, high: float, **kw: bool) -> st.SearchStrategy[float]:
    return st.floats(low, high, allow_nan=False, **kw)


MESSAGES: st.SearchStrategy[Message] = st.one_of(
    st.builds(
        Heartbeat,
        st.just(SENDER),
        U64,
        st.just(MISSION),
        st.sampled_from(AgentType),
        st.sampled_from(Condition),
        U32,
        U32,
    ),
    st.builds(
        AgentStatus,
        st.just(SENDER),
        U64,
        _floats(-90, 90),
        _floats(-180, 180),
        _floats(-2e6, 2e6),
        _floats(0, 2e7),
        _floats(-2e7, 2e7),
        _floats(0, 360, exclude_max=True),
        U32,
    ),
    st.builds(
        PictureData,
        st.just(SENDER),
        U64,
        _floats(-90, 90),
        _floats(-180, 180),
        _floats(-2e6, 2e6),
        U32,
    ),
    st.builds(ModeChangeRequest, st.just(SENDER), U64, TARGET, U32),
    st.builds(
        ActivateController,
        st.just(SENDER),
        U64,
        TARGET,
        st.booleans(),
        U64,
        st.integers(-(1 << 31), (1 << 31) - 1),
    ),
    st.builds(AgentAttitude, st.just(SENDER), U64, *[_floats(-360, 360)] * 3),
    st.builds(Terminate, st.just(SENDER), U64, TARGET, TEXT),
    st.builds(BehaviorState, st.just(SENDER), U64, st.lists(TEXT, max_size=3).map(tuple), TEXT),
)


def decode_or_reject(codec: Codec, data: bytes) -> Packet | None:
    """The property under test: a Packet, or a ClarkLinkError, nothing else."""
    try:
        return codec.decode(data)
    except ClarkLinkError:
        return None


@FUZZ
@given(data=st.binary(max_size=1500), keyed=st.booleans())
def test_random_bytes_are_rejected_cleanly(data: bytes, keyed: bool) -> None:
    assert decode_or_reject(Codec(MISSION, 1, KEY if keyed else None), data) is None


@FUZZ
@given(bundle=st.binary(max_size=300), counter=st.integers(0, (1 << 48) - 1))
def test_random_bundles_behind_a_valid_header_never_escape(bundle: bytes, counter: int) -> None:
    header = bytes.fromhex("01000000000700020000") + counter.to_bytes(6, "big")
    decode_or_reject(Codec(MISSION, 1), header + bundle)
    signed = b"\x01\x01" + header[2:] + bundle
    signed += hmac.new(KEY, signed, hashlib.sha256).digest()[:TAG_BYTES]
    decode_or_reject(Codec(MISSION, 1, KEY), signed)


KINDS = ("flip", "truncate", "extend", "counter", "mission", "sender", "byte", "splice")
#: (what, a number, some bytes): each kind uses the number and bytes in its own way.
MUTATIONS = st.tuples(st.sampled_from(KINDS), st.integers(0, (1 << 48) - 1), st.binary(max_size=64))


def mutate(packet: bytes, mutations: list[tuple[str, int, bytes]]) -> bytes:
    data = bytearray(packet)
    for kind, number, blob in mutations:
        header = len(data) >= HEADER_BYTES
        if kind == "flip" and data:
            data[number % len(data)] ^= 1 << (number % 8)
        elif kind == "truncate":
            del data[number % (len(data) + 1) :]
        elif kind == "extend":
            data += blob or b"\x00"
        elif kind == "counter" and header:
            data[10:16] = number.to_bytes(6, "big")  # any 48-bit counter
        elif kind == "mission" and header:
            data[2:6] = (number & 0xFFFFFFFF).to_bytes(4, "big")
        elif kind == "sender" and header:
            data[6:8] = (number & 0xFFFF).to_bytes(2, "big")
        elif kind == "byte" and header:
            data[number % HEADER_BYTES] = number >> 8 & 0xFF  # version, flags, ids, counter
        elif kind == "splice" and data:
            at = number % len(data)
            data[at : at + len(blob)] = blob
    return bytes(data)


@FUZZ
@given(
    messages=st.lists(MESSAGES, min_size=1, max_size=6),
    keyed=st.booleans(),
    mutations=st.lists(MUTATIONS, min_size=1, max_size=3),
    resign=st.booleans(),
)
def test_mutated_valid_packets_never_escape(
    messages: list[Message], keyed: bool, mutations: list[tuple[str, int, bytes]], resign: bool
) -> None:
    key = KEY if keyed else None
    (packet,) = Codec(MISSION, SENDER, key).encode(messages, destination=0)
    receiver = Codec(MISSION, 1, key)
    got = receiver.decode(packet)  # unmutated: decodes
    assert len(got.messages) == len(messages)
    damaged = mutate(packet, mutations)
    if keyed and resign and len(damaged) > TAG_BYTES:
        body = damaged[:-TAG_BYTES]  # as if a key holder sent the damaged bytes
        damaged = body + hmac.new(KEY, body, hashlib.sha256).digest()[:TAG_BYTES]
    # The same receiver, whose replay window now holds the genuine packet, and a fresh one.
    decode_or_reject(receiver, damaged)
    result = decode_or_reject(Codec(MISSION, 1, key), damaged)
    if result is not None:
        assert result.mission_id == MISSION
        assert all(m.agent_id == result.sender_id for m in result.messages)
