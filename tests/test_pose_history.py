"""PoseHistory: interpolation on the host clock, the circle, the extrapolation limit, and no-ego-pose mode."""

from __future__ import annotations

import math
import threading

import numpy as np
import pytest

from daemon.pose_history import PoseHistory, wrap_angle
from drivers.frames import EgoPose


def pose(t: float, pos=(0.0, 0.0, 0.0), vel=(0.0, 0.0, 0.0), roll=0.0, pitch=0.0, yaw=0.0, yaw_rate=0.0) -> EgoPose:
    return EgoPose(t, np.array(pos, float), np.array(vel, float), roll, pitch, yaw, yaw_rate)


def test_yaw_wrap_interpolates_through_north_exactly() -> None:
    h = PoseHistory()
    h.add(pose(10.0, yaw=math.radians(359.0)))
    h.add(pose(11.0, yaw=math.radians(1.0)))
    mid = h.at(10.5)
    assert mid is not None
    assert mid.yaw == pytest.approx(0.0, abs=1e-12)
    quarter = h.at(10.25)
    assert quarter is not None
    assert math.degrees(quarter.yaw) == pytest.approx(-0.5, abs=1e-9)
    # and the other way round, through +-180 (south)
    h2 = PoseHistory()
    h2.add(pose(0.0, yaw=math.radians(179.0)))
    h2.add(pose(1.0, yaw=math.radians(-179.0)))
    s = h2.at(0.75)
    assert s is not None
    assert math.degrees(s.yaw) == pytest.approx(-179.5, abs=1e-9)


def test_linear_position_velocity_and_roll_wrap() -> None:
    h = PoseHistory()
    h.add(pose(1.0, pos=(0, 0, 0), vel=(1, 0, 0), roll=math.radians(-179), pitch=0.1))
    h.add(pose(2.0, pos=(10, -4, 1), vel=(3, 0, 0), roll=math.radians(179), pitch=0.3))
    p = h.at(1.25)
    assert p is not None
    np.testing.assert_allclose(p.position, [2.5, -1.0, 0.25], atol=1e-12)
    np.testing.assert_allclose(p.velocity, [1.5, 0, 0], atol=1e-12)
    assert math.degrees(p.roll) == pytest.approx(-179.5, abs=1e-9)  # shorter arc: -179 -> -181
    assert p.pitch == pytest.approx(0.15, abs=1e-12)
    assert p.t == 1.25
    # exactly on a sample: that sample
    q = h.at(2.0)
    assert q is not None
    np.testing.assert_allclose(q.position, [10, -4, 1], atol=1e-12)


def test_extrapolation_limit_and_velocity_extrapolation() -> None:
    h = PoseHistory(max_extrapolation=0.3)
    h.add(pose(5.0, pos=(0, 0, 0), vel=(2, 1, 0), yaw=0.0, yaw_rate=0.5))
    h.add(pose(6.0, pos=(2, 1, 0), vel=(2, 1, 0), yaw=0.5, yaw_rate=0.5))
    ahead = h.at(6.2)
    assert ahead is not None
    np.testing.assert_allclose(ahead.position, [2.4, 1.2, 0], atol=1e-12)
    assert ahead.yaw == pytest.approx(0.6, abs=1e-12)
    behind = h.at(4.9)
    assert behind is not None
    np.testing.assert_allclose(behind.position, [-0.2, -0.1, 0], atol=1e-12)
    assert h.at(6.31) is None
    assert h.at(4.69) is None
    assert PoseHistory().at(1.0) is None  # empty


def test_a_rolling_boats_attitude_is_extrapolated_with_its_rates_not_held() -> None:
    """The busy-machine case: ATTITUDE stopped arriving 0.25 s before the scan's newest point. The boat rolls
    5 deg over 5 s and pitches 3 deg over 3.7 s (peak rates 6.3 and 5.1 deg/s). Held, the roll would be wrong by
    over a degree -- the water 20 m off would stand 0.4 m high; with its rate it is wrong by no more than the
    sinusoid's curvature over 0.25 s allows, A w^2 dt^2 / 2: 0.25 deg of roll, 0.27 deg of pitch (9 cm at 20 m)."""
    w_r, w_p = 2 * math.pi / 5.0, 2 * math.pi / 3.7
    a_r, a_p = math.radians(5.0), math.radians(3.0)
    h = PoseHistory(max_extrapolation=0.3)
    t_last = 4.9  # near a zero crossing of the roll: its rate is the largest
    for t in np.arange(4.0, t_last + 1e-9, 0.02):
        h.add(
            EgoPose(
                float(t), np.zeros(3), np.zeros(3), a_r * math.sin(w_r * t), a_p * math.sin(w_p * t), 0.0,
                roll_rate=a_r * w_r * math.cos(w_r * t), pitch_rate=a_p * w_p * math.cos(w_p * t),
            )
        )  # fmt: skip
    t_q = t_last + 0.25
    got = h.at(t_q)
    assert got is not None
    held = a_r * math.sin(w_r * t_last)
    assert abs(held - a_r * math.sin(w_r * t_q)) > math.radians(1.0)  # the case is meaningful
    dt = t_q - t_last
    assert abs(got.roll - a_r * math.sin(w_r * t_q)) <= 0.5 * a_r * w_r**2 * dt**2 + 1e-9
    assert abs(got.pitch - a_p * math.sin(w_p * t_q)) <= 0.5 * a_p * w_p**2 * dt**2 + 1e-9
    _pos, roll, pitch, _yaw = h.at_many(np.array([t_q]))
    assert roll[0] == pytest.approx(got.roll, abs=1e-12) and pitch[0] == pytest.approx(got.pitch, abs=1e-12)


def test_long_gap_is_not_interpolated_across() -> None:
    h = PoseHistory(max_extrapolation=0.3, max_gap=1.0)
    h.add(pose(0.0, pos=(0, 0, 0), vel=(1, 0, 0)))
    h.add(pose(5.0, pos=(100, 0, 0), vel=(1, 0, 0)))
    near_first = h.at(0.2)
    assert near_first is not None
    np.testing.assert_allclose(near_first.position, [0.2, 0, 0], atol=1e-12)  # reckoned, not 4.0
    near_second = h.at(4.9)
    assert near_second is not None
    np.testing.assert_allclose(near_second.position, [99.9, 0, 0], atol=1e-12)
    assert h.at(2.5) is None


def test_at_many_matches_at_and_marks_unknown_rows_nan() -> None:
    h = PoseHistory(max_extrapolation=0.3)
    rng = np.random.default_rng(3)
    ts = np.arange(0.0, 2.0, 0.02)
    for t in ts:
        h.add(
            pose(
                t,
                pos=(3 * t, -t, 0.01 * t),
                vel=(3, -1, 0.01),
                roll=0.05 * math.sin(t),
                yaw=wrap_angle(3.0 + 0.8 * t),
                yaw_rate=0.8,
            )
        )
    q = np.concatenate([rng.uniform(-0.2, 2.2, 200), [-0.5, 3.0, np.nan]])
    pos, roll, pitch, yaw = h.at_many(q)
    assert pos.shape == (203, 3) and roll.shape == pitch.shape == yaw.shape == (203,)
    for i, t in enumerate(q):
        single = h.at(float(t))
        if single is None:
            assert np.isnan(pos[i]).all() and np.isnan(yaw[i])
        else:
            np.testing.assert_allclose(pos[i], single.position, atol=1e-12)
            assert yaw[i] == pytest.approx(single.yaw, abs=1e-12)
            assert roll[i] == pytest.approx(single.roll, abs=1e-12)
    assert np.isnan(yaw[-3:]).all()
    inside = (q >= 0) & (q <= ts[-1])
    np.testing.assert_allclose(pos[inside, 0], 3 * q[inside], atol=1e-9)  # linear motion is reproduced exactly
    np.testing.assert_allclose(yaw[inside], wrap_angle(3.0 + 0.8 * q[inside]), atol=1e-9)


def test_a_query_reads_the_same_pose_whatever_else_is_asked_with_it() -> None:
    """at_many copies only the samples its queries can reach; a time's answer must not depend on that window: the
    same bits asked alone, with its neighbours, or beside the history's whole span (a gap longer than max_gap,
    both ends of the history, exact sample times, NaN)."""
    h = PoseHistory(max_extrapolation=0.3, max_gap=1.0)
    rng = np.random.default_rng(11)
    sample_t = np.concatenate([np.arange(0.0, 3.0, 0.05), np.arange(4.5, 6.0, 0.05)])  # 1.55 s gap
    for t in sample_t:
        h.add(pose(t, pos=(2 * t, math.sin(t), 0.0), vel=(2, math.cos(t), 0), roll=0.1 * math.sin(3 * t), yaw=t))
    q = np.concatenate([rng.uniform(-0.5, 6.5, 300), sample_t[::7], [2.96, 3.1, 3.5, 4.4, 4.5, np.nan]])
    together = h.at_many(q)
    wide = h.at_many(np.concatenate([q, [-1.0, 7.0]]))
    for k in range(4):
        np.testing.assert_array_equal(wide[k][: q.size], together[k])
    for i, t in enumerate(q):
        alone = h.at_many(np.array([t]))
        for k in range(4):
            np.testing.assert_array_equal(alone[k][0], together[k][i])
    pos = together[0]
    assert np.isnan(pos[q.size - 4]).all()  # 3.5 s: 0.55 s past the gap's start, 1 s before its end: unknown
    # 3.1 s reckoned on from the last sample before the gap (2.95 s), 4.4 s back from the first after it (4.5 s)
    np.testing.assert_allclose(pos[q.size - 5], [2 * 3.1, math.sin(2.95) + math.cos(2.95) * 0.15, 0], atol=1e-9)
    np.testing.assert_allclose(pos[q.size - 3], [2 * 4.4, math.sin(4.5) - math.cos(4.5) * 0.1, 0], atol=1e-9)
    np.testing.assert_allclose(pos[q.size - 2, 0], 2 * 4.5, atol=1e-12)


def test_bounded_capacity_keeps_the_newest() -> None:
    h = PoseHistory(capacity=50)
    for i in range(275):
        h.add(pose(float(i), pos=(i, 0, 0), vel=(1, 0, 0)))
    assert len(h) == 50
    assert h.oldest_time == 225.0 and h.newest_time == 274.0
    p = h.at(250.5)
    assert p is not None and p.position[0] == pytest.approx(250.5)
    assert h.at(100.0) is None


def test_out_of_order_sample_is_inserted_in_place_and_bad_samples_rejected() -> None:
    h = PoseHistory()
    h.add(pose(0.0, pos=(0, 0, 0)))
    h.add(pose(2.0, pos=(2, 0, 0)))
    h.add(pose(1.0, pos=(5, 0, 0)))  # late arrival
    assert h.reordered == 1 and len(h) == 3
    p = h.at(0.5)
    assert p is not None and p.position[0] == pytest.approx(2.5)
    h.add(pose(1.0, pos=(1, 0, 0)))  # same instant again: replaced, not duplicated
    assert len(h) == 3
    p = h.at(0.5)
    assert p is not None and p.position[0] == pytest.approx(0.5)
    assert not h.add(pose(3.0, pos=(np.nan, 0, 0)))
    assert not h.add(pose(float("inf")))
    assert h.rejected == 2 and len(h) == 3
    latest = h.latest()
    assert latest is not None and latest.t == 2.0


def test_no_ego_pose_mode_is_the_identity() -> None:
    h = PoseHistory.identity()
    assert h.no_ego_pose
    assert not h.add(pose(1.0, pos=(5, 5, 5), yaw=1.0))
    p = h.at(123.4)
    assert p is not None
    assert p.t == 123.4 and p.yaw == 0.0 and p.roll == 0.0 and p.pitch == 0.0
    np.testing.assert_array_equal(p.position, np.zeros(3))
    pos, roll, pitch, yaw = h.at_many(np.array([1.0, 2.0, 3.0]))
    np.testing.assert_array_equal(pos, np.zeros((3, 3)))
    np.testing.assert_array_equal(np.stack([roll, pitch, yaw]), np.zeros((3, 3)))


def test_concurrent_writer_and_readers_see_consistent_data() -> None:
    """A writer appending a straight line while readers query: every answer lies on that line."""
    h = PoseHistory(capacity=100)
    errors: list[str] = []
    stop = threading.Event()

    def writer() -> None:
        for i in range(3000):
            t = i * 0.01
            h.add(pose(t, pos=(2 * t, 0, 0), vel=(2, 0, 0)))
        stop.set()

    def reader() -> None:
        while not stop.is_set():
            newest = h.newest_time
            if newest is None:
                continue
            q = np.linspace(newest - 0.5, newest, 64)
            pos, _r, _p, _y = h.at_many(q)
            ok = ~np.isnan(pos[:, 0])
            if not np.allclose(pos[ok, 0], 2 * q[ok], atol=1e-9):
                errors.append("off the line")

    threads = [threading.Thread(target=writer)] + [threading.Thread(target=reader) for _ in range(2)]
    for th in threads:
        th.start()
    for th in threads:
        th.join(10)
    assert not errors
    assert len(h) == 100


def test_sampled_poses_place_a_turning_boats_returns_within_a_centimetre() -> None:
    # 5 m/s north while turning 20 deg/s: a revolution's returns at 50 m placed with a pose every 1 ms land within
    # 1.2 cm of where their own exactly interpolated pose puts them.
    from tracker.ego import PoseTable, sample_poses

    h = PoseHistory()
    rate = math.radians(20.0)
    for k in range(30):
        t = 0.01 * k
        h.add(pose(t, pos=(5.0 * t, 0.0, 0.0), vel=(5.0, 0.0, 0.0), yaw=rate * t, yaw_rate=rate))
    t = np.linspace(0.1, 0.2, 2000)
    az = np.linspace(0.0, 2 * math.pi, 2000)
    body = np.column_stack([50.0 * np.cos(az), 50.0 * np.sin(az), np.full(2000, -1.0)])
    (pos, roll, pitch, yaw), index = sample_poses(h, t)
    assert index is not None and 101 <= yaw.size <= 102  # one every 1 ms over the 100 ms sweep
    sampled, _ = PoseTable.of(pos, roll, pitch, yaw, 2000, index).body_to_world(body, np.arange(2000))
    exact, _ = PoseTable.of(*h.at_many(t), 2000).body_to_world(body, np.arange(2000))
    err = np.linalg.norm(sampled - exact, axis=1)
    assert 0.005 < err.max() < 0.012
    # a point without a time: every point gets its own pose, the timeless one none
    t[5] = np.nan
    (_, _, _, yaw_each), index = sample_poses(h, t)
    assert index is None and np.isnan(yaw_each[5]) and np.isfinite(np.delete(yaw_each, 5)).all()


def test_a_scan_with_a_wild_timestamp_gets_a_pose_per_point() -> None:
    # One point 600 s off (a bad packet time): no 600,000 pose samples, each point its own pose (the wild one none).
    from tracker.ego import sample_poses

    h = PoseHistory()
    for k in range(30):
        h.add(pose(0.01 * k, pos=(0.1 * k, 0.0, 0.0), vel=(10.0, 0.0, 0.0)))
    t = np.array([0.10, 0.15, 600.0])
    (pos, _, _, yaw), index = sample_poses(h, t)
    assert index is None and pos.shape == (3, 3)
    assert pos[:2, 0] == pytest.approx([1.0, 1.5]) and np.isnan(yaw[2])
