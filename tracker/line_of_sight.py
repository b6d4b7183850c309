"""What lies behind what, seen from the own boat: one test shared by the LiDAR's duplicate rule and the fusion.

A hull seen end-on shows the sensor its near face; whatever else of it comes back (a cabin above, the radar's
scatterers along it) lies beyond that face on the same line of sight. Frames: world NED (north, east), metres.
"""

from __future__ import annotations

import numpy as np


def in_shadow(
    host_ne: np.ndarray, half_size: np.ndarray, guest_ne: np.ndarray, own_ne: np.ndarray, depth_m: float, aside_m: float
) -> np.ndarray:
    """(H, G) bool: guest centre g lies behind host h as seen from ``own_ne``: beyond h's centre along the line of
    sight by at most ``half_size[h] + depth_m`` and off that line by at most ``half_size[h] + aside_m``.
    ``host_ne`` (H, 2), ``half_size`` (H,), ``guest_ne`` (G, 2), ``own_ne`` (2,)."""
    sight = host_ne - np.asarray(own_ne, dtype=float)[:2]  # (H, 2) own boat -> host centre
    sight = sight / np.maximum(np.hypot(sight[:, 0], sight[:, 1]), 1e-6)[:, None]
    rel = guest_ne[None, :, :] - host_ne[:, None, :]  # (H, G, 2) guest centre from host centre
    behind = rel[..., 0] * sight[:, [0]] + rel[..., 1] * sight[:, [1]]
    aside = np.abs(rel[..., 1] * sight[:, [0]] - rel[..., 0] * sight[:, [1]])
    half = np.asarray(half_size, dtype=float)[:, None]
    return (behind >= 0) & (behind <= half + depth_m) & (aside <= half + aside_m)
