"""The coordinated-turn motion model, shared by the LiDAR EKF (tracker.lidar.ekf) and the radar filter
(tracker.radar.kalman): a body moving at constant speed whose velocity (v_n, v_e) turns at the constant rate w
(rad/s, clockwise seen from above: north toward east), d/dt (v_n, v_e) = w (-v_e, v_n).

Over dt, with theta = w dt, the velocity turns by theta and the position follows the arc:

    v' = R(theta) v,   p' = p + [[a, -b], [b, a]] v,   a = sin(theta) / w,   b = (1 - cos(theta)) / w

:func:`coordinated_turn` gives the update and its partial derivatives in (v_n, v_e, w) for any number of bodies at
once; each tracker lays them into its own state vector and Jacobian.

Near w = 0 the closed forms divide a vanishing numerator by w (or w^2), so below |theta| < ``SERIES_BELOW`` each
gain is its Taylor series in theta instead, to the theta^4 term. Threshold and order are chosen so that both sides
are good to float64 rounding where they meet (tests/test_coordinated_turn.py checks it against a 60-digit
reference): the series' first omitted term is at most theta^6 / 2880 < 6e-18 relative there, a twentieth of a
rounding step (1.1e-16); the closed forms write 1 - cos(theta) as 2 sin^2(theta / 2), which cancels nothing. One
closed form still cancels, d a / d w = (theta cos - sin) / w^2, whose numerator (~ -theta^3 / 3) is the difference
of two terms ~ theta: its error is ~ 1e-16 dt^2 / |theta|, about 2e-14 dt^2 just above the threshold, against the
~ speed x dt^2 / 2 (d b / d w) of the Jacobian entry it enters. A higher threshold would shrink that error but
bring the series' own up to rounding (theta^6 / 2880 is 3.5e-16 at 1e-2).
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np
from numpy.typing import ArrayLike

SERIES_BELOW = 5e-3  # |w dt| below which the gains are their Taylor series


class TurnStep(NamedTuple):
    """The coordinated turn over dt for n bodies (all arrays have the broadcast shape of the inputs first)."""

    delta_position: np.ndarray  # (..., 2): north, east displacement
    velocity: np.ndarray  # (..., 2): north, east velocity after dt
    # (..., 4, 3): d(p_n', p_e', v_n', v_e') / d(v_n, v_e, w); the displacement does not depend on the position.
    jacobian: np.ndarray


def coordinated_turn(vn: ArrayLike, ve: ArrayLike, w: ArrayLike, dt: ArrayLike) -> TurnStep:
    """The coordinated turn of bodies at velocity (``vn``, ``ve``) m/s turning at ``w`` rad/s, over ``dt`` s.

    Inputs broadcast against each other (arrays of n bodies, with one dt or n of them).
    """
    vn, ve, w, dt = (np.asarray(v, dtype=float) for v in (vn, ve, w, dt))
    th = w * dt
    s, c = np.sin(th), np.cos(th)
    small = np.abs(th) < SERIES_BELOW
    # w = 0 must not divide; the closed forms' values there are replaced by the series below.
    w_safe = np.where(small, 1.0, w)
    half = np.sin(0.5 * th)
    one_minus_c = 2.0 * half * half  # 1 - cos(theta) without its cancellation at small theta
    a = s / w_safe
    b = one_minus_c / w_safe
    da = (dt * c * w - s) / w_safe**2
    db = (dt * s * w - one_minus_c) / w_safe**2
    if small.any():  # the series cost as much again as the closed forms: only when some body needs them
        t2 = th * th
        a = np.where(small, dt * (1.0 - t2 / 6.0 * (1.0 - t2 / 20.0)), a)
        b = np.where(small, 0.5 * w * dt * dt * (1.0 - t2 / 12.0 * (1.0 - t2 / 30.0)), b)
        da = np.where(small, -w * dt**3 / 3.0 * (1.0 - t2 / 10.0 * (1.0 - t2 / 28.0)), da)
        db = np.where(small, 0.5 * dt * dt * (1.0 - t2 / 4.0 * (1.0 - t2 / 18.0)), db)

    shape = np.broadcast_shapes(vn.shape, ve.shape, th.shape)
    delta = np.empty((*shape, 2))
    delta[..., 0] = a * vn - b * ve
    delta[..., 1] = b * vn + a * ve
    vel = np.empty((*shape, 2))
    vel[..., 0] = c * vn - s * ve
    vel[..., 1] = s * vn + c * ve
    jac = np.empty((*shape, 4, 3))
    jac[..., 0, 0], jac[..., 0, 1], jac[..., 0, 2] = a, -b, da * vn - db * ve
    jac[..., 1, 0], jac[..., 1, 1], jac[..., 1, 2] = b, a, db * vn + da * ve
    jac[..., 2, 0], jac[..., 2, 1], jac[..., 2, 2] = c, -s, -dt * (s * vn + c * ve)
    jac[..., 3, 0], jac[..., 3, 1], jac[..., 3, 2] = s, c, dt * (c * vn - s * ve)
    return TurnStep(delta, vel, jac)
