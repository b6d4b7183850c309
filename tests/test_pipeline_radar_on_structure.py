"""A radar track on a quay the LiDAR has seen is the quay: an obstacle, never a vessel.

A quay face returns the radar's chirps as strongly as a hull, and where the LiDAR's beams do not vouch for a low
hull (30-63 m under a VLP-16 1.6 m up) the radar speaks alone; its tracks along the wall were published as vessels
moving along it. The LiDAR tracker remembers where it saw structure (tracker.lidar.structure); a radar-only track
within ``radar_on_structure_gate_m`` of it keeps its outline in the obstacle array and leaves the track list."""

from __future__ import annotations

from dataclasses import replace

import numpy as np

from daemon.config import Config
from daemon.runner import pipeline_for
from drivers.frames import RadarFrame
from drivers.mount import Mount
from tests.sea_geometry import SteadyEgo, revolution_over_water, scan_of
from tests.test_pipeline_radar_outlines import FixedRadarTracks, radar_track
from tracker.obstacle_map import bearing_bins
from tracker.types import Track

MOUNT = Mount(z=-1.6)  # the VLP-16 1.6 m above the water, the body origin at the waterline
# A quay face 80 m long (too long for a vessel: structure) 42 m north, 2.5 m high: the -1 and +1 deg beams reach it.
QUAY = (((42.0, -40.0), (42.0, 40.0), 2.5),)


def level(t: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    return np.zeros(np.shape(t)), np.zeros(np.shape(t))


def run(
    radar_north_east: tuple[float, float], gate_m: float = 3.0, then: Track | None = None, behind: bool = True
) -> tuple[np.ndarray, list[str]]:
    """Three revolutions with one radar track at ``radar_north_east``; with ``then``, a fourth with that track."""
    config = Config()
    config.lidar.mount.z = MOUNT.z
    pipeline = pipeline_for(config)
    pipeline.settings = type(pipeline.settings)(
        **{
            **pipeline.settings.__dict__,
            "lidar_mount": MOUNT,
            "radar_on_structure_gate_m": gate_m,
            "radar_behind_structure": behind,
        }
    )
    pipeline.radar_tracker = FixedRadarTracks([radar_track(*radar_north_east)])
    ego = SteadyEgo(level, 0.0)
    out = None
    for k in range(3 if then is None else 4):  # the quay is seen whole, and remembered, from the first revolution
        if k == 3:
            pipeline.radar_tracker = FixedRadarTracks([then])
        t0 = 0.1 * k
        ret = revolution_over_water(MOUNT, level, yaw=0.0, t0=t0, walls=QUAY, water_returns=False)
        frame = RadarFrame(t0 + 0.1, k + 1, np.zeros((0, 3)), np.zeros(0), np.zeros(0), np.zeros(0))
        out = pipeline.step(t0 + 0.1, scan_of(ret, t0 + 0.1), [frame], ego)
    assert out is not None
    return out.distances_cm, [tr.source for tr in out.tracks]


def test_a_radar_track_against_the_quay_is_an_obstacle_and_no_vessel() -> None:
    d, sources = run((40.0, 10.0))  # 2 m off the face, 40 m out: in the gap where a 0.5 m hull hides
    assert sources == []
    b = int(bearing_bins(np.array([[40.0, 10.0]]))[0])
    # the track's 2 x 2 m outline, its near corner 39 m north: 39 / cos(bearing) to within the bin's spread
    assert 3900 <= d[b] <= 4100


def test_a_radar_track_in_open_water_in_the_gap_is_still_a_vessel() -> None:
    _, sources = run((-40.0, 0.0))  # astern, 40 m: nothing the LiDAR saw is within 80 m of it
    assert sources == ["radar"]


def test_a_radar_track_behind_the_quay_is_a_ghost_and_no_vessel() -> None:
    # 13 m behind the face (42 m north), 10 m beyond the gate: the quay's mirror image of a hull, which the radar,
    # below the quay's top, could not see directly. Its line of sight crosses the remembered face.
    _, sources = run((55.0, 10.0))
    assert sources == []
    _, sources = run((55.0, 10.0), behind=False)
    assert sources == ["radar"]
    # Past the quay's end (its line of sight crosses the face's line 9 m beyond the end): a vessel.
    _, sources = run((50.0, 55.0))
    assert sources == ["radar"]


def test_with_the_gate_off_the_radar_track_on_the_quay_is_a_vessel() -> None:
    _, sources = run((40.0, 10.0), gate_m=-1.0)
    assert sources == ["radar"]


def test_a_radar_track_once_on_the_quay_stays_the_quay_when_it_drifts_off_it() -> None:
    # The echo of the face drifts 8 m out, past the 3 m gate: the same track (id 1) is still the quay's.
    _, sources = run((40.0, 10.0), then=radar_track(34.0, 10.0))
    assert sources == []
    # Another radar track there (a new id) that never lay on the quay is a vessel.
    other = replace(radar_track(34.0, 10.0), id=2)
    _, sources = run((40.0, 10.0), then=other)
    assert sources == ["radar"]
