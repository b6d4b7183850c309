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


def _edge_mse(uv: np.ndarray, lo: np.ndarray, hi: np.ndarray) -> float:
    """Mean squared distance to the nearest box edge, each edge refit to the mean line of the points nearest to it.

    Per edge k with points at distances d: sum (d - mean d)^2 = sum d^2 - (sum d)^2 / count.
    """
    n = uv.shape[1]
    dist = np.empty((4, n))
    np.subtract(uv, lo[:, None], out=dist[:2])
    np.subtract(hi[:, None], uv, out=dist[2:])
    dmin = dist.min(axis=0)
    owner = dist == dmin
    count = np.maximum(owner.sum(axis=1), 1)
    per_edge = owner @ dmin
    return max(float(dmin @ dmin - np.sum(per_edge * per_edge / count)), 0.0) / n


def box_from_heading(xy: np.ndarray, theta: float, method: str, origin: np.ndarray) -> ShapeFit:
    """Bounding rectangle of centred (2, n) points with a side along ``theta``; heading along the longest side."""
    c, s = math.cos(theta), math.sin(theta)
    uv = np.array([[c, s], [-s, c]]) @ xy
    lo, hi = uv.min(axis=1), uv.max(axis=1)
    mu, mv = 0.5 * (lo[0] + hi[0]), 0.5 * (lo[1] + hi[1])
    center = np.array([origin[0] + mu * c - mv * s, origin[1] + mu * s + mv * c])
    length, width = float(hi[0] - lo[0]), float(hi[1] - lo[1])
    if length == 0.0 and width == 0.0:  # all points identical
        return ShapeFit(origin.copy(), 0.0, 0.0, 0.0, 0.0, ShapeKind.POINT, xy.shape[1], "point")
    if width > length:
        length, width, theta = width, length, theta + HALF_PI
    mse = _edge_mse(uv, lo, hi)
    return ShapeFit(center, _axis_angle(theta), length, width, mse, ShapeKind.BOX, xy.shape[1], method)


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
    xy, origin = _prepare(points)
    degenerate = _point_fit(xy, origin)
    if degenerate is not None:
        return degenerate
    x, y = xy
    proj = np.array([[1.0, 0.0], [0.0, 1.0], [1.0, 1.0], [1.0, -1.0]]) @ xy
    cand = np.concatenate([proj.argmin(axis=1), proj.argmax(axis=1)])
    cp = xy[:, cand]  # (2, 8)
    dist2 = (cp[0][:, None] - cp[0]) ** 2 + (cp[1][:, None] - cp[1]) ** 2
    flat = int(dist2.argmax())
    p1, p2 = cp[:, flat // cand.size], cp[:, flat % cand.size]
    diag = p2 - p1
    diag_len = math.hypot(diag[0], diag[1])
    offset = np.abs(diag[0] * (p1[1] - y) - diag[1] * (p1[0] - x))  # distance to the diagonal times its length
    k = int(offset.argmax())
    if offset[k] <= min_offset * diag_len:
        theta = math.atan2(diag[1], diag[0])
    else:
        p3 = xy[:, k]
        leg1, leg2 = p1 - p3, p2 - p3
        leg = leg1 if leg1 @ leg1 >= leg2 @ leg2 else leg2
        theta = math.atan2(leg[1], leg[0])
    return box_from_heading(xy, theta, "corner", origin)


# ---------------------------------------------------------------------------------------------------------------------
# Ellipse fitting


def _conic_fit(q: np.ndarray) -> np.ndarray:
    """Halir & Flusser's stable direct least-squares ellipse: conic [a, b, c, d, e, f] for normalised (2, n) points."""
    x, y = q
    d1 = np.stack([x * x, x * y, y * y])
    d2 = np.stack([x, y, np.ones_like(x)])
    s1, s2, s3 = d1 @ d1.T, d1 @ d2.T, d2 @ d2.T
    try:
        t = -np.linalg.solve(s3, s2.T)
    except np.linalg.LinAlgError as exc:
        raise DegenerateClusterError("ellipse: points are collinear") from exc
    m = s1 + s2 @ t
    # Premultiply by the inverse of the constraint matrix C1 = [[0, 0, 2], [0, -1, 0], [2, 0, 0]].
    m = np.array([m[2] / 2.0, -m[1], m[0] / 2.0])
    if not np.all(np.isfinite(m)):
        raise DegenerateClusterError("ellipse: ill-conditioned scatter matrix")
    _, vecs = np.linalg.eig(m)
    vecs = np.real(vecs)
    cond = 4.0 * vecs[0] * vecs[2] - vecs[1] ** 2
    ok = np.flatnonzero(cond > 0)
    if ok.size == 0:
        raise DegenerateClusterError("ellipse: no elliptic solution")
    a1 = vecs[:, ok[np.argmax(cond[ok])]]
    return np.concatenate([a1, t @ a1])


def ellipse_sampson_sq(conic: np.ndarray, q: np.ndarray) -> np.ndarray:
    """Squared Sampson distance of (2, n) points to a conic: F^2 / |grad F|^2, a first-order geometric distance."""
    a, b, c, d, e, f = conic
    x, y = q
    val = (a * x + b * y + d) * x + (c * y + e) * y + f
    gx = 2.0 * a * x + b * y + d
    gy = b * x + 2.0 * c * y + e
    return val * val / np.maximum(gx * gx + gy * gy, 1e-300)


def fit_ellipse(points: np.ndarray) -> ShapeFit:
    """Direct least-squares ellipse, cut to the points' extent along its major axis (sec. 2.2.2)."""
    xy, origin = _prepare(points)
    n = xy.shape[1]
    if n < 5:
        raise DegenerateClusterError(f"ellipse: needs 5 points, got {n}")
    cov = xy @ xy.T / n
    scale = math.sqrt(cov[0, 0] + cov[1, 1])
    if not scale > 0:
        raise DegenerateClusterError("ellipse: all points coincide")
    # Collinear points (smallest principal spread ~ 0) admit no ellipse.
    det, tr = cov[0, 0] * cov[1, 1] - cov[0, 1] ** 2, cov[0, 0] + cov[1, 1]
    if det < 1e-10 * tr * tr:
        raise DegenerateClusterError("ellipse: points are collinear")
    q = xy / scale
    conic = _conic_fit(q)
    if conic[0] + conic[2] < 0.0:  # eigenvectors have no sign; make the quadratic form positive definite
        conic = -conic
    a, b, c, d, e, f = conic
    den = 4.0 * a * c - b * b
    if not den > 0:
        raise DegenerateClusterError("ellipse: conic is not an ellipse")
    x0 = (b * e - 2.0 * c * d) / den
    y0 = (b * d - 2.0 * a * e) / den
    f0 = f + 0.5 * (d * x0 + e * y0)
    lam, vec = np.linalg.eigh(np.array([[a, 0.5 * b], [0.5 * b, c]]))
    semi_sq = -f0 / lam
    if not (np.all(semi_sq > 0) and np.all(np.isfinite(semi_sq))):
        raise DegenerateClusterError("ellipse: imaginary ellipse")
    # eigh sorts ascending: the smaller eigenvalue belongs to the major semi-axis, which the cut below replaces.
    semi_minor = math.sqrt(semi_sq[1]) * scale
    theta = math.atan2(vec[1, 0], vec[0, 0])
    mse = float(np.mean(ellipse_sampson_sq(conic / np.linalg.norm(conic), q))) * scale * scale

    # Cut: coordinates along the major (u) and minor (v) axis, relative to the fitted centre.
    ct, st = math.cos(theta), math.sin(theta)
    cx, cy = x0 * scale, y0 * scale
    uv = np.array([[ct, st], [-st, ct]]) @ (xy - np.array([[cx], [cy]]))
    lo, hi = uv.min(axis=1), uv.max(axis=1)
    length = float(hi[0] - lo[0])
    mid_u = 0.5 * float(lo[0] + hi[0])
    # The minor axis is only as trustworthy as the hull's curvature: keep the fitted width unless it exceeds the
    # visible length (an almost straight side fits a huge ellipse); then keep the visible side and shrink inward.
    spread_v, full_v = float(hi[1] - lo[1]), 2.0 * semi_minor
    if spread_v >= full_v:
        width, mid_v = spread_v, 0.5 * float(lo[1] + hi[1])
    elif full_v <= length:
        width, mid_v = full_v, 0.0
    else:
        width = max(spread_v, length)
        mid_v = float(lo[1]) + 0.5 * width if float(uv[1].mean()) < 0.0 else float(hi[1]) - 0.5 * width
    center = np.array([origin[0] + cx + mid_u * ct - mid_v * st, origin[1] + cy + mid_u * st + mid_v * ct])
    if width > length:
        length, width, theta = width, length, theta + HALF_PI
    return ShapeFit(center, _axis_angle(theta), length, width, mse, ShapeKind.ELLIPSE, n, "ellipse")


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
    points: np.ndarray, config: ShapeConfig | None = None, sensor_position: np.ndarray | None = None
) -> ShapeFit:
    """Fit per ``config.mode``; "adaptive" is Algorithm 4: box and ellipse, the smaller MSE wins.

    Never raises for a cluster with at least one finite point: an impossible ellipse falls back to the box.
    """
    cfg = config or ShapeConfig()
    mode = cfg.mode
    if mode == "adaptive":
        box = fit_box(points, cfg, sensor_position)
        if box.kind is ShapeKind.POINT:
            return box
        try:
            ellipse = fit_ellipse(points)
        except DegenerateClusterError:
            return box
        return ellipse if ellipse.mse < box.mse else box
    if mode == "ellipse":
        try:
            return fit_ellipse(points)
        except DegenerateClusterError:
            return fit_lshape_corner(points, cfg.corner_min_offset)
    if mode not in _LSHAPE_MODES:
        raise ValueError(f"unknown shape mode {mode!r}")
    return fit_box(points, cfg, sensor_position, _LSHAPE_MODES[mode])
