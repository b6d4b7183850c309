"""A horizontal surface met by one descending beam (a quay's deck) against a vertical face met by the same beam."""

from __future__ import annotations

import math

import numpy as np

from tracker.lidar.level_returns import LevelRule, horizontal_tops

SENSOR = np.array([0.0, 0.0, -1.73])  # world NED: 1.73 m above the calm water (down 0)
RULE = LevelRule()


def _line(r0: float, r1: float, bearing0_deg: float, bearing1_deg: float, n: int) -> np.ndarray:
    """(n, 2) north, east along a straight line from (r0, bearing0) to (r1, bearing1) seen from the sensor."""
    a = np.array([r0 * math.cos(math.radians(bearing0_deg)), r0 * math.sin(math.radians(bearing0_deg))])
    b = np.array([r1 * math.cos(math.radians(bearing1_deg)), r1 * math.sin(math.radians(bearing1_deg))])
    return a + np.linspace(0.0, 1.0, n)[:, None] * (b - a)


def _with_down(ne: np.ndarray, down: np.ndarray) -> np.ndarray:
    return np.column_stack([ne, down])


def _beam_down(ne: np.ndarray, depression_deg: float) -> np.ndarray:
    """World down where a beam descending at ``depression_deg`` from the sensor meets a vertical face at ``ne``."""
    return SENSOR[2] + np.hypot(ne[:, 0], ne[:, 1]) * math.tan(math.radians(depression_deg))


def test_a_deck_met_by_a_rolling_beam_is_level_over_metres_of_range_a_face_is_not() -> None:
    # The case of tuning seed 60: a quay 0.82 m high, its face met by the -1 deg beam of a rolled boat at 42-44 m
    # (the beam rising along it to the face's top edge), then its deck, level, from 44 to 52 m.
    face = _line(42.5, 43.7, 20.0, 28.0, 60)
    face_down = np.linspace(-0.30, -0.82, 60)
    deck = _line(43.8, 52.0, 28.2, 33.0, 24)
    quay = _with_down(np.vstack([face, deck]), np.concatenate([face_down, np.full(24, -0.82)]))
    # The same plan positions on a hull's vertical sides: the deck's branch met by a beam descending 1.1 deg,
    # its height falling 0.14 m from 44 to 52 m.
    hull = _with_down(np.vstack([face, deck]), np.concatenate([face_down, _beam_down(deck, 1.1)]))
    np.testing.assert_array_equal(horizontal_tops([quay, hull], SENSOR, RULE), [True, False])


def test_a_deck_met_by_a_level_boats_beam_is_an_arc_round_the_sensor_a_straight_face_is_not() -> None:
    # A level boat's -1 deg beam (0.54 deg below the sensor at the deck's 1.06 m) meets a flat deck at one range:
    # 10 m of arc at 70 m. A straight face as long, square to the line of sight, spreads 0.18 m in range.
    bearings = np.radians(np.linspace(-4.1, 4.1, 40))
    arc = _with_down(70.0 * np.column_stack([np.cos(bearings), np.sin(bearings)]), np.full(40, -1.06))
    straight_ne = np.column_stack([np.full(40, 70.0), 70.0 * np.tan(bearings)])
    straight = _with_down(straight_ne, _beam_down(straight_ne, 0.54))
    np.testing.assert_array_equal(horizontal_tops([arc, straight], SENSOR, RULE), [True, False])


def test_a_hull_side_met_by_several_beams_or_a_top_above_the_beams_is_no_deck() -> None:
    deck = _line(44.0, 52.0, 0.0, 6.0, 30)
    level = _with_down(deck, np.full(30, -0.82))
    # the same level line plus a second beam's returns 2 deg lower on the same side: a hull's side
    second = _with_down(deck, _beam_down(deck, 3.0))
    two_beams = np.vstack([level, second])
    # level, but at the sensor's own height: a beam at 0 deg would draw that on any vertical face
    flat_beam = _with_down(deck, np.full(30, -1.70))
    out = horizontal_tops([two_beams, flat_beam, level], SENSOR, RULE)
    np.testing.assert_array_equal(out, [False, False, True])


def test_too_few_level_returns_are_no_deck_and_empty_input_is_none() -> None:
    deck = _with_down(_line(44.0, 52.0, 0.0, 6.0, 7), np.full(7, -0.82))  # fewer than min_points (8)
    assert horizontal_tops([deck], SENSOR, RULE).tolist() == [False]
    assert horizontal_tops([], SENSOR, RULE).shape == (0,)
    assert horizontal_tops([np.zeros((0, 3)), deck], SENSOR, RULE).tolist() == [False, False]
