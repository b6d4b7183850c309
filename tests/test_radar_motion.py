"""Motion discriminator (paper 001, eq. 8, Table 1) and the convex-hull IoU it runs on."""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy.spatial import ConvexHull

from tracker.radar.config import RadarTrackerConfig
from tracker.radar.hull import clip_convex, convex_iou, padded_hull, point_group_iou, polygon_area
from tracker.radar.motion import MotionDiscriminator
from tracker.types import MotionState

AS, S, W, D, AD = (
    MotionState.ABSOLUTELY_STATIC,
    MotionState.STATIC,
    MotionState.WAIT,
    MotionState.DYNAMIC,
    MotionState.ABSOLUTELY_DYNAMIC,
)


def square(x0: float, y0: float, side: float) -> np.ndarray:
    return np.array([[x0, y0], [x0 + side, y0], [x0 + side, y0 + side], [x0, y0 + side]])


# --- hulls and their IoU -------------------------------------------------------------------------------------------


def test_iou_of_known_squares() -> None:
    a = square(0, 0, 2)
    assert convex_iou(a, square(1, 1, 2)) == pytest.approx(1 / 7)  # overlap 1 m^2 of 4 + 4 - 1
    assert convex_iou(a, square(1, 0, 2)) == pytest.approx(2 / 6)
    assert convex_iou(a, square(0.5, 0.5, 1)) == pytest.approx(1 / 4)  # contained
    assert convex_iou(a, square(5, 5, 1)) == 0.0  # disjoint
    assert convex_iou(a, a) == pytest.approx(1.0)
    assert polygon_area(clip_convex(a, square(1, 1, 2))) == pytest.approx(1.0)


def test_iou_matches_a_raster_reference_on_random_convex_polygons() -> None:
    rng = np.random.default_rng(5)
    g = np.linspace(-3, 3, 601)
    gx, gy = np.meshgrid(g, g, indexing="ij")
    cells = np.column_stack([gx.ravel(), gy.ravel()])

    def inside(poly: np.ndarray) -> np.ndarray:
        edges = np.roll(poly, -1, axis=0) - poly
        rel = cells[:, None, :] - poly[None, :, :]
        return np.all(edges[None, :, 0] * rel[:, :, 1] - edges[None, :, 1] * rel[:, :, 0] >= 0, axis=1)

    for _ in range(4):
        a = padded_hull(rng.normal(0, 1, (7, 2)), 0.0)
        b = padded_hull(rng.normal(0.5, 1, (6, 2)), 0.0)
        ia, ib = inside(a), inside(b)
        want = (ia & ib).sum() / (ia | ib).sum()
        assert convex_iou(a, b) == pytest.approx(want, abs=0.01)


def test_padded_hull_of_degenerate_groups() -> None:
    one = padded_hull(np.array([[1.0, 2.0]]), 0.5)
    assert polygon_area(one) == pytest.approx(1.0)  # one return -> a 1 m square
    line = padded_hull(np.array([[0.0, 0.0], [1.0, 0.0], [2.0, 0.0]]), 0.25)
    assert polygon_area(line) == pytest.approx(2.5 * 0.5)
    flat = padded_hull(np.array([[0.0, 0.0], [1.0, 0.0], [2.0, 0.0]]), 0.0)  # no pad: a segment, no area
    assert polygon_area(flat) == 0.0
    assert convex_iou(flat, flat) == 0.0
    assert padded_hull(np.array([[np.nan, 0.0]]), 0.5).shape == (0, 2)
    hull = padded_hull(np.random.default_rng(1).normal(size=(30, 2)), 0.0)
    assert polygon_area(hull) == pytest.approx(ConvexHull(hull).volume)  # counter-clockwise, same area
    assert point_group_iou(np.array([[0.0, 0.0]]), np.array([[0.5, 0.0]]), 0.5) == pytest.approx(1 / 3)


# --- discriminator ----------------------------------------------------------------------------------------------


def test_scripted_iou_sequence_walks_the_five_levels() -> None:
    md = MotionDiscriminator(RadarTrackerConfig())  # c = 0.5, Table 1 thresholds -6 / -3 / 3 / 6, |D| <= 6
    assert md.state is W and md.counter == 0
    script = [
        # (IoU, D after, level after)
        (0.9, -1, W),
        (0.9, -2, W),
        (0.9, -3, S),
        (0.8, -4, S),
        (0.8, -5, S),
        (0.7, -6, AS),
        (0.95, -6, AS),  # clamped at the limit
        (0.1, -5, S),
        (0.2, -4, S),
        (0.3, -3, S),
        (0.4, -2, W),
        (0.5, -1, W),  # IoU == c counts as moved (eq. 8: IoU <= c)
        (0.0, 0, W),
        (0.0, 1, W),
        (0.0, 2, W),
        (0.0, 3, D),
        (0.0, 4, D),
        (0.0, 5, D),
        (0.0, 6, AD),
        (0.0, 6, AD),
        (0.9, 5, D),
        (math.nan, 6, AD),  # no overlap computable: counts as moved
    ]
    for iou, d_after, level in script:
        assert md.step_iou(iou) is level, (iou, d_after)
        assert md.counter == d_after


def test_level_moves_only_to_an_adjacent_one() -> None:
    md = MotionDiscriminator(RadarTrackerConfig())
    md.state, md.counter = AS, 5  # e.g. a counter restored from elsewhere: Table 1 would say dynamic at once
    assert md.step_iou(0.0) is S
    assert md.step_iou(0.0) is W
    assert md.step_iou(0.0) is D
    assert md.step_iou(0.0) is AD


def test_published_velocity_follows_the_level() -> None:
    md = MotionDiscriminator(RadarTrackerConfig())
    kf_v = np.array([0.3, -0.2])
    assert np.isnan(md.velocity(kf_v)).all()  # wait: unknown
    for _ in range(3):
        md.step_iou(1.0)
    assert md.state is S
    np.testing.assert_array_equal(md.velocity(kf_v), [0.0, 0.0])
    for _ in range(3):
        md.step_iou(1.0)
    assert md.state is AS
    np.testing.assert_array_equal(md.velocity(kf_v), [0.0, 0.0])
    for _ in range(9):
        md.step_iou(0.0)
    assert md.state is D
    np.testing.assert_array_equal(md.velocity(kf_v), kf_v)


def test_observe_compares_consecutive_frames_with_zero_baseline() -> None:
    md = MotionDiscriminator(
        RadarTrackerConfig().replaced(motion={"hull_baseline_s": 0.0, "hull_point_pad_m": 0.0, "group_window_s": 0.0})
    )
    pts = square(0, 0, 2)
    assert md.observe(0.0, pts) is W and md.counter == 0  # nothing to compare with yet
    md.observe(0.1, pts)
    assert md.last_iou == pytest.approx(1.0) and md.counter == -1
    md.observe(0.2, pts + np.array([1.0, 0.0]))  # shifted half its length: IoU 1/3 <= 0.5
    assert md.last_iou == pytest.approx(1 / 3) and md.counter == 0
    md.observe(0.3, pts + np.array([1.0, 0.0]))
    assert md.last_iou == pytest.approx(1.0) and md.counter == -1


def test_observe_with_baseline_compares_with_the_hull_one_second_older() -> None:
    md = MotionDiscriminator(
        RadarTrackerConfig().replaced(motion={"hull_baseline_s": 1.0, "hull_point_pad_m": 0.0, "group_window_s": 0.0})
    )
    pts = square(0, 0, 2)
    speed = 1.0  # m/s north: 0.1 m per frame, 1 m per second
    for k in range(10):  # t = 0.0 .. 0.9: nothing a full second old yet
        md.observe(0.1 * k, pts + np.array([speed * 0.1 * k, 0.0]))
    assert md.counter == 0 and math.isnan(md.last_iou)
    md.observe(1.0, pts + np.array([speed * 1.0, 0.0]))  # against t = 0.0: shifted 1 m -> IoU 1/3
    assert md.last_iou == pytest.approx(1 / 3) and md.counter == 1
    md.observe(1.1, pts + np.array([speed * 1.1, 0.0]))  # against t = 0.1
    assert md.last_iou == pytest.approx(1 / 3) and md.counter == 2


@pytest.mark.parametrize("exact", [False, True], ids=["support-polygon", "qhull"])
def test_point_group_accumulates_recent_frames(exact: bool) -> None:
    # Two returns per frame alternate between opposite corners: one frame's hull is a sliver, the 0.25 s group's
    # hull (three frames) is the whole 2 x 2 square, so the comparison one second apart sees full overlap.
    cfg = RadarTrackerConfig().replaced(
        motion={"hull_baseline_s": 1.0, "hull_point_pad_m": 0.0, "group_window_s": 0.25, "hull_exact": exact}
    )
    md = MotionDiscriminator(cfg)
    a = np.array([[0.0, 0.0], [2.0, 2.0]])
    b = np.array([[2.0, 0.0], [0.0, 2.0]])
    ious = []
    for k in range(13):
        md.observe(0.1 * k, a if k % 2 == 0 else b)
        ious.append(md.last_iou)
    # t = 1.0 compares with the group of t = 0.0, which had only its first frame (a segment): IoU 0, "moved".
    # From t = 1.1 on both groups are the full square.
    assert np.isnan(ious[:10]).all()
    assert ious[10:] == [0.0, pytest.approx(1.0), pytest.approx(1.0)]
    assert md.counter == -1
    alone = MotionDiscriminator(cfg.replaced(motion={"group_window_s": 0.0}))
    for k in range(13):
        alone.observe(0.1 * k, a if k % 2 == 0 else b)
    assert alone.last_iou == 0.0 and alone.counter == 3  # the single-frame "hulls" are segments: always "moved"


def test_doppler_veto_counts_as_moved() -> None:
    cfg = RadarTrackerConfig().replaced(motion={"hull_baseline_s": 0.0, "group_window_s": 0.0})
    md = MotionDiscriminator(cfg)
    pts = square(0, 0, 2)
    md.observe(0.0, pts)
    md.observe(0.1, pts, doppler_moving=True)
    # Full overlap, but the Doppler says it moves: counted as moved without building the hulls at all.
    assert math.isnan(md.last_iou) and md.counter == 1
    off = MotionDiscriminator(cfg.replaced(motion={"doppler_veto": False}))
    off.observe(0.0, pts)
    off.observe(0.1, pts, doppler_moving=True)
    assert off.counter == -1


def test_vectorised_intersection_area_equals_clipping() -> None:
    from tracker.radar.hull import convex_intersection_area

    rng = np.random.default_rng(9)
    for _ in range(300):
        a = padded_hull(rng.normal(0, 1, (int(rng.integers(1, 12)), 2)), 0.15)
        b = padded_hull(rng.normal(rng.normal(0, 1, 2), 1, (int(rng.integers(1, 12)), 2)), 0.15)
        want = max(polygon_area(clip_convex(a, b)), 0.0)
        assert convex_intersection_area(a, b) == pytest.approx(want, abs=1e-9)
    sq = np.array([[0.0, 0.0], [2.0, 0.0], [2.0, 2.0], [0.0, 2.0]])
    assert convex_intersection_area(sq, sq + np.array([1.0, 1.0])) == pytest.approx(1.0)
    assert convex_intersection_area(sq, sq + np.array([3.0, 0.0])) == 0.0


def test_support_polygon_iou_matches_the_hull_iou_on_radar_groups() -> None:
    from tracker.radar.hull import outline_area, support_area, support_frame, support_iou, support_offsets

    # Exact where the fan of 16 directions holds the shape: squares, a padded point, a square pad on a segment.
    assert outline_area(support_offsets(square(0, 0, 2), 0.0)) == pytest.approx(4.0)
    assert outline_area(support_offsets(np.array([[3.0, -1.0]]), 0.25)) == pytest.approx(0.25)
    seg = np.array([[0.0, 0.0], [2.0, 0.0]])
    assert outline_area(support_offsets(seg, 0.5)) == pytest.approx(3.0)  # 3 x 1 rectangle
    assert support_iou(support_offsets(seg, 0.0), support_offsets(seg, 0.0)) == 0.0  # no area, no IoU
    assert support_iou(support_offsets(square(0, 0, 2), 0.0), support_offsets(square(1, 1, 2), 0.0)) == pytest.approx(
        1 / 7
    )
    assert support_iou(support_offsets(square(0, 0, 1), 0.1), support_offsets(square(5, 5, 1), 0.1)) == 0.0
    assert support_offsets(np.array([[np.nan, 1.0]]), 0.1) is None and support_iou(None, None) == 0.0
    assert support_frame(np.array([[np.nan, 1.0]])) is None
    # The general area (any offsets, redundant lines included) agrees with the outline where both apply.
    h = support_offsets(np.random.default_rng(3).normal(size=(9, 2)), 0.15)
    assert support_area(h) == pytest.approx(outline_area(h), abs=1e-9)
    # In the group's own frame (centre, principal axes) a segment at any angle is a segment - and a padded one a
    # rectangle - and nothing depends on where in the world the group lies.
    turn = np.array([[np.cos(0.4), -np.sin(0.4)], [np.sin(0.4), np.cos(0.4)]])
    tilted = seg @ turn.T + np.array([5.0e4, -3.0e4])
    frame = support_frame(tilted)
    assert outline_area(support_offsets(tilted, 0.0, frame)) == pytest.approx(0.0, abs=1e-9)
    assert outline_area(support_offsets(tilted, 0.5, frame)) == pytest.approx(3.0)
    assert support_iou(support_offsets(tilted, 0.15, frame), support_offsets(tilted, 0.15, frame)) == pytest.approx(1.0)
    # Radar-like groups 100 km from the origin at any heading - a filled 3 x 2 m hull, or the returns of its near side
    # only (the thin case) - shifted up to 1.5 m along it: in the first group's frame the IoU is the convex hull's
    # (pads in the same frame) within 0.025 on average and 0.15 always, inside the 0.4-0.8 scatter of a sparse hull's
    # IoU with itself a second later.
    rng = np.random.default_rng(8)
    for thin in (False, True):
        diff = []
        for _ in range(200):
            n_a, n_b = rng.integers(12, 31, 2)
            heading = rng.uniform(0.0, np.pi)
            rot = np.array([[np.cos(heading), -np.sin(heading)], [np.sin(heading), np.cos(heading)]])

            def hull_points(n: int, thin: bool = thin) -> np.ndarray:
                if thin:
                    return np.column_stack([rng.uniform(-1.5, 1.5, n), rng.normal(0.0, 0.1, n)])
                return rng.uniform([-1.5, -1.0], [1.5, 1.0], (n, 2))

            origin = np.array([1.0e5, 3.0e4])
            a = hull_points(n_a) @ rot.T + origin
            b = (hull_points(n_b) + np.array([rng.uniform(-1.5, 1.5), 0.0])) @ rot.T + origin
            f = support_frame(a)
            exact = convex_iou(padded_hull((a - f[0]) @ f[1], 0.15), padded_hull((b - f[0]) @ f[1], 0.15))
            diff.append(support_iou(support_offsets(a, 0.15, f), support_offsets(b, 0.15, f)) - exact)
        assert abs(np.mean(diff)) < 0.025 and np.max(np.abs(diff)) < 0.15
