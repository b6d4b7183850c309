"""Does a track hold more returns than the clutter around it explains? A Poisson test against measured clutter.

Sea clutter comes back at fresh places every frame, but where it is dense (near the boat, on a rough sea) a few of
its returns fall together now and then, and an M-of-N rule confirms them: a track on open water. A hull's returns
come back at the same place frame after frame. So each track counts the returns inside its predicted box (grown
by a pad) every frame, and the clutter density at its range says how many of those clutter alone would put there.
Over the track's recent frames, N returns against M expected from clutter: the chance that clutter gives N or more
is the Poisson tail P(X >= N | M) (the regularised lower incomplete gamma function). A track is confirmed only while
that chance is small; a confirmed one whose recent returns clutter explains as well is no longer believed.

The clutter density is measured, not assumed: returns per square metre in range rings (geometric: clutter thins
with range) and azimuth sectors around the sensor, decayed over a few seconds. The median over a ring's sectors
is the ring's density, so a boat or a quay filling one sector does not raise it for the whole ring. This is the
existence half of an IPDA filter (Musicki et al. 1994) with its clutter density estimated from the data.
"""

from __future__ import annotations

import math
from collections import deque
from dataclasses import dataclass, field

import numpy as np
from scipy.special import gammainc

# Rings grow by this ratio outward: the clutter density of a rough sea falls about as range^-2 (grazing angle),
# so equal ratios keep its change across any ring under 1.6x.
RING_RATIO = 1.25
N_SECTORS = 8  # azimuth sectors across the field of view: a quay or a large ship fills one or two of them
# Each (ring, sector) cell starts with half a return over one frame of its own area: until the sea has been measured
# for a few frames, a bunch of returns is not taken for a hull (when unsure, silence); the prior fades as frames come.
PRIOR_COUNT = 0.5


def clutter_tail(n: np.ndarray | float, mu: np.ndarray | float) -> np.ndarray:
    """P(X >= n) for X ~ Poisson(mu): the chance clutter alone gives at least ``n`` returns where ``mu`` expected.
    1 for n <= 0."""
    n_a = np.asarray(n, float)
    mu_a = np.maximum(np.asarray(mu, float), 1e-300)
    return np.where(n_a > 0, gammainc(np.maximum(n_a, 1.0), mu_a), 1.0)


class ClutterDensity:
    """Returns per square metre around one sensor, by range ring and azimuth sector, decayed with ``time_constant_s``.

    ``update`` takes a frame's candidate returns (those no shore or ghost test removed) by range and azimuth from
    the sensor's boresight; ``at`` gives the density at given ranges (the median over the ring's sectors).
    """

    def __init__(self, min_range_m: float, max_range_m: float, fov_rad: float, time_constant_s: float) -> None:
        if not (0 < min_range_m < max_range_m and fov_rad > 0 and time_constant_s > 0):
            raise ValueError("ClutterDensity: need 0 < min_range_m < max_range_m, fov_rad > 0, time_constant_s > 0")
        n_rings = max(1, math.ceil(math.log(max_range_m / min_range_m) / math.log(RING_RATIO)))
        edges = min_range_m * RING_RATIO ** np.arange(n_rings + 1)
        # The last ring ends at max_range_m: reaching past it, it counted area no return can come from and read the
        # clutter there as down to half its density, so clutter at the edge of the radar's range confirmed as tracks.
        # A last ring thinner than sqrt(RING_RATIO) joins the one before it.
        edges[-1] = max_range_m
        if n_rings > 1 and edges[-1] / edges[-2] < math.sqrt(RING_RATIO):
            edges = np.delete(edges, -2)
        self.edges = edges
        self.half_fov = min(fov_rad, 2 * math.pi) / 2
        sector = 2 * self.half_fov / N_SECTORS
        self.cell_area = sector / 2 * np.diff(self.edges**2)  # (rings,) m^2 of one sector of each ring
        self.time_constant_s = time_constant_s
        self.counts = np.full((n_rings, N_SECTORS), PRIOR_COUNT)
        self.exposure = np.ones((n_rings, N_SECTORS))  # frames seen, decayed; times cell_area is m^2 x frames
        self.t: float | None = None
        self._density = self._median_density()

    def update(self, t: float, range_m: np.ndarray, azimuth_rad: np.ndarray) -> None:
        """One frame's candidate returns: ``range_m`` (n,) from the sensor, ``azimuth_rad`` (n,) from its boresight."""
        decay = 1.0 if self.t is None else math.exp(-max(t - self.t, 0.0) / self.time_constant_s)
        self.t = t
        self.counts *= decay
        self.exposure *= decay
        self.exposure += 1.0
        ring = np.searchsorted(self.edges, range_m, side="right") - 1
        sector = np.floor((azimuth_rad + self.half_fov) / (2 * self.half_fov) * N_SECTORS).astype(np.int64)
        ok = (ring >= 0) & (ring < self.counts.shape[0]) & (sector >= 0) & (sector < N_SECTORS)
        np.add.at(self.counts, (ring[ok], sector[ok]), 1.0)
        self._density = self._median_density()

    def _median_density(self) -> np.ndarray:
        """(rings,) returns per m^2 per frame: the median over each ring's sectors."""
        return np.median(self.counts / self.exposure, axis=1) / self.cell_area

    def at(self, range_m: np.ndarray) -> np.ndarray:
        """(n,) density at these ranges (the nearest ring's inside, the edge rings' outside)."""
        ring = np.clip(np.searchsorted(self.edges, range_m, side="right") - 1, 0, self.counts.shape[0] - 1)
        return self._density[ring]


@dataclass
class ExistenceEvidence:
    """One track's recent returns against the clutter expected in its window: (n, mu) per frame, birth excluded
    (the frame that made the track was chosen for holding a bunch of returns)."""

    window_frames: int
    frames: deque[tuple[float, float]] = field(default_factory=deque)

    def add(self, n: float, mu: float) -> None:
        self.frames.append((n, mu))
        while len(self.frames) > self.window_frames:
            self.frames.popleft()

    def tail(self) -> float:
        """P(clutter alone gives at least the returns seen) over the window; 1 before any frame."""
        if not self.frames:
            return 1.0
        n = sum(f[0] for f in self.frames)
        mu = sum(f[1] for f in self.frames)
        return float(clutter_tail(n, mu))

    @property
    def full(self) -> bool:
        return len(self.frames) >= self.window_frames


def boxes_members(points: np.ndarray, boxes: np.ndarray, pad: float) -> np.ndarray:
    """(boxes, n) bool: which of ``points`` (n, 2) lie in each axis-aligned box [min0, min1, max0, max1] grown by
    ``pad``."""
    if len(boxes) == 0 or len(points) == 0:
        return np.zeros((len(boxes), len(points)), bool)
    lo = boxes[:, None, :2] - pad
    hi = boxes[:, None, 2:] + pad
    return np.all((points[None] >= lo) & (points[None] <= hi), axis=2)


def boxes_area(boxes: np.ndarray, pad: float) -> np.ndarray:
    """(boxes,) m^2 of each box grown by ``pad``."""
    return np.prod(boxes[:, 2:] - boxes[:, :2] + 2 * pad, axis=1)
