"""The adaptive EKF bank (paper sec. 2.4, eq. 6-12): one filterpy EKF per object, predicted together.

State (eq. 6), world NED: x = [p_n, p_e, v_n, v_e, heading, yaw_rate, length, width, height]; heading 0 = north,
clockwise positive, so a velocity (v_n, v_e) turning at yaw_rate w rotates as d/dt (v_n, v_e) = w (-v_e, v_n).
Motion model (eq. 8): a rigid body at constant turn rate and speed (the coordinated-turn model with Cartesian
velocity): the hull heading and the velocity vector both turn at w; sizes are constant. Its Jacobian feeds the
covariance prediction. All tracks are predicted at once with numpy; each track's update is filterpy's.

Measurement (eq. 7): y = [p_n, p_e, heading, length, width, height], linear in the state. R (eq. 11, 12) is the
full-visibility noise inflated where visibility (eq. 10) is poor: far away, a bad fit, or the object seen
end-on or broadside (relative heading 0 or 90 deg), when only one side shows and heading and size are guesses.

Heading lives on a circle and a fitted shape does not know which way is forward: a box's heading is only known
modulo 90 deg (with length and width swapped for odd quarter turns), an ellipse's modulo 180 deg (and modulo 90
once cut to a bow-on view, see :func:`heading_aliases`). Before each
update the measurement is replaced by the alias with the smallest Mahalanobis distance in (heading, length,
width) to the prediction, and the heading residual is wrapped; so a box seen from a new side never flips the
track. Once the track's speed is clearly known, its heading is turned once by 180 deg if it points astern.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from filterpy.kalman import ExtendedKalmanFilter

from tracker.lidar.config import EkfConfig
from tracker.types import ShapeKind

PN, PE, VN, VE, PSI, OMEGA, LEN, WID, HGT = range(9)
DIM_X, DIM_Z = 9, 6
Z_PN, Z_PE, Z_PSI, Z_LEN, Z_WID, Z_HGT = range(6)
H_FULL = np.zeros((DIM_Z, DIM_X))
H_FULL[[0, 1, 2, 3, 4, 5], [PN, PE, PSI, LEN, WID, HGT]] = 1.0
H_POSITION = H_FULL[:2]


def wrap_angle(a: np.ndarray | float) -> np.ndarray | float:
    """Angle(s) to [-pi, pi)."""
    return (a + math.pi) % (2.0 * math.pi) - math.pi


def ctrv_predict(x: np.ndarray, dt: float) -> tuple[np.ndarray, np.ndarray]:
    """Constant turn rate and velocity for (T, 9) states over ``dt`` s: predicted states and (T, 9, 9) Jacobians."""
    x = np.atleast_2d(x)
    n = x.shape[0]
    vn, ve, w = x[:, VN], x[:, VE], x[:, OMEGA]
    wt = w * dt
    s, c = np.sin(wt), np.cos(wt)
    small = np.abs(wt) < 1e-3
    w_safe = np.where(small, 1.0, w)
    # a = sin(wT)/w, b = (1 - cos(wT))/w and their derivatives in w; Taylor series near w = 0.
    a = np.where(small, dt * (1.0 - wt * wt / 6.0), s / w_safe)
    b = np.where(small, 0.5 * w * dt * dt * (1.0 - wt * wt / 12.0), (1.0 - c) / w_safe)
    da = np.where(small, -w * dt**3 / 3.0, (dt * c * w - s) / w_safe**2)
    db = np.where(small, 0.5 * dt * dt * (1.0 - wt * wt / 4.0), (dt * s * w - (1.0 - c)) / w_safe**2)

    out = x.copy()
    out[:, PN] += a * vn - b * ve
    out[:, PE] += b * vn + a * ve
    out[:, VN] = c * vn - s * ve
    out[:, VE] = s * vn + c * ve
    out[:, PSI] = wrap_angle(x[:, PSI] + wt)

    f = np.broadcast_to(np.eye(DIM_X), (n, DIM_X, DIM_X)).copy()
    f[:, PN, VN], f[:, PN, VE], f[:, PN, OMEGA] = a, -b, da * vn - db * ve
    f[:, PE, VN], f[:, PE, VE], f[:, PE, OMEGA] = b, a, db * vn + da * ve
    f[:, VN, VN], f[:, VN, VE], f[:, VN, OMEGA] = c, -s, -dt * (s * vn + c * ve)
    f[:, VE, VN], f[:, VE, VE], f[:, VE, OMEGA] = s, c, dt * (c * vn - s * ve)
    f[:, PSI, OMEGA] = dt
    return out, f


def process_noise(dt: float, config: EkfConfig) -> np.ndarray:
    """(9, 9) Q for one step: white acceleration on (p, v), white yaw acceleration on (heading, rate), size drift."""
    q = np.zeros((DIM_X, DIM_X))
    block = np.array([[dt**4 / 4.0, dt**3 / 2.0], [dt**3 / 2.0, dt * dt]])
    for p, v in ((PN, VN), (PE, VE)):
        q[np.ix_([p, v], [p, v])] = block * config.accel_std**2
    q[np.ix_([PSI, OMEGA], [PSI, OMEGA])] = block * config.yaw_accel_std**2
    q[[LEN, WID, HGT], [LEN, WID, HGT]] = config.size_drift_std**2 * dt
    return q


def visibility(range_m: float, mse: float, aspect: float, config: EkfConfig, occluded: bool = False) -> np.ndarray:
    """Eq. 10: trust (0..1) in each measured component [p_n, p_e, heading, length, width, height].

    ``aspect`` is the object's heading relative to the line of sight from the sensor; at 0 or 90 deg only one
    side is visible: length, width and the centre are uncertain, the heading is not. The paper names the inputs (relative position, relative heading, MSE) and their direction of
    influence, not the function; ours: a range factor 1 / (1 + (r / r_half)^2), a fit factor exp(-MSE / MSE_0) and
    an aspect factor max(|sin 2 aspect|, floor). An ``occluded`` object (partly in a nearer one's shadow) has its
    position and size trust multiplied by ``occluded_visibility``.
    """
    f_range = 1.0 / (1.0 + (range_m / config.visibility_half_range) ** 2)
    f_fit = math.exp(-max(mse, 0.0) / config.visibility_mse_scale)
    f_aspect = max(abs(math.sin(2.0 * aspect)), config.visibility_aspect_floor)
    # A one-sided view (aspect 0 or 90 deg) leaves the unseen dimension, and so the centre across it, unknown;
    # the visible side's direction, and so the heading (modulo its aliases), is as good as ever.
    position = f_range * f_fit * (0.5 + 0.5 * f_aspect)
    size = f_range * f_fit * f_aspect
    p = np.array([position, position, f_range * f_fit, size, size, f_range])
    if occluded:
        p[[Z_PN, Z_PE, Z_LEN, Z_WID]] *= config.occluded_visibility
    return p


def measurement_noise(p_vis: np.ndarray | None, config: EkfConfig) -> np.ndarray:
    """Eq. 11: R_k = R_full + r (1 - p)(1 - p)^T (or its diagonal, see ``EkfConfig.inflation_form``); eq. 12."""
    r_full = np.diag(np.square(config.r_full_std))
    if p_vis is None or not config.adaptive_r:
        return r_full
    miss = 1.0 - np.clip(np.asarray(p_vis, dtype=float), 0.0, 1.0)
    if config.inflation_form == "outer":
        return r_full + config.r_inflation * np.outer(miss, miss)
    return r_full + config.r_inflation * np.diag(miss * miss)


@dataclass
class Measurement:
    """One LiDAR detection as the filter sees it."""

    center: np.ndarray  # (2,) world north, east
    heading: float
    length: float
    width: float
    height: float
    kind: ShapeKind
    r: np.ndarray  # (6, 6) measurement covariance (eq. 11)

    def vector(self) -> np.ndarray:
        return np.array([self.center[0], self.center[1], self.heading, self.length, self.width, self.height])


def heading_aliases(m: Measurement) -> list[tuple[float, float, float]]:
    """(heading, length, width) quadruples that describe the same measured footprint.

    A box is symmetric under quarter turns with length and width swapped. So, in practice, is a cut ellipse: seen
    bow-on, the visible arc is wider than deep, the cut makes the across-hull extent the longer side, and the
    fitted heading is 90 deg off. Both kinds therefore offer all four; the Mahalanobis choice in
    :meth:`EkfBank.choose_alias` weighs heading and size, so a well-seen ellipse never takes a quarter turn.
    """
    return [
        (m.heading + k * 0.5 * math.pi, *((m.length, m.width) if k % 2 == 0 else (m.width, m.length))) for k in range(4)
    ]


def _residual(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    y = np.subtract(a, b)
    if y.shape[0] > Z_PSI:
        y[Z_PSI] = wrap_angle(float(y[Z_PSI]))
    return y


class EkfBank:
    """One ExtendedKalmanFilter per track, in a list; the bank predicts all of them in one batch."""

    def __init__(self, config: EkfConfig | None = None) -> None:
        self.config = config or EkfConfig()
        self.filters: list[ExtendedKalmanFilter] = []
        self.aligned: list[bool] = []  # heading's 180 deg ambiguity resolved by the course

    def __len__(self) -> int:
        return len(self.filters)

    # -- track birth and death --------------------------------------------------------------------------------

    def add(self, m: Measurement) -> int:
        cfg = self.config
        ekf = ExtendedKalmanFilter(dim_x=DIM_X, dim_z=DIM_Z)
        x = np.zeros(DIM_X)
        x[[PN, PE]] = m.center
        x[PSI] = wrap_angle(m.heading)
        x[[LEN, WID, HGT]] = m.length, m.width, m.height
        p = np.diag(np.diag(m.r)[[0, 1, 0, 0, 2, 0, 3, 4, 5]])
        p[VN, VN] = p[VE, VE] = cfg.init_speed_std**2
        p[OMEGA, OMEGA] = cfg.init_yaw_rate_std**2
        if m.kind is ShapeKind.POINT:  # no heading or size seen: wide priors
            p[PSI, PSI] = math.pi**2
            p[LEN, LEN] = p[WID, WID] = 4.0
        ekf.x, ekf.P, ekf.R = x, p, m.r
        self.filters.append(ekf)
        self.aligned.append(False)
        return len(self.filters) - 1

    def remove(self, indices: list[int]) -> None:
        drop = set(indices)
        self.filters = [f for i, f in enumerate(self.filters) if i not in drop]
        self.aligned = [a for i, a in enumerate(self.aligned) if i not in drop]

    # -- the cycle ----------------------------------------------------------------------------------------------

    def states(self) -> np.ndarray:
        return np.array([f.x for f in self.filters]).reshape(-1, DIM_X)

    def covariances(self) -> np.ndarray:
        return np.array([f.P for f in self.filters]).reshape(-1, DIM_X, DIM_X)

    def predict(self, dt: float) -> None:
        """Predict every track ``dt`` s ahead (in steps no longer than ``max_dt``)."""
        if not self.filters or not dt > 0:
            return
        x, p = self.states(), self.covariances()
        steps = max(1, math.ceil(dt / self.config.max_dt))
        h = dt / steps
        q = process_noise(h, self.config)
        for _ in range(steps):
            x, f = ctrv_predict(x, h)
            p = f @ p @ f.transpose(0, 2, 1) + q
        p = 0.5 * (p + p.transpose(0, 2, 1))
        for ekf, xi, pi, fi in zip(self.filters, x, p, f, strict=True):
            ekf.x, ekf.P, ekf.F = xi, pi, fi
            ekf.x_prior, ekf.P_prior = xi.copy(), pi.copy()

    def choose_alias(self, i: int, m: Measurement) -> Measurement:
        """The alias of ``m`` closest (Mahalanobis in heading, length, width) to track ``i``'s prediction."""
        if m.kind is ShapeKind.POINT:
            return m
        ekf = self.filters[i]
        x = ekf.x
        idx = [PSI, LEN, WID]
        s = ekf.P[np.ix_(idx, idx)] + m.r[np.ix_([Z_PSI, Z_LEN, Z_WID], [Z_PSI, Z_LEN, Z_WID])]
        s_inv = np.linalg.inv(s)
        best, best_d = None, math.inf
        for heading, length, width in heading_aliases(m):
            y = np.array([wrap_angle(heading - x[PSI]), length - x[LEN], width - x[WID]])
            d = float(y @ s_inv @ y)
            if d < best_d:
                best, best_d = (heading, length, width), d
        assert best is not None
        heading, length, width = best
        return Measurement(m.center, float(wrap_angle(heading)), length, width, m.height, m.kind, m.r)

    def update(self, i: int, m: Measurement) -> None:
        ekf = self.filters[i]
        if m.kind is ShapeKind.POINT:
            h = H_POSITION
            ekf.update(m.center, HJacobian=lambda _x: h, Hx=lambda x: h @ x, R=m.r[:2, :2])
        else:
            m = self.choose_alias(i, m)
            ekf.update(m.vector(), HJacobian=lambda _x: H_FULL, Hx=lambda x: H_FULL @ x, R=m.r, residual=_residual)
        ekf.x[PSI] = wrap_angle(float(ekf.x[PSI]))
        ekf.x[[LEN, WID, HGT]] = np.maximum(ekf.x[[LEN, WID, HGT]], 0.0)
        self._align_with_course(i)

    def _align_with_course(self, i: int) -> None:
        """Turn the heading once by 180 deg if it points against the course over ground.

        A fitted shape cannot tell bow from stern; the velocity can, once it is known well. Only half turns: which
        side is the longer one is the shape's business, and a boat may crab sideways in a current.
        """
        if self.aligned[i]:
            return
        ekf = self.filters[i]
        x, p = ekf.x, ekf.P
        speed = math.hypot(x[VN], x[VE])
        speed_std = math.sqrt(max(p[VN, VN] + p[VE, VE], 0.0))
        if speed < self.config.align_heading_min_speed or speed < 3.0 * speed_std:
            return
        along = math.cos(math.atan2(x[VE], x[VN]) - x[PSI])
        if abs(along) < 0.5:  # moving across the hull axis: no evidence about bow and stern yet
            return
        if along < 0.0:
            x[PSI] = wrap_angle(float(x[PSI]) + math.pi)
        self.aligned[i] = True
