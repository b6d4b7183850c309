"""Shadows of nearer objects on a radar track's bearing span, and the lit-edge centre (tracker.radar.occlusion)."""

from __future__ import annotations

import numpy as np

from tracker.radar.occlusion import SHADOW_BINS, ShadowCasters, lit_edge_centre, shadow

SENSOR = np.zeros(2)
BOX = np.array([39.0, -2.0, 41.0, 2.0])  # 2 m (north) x 4 m (east) at 40 m north: +-2.86 deg of bearing


def test_a_nearer_boat_over_the_clockwise_half_shadows_exactly_that_half() -> None:
    east = np.linspace(0.0, 2.0, 9)
    casters = ShadowCasters.of([np.column_stack([np.full(9, 20.0), east])], SENSOR)  # 20 m out, 0 to 5.7 deg
    got = shadow(BOX, casters, SENSOR, margin_m=1.0, own_gap_m=2.0, point_pad_m=0.0)
    assert got is not None and got.size == SHADOW_BINS
    np.testing.assert_array_equal(got, np.arange(SHADOW_BINS) >= SHADOW_BINS // 2)


def test_no_shadow_from_farther_returns_or_from_the_tracks_own_hull() -> None:
    behind = ShadowCasters.of([np.array([[60.0, 0.0], [60.0, 1.0]])], SENSOR)
    assert shadow(BOX, behind, SENSOR, 1.0, 2.0, 0.15) is None
    own_near_side = ShadowCasters.of([np.array([[37.5, -1.0], [37.5, 1.0]])], SENSOR)  # 2.5 m nearer, in the box + gap
    assert shadow(BOX, own_near_side, SENSOR, 1.0, 2.0, 0.15) is None
    assert shadow(BOX, own_near_side, SENSOR, 1.0, 0.0, 0.15) is not None  # without the gap it would hide itself
    assert shadow(BOX, ShadowCasters.of([], SENSOR), SENSOR, 1.0, 2.0, 0.15) is None


def test_the_centre_of_a_half_hidden_hull_is_measured_from_its_lit_edge() -> None:
    hidden_cw = np.arange(SHADOW_BINS) >= SHADOW_BINS // 2  # the east half hidden: returns from the west half only
    returns = np.column_stack([np.full(5, 39.0), np.linspace(-2.0, 0.0, 5)])
    box_centre = np.array([40.0, -1.0])  # what the lit returns' box says: 1 m west of the hull's centre
    got = lit_edge_centre(box_centre, returns, np.array([40.0, -0.3]), np.array([2.0, 4.0]), hidden_cw, SENSOR)
    # Across the line of sight (about east here) the lit (west) edge at -2 m plus half the 4 m silhouette.
    assert abs(got[1] - 0.0) < 0.01 and abs(got[0] - 40.0) < 0.06
    both = np.ones(SHADOW_BINS, bool)  # both ends hidden: no edge to hold on to
    np.testing.assert_array_equal(lit_edge_centre(box_centre, returns, box_centre, np.array([2.0, 4.0]), both, SENSOR),
                                  box_centre)  # fmt: skip
    np.testing.assert_array_equal(lit_edge_centre(box_centre, returns, box_centre, np.array([2.0, 4.0]), None, SENSOR),
                                  box_centre)  # fmt: skip


def test_batched_shadows_and_bins_match_the_one_box_arithmetic() -> None:
    from tracker.radar.occlusion import _bins, shadows

    rng = np.random.default_rng(4)
    half = rng.uniform(1e-4, 0.5, 50)
    for h, row in zip(half, _bins(half), strict=True):
        np.testing.assert_array_equal(row, np.linspace(-h, h, SHADOW_BINS))
    # a nearer boat over part of one track, nothing in front of the other: one pass gives each its own answer
    casters = ShadowCasters.of([np.array([[20.0, 0.5], [20.0, 1.5]])], SENSOR)
    far = np.array([BOX, [39.0, -40.0, 41.0, -36.0]])
    got = shadows(far, casters, SENSOR, 1.0, 1.0, 0.3)
    np.testing.assert_array_equal(got[0], shadow(BOX, casters, SENSOR, 1.0, 1.0, 0.3))
    assert got[0] is not None and got[0].any() and got[1] is None
