"""The 10 Hz loop locks its phase to the LiDAR's revolutions, so none is dropped for arriving at a tick's edge."""

from __future__ import annotations

import numpy as np
import pytest

from daemon.loop import LidarPhaseLock, TickSchedule, lidar_phase_shift

PERIOD = 0.1


def run_ticks(
    gain_on: bool, start_offset: float, seed: int = 1, n_ticks: int = 600, lidar_period: float = PERIOD
) -> tuple[np.ndarray, np.ndarray]:
    """Drive the loop's real scheduling with a simulated VLP-16: revolutions every ``lidar_period`` x (1 + 30 ppm)
    on its own clock, each delivered up to 20 ms late (socket, reader batching). Returns per tick how many
    revolutions arrived since the previous tick, and the tick times."""
    rng = np.random.default_rng(seed)
    n = int(n_ticks * PERIOD / lidar_period) + 50
    arrivals = np.sort(start_offset + np.arange(n) * lidar_period * (1 + 30e-6) + rng.uniform(0.0, 0.02, n))
    schedule, lock = TickSchedule(PERIOD, PERIOD), LidarPhaseLock(PERIOD)
    now, last_tick, counts, times = PERIOD, 0.0, [], []
    for _ in range(n_ticks):
        got = arrivals[(arrivals > last_tick) & (arrivals <= now)]
        counts.append(got.size)
        times.append(now)
        earlier = arrivals[arrivals <= now]
        last_put = earlier[-1] if earlier.size else -np.inf
        shift = lock.shift(now, last_put, earlier.size) if gain_on else 0.0
        last_tick = now
        done = now + 0.012  # the cycle's own time
        now = done + schedule.after_tick(done, shift)
    return np.array(counts), np.array(times)


def ticks_per_revolution(gain_on: bool, start_offset: float) -> np.ndarray:
    return run_ticks(gain_on, start_offset)[0]


@pytest.mark.parametrize("lidar_period", [0.05, 0.2])
def test_a_lidar_at_another_rate_leaves_the_loop_rate_alone(lidar_period: float) -> None:
    # 1200 rpm (20 Hz) or 300 rpm (5 Hz) against the 10 Hz loop: no lock, so no tick is pushed and the rate holds.
    _, times = run_ticks(True, 0.0, lidar_period=lidar_period)
    assert np.mean(np.diff(times[10:])) == pytest.approx(PERIOD, rel=1e-4)  # after the first (late) deadline


@pytest.mark.parametrize("start_offset", [0.0, 0.005, 0.05, 0.095])
def test_locked_loop_meets_every_revolution_once(start_offset: float) -> None:
    counts = ticks_per_revolution(True, start_offset)[100:]  # locked within the first 10 s
    assert counts.tolist() == [1] * counts.size


def test_unlocked_loop_at_the_edge_drops_revolutions() -> None:
    # The same stream with the phase left alone: ticks at the arrivals' edge see 0 or 2 (one of them dropped).
    counts = ticks_per_revolution(False, 0.09)[100:]  # arrivals 0.09-0.11 s after each tick time
    assert (counts == 2).sum() > 50 and (counts == 0).sum() > 50


def test_phase_shift_direction_and_bounds() -> None:
    assert lidar_phase_shift(0.05, PERIOD) == 0.0  # already halfway
    assert lidar_phase_shift(0.01, PERIOD) == pytest.approx(0.005)  # just after an arrival: tick later (capped)
    assert lidar_phase_shift(0.06, PERIOD) == pytest.approx(-0.002)  # a little late: tick 2 ms earlier
    assert lidar_phase_shift(float("inf"), PERIOD) == 0.0  # no LiDAR
    assert lidar_phase_shift(0.25, PERIOD) == 0.0  # none this period
