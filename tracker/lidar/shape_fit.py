"""Shape fitting of one cluster's horizontal footprint (paper sec. 2.2-2.3, Algorithms 1-4).

Every fitter takes an (n, 2) array of world (north, east) points, metres, and returns a :class:`ShapeFit`: centre,
heading along the LONGEST side in [0, pi) (0 = north, clockwise, as atan2(east, north)), length >= width, the mean
squared point-to-shape distance (m^2) and the kind.

* L-shape, three ways: brute force over sorted point splits (Alg. 1, after Shen et al.), search over rotated
  rectangles (Alg. 2, after Zhang et al.'s closeness criterion), corner-point determination (Alg. 3). All three only
  choose a heading; the box is then the points' bounding rectangle in that heading, so it contains the cluster.
* Ellipse by direct least squares (Fitzgibbon, in Halir & Flusser's numerically stable form, on normalised points),
  then cut to the points' extent along the major axis (sec. 2.2.2): a boat seen from one side is an incomplete hull,
  and the full fitted ellipse would be oversized.
* Shape decision (Alg. 4): the smaller MSE wins. Both MSEs are mean squared distances in m^2 so they compare:
  the box's is the distance to the nearest edge, with each edge moved to the least-squares line of the points
  nearest to it (the bounding edge itself sits on the noisiest point and would penalise boxes unfairly); the
  ellipse's is the Sampson distance, a first-order geometric distance that needs no iterative solve.

Ours, not in the paper, used by the tracker's detection step: :func:`guard_heading` (a cabin's faces inside the
outline break the L-shape assumption; the outline's own edges are tried too). The corner and ellipse fits run a
whole scan's clusters at once as stacked arrays (:func:`fit_lshape_corners`, :func:`fit_ellipses`); one cluster is a
batch of one.

Degenerate input: non-finite rows are dropped; no finite point at all raises :class:`DegenerateClusterError`;
one or two distinct points give a POINT fit; collinear points give a BOX of width 0. The ellipse fit raises
:class:`DegenerateClusterError` when no ellipse exists (fewer than 5 points, collinear, hyperbola); the shape
decision then keeps the box.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from tracker.lidar.config import ShapeConfig
from tracker.types import ShapeKind

HALF_PI = 0.5 * math.pi


class DegenerateClusterError(ValueError):
    """The points do not determine the requested shape (too few, collinear, not an ellipse, not finite)."""


@dataclass
class ShapeFit:
    center: np.ndarray  # (2,) world north, east, m
    heading: float  # rad in [0, pi), along the longest side
    length: float  # m, along heading
    width: float  # m
    mse: float  # m^2, mean squared point-to-shape distance
    kind: ShapeKind
    n_points: int
    method: str  # corner | rotation | bruteforce | ellipse | point

    def corners(self) -> np.ndarray:
        """(4, 2) corners of the oriented rectangle (an ellipse's bounding rectangle)."""
        c, s = math.cos(self.heading), math.sin(self.heading)
        along = np.array([c, s]) * (self.length / 2)
        across = np.array([-s, c]) * (self.width / 2)
        p = self.center
        return np.array([p + along + across, p + along - across, p - along - across, p - along + across])


def cluster_height(z: np.ndarray) -> float:
    """Vertical extent of a cluster, m: highest minus lowest return (sec. 2.2); 0 for no finite value."""
    z = np.asarray(z, dtype=float)
    z = z[np.isfinite(z)]
    return float(z.max() - z.min()) if z.size else 0.0


# ---------------------------------------------------------------------------------------------------------------------
# Common helpers. Internally points are a contiguous (2, n) array, centred: reductions along the last axis of small
# arrays are several times cheaper than along the first, and centring keeps the sums of squares well conditioned.


def _axis_angle(theta: float) -> float:
    """An axis direction in [0, pi): float modulo can round a tiny negative angle up to exactly pi."""
    h = theta % math.pi
    return 0.0 if h >= math.pi else h


def _prepare(points: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Finite points as a centred (2, n) array, and the centre that was subtracted."""
    pts = np.asarray(points, dtype=float)
    if pts.ndim != 2 or pts.shape[1] < 2:
        raise DegenerateClusterError(f"expected an (n, 2) point array, got shape {pts.shape}")
    xy = np.ascontiguousarray(pts[:, :2].T)
    if not np.isfinite(xy).all():
        xy = np.ascontiguousarray(xy[:, np.isfinite(xy).all(axis=0)])
    n = xy.shape[1]
    if n == 0:
        raise DegenerateClusterError("no finite points")
    origin = xy.sum(axis=1) / n
    return xy - origin[:, None], origin


def _point_fit(xy: np.ndarray, origin: np.ndarray) -> ShapeFit | None:
    """A POINT fit for fewer than 3 points, else None (identical points are caught where the extent is 0)."""
    n = xy.shape[1]
    if n >= 3:
        return None
    d = xy[:, -1] - xy[:, 0]
    length = math.hypot(d[0], d[1])
    heading = _axis_angle(math.atan2(d[1], d[0])) if length > 0 else 0.0
    return ShapeFit(origin.copy(), heading, length, 0.0, 0.0, ShapeKind.POINT, n, "point")


def box_from_heading(xy: np.ndarray, theta: float, method: str, origin: np.ndarray) -> ShapeFit:
    """Bounding rectangle of centred (2, n) points with a side along ``theta``; heading along the longest side
    (:func:`boxes_from_headings` of one)."""
    pad, mask = _pad([xy])
    return boxes_from_headings(pad, mask, np.array([theta]), method, [origin])[0]


# ---------------------------------------------------------------------------------------------------------------------
# L-shape fitting


def fit_lshape_bruteforce(points: np.ndarray, sensor_position: np.ndarray | None = None) -> ShapeFit:
    """Algorithm 1: try every split of the bearing-sorted points into two perpendicular lines.

    For a split into P (first i points) and Q (the rest), the least-squares perpendicular pair with P's normal n
    leaves residual n^T (S_P + R90^T S_Q R90) n, whose minimum is the smallest eigenvalue of that 2x2 matrix
    (S = scatter matrix). Cumulative sums give every split's scatter at once: O(n log n) for the sort, O(n) after.
    ``sensor_position`` (north, east) orders the points by bearing, the order in which the scanner swept them;
    default the coordinate origin.
    """
    xy, origin = _prepare(points)
    degenerate = _point_fit(xy, origin)
    if degenerate is not None:
        return degenerate
    sensor = np.zeros(2) if sensor_position is None else np.asarray(sensor_position, dtype=float)[:2]
    rel_origin = origin - sensor
    ref = math.atan2(rel_origin[1], rel_origin[0])
    bearing = (np.arctan2(xy[1] + rel_origin[1], xy[0] + rel_origin[0]) - ref + math.pi) % (2 * math.pi)
    x, y = xy[:, np.argsort(bearing, kind="stable")]
    n = x.size
    cum = np.cumsum(np.stack([x, y, x * x, x * y, y * y]), axis=1)
    i = np.arange(1, n, dtype=float)  # |P| for the split after point i - 1
    p = cum[:, :-1]
    q = cum[:, -1:] - p
    j = n - i
    pxx, pxy, pyy = p[2] - p[0] ** 2 / i, p[3] - p[0] * p[1] / i, p[4] - p[1] ** 2 / i
    qxx, qxy, qyy = q[2] - q[0] ** 2 / j, q[3] - q[0] * q[1] / j, q[4] - q[1] ** 2 / j
    a, b, c = pxx + qyy, pxy - qxy, pyy + qxx
    lam_min = 0.5 * (a + c) - np.sqrt((0.5 * (a - c)) ** 2 + b**2)
    k = int(np.argmin(lam_min))
    # P's normal = eigenvector of the smallest eigenvalue, perpendicular to the principal direction; the box's
    # sides run along the normal and across it, so either direction gives the same rectangle.
    principal = 0.5 * math.atan2(2.0 * b[k], a[k] - c[k])
    return box_from_heading(xy, principal, "bruteforce", origin)


def fit_lshape_rotation(points: np.ndarray, step: float = math.radians(1.0), min_distance: float = 0.01) -> ShapeFit:
    """Algorithm 2: score rectangles rotated in steps of ``step`` over [0, 90) deg, all angles at once.

    The score is Zhang et al.'s closeness criterion: sum over points of 1 / max(d, min_distance), d the point's
    distance to the nearest rectangle edge, so rectangles that many points hug score high.
    """
    if not step > 0:
        raise ValueError(f"rotation step must be > 0, got {step}")
    xy, origin = _prepare(points)
    degenerate = _point_fit(xy, origin)
    if degenerate is not None:
        return degenerate
    thetas = np.arange(0.0, HALF_PI - 1e-12, step)
    rot = np.concatenate(
        [np.stack([np.cos(thetas), np.sin(thetas)], 1), np.stack([-np.sin(thetas), np.cos(thetas)], 1)]
    )
    proj = rot @ xy  # (2K, n): every angle's e1 projections, then every angle's e2 projections
    d = np.minimum(proj - proj.min(axis=1, keepdims=True), proj.max(axis=1, keepdims=True) - proj)
    k = thetas.size
    score = (1.0 / np.maximum(np.minimum(d[:k], d[k:]), min_distance)).sum(axis=1)
    return box_from_heading(xy, float(thetas[int(np.argmax(score))]), "rotation", origin)


def fit_lshape_corner(points: np.ndarray, min_offset: float = 0.15) -> ShapeFit:
    """Algorithm 3: the most distant pair of extreme points is the diagonal, the point furthest from it the corner.

    The diagonal ends are searched among the extremes along x, y and both diagonals (8 candidates), which finds
    the ends of an L without an O(n^2) search. The heading follows the longer leg from the corner; a corner
    closer than ``min_offset`` to the diagonal means only one side is visible, and the heading follows the diagonal.
    """
    fit = fit_lshape_corners([points], min_offset)[0]
    if isinstance(fit, DegenerateClusterError):
        raise fit
    return fit


_CORNER_DIRS = np.array([[1.0, 0.0], [0.0, 1.0], [1.0, 1.0], [1.0, -1.0]])


def _pad(xys: list[np.ndarray]) -> tuple[np.ndarray, np.ndarray]:
    """Centred (2, n_i) point sets as one (k, 2, n_max) array (zeros beyond n_i) and its (k, n_max) bool mask."""
    nmax = max(xy.shape[1] for xy in xys)
    pad = np.zeros((len(xys), 2, nmax))
    mask = np.zeros((len(xys), nmax), dtype=bool)
    for j, xy in enumerate(xys):
        pad[j, :, : xy.shape[1]] = xy
        mask[j, : xy.shape[1]] = True
    return pad, mask


def prepare_all(clouds: list[np.ndarray]) -> list[tuple[np.ndarray, np.ndarray] | DegenerateClusterError]:
    """Each cloud's centred points and centre as the fitters take them (or the error preparing it raises): a
    scan's batch fitters can share them instead of preparing every cluster again."""
    out: list[tuple[np.ndarray, np.ndarray] | DegenerateClusterError] = []
    for pts in clouds:
        try:
            out.append(_prepare(pts))
        except DegenerateClusterError as exc:
            out.append(exc)
    return out


def fit_lshape_corners(
    clouds: list[np.ndarray],
    min_offset: float = 0.15,
    prepared: list[tuple[np.ndarray, np.ndarray] | DegenerateClusterError] | None = None,
) -> list[ShapeFit | DegenerateClusterError]:
    """Algorithm 3 (:func:`fit_lshape_corner`) for many clusters at once, on stacked, padded arrays.

    Each entry is the fit, or the :class:`DegenerateClusterError` that makes the cluster unfit.
    ``prepared``: :func:`prepare_all` of ``clouds``, if already at hand.
    """
    out: list[ShapeFit | DegenerateClusterError] = [DegenerateClusterError("corner: not fitted")] * len(clouds)
    batch: list[tuple[int, np.ndarray, np.ndarray]] = []
    for i, ready in enumerate(prepared if prepared is not None else prepare_all(clouds)):
        if isinstance(ready, DegenerateClusterError):
            out[i] = ready
            continue
        xy, origin = ready
        point = _point_fit(xy, origin)
        if point is not None:
            out[i] = point
            continue
        batch.append((i, xy, origin))
    if not batch:
        return out
    pad, mask = _pad([xy for _, xy, _ in batch])
    k = len(batch)
    rows = np.arange(k)
    proj = np.einsum("dc,kcn->kdn", _CORNER_DIRS, pad)
    cand = np.concatenate(
        [
            np.where(mask[:, None, :], proj, np.inf).argmin(axis=2),
            np.where(mask[:, None, :], proj, -np.inf).argmax(axis=2),
        ],
        axis=1,
    )  # (k, 8)
    cp = pad[rows[:, None], :, cand]  # (k, 8, 2)
    diff = cp[:, :, None, :] - cp[:, None, :, :]
    flat = (diff * diff).sum(axis=3).reshape(k, -1).argmax(axis=1)
    p1, p2 = cp[rows, flat // 8], cp[rows, flat % 8]  # (k, 2)
    diag = p2 - p1
    diag_len = np.hypot(diag[:, 0], diag[:, 1])
    offset = np.abs(diag[:, 0:1] * (p1[:, 1:2] - pad[:, 1]) - diag[:, 1:2] * (p1[:, 0:1] - pad[:, 0]))
    k3 = np.where(mask, offset, -np.inf).argmax(axis=1)
    p3 = pad[rows, :, k3]
    leg1, leg2 = p1 - p3, p2 - p3
    leg = np.where(((leg1 * leg1).sum(axis=1) >= (leg2 * leg2).sum(axis=1))[:, None], leg1, leg2)
    one_side = offset[rows, k3] <= min_offset * diag_len
    direction = np.where(one_side[:, None], diag, leg)
    theta = np.array([math.atan2(float(d[1]), float(d[0])) for d in direction])
    boxes = boxes_from_headings(pad, mask, theta, "corner", [origin for _, _, origin in batch])
    for (i, _, _), box in zip(batch, boxes, strict=True):
        out[i] = box
    return out


def boxes_from_headings(
    pad: np.ndarray, mask: np.ndarray, theta: np.ndarray, method: str, origins: list[np.ndarray]
) -> list[ShapeFit]:
    """Bounding rectangles of padded centred point sets (see :func:`_pad`), each with a side along its ``theta``,
    heading along the longest side, with the MSE of the points to their nearest edge."""
    c = np.array([math.cos(float(t)) for t in theta])[:, None]
    s = np.array([math.sin(float(t)) for t in theta])[:, None]
    x, y = pad[:, 0], pad[:, 1]
    u, v = c * x + s * y, c * y - s * x
    lo_u, hi_u = np.where(mask, u, np.inf).min(axis=1), np.where(mask, u, -np.inf).max(axis=1)
    lo_v, hi_v = np.where(mask, v, np.inf).min(axis=1), np.where(mask, v, -np.inf).max(axis=1)
    mu, mv = 0.5 * (lo_u + hi_u), 0.5 * (lo_v + hi_v)
    cn, ce = mu * c[:, 0] - mv * s[:, 0], mu * s[:, 0] + mv * c[:, 0]
    length, width = hi_u - lo_u, hi_v - lo_v
    # Edge MSE: each point's nearest edge, each edge refit to the mean line of its points; per edge k with points
    # at distances d: sum (d - mean d)^2 = sum d^2 - (sum d)^2 / count.
    dist = np.stack([u - lo_u[:, None], v - lo_v[:, None], hi_u[:, None] - u, hi_v[:, None] - v], axis=1)
    owner = dist.argmin(axis=1)  # (k, n)
    dmin = np.where(mask, dist.min(axis=1), 0.0)  # the owner's distance: the same value, without a gather
    onehot = (owner[:, None, :] == np.arange(4)[None, :, None]) & mask[:, None, :]
    count = onehot.sum(axis=2)
    per_edge = (onehot * dmin[:, None, :]).sum(axis=2)
    n = mask.sum(axis=1)
    mse = np.maximum((dmin * dmin).sum(axis=1) - (per_edge * per_edge / np.maximum(count, 1)).sum(axis=1), 0.0) / n
    out = []
    for j, origin in enumerate(origins):
        center = np.array([origin[0] + cn[j], origin[1] + ce[j]])
        lj, wj, tj = float(length[j]), float(width[j]), float(theta[j])
        if lj == 0.0 and wj == 0.0:
            out.append(ShapeFit(origin.copy(), 0.0, 0.0, 0.0, 0.0, ShapeKind.POINT, int(n[j]), "point"))
            continue
        if wj > lj:
            lj, wj, tj = wj, lj, tj + HALF_PI
        out.append(ShapeFit(center, _axis_angle(tj), lj, wj, float(mse[j]), ShapeKind.BOX, int(n[j]), method))
    return out


# ---------------------------------------------------------------------------------------------------------------------
# Ellipse fitting


def fit_ellipse(points: np.ndarray) -> ShapeFit:
    """Direct least-squares ellipse, cut to the points' extent along its major axis (sec. 2.2.2): :func:`fit_ellipses`
    of one."""
    fit = fit_ellipses([points])[0]
    if isinstance(fit, DegenerateClusterError):
        raise fit
    return fit


def fit_ellipses(
    clouds: list[np.ndarray], prepared: list[tuple[np.ndarray, np.ndarray] | DegenerateClusterError] | None = None
) -> list[ShapeFit | DegenerateClusterError]:
    """Direct least-squares ellipses (Halir & Flusser's stable form, on points normalised by their spread), each
    cut to its points' extent along its major axis (sec. 2.2.2), with the mean squared Sampson distance as MSE.
    The least-squares systems of all clusters are built and solved as stacked arrays, so a scan's twenty boats
    cost about what a few cost one at a time.

    Each entry is the fit, or the :class:`DegenerateClusterError` that makes the cluster unfit (fewer than 5
    points, collinear or coincident points, no real ellipse).
    ``prepared``: :func:`prepare_all` of ``clouds``, if already at hand.
    """
    out: list[ShapeFit | DegenerateClusterError] = [DegenerateClusterError("ellipse: not fitted")] * len(clouds)
    batch: list[tuple[int, np.ndarray, np.ndarray]] = []
    for i, ready in enumerate(prepared if prepared is not None else prepare_all(clouds)):
        if isinstance(ready, DegenerateClusterError):
            out[i] = ready
            continue
        xy, origin = ready
        if xy.shape[1] < 5:
            out[i] = DegenerateClusterError(f"ellipse: needs 5 points, got {xy.shape[1]}")
            continue
        batch.append((i, xy, origin))
    if not batch:
        return out
    pad, mask = _pad([xy for _, xy, _ in batch])
    k, nmax = mask.shape
    ones = mask.astype(float)
    n = ones.sum(axis=1)
    sxx = np.einsum("kn,kn->k", pad[:, 0], pad[:, 0]) / n
    syy = np.einsum("kn,kn->k", pad[:, 1], pad[:, 1]) / n
    sxy = np.einsum("kn,kn->k", pad[:, 0], pad[:, 1]) / n
    tr = sxx + syy
    flat = ~(tr > 0.0) | (sxx * syy - sxy * sxy < 1e-10 * tr * tr)
    scale = np.sqrt(np.where(flat, 1.0, tr))
    q = pad / scale[:, None, None]
    design = np.empty((k, 6, nmax))
    x, y = q[:, 0], q[:, 1]
    design[:, 0], design[:, 1], design[:, 2] = x * x, x * y, y * y
    design[:, 3], design[:, 4], design[:, 5] = x, y, ones
    scatter = design @ design.transpose(0, 2, 1)
    s3 = scatter[:, 3:, 3:]
    s3[flat] = np.eye(3)  # keeps the stacked solve regular; these clusters are reported below
    t = -np.linalg.solve(s3, scatter[:, 3:, :3])
    m = scatter[:, :3, :3] + scatter[:, :3, 3:] @ t
    # Premultiply by the inverse of the constraint matrix C1 = [[0, 0, 2], [0, -1, 0], [2, 0, 0]].
    m = np.stack([m[:, 2] / 2.0, -m[:, 1], m[:, 0] / 2.0], axis=1)
    finite = np.isfinite(m).all(axis=(1, 2))
    m[~finite] = np.eye(3)
    _, vecs = np.linalg.eig(m)
    vecs = np.real(vecs)
    cond = 4.0 * vecs[:, 0] * vecs[:, 2] - vecs[:, 1] ** 2  # (k, 3): one per eigenvector
    elliptic = cond > 0.0
    pick = np.argmax(np.where(elliptic, cond, -np.inf), axis=1)
    a1 = vecs[np.arange(k), :, pick]  # (k, 3)
    conics = np.concatenate([a1, np.einsum("kij,kj->ki", t, a1)], axis=1)
    # The Sampson MSE of the normalised conic; then its centre and axes, the quadratic form made positive definite
    # (eigenvectors have no sign).
    norm = np.linalg.norm(conics, axis=1, keepdims=True)
    cn = conics / np.where(norm > 0.0, norm, 1.0)
    val = np.einsum("kj,kjn->kn", cn, design)
    gx = np.einsum("kj,kjn->kn", np.stack([2.0 * cn[:, 0], cn[:, 1], cn[:, 3]], axis=1), design[:, 3:])
    gy = np.einsum("kj,kjn->kn", np.stack([cn[:, 1], 2.0 * cn[:, 2], cn[:, 4]], axis=1), design[:, 3:])
    mse = (val * val / np.maximum(gx * gx + gy * gy, 1e-300)).sum(axis=1) / n * scale * scale
    conics = np.where((conics[:, 0] + conics[:, 2] < 0.0)[:, None], -conics, conics)
    a, b, c, d, e, f = conics.T
    den = 4.0 * a * c - b * b
    ok = ~flat & finite & elliptic.any(axis=1) & (den > 0.0)
    den = np.where(ok, den, 1.0)
    x0 = (b * e - 2.0 * c * d) / den
    y0 = (b * d - 2.0 * a * e) / den
    f0 = f + 0.5 * (d * x0 + e * y0)
    mean, half = 0.5 * (a + c), np.hypot(0.5 * (a - c), 0.5 * b)
    real = (mean - half > 0.0) & (f0 < 0.0)
    semi_minor = np.sqrt(np.where(real & ok, -f0 / np.where(mean + half > 0.0, mean + half, 1.0), 0.0)) * scale
    theta = 0.5 * np.arctan2(b, a - c) + HALF_PI
    ct, st = np.cos(theta), np.sin(theta)
    cx, cy = x0 * scale, y0 * scale
    px, py = pad[:, 0] - cx[:, None], pad[:, 1] - cy[:, None]
    u = ct[:, None] * px + st[:, None] * py
    v = ct[:, None] * py - st[:, None] * px
    lo_u, hi_u = np.where(mask, u, np.inf).min(axis=1), np.where(mask, u, -np.inf).max(axis=1)
    lo_v, hi_v = np.where(mask, v, np.inf).min(axis=1), np.where(mask, v, -np.inf).max(axis=1)
    mean_v = (v * ones).sum(axis=1) / n
    length = hi_u - lo_u
    mid_u = 0.5 * (lo_u + hi_u)
    # The minor axis is only as trustworthy as the hull's curvature: keep the fitted width unless it exceeds the
    # visible length (an almost straight side fits a huge ellipse); then keep the visible side and shrink inward.
    spread_v, full_v = hi_v - lo_v, 2.0 * semi_minor
    wide = spread_v >= full_v
    fits = ~wide & (full_v <= length)
    width = np.where(wide, spread_v, np.where(fits, full_v, np.maximum(spread_v, length)))
    shrunk = np.where(mean_v < 0.0, lo_v + 0.5 * width, hi_v - 0.5 * width)
    mid_v = np.where(wide, 0.5 * (lo_v + hi_v), np.where(fits, 0.0, shrunk))
    cen_n = cx + mid_u * ct - mid_v * st
    cen_e = cy + mid_u * st + mid_v * ct
    swap = width > length
    length, width = np.where(swap, width, length), np.where(swap, length, width)
    theta = theta + np.where(swap, HALF_PI, 0.0)
    for j, (i, xy, origin) in enumerate(batch):
        if flat[j]:
            msg = "all points coincide" if not tr[j] > 0.0 else "points are collinear"
            out[i] = DegenerateClusterError(f"ellipse: {msg}")
        elif not finite[j]:
            out[i] = DegenerateClusterError("ellipse: ill-conditioned scatter matrix")
        elif not elliptic[j].any():
            out[i] = DegenerateClusterError("ellipse: no elliptic solution")
        elif not ok[j]:
            out[i] = DegenerateClusterError("ellipse: conic is not an ellipse")
        elif not real[j]:
            out[i] = DegenerateClusterError("ellipse: imaginary ellipse")
        else:
            center = np.array([origin[0] + cen_n[j], origin[1] + cen_e[j]])
            out[i] = ShapeFit(
                center,
                _axis_angle(float(theta[j])),
                float(length[j]),
                float(width[j]),
                float(mse[j]),
                ShapeKind.ELLIPSE,
                xy.shape[1],
                "ellipse",
            )
    return out


# ---------------------------------------------------------------------------------------------------------------------
# Heading guard (ours, not in the paper)


_EXTREME_DIRS = np.stack(
    [np.cos(np.arange(16) * math.pi / 16), np.sin(np.arange(16) * math.pi / 16)], axis=1
)  # (16, 2): the outline's extreme points along these directions stand in for its convex hull


def outline_edge_headings(xy: np.ndarray, min_fraction: float = 0.25) -> np.ndarray:
    """Directions (rad, [0, pi/2)) of the edges of centred (2, n) points' convex outline.

    The outline is approximated by the points extreme along 16 directions: enough to catch a hull's long straight
    sides, whose two ends are extreme for every direction near the side's normal. Edges shorter than
    ``min_fraction`` of the longest are left out.
    """
    proj = _EXTREME_DIRS @ xy
    # The sorted distinct extreme points, by marking them (np.unique sorts and has more overhead for 32 indices).
    extreme = np.zeros(xy.shape[1], dtype=bool)
    extreme[proj.argmin(axis=1)] = True
    extreme[proj.argmax(axis=1)] = True
    idx = np.flatnonzero(extreme)
    ext = xy[:, idx]
    if idx.size < 2:
        return np.zeros(0)
    mid = ext.mean(axis=1, keepdims=True)
    ext = ext[:, np.argsort(np.arctan2(ext[1] - mid[1], ext[0] - mid[0]))]
    edge = np.concatenate((ext[:, 1:], ext[:, :1]), axis=1) - ext  # each point to the next, around the outline
    size = np.hypot(edge[0], edge[1])
    edge = edge[:, size >= min_fraction * size.max()]  # a hull's sides, not the short chords of a rounded end
    return np.arctan2(edge[1], edge[0]) % HALF_PI


def closeness_scores(xy: np.ndarray, thetas: np.ndarray, min_distance: float) -> np.ndarray:
    """Zhang et al.'s closeness of centred (2, n) points to their bounding rectangle along each heading."""
    c, s = np.cos(thetas)[:, None], np.sin(thetas)[:, None]
    u = c * xy[0] + s * xy[1]
    v = c * xy[1] - s * xy[0]
    du = np.minimum(u - u.min(axis=1, keepdims=True), u.max(axis=1, keepdims=True) - u)
    dv = np.minimum(v - v.min(axis=1, keepdims=True), v.max(axis=1, keepdims=True) - v)
    return (1.0 / np.maximum(np.minimum(du, dv), min_distance)).sum(axis=1)


def guard_heading(
    fit: ShapeFit,
    points: np.ndarray,
    min_distance: float = 0.1,
    prepared: tuple[np.ndarray, np.ndarray] | None = None,
) -> ShapeFit:
    """The box along the outline edge that most points hug, instead of ``fit``'s when it scores higher.

    Algorithms 1-3 assume the outline is an L; a boat's cabin adds faces inside it (the paper's "more than 2 lines"),
    and the corner method then takes a cabin corner for the hull's and turns the box by tens of degrees. A hull's
    real sides are edges of its convex outline, so the outline's edge directions are the candidates, scored by
    Algorithm 2's closeness criterion (with ``min_distance`` about the footprint's grid cell) against the fit's own.
    ``prepared``: these points' :func:`_prepare` result when already computed (:func:`prepare_all`).
    """
    if fit.kind is not ShapeKind.BOX:
        return fit
    xy, origin = prepared if prepared is not None else _prepare(points)
    if xy.shape[1] < 3:
        return fit
    thetas = np.concatenate(([fit.heading % HALF_PI], outline_edge_headings(xy)))
    best = int(np.argmax(closeness_scores(xy, thetas, min_distance)))
    if best == 0 or abs((thetas[best] - thetas[0] + 0.25 * math.pi) % HALF_PI - 0.25 * math.pi) < 1e-3:
        return fit
    return box_from_heading(xy, float(thetas[best]), fit.method, origin)


# ---------------------------------------------------------------------------------------------------------------------
# Shape decision


def fit_box(
    points: np.ndarray, config: ShapeConfig, sensor_position: np.ndarray | None = None, method: str | None = None
) -> ShapeFit:
    """The L-shape fit ``method`` names (default: the configured one)."""
    method = method or config.lshape_method
    if method == "corner":
        return fit_lshape_corner(points, config.corner_min_offset)
    if method == "rotation":
        return fit_lshape_rotation(points, config.rotation_step, config.rotation_min_distance)
    if method == "bruteforce":
        return fit_lshape_bruteforce(points, sensor_position)
    raise ValueError(f"unknown L-shape method {method!r} (bruteforce | rotation | corner)")


_LSHAPE_MODES = {"lshape-bruteforce": "bruteforce", "lshape-rotation": "rotation", "lshape-corner": "corner"}


def fit_shape(
    points: np.ndarray,
    config: ShapeConfig | None = None,
    sensor_position: np.ndarray | None = None,
    ellipse: ShapeFit | DegenerateClusterError | None = None,
    box: ShapeFit | None = None,
) -> ShapeFit:
    """Fit per ``config.mode``; "adaptive" is Algorithm 4: box and ellipse, the smaller MSE wins.

    ``ellipse``: these points' :func:`fit_ellipse` result (or its error) when already computed, e.g. for a whole
    scan by :func:`fit_ellipses`; ``box`` likewise the configured L-shape fit (e.g. :func:`fit_lshape_corners`).
    Never raises for a cluster with at least one finite point: an impossible ellipse falls back to the box.
    """
    cfg = config or ShapeConfig()
    mode = cfg.mode
    if mode in ("adaptive", "ellipse") and ellipse is None:
        try:
            ellipse = fit_ellipse(points)
        except DegenerateClusterError as exc:
            ellipse = exc
    if mode == "adaptive":
        box = box or fit_box(points, cfg, sensor_position)
        if box.kind is ShapeKind.POINT or isinstance(ellipse, DegenerateClusterError):
            return box
        assert ellipse is not None
        return ellipse if ellipse.mse < box.mse else box
    if mode == "ellipse":
        if isinstance(ellipse, ShapeFit):
            return ellipse
        return fit_lshape_corner(points, cfg.corner_min_offset)
    if mode not in _LSHAPE_MODES:
        raise ValueError(f"unknown shape mode {mode!r}")
    return box or fit_box(points, cfg, sensor_position, _LSHAPE_MODES[mode])
