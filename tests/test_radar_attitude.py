"""The radar on a rolling boat: returns are laid on the water with the full attitude, not the yaw alone."""

from __future__ import annotations

import math

import numpy as np

from drivers.frames import EgoPose, RadarFrame
from drivers.mount import rotation_zyx
from tracker.radar.config import RadarTrackerConfig
from tracker.radar.detector import RadarDetector
from tracker.radar.tracker import RadarTracker


def test_a_return_lands_within_0_2_m_of_its_scatterer_at_5_deg_roll() -> None:
    """A ship's bridge 3 m above the water, 30 m off on the starboard bow (50 deg) of a boat heading east, rolled
    5 deg and pitched 2 deg bow down: the body frame leans, so the return's body coordinates mix height into the
    horizontal. Laid with the full attitude it lands on the bridge; with the yaw alone 0.3 m off."""
    roll, pitch, yaw = math.radians(5.0), math.radians(-2.0), math.radians(90.0)
    pos = np.array([100.0, 50.0])
    body_origin_up = 0.0  # the body origin on the waterline
    # world NED of the scatterer: bearing 90 + 50 deg from north, 30 m; 3 m above the water
    b = math.radians(140.0)
    target = np.array([pos[0] + 30.0 * math.cos(b), pos[1] + 30.0 * math.sin(b), -(3.0 - body_origin_up)])
    r_bw = rotation_zyx(roll, pitch, yaw)
    body = r_bw.T @ (target - np.array([pos[0], pos[1], 0.0]))
    # through the daemon's call: a driver frame and the autopilot's pose at its time
    tracker = RadarTracker(RadarTrackerConfig().replaced(roi={"max_range_m": 50.0}))
    frame = RadarFrame(1.0, 1, body[None, :], np.zeros(1), np.full(1, 20.0), np.full(1, 5.0))
    pose = EgoPose(1.0, np.array([pos[0], pos[1], 0.0]), np.zeros(3), roll, pitch, yaw)
    tracker.step_frame(frame, pose)
    placed = tracker.last.points[0]
    assert np.hypot(*(placed - target[:2])) < 0.2
    np.testing.assert_allclose(placed, target[:2], atol=1e-9)
    # what laying the body frame flat (the yaw alone) gets wrong
    flat = RadarDetector(RadarTrackerConfig().replaced(roi={"max_range_m": 50.0})).detect(
        body[None, :], np.zeros(1), None, 0.0, pos, yaw
    )
    assert np.hypot(*(flat.points[0] - target[:2])) > 0.25
