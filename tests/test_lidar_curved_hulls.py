"""The paper's adaptive shape choice (Algorithm 4: the fit with the smaller MSE, L-shape or ellipse) on curved hulls.

With every simulated hull a prism the ellipse was chosen in 0-5 % of scans and the paper's central idea went
unexercised. Here a buoy, a round-ended tender and a RIB (simulator hull "buoy" / "round") are played through the
whole path (ray-cast packets -> decoder -> preprocess -> clustering -> fits -> tracks) from a still boat, and then
the same boats as boxes: the fit follows the hull.
"""

from __future__ import annotations

import math
from collections import Counter

import numpy as np
import pytest

from daemon.config import Config
from daemon.runner import pipeline_for
from drivers.frames import EgoPose
from drivers.vlp16.decoder import ScanAssembler
from drivers.vlp16.packet import encode_data_packet
from simulator.lidar_model import Vlp16Model
from simulator.scene import OwnBoat, Scene, Trajectory, Vessel

# (name, length, width, freeboard, range, bearing deg, heading deg): all broadside or round to the boat
BOATS = (
    ("buoy", 2.0, 2.0, 1.2, 15.0, 0.0, 0.0),
    ("tender", 6.0, 2.4, 1.0, 20.0, 60.0, 150.0),
    ("rib", 8.0, 3.0, 1.2, 30.0, 120.0, 30.0),
)


class _StillEgo:
    """The own boat at the origin facing north, level: the pose source the pipeline samples."""

    epoch = 0
    available = True

    def at_many(self, times: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        n = np.asarray(times).size
        return np.zeros((n, 3)), np.zeros(n), np.zeros(n), np.zeros(n)

    def at(self, t: float) -> EgoPose:
        return EgoPose(t=t, position=np.zeros(3), velocity=np.zeros(3), roll=0.0, pitch=0.0, yaw=0.0, yaw_rate=0.0)


def _centre(rng: float, bearing_deg: float) -> np.ndarray:
    b = math.radians(bearing_deg)
    return np.array([rng * math.cos(b), rng * math.sin(b)])


def _run(curved: bool) -> tuple[dict[str, Counter], dict[str, list[float]]]:
    """Per boat: the shape of every detection on it, and the confirmed track's centre error each revolution."""
    vessels = [
        Vessel(
            name,
            length,
            width,
            freeboard,
            Trajectory.stationary(tuple(_centre(rng, brg)), math.radians(hdg)),
            hull=("buoy" if name == "buoy" else "round") if curved else "box",
        )
        for name, length, width, freeboard, rng, brg, hdg in BOATS
    ]
    scene = Scene("curved", OwnBoat(Trajectory.stationary((0.0, 0.0), 0.0)), vessels, [], duration=60.0)
    assembler = ScanAssembler(mount=scene.lidar_mount)
    scans = []
    for pkt in Vlp16Model(scene, scene.lidar_mount, seed=1).packets(1.0, 4.0):
        payload = encode_data_packet(pkt.block_azimuth_cdeg, pkt.distance_m, pkt.reflectivity, pkt.timestamp_us)
        scans += assembler.push(pkt.t, payload)
    config = Config()
    config.lidar.mount.z = scene.lidar_mount.z
    config.radar.enabled = False
    pipeline = pipeline_for(config)
    assert pipeline.lidar_tracker is not None
    shapes: dict[str, Counter] = {b[0]: Counter() for b in BOATS}
    errors: dict[str, list[float]] = {b[0]: [] for b in BOATS}
    for scan in scans[1:]:  # the first revolution is partial
        out = pipeline.step(scan.stamp + 0.01, scan, [], _StillEgo())
        for name, *_, rng, brg, _hdg in BOATS:
            c = _centre(rng, brg)
            for det in pipeline.lidar_tracker.last_detections:
                if np.hypot(*(det.center - c)) < 3.0:
                    shapes[name][det.shape.name] += 1
            errors[name] += [
                float(np.hypot(*(tr.position - c)))
                for tr in out.tracks
                if tr.confirmed and np.hypot(*(tr.position - c)) < 3.0
            ]
    return shapes, errors


@pytest.mark.parametrize("curved", [True, False], ids=["curved hulls", "the same boats as boxes"])
def test_the_adaptive_fit_follows_the_hull(curved: bool) -> None:
    shapes, errors = _run(curved)
    want = "ELLIPSE" if curved else "BOX"
    for name, *_ in BOATS:
        n = sum(shapes[name].values())
        assert n >= 25, f"{name}: {n} detections in 29 revolutions"
        # measured: every detection of each curved hull an ellipse, of each box a box but two of the buoy-sized box's
        assert shapes[name][want] >= 0.9 * n, f"{name}: {dict(shapes[name])}"
        assert len(errors[name]) >= 20, f"{name}: confirmed in {len(errors[name])} revolutions"
    if curved:
        # the ellipse puts a round hull's centre where it is: measured 0.18 / 0.29 / 0.27 m (median)
        assert np.median(errors["buoy"]) <= 0.3
        assert np.median(errors["tender"]) <= 0.5
        assert np.median(errors["rib"]) <= 0.5
