"""Grouping points by integer cell keys with one sort: the building block of the grid-based neighbour searches."""

from __future__ import annotations

import numpy as np


def group_keys(keys: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Group equal integer keys: (order, starts, counts, inverse).

    ``keys[order]`` is sorted; group g is ``order[starts[g] : starts[g] + counts[g]]`` and groups come in key
    order; ``inverse[i]`` is element i's group. The sort is numpy's stable one on purpose: a scan's cell keys come
    in long runs (the sweep walks round the boat), which it exploits - 0.15 ms for a revolution's keys here
    against 1.1 ms for the default quicksort and 1.3 ms for ``np.unique``.
    """
    keys = np.asarray(keys).ravel()
    n = keys.shape[0]
    order = np.argsort(keys, kind="stable")
    sorted_keys = keys[order]
    new = np.ones(n, dtype=bool)
    new[1:] = sorted_keys[1:] != sorted_keys[:-1]
    starts = np.flatnonzero(new)
    counts = np.diff(np.append(starts, n))
    inverse = np.empty(n, dtype=np.intp)
    inverse[order] = np.cumsum(new) - 1
    return order, starts, counts, inverse


def expand_groups(order: np.ndarray, starts: np.ndarray, counts: np.ndarray, groups: np.ndarray) -> np.ndarray:
    """The elements of ``groups`` (indices into ``starts``/``counts``), group after group, as one index array."""
    cnt = counts[groups]
    total = int(cnt.sum())
    if total == 0:
        return np.zeros(0, dtype=np.intp)
    # Position p of the output belongs to group g = groups[k]: its element is order[starts[g] + (p - first_p(k))].
    first = np.cumsum(cnt) - cnt
    return order[np.repeat(starts[groups] - first, cnt) + np.arange(total)]
