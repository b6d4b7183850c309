"""A radar cluster's velocity fit drawn only when its track needs it, and reading fits from outside the tracker (a
viewer, a bench) never moves the tracker's random draws: a replay gives the same tracks whoever looks."""

from __future__ import annotations

import math

import numpy as np

from daemon.config import Config
from daemon.tracker_adapters import tracker_factories
from drivers.awr1843.parser import RadarFrameParser, encode_frame
from simulator.radar_model import SHIPPED_PROFILE, Awr1843Model
from simulator.scene import OwnBoat, Scene, Trajectory, Vessel


def _run(read_every_fit: bool) -> tuple[list[np.ndarray], int]:
    """Track states per frame of two boats crossing ahead (the simulated AWR1843 through the real parser), and how
    many cluster fits the reader made; with ``read_every_fit`` every cluster's fit is read after each frame."""
    own = OwnBoat(Trajectory.constant_velocity((0.0, 0.0), (1.0, 0.0), heading=0.0))
    boats = [
        Vessel("big", 14.0, 4.5, 2.5, Trajectory.constant_velocity((22.0, -12.0), (0.0, 3.0), heading=math.pi / 2)),
        Vessel("small", 5.0, 2.0, 1.5, Trajectory.constant_velocity((35.0, 10.0), (0.0, -2.0), heading=-math.pi / 2)),
    ]
    scene = Scene("two hulls", own, boats, [])
    config = Config()
    config.radar.profile = str(SHIPPED_PROFILE)
    config.radar.mount.x, config.radar.mount.y, config.radar.mount.z = 0.0, 0.0, 0.0
    config.radar.mount.yaw = 0.0
    _, make_radar, _ = tracker_factories(config)
    assert make_radar is not None
    tracker = make_radar()
    model = Awr1843Model(scene, scene.radar_mount, seed=5)
    parser = RadarFrameParser(None, scene.radar_mount)
    states, reads = [], 0
    for k, d in enumerate(model.frames(0.0, 6.0)):
        for frame in parser.feed(encode_frame(k + 1, d.xyz_ti, d.doppler, d.snr_db, d.noise_db), d.t):
            tracks = tracker.step_frame(frame, scene.own.pose(frame.stamp))
            states.append(np.array([[tr.id, *tr.position, *tr.velocity] for tr in tracks]).reshape(-1, 5))
            if read_every_fit:
                for cl in tracker.last_clusters:
                    if not cl.fitted:
                        # a fit the tracker left undone has no claim on its generator
                        assert cl.rng is not tracker.detector.rng
                        reads += 1
                    _ = cl.velocity
    return states, reads


def test_reading_every_clusters_fit_leaves_the_tracks_as_they_are() -> None:
    looked, reads = _run(True)
    alone, _ = _run(False)
    assert reads > 20  # fits the tracker never made: clusters no track took (clutter, shore)
    assert sum(len(s) for s in alone) > 60  # the boats were tracked
    assert len(looked) == len(alone) == 60
    for a, b in zip(looked, alone, strict=True):
        np.testing.assert_array_equal(a, b)
