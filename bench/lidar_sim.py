"""The honest LiDAR path for the benchmarks, and the footprint geometry the scores need.

``simulate`` runs what the daemon runs on the boat: the simulator's noisy packets are encoded into real 1206-byte
VLP-16 data packets, decoded by :class:`drivers.vlp16.decoder.ScanAssembler` into body-frame revolutions with per-point
times, each point is put in the world with the own boat's pose at its own firing time, and
:func:`tracker.lidar.preprocess.preprocess` filters it. No noise-free hit and no label reaches the tracker; the labels
are only kept (as per-point times) so the benchmark can tell when the sensor looked at a target.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from drivers.vlp16.decoder import ScanAssembler
from drivers.vlp16.packet import encode_data_packet
from simulator.lidar_model import Vlp16Model
from simulator.scenarios import get_scenario
from simulator.scene import Scene
from tracker.lidar.config import PreprocessConfig
from tracker.lidar.preprocess import preprocess


@dataclass
class Frame:
    """One revolution after preprocessing, in the world frame (local NED)."""

    stamp: float  # s, time of the revolution's last firing (what the daemon hands the tracker)
    points_world: np.ndarray  # (M, 3) world NED, m
    point_t: np.ndarray  # (M,) firing time of each kept point, s
    own_position: np.ndarray  # (2,) north, east at ``stamp``
    own_yaw: float  # rad at ``stamp``
    n_raw: int  # returns in the decoded revolution, before preprocessing


def simulate(
    scene: Scene | str,
    t0: float,
    t1: float,
    seed: int = 1,
    config: PreprocessConfig | None = None,
) -> list[Frame]:
    """Every complete revolution the decoder closes between ``t0`` and ``t1`` (s), through the daemon's path."""
    if isinstance(scene, str):
        scene = get_scenario(scene, seed=seed)
    model = Vlp16Model(scene, scene.lidar_mount, seed=seed)
    assembler = ScanAssembler(mount=scene.lidar_mount)
    frames: list[Frame] = []
    first = True
    for packet in model.packets(t0, t1):
        payload = encode_data_packet(
            packet.block_azimuth_cdeg, packet.distance_m, packet.reflectivity, packet.timestamp_us
        )
        for scan in assembler.push(packet.t, payload):
            if first:  # the stream starts mid-revolution: the first scan is a partial turn
                first = False
                continue
            poses = scene.own.poses(scan.t)
            pre = preprocess(scan.xyz, poses.position_ned, poses.roll, poses.pitch, poses.yaw, config)
            own = scene.own.poses(scan.stamp)
            frames.append(
                Frame(
                    stamp=float(scan.stamp),
                    points_world=pre.points_world,
                    point_t=scan.t[pre.keep],
                    own_position=own.position[0].copy(),
                    own_yaw=float(own.yaw[0]),
                    n_raw=scan.n_points,
                )
            )
    return frames


# ---------------------------------------------------------------------------------------------------------------------
# Footprint geometry (north, east), for IoU


def polygon_area(poly: np.ndarray) -> float:
    """Signed area (positive counter-clockwise in the (north, east) plane) of a (k, 2) polygon."""
    x, y = poly[:, 0], poly[:, 1]
    return 0.5 * float(np.dot(x, np.roll(y, -1)) - np.dot(y, np.roll(x, -1)))


def _ccw(poly: np.ndarray) -> np.ndarray:
    poly = np.asarray(poly, dtype=float)
    keep = np.r_[True, np.hypot(*np.diff(poly, axis=0).T) > 1e-9]  # drop repeated (padding) vertices
    poly = poly[keep]
    if len(poly) > 1 and np.hypot(*(poly[0] - poly[-1])) <= 1e-9:
        poly = poly[:-1]
    return poly if polygon_area(poly) >= 0 else poly[::-1]


def points_in_convex(points: np.ndarray, poly: np.ndarray) -> np.ndarray:
    """(n,) bool: which (n, 2) points lie inside convex polygon ``poly`` (either orientation)."""
    c = _ccw(poly)
    edge = np.roll(c, -1, axis=0) - c  # (k, 2)
    rel = points[:, None, :] - c[None, :, :]  # (n, k, 2)
    side = edge[None, :, 0] * rel[..., 1] - edge[None, :, 1] * rel[..., 0]
    return np.all(side >= 0.0, axis=1)


def clip_convex(subject: np.ndarray, clip: np.ndarray) -> np.ndarray:
    """Sutherland-Hodgman: the part of convex polygon ``subject`` inside convex polygon ``clip``."""
    out = _ccw(subject)
    c = _ccw(clip)
    for a, b in zip(c, np.roll(c, -1, axis=0), strict=True):
        if len(out) == 0:
            break
        edge = b - a
        side = edge[0] * (out[:, 1] - a[1]) - edge[1] * (out[:, 0] - a[0])  # >= 0: inside (left of a -> b)
        nxt = np.roll(out, -1, axis=0)
        side_n = np.roll(side, -1)
        pts = []
        for p, q, sp, sq in zip(out, nxt, side, side_n, strict=True):
            if sp >= 0:
                pts.append(p)
            if (sp >= 0) != (sq >= 0):
                pts.append(p + (q - p) * (sp / (sp - sq)))
        out = np.array(pts) if pts else np.zeros((0, 2))
    return out


def iou(a: np.ndarray, b: np.ndarray) -> float:
    """Intersection over union of two convex polygons."""
    inter = clip_convex(a, b)
    area_i = abs(polygon_area(inter)) if len(inter) >= 3 else 0.0
    area_u = abs(polygon_area(_ccw(a))) + abs(polygon_area(_ccw(b))) - area_i
    return area_i / area_u if area_u > 0 else 0.0


def shape_polygon(
    center: np.ndarray, heading: float, length: float, width: float, ellipse: bool, segments: int = 48
) -> np.ndarray:
    """The fitted footprint as a polygon: the oriented rectangle, or the ellipse with those axes."""
    c, s = math.cos(heading), math.sin(heading)
    if ellipse:
        a = np.linspace(0.0, 2.0 * math.pi, segments, endpoint=False)
        u, v = 0.5 * length * np.cos(a), 0.5 * width * np.sin(a)
    else:
        u = 0.5 * length * np.array([1.0, 1.0, -1.0, -1.0])
        v = 0.5 * width * np.array([-1.0, 1.0, 1.0, -1.0])
    return np.stack([center[0] + u * c - v * s, center[1] + u * s + v * c], axis=1)
