"""The simulated camera: delays, the minimum interval, failures, ids, determinism."""

from __future__ import annotations

import random
from pathlib import Path
from typing import Any

import pytest
import yaml

from clark_engine.runtime.commands import PayloadCommand
from clark_engine.runtime.events import PayloadEvent
from clark_engine.sim.camera import DEFAULT_RESPONSE_DELAY_S, SimCamera

ROOT = Path(__file__).resolve().parent.parent
PI_CAMERA: dict[str, Any] = yaml.safe_load(
    (ROOT / "hardware_profiles" / "payloads" / "raspberry_pi_camera.yaml").read_text()
)
DELAY_S = 0.8  # the profile's capture_delay_s
INTERVAL_S = 2.0  # the profile's min_interval_s


def test_the_profile_figures_are_used() -> None:
    camera = SimCamera("camera", PI_CAMERA)
    assert (camera.capture_delay_s, camera.min_interval_s) == (DELAY_S, INTERVAL_S)
    assert camera.resolution_mp == 5.0


def test_a_capture_is_reported_after_the_delay_with_its_file_name() -> None:
    camera = SimCamera("camera", PI_CAMERA)
    camera.request(7, 10.0)
    assert camera.next_event_s() == pytest.approx(10.0 + DELAY_S)
    assert camera.events_until(10.5) == []
    [(at_s, event)] = camera.events_until(11.0)
    assert at_s == pytest.approx(10.8)
    assert event == PayloadEvent("camera", "captured", 7, "IMG_0001.jpg")
    assert camera.next_event_s() is None


def test_too_soon_is_refused_and_does_not_restart_the_interval() -> None:
    camera = SimCamera("cam", PI_CAMERA)
    camera.request(1, 0.0)
    camera.request(2, 1.0)  # refused: 1 s after the accepted one
    camera.request(3, 1.9)  # refused
    camera.request(4, 2.0)  # accepted: 2 s after request 1 (refusals do not count)
    events = camera.events_until(10.0)
    assert [(round(at_s, 3), e.request_id, e.kind) for at_s, e in events] == [
        (0.8, 1, "captured"),
        (1.05, 2, "refused"),
        (1.95, 3, "refused"),
        (2.8, 4, "captured"),
    ]
    assert "too soon" in events[1][1].detail
    assert [e.detail for _, e in events if e.kind == "captured"] == [
        "IMG_0001.jpg",
        "IMG_0002.jpg",
    ]
    stats = camera.stats
    assert (stats.requests, stats.accepted, stats.captured, stats.refused, stats.errors) == (
        4,
        2,
        2,
        2,
        0,
    )


def test_every_five_seconds_as_in_the_thesis_is_never_refused() -> None:
    camera = SimCamera("camera", PI_CAMERA)
    for i in range(83):
        camera.request(i, 5.0 * i)
    events = camera.events_until(500.0)
    assert [e.kind for _, e in events] == ["captured"] * 83
    assert [e.request_id for _, e in events] == list(range(83))
    assert events[-1][1].detail == "IMG_0083.jpg"


def test_requests_in_a_failure_window_get_errors() -> None:
    camera = SimCamera("camera", PI_CAMERA)
    camera.fail(10.0, 20.0)
    camera.request(1, 5.0)
    camera.request(2, 12.0)
    camera.request(3, 25.0)
    events = camera.events_until(100.0)
    assert [(e.request_id, e.kind) for _, e in events] == [
        (1, "captured"),
        (2, "error"),
        (3, "captured"),
    ]
    assert events[1][0] == pytest.approx(12.0 + DEFAULT_RESPONSE_DELAY_S)
    assert events[2][1].detail == "IMG_0002.jpg"
    assert camera.stats.errors == 1


def test_a_capture_completing_inside_a_failure_fails() -> None:
    camera = SimCamera("camera", PI_CAMERA)
    camera.request(1, 0.0)
    camera.fail(0.5)  # the camera dies mid-capture, for good
    [(at_s, event)] = camera.events_until(5.0)
    assert at_s == pytest.approx(DELAY_S)
    assert (event.kind, event.request_id) == ("error", 1)
    camera.request(2, 3.0)
    assert camera.events_until(9.0)[0][1].kind == "error"


def test_payload_commands_are_served() -> None:
    camera = SimCamera("camera", PI_CAMERA)
    camera.command(PayloadCommand("camera", "capture", 41), 0.0)
    camera.command(PayloadCommand("camera", "zoom", 42), 0.0)
    events = camera.events_until(5.0)
    assert [(e.request_id, e.kind) for _, e in events] == [(42, "error"), (41, "captured")]
    assert "zoom" in events[0][1].detail
    with pytest.raises(ValueError, match="'other'"):
        camera.command(PayloadCommand("other", "capture", 43), 1.0)


def test_jitter_is_bounded_seeded_and_deterministic() -> None:
    def times(seed: int) -> list[float]:
        camera = SimCamera("camera", PI_CAMERA, random.Random(seed), jitter_s=0.2)
        for i in range(20):
            camera.request(i, 3.0 * i)
        return [at_s - 3.0 * e.request_id for at_s, e in camera.events_until(100.0)]

    first = times(1)
    assert first == times(1)
    assert first != times(2)
    assert all(DELAY_S <= d <= DELAY_S + 0.2 for d in first)
    assert len(set(first)) == 20


def test_equal_times_come_out_in_request_order() -> None:
    camera = SimCamera("camera", {"min_interval_s": 0.0, "capture_delay_s": 0.0})
    for i in range(5):
        camera.request(i, 1.0)
    assert [e.request_id for _, e in camera.events_until(1.0)] == [0, 1, 2, 3, 4]


@pytest.mark.parametrize(
    ("profile", "kwargs", "message"),
    [
        ({"capture_delay_s": 0.8}, {}, "min_interval_s"),
        ({**PI_CAMERA, "capture_delay_s": -1}, {}, "capture_delay_s"),
        (PI_CAMERA, {"jitter_s": 0.1}, "random source"),
    ],
)
def test_bad_configuration_is_named(
    profile: dict[str, Any], kwargs: dict[str, Any], message: str
) -> None:
    with pytest.raises(ValueError, match=message):
        SimCamera("camera", profile, **kwargs)


def test_time_never_goes_back() -> None:
    camera = SimCamera("camera", PI_CAMERA)
    camera.request(1, 5.0)
    with pytest.raises(ValueError, match="time went back"):
        camera.request(2, 4.0)
