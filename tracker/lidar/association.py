"""Track-to-detection association by Bhattacharyya distance (paper sec. 2.4, after the authors' ref. [10]).

Each object, predicted track or fresh detection, is a 2-D Gaussian over the water it occupies: its mean is the
centre, its covariance the second moment of its footprint (a uniform rectangle l x w has variances l^2/12 and
w^2/12 along and across its heading) plus the uncertainty of its centre. The Bhattacharyya distance between two
such Gaussians grows with the centre offset measured in units of the objects' size and with the mismatch of
their size and orientation, so a small dinghy next to a large ferry is not mistaken for it even when the centres
are close. Pairs beyond the gate are impossible; the rest go to the optimal assignment.
"""

from __future__ import annotations

import numpy as np

from tracker.assignment import Assignment, gated_assignment
from tracker.lidar.config import AssociationConfig


def footprint_covariance(heading: np.ndarray, length: np.ndarray, width: np.ndarray) -> np.ndarray:
    """(k, 2, 2) second moment of uniform rectangles, world (north, east), m^2."""
    heading, length, width = np.broadcast_arrays(*(np.asarray(a, dtype=float) for a in (heading, length, width)))
    c, s = np.cos(heading).ravel(), np.sin(heading).ravel()
    va, vc = (length.ravel() ** 2) / 12.0, (width.ravel() ** 2) / 12.0
    cov = np.empty((c.size, 2, 2))
    cov[:, 0, 0] = va * c * c + vc * s * s
    cov[:, 1, 1] = va * s * s + vc * c * c
    cov[:, 0, 1] = cov[:, 1, 0] = (va - vc) * c * s
    return cov


def bhattacharyya_distance(mean_a: np.ndarray, cov_a: np.ndarray, mean_b: np.ndarray, cov_b: np.ndarray) -> np.ndarray:
    """(A, B) Bhattacharyya distances between 2-D Gaussians a (A, 2), (A, 2, 2) and b (B, 2), (B, 2, 2).

    D = 1/8 d^T S^-1 d + 1/2 ln(det S / sqrt(det Sa det Sb)),  S = (Sa + Sb) / 2,  d = mean_a - mean_b.
    2x2 inverses and determinants are written out, so all pairs are computed at once.
    """
    mean_a, mean_b = np.asarray(mean_a, float).reshape(-1, 2), np.asarray(mean_b, float).reshape(-1, 2)
    cov_a, cov_b = np.asarray(cov_a, float).reshape(-1, 2, 2), np.asarray(cov_b, float).reshape(-1, 2, 2)
    s = 0.5 * (cov_a[:, None] + cov_b[None, :])  # (A, B, 2, 2)
    det_s = s[..., 0, 0] * s[..., 1, 1] - s[..., 0, 1] * s[..., 1, 0]
    d = mean_a[:, None, :] - mean_b[None, :, :]
    # d^T S^-1 d with S^-1 = adj(S) / det S.
    quad = (
        s[..., 1, 1] * d[..., 0] ** 2 - 2.0 * s[..., 0, 1] * d[..., 0] * d[..., 1] + s[..., 0, 0] * d[..., 1] ** 2
    ) / det_s
    det_a = cov_a[:, 0, 0] * cov_a[:, 1, 1] - cov_a[:, 0, 1] * cov_a[:, 1, 0]
    det_b = cov_b[:, 0, 0] * cov_b[:, 1, 1] - cov_b[:, 0, 1] * cov_b[:, 1, 0]
    log_term = np.log(det_s) - 0.5 * (np.log(det_a)[:, None] + np.log(det_b)[None, :])
    return 0.125 * quad + 0.5 * log_term


def associate(
    track_mean: np.ndarray,
    track_cov: np.ndarray,
    det_mean: np.ndarray,
    det_cov: np.ndarray,
    config: AssociationConfig | None = None,
) -> tuple[Assignment, np.ndarray]:
    """Gated optimal assignment of tracks (rows) to detections (columns); also returns the cost matrix."""
    cfg = config or AssociationConfig()
    n_t, n_d = len(track_mean), len(det_mean)
    if n_t == 0 or n_d == 0:
        cost = np.zeros((n_t, n_d))
        return gated_assignment(cost, cfg.gate), cost
    cost = bhattacharyya_distance(track_mean, track_cov, det_mean, det_cov)
    far = np.hypot(*(np.asarray(track_mean)[:, None, :] - np.asarray(det_mean)[None, :, :]).transpose(2, 0, 1))
    cost = np.where((far <= cfg.max_distance) & np.isfinite(cost), cost, np.inf)
    return gated_assignment(cost, cfg.gate), cost
