"""A cluster's velocity from its Doppler velocity profile (paper 001, eq. 3-6).

Every return i of one rigid target sees the same velocity v along its own line of sight u_i:
v_r,i = v . u_i = v cos(theta_i - alpha) (eq. 4). Written linearly in (vx, vy) (eq. 3), RANSAC over pairs of returns
rejects Doppler outliers and least squares on the inliers gives v. This replaces the paper's search over alpha
(eq. 5-6), which divides by cos(theta_i - alpha) and is undefined for a target at rest.

What the geometry can and cannot tell: the normal matrix N = sum u_i u_i^T has one large eigenvalue along the mean
line of sight and one of about n * spread^2 / 12 across it. A boat 30 m away spans a few degrees, so its radial
speed is known to a few cm/s and its tangential speed hardly at all. Such a cluster is reported RADIAL_ONLY: the
radial component with a covariance that is huge across the line of sight, never a made-up tangential value.
"""

from __future__ import annotations

import functools
import math
from dataclasses import dataclass
from enum import Enum

import numpy as np


class VelocityStatus(str, Enum):
    FULL = "full"  # both components determined
    RADIAL_ONLY = "radial_only"  # only the component along the cluster's line of sight
    UNDETERMINED = "undetermined"  # too few points, or no Doppler consensus


@dataclass(frozen=True)
class ProfileFitSettings:
    inlier_threshold: float  # m/s
    outlier_rate: float  # assumed share of outliers, sets the RANSAC iteration count
    confidence: float  # probability that one RANSAC sample is outlier-free
    max_iterations: int
    min_points: int
    min_inlier_fraction: float
    noise_std: float  # m/s, floor on the residual std
    max_tangential_std: float  # m/s; a weaker direction is "not determined"
    undetermined_var: float  # (m/s)^2 put on a direction that is not determined
    heading_min_snr: float


@dataclass(frozen=True)
class VelocityEstimate:
    """Velocity in the frame of the line-of-sight vectors that were fitted (world N/E for clusters)."""

    status: VelocityStatus
    velocity: np.ndarray  # (2,); NaN when UNDETERMINED; RADIAL_ONLY: radial component only (zero across)
    covariance: np.ndarray  # (2, 2); NaN when UNDETERMINED; RADIAL_ONLY: undetermined_var across the line of sight
    radial_direction: np.ndarray  # (2,) unit, best-determined direction (about the mean line of sight); NaN if none
    radial_speed: float  # m/s along radial_direction; NaN when UNDETERMINED
    tangential_speed: float  # m/s across it; NaN unless FULL
    heading_determined: bool  # FULL and the speed is clearly above its noise: the course means something
    inliers: np.ndarray  # (n,) bool over the input points
    residual_std: float  # m/s, of the inliers (NaN when UNDETERMINED)
    reason: str = ""  # why not FULL, for logs

    @property
    def determined(self) -> bool:
        return self.status is VelocityStatus.FULL

    @property
    def speed(self) -> float:
        return float(np.hypot(*self.velocity)) if self.determined else math.nan

    @property
    def course(self) -> float:
        """Direction of motion, rad from the first axis toward the second (north -> east); NaN if not determined."""
        return float(np.arctan2(self.velocity[1], self.velocity[0])) if self.heading_determined else math.nan


def undetermined(n: int, reason: str) -> VelocityEstimate:
    nan2 = np.full(2, np.nan)
    return VelocityEstimate(
        status=VelocityStatus.UNDETERMINED,
        velocity=nan2,
        covariance=np.full((2, 2), np.nan),
        radial_direction=nan2.copy(),
        radial_speed=math.nan,
        tangential_speed=math.nan,
        heading_determined=False,
        inliers=np.zeros(n, bool),
        residual_std=math.nan,
        reason=reason,
    )


def normal_eig(u: np.ndarray) -> tuple[float, float, np.ndarray]:
    """Eigen-decomposition of N = u^T u (2 x 2, symmetric) in closed form: (small, large, unit eigenvector of the
    large). The same numbers as ``np.linalg.eigh`` at a tenth of its call overhead, which dominates on 5-point
    clusters fitted a hundred times a second."""
    x, y = u[:, 0], u[:, 1]
    a, b, c = float(x @ x), float(x @ y), float(y @ y)
    mean, half = 0.5 * (a + c), 0.5 * (a - c)
    d = math.hypot(half, b)
    lam_big = mean + d
    if d == 0.0:
        vec = np.array([0.0, 1.0])  # isotropic: any direction; eigh's second column
    elif half >= 0:
        vec = np.array([lam_big - c, b]) / math.hypot(lam_big - c, b)
    else:
        vec = np.array([b, lam_big - a]) / math.hypot(b, lam_big - a)
    return max(mean - d, 0.0), lam_big, vec


def ransac_iterations(outlier_rate: float, confidence: float, sample_size: int, max_iterations: int) -> int:
    """Samples needed so that one is outlier-free with probability ``confidence``."""
    good = (1.0 - outlier_rate) ** sample_size
    if good >= 1.0:
        return 1
    if good <= 0.0:
        return max_iterations
    k = math.ceil(math.log(1.0 - confidence) / math.log(1.0 - good))
    return int(min(max(k, 1), max_iterations))


def fit_velocity_profile(
    los: np.ndarray, v_r: np.ndarray, settings: ProfileFitSettings, rng: np.random.Generator
) -> VelocityEstimate:
    """Velocity v with v_r,i ~= v . los_i, robust to Doppler outliers.

    ``los``: (n, 2) unit lines of sight from the sensor to each return; ``v_r``: (n,) Doppler, positive = the
    return recedes (made relative to the world beforehand, or the fit gives the velocity relative to the sensor).
    Non-finite rows are ignored.
    """
    los = np.asarray(los, float).reshape(-1, 2)
    v_r = np.asarray(v_r, float).reshape(-1)
    n_all = v_r.shape[0]
    if los.shape[0] != n_all:
        raise ValueError(f"fit_velocity_profile: {los.shape[0]} lines of sight for {n_all} Doppler values")
    finite = np.all(np.isfinite(los), axis=1) & np.isfinite(v_r)
    idx = np.flatnonzero(finite)
    n = idx.size
    if n < max(settings.min_points, 1):
        return undetermined(n_all, f"{n} Doppler points, need {settings.min_points}")
    u, z = los[idx], v_r[idx]
    lam_small = normal_eig(u)[0]  # across the line of sight
    weak_std = settings.noise_std / math.sqrt(lam_small) if lam_small > 1e-12 else math.inf
    if weak_std > settings.max_tangential_std:
        return _fit_radial(u, z, idx, n_all, settings, rng, "azimuth spread too small for the tangential component")
    best = _ransac_2d(u, z, settings, rng)
    if best is None:
        return _fit_radial(u, z, idx, n_all, settings, rng, "all sample pairs share one azimuth")
    inl = best
    v = np.zeros(2)
    fitted = None  # the inlier mask v was fitted on
    for _ in range(2):  # refit, re-select inliers with the refined model, refit
        v = np.linalg.lstsq(u[inl], z[inl], rcond=None)[0]
        fitted = inl
        inl_new = np.abs(u @ v - z) <= settings.inlier_threshold
        if inl_new.sum() < 2 or np.array_equal(inl_new, inl):
            break
        inl = inl_new
    m = int(inl.sum())
    need = max(3, math.ceil(settings.min_inlier_fraction * n))
    if m < need:
        return undetermined(n_all, f"Doppler consensus {m} of {n} points, need {need}")
    u_in, z_in = u[inl], z[inl]
    if inl is not fitted:  # the inliers moved on the last refit: once more on the final ones
        v = np.linalg.lstsq(u_in, z_in, rcond=None)[0]
    res = u_in @ v - z_in
    var = max(float(res @ res) / (m - 2) if m > 2 else 0.0, settings.noise_std**2)
    lam_small, lam_big, big = normal_eig(u_in)
    inliers = np.zeros(n_all, bool)
    inliers[idx[inl]] = True
    along = _orient(big, u_in)
    across = np.array([-along[1], along[0]])
    if lam_small <= 1e-12 or math.sqrt(var / lam_small) > settings.max_tangential_std:
        s = float(along @ v)
        return _radial_estimate(s, var / lam_big, along, inliers, math.sqrt(var), settings, "tangential std too large")
    cov = var * (along[:, None] * along / lam_big + across[:, None] * across / lam_small)
    speed = float(np.hypot(*v))
    heading_ok = False
    if speed > 0:
        d = v / speed
        heading_ok = speed >= settings.heading_min_snr * math.sqrt(float(d @ cov @ d))
    return VelocityEstimate(
        status=VelocityStatus.FULL,
        velocity=v,
        covariance=cov,
        radial_direction=along,
        radial_speed=float(along @ v),
        tangential_speed=float(across @ v),
        heading_determined=heading_ok,
        inliers=inliers,
        residual_std=math.sqrt(var),
    )


def _orient(direction: np.ndarray, u: np.ndarray) -> np.ndarray:
    """Eigenvectors have no sign; point the radial one away from the sensor, like the lines of sight."""
    return direction if float(direction @ u.sum(axis=0)) >= 0 else -direction


def _ransac_2d(u: np.ndarray, z: np.ndarray, s: ProfileFitSettings, rng: np.random.Generator) -> np.ndarray | None:
    """Inlier mask of the best two-point hypothesis, or None if every sampled pair is degenerate."""
    n = z.size
    k = ransac_iterations(s.outlier_rate, s.confidence, 2, s.max_iterations)
    n_pairs = n * (n - 1) // 2
    if n_pairs <= max(k, s.max_iterations):
        i, j = _all_pairs(n)  # small cluster: try every pair, deterministic
    else:
        i = rng.integers(0, n, size=k)
        j = (i + rng.integers(1, n, size=k)) % n
    det = u[i, 0] * u[j, 1] - u[i, 1] * u[j, 0]
    ok = np.abs(det) > 1e-9
    if not ok.any():
        return None
    i, j, det = i[ok], j[ok], det[ok]
    vx = (z[i] * u[j, 1] - z[j] * u[i, 1]) / det
    vy = (u[i, 0] * z[j] - u[j, 0] * z[i]) / det
    res = np.abs(vx[:, None] * u[None, :, 0] + vy[:, None] * u[None, :, 1] - z[None, :])  # (hypotheses, points)
    inl = res <= s.inlier_threshold
    return inl[_best_hypothesis(inl, res, s.inlier_threshold)]


@functools.lru_cache(maxsize=128)
def _all_pairs(n: int) -> tuple[np.ndarray, np.ndarray]:
    """np.triu_indices(n, 1), made once per cluster size (read-only: shared between calls)."""
    i, j = np.triu_indices(n, 1)
    i.flags.writeable = j.flags.writeable = False
    return i, j


def _best_hypothesis(inl: np.ndarray, res: np.ndarray, threshold: float) -> int:
    """Row with the most inliers, then the smallest inlier squared error, then the first: one argmax, as the
    inlier error of a row (< count x threshold^2) never outweighs one more inlier."""
    count = inl.sum(axis=1)
    sse = (res * res * inl).sum(axis=1)
    return int(np.argmax(count * (res.shape[1] * threshold * threshold + 1.0) - sse))


def _fit_radial(
    u: np.ndarray,
    z: np.ndarray,
    idx: np.ndarray,
    n_all: int,
    s: ProfileFitSettings,
    rng: np.random.Generator,
    reason: str,
) -> VelocityEstimate:
    """One-parameter model v_r,i = s (u_i . e): only the speed along the mean line of sight e."""
    n = z.size
    mean = u.sum(axis=0)
    norm = float(np.hypot(*mean))
    if norm < 1e-9:
        return undetermined(n_all, "lines of sight cancel out")
    e = mean / norm
    a = u @ e
    use = np.abs(a) > 0.5  # returns more than 60 deg off the mean line carry little radial information
    cand = np.flatnonzero(use)
    if cand.size == 0:
        return undetermined(n_all, "no return near the mean line of sight")
    k = ransac_iterations(s.outlier_rate, s.confidence, 1, s.max_iterations)
    if cand.size > max(k, s.max_iterations):
        cand = rng.choice(cand, size=k, replace=False)
    hyp = z[cand] / a[cand]
    res = np.abs(hyp[:, None] * a[None, :] - z[None, :])
    inl_all = res <= s.inlier_threshold
    inl = inl_all[_best_hypothesis(inl_all, res, s.inlier_threshold)]
    m = int(inl.sum())
    need = max(2, math.ceil(s.min_inlier_fraction * n))
    if m < need:
        return undetermined(n_all, f"radial Doppler consensus {m} of {n} points, need {need}")
    aa = float(a[inl] @ a[inl])
    speed = float(a[inl] @ z[inl]) / aa
    r = a[inl] * speed - z[inl]
    var = max(float(r @ r) / (m - 1) if m > 1 else 0.0, s.noise_std**2)
    inliers = np.zeros(n_all, bool)
    inliers[idx[inl]] = True
    return _radial_estimate(speed, var / aa, e, inliers, math.sqrt(var), s, reason)


def _radial_estimate(
    speed: float,
    var: float,
    along: np.ndarray,
    inliers: np.ndarray,
    residual_std: float,
    s: ProfileFitSettings,
    reason: str,
) -> VelocityEstimate:
    across = np.array([-along[1], along[0]])
    cov = var * along[:, None] * along + s.undetermined_var * across[:, None] * across
    return VelocityEstimate(
        status=VelocityStatus.RADIAL_ONLY,
        velocity=speed * along,
        covariance=cov,
        radial_direction=along,
        radial_speed=speed,
        tangential_speed=math.nan,
        heading_determined=False,
        inliers=inliers,
        residual_std=residual_std,
        reason=reason,
    )
