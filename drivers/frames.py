"""Typed, time-stamped frames that the drivers hand to the rest of the daemon.

All geometry is in the body frame (FRD, metres) once it leaves a driver; all times are seconds.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np


@dataclass
class LidarScan:
    """One VLP-16 revolution, already in the body frame.

    ``xyz`` is (N, 3) float64 body FRD; ``t`` is each point's time on the same clock as ``stamp``
    (host clock for live data and replay, so that ego poses can be interpolated per point).
    """

    stamp: float  # time of the revolution's last firing, host clock, s
    stamp_device: float  # same instant on the sensor's clock (Unix s; hour from the host)
    xyz: np.ndarray  # (N, 3) float64, body FRD, m
    intensity: np.ndarray  # (N,) float32, calibrated reflectivity 0..255
    ring: np.ndarray  # (N,) uint8, 0 = lowest beam (-15 deg)
    t: np.ndarray  # (N,) float64, per-point time, s (same clock as stamp)
    packets: int = 0  # data packets that went into this revolution
    packets_missing: int = 0  # gaps in the 1327.104 us packet clock
    return_mode: str = "strongest"  # strongest | last | dual
    model: str = "VLP16"
    pps_locked: bool = False
    # Sensor azimuths (rad, clockwise from the sensor's forward) swept by the firings in this scan: start and the
    # sweep's extent (2*pi for a whole revolution). A partial scan (stream start, stall, loss) only vouches for
    # "nothing there" within its sweep.
    sweep_start: float = 0.0
    sweep_extent: float = 2 * math.pi
    # Sensor azimuths (rad, clockwise from the sensor's forward) each received data packet swept: (P, 2) start and
    # extent. A lost packet leaves a 4.8 deg hole in which nothing was measured, not "nothing there". None when
    # unknown (scans not built from packets).
    packet_sweeps: np.ndarray | None = None

    @property
    def n_points(self) -> int:
        return int(self.xyz.shape[0])


@dataclass
class RadarFrame:
    """One AWR1843 out-of-box-demo frame, already in the body frame."""

    stamp: float  # host receive time of the frame header, s
    frame_number: int
    xyz: np.ndarray  # (N, 3) float64, body FRD, m
    doppler: np.ndarray  # (N,) float64, m/s along the line of sight, positive = moving away
    snr: np.ndarray  # (N,) float64, dB (NaN when TLV 7 is absent)
    noise: np.ndarray  # (N,) float64, dB (NaN when TLV 7 is absent)
    time_cpu_cycles: int = 0
    sdk_version: tuple[int, int, int, int] = (0, 0, 0, 0)
    platform: int = 0
    tlv_types: tuple[int, ...] = ()
    bytes_skipped: int = 0  # garbage skipped before this frame's magic word
    stats: dict[str, int] | None = None  # TLV 6
    temperature: dict[str, float] | None = None  # TLV 9, deg C per sensor, plus "valid"/"time_ms"
    range_profile: np.ndarray | None = None  # TLV 2, log2 magnitude per range bin
    noise_profile: np.ndarray | None = None  # TLV 3
    extra: dict[int, bytes] = field(default_factory=dict)  # heat maps etc. kept raw

    @property
    def n_points(self) -> int:
        return int(self.xyz.shape[0])


@dataclass(frozen=True)
class EgoPose:
    """The boat's pose in the world frame (local NED), at time ``t`` on the host clock."""

    t: float
    position: np.ndarray  # (3,) NED, m
    velocity: np.ndarray  # (3,) NED, m/s
    roll: float
    pitch: float
    yaw: float  # rad, 0 = north, clockwise positive
    yaw_rate: float = 0.0  # Euler angle rates, rad/s (not the body rates p, q, r: see body_rates_to_euler)
    roll_rate: float = 0.0
    pitch_rate: float = 0.0


def body_rates_to_euler(roll: float, pitch: float, p: float, q: float, r: float) -> tuple[float, float, float]:
    """Body FRD angular rates (p, q, r), as MAVLink ATTITUDE carries them, -> ZYX Euler angle rates
    (roll_rate, pitch_rate, yaw_rate), rad/s. At pitch +-90 deg yaw and roll are one axis: the body rates are
    returned as they are."""
    cr, sr = math.cos(roll), math.sin(roll)
    cp = math.cos(pitch)
    if abs(cp) < 1e-6:
        return p, q, r
    tp = math.sin(pitch) / cp
    return p + (q * sr + r * cr) * tp, q * cr - r * sr, (q * sr + r * cr) / cp


def euler_rates_to_body(
    roll: float, pitch: float, roll_rate: float, pitch_rate: float, yaw_rate: float
) -> tuple[float, float, float]:
    """ZYX Euler angle rates -> body FRD angular rates (p, q, r); the inverse of ``body_rates_to_euler``."""
    cr, sr = math.cos(roll), math.sin(roll)
    cp, sp = math.cos(pitch), math.sin(pitch)
    return (
        roll_rate - sp * yaw_rate,
        cr * pitch_rate + sr * cp * yaw_rate,
        -sr * pitch_rate + cr * cp * yaw_rate,
    )
