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

_NARROW = "azimuth spread too small for the tangential component"
_NO_PAIR = "all sample pairs share one azimuth"


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
        return _fit_radial(u, z, idx, n_all, settings, rng, _NARROW)
    best = _ransac_2d(u, z, settings, rng)
    if best is None:
        return _fit_radial(u, z, idx, n_all, settings, rng, _NO_PAIR)
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
    if lam_small <= 1e-12 or math.sqrt(var / lam_small) > settings.max_tangential_std:
        s = float(along @ v)
        return _radial_estimate(s, var / lam_big, along, inliers, math.sqrt(var), settings, "tangential std too large")
    return _full_estimate(v, var, along, lam_big, lam_small, inliers, settings)


def _full_estimate(
    v: np.ndarray,
    var: float,
    along: np.ndarray,
    lam_big: float,
    lam_small: float,
    inliers: np.ndarray,
    s: ProfileFitSettings,
) -> VelocityEstimate:
    """Both components, with the covariance the returns' spread of azimuths allows along and across the mean line
    of sight."""
    cov, across, heading_ok = _full_covariances(
        v[None], np.array([var]), along[None], np.array([lam_big]), np.array([lam_small]), s
    )
    return _full_row(v, cov[0], along, across[0], bool(heading_ok[0]), inliers, var)


def _full_covariances(
    v: np.ndarray, var: np.ndarray, along: np.ndarray, lam_big: np.ndarray, lam_small: np.ndarray, s: ProfileFitSettings
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(b, 2, 2) covariances, (b, 2) across directions and (b,) "heading determined" of b full fits."""
    across = np.stack([-along[:, 1], along[:, 0]], axis=1)
    cov = var[:, None, None] * (
        along[:, :, None] * along[:, None, :] / lam_big[:, None, None]
        + across[:, :, None] * across[:, None, :] / lam_small[:, None, None]
    )
    speed = np.hypot(v[:, 0], v[:, 1])
    d = v / np.where(speed > 0, speed, 1.0)[:, None]
    spread = np.sqrt(np.einsum("bi,bij,bj->b", d, cov, d))
    return cov, across, (speed > 0) & (speed >= s.heading_min_snr * spread)


def _full_row(
    v: np.ndarray,
    cov: np.ndarray,
    along: np.ndarray,
    across: np.ndarray,
    heading_ok: bool,
    inliers: np.ndarray,
    var: float,
) -> VelocityEstimate:
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
    cov = _radial_covariances(np.array([var]), along[None], s)[0]
    return _radial_row(speed, speed * along, cov, along, inliers, residual_std, reason)


def _radial_covariances(var: np.ndarray, along: np.ndarray, s: ProfileFitSettings) -> np.ndarray:
    """(b, 2, 2): ``var`` (b,) along each unit direction (b, 2), ``undetermined_var`` across it."""
    across = np.stack([-along[:, 1], along[:, 0]], axis=1)
    return (
        var[:, None, None] * along[:, :, None] * along[:, None, :]
        + s.undetermined_var * across[:, :, None] * across[:, None, :]
    )


def _radial_row(
    speed: float,
    velocity: np.ndarray,
    cov: np.ndarray,
    along: np.ndarray,
    inliers: np.ndarray,
    residual_std: float,
    reason: str,
) -> VelocityEstimate:
    return VelocityEstimate(
        status=VelocityStatus.RADIAL_ONLY,
        velocity=velocity,
        covariance=cov,
        radial_direction=along,
        radial_speed=speed,
        tangential_speed=math.nan,
        heading_determined=False,
        inliers=inliers,
        residual_std=residual_std,
        reason=reason,
    )


def batch_size_limit(s: ProfileFitSettings) -> int:
    """Largest cluster whose fit tries every pair (and every radial candidate) and so draws no random number."""
    limit = max(ransac_iterations(s.outlier_rate, s.confidence, 2, s.max_iterations), s.max_iterations)
    return int((1 + math.isqrt(1 + 8 * limit)) // 2)  # n (n - 1) / 2 <= limit


def fit_velocity_profiles(
    los: list[np.ndarray], v_r: list[np.ndarray], settings: ProfileFitSettings, rng: np.random.Generator
) -> list[VelocityEstimate]:
    """``fit_velocity_profile`` of each cluster, in order: the small ones (every pair tried, no random draw) in one
    padded batch, the rest one by one, drawing from ``rng`` in their order as before. A frame's dozen 3-6 return
    clusters cost one fit's numpy calls instead of a dozen; the results agree with the single fit to rounding (the
    least squares are solved by 2 x 2 normal equations here)."""
    out: list[VelocityEstimate | None] = [None] * len(los)
    small: list[int] = []
    cap = batch_size_limit(settings)
    for k, (u, z) in enumerate(zip(los, v_r, strict=True)):
        n = len(z)
        if max(settings.min_points, 2) <= n <= cap and np.isfinite(u).all() and np.isfinite(z).all():
            small.append(k)
        else:
            out[k] = fit_velocity_profile(u, z, settings, rng)
    if small:
        for k, est in zip(small, _batch_fit([los[k] for k in small], [v_r[k] for k in small], settings), strict=True):
            out[k] = est if est is not None else fit_velocity_profile(los[k], v_r[k], settings, rng)
    return out  # type: ignore[return-value]


def _normal_eig_batch(u: np.ndarray, w: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """``normal_eig`` of every row of ``u`` (b, N, 2) weighted by ``w`` (b, N) in {0, 1}: (small (b,), large (b,),
    unit eigenvector of the large (b, 2))."""
    x, y = u[..., 0] * w, u[..., 1] * w
    a, b, c = (x * x).sum(axis=1), (x * y).sum(axis=1), (y * y).sum(axis=1)
    mean, half = 0.5 * (a + c), 0.5 * (a - c)
    d = np.hypot(half, b)
    big = mean + d
    vec = np.where((half >= 0)[:, None], np.stack([big - c, b], axis=1), np.stack([b, big - a], axis=1))
    norm = np.hypot(vec[:, 0], vec[:, 1])
    vec = np.where((d == 0.0)[:, None], np.array([0.0, 1.0]), vec / np.where(norm > 0, norm, 1.0)[:, None])
    return np.maximum(mean - d, 0.0), big, vec


def _least_squares_batch(u: np.ndarray, z: np.ndarray, w: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """v minimising sum w (u . v - z)^2 per row, by the 2 x 2 normal equations; and (b,) bool: too near singular
    for them (lstsq's minimum-norm answer is what the single fit gives there)."""
    x, y = u[..., 0] * w, u[..., 1] * w
    a, b, c = (x * u[..., 0]).sum(axis=1), (x * u[..., 1]).sum(axis=1), (y * u[..., 1]).sum(axis=1)
    r0, r1 = (x * z).sum(axis=1), (y * z).sum(axis=1)
    det = a * c - b * b
    singular = det <= 1e-9 * np.maximum(a * c, 1e-300)
    safe = np.where(singular, 1.0, det)
    return np.stack([(c * r0 - b * r1) / safe, (a * r1 - b * r0) / safe], axis=1), singular


def _batch_fit(los: list[np.ndarray], v_r: list[np.ndarray], s: ProfileFitSettings) -> list[VelocityEstimate | None]:
    """The single fit's steps on padded (b, N) arrays of clusters small enough to try every pair; None for a
    cluster whose least squares are too near singular for the normal equations (the caller fits it alone)."""
    n = np.array([len(z) for z in v_r])
    width = int(n.max())
    real = np.arange(width)[None, :] < n[:, None]
    u = np.zeros((n.size, width, 2))
    z = np.zeros((n.size, width))
    u[real] = np.concatenate(los).reshape(-1, 2)
    z[real] = np.concatenate(v_r).reshape(-1)
    lam_small = _normal_eig_batch(u, real)[0]
    with np.errstate(divide="ignore"):
        weak_std = np.where(lam_small > 1e-12, s.noise_std / np.sqrt(np.maximum(lam_small, 1e-300)), np.inf)
    out: list[VelocityEstimate | None] = [None] * n.size
    reasons = dict.fromkeys(np.flatnonzero(weak_std > s.max_tangential_std).tolist(), _NARROW)
    plane = np.flatnonzero(weak_std <= s.max_tangential_std)
    if plane.size:
        for k, est in zip(plane.tolist(), _batch_plane(u[plane], z[plane], n[plane], real[plane], s), strict=True):
            if est == _NO_PAIR:
                reasons[k] = _NO_PAIR
            else:
                out[k] = est  # type: ignore[assignment]
    if reasons:
        radial = np.array(sorted(reasons))
        ests = _batch_radial(u[radial], z[radial], n[radial], real[radial], [reasons[k] for k in radial.tolist()], s)
        for k, est in zip(radial.tolist(), ests, strict=True):
            out[k] = est
    return out


def _batch_plane(
    u: np.ndarray, z: np.ndarray, n: np.ndarray, real: np.ndarray, s: ProfileFitSettings
) -> list[VelocityEstimate | str | None]:
    """The two-component model of ``fit_velocity_profile`` on padded rows: an estimate, ``_NO_PAIR`` for a row the
    radial model must take, or None (normal equations too near singular)."""
    b, width = z.shape
    thr, rows = s.inlier_threshold, np.arange(b)
    i, j = _all_pairs(width)  # the pairs of the widest cluster, cut to each one's own
    det = u[:, i, 0] * u[:, j, 1] - u[:, i, 1] * u[:, j, 0]
    ok = (j[None, :] < n[:, None]) & (np.abs(det) > 1e-9)
    safe = np.where(ok, det, 1.0)
    vx = (z[:, i] * u[:, j, 1] - z[:, j] * u[:, i, 1]) / safe
    vy = (u[:, i, 0] * z[:, j] - u[:, j, 0] * z[:, i]) / safe
    res = np.abs(vx[:, :, None] * u[:, None, :, 0] + vy[:, :, None] * u[:, None, :, 1] - z[:, None, :])
    inl = (res <= thr) & real[:, None, :]
    score = inl.sum(axis=2) * (n[:, None] * thr * thr + 1.0) - (res * res * inl).sum(axis=2)
    inl0 = inl[rows, np.argmax(np.where(ok, score, -np.inf), axis=1)]

    def reselect(v: np.ndarray) -> np.ndarray:
        return (np.abs((u * v[:, None, :]).sum(axis=2) - z) <= thr) & real

    # refit, re-select inliers with the refined model, refit; once more if the inliers moved on the last refit
    v1, sing1 = _least_squares_batch(u, z, inl0)
    new1 = reselect(v1)
    stop1 = (new1.sum(axis=1) < 2) | (new1 == inl0).all(axis=1)
    inl1 = np.where(stop1[:, None], inl0, new1)
    v2, sing2 = _least_squares_batch(u, z, inl1)
    new2 = reselect(v2)
    refit = ~stop1 & (new2.sum(axis=1) >= 2) & (new2 != inl1).any(axis=1)
    final = np.where(refit[:, None], new2, inl1)
    v3, sing3 = _least_squares_batch(u, z, final)
    v = np.where(stop1[:, None], v1, np.where(refit[:, None], v3, v2))
    singular = sing1 | (~stop1 & sing2) | (refit & sing3)
    m = final.sum(axis=1)
    need = np.maximum(3, np.ceil(s.min_inlier_fraction * n)).astype(int)
    r = ((u * v[:, None, :]).sum(axis=2) - z) * final
    var = np.maximum(np.where(m > 2, (r * r).sum(axis=1) / np.maximum(m - 2, 1), 0.0), s.noise_std**2)
    small, big, vec = _normal_eig_batch(u, final)
    along = np.where(((vec * (u * final[..., None]).sum(axis=1)).sum(axis=1) >= 0)[:, None], vec, -vec)
    with np.errstate(divide="ignore", invalid="ignore"):
        tang_bad = (small <= 1e-12) | (np.sqrt(var / small) > s.max_tangential_std)

    # what each row becomes, every covariance made at once: radial along the best direction, or both components
    radial_s = (along * v).sum(axis=1)
    radial_cov = _radial_covariances(var / big, along, s)
    full_cov, across, heading_ok = _full_covariances(v, var, along, big, np.where(tang_bad, 1.0, small), s)
    sd = np.sqrt(var).tolist()
    out: list[VelocityEstimate | str | None] = []
    no_pair = (~ok.any(axis=1)).tolist()
    flags = zip(singular.tolist(), (m < need).tolist(), tang_bad.tolist(), strict=True)
    for k, (nk, (sing, few, tang)) in enumerate(zip(n.tolist(), flags, strict=True)):
        if no_pair[k]:
            out.append(_NO_PAIR)
        elif sing:
            out.append(None)
        elif few:
            out.append(undetermined(nk, f"Doppler consensus {m[k]} of {nk} points, need {need[k]}"))
        elif tang:
            rs = float(radial_s[k])
            out.append(
                _radial_row(
                    rs, rs * along[k], radial_cov[k], along[k], final[k, :nk], sd[k], "tangential std too large"
                )
            )
        else:
            out.append(
                _full_row(v[k], full_cov[k], along[k], across[k], bool(heading_ok[k]), final[k, :nk], float(var[k]))
            )
    return out


def _batch_radial(
    u: np.ndarray, z: np.ndarray, n: np.ndarray, real: np.ndarray, reasons: list[str], s: ProfileFitSettings
) -> list[VelocityEstimate]:
    """``_fit_radial`` on padded rows, every return a candidate (no random draw for clusters this small)."""
    thr, rows = s.inlier_threshold, np.arange(z.shape[0])
    mean = u.sum(axis=1)
    norm = np.hypot(mean[:, 0], mean[:, 1])
    e = mean / np.where(norm < 1e-9, 1.0, norm)[:, None]
    a = (u * e[:, None, :]).sum(axis=2)
    use = (np.abs(a) > 0.5) & real
    hyp = z / np.where(use, a, 1.0)
    res = np.abs(hyp[:, :, None] * a[:, None, :] - z[:, None, :])
    inl_all = (res <= thr) & real[:, None, :]
    score = inl_all.sum(axis=2) * (n[:, None] * thr * thr + 1.0) - (res * res * inl_all).sum(axis=2)
    inl = inl_all[rows, np.argmax(np.where(use, score, -np.inf), axis=1)]
    m = inl.sum(axis=1)
    need = np.maximum(2, np.ceil(s.min_inlier_fraction * n)).astype(int)
    aa = (a * a * inl).sum(axis=1)
    speed = (a * z * inl).sum(axis=1) / np.where(aa > 0, aa, 1.0)
    r = (a * speed[:, None] - z) * inl
    var = np.maximum(np.where(m > 1, (r * r).sum(axis=1) / np.maximum(m - 1, 1), 0.0), s.noise_std**2)
    cov = _radial_covariances(var / np.where(aa > 0, aa, 1.0), e, s)
    velocity = speed[:, None] * e
    sd = np.sqrt(var).tolist()
    out = []
    cancel, none_near, few = (norm < 1e-9).tolist(), (~use.any(axis=1)).tolist(), (m < need).tolist()
    for k, nk in enumerate(n.tolist()):
        if cancel[k]:
            out.append(undetermined(nk, "lines of sight cancel out"))
        elif none_near[k]:
            out.append(undetermined(nk, "no return near the mean line of sight"))
        elif few[k]:
            out.append(undetermined(nk, f"radial Doppler consensus {m[k]} of {nk} points, need {need[k]}"))
        else:
            out.append(_radial_row(float(speed[k]), velocity[k], cov[k], e[k], inl[k, :nk], sd[k], reasons[k]))
    return out
