"""The own boat of the autopilot-link tests: a steady turning circle whose yaw crosses +-180 deg, rocking gently."""

from __future__ import annotations

import math
import time

import numpy as np

from daemon.pose_history import wrap_angle
from drivers.frames import EgoPose

T0 = time.monotonic()
RADIUS, OMEGA = 20.0, 0.3  # a 6 m/s turn, yaw crossing +-180 deg after ~0.5 s


def circle(t: float) -> EgoPose:
    """Turning circle in NED; yaw = course, roll and pitch gently rocking."""
    s = t - T0
    a = OMEGA * s + math.pi - 0.15
    pos = np.array([RADIUS * math.sin(a), RADIUS * (1 - math.cos(a)), 0.0])
    vel = np.array([RADIUS * OMEGA * math.cos(a), RADIUS * OMEGA * math.sin(a), 0.0])
    return EgoPose(t, pos, vel, 0.05 * math.sin(2 * s), 0.02 * math.cos(1.5 * s), wrap_angle(a), OMEGA)
