"""Grouping points by integer cell keys with one sort, the building block of the grid-based neighbour searches; and
nodes into the connected components of their edges."""

from __future__ import annotations

import numpy as np


def group_keys(keys: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Group equal integer keys: (order, starts, counts, inverse).

    ``keys[order]`` is sorted; group g is ``order[starts[g] : starts[g] + counts[g]]`` and groups come in key
    order; ``inverse[i]`` is element i's group. The sort is a stable one on purpose: a scan's cell keys come
    in long runs (the sweep walks round the boat), which it exploits - 0.15 ms for a revolution's keys here
    against 1.1 ms for the default quicksort and 1.3 ms for ``np.unique``.
    """
    order, starts, counts, new = _grouped(keys)
    inverse = np.empty(order.shape[0], dtype=np.intp)
    inverse[order] = np.cumsum(new) - 1
    return order, starts, counts, inverse


def group_order(keys: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """:func:`group_keys` without the inverse, for callers that do not need it (a pass over the keys saved)."""
    order, starts, counts, _ = _grouped(keys)
    return order, starts, counts


def _grouped(keys: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """(order, starts, counts, whether each sorted key starts a group)."""
    keys = np.asarray(keys).ravel()
    n = keys.shape[0]
    order = stable_order(keys)
    sorted_keys = keys[order]
    new = np.ones(n, dtype=bool)
    new[1:] = sorted_keys[1:] != sorted_keys[:-1]
    starts = np.flatnonzero(new)
    counts = np.diff(np.append(starts, n))
    return order, starts, counts, new


def expand_groups(order: np.ndarray, starts: np.ndarray, counts: np.ndarray, groups: np.ndarray) -> np.ndarray:
    """The elements of ``groups`` (indices into ``starts``/``counts``), group after group, as one index array."""
    cnt = counts[groups]
    total = int(cnt.sum())
    if total == 0:
        return np.zeros(0, dtype=np.intp)
    # Position p of the output belongs to group g = groups[k]: its element is order[starts[g] + (p - first_p(k))].
    first = np.cumsum(cnt) - cnt
    return order[np.repeat(starts[groups] - first, cnt) + np.arange(total)]


_RADIX_FROM = 2048  # below this many keys the two passes' overhead outweighs what they save


def stable_order(keys: np.ndarray) -> np.ndarray:
    """np.argsort(keys, kind="stable"), the same permutation. Non-negative integer keys below 2**32 are sorted by
    two 16-bit passes, low half then high half (a stable sort by each half in turn is the stable sort by the
    whole key): numpy radix-sorts 16-bit integers, 1.5x (a scan's cell keys) to 6x (random keys) faster than its
    merge sort of 64-bit ones."""
    keys = np.asarray(keys)
    if keys.dtype.kind not in "iu" or keys.size < _RADIX_FROM or keys.min() < 0 or keys.max() >= 1 << 32:
        return np.argsort(keys, kind="stable")
    order = np.argsort((keys & 0xFFFF).astype(np.uint16), kind="stable")
    if keys.max() < 1 << 16:
        return order
    return order[np.argsort((keys[order] >> 16).astype(np.uint16), kind="stable")]


def component_labels(n: int, a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """(n,) connected-component label of each node given edges a[k] - b[k]: the lowest node index in its component.

    Root hooking with edge filtering: every node points at a root; each round, every edge still joining two
    different roots hooks the higher root onto the lower, pointers are flattened, and edges inside one root's tree
    are dropped for good. A component's lowest node is never hooked, so it ends as the root of all its nodes. The
    edge list shrinks each round, so a shore window's ~16k cell links cost a quarter of what min-label propagation
    over all of them every round did; for the few hundred nodes of a radar frame this is several times faster than
    building a sparse matrix for scipy's connected_components (and for a LiDAR scan's dozen wall pieces, a tenth of
    what scipy takes for the graph's validation alone).
    """
    lab = np.arange(n)
    if a.size == 0:
        return lab
    while True:
        la, lb = lab[a], lab[b]
        cross = la != lb
        if not cross.any():
            return lab
        a, b, la, lb = a[cross], b[cross], la[cross], lb[cross]
        np.minimum.at(lab, np.maximum(la, lb), np.minimum(la, lb))
        while True:  # flatten: every node points at its root again
            up = lab[lab]
            if np.array_equal(up, lab):
                break
            lab = up


def lowest_to_ranks(lowest: np.ndarray, roots: np.ndarray | None = None) -> np.ndarray:
    """(n,) component number 0..k-1 of each node from ``component_labels``' lowest-node labels, numbered in the
    order of the components' lowest nodes (what ``np.unique(lowest, return_inverse=True)`` gives, without its
    sort). ``roots``: (n,) bool, the nodes whose components count (their lowest nodes); others get -1."""
    is_root = lowest == np.arange(lowest.size)
    if roots is not None:
        is_root &= roots
    rank = np.cumsum(is_root) - 1
    return np.where(is_root[lowest], rank[lowest], -1)
