"""The sea around the own boat: waves, heave, what the water and the rain return to a LiDAR.

The water is not a mirror. A surface roughened by chop scatters some of a LiDAR's light back, more the steeper the
beam meets it, so a boat rolling a few degrees sees the water at 6-30 m with its lower beams. Waves stand +-0.3 m
about the mean in a moderate sea, and the boat heaves with them, so the water 20 m away is not at the hull's
waterline (the own boat's heave is OwnBoat's, scene.py). Rain puts drop returns in the air close to the sensor.

Frames: world NED, heights above the mean water up positive, m; directions of travel clockwise from north, rad.
Deep-water waves: omega^2 = g k.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

G = 9.81


@dataclass(frozen=True)
class WaveTrain:
    amplitude: float  # m, crest above the mean
    wavelength: float  # m
    direction: float  # rad, direction of travel, clockwise from north
    phase: float = 0.0  # rad

    @property
    def wavenumber(self) -> float:
        return 2 * math.pi / self.wavelength

    @property
    def omega(self) -> float:
        return math.sqrt(G * self.wavenumber)


@dataclass(frozen=True)
class Sea:
    """Everything the water and the air add to the scene. The default is the calm mirror of earlier simulators."""

    waves: tuple[WaveTrain, ...] = ()
    # Probability that a LiDAR firing meeting the water at 10 deg of grazing returns from it; it rises with the
    # square of the grazing angle (capped at 1): 1 deg returns a hundredth as often, a -15 deg beam 2.25x as often.
    water_return_at_10deg: float = 0.0
    rain_rate: float = 0.0  # LiDAR drop returns per second (10 Hz sensor: a tenth of that per revolution)
    rain_max_range: float = 12.0  # m; drop returns thin out with range as r^-0.5 (denser close in)

    @property
    def crest(self) -> float:
        """Highest the surface can stand above the mean, m."""
        return float(sum(w.amplitude for w in self.waves))

    def elevation(self, north: np.ndarray, east: np.ndarray, t: np.ndarray | float) -> np.ndarray:
        """Surface height above the mean water at world (north, east) and time t, m (up positive)."""
        north = np.asarray(north, float)
        h = np.zeros(np.broadcast(north, np.asarray(east, float), np.asarray(t, float)).shape)
        for w in self.waves:
            k = w.wavenumber
            along = north * math.cos(w.direction) + np.asarray(east, float) * math.sin(w.direction)
            h = h + w.amplitude * np.sin(k * along - w.omega * np.asarray(t, float) + w.phase)
        return h

    def water_return_probability(self, grazing: np.ndarray) -> np.ndarray:
        """Chance that a firing meeting the water at ``grazing`` rad (below the horizon) returns from it."""
        g = np.clip(np.asarray(grazing, float), 0.0, None) / math.radians(10.0)
        return np.clip(self.water_return_at_10deg * g * g, 0.0, 1.0)

    def water_distance(self, origin: np.ndarray, direction: np.ndarray, t: np.ndarray) -> np.ndarray:
        """Distance along each ray (world NED origin and unit direction, (N, 3)) to the wavy surface; inf for a ray
        that does not point down. Three fixed-point steps from the mean plane: good to millimetres for the gentle
        slopes of wind waves except at the grazing angles where the water returns (almost) nothing anyway."""
        dz = direction[:, 2]
        down = dz > 1e-9
        lam = np.full(dz.shape, np.inf)
        if not down.any():
            return lam
        o, d, tt = origin[down], direction[down], np.broadcast_to(np.asarray(t, float), dz.shape)[down]
        ld = -o[:, 2] / d[:, 2]  # the mean plane (world z = 0)
        if self.waves:
            for _ in range(3):
                p = o + ld[:, None] * d
                ld = np.maximum((-self.elevation(p[:, 0], p[:, 1], tt) - o[:, 2]) / d[:, 2], 0.0)
        lam[down] = ld
        return lam

    @classmethod
    def state(cls, sea_state: int, seed: int = 0, water_return_at_10deg: float | None = None) -> Sea:
        """A sea of WMO sea state 0-3 (calm-glassy to slight: crests up to 0, 0.05, 0.15, 0.3 m) from three wave
        trains of random direction and phase."""
        crest = {0: 0.0, 1: 0.05, 2: 0.15, 3: 0.3}[int(sea_state)]
        if crest == 0.0:
            return cls()
        rng = np.random.default_rng([int(seed), 0x5EA])
        main = rng.uniform(-math.pi, math.pi)
        shares = np.array([0.5, 0.33, 0.17])
        lengths = np.array([14.0, 7.0, 3.5]) * (0.8 + 0.4 * rng.random(3))
        dirs = main + np.array([0.0, rng.uniform(-0.8, 0.8), rng.uniform(-1.5, 1.5)])
        waves = tuple(
            WaveTrain(float(crest * s), float(lam), float(d), float(rng.uniform(0, 2 * math.pi)))
            for s, lam, d in zip(shares, lengths, dirs, strict=True)
        )
        ret = {1: 0.05, 2: 0.15, 3: 0.3}[int(sea_state)] if water_return_at_10deg is None else water_return_at_10deg
        return cls(waves, water_return_at_10deg=ret)
