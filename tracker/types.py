"""What the trackers hand to the daemon, and the world-frame conventions they share.

World frame: the autopilot's local NED (or, in "no ego pose" mode, the body frame at start). Trackers work in the
horizontal plane: 2-D positions are (north, east) in metres; headings are radians, 0 = north, clockwise positive,
the same convention as MAVLink yaw. Velocities are (v_north, v_east) in m/s.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from enum import Enum

import numpy as np


class ShapeKind(str, Enum):
    BOX = "box"
    ELLIPSE = "ellipse"
    POINT = "point"  # too few points for a shape: centroid only


class MotionState(str, Enum):
    """ROTracker's five-level motion discriminator (paper 001, Table 1)."""

    ABSOLUTELY_STATIC = "absolutely_static"
    STATIC = "static"
    WAIT = "wait"
    DYNAMIC = "dynamic"
    ABSOLUTELY_DYNAMIC = "absolutely_dynamic"


@dataclass
class Detection:
    """One object seen in one sensor frame, in the world frame."""

    t: float
    center: np.ndarray  # (2,) north, east, m
    heading: float  # rad, in [0, pi) for symmetric shapes
    length: float  # m, along heading
    width: float  # m
    height: float  # m
    shape: ShapeKind = ShapeKind.BOX
    mse: float = 0.0
    n_points: int = 0
    range_m: float = 0.0  # distance from the own boat, for visibility weighting
    points: np.ndarray | None = None  # (n, 2) world north/east, kept for hull IoU and obstacle bins
    velocity: np.ndarray | None = None  # (2,) measured (radar Doppler), NaN where not determined
    velocity_cov: np.ndarray | None = None  # (2, 2)
    source: str = "lidar"


@dataclass
class Track:
    """A tracked object as the daemon publishes it."""

    id: int
    t: float
    position: np.ndarray  # (2,) north, east, m (world)
    velocity: np.ndarray  # (2,) m/s (world); NaN when speed is not known (motion state "wait")
    heading: float  # rad, 0 = north, clockwise
    yaw_rate: float  # rad/s
    length: float
    width: float
    height: float
    shape: ShapeKind = ShapeKind.BOX
    confirmed: bool = False
    source: str = "lidar"  # lidar | radar | fused
    motion: MotionState | None = None
    position_cov: np.ndarray = field(default_factory=lambda: np.eye(2))
    hits: int = 0
    age: float = 0.0  # s since the first detection
    time_since_update: float = 0.0
    # The id of the track whose hull this one is a piece of (tracker.radar.pieces): an outline for the obstacle
    # array, not a vessel of its own. None: a vessel.
    part_of: int | None = None

    @property
    def speed_valid(self) -> bool:
        return bool(np.all(np.isfinite(self.velocity)))

    def footprint(self, grow_m: float = 0.0) -> np.ndarray:
        """(4, 2) corners of the oriented rectangle in world north/east (ellipses: their bounding box), grown by
        ``grow_m`` on every side."""
        c, s = np.cos(self.heading), np.sin(self.heading)
        along = np.array([c, s]) * (self.length / 2 + grow_m)
        across = np.array([-s, c]) * (self.width / 2 + grow_m)
        p = self.position
        return np.array([p + along + across, p + along - across, p - along - across, p - along + across])
