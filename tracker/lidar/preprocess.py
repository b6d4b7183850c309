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


_EXACT_BELOW = 10  # cube counts under 10x the minimum get an exact ball count (dense surfaces never need one)
_OFFSETS = np.array([(i, j, k) for i in (-1, 0, 1) for j in (-1, 0, 1) for k in (-1, 0, 1)], dtype=np.int64)


def neighbour_counts(points: np.ndarray, queries: np.ndarray, radius: float) -> np.ndarray:
    """For each query point (itself among ``points``), how many OTHER points lie in the 3 x 3 x 3 block of cubes of
    side ``radius`` around its cube: a box of about 1.5 x radius either way, counted with sorts, not a tree walk.

    A k-d tree ball query costs per neighbour: a wall 5 m away gives every return hundreds of neighbours within
    0.5 m and 29k queries took 150 ms. Counting cube occupancy costs per cube, whatever the density.
    """
    if points.shape[0] == 0 or queries.shape[0] == 0:
        return np.zeros(queries.shape[0], dtype=np.int64)
    origin = points.min(axis=0) - 2 * radius
    cells = np.floor((points - origin) / radius).astype(np.int64)
    span = cells.max(axis=0) + 3
    keys = (cells[:, 0] * span[1] + cells[:, 1]) * span[2] + cells[:, 2]
    uniq, count = np.unique(keys, return_counts=True)
    # Work per occupied query cube, not per query point: dense surfaces put dozens of returns in one cube.
    qc = np.floor((queries - origin) / radius).astype(np.int64)
    q_keys, q_inverse = np.unique((qc[:, 0] * span[1] + qc[:, 1]) * span[2] + qc[:, 2], return_inverse=True)
    q = np.stack([q_keys // (span[1] * span[2]), (q_keys // span[2]) % span[1], q_keys % span[2]], axis=1)
    cube_total = np.zeros(q.shape[0], dtype=np.int64)
    for di, dj, dk in _OFFSETS:
        nk = ((q[:, 0] + di) * span[1] + (q[:, 1] + dj)) * span[2] + (q[:, 2] + dk)
        pos = np.minimum(np.searchsorted(uniq, nk), uniq.size - 1)
        cube_total += np.where(uniq[pos] == nk, count[pos], 0)
    total = cube_total[q_inverse.ravel()]
    return total - 1


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
        reach = in_height & (
            (height < cfg.spray_max_height + cfg.spray_radius)
            | (r2[idx] < (cfg.spray_near_range + cfg.spray_radius) ** 2)
        )
        # The cube block (about 1.5 x spray_radius either way) holds the ball of spray_radius, so its count is an
        # upper bound. Far out that generosity is right: rings are 2 deg apart, so a hull's low edge has few
        # neighbours within 0.5 m at 40 m. Near the boat, where hulls are dense and spray comes in bursts of a few
        # returns, a count just above the minimum is checked exactly (a k-d tree ball query on those few only).
        upper = neighbour_counts(world[reach], world[low], cfg.spray_radius)
        verdict = upper < cfg.spray_min_neighbours
        unsure = ~verdict & (upper < _EXACT_BELOW * max(cfg.spray_min_neighbours, 1)) & near[low]
        if np.any(unsure):
            tree = cKDTree(world[reach])
            low_pts = world[low][unsure]
            exact = tree.query_ball_point(low_pts, r=cfg.spray_radius, return_length=True) - 1
            verdict[unsure] = exact < cfg.spray_min_neighbours
        spray[np.flatnonzero(low)] = verdict
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
