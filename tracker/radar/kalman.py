"""The radar track filter (paper 001, eq. 1-2 and 7): state x = [px, py, vx, vy, ax, ay, l, w].

World frame N/E; (l, w) are the box's extents along north and east (the paper's state has no heading). Motion is
constant acceleration driven by white jerk; size is a slow random walk.

Eq. 7 writes the fused measurement as z = (H + gamma [vx, vy] / d) x + v: the cluster position and size always, plus
the Doppler velocity with a weight gamma that falls off with distance d (azimuth resolution, and with it the angular
spread a cluster gives the velocity profile, worsens with range). Here that weight scales the velocity measurement's
information: R_v = C_doppler / (gamma * min(1, d_ref / d)). The Doppler covariance already carries what the cluster
cannot determine (a huge variance across the line of sight), so a radial-only velocity corrects only the radial
component of the state.

Not in the paper: motion_model "ct" appends a turn rate omega (state TURN) and predicts a coordinated turn (EKF;
tracker.coordinated_turn, shared with the LiDAR EKF). A turning hull's returns carry omega x lever arm, so the profile
fit over them reads v + M omega (M from the returns' offsets, RadarTracker._turn_gain); the velocity measurement gets
that row for omega instead of being read as v.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import NamedTuple

import numpy as np
from filterpy.kalman import KalmanFilter

from tracker.coordinated_turn import coordinated_turn
from tracker.kalman_update import joseph_update, selection_matrix
from tracker.radar.config import RadarTrackerConfig
from tracker.radar.velocity_profile import VelocityEstimate, VelocityStatus

DIM_X = 8
POS, VEL, ACC, SIZE = slice(0, 2), slice(2, 4), slice(4, 6), slice(6, 8)
TURN = 8  # the "ct" model's ninth state: turn rate (rad/s, + clockwise seen from above, i.e. north toward east)
# Where coordinated_turn's (4, 3) Jacobian block goes: rows (px, py, vx, vy), columns (vx, vy, turn rate).
_TURN_ROWS = np.array([[0], [1], [2], [3]])
_TURN_COLS = np.array([2, 3, TURN])


def dim_x(cfg: RadarTrackerConfig) -> int:
    return DIM_X + 1 if cfg.kalman.motion_model == "ct" else DIM_X


def turn_rate(kf: KalmanFilter) -> tuple[float, float]:
    """(turn rate rad/s, its variance) of a "ct" filter; (0, 0) for the other models."""
    if kf.dim_x <= TURN:
        return 0.0, 0.0
    return float(kf.x[TURN, 0]), float(kf.P[TURN, TURN])


def freeze_turn_rate(kf: KalmanFilter) -> None:
    """Set a "ct" filter's turn rate to zero with no uncertainty: it then predicts as the "cv" model."""
    kf.x[TURN, 0] = 0.0
    kf.P[TURN, :] = 0.0
    kf.P[:, TURN] = 0.0


def transition(dt: float, cfg: RadarTrackerConfig | None = None) -> np.ndarray:
    cv = cfg is not None and cfg.kalman.motion_model == "cv"
    f = np.eye(DIM_X)
    for axis in range(2):
        p, v, a = axis, 2 + axis, 4 + axis
        f[p, v] = dt
        if not cv:
            f[p, a] = 0.5 * dt * dt
            f[v, a] = dt
    return f


def ct_transition(x: np.ndarray, dt: float | np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Coordinated turn (tracker.coordinated_turn) of (n, 9) states over ``dt`` s (one, or (n,) of them): the
    predicted states and the (n, 9, 9) Jacobians of the prediction (EKF).

    The velocity turns by omega dt at constant speed and the position follows the arc; omega (state TURN) is a random
    walk. omega x r = (-omega r_e, omega r_n) in N/E, as the simulator's rigid-body velocity."""
    x = np.atleast_2d(np.asarray(x, float))
    n, dim = x.shape
    step = coordinated_turn(x[:, 2], x[:, 3], x[:, TURN], dt)
    out = x.copy()
    out[:, POS] += step.delta_position
    out[:, VEL] = step.velocity
    j = np.broadcast_to(np.eye(dim), (n, dim, dim)).copy()
    j[:, _TURN_ROWS, _TURN_COLS] = step.jacobian
    return out, j


def process_noise(dt: float, cfg: RadarTrackerConfig) -> np.ndarray:
    """Per axis: discrete white-jerk noise on (position, velocity, acceleration) for the constant-acceleration model,
    or discrete white-acceleration noise on (position, velocity) for the constant-velocity one (the acceleration
    state then stays at zero; "ct" the same, plus a random walk of the turn rate); plus a random walk of the size."""
    q = np.zeros((dim_x(cfg), dim_x(cfg)))
    if cfg.kalman.motion_model == "ct":
        q[TURN, TURN] = cfg.kalman.turn_rate_std**2 * dt
    if cfg.kalman.motion_model in ("cv", "ct"):
        block = cfg.kalman.accel_std**2 * np.array([[dt**4 / 4, dt**3 / 2], [dt**3 / 2, dt**2]])
        q[0::2, 0::2][:2, :2] = block  # rows/columns (px, vx)
        q[1::2, 1::2][:2, :2] = block  # (py, vy)
    else:
        j2 = cfg.kalman.jerk_std**2
        block = j2 * np.array(
            [
                [dt**5 / 20, dt**4 / 8, dt**3 / 6],
                [dt**4 / 8, dt**3 / 3, dt**2 / 2],
                [dt**3 / 6, dt**2 / 2, dt],
            ]
        )
        q[0:6:2, 0:6:2] = block  # (px, vx, ax)
        q[1:6:2, 1:6:2] = block  # (py, vy, ay)
    q[6, 6] = q[7, 7] = cfg.kalman.size_std_rate**2 * dt
    return q


def position_std(cfg: RadarTrackerConfig, distance: float) -> float:
    return cfg.kalman.position_std_m + cfg.kalman.position_std_per_m * distance


def doppler_weight(cfg: RadarTrackerConfig, distance: float) -> float:
    """Eq. 7's gamma / d, capped at gamma within the reference distance."""
    return cfg.doppler.gamma * min(1.0, cfg.doppler.reference_distance_m / max(distance, 1e-6))


def velocity_noise(vel: VelocityEstimate, distance: float, cfg: RadarTrackerConfig) -> np.ndarray:
    """R of the Doppler velocity: the profile fit's covariance plus a model-error floor (not in the paper: a turning
    hull's returns differ by yaw rate x lever arm, and the visible side is not the hull's centre), over eq. 7's
    weight. The floor applies along the directions the cluster determines only."""
    cov = np.asarray(vel.covariance, float)
    floor = cfg.doppler.model_std_mps**2
    if vel.status is VelocityStatus.RADIAL_ONLY:
        e = vel.radial_direction
        cov = cov + floor * np.outer(e, e)
    else:
        cov = cov + floor * np.eye(2)
    return cov / doppler_weight(cfg, distance)


def uses_doppler(cfg: RadarTrackerConfig, vel: VelocityEstimate | None) -> bool:
    return (
        cfg.doppler.enabled
        and cfg.doppler.gamma > 0
        and vel is not None
        and vel.status is not VelocityStatus.UNDETERMINED
    )


def new_filter(
    centre: np.ndarray, size: np.ndarray, distance: float, vel: VelocityEstimate | None, cfg: RadarTrackerConfig
) -> KalmanFilter:
    n = dim_x(cfg)
    kf = KalmanFilter(dim_x=n, dim_z=4)
    x = np.zeros(n)
    p = np.zeros((n, n))
    if n > TURN:
        p[TURN, TURN] = cfg.kalman.init_turn_rate_std**2
    x[POS] = centre
    x[SIZE] = size
    p[POS, POS] = np.eye(2) * position_std(cfg, distance) ** 2
    p[ACC, ACC] = np.eye(2) * (cfg.kalman.init_accel_std_mps2**2 if cfg.kalman.motion_model == "ca" else 0.0)
    p[SIZE, SIZE] = np.eye(2) * cfg.kalman.size_std_m**2
    prior_info = np.eye(2) / cfg.kalman.init_velocity_std_mps**2
    if uses_doppler(cfg, vel):
        # Prior "some boat speed" combined with the Doppler velocity: a radial-only measurement fixes the radial part.
        assert vel is not None
        r_inv = np.linalg.inv(velocity_noise(vel, distance, cfg))
        p_v = np.linalg.inv(prior_info + r_inv)
        x[VEL] = p_v @ r_inv @ vel.velocity
        p[VEL, VEL] = (p_v + p_v.T) / 2
    else:
        p[VEL, VEL] = np.linalg.inv(prior_info)
    kf.x = x.reshape(-1, 1)
    kf.P = p
    return kf


def predict(kf: KalmanFilter, dt: float, cfg: RadarTrackerConfig) -> None:
    """:func:`predict_many` for one filter."""
    predict_many([kf], [dt], cfg)


def predict_many(filters: Sequence[KalmanFilter], dts: Sequence[float], cfg: RadarTrackerConfig) -> None:
    """Predict each filter its own ``dt`` s ahead (none for dt <= 0), all in one stack: per filter, the dozens of
    small numpy calls would cost more than their arithmetic."""
    moving = [(kf, dt) for kf, dt in zip(filters, dts, strict=True) if dt > 0]
    if not moving:
        return
    x = np.array([kf.x[:, 0] for kf, _ in moving])
    p = np.array([kf.P for kf, _ in moving])
    dt = np.array([d for _, d in moving], float)
    # The tracks of a frame are all predicted to its time, so there is mostly one dt: one Q (and F) per distinct dt.
    q_of = {d: process_noise(d, cfg) for d in set(dt.tolist())}
    q = np.array([q_of[d] for d in dt.tolist()])
    if cfg.kalman.motion_model == "ct":
        x, j = ct_transition(x, dt)
        p = j @ p @ j.transpose(0, 2, 1) + q
        x[:, TURN] = np.minimum(np.maximum(x[:, TURN], -cfg.kalman.max_turn_rate), cfg.kalman.max_turn_rate)
        p = (p + p.transpose(0, 2, 1)) / 2
    else:
        # filterpy's KalmanFilter.predict, without its per-call copies of the prior (nothing here reads them).
        f_of = {d: transition(d, cfg) for d in q_of}
        f = np.array([f_of[d] for d in dt.tolist()])
        x = (f @ x[:, :, None])[:, :, 0]
        p = f @ p @ f.transpose(0, 2, 1) + q
    x[:, SIZE] = np.maximum(x[:, SIZE], cfg.clustering.min_box_size_m)
    for n, (kf, d) in enumerate(moving):
        kf.x = x[n].reshape(-1, 1)
        kf.P = p[n]
        kf.last_dt = d  # for the manoeuvre rule in fused_update


def doppler_consistent(
    kf: KalmanFilter,
    vel: VelocityEstimate,
    distance: float,
    cfg: RadarTrackerConfig,
    turn_gain: np.ndarray | None = None,
) -> bool:
    """Chi-square gate on the velocity innovation alone.

    A Doppler velocity that contradicts a well-established track (two boats merged in one cluster, a multipath
    echo) would otherwise be explained through the component the track knows least: a radial error of 1 m/s on a
    line of sight 4 deg off north becomes ~14 m/s east. Such a measurement is left out; position still updates.
    """
    return _velocity_gate(kf, vel, velocity_rows(kf, turn_gain), velocity_noise(vel, distance, cfg), cfg)


def _velocity_gate(
    kf: KalmanFilter, vel: VelocityEstimate, h_v: np.ndarray, r_v: np.ndarray, cfg: RadarTrackerConfig
) -> bool:
    """``doppler_consistent`` with the velocity rows ``h_v`` and noise ``r_v`` the update goes on to use."""
    y = vel.velocity - h_v @ kf.x[:, 0]
    d2 = mahalanobis2(y, h_v @ kf.P @ h_v.T + r_v)
    return math.isfinite(d2) and d2 <= cfg.doppler.gate_chi2


def mahalanobis2(y: np.ndarray, s: np.ndarray) -> float:
    """y^T S^-1 y for a 2-vector and a 2 x 2 covariance, in closed form (np.linalg.solve's call overhead is most of
    its cost at this size); inf when det S <= 0 (S singular or indefinite; a covariance here never is)."""
    a, b, c, d = float(s[0, 0]), float(s[0, 1]), float(s[1, 0]), float(s[1, 1])
    det = a * d - b * c
    if not det > 0.0:
        return math.inf
    y0, y1 = float(y[0]), float(y[1])
    return (d * y0 * y0 - (b + c) * y0 * y1 + a * y1 * y1) / det


def mahalanobis2_many(y: np.ndarray, s: np.ndarray) -> np.ndarray:
    """``mahalanobis2`` for many at once: y (..., 2) under covariances s (..., 2, 2); inf where det S <= 0."""
    det = s[..., 0, 0] * s[..., 1, 1] - s[..., 0, 1] * s[..., 1, 0]
    num = s[..., 1, 1] * y[..., 0] ** 2 - 2 * s[..., 0, 1] * y[..., 0] * y[..., 1] + s[..., 0, 0] * y[..., 1] ** 2
    return num / np.where(det > 0, det, np.inf)


def velocity_rows(kf: KalmanFilter, turn_gain: np.ndarray | None = None) -> np.ndarray:
    """(2, n) rows of the Doppler velocity measurement: the velocity, plus turn_gain x the turn rate (see
    RadarTracker._turn_gain) when the filter has a turn-rate state."""
    h = np.zeros((2, kf.dim_x))
    h[0, 2] = h[1, 3] = 1.0
    if turn_gain is not None and kf.dim_x > TURN:
        h[:, TURN] = turn_gain
    return h


class Measurement(NamedTuple):
    """What one track's cluster gives eq. 7 (see fused_update)."""

    centre: np.ndarray  # (2,) world N/E, m
    size: np.ndarray  # (2,) north and east extents, m
    distance: float  # m, radar to the centre
    vel: VelocityEstimate | None  # the cluster's Doppler velocity profile fit
    turn_gain: np.ndarray | None = None  # (2,) RadarTracker._turn_gain
    position_var_extra: float = 0.0  # m^2 added to the centre's variance (a partly hidden hull)


def fused_update(
    kf: KalmanFilter,
    centre: np.ndarray,
    size: np.ndarray,
    distance: float,
    vel: VelocityEstimate | None,
    cfg: RadarTrackerConfig,
    turn_gain: np.ndarray | None = None,
    position_var_extra: float = 0.0,
) -> None:
    """Eq. 7 for one filter: :func:`fused_update_many` of one."""
    fused_update_many([kf], [Measurement(centre, size, distance, vel, turn_gain, position_var_extra)], cfg)


def fused_update_many(
    filters: Sequence[KalmanFilter], measured: Sequence[Measurement], cfg: RadarTrackerConfig
) -> None:
    """Eq. 7 for each filter with its measurement: position and size, plus the distance-weighted Doppler velocity
    when the cluster determines one and it agrees with the track (see doppler_consistent). The Joseph updates of
    filters with measurements of one size run in one stack (tracker.kalman_update: a filter's result does not depend
    on how many share the stack): per filter, the update's dozens of small numpy calls cost more than its
    arithmetic."""
    plans = [_measurement_rows(kf, m, cfg) for kf, m in zip(filters, measured, strict=True)]
    for size in sorted({h.shape[0] for h, _, _ in plans}):
        group = [k for k, (h, _, _) in enumerate(plans) if h.shape[0] == size]
        x = np.array([filters[k].x[:, 0] for k in group])
        h = np.array([plans[k][0] for k in group])
        y = np.array([plans[k][1] - plans[k][0] @ filters[k].x[:, 0] for k in group])
        x1, p1, _, _ = joseph_update(
            x, np.array([filters[k].P for k in group]), h, y, np.array([plans[k][2] for k in group])
        )
        x1[:, SIZE] = np.maximum(x1[:, SIZE], cfg.clustering.min_box_size_m)
        if x1.shape[1] > TURN:
            x1[:, TURN] = np.minimum(np.maximum(x1[:, TURN], -cfg.kalman.max_turn_rate), cfg.kalman.max_turn_rate)
        for n, k in enumerate(group):
            filters[k].x, filters[k].P = x1[n].reshape(-1, 1), p1[n]


def _measurement_rows(
    kf: KalmanFilter, m: Measurement, cfg: RadarTrackerConfig
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(H, z, R) of eq. 7 for this filter and measurement; opens up the filter's covariance first on a manoeuvre."""
    sp = position_std(cfg, m.distance) ** 2 + m.position_var_extra
    maneuver = False
    if cfg.doppler.maneuver_nis > 0:
        # Manoeuvre: the centre is further from the prediction than the filter's own uncertainty allows (a boat
        # turning 1 rad/s leaves a constant-velocity prediction within a second). The velocity is opened up so this
        # update can turn it, instead of the track sliding off and a new one starting on the boat. Not in the paper.
        y = np.asarray(m.centre, float) - kf.x[POS, 0]
        s = kf.P[POS, POS] + sp * np.eye(2)
        maneuver = mahalanobis2(y, s) > cfg.doppler.maneuver_nis
        if maneuver:
            # As if the velocity had taken a random step of doppler.maneuver_velocity_std_mps at the start of the last
            # prediction: position and velocity variance and their coupling grow, so this very update can turn it.
            dt = float(getattr(kf, "last_dt", 0.1))
            g = np.zeros((kf.dim_x, 2))
            g[POS, :] = dt * np.eye(2)
            g[VEL, :] = np.eye(2)
            kf.P = kf.P + cfg.doppler.maneuver_velocity_std_mps**2 * (g @ g.T)
    # A turning hull's returns carry yaw rate x lever arm (1 m/s and more on a sharp turn, all one way when only one
    # side is seen): during a manoeuvre the Doppler velocity is left out and the positions turn the track.
    vel = m.vel
    with_v = uses_doppler(cfg, vel) and not (maneuver and cfg.doppler.maneuver_skip_doppler)
    if with_v:
        assert vel is not None
        h_v, r_v = velocity_rows(kf, m.turn_gain), velocity_noise(vel, m.distance, cfg)
        with_v = _velocity_gate(kf, vel, h_v, r_v, cfg)  # doppler_consistent
    rows = _Z_POS_SIZE_VEL if with_v else _Z_POS_SIZE
    n = rows.size
    z = np.empty(n)
    z[:2], z[2:4] = m.centre, m.size
    r = np.zeros((n, n))
    r[0, 0] = r[1, 1] = sp
    r[2, 2] = r[3, 3] = cfg.kalman.size_std_m**2
    if with_v:
        assert vel is not None
        z[4:] = vel.velocity
        r[4:, 4:] = r_v
    h = selection_matrix(rows, kf.dim_x)
    if with_v and m.turn_gain is not None and kf.dim_x > TURN:
        h[4:] = h_v  # the velocity rows also read the turn rate (velocity_rows)
    return h, z, r


# Measured states: centre (px, py), size (l, w), and with a Doppler velocity (vx, vy). H only picks states.
_Z_POS_SIZE = np.array([0, 1, 6, 7])
_Z_POS_SIZE_VEL = np.array([0, 1, 6, 7, 2, 3])


def box_of(kf: KalmanFilter) -> np.ndarray:
    """(4,) north_min, east_min, north_max, east_max of the filter's box."""
    x = kf.x[:, 0]
    half = x[SIZE] / 2
    return np.concatenate([x[POS] - half, x[POS] + half])
