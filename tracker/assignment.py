"""Gated optimal assignment between rows (tracks) and columns (detections) of any cost matrix.

The Hungarian solver alone would pair every track with some detection, however far; so pairs whose cost is above
the gate (or not finite) are made impossible before solving, and any pair the solver still returns across an
impossible entry is dropped. Cost measures (Bhattacharyya, 1 - IoU, Mahalanobis...) live with their trackers.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.optimize import linear_sum_assignment


@dataclass
class Assignment:
    matches: np.ndarray  # (k, 2) int: row, column; sorted by row
    unmatched_rows: np.ndarray  # (r,) int
    unmatched_cols: np.ndarray  # (c,) int


def gated_assignment(cost: np.ndarray, gate: float) -> Assignment:
    """Minimum-total-cost one-to-one pairing using only entries with ``cost <= gate``.

    NaN and +inf entries count as impossible. ``gate`` may be ``np.inf`` to accept every finite entry.
    """
    cost = np.asarray(cost, dtype=float)
    if cost.ndim != 2:
        raise ValueError(f"cost must be a 2-D matrix, got shape {cost.shape}")
    n_rows, n_cols = cost.shape
    allowed = np.isfinite(cost) & (cost <= gate)
    if n_rows == 0 or n_cols == 0 or not allowed.any():
        return Assignment(np.empty((0, 2), int), np.arange(n_rows), np.arange(n_cols))
    # Forbidden entries get a cost larger than any sum of allowed ones, so the solver never trades an allowed
    # pair for a forbidden one; rows and columns with no allowed entry at all are left out of the problem.
    rows = np.flatnonzero(allowed.any(axis=1))
    cols = np.flatnonzero(allowed.any(axis=0))
    sub_allowed = allowed[rows][:, cols]
    sub = np.where(sub_allowed, cost[rows][:, cols], 0.0)
    big = 1.0 + 2.0 * np.abs(sub).sum() * max(len(rows), len(cols))
    sub = np.where(sub_allowed, sub, big)
    r, c = linear_sum_assignment(sub)
    keep = sub_allowed[r, c]
    matches = np.stack([rows[r[keep]], cols[c[keep]]], axis=1).astype(int)
    matches = matches[np.argsort(matches[:, 0], kind="stable")]
    free_rows, free_cols = np.ones(n_rows, bool), np.ones(n_cols, bool)
    free_rows[matches[:, 0]] = False
    free_cols[matches[:, 1]] = False
    return Assignment(matches, np.flatnonzero(free_rows), np.flatnonzero(free_cols))
