"""ROTracker: MMW radar multi-object tracking for a USV (paper 001, Xu et al. 2024).

Modules, in the order a frame meets them: ``detector`` (ROI, ego-motion Doppler compensation, ``multipath``,
``dbscan`` + Doppler split, ``static_map`` and ``shore_lines`` shore filter, ``velocity_profile`` eq. 3-6),
``tracker`` (``kalman`` eq. 1-2 and the fused update of eq. 7, IoU association with the sparse-hull rules, the
``visible_side`` centre, shared lifecycle) and ``motion`` (eq. 8, Table 1, with ``hull``). Every parameter is in
``config.RadarTrackerConfig``; the paper's values are the defaults, and what the paper does not have is marked "not in
the paper" there, with a switch to turn it off. bench/radar_paper.py scores the tracker on the simulator.

Radar tracks are world-axis-aligned boxes (the paper's state has no heading): ``Track.heading`` is 0, ``length`` is
the north extent and ``width`` the east extent; the course over ground is atan2(v_east, v_north).
"""

from __future__ import annotations

from tracker.radar.config import RadarTrackerConfig
from tracker.radar.detector import DetectorOutput, RadarCluster, RadarDetector
from tracker.radar.tracker import RadarTracker
from tracker.radar.velocity_profile import VelocityEstimate, VelocityStatus, fit_velocity_profile

__all__ = [
    "DetectorOutput",
    "RadarCluster",
    "RadarDetector",
    "RadarTracker",
    "RadarTrackerConfig",
    "VelocityEstimate",
    "VelocityStatus",
    "fit_velocity_profile",
]
