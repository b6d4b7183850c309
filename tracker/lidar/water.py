"""The water surface around the boat, estimated from the LiDAR's own water returns, and the sea-state margin.

Why not the hull's waterline alone: the water 20 m away is not at the waterline. The boat heaves, waves stand
+-0.3 m around it, and an attitude off by half a degree puts the water 0.17 m high or low at 20 m. A tilted VLP-16
meets the water with its lower beams at 6-30 m and a choppy surface returns some of those firings; those returns
are the best measurement of where the water is. So each revolution:

1. candidates: returns within ``search_window`` of the current surface estimate, at ``fit_min_range``..
   ``fit_max_range`` horizontally;
2. a plane h = a + b x + c y (heights up, body x forward / y starboard) fitted by least squares, re-fitted three
   times on the returns within 3 robust sigmas of the last fit. The plane takes the heave and the waterline's
   offset (a, up to ``max_offset``) and a small attitude error (b, c, up to ``max_tilt``);
3. accepted only if it rests on water, not on a few hulls or a quay: at least ``min_returns`` inliers spread over
   ``min_sectors`` of 36 bearing sectors, carried by ``min_rings`` lasers whose median heights agree within
   ``max_ring_disagreement`` (water meets every lower beam at the surface's height; a quay face meets several
   beams at one range, each at its own height), with a robust spread below ``max_spread`` (hull sides spread
   their returns evenly over a metre; a water surface is a thin layer), and with its inliers' median range within
   ``max_median_range`` (the steep beams close in return the water most often; decks of boats farther out are a
   thin layer too);
4. the sea-state margin: the ``margin_quantile`` of the water layer's distance from the plane (the crests; the
   layer is the returns within ``crest_sigmas`` robust sigmas of it), at least ``margin_sigmas`` robust sigmas, plus
   ``margin_pad``, between ``margin_floor`` and ``margin_max``. A return counts as solid only above the surface
   plus this margin; beyond the water the fit saw, a rising plane is held at its height there
   (``WaterEstimate.floor``).

Without enough water returns (calm water returns almost nothing), the last accepted estimate holds for
``memory_s`` seconds, then the configured waterline with the floor margin applies again.

Frames: body FRD points rotated by the pose's roll and pitch into a yaw-free level frame; heights up positive, m,
relative to the configured waterline at the body origin.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from tracker.lidar.config import WaterConfig

N_SECTORS = 36
_SUBSAMPLE = 2500  # candidates used for the fit: a plane of 3 unknowns and a 0.995 quantile need no more


@dataclass(frozen=True)
class WaterEstimate:
    """h_surface(x, y) = offset + slope_x x + slope_y y (m, up); a return is solid above it plus ``margin``."""

    offset: float = 0.0
    slope_x: float = 0.0
    slope_y: float = 0.0
    margin: float = 0.15
    t: float = -math.inf  # when it was last measured (host s); -inf = the configured waterline
    n_inliers: int = 0
    spread: float = 0.0  # robust sigma of the inliers about the plane, m
    reach: float = math.inf  # horizontal range (m) within which the fit's water returns lay (their 95th percentile)

    @property
    def measured(self) -> bool:
        return math.isfinite(self.t)

    def surface(self, x: np.ndarray, y: np.ndarray) -> np.ndarray:
        return self.offset + self.slope_x * x + self.slope_y * y

    def floor(self, x: np.ndarray, y: np.ndarray) -> np.ndarray:
        """The surface a return must stand above to be solid: the plane within the fit's reach; beyond it, where
        the plane rises, its height at the reach along that bearing. The tilt is measured on water within about
        20 m, where a wave's slope or an attitude error of 0.4 deg is 0.14 m; carried on to 63 m it stands 0.44 m
        high and swallows a low hull there. Where the plane falls away it is followed: the lower floor only lets
        more returns count as solid."""
        rise = self.slope_x * x + self.slope_y * y
        r2 = x * x + y * y
        beyond = (rise > 0.0) & (r2 > self.reach * self.reach)
        if beyond.any():  # a square root only for those few, on the 10 Hz path
            rise[beyond] *= self.reach / np.sqrt(r2[beyond])
        return self.offset + rise


class WaterSurface:
    """Keeps the newest accepted estimate; ``update`` once per revolution, ``current`` for the margin in force."""

    def __init__(self, config: WaterConfig | None = None) -> None:
        self.config = config or WaterConfig()
        self.estimate = self._prior()
        self.accepted = 0
        self.refused = 0

    def _prior(self) -> WaterEstimate:
        return WaterEstimate(margin=self.config.margin_floor)

    def current(self, t: float) -> WaterEstimate:
        e = self.estimate
        if e.measured and t - e.t > self.config.memory_s:
            self.estimate = e = self._prior()
        return e

    def update(
        self,
        x: np.ndarray,
        y: np.ndarray,
        height: np.ndarray,
        t: float,
        ring: np.ndarray | None = None,
        vertical: np.ndarray | None = None,
        alone: np.ndarray | None = None,
        on_hull: Callable[[np.ndarray], np.ndarray] | None = None,
    ) -> WaterEstimate:
        """Fit the surface to this revolution's returns (level-frame x, y and height above the configured
        waterline; ``ring`` the laser of each, 0 = lowest; ``vertical`` marks returns on a vertical face, never
        water; ``alone`` those with no neighbour in the range image, which may be rain; ``on_hull`` says, for the
        indices of some of them, which lie on a hull the tracker holds) and return the estimate to classify
        them with."""
        cfg = self.config
        prev = self.current(t)
        if not cfg.enabled:
            return prev
        r2 = x * x + y * y
        cand = (r2 >= cfg.fit_min_range**2) & (r2 <= cfg.fit_max_range**2)
        cand &= np.abs(height - prev.surface(x, y)) <= cfg.search_window
        if vertical is not None:
            cand &= ~vertical
        idx = np.flatnonzero(cand)
        if idx.size < cfg.min_returns:
            return prev
        if idx.size > _SUBSAMPLE:
            idx = idx[:: idx.size // _SUBSAMPLE + 1]
        cx, cy, ch = x[idx], y[idx], height[idx]
        c_alone = alone[idx] if alone is not None else np.zeros(idx.size, dtype=bool)
        cring = ring[idx] if ring is not None else None
        sector = np.floor((np.arctan2(cy, cx) + math.pi) * (N_SECTORS / (2 * math.pi))).astype(np.int64)
        if np.count_nonzero(np.bincount(sector, minlength=N_SECTORS + 1)) < cfg.min_sectors:
            return prev
        design = np.stack([np.ones_like(cx), cx, cy], axis=1)
        inlier = np.ones(cx.size, dtype=bool)
        coef = np.zeros(3)
        sigma = 0.0
        for _ in range(4):
            if np.count_nonzero(inlier) < cfg.min_returns:
                self.refused += 1
                return prev
            a = design[inlier]
            # normal equations: 3 x 3, well conditioned (x, y within 50 m, a few thousand returns)
            coef = np.linalg.solve(a.T @ a, a.T @ ch[inlier])
            res = ch - design @ coef
            res_in = res[inlier]
            sigma = 1.4826 * _median(np.abs(res_in - _median(res_in)))
            kept = np.abs(res) <= max(3.0 * sigma, 0.05)
            settled = np.array_equal(kept, inlier)
            inlier = kept
            if settled:  # the next pass would fit the same returns to the same plane
                break
        n_in = int(np.count_nonzero(inlier))
        tilt = math.tan(cfg.max_tilt)
        in_sectors = np.count_nonzero(np.bincount(sector[inlier], minlength=N_SECTORS + 1))
        # Water meets every lower beam at its own range, each at the surface's height; a quay face or a row of hulls
        # meets several beams at one range, each at its own height. So the beams carrying the fit must agree.
        rings_ok = True
        if cring is not None:
            r_in = cring[inlier].astype(np.int64)
            per_ring = np.bincount(r_in, minlength=16)
            carrying = np.flatnonzero(per_ring >= cfg.min_ring_share * n_in)
            rings_ok = carrying.size >= cfg.min_rings
            if rings_ok:
                res_in = res[inlier]
                bias = [_median(res_in[r_in == k]) for k in carrying]
                rings_ok = max(bias) - min(bias) <= cfg.max_ring_disagreement
        near_enough = _median(np.hypot(cx[inlier], cy[inlier])) <= cfg.max_median_range if n_in else False
        if (
            n_in < cfg.min_returns
            or not rings_ok
            or not near_enough
            or in_sectors < cfg.min_sectors
            or sigma > cfg.max_spread
            or abs(coef[0]) > cfg.max_offset
            or abs(coef[1]) > tilt
            or abs(coef[2]) > tilt
        ):
            self.refused += 1
            return prev
        # The crests: the fit's 3-sigma inliers leave out the highest of them, so the quantile is taken over the
        # whole water layer (within crest_sigmas of the plane), which still leaves out decks and hull sides above.
        # Lone returns are left out of it: rain drops in the fit's window spread the layer (0.40 m of "crests" in a
        # 0.05 m sea), and a sparse sea's lone water returns still show in the fit's sigma below.
        layer = (np.abs(res) <= max(cfg.crest_sigmas * sigma, 0.05)) & ~c_alone
        if not layer.any():
            layer = np.abs(res) <= max(cfg.crest_sigmas * sigma, 0.05)
        # A low hull's side stands in the layer too (a buoy 6 m off: three lasers, 150 returns), and its returns
        # were the layer's highest: the margin rose over the buoy's top and hid it. The returns that could raise the
        # crests over the sea's spread are asked whether a tracked hull holds them: those are not the sea.
        floor = cfg.margin_sigmas * sigma
        tail = np.flatnonzero(layer & (np.abs(res) > floor))
        if on_hull is not None and tail.size:
            layer[tail[on_hull(idx[tail])]] = False
        # The returns under-sample the crests (a beam meets a crest's face, seldom its top), so the sea's own spread
        # sets a floor: a Gaussian sea's crests reach about 3 sigma (Rayleigh crests: 1 in 100 above 3 sigma).
        crest = max(_quantile(np.abs(res[layer]), cfg.margin_quantile), floor) if layer.any() else floor
        margin = min(max(crest + cfg.margin_pad, cfg.margin_floor), cfg.margin_max)
        reach = _quantile(np.hypot(cx[inlier], cy[inlier]), 0.95)
        self.estimate = WaterEstimate(float(coef[0]), float(coef[1]), float(coef[2]), margin, t, n_in, sigma, reach)
        self.accepted += 1
        return self.estimate


def _median(values: np.ndarray) -> float:
    """np.median of a 1-D array of finite values without its generic machinery (about 10 us a call, and a fit
    takes a dozen): the same order statistics, and the middle two averaged as np.mean does, (a + b) / 2 (up to the
    sign of a zero, which every use here discards)."""
    n = values.size
    if n == 0:
        return math.nan
    half = n // 2
    if n % 2:
        return float(np.partition(values, half)[half])
    part = np.partition(values, (half - 1, half))
    return float((part[half - 1] + part[half]) / 2.0)


def _quantile(values: np.ndarray, q: float) -> float:
    """np.quantile (its default, linear interpolation) of a non-empty 1-D array of finite values, ``q`` in [0, 1],
    without its generic machinery (about 0.1 ms a call on a fit's returns, twice a revolution): the same two order
    statistics, and numpy's own interpolation, which measures from the nearer of the two."""
    n = values.size
    pos = (n - 1) * q
    if pos >= n - 1:
        return float(values.max())
    lo = math.floor(pos)
    part = np.partition(values, (lo, lo + 1))
    a, b = part[lo], part[lo + 1]
    t = pos - lo
    return float(b - (b - a) * (1 - t) if t >= 0.5 else a + (b - a) * t)
