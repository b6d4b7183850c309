"""Grids that follow the boat shift in place with exactly the values a new array would have had."""

from __future__ import annotations

import tracemalloc

import numpy as np
import pytest

from tracker.grid_shift import shift_in_place


def shifted_copy(a: np.ndarray, di: int, dj: int, fill: float) -> np.ndarray:
    """How the static map and the structure memory shifted before: a new array."""
    n, m = a.shape
    new = np.full_like(a, fill)
    src_i, dst_i = slice(max(di, 0), n + min(di, 0)), slice(max(-di, 0), n + min(-di, 0))
    src_j, dst_j = slice(max(dj, 0), m + min(dj, 0)), slice(max(-dj, 0), m + min(-dj, 0))
    if src_i.start < src_i.stop and src_j.start < src_j.stop:
        new[dst_i, dst_j] = a[src_i, src_j]
    return new


def test_every_shift_gives_the_new_arrays_values_bit_for_bit() -> None:
    rng = np.random.default_rng(14)
    for _ in range(2000):
        n, m = (int(x) for x in rng.integers(1, 10, 2))
        a = rng.normal(size=(n, m))
        a[rng.random((n, m)) < 0.2] = -np.inf
        di, dj = (int(x) for x in rng.integers(-12, 13, 2))
        want = shifted_copy(a, di, dj, -np.inf)
        shift_in_place(a, di, dj, -np.inf)
        assert a.tobytes() == want.tobytes(), (n, m, di, dj)


@pytest.mark.parametrize(("di", "dj"), [(400, 0), (0, -400), (-400, 400), (800, -800), (1200, 0)])
def test_a_static_map_sized_grid_shifts_without_a_second_grid(di: int, dj: int) -> None:
    grid = np.random.default_rng(1).random((1200, 1200))  # the radar static map: 11 MB
    want = shifted_copy(grid, di, dj, 0.0)
    tracemalloc.start()  # numpy reports its buffers to tracemalloc
    try:
        shift_in_place(grid, di, dj, 0.0)
        peak = tracemalloc.get_traced_memory()[1]
    finally:
        tracemalloc.stop()
    assert grid.tobytes() == want.tobytes()
    assert peak < 64 * 1024, peak


def test_a_strided_view_is_refused() -> None:
    with pytest.raises(ValueError, match="C-contiguous"):
        shift_in_place(np.zeros((4, 6))[:, ::2], 1, 0, 0.0)
