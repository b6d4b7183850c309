"""Shape fitting (paper Algorithms 1-4) on exact synthetic clusters, with noise, and on degenerate input.

Conventions checked: centre in world (north, east), heading along the longest side in [0, pi), 0 = north,
clockwise (atan2(east, north)), length >= width.
"""

from __future__ import annotations

import math
from collections.abc import Callable

import numpy as np
import pytest

from tracker.lidar.config import ShapeConfig
from tracker.lidar.shape_fit import (
    DegenerateClusterError,
    ShapeFit,
    cluster_height,
    fit_ellipse,
    fit_lshape_bruteforce,
    fit_lshape_corner,
    fit_lshape_rotation,
    fit_shape,
)
from tracker.types import ShapeKind

CENTER = np.array([20.0, 10.0])
LENGTH, WIDTH = 8.6, 3.6  # the paper's container (sec. 3.1)
SENSOR = np.array([0.0, 0.0])


def rot(heading: float) -> np.ndarray:
    """Body (along, across) -> world (north, east) for a heading clockwise from north."""
    c, s = math.cos(heading), math.sin(heading)
    return np.array([[c, -s], [s, c]])


def box_sides(heading: float, sides: tuple[int, ...], spacing: float = 0.05) -> np.ndarray:
    """Points on chosen sides of the container: 0 = +along (bow), 1 = +across, 2 = -along, 3 = -across."""
    hl, hw = LENGTH / 2, WIDTH / 2
    corners = np.array([[hl, -hw], [hl, hw], [-hl, hw], [-hl, -hw], [hl, -hw]])
    pts = []
    for k in sides:
        a, b = corners[k], corners[k + 1]
        n = round(np.linalg.norm(b - a) / spacing) + 1
        pts.append(a + np.linspace(0.0, 1.0, n)[:, None] * (b - a))
    return np.concatenate(pts) @ rot(heading).T + CENTER


def ellipse_arc(heading: float, a: float, b: float, t0: float, t1: float, n: int = 120) -> np.ndarray:
    t = np.linspace(t0, t1, n)
    return np.stack([a * np.cos(t), b * np.sin(t)], axis=1) @ rot(heading).T + CENTER


def heading_error(a: float, b: float, period: float = math.pi) -> float:
    return abs((a - b + period / 2) % period - period / 2)


def assert_box(
    fit: ShapeFit, heading: float, length: float, width: float, pos_tol: float, ang_tol: float, size_tol: float
) -> None:
    assert np.hypot(*(fit.center - CENTER)) < pos_tol
    assert heading_error(fit.heading, heading) < ang_tol
    assert 0.0 <= fit.heading < math.pi
    assert fit.length == pytest.approx(length, abs=size_tol)
    assert fit.width == pytest.approx(width, abs=size_tol)
    assert fit.length >= fit.width


def visible_sides(heading: float) -> tuple[int, ...]:
    """The sides whose outward normal faces the sensor."""
    normals = np.array([[1.0, 0.0], [0.0, 1.0], [-1.0, 0.0], [0.0, -1.0]]) @ rot(heading).T
    mids = CENTER + normals * np.array([LENGTH, WIDTH, LENGTH, WIDTH])[:, None] / 2
    return tuple(int(k) for k in np.flatnonzero(np.einsum("ij,ij->i", normals, SENSOR - mids) > 0))


LSHAPE_FITTERS = {
    "corner": lambda p: fit_lshape_corner(p),
    "rotation": lambda p: fit_lshape_rotation(p, math.radians(0.5)),
    "bruteforce": lambda p: fit_lshape_bruteforce(p, SENSOR),
}


@pytest.mark.parametrize("method", sorted(LSHAPE_FITTERS))
@pytest.mark.parametrize("heading_deg", [10.0, 75.0, 150.0])
def test_lshape_exact_l_view(method: str, heading_deg: float) -> None:
    heading = math.radians(heading_deg)
    sides = visible_sides(heading)
    assert len(sides) == 2  # an L as the scanner sees it
    pts = box_sides(heading, sides)
    fit = LSHAPE_FITTERS[method](pts)
    assert fit.kind is ShapeKind.BOX and fit.method == method
    # Rotation searches 0.5 deg steps: the rectangle may be off by half a step, which shifts a 8.6 m box's
    # extent by up to 8.6 * sin(0.25 deg) = 0.04 m.
    assert_box(fit, heading, LENGTH, WIDTH, pos_tol=0.05, ang_tol=math.radians(0.3), size_tol=0.05)
    assert fit.mse < 1e-4
    assert fit.n_points == len(pts)


@pytest.mark.parametrize("method", sorted(LSHAPE_FITTERS))
def test_lshape_noisy_l_view(method: str) -> None:
    heading = math.radians(35.0)
    rng = np.random.default_rng(7)
    pts = box_sides(heading, visible_sides(heading))
    pts = pts + rng.normal(0.0, 0.03, pts.shape)
    fit = LSHAPE_FITTERS[method](pts)
    # The bounding rectangle reaches the outermost noisy point: sizes grow by ~2-3 sigma, centre moves ~1 sigma.
    assert_box(fit, heading, LENGTH, WIDTH, pos_tol=0.15, ang_tol=math.radians(2.0), size_tol=0.2)
    assert fit.mse < 0.03**2 * 3  # about the noise variance: the edges are refit to the mean lines


@pytest.mark.parametrize("method", sorted(LSHAPE_FITTERS))
def test_lshape_i_view_gives_the_visible_side(method: str) -> None:
    heading = math.radians(60.0)
    pts = box_sides(heading, (1,))  # only the starboard side, 8.6 m long
    fit = LSHAPE_FITTERS[method](pts)
    assert heading_error(fit.heading, heading) < math.radians(0.3)
    assert fit.length == pytest.approx(LENGTH, abs=0.01)
    assert fit.width < 0.01
    side_mid = CENTER + rot(heading) @ np.array([0.0, WIDTH / 2])
    assert np.hypot(*(fit.center - side_mid)) < 0.01


def test_ellipse_exact_half_hull() -> None:
    heading = math.radians(70.0)
    pts = ellipse_arc(heading, 5.0, 2.0, 0.0, math.pi)  # one long side, bow to stern: 10 m x 4 m
    fit = fit_ellipse(pts)
    assert fit.kind is ShapeKind.ELLIPSE
    assert_box(fit, heading, 10.0, 4.0, pos_tol=0.01, ang_tol=math.radians(0.1), size_tol=0.01)
    assert fit.mse < 1e-10


def test_ellipse_noisy_partial_hull() -> None:
    heading = math.radians(125.0)
    rng = np.random.default_rng(3)
    pts = ellipse_arc(heading, 5.0, 2.0, -0.2, math.pi + 0.2, n=150)
    pts = pts + rng.normal(0.0, 0.02, pts.shape)
    fit = fit_ellipse(pts)
    assert_box(fit, heading, 10.0, 4.0, pos_tol=0.2, ang_tol=math.radians(2.0), size_tol=0.3)
    assert fit.mse == pytest.approx(0.02**2, rel=0.5)


def test_ellipse_is_cut_to_the_visible_extent() -> None:
    # A shallow arc of a 40 m x 4 m ellipse: the full fit would be 40 m long; the cut keeps what was seen.
    heading = math.radians(20.0)
    pts = ellipse_arc(heading, 20.0, 2.0, math.radians(60.0), math.radians(120.0))
    fit = fit_ellipse(pts)
    visible = 2 * 20.0 * math.cos(math.radians(60.0))  # 20 m along the major axis
    assert fit.length == pytest.approx(visible, abs=0.05)
    assert fit.width <= fit.length
    assert heading_error(fit.heading, heading) < math.radians(0.5)
    # The centre moves to the middle of the visible arc along the major axis, the fitted centre across it.
    assert np.hypot(*(fit.center - CENTER)) < 0.05


def test_ellipse_rejects_what_is_not_an_ellipse() -> None:
    with pytest.raises(DegenerateClusterError, match="5 points"):
        fit_ellipse(np.array([[0.0, 0.0], [1.0, 0.0], [0.0, 1.0], [1.0, 1.0]]))
    with pytest.raises(DegenerateClusterError, match="collinear"):
        fit_ellipse(np.stack([np.arange(10.0), 2.0 * np.arange(10.0)], axis=1))
    with pytest.raises(DegenerateClusterError, match="coincide"):
        fit_ellipse(np.ones((6, 2)))


def test_ellipse_mse_is_the_mean_squared_sampson_distance() -> None:
    # A circle of radius 5 whose returns alternate 0.1 m outside and inside it: the fit is the circle (by symmetry)
    # and each return's Sampson distance F / |grad F| = (2 r d + d^2) / (2 (r + d)) is 0.1 m to within 1 %, so the
    # MSE is 0.01 m^2; returns exactly on it give 0.
    a = np.linspace(0.0, 2.0 * math.pi, 40, endpoint=False)
    r = 5.0 + 0.1 * np.where(np.arange(40) % 2 == 0, 1.0, -1.0)
    fit = fit_ellipse(np.column_stack([r * np.cos(a) + 20.0, r * np.sin(a) - 3.0]))
    assert fit.mse == pytest.approx(0.01, rel=0.01)
    np.testing.assert_allclose(fit.center, [20.0, -3.0], atol=1e-9)
    assert fit_ellipse(np.column_stack([5.0 * np.cos(a), 5.0 * np.sin(a)])).mse < 1e-20


@pytest.mark.parametrize("method", ["corner", "rotation", "bruteforce"])
def test_adaptive_picks_box_for_container_and_ellipse_for_hull(method: str) -> None:
    cfg = ShapeConfig(lshape_method=method)  # type: ignore[arg-type]
    rng = np.random.default_rng(11)
    container = box_sides(math.radians(40.0), visible_sides(math.radians(40.0)))
    container = container + rng.normal(0.0, 0.02, container.shape)
    hull = ellipse_arc(math.radians(40.0), 5.0, 2.0, -0.3, 2.2)
    hull = hull + rng.normal(0.0, 0.02, hull.shape)
    assert fit_shape(container, cfg, SENSOR).kind is ShapeKind.BOX
    assert fit_shape(hull, cfg, SENSOR).kind is ShapeKind.ELLIPSE


@pytest.mark.parametrize(
    ("mode", "method", "kind"),
    [
        ("lshape-corner", "corner", ShapeKind.BOX),
        ("lshape-rotation", "rotation", ShapeKind.BOX),
        ("lshape-bruteforce", "bruteforce", ShapeKind.BOX),
        ("ellipse", "ellipse", ShapeKind.ELLIPSE),
    ],
)
def test_ablation_modes_use_one_fitter(mode: str, method: str, kind: ShapeKind) -> None:
    hull = ellipse_arc(math.radians(40.0), 5.0, 2.0, -0.3, 2.2)
    fit = fit_shape(hull, ShapeConfig(mode=mode), SENSOR)  # type: ignore[arg-type]
    assert (fit.method, fit.kind) == (method, kind)


ALL_FITTERS = [
    lambda p: fit_lshape_corner(p),
    lambda p: fit_lshape_rotation(p),
    lambda p: fit_lshape_bruteforce(p, SENSOR),
    lambda p: fit_shape(p),
]


@pytest.mark.parametrize("fitter", ALL_FITTERS)
def test_degenerate_input(fitter: Callable[[np.ndarray], ShapeFit]) -> None:
    nan = float("nan")
    with pytest.raises(DegenerateClusterError, match="no finite points"):
        fitter(np.zeros((0, 2)))
    with pytest.raises(DegenerateClusterError, match="no finite points"):
        fitter(np.array([[nan, 1.0], [2.0, nan]]))
    with pytest.raises(DegenerateClusterError, match=r"\(n, 2\)"):
        fitter(np.array([1.0, 2.0]))

    one = fitter(np.array([[3.0, 4.0]]))
    assert (one.kind, one.length, one.width) == (ShapeKind.POINT, 0.0, 0.0)
    assert one.center == pytest.approx([3.0, 4.0])

    two = fitter(np.array([[0.0, 0.0], [3.0, 4.0]]))
    assert two.kind is ShapeKind.POINT
    assert two.center == pytest.approx([1.5, 2.0])
    assert (two.length, two.heading) == pytest.approx((5.0, math.atan2(4.0, 3.0)))

    dup = fitter(np.array([[1.0, 1.0]] * 7))
    assert dup.kind is ShapeKind.POINT and dup.center == pytest.approx([1.0, 1.0])

    line = fitter(np.array([[0.0, 0.0], [1.0, 1.0], [2.0, 2.0], [3.0, 3.0], [3.0, 3.0], [1.5, 1.5]]))
    assert line.kind is ShapeKind.BOX  # a thin box along the line
    assert line.width < 1e-9
    assert line.length == pytest.approx(3.0 * math.sqrt(2.0))
    assert line.heading == pytest.approx(math.pi / 4)
    assert line.center == pytest.approx([1.5, 1.5])

    # NaN rows are dropped, the rest is fitted as if they were not there.
    clean = box_sides(0.3, visible_sides(0.3), spacing=0.2)
    dirty = np.insert(clean, [3, 10], [[nan, 5.0], [np.inf, 1.0]], axis=0)
    a, b = fitter(clean), fitter(dirty)
    assert a.center == pytest.approx(b.center)
    assert (a.heading, a.length, a.width, a.n_points) == pytest.approx((b.heading, b.length, b.width, b.n_points))


def test_heading_is_never_exactly_pi() -> None:
    # Points along north with a hair of westward tilt: the axis angle is -1e-17, which float modulo turns into pi.
    pts = np.array([[0.0, 0.0], [10.0, -1e-16], [5.0, -5e-17], [2.0, 0.0]])
    for fit in (fit_lshape_corner(pts), fit_lshape_bruteforce(pts), fit_lshape_rotation(pts)):
        assert 0.0 <= fit.heading < math.pi
        assert heading_error(fit.heading, 0.0) < 1e-12


def test_cluster_height() -> None:
    z = np.array([-0.2, -3.1, np.nan, -1.0])  # NED down: 3.1 m above the lowest... 0.2 m
    assert cluster_height(z) == pytest.approx(2.9)
    assert cluster_height(np.array([np.nan])) == 0.0
