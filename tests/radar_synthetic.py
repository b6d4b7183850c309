"""Synthetic radar returns with exact Doppler, for tests and benchmarks of the radar tracker.

Geometry is built in the world frame (north, east) and handed out the way the driver would: body FRD points and raw
Doppler (positive = receding, relative to the moving radar).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np


@dataclass
class OwnBoat:
    position: np.ndarray  # (2,) world N/E
    yaw: float = 0.0
    velocity: np.ndarray = field(default_factory=lambda: np.zeros(2))  # world N/E
    yaw_rate: float = 0.0
    sensor_body: np.ndarray = field(default_factory=lambda: np.zeros(2))  # radar origin, body FRD x/y

    def rotation(self) -> np.ndarray:
        c, s = np.cos(self.yaw), np.sin(self.yaw)
        return np.array([[c, -s], [s, c]])

    def sensor_world(self) -> np.ndarray:
        return self.position + self.rotation() @ self.sensor_body

    def sensor_velocity(self) -> np.ndarray:
        lever = self.yaw_rate * np.array([-self.sensor_body[1], self.sensor_body[0]])
        return self.velocity + self.rotation() @ lever


def box_points(centre: np.ndarray, size: tuple[float, float], n: int, rng: np.random.Generator) -> np.ndarray:
    """(n, 2) points spread uniformly over a world-axis-aligned box (length along north, width along east)."""
    half = np.asarray(size, float) / 2
    return np.asarray(centre, float) + rng.uniform(-half, half, size=(n, 2))


def segment_points(a: np.ndarray, b: np.ndarray, n: int, jitter: float, rng: np.random.Generator) -> np.ndarray:
    s = rng.uniform(0.0, 1.0, size=(n, 1))
    return np.asarray(a, float) + s * (np.asarray(b, float) - np.asarray(a, float)) + rng.normal(0, jitter, (n, 2))


def observe(
    own: OwnBoat,
    points_ne: np.ndarray,
    velocity_ne: np.ndarray,
    rng: np.random.Generator | None = None,
    doppler_noise: float = 0.0,
    z: float = 0.0,
) -> tuple[np.ndarray, np.ndarray]:
    """Body FRD (n, 3) positions and raw Doppler (n,) of world points moving with ``velocity_ne`` ((2,) or (n, 2))."""
    p = np.asarray(points_ne, float).reshape(-1, 2)
    rel = p - own.sensor_world()
    u = rel / np.linalg.norm(rel, axis=1, keepdims=True)
    v = np.broadcast_to(np.asarray(velocity_ne, float), p.shape)
    dop = np.einsum("ij,ij->i", v - own.sensor_velocity(), u)
    if rng is not None and doppler_noise > 0:
        dop = dop + rng.normal(0.0, doppler_noise, dop.shape)
    body = (p - own.position) @ own.rotation()  # R^T (p - pos), row-wise
    return np.column_stack([body, np.full(len(p), z)]), dop


def sea_clutter(
    rng: np.random.Generator, per_frame: float, half_fov: float = np.radians(60.0), r0: float = 1.0, r1: float = 50.0
) -> np.ndarray:
    """(n, 2) sea-clutter returns of one frame around a radar at the origin looking north, at fresh places: a Poisson
    count of mean ``per_frame`` with areal density proportional to range^-2 (uniform in log range), uniform in bearing
    within ``half_fov``."""
    n = rng.poisson(per_frame)
    r = np.exp(rng.uniform(np.log(r0), np.log(r1), n))
    b = rng.uniform(-half_fov, half_fov, n)
    return np.column_stack([r * np.cos(b), r * np.sin(b)])


def sea_clutter_density(
    per_frame: float, range_m: float, half_fov: float = np.radians(60.0), r0: float = 1.0, r1: float = 50.0
) -> float:
    """Returns per m^2 per frame of ``sea_clutter`` at ``range_m``."""
    return per_frame / (2 * half_fov * np.log(r1 / r0)) / range_m**2
