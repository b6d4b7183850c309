"""Body-frame LiDAR returns -> world-frame returns that may belong to objects on the water (paper sec. 2.1).

Order matters for cost: the cheap per-point masks (finite, range, own boat, height) run first, so the neighbour
search for spray only sees the few low returns that survive them.

Frames: input body FRD (x bow, y starboard, z down), metres, with the boat's pose in world NED per point (or one
pose for all); output world NED. Heights are "above the water surface", up positive.
"""

from __future__ import annotations

import logging
from dataclasses import dataclass

import numpy as np
from scipy.spatial import cKDTree

from tracker.ego import body_to_world
from tracker.lidar.config import PreprocessConfig

log = logging.getLogger(__name__)


@dataclass
class PreprocessResult:
    points_world: np.ndarray  # (M, 3) world NED, m: the returns kept
    keep: np.ndarray  # (N,) bool over the input points
    n_nonfinite: int = 0
    n_range: int = 0  # outside [min_range, max_range]
    n_own_boat: int = 0
    n_height: int = 0  # outside [min_height, max_height] above the water
    n_spray: int = 0  # low and isolated: water surface or spray


def preprocess(
    xyz_body: np.ndarray,
    position_ned: np.ndarray,
    roll: np.ndarray | float,
    pitch: np.ndarray | float,
    yaw: np.ndarray | float,
    config: PreprocessConfig | None = None,
) -> PreprocessResult:
    """Filter one revolution and move it to the world frame.

    ``position_ned`` is (3,) or (N, 3): the body origin in world NED at each point's time; ``roll``, ``pitch``,
    ``yaw`` are scalars or (N,) arrays (radians, body->NED, aerospace Z-Y-X).
    """
    cfg = config or PreprocessConfig()
    xyz = np.asarray(xyz_body, dtype=float).reshape(-1, 3)
    n = xyz.shape[0]
    pos = np.broadcast_to(np.asarray(position_ned, dtype=float), (n, 3)) if n else np.zeros((0, 3))
    attitude = [np.broadcast_to(np.asarray(a, dtype=float), (n,)) for a in (roll, pitch, yaw)]

    finite = np.isfinite(xyz).all(axis=1) & np.isfinite(pos).all(axis=1)
    for a in attitude:
        finite &= np.isfinite(a)
    keep = finite.copy()

    # Range is horizontal from the body origin: the sensor sits a metre or so from it, well inside the tolerance.
    r2 = xyz[:, 0] ** 2 + xyz[:, 1] ** 2
    in_range = (r2 >= cfg.min_range**2) & (r2 <= cfg.max_range**2)
    n_range = int(np.count_nonzero(keep & ~in_range))
    keep &= in_range

    x0, x1, y0, y1, z0, z1 = cfg.own_box
    own = (xyz[:, 0] >= x0) & (xyz[:, 0] <= x1) & (xyz[:, 1] >= y0) & (xyz[:, 1] <= y1)
    own &= (xyz[:, 2] >= z0) & (xyz[:, 2] <= z1)
    n_own = int(np.count_nonzero(keep & own))
    keep &= ~own

    idx = np.flatnonzero(keep)
    world = body_to_world(xyz[idx], pos[idx], *(a[idx] for a in attitude)) if idx.size else np.zeros((0, 3))
    water_down = pos[idx, 2] + cfg.origin_height_above_water
    height = water_down - world[:, 2]

    in_height = (height >= cfg.min_height) & (height <= cfg.max_height)
    n_height = int(np.count_nonzero(~in_height))

    # Spray suspects: low returns anywhere, and any return near the boat, where a real hull gives dense returns
    # (0.2 deg steps are centimetres apart at a few metres) but bow spray gives lone points in mid-air.
    near = r2[idx] < cfg.spray_near_range**2
    low = in_height & ((height < cfg.spray_max_height) | near)
    spray = np.zeros(idx.size, dtype=bool)
    if np.any(low):
        # Neighbours among the kept returns within reach of a suspect (a low return next to a hull is hull),
        # counted without itself.
        reach = (height < cfg.spray_max_height + cfg.spray_radius) | (
            r2[idx] < (cfg.spray_near_range + cfg.spray_radius) ** 2
        )
        tree = cKDTree(world[in_height & reach])
        counts = tree.query_ball_point(world[low], r=cfg.spray_radius, return_length=True) - 1
        spray[np.flatnonzero(low)] = counts < cfg.spray_min_neighbours
    n_spray = int(np.count_nonzero(spray))

    good = in_height & ~spray
    keep[idx[~good]] = False
    n_nonfinite = n - int(np.count_nonzero(finite))
    if n_nonfinite:
        log.debug("preprocess: %d non-finite returns skipped", n_nonfinite)
    return PreprocessResult(
        points_world=world[good],
        keep=keep,
        n_nonfinite=n_nonfinite,
        n_range=n_range,
        n_own_boat=n_own,
        n_height=n_height,
        n_spray=n_spray,
    )
