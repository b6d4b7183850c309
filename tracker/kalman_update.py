"""The Kalman measurement update in Joseph form, as filterpy's ``KalmanFilter.update`` computes it, without its
per-call bookkeeping (prior/posterior copies, likelihood), for both trackers' filters.

Both functions take the state ``x`` (n,), its covariance ``p`` (n, n), the innovation ``y`` (m,) (already wrapped where
a row is an angle) and the measurement noise ``r`` (m, m), and return (x, P, S, K) after the update.
"""

from __future__ import annotations

import numpy as np


def joseph_update(
    x: np.ndarray, p: np.ndarray, h: np.ndarray, y: np.ndarray, r: np.ndarray
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Any measurement matrix ``h`` (m, n)."""
    pht = p @ h.T
    s = h @ pht + r
    k = np.linalg.solve(s, pht.T).T
    i_kh = np.eye(p.shape[0]) - k @ h
    return x + k @ y, i_kh @ p @ i_kh.T + k @ r @ k.T, s, k


def joseph_update_selected(
    x: np.ndarray, p: np.ndarray, rows: np.ndarray, y: np.ndarray, r: np.ndarray
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """A measurement matrix that only picks the states ``rows``: the products with H become indexing."""
    pht = p[:, rows]
    s = pht[rows] + r
    k = np.linalg.solve(s, pht.T).T
    i_kh = np.eye(p.shape[0])
    i_kh[:, rows] -= k
    return x + k @ y, i_kh @ p @ i_kh.T + k @ r @ k.T, s, k
