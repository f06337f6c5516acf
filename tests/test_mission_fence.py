"""Geofence geometry (clark_engine.mission.fence): zones, margins, clamping."""

from __future__ import annotations

import math

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from clark_engine.mission.fence import Fence, Zone

SQUARE = Zone.polygon([(0, 0), (100, 0), (100, 100), (0, 100)])
#: An L: the square with its north-east quarter cut away (a concave corner at 50, 50).
ELL = Zone.polygon([(0, 0), (100, 0), (100, 50), (50, 50), (50, 100), (0, 100)])


def test_polygon_contains_and_signed_distance() -> None:
    assert SQUARE.contains(50, 50)
    assert SQUARE.signed_distance_m(50, 50) == pytest.approx(50)
    assert SQUARE.signed_distance_m(10, 50) == pytest.approx(10)
    assert not SQUARE.contains(-1, 50)
    assert SQUARE.signed_distance_m(-3, 50) == pytest.approx(-3)
    assert SQUARE.signed_distance_m(103, 104) == pytest.approx(-5)  # from the corner
    assert SQUARE.contains(0, 50)  # on the edge


def test_concave_polygon() -> None:
    assert ELL.contains(25, 75)
    assert not ELL.contains(75, 75)
    assert ELL.signed_distance_m(75, 75) == pytest.approx(-25)


def test_circle() -> None:
    zone = Zone.circle((10, 10), 20)
    assert zone.contains(10, 29)
    assert zone.signed_distance_m(10, 10) == pytest.approx(20)
    assert zone.signed_distance_m(10, 40) == pytest.approx(-10)
    assert zone.nearest_on_edge(10, 40) == pytest.approx((10, 30))


def test_self_crossing() -> None:
    assert SQUARE.self_crossing() is None
    assert ELL.self_crossing() is None
    bow_tie = Zone.polygon([(0, 0), (10, 10), (10, 0), (0, 10)])
    assert bow_tie.self_crossing() == (0, 2)


def test_fence_margin_include_and_exclude() -> None:
    fence = Fence(include=(SQUARE,), exclude=(Zone.circle((50, 50), 10),))
    assert fence.margin_m(50, 5) == pytest.approx(5)
    assert fence.margin_m(50, 55) == pytest.approx(-5)  # inside the excluded circle
    assert fence.margin_m(50, 65) == pytest.approx(5)
    assert not fence.contains(50, 50)
    assert Fence().margin_m(1e6, 1e6) == math.inf


def test_clamp_keeps_a_target_inside() -> None:
    fence = Fence(include=(SQUARE,))
    assert fence.clamp((50, 50), (60, 60), 2) == (60, 60)
    n, e = fence.clamp((50, 50), (150, 50), 2)  # type: ignore[misc]
    assert (n, e) == pytest.approx((98, 50), abs=0.1)
    assert fence.margin_m(n, e) >= 2 - 1e-6


def test_clamp_cuts_a_leg_through_an_exclusion_zone() -> None:
    fence = Fence(include=(SQUARE,), exclude=(Zone.circle((50, 50), 10),))
    goal = fence.clamp((50, 20), (50, 80), 2)
    assert goal is not None
    assert goal[1] == pytest.approx(38, abs=0.1)  # stops 2 m short of the circle


def test_clamp_from_outside_goes_back_in() -> None:
    fence = Fence(include=(SQUARE,))
    goal = fence.clamp((120, 50), (130, 50), 2)
    assert goal is not None
    assert fence.margin_m(*goal) >= 2 - 1e-6


def test_clamp_refuses_where_nothing_fits() -> None:
    fence = Fence(include=(Zone.circle((0, 0), 1),))
    assert fence.clamp((0, 0), (50, 0), 5) is None


def test_leaves_at_near_the_edge_may_move_away() -> None:
    fence = Fence(include=(SQUARE,))
    assert fence.leaves_at((1, 50), (50, 50), 2) is None  # moving inwards from the band
    assert fence.leaves_at((1, 50), (-10, 50), 2) == pytest.approx(0, abs=0.01)


@settings(max_examples=200, deadline=None)
@given(
    st.floats(-200, 300),
    st.floats(-200, 300),
    st.floats(-200, 300),
    st.floats(-200, 300),
    st.floats(0, 10),
)
def test_clamped_targets_are_inside_by_the_margin(
    n0: float, e0: float, n1: float, e1: float, margin: float
) -> None:
    """Whatever the target, a clamped one is inside the L-shaped fence by the margin."""
    fence = Fence(include=(ELL,), exclude=(Zone.circle((25, 25), 5),))
    goal = fence.clamp((n0, e0), (n1, e1), margin)
    if goal is not None:
        assert fence.margin_m(*goal) >= margin - 0.05 or fence.margin_m(n0, e0) < margin
