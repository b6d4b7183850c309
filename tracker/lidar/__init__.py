"""LiDAR multi-object tracker after paper 000 (adaptive shape fitting + adaptive EKF bank).

Pipeline, one module per role: :mod:`preprocess` (body points -> world, range/height/own-boat/spray filters),
:mod:`clustering` (range-adaptive Euclidean clustering), :mod:`shape_fit` (L-shape, ellipse, shape decision),
:mod:`association` (Bhattacharyya distance + gated assignment), :mod:`ekf` (adaptive EKF bank),
:mod:`tracker` (the cycle: predict, detect, associate, update, lifecycle).
"""

from __future__ import annotations

from tracker.lidar.config import LidarTrackerConfig
from tracker.lidar.tracker import LidarTracker

__all__ = ["LidarTracker", "LidarTrackerConfig"]
