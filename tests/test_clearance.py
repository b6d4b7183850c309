"""Clearance between moving convex solids (simulator/clearance.py): gaps, the allowance for motion between samples,
and the all-at-once test a scene generator places its solids with."""

from __future__ import annotations

import math

import numpy as np
import pytest

from simulator.clearance import Body, Occupancy, clear, point_polygon_distance, separation

SQUARE = np.array([[0.0, 0.0], [1.0, 0.0], [1.0, 1.0], [0.0, 1.0], [0.0, 1.0]])  # padded to 5 like the hulls


def test_separation_is_the_gap_for_faces_and_the_push_for_overlaps() -> None:
    assert separation(SQUARE, SQUARE + np.array([2.5, 0.0])) == pytest.approx(1.5, abs=1e-12)
    assert separation(SQUARE, SQUARE + np.array([0.0, -3.0])) == pytest.approx(2.0, abs=1e-12)
    assert separation(SQUARE, SQUARE + np.array([0.5, 0.25])) == pytest.approx(-0.5, abs=1e-12)  # the smaller push
    assert separation(SQUARE, SQUARE[::-1] + np.array([3.0, 0.0])) == pytest.approx(
        2.0, abs=1e-12
    )  # either orientation


def test_separation_never_exceeds_the_true_distance() -> None:
    # corner to corner on the diagonal: true distance sqrt(2), the axis gap only 1
    assert separation(SQUARE, SQUARE + np.array([2.0, 2.0])) == pytest.approx(1.0, abs=1e-12)
    rng = np.random.default_rng(5)
    angle = rng.uniform(0, 2 * math.pi, 200)
    shift = rng.uniform(-6, 6, (200, 2))
    c, s = np.cos(angle)[:, None], np.sin(angle)[:, None]
    box = SQUARE - 0.5
    other = np.stack([c * box[:, 0] - s * box[:, 1], s * box[:, 0] + c * box[:, 1]], -1) + shift[:, None, :]
    gap = separation(np.broadcast_to(box, other.shape), other)
    # true distance of two disjoint convex polygons: the nearest vertex of either to the other
    true = np.minimum(
        point_polygon_distance(other, np.broadcast_to(box, other.shape)[:, None]).min(-1),
        point_polygon_distance(np.broadcast_to(box, other.shape), other[:, None]).min(-1),
    )
    apart = gap > 0
    assert apart.sum() > 150
    assert np.all(gap[apart] <= true[apart] + 1e-12)
    assert np.all(gap[apart] >= true[apart] / math.sqrt(2) - 1e-12)  # two squares: never worse than the diagonal


def test_point_polygon_distance_inside_on_an_edge_and_off_a_corner() -> None:
    pts = np.array([[0.5, 0.5], [3.0, 0.5], [2.0, 2.0], [1.0, 0.5]])
    np.testing.assert_allclose(point_polygon_distance(pts, SQUARE), [0.0, 2.0, math.sqrt(2), 0.0], atol=1e-12)


def _crossing(speed: float, times: np.ndarray) -> Body:
    """A 1 m square sailing east along north = 0.25 at ``speed``, centred on east = 0 at t = 0."""
    centre = np.stack([np.full_like(times, 0.5), speed * times], -1)
    outline = SQUARE[None] - 0.5 + centre[:, None, :]
    return Body.moving(outline, centre, speed)


def test_a_body_passing_through_another_between_two_samples_is_caught() -> None:
    times = np.array([-0.5, 0.5])  # 0.5 s either side of the meeting: at both samples 4 m clear
    fast = _crossing(10.0, times)
    buoy = Body.fixed(SQUARE - 0.5 + np.array([0.5, 0.0]))
    assert separation(fast.outline, np.broadcast_to(buoy.outline[0], fast.outline.shape)).min() == pytest.approx(4.0)
    assert not clear(fast, buoy, 0.0, step=1.0)  # 10 m/s x 0.5 s of possible motion either way
    slow = _crossing(1.0, np.array([-5.0, 5.0]))  # 4 m clear at the samples, 5 m of motion allowed: refused too
    assert not clear(slow, buoy, 0.0, step=10.0)
    far = Body.fixed(SQUARE + np.array([8.0, 0.0]))  # 7 m off the track: clear with a 1 m margin
    assert clear(fast, far, 1.0, step=1.0)


def test_occupancy_admits_what_clear_admits_and_refuses_land() -> None:
    times = np.linspace(0.0, 10.0, 41)
    step = times[1] - times[0]
    quay = Body.fixed(np.array([[20.0, -50.0], [20.0, 50.0], [30.0, 50.0], [30.0, -50.0], [30.0, -50.0]]))
    placed = Occupancy(step)
    placed.add(quay, 0.2)
    rng = np.random.default_rng(11)
    verdicts, accepted = [], []
    for _ in range(60):
        start, velocity = rng.uniform(-10, 25, 2), rng.uniform(-2, 2, 2)
        centre = start + times[:, None] * velocity
        body = Body.moving(SQUARE[None] * 3 - 1.5 + centre[:, None, :], centre, float(np.hypot(*velocity)))
        expected = clear(body, quay, 0.2, step) and all(clear(body, b, 1.0, step) for b in accepted)
        verdicts.append(expected)
        assert placed.admits(body) == expected
        if expected:
            placed.add(body, 1.0)
            accepted.append(body)
    assert 5 < sum(verdicts) < 55  # both answers were exercised
    assert placed.on_fixed(np.array([[25.0, 0.0]])) and not placed.on_fixed(np.array([[19.0, 0.0]]))
