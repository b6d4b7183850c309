"""Visible-side compensation: the hull centre behind returns from the near sides only."""

from __future__ import annotations

import math

import numpy as np
import pytest

from tracker.radar.visible_side import spread, visible_side_centre


def test_spread_is_the_linear_quantile_range() -> None:
    rng = np.random.default_rng(3)
    for n in (2, 3, 7, 40):
        v = rng.normal(size=n)
        lo, hi = np.quantile(v, [0.05, 0.95])
        assert spread(v, 0.05) == pytest.approx(hi - lo, abs=1e-12)
    assert spread(np.array([1.0]), 0.05) == 0.0
    assert spread(np.array([0.0, 1.0, 2.0, 3.0, 4.0]), 0.25) == pytest.approx(2.0)  # 1.0 .. 3.0


def test_centre_moves_behind_the_nearest_return_along_the_line_of_sight() -> None:
    # Radar at the origin, looking north at a 4 m (north) x 2 m (east) hull centred 20 m north: only the south
    # face (y in [-1, 1] at x = 18) is seen. Box centre of the returns: (18, 0); outline depth 0, width 2 m.
    face = np.column_stack([np.full(5, 18.0), np.linspace(-1.0, 1.0, 5)])
    c = visible_side_centre(face, np.zeros(2), face - [20.0, 0.0], depth_gain=0.4, width_gain=0.2, quantile=0.0)
    # nearest return at range 18 (on the line of sight through the box centre), + 0.4 * 0 + 0.2 * 2
    np.testing.assert_allclose(c, [18.4, 0.0], atol=1e-12)


def test_corner_view_of_a_rectangle() -> None:
    # A 4 x 2 m hull at (30, 10) seen corner-on: its two visible sides from the corner nearest the radar.
    centre = np.array([30.0, 10.0])
    half = np.array([2.0, 1.0])
    near = centre - half  # south-west corner faces a radar at the origin
    south = np.column_stack([np.full(9, near[0]), np.linspace(near[1], near[1] + 2.0, 9)])
    west = np.column_stack([np.linspace(near[0], near[0] + 4.0, 9), np.full(9, near[1])])
    pts = np.concatenate([south, west])
    box_c = (pts.min(axis=0) + pts.max(axis=0)) / 2  # the box of an L is the whole hull's box here
    u = box_c / np.linalg.norm(box_c)
    n = np.array([-u[1], u[0]])
    shape = pts - centre
    depth = np.ptp(shape @ u)
    width = np.ptp(shape @ n)
    want = u * ((pts @ u).min() + 0.4 * depth + 0.2 * width)
    got = visible_side_centre(pts, np.zeros(2), shape, 0.4, 0.2, quantile=0.0)
    np.testing.assert_allclose(got, want, atol=1e-12)
    # and it lands within 0.5 m of the true centre, where the nearest return alone is 2.2 m short
    assert np.linalg.norm(got - centre) < 0.5
    assert math.hypot(*centre) - (pts @ u).min() > 2.0


def test_never_in_front_of_the_nearest_return_and_degenerate_input() -> None:
    pts = np.array([[10.0, 0.0], [10.0, 0.5]])
    c = visible_side_centre(pts, np.zeros(2), np.zeros((0, 2)), depth_gain=0.0, width_gain=0.0)
    u = np.array([10.0, 0.25]) / np.hypot(10.0, 0.25)  # towards the box centre
    np.testing.assert_allclose(c, u * (pts @ u).min(), atol=1e-12)  # on the nearest return's range, not in front
    one = np.array([[0.0, 0.0]])  # a return at the radar itself: no line of sight, the box centre stays
    np.testing.assert_array_equal(visible_side_centre(one, np.zeros(2), one, 0.4, 0.2), [0.0, 0.0])
