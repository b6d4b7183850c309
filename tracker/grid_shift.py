"""Move a world grid that follows the own boat, in place.

The radar static map (two 1200 x 1200 float grids, 11 MB each) and the LiDAR structure memory (2.8 MB) used to
shift by making a new array and dropping the old one. That cost the daemon 20-40 MB of RSS (bench/soak.py, issue
#14): freeing the first 11 MB grid raised glibc's mmap threshold to 11 MB, so the later grids and every smaller numpy
array were carved from the main heap, and each shift left the old grids' pages free but resident in it (the main
arena grew to 66-98 MB, up to 36 MB of it free; Python's own objects stayed flat under tracemalloc). Shifted in
place, the grids keep their one allocation for the whole run.
"""

from __future__ import annotations

import numpy as np


def shift_in_place(a: np.ndarray, di: int, dj: int, fill: float) -> None:
    """``a[i, j] = a[i + di, j + dj]`` where that cell lies in ``a``, else ``fill``: the values

        new = np.full_like(a, fill); new[dst_i, dst_j] = a[src_i, src_j]

    gives, in ``a`` itself and without a temporary of its size. ``a``: 2-D, C-contiguous.

    For such an array, cell (i + di, j + dj) lies ``di * columns + dj`` elements after (i, j) in memory, so one
    overlapping 1-D copy of the flat view moves every cell (numpy copies an overlapping 1-D view in the safe order,
    as memmove does, with no temporary); the rows and columns that had no source are filled afterwards.
    """
    if a.ndim != 2 or not a.flags.c_contiguous:
        raise ValueError("shift_in_place needs a C-contiguous 2-D array")
    n, m = a.shape
    di, dj = int(di), int(dj)
    if abs(di) >= n or abs(dj) >= m:
        a.fill(fill)
        return
    flat = a.reshape(-1)  # a view (C-contiguous)
    offset = di * m + dj
    if offset > 0:
        flat[: flat.size - offset] = flat[offset:]
    elif offset < 0:
        flat[-offset:] = flat[: flat.size + offset]
    if di > 0:
        a[n - di :, :] = fill
    elif di < 0:
        a[:-di, :] = fill
    if dj > 0:
        a[:, m - dj :] = fill
    elif dj < 0:
        a[:, :-dj] = fill
