"""The adaptive EKF bank (paper sec. 2.4, eq. 6-12): one filterpy EKF per object, predicted together.

State (eq. 6), world NED: x = [p_n, p_e, v_n, v_e, heading, yaw_rate, length, width, height]; heading 0 = north,
clockwise positive, so a velocity (v_n, v_e) turning at yaw_rate w rotates as d/dt (v_n, v_e) = w (-v_e, v_n).
Motion model (eq. 8): a rigid body at constant turn rate and speed (the coordinated-turn model with Cartesian velocity,
tracker.coordinated_turn, shared with the radar filter): the hull heading and the velocity vector both turn at w; sizes
are constant. Its Jacobian feeds the covariance prediction. All tracks are predicted at once with numpy; the filterpy
objects hold each track's state, and the updates (Joseph form, as filterpy's) run stacked for all tracks that take
eq. 7's plain update.

Measurement (eq. 7): y = [p_n, p_e, heading, length, width, height], linear in the state. R (eq. 11, 12) is the
full-visibility noise inflated where visibility (eq. 10) is poor: far away, a bad fit, or the object seen
end-on or broadside (relative heading 0 or 90 deg), when only one side shows and heading and size are guesses.

Heading lives on a circle and a fitted shape does not know which way is forward: a box's heading is only known
modulo 90 deg (with length and width swapped for odd quarter turns), an ellipse's modulo 180 deg (and modulo 90
once cut to a bow-on view: the visible arc is wider than deep, the cut makes the across-hull extent the longer
side, and the fitted heading is 90 deg off; so both kinds offer all four quarter turns). Before each
update the measurement is replaced by the alias with the smallest Mahalanobis distance in (heading, length,
width) to the prediction, and the heading residual is wrapped; so a box seen from a new side never flips the
track. Once the track's speed is clearly known, its heading is turned once by 180 deg if it points astern.

Ours, not in the paper (``EkfConfig.view_aware``; see :meth:`EkfBank._view_aware_plan`): a LiDAR sees at most two
sides, so an extent whose far end is out of view only bounds the size from below, and the update then measures the
near edge instead of the centre; a newborn seen from one side gets a prior beam behind that side; a track whose
width outgrows its length is re-expressed a quarter turn on (:meth:`EkfBank._canonical`). A cluster swept
``Measurement.lag`` s before the scan's time measures where the hull was then: its centre rows observe p - lag v,
still linear in the state.
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass

import numpy as np
from filterpy.kalman import ExtendedKalmanFilter

from tracker.coordinated_turn import coordinated_turn
from tracker.kalman_update import joseph_update
from tracker.lidar.config import EkfConfig
from tracker.types import ShapeKind

PN, PE, VN, VE, PSI, OMEGA, LEN, WID, HGT = range(9)
DIM_X, DIM_Z = 9, 6
Z_PN, Z_PE, Z_PSI, Z_LEN, Z_WID, Z_HGT = range(6)
H_FULL = np.zeros((DIM_Z, DIM_X))
H_FULL[[0, 1, 2, 3, 4, 5], [PN, PE, PSI, LEN, WID, HGT]] = 1.0
H_POSITION = H_FULL[:2]
# Heading aliases (the module's doc): state and measurement indices of (heading, length, width), and the four
# quarter turns, the odd ones swapping length and width.
_ALIAS_STATE = np.array([[PSI], [LEN], [WID]])
_ALIAS_MEAS = np.array([[Z_PSI], [Z_LEN], [Z_WID]])
_QUARTERS = 0.5 * math.pi * np.arange(4)
_Z_STATES = np.array([PN, PE, PSI, LEN, WID, HGT])  # the state each measurement component observes (H_FULL)
_ODD = np.arange(4) % 2 == 1
# Where coordinated_turn's results go: rows (p_n, p_e, v_n, v_e) of its (4, 3) Jacobian block, columns (v_n, v_e,
# yaw rate). Slices where they can be: a fancy index costs several times as much in this per-cycle path.
_POSITION, _VELOCITY = slice(PN, PE + 1), slice(VN, VE + 1)
_TURN_ROWS = np.array([[PN], [PE], [VN], [VE]])
_TURN_COLS = np.array([VN, VE, OMEGA])


def wrap_angle(a: np.ndarray | float) -> np.ndarray | float:
    """Angle(s) to [-pi, pi)."""
    return (a + math.pi) % (2.0 * math.pi) - math.pi


def ctrv_predict(x: np.ndarray, dt: float) -> tuple[np.ndarray, np.ndarray]:
    """Constant turn rate and velocity for (T, 9) states over ``dt`` s: predicted states and (T, 9, 9) Jacobians."""
    x = np.atleast_2d(x)
    n = x.shape[0]
    step = coordinated_turn(x[:, VN], x[:, VE], x[:, OMEGA], dt)
    out = x.copy()
    out[:, _POSITION] += step.delta_position
    out[:, _VELOCITY] = step.velocity
    out[:, PSI] = wrap_angle(x[:, PSI] + x[:, OMEGA] * dt)

    f = np.broadcast_to(np.eye(DIM_X), (n, DIM_X, DIM_X)).copy()
    f[:, _TURN_ROWS, _TURN_COLS] = step.jacobian
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


def visibility(
    range_m: float, mse: float, aspect: float, config: EkfConfig, occluded: bool = False, use_aspect: bool = True
) -> np.ndarray:
    """Eq. 10: trust (0..1) in each measured component [p_n, p_e, heading, length, width, height].

    ``aspect`` is the object's heading relative to the line of sight from the sensor; at 0 or 90 deg only one
    side is visible: length, width and the centre are uncertain, the heading is not. The paper names the inputs
    (relative position, relative heading, MSE) and their direction of influence, not the function; ours: a range factor
    1 / (1 + (r / r_half)^2), a fit factor exp(-MSE / MSE_0) and an aspect factor max(|sin 2 aspect|, floor). An
    ``occluded`` object (partly in a nearer one's shadow) has its position and size trust multiplied by
    ``occluded_visibility``.
    """
    f_range = 1.0 / (1.0 + (range_m / config.visibility_half_range) ** 2)
    f_fit = math.exp(-max(mse, 0.0) / config.visibility_mse_scale)
    # The view-aware update (EkfConfig.view_aware) knows which extents the view cuts short from the faces in view;
    # it passes use_aspect=False, so a well-seen L at a small aspect angle is not distrusted as well.
    f_aspect = max(abs(math.sin(2.0 * aspect)), config.visibility_aspect_floor) if use_aspect else 1.0
    # A one-sided view (aspect 0 or 90 deg) leaves the unseen dimension, and so the centre across it, unknown;
    # the visible side's direction, and so the heading (modulo its aliases), is as good as ever.
    position = f_range * f_fit * (0.5 + 0.5 * f_aspect)
    size = f_range * f_fit * f_aspect
    p = np.array([position, position, f_range * f_fit, size, size, f_range])
    if occluded:
        p[[Z_PN, Z_PE, Z_LEN, Z_WID]] *= config.occluded_visibility
    return p


def measurement_noises(p_vis: np.ndarray, config: EkfConfig) -> np.ndarray:
    """Eq. 11 for (k, 6) visibilities: (k, 6, 6) R_k = R_full + r (1 - p)(1 - p)^T, or its diagonal (see
    ``EkfConfig.inflation_form``); R_full alone without ``adaptive_r`` (eq. 12)."""
    p_vis = np.asarray(p_vis, dtype=float).reshape(-1, DIM_Z)
    r_full = np.diag(np.square(np.asarray(config.r_full_std, dtype=float)))
    if not config.adaptive_r:
        return np.broadcast_to(r_full, (p_vis.shape[0], DIM_Z, DIM_Z)).copy()
    miss = 1.0 - np.clip(p_vis, 0.0, 1.0)
    if config.inflation_form == "outer":
        return r_full + config.r_inflation * (miss[:, :, None] * miss[:, None, :])
    squares = np.zeros((p_vis.shape[0], DIM_Z, DIM_Z))
    squares[:, np.arange(DIM_Z), np.arange(DIM_Z)] = miss * miss
    return r_full + config.r_inflation * squares


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
    # Own boat (north, east) when the cluster was seen; enables the view-aware update (EkfConfig.view_aware).
    sensor: np.ndarray | None = None
    # Ends, in bearing from the sensor (low, high), that a nearer object's shadow reaches (clustering.shadows):
    # the hull may go on there, so the view-aware update measures the other end, or neither.
    shadowed: tuple[bool, bool] = (False, False)
    # Time (s) from the cluster's sweep to the scan's: the centre is where the hull was then, h(x) = p - lag v, so
    # the filter weighs the lag by its own velocity uncertainty instead of trusting the estimate
    # (EkfConfig.compensate_sweep).
    lag: float = 0.0

    def vector(self) -> np.ndarray:
        return np.array([self.center[0], self.center[1], self.heading, self.length, self.width, self.height])


def faces_seen(
    center: np.ndarray, heading: float, length: float, width: float, sensor: np.ndarray, min_angle: float
) -> tuple[bool, bool]:
    """Whether the box's extent along (length, width) is fully in view from ``sensor``.

    A LiDAR sees at most two adjacent faces, and a face in view shows its whole span. The length is fully seen
    when a long side faces the sensor and subtends at least ``min_angle`` (rad, a few azimuth steps, so that both
    its ends carry returns); the width likewise when an end face does.
    """
    c, s = math.cos(heading), math.sin(heading)
    rx, ry = float(sensor[0] - center[0]), float(sensor[1] - center[1])
    su, sv = rx * c + ry * s, ry * c - rx * s
    du, dv = abs(su) - 0.5 * length, abs(sv) - 0.5 * width
    # Apparent size of a face: its span x cos(incidence) / distance = span x (normal offset) / distance^2.
    end_angle = width * du / (du * du + sv * sv) if du > 0.0 else 0.0
    side_angle = length * dv / (dv * dv + su * su) if dv > 0.0 else 0.0
    return side_angle >= min_angle, end_angle >= min_angle


def prior_beam_would_show(
    center: np.ndarray, heading: float, length: float, sensor: np.ndarray, config: EkfConfig
) -> bool:
    """Whether a hull ``length`` long along ``heading``, with the prior beam (``beam_ratio`` x ``length``), would
    show an end face from ``sensor`` (:func:`faces_seen`): if so, a thinner outline seen there is the whole object."""
    return faces_seen(center, heading, length, config.beam_ratio * length, sensor, config.face_min_angle)[1]


def _update_full(filters: list[ExtendedKalmanFilter], ms: list[Measurement]) -> None:
    """Eq. 7's update of each filter with its measurement (all six components), stacked."""
    x = np.array([f.x for f in filters])
    y = np.array([[m.center[0], m.center[1], m.heading, m.length, m.width, m.height] for m in ms]) - x[:, _Z_STATES]
    y[:, Z_PSI] = (y[:, Z_PSI] + math.pi) % (2.0 * math.pi) - math.pi
    lags = np.array([m.lag for m in ms])
    h = _lag_rows(np.repeat(H_FULL[None], len(ms), axis=0), lags)
    y[:, :2] += lags[:, None] * x[:, [VN, VE]]
    _apply(filters, x, h, y, np.array([m.r for m in ms]))


def _lag_rows(h: np.ndarray, lag: np.ndarray | float) -> np.ndarray:
    """``h`` (..., rows, DIM_X) of measurements swept ``lag`` s (one per leading index) before the state's time, in
    place: each row's position columns, times -lag, on its velocity columns, so that it observes p - lag v."""
    h[..., VN : VE + 1] = -np.asarray(lag, dtype=float)[..., None, None] * h[..., PN : PE + 1]
    return h


def _apply(filters: list[ExtendedKalmanFilter], x: np.ndarray, h: np.ndarray, y: np.ndarray, r: np.ndarray) -> None:
    """tracker.kalman_update.joseph_update of ``filters`` (states ``x``), written back to them."""
    x, p, s, k = joseph_update(x, np.array([f.P for f in filters]), h, y, r)
    for j, f in enumerate(filters):
        f.x, f.P, f.y, f.S, f.K = x[j], p[j], y[j], s[j], k[j]


def _update_rows(
    filters: list[ExtendedKalmanFilter], rows: list[tuple[np.ndarray, np.ndarray, np.ndarray, int]]
) -> None:
    """Linear(ised) Kalman update, Joseph form, of each filter with its own (z, H, R, heading row), stacked by row
    count and heading row; the residual of the heading row (-1: no heading measured) is wrapped to (-pi, pi]."""
    groups: dict[tuple[int, int], list[int]] = {}
    for j, (z, _, _, heading_row) in enumerate(rows):
        groups.setdefault((z.shape[0], heading_row), []).append(j)
    for (_, heading_row), group in groups.items():
        x = np.array([filters[j].x for j in group])
        h = np.array([rows[j][1] for j in group])
        y = np.array([rows[j][0] for j in group]) - (h @ x[:, :, None])[:, :, 0]
        if heading_row >= 0:
            y[:, heading_row] = (y[:, heading_row] + math.pi) % (2.0 * math.pi) - math.pi
        _apply([filters[j] for j in group], x, h, y, np.array([rows[j][2] for j in group]))


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
        elif cfg.view_aware and m.sensor is not None:
            self._unseen_beam(x, p, m)
        ekf.x, ekf.P, ekf.R = x, p, m.r
        self.filters.append(ekf)
        self.aligned.append(False)
        return len(self.filters) - 1

    def _unseen_beam(self, x: np.ndarray, p: np.ndarray, m: Measurement) -> None:
        """A newborn seen from one side only: its beam is a prior, and the centre lies behind the seen side.

        The fitted box puts its length along the seen side; when no end face was in view, the width is a lower
        bound. It becomes max(seen, beam_ratio x length) with ``unseen_size_std``, the centre half the difference
        further from the sensor, and the centre's uncertainty across the hull is tied to the width's.
        """
        cfg = self.config
        assert m.sensor is not None
        prior = cfg.beam_ratio * m.length
        # Would a hull of the prior's beam show an end face from here? Then the thin outline is the whole object.
        if prior_beam_would_show(m.center, m.heading, m.length, m.sensor, cfg) or m.width >= prior:
            return
        c, s = math.cos(m.heading), math.sin(m.heading)
        e_v = np.array([-s, c])
        away = -1.0 if float((m.sensor - m.center) @ e_v) > 0.0 else 1.0  # across the hull, away from the sensor
        x[[PN, PE]] += away * 0.5 * (prior - m.width) * e_v
        x[WID] = prior
        var = cfg.unseen_size_std**2
        p[WID, WID] = var
        p[np.ix_([PN, PE], [PN, PE])] += 0.25 * var * np.outer(e_v, e_v)
        p[[PN, PE], WID] = p[WID, [PN, PE]] = 0.5 * away * var * e_v

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
        # The priors are copies (the updates replace x and P); one copy of the stack, not two per track.
        x_prior, p_prior = x.copy(), p.copy()
        for j, ekf in enumerate(self.filters):
            ekf.x, ekf.P, ekf.F = x[j], p[j], f[j]
            ekf.x_prior, ekf.P_prior = x_prior[j], p_prior[j]

    def choose_aliases(self, pairs: list[tuple[int, Measurement]], seen: list[tuple[bool, bool]]) -> list[Measurement]:
        """The alias of each measurement closest (Mahalanobis in heading, length, width) to its track's prediction,
        for many (track, measurement) pairs at once (box or ellipse kinds only): the four quarter turns of each,
        residuals in (heading, length, width), the size rows of an extent not in view counted only where the alias comes
        out larger than the track."""
        k = len(pairs)
        if k == 0:
            return []
        x = np.array([self.filters[i].x for i, _ in pairs])
        p = np.array([self.filters[i].P for i, _ in pairs])
        r = np.array([m.r for _, m in pairs])
        s = p[:, _ALIAS_STATE, _ALIAS_STATE.T] + r[:, _ALIAS_MEAS, _ALIAS_MEAS.T]
        meas = np.array([(m.heading, m.length, m.width) for _, m in pairs])
        heading = meas[:, :1] + _QUARTERS  # (k, 4)
        length = np.where(_ODD, meas[:, 2:3], meas[:, 1:2])
        width = np.where(_ODD, meas[:, 1:2], meas[:, 2:3])
        y = np.empty((k, 3, 4))
        y[:, 0] = (heading - x[:, PSI : PSI + 1] + math.pi) % (2.0 * math.pi) - math.pi
        y[:, 1] = length - x[:, LEN : LEN + 1]
        y[:, 2] = width - x[:, WID : WID + 1]
        full = np.array(seen, dtype=bool).reshape(k, 2)
        y[:, 1:] = np.where(full[:, :, None], y[:, 1:], np.maximum(y[:, 1:], 0.0))
        best = np.argmin((y * np.linalg.solve(s, y)).sum(axis=1), axis=1)
        out = []
        for j, (_, m) in enumerate(pairs):
            b = int(best[j])
            if b == 0:
                out.append(m)
                continue
            out.append(
                dataclasses.replace(
                    m, heading=float(wrap_angle(heading[j, b])), length=float(length[j, b]), width=float(width[j, b])
                )
            )
        return out

    def update(self, i: int, m: Measurement) -> None:
        """Update track ``i`` with measurement ``m`` (eq. 7 and 11, view-aware if configured)."""
        self.update_many([(i, m)])

    def update_many(self, pairs: list[tuple[int, Measurement]]) -> None:
        """Update several tracks, one measurement each; the plain eq. 7 updates run as one stacked solve."""
        points = [(i, m) for i, m in pairs if m.kind is ShapeKind.POINT]
        shaped = [(i, m) for i, m in pairs if m.kind is not ShapeKind.POINT]
        if points:
            _update_rows(
                [self.filters[i] for i, _ in points],
                [(m.center, _lag_rows(H_POSITION.copy(), m.lag), m.r[:2, :2], -1) for _, m in points],
            )
        view_aware = self.config.view_aware
        aware = [(i, m) for i, m in shaped if view_aware and m.sensor is not None]
        plain = [(i, m) for i, m in shaped if not (view_aware and m.sensor is not None)]
        full = list(zip([i for i, _ in plain], self.choose_aliases(plain, [(True, True)] * len(plain)), strict=True))
        if aware:
            seen = [self._seen(i, m) for i, m in aware]
            partial: list[int] = []
            partial_rows: list[tuple[np.ndarray, np.ndarray, np.ndarray, int]] = []
            for (i, _), aliased, s in zip(aware, self.choose_aliases(aware, seen), seen, strict=True):
                rows = self._view_aware_plan(i, aliased, s)
                if rows is None:
                    full.append((i, aliased))
                else:
                    partial.append(i)
                    partial_rows.append(rows)
            if partial:
                _update_rows([self.filters[i] for i in partial], partial_rows)
        if full:
            _update_full([self.filters[i] for i, _ in full], [m for _, m in full])
        for i, _ in pairs:
            x = self.filters[i].x
            x[PSI] = wrap_angle(float(x[PSI]))
            np.maximum(x[LEN : HGT + 1], 0.0, out=x[LEN : HGT + 1])
            self._canonical(i)
            self._align_with_course(i)

    def _seen(self, i: int, m: Measurement) -> tuple[bool, bool]:
        """Whether track ``i``'s (length, width) extents are fully in view from ``m``'s sensor position."""
        x = self.filters[i].x
        assert m.sensor is not None
        return faces_seen(
            x[[PN, PE]], float(x[PSI]), float(x[LEN]), float(x[WID]), m.sensor, self.config.face_min_angle
        )

    def _view_aware_plan(
        self, i: int, m: Measurement, seen: tuple[bool, bool]
    ) -> tuple[np.ndarray, np.ndarray, np.ndarray, int] | None:
        """Eq. 7's update, with the centre measured from the visible edge where the far one may be missing.

        In the track's frame (u along its heading, v across), per axis, with d = measured extent - track size:

        * d > partial_tolerance: the hull is at least that long; the size's variance grows by d^2 (the
          centre's along the axis by (d / 2)^2, tied to the size so that the near edge stays put) and the extent
          is measured, seen or not: the size and centre move most of the way at once, not the velocity.
        * no face across the axis in view (:func:`faces_seen`), or d < -partial_tolerance, with the sensor beyond
          one end of the axis: the far edge may be missing (out of view, or too sparse to show), so the axis
          measures the coordinate of its near edge, h = p.e + side * size / 2, not the centre.
        * otherwise the size itself is measured only when seen, so a one-sided view never shrinks it.
        * a shadow over an end (``m.shadowed``), on the axis that runs more across the line of sight: that end is
          not the hull's; the axis measures the other end's coordinate (both shadowed: no coordinate along it), and
          its size only if it came out longer. A ship behind a passing boat keeps its length and its place instead
          of shrinking to, and sliding with, its lit piece.

        The heading and height update as usual; directions are the predicted heading's. ``m`` is the measurement's
        alias chosen with ``seen`` (:meth:`choose_aliases`). Returns the rows (z, H, R, heading row) to apply, or
        None where it is eq. 7's plain update.
        """
        cfg = self.config
        ekf = self.filters[i]
        x = ekf.x
        assert m.sensor is not None
        c, s = math.cos(float(x[PSI])), math.sin(float(x[PSI]))
        axes = np.array([[c, s], [-s, c]])  # rows: e_u, e_v in (north, east)
        rel = axes @ (m.sensor - m.center)
        sizes = (m.length, m.width)
        edge = [False, False]
        measured = list(seen)
        for a in (0, 1):
            d = sizes[a] - float(x[LEN + a])
            if d > cfg.partial_tolerance:  # at least this long: open the size up to it, and measure it
                # With the near edge where it was: the centre is as uncertain as half the size, against it.
                near = 1.0 if rel[a] > 0.0 else -1.0
                j = LEN + a
                ekf.P[j, j] += d * d
                ekf.P[PN : PE + 1, PN : PE + 1] += 0.25 * d * d * np.outer(axes[a], axes[a])
                ekf.P[PN : PE + 1, j] -= 0.5 * near * d * d * axes[a]
                ekf.P[j, PN : PE + 1] -= 0.5 * near * d * d * axes[a]
                measured[a] = True
            # Only a sensor clearly beyond one end of the axis (that end's face in view at less than ~80 deg
            # incidence) knows which edge is the near one; from abeam, a short extent may have lost either end
            # (a shadow, a sparse far part), so the centre stays the measurement.
            beyond = abs(float(rel[a])) - 0.5 * sizes[a] > 0.2 * abs(float(rel[1 - a]))
            edge[a] = beyond and (not seen[a] or d < -cfg.partial_tolerance)
        side = [(1.0 if rel[a] > 0.0 else -1.0) if edge[a] else 0.0 for a in (0, 1)]  # 0: the centre
        located = [True, True]
        if m.shadowed[0] or m.shadowed[1]:
            los = m.center - m.sensor
            across = axes @ np.array([-los[1], los[0]])  # > 0: the axis runs toward higher bearings
            cut = int(np.argmax(np.abs(across)))
            plus_cut, minus_cut = m.shadowed[::-1] if across[cut] > 0.0 else m.shadowed
            measured[cut] = sizes[cut] - float(x[LEN + cut]) > cfg.partial_tolerance
            located[cut] = not (plus_cut and minus_cut)
            side[cut] = -1.0 if plus_cut else (1.0 if minus_cut else 0.0)
        if measured[0] and measured[1] and side == [0.0, 0.0] and located[0] and located[1]:
            return None
        return self._partial_rows(m, axes, side, measured, located)

    @staticmethod
    def _partial_rows(
        m: Measurement, axes: np.ndarray, side: list[float], measured: list[bool], located: list[bool]
    ) -> tuple[np.ndarray, np.ndarray, np.ndarray, int]:
        """(z, H, R, heading row) of the view-aware update: along each ``located`` track axis its centre, or with
        ``side`` +-1 the coordinate of that edge; then the heading, the ``measured`` sizes and the height; built at
        their final size (no 6-row table cut down)."""
        along = [a for a in (0, 1) if located[a]]
        others = [(PSI, m.heading, Z_PSI)]
        others += [(LEN + a, (m.length, m.width)[a], Z_LEN + a) for a in (0, 1) if measured[a]]
        others.append((HGT, m.height, Z_HGT))
        k = len(along)
        n = k + len(others)
        rows = np.zeros((n, DIM_X))
        z = np.empty(n)
        r = np.zeros((n, n))
        picked = axes[along]
        r[:k, :k] = picked @ m.r[:2, :2] @ picked.T
        rows[:k, PN : PE + 1] = picked
        sizes = (m.length, m.width)
        for row, a in enumerate(along):
            z[row] = float(axes[a] @ m.center)
            if side[a]:
                rows[row, LEN + a] = 0.5 * side[a]
                z[row] += 0.5 * side[a] * sizes[a]
        for j, (state, value, comp) in enumerate(others, start=k):
            rows[j, state] = 1.0
            z[j] = value
            r[j, j] = m.r[comp, comp]
        return z, _lag_rows(rows, m.lag), r, k

    def _canonical(self, i: int) -> None:
        """Keep length >= width: a track whose width has outgrown its length is the same box turned 90 deg.

        A hull first seen end-on starts with its beam as its "length"; when its long side comes into view, the
        width grows past the length, and the state is re-expressed (heading + 90 deg, sizes and their covariance
        swapped) so the heading runs along the hull again. The course alignment may then turn it once more.
        """
        ekf = self.filters[i]
        x, p = ekf.x, ekf.P
        if x[WID] <= x[LEN] + 0.1:
            return
        perm = np.arange(DIM_X)
        perm[LEN], perm[WID] = WID, LEN
        ekf.x = x[perm]
        ekf.x[PSI] = wrap_angle(float(x[PSI]) + 0.5 * math.pi)
        ekf.P = p[np.ix_(perm, perm)]
        self.aligned[i] = False

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
