"""Grouping by integer keys with one sort (the grid searches' building block)."""

from __future__ import annotations

import numpy as np

from tracker.grouping import component_labels, expand_groups, group_keys, lowest_to_ranks


def test_groups_come_in_key_order_with_their_members() -> None:
    keys = np.array([7, 3, 7, 9, 3, 3])
    order, starts, counts, inverse = group_keys(keys)
    assert keys[order].tolist() == [3, 3, 3, 7, 7, 9]
    assert starts.tolist() == [0, 3, 5] and counts.tolist() == [3, 2, 1]
    assert inverse.tolist() == [1, 0, 1, 2, 0, 0]
    # stable: equal keys keep their input order
    assert order[:3].tolist() == [1, 4, 5]


def test_expand_groups_lists_members_group_after_group() -> None:
    keys = np.array([7, 3, 7, 9, 3, 3])
    order, starts, counts, _ = group_keys(keys)
    assert expand_groups(order, starts, counts, np.array([2, 0])).tolist() == [3, 1, 4, 5]
    assert expand_groups(order, starts, counts, np.array([1])).tolist() == [0, 2]
    assert expand_groups(order, starts, counts, np.zeros(0, dtype=int)).size == 0


def test_empty_keys() -> None:
    order, starts, counts, inverse = group_keys(np.zeros(0, dtype=np.int64))
    assert order.size == starts.size == counts.size == inverse.size == 0


def test_components_are_numbered_in_the_order_of_their_lowest_nodes() -> None:
    # 0-3, 3-5 and 2-5 join {0, 2, 3, 5}; 1-4 joins {1, 4}; 6 is alone. Numbered by lowest node: 0, 1, 6.
    lowest = component_labels(7, np.array([0, 3, 2, 1]), np.array([3, 5, 5, 4]))
    assert lowest.tolist() == [0, 1, 0, 0, 1, 0, 6]
    assert lowest_to_ranks(lowest).tolist() == [0, 1, 0, 0, 1, 0, 2]
    # Only the components of the marked nodes count (DBSCAN's core points); the rest get -1.
    marked = np.array([False, True, False, False, True, False, True])
    assert lowest_to_ranks(lowest, marked).tolist() == [-1, 0, -1, -1, 0, -1, 1]
