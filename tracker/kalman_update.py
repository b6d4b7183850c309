"""The Kalman measurement update in Joseph form, as filterpy's ``KalmanFilter.update`` computes it, without its
per-call bookkeeping (prior/posterior copies, likelihood): the one update both trackers' filters take.

Stacked: ``k`` filters at once, each with its own measurement of ``m`` rows. A stacked matmul or solve runs the
same BLAS / LAPACK call on each slice as a single one would, so a filter's result does not depend on how many
share the call; a batch of one is a single update.
"""

from __future__ import annotations

import numpy as np


def joseph_update(
    x: np.ndarray, p: np.ndarray, h: np.ndarray, y: np.ndarray, r: np.ndarray
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """States ``x`` (k, n), covariances ``p`` (k, n, n), measurement matrices ``h`` (k, m, n), innovations ``y``
    (k, m) (already wrapped where a row is an angle) and measurement noises ``r`` (k, m, m); returns the updated
    (x, P) and the innovation covariances S (k, m, m) and gains K (k, n, m)."""
    ht = h.transpose(0, 2, 1)
    pht = p @ ht
    s = h @ pht + r
    k = np.linalg.solve(s, pht.transpose(0, 2, 1)).transpose(0, 2, 1)
    i_kh = np.eye(p.shape[1]) - k @ h
    kt = k.transpose(0, 2, 1)
    return x + (k @ y[:, :, None])[:, :, 0], i_kh @ p @ i_kh.transpose(0, 2, 1) + k @ r @ kt, s, k


def selection_matrix(rows: np.ndarray, n: int) -> np.ndarray:
    """(m, n) H of a measurement that reads the states ``rows`` directly."""
    h = np.zeros((len(rows), n))
    h[np.arange(len(rows)), rows] = 1.0
    return h
