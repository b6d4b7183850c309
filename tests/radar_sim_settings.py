"""Settings that make the simulated AWR1843 exact (no noise, fading, clutter, ghosts or missed detections), for tests
that check its geometry against hand-computed values."""

from __future__ import annotations

from typing import Any

EXACT: dict[str, Any] = {
    "range_noise_m": 0.0,
    "azimuth_noise_deg": 0.0,
    "elevation_noise_deg": 0.0,
    "doppler_noise": 0.0,
    "fluctuation": False,
    "clutter_calm": 0.0,
    "clutter_sea_state_3": 0.0,
    "ghost_probability": 0.0,
    "detect_probability": 1.0,
}
