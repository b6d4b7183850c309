"""returns.csv: what the simulated sensors returned from each solid, per 0.1 s window, against the model's own hits."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest

from daemon.config import load_config
from simulator.capture import write_captures
from simulator.lidar_model import Vlp16Model
from simulator.radar_model import RadarDetections
from simulator.returns import ReturnsFormatError, ReturnsRecorder, bearing_bin, read_returns_csv
from simulator.scene import LABEL_CLUTTER, LABEL_GHOST, LABEL_SHORE, OwnBoat, Quay, Scene, Trajectory, Vessel


def wall_scene(own_heading: float = 0.0) -> Scene:
    """A still own boat; vessel 0, a box whose near face is a wall 19 m north (east -5..5); a quay 30 m south."""
    box = Vessel("wall", 2.0, 10.0, 2.5, Trajectory.stationary((20.0, 0.0), 0.0))
    quay = Quay(np.array([[-30.0, 20.0], [-30.0, -20.0]]), height=2.0, land_side="port")
    return Scene("wall", OwnBoat(Trajectory.stationary((0.0, 0.0), own_heading)), [box], [quay], duration=5.0)


def record_lidar(scene: Scene, seconds: float) -> tuple[ReturnsRecorder, Vlp16Model]:
    model = Vlp16Model(scene, range_noise_m=0.0, spray_rate=0.0)
    rec = ReturnsRecorder(scene, seconds)
    for pkt in model.packets(0.0, seconds):
        rec.add_lidar_packet(model, pkt)
    rec.flush()
    return rec, model


def test_bin_convention_is_clockwise_from_the_bow() -> None:
    fwd = np.array([1.0, 1.0, 0.0, -1.0, 0.0, 1.0])
    stbd = np.array([0.0, 1.0, 1.0, 0.0, -1.0, -0.0437])  # last: -2.5 deg rounds to bin 0 or 71 (the edge)
    assert bearing_bin(fwd[:5], stbd[:5]).tolist() == [0, 9, 18, 36, 54]
    assert bearing_bin(np.array([1.0]), np.array([-0.05]))[0] == 71  # -2.86 deg: port of the bow


@pytest.mark.parametrize(("heading", "bin_ahead", "bin_quay"), [(0.0, 0, 36), (math.pi / 2, 54, 18)])
def test_nearest_per_bin_in_the_level_frame(heading: float, bin_ahead: int, bin_quay: int) -> None:
    """The wall 19 m north is dead ahead of a boat heading north and on its port beam heading east; the quay 30 m
    south astern or to starboard. Ranges are horizontal, from the own boat's origin."""
    rec, _ = record_lidar(wall_scene(heading), 0.3)
    for k in range(rec.n_windows):
        near = rec.nearest[0, k]  # the LiDAR's
        assert near[bin_ahead] == pytest.approx(19.0, abs=0.01)
        assert near[bin_quay] == pytest.approx(30.0, abs=0.01)
        # the wall's 10 m face spans +-14.7 deg: bins within it see it at 19 / cos(bearing), none beyond 25 m
        for off in (-2, -1, 1, 2):
            j = (bin_ahead + off) % 72
            assert near[j] == pytest.approx(19.0 / math.cos(math.radians(5 * abs(off) - 2.5)), abs=0.02)
        assert np.isinf(near[(bin_ahead + 9) % 72])  # 45 deg off the bow: open water


def test_counts_and_ranges_match_the_models_own_hits() -> None:
    """Every labelled LiDAR return of a noise-free sweep is in the window of its firing time, at its true place."""
    scene = wall_scene(0.3)
    rec, model = record_lidar(scene, 0.3)
    for k in range(3):
        hits = model.hits_between(0.1 * k, 0.1 * (k + 1))
        for solid, label in ((0, LABEL_SHORE), (1, 0)):
            assert rec.lidar_counts[k, solid] == int(np.sum(hits.label == label))
        own = scene.own.pose(0.1 * (k + 1))
        rel = hits.xyz_world[:, :2] - own.position[:2]
        c, s = math.cos(own.yaw), math.sin(own.yaw)
        fwd, stbd = c * rel[:, 0] + s * rel[:, 1], -s * rel[:, 0] + c * rel[:, 1]
        expected = np.full(72, np.inf)
        np.minimum.at(expected, bearing_bin(fwd, stbd), np.hypot(fwd, stbd))
        np.testing.assert_allclose(rec.nearest[0, k], expected, atol=1e-6)
    assert rec.radar_counts.sum() == 0 and np.isinf(rec.nearest[1]).all()


def test_present_is_every_solid_there_returned_or_not() -> None:
    """The present record is geometry, not returns: the wall 19 m ahead and the quay 30 m astern in their bins
    (the wall's face spans +-14.7 deg, each bin at 19 / cos of its nearer edge) and open water elsewhere; a solid a
    sensor returned is never nearer than what is there, to the outline's 0.1 m sampling."""
    rec, _ = record_lidar(wall_scene(), 0.3)
    present = rec.present_nearest()
    assert present.shape == (3, 72)
    for k in range(3):
        assert present[k, 0] == pytest.approx(19.0, abs=0.01)
        assert present[k, 36] == pytest.approx(30.0, abs=0.01)
        for off in (-2, -1, 1, 2):
            assert present[k, off % 72] == pytest.approx(19.0 / math.cos(math.radians(5 * abs(off) - 2.5)), abs=0.02)
        assert np.isinf(present[k, 9])  # 45 deg off the bow: open water
        returned = np.isfinite(rec.nearest[0, k])
        assert np.all(present[k, returned] <= rec.nearest[0, k, returned] + 0.1)


@pytest.mark.parametrize("present", [False, True])
def test_a_file_with_no_windows_reads_as_an_empty_record(tmp_path: Path, present: bool) -> None:
    """A capture stopped before its first window ends: the header alone, with or without the present columns."""
    path = tmp_path / "returns.csv"
    rec, _ = record_lidar(wall_scene(), 0.3)
    rec.write(path)
    header = path.read_text().splitlines()[0]
    if not present:
        header = ",".join(header.split(",")[:-72])
    path.write_text(header + "\n")
    table = read_returns_csv(path)
    assert table.t_end.shape == (0,) and table.sensor_nearest.shape == (2, 0, 72) and table.vessel_ids == (0,)
    assert (table.present is not None) == present and (table.present is None or table.present.shape == (0, 72))


def test_radar_counts_only_vessels_and_shore() -> None:
    scene = wall_scene()
    rec = ReturnsRecorder(scene, 0.2)
    label = np.array([0, 0, LABEL_GHOST, LABEL_CLUTTER, LABEL_SHORE])
    world = np.array([[10.0, 0.0, -1.0], [12.0, 0.0, -1.0], [3.0, 0.0, 0.0], [2.0, 0.0, 0.0], [0.0, 7.0, -1.0]])
    n = label.size
    det = RadarDetections(
        0.1, 1, np.zeros((n, 3)), np.zeros(n), np.zeros(n), np.zeros(n), label, world, np.zeros(n), -np.ones(n, int)
    )
    rec.add_radar_frame(det)
    assert rec.radar_counts.tolist() == [[0, 0], [1, 2]]  # window 1: shore 1, vessel 0 twice; ghosts/clutter never
    radar = rec.nearest[1]  # the radar's bins; the LiDAR's stay empty
    assert radar[1, 0] == pytest.approx(10.0)
    assert radar[1, 18] == pytest.approx(7.0)
    assert np.isinf(radar[0]).all() and np.isinf(np.delete(radar[1], [0, 18])).all()
    assert np.isinf(rec.nearest[0]).all()


def test_written_file_reads_back(tmp_path: Path) -> None:
    rec, _ = record_lidar(wall_scene(), 0.3)
    assert rec.write(tmp_path / "returns.csv") == 3
    table = read_returns_csv(tmp_path / "returns.csv")
    assert table.vessel_ids == (0,)
    np.testing.assert_allclose(table.t_end, [0.1, 0.2, 0.3])
    assert table.window_s == pytest.approx(0.1)
    assert table.lidar.tolist() == rec.lidar_counts.tolist()
    np.testing.assert_allclose(table.sensor_nearest, rec.nearest, atol=5e-4)  # written to the millimetre
    np.testing.assert_allclose(table.sensor_core, rec.core, atol=5e-4)
    np.testing.assert_allclose(table.nearest, rec.nearest[0], atol=5e-4)  # both sensors: the radar saw nothing
    assert table.returns_of(0).tolist() == (rec.lidar_counts[:, 1] + rec.radar_counts[:, 1]).tolist()
    assert table.returns_of(7).tolist() == [0, 0, 0]
    assert table.present is not None
    np.testing.assert_allclose(table.present, rec.present_nearest(), atol=5e-4)
    radar_only = table.for_sensors(["radar"])
    assert np.isinf(radar_only.nearest).all() and radar_only.returns_of(0).tolist() == [0, 0, 0]


@pytest.mark.parametrize(
    ("edit", "message"),
    [
        (lambda rows: [*rows[:2], rows[2][:-1], *rows[3:]], "line 3: 368 fields, expected 369"),
        (lambda rows: [*rows[:3], ["nan", *rows[3][1:]], *rows[4:]], "line 4: 'nan' is not a finite number"),
        (lambda rows: [*rows[:1], [*rows[1][:5], "x", *rows[1][6:]], *rows[2:]], "line 2: invalid literal"),
        (lambda rows: [["t", *rows[0][1:]], *rows[1:]], "line 1: not a returns.csv header"),
    ],
)
def test_malformed_file_names_the_line(tmp_path: Path, edit: object, message: str) -> None:
    path = tmp_path / "returns.csv"
    rec, _ = record_lidar(wall_scene(), 0.3)
    rec.write(path)
    rows = [line.split(",") for line in path.read_text().splitlines()]
    path.write_text("\n".join(",".join(r) for r in edit(rows)) + "\n")  # type: ignore[operator]
    with pytest.raises(ReturnsFormatError, match=message) as err:
        read_returns_csv(path)
    assert str(path) in str(err.value)


def test_captures_include_returns_and_the_scene_mounts(tmp_path: Path) -> None:
    scene = wall_scene()
    paths = write_captures("wall", tmp_path, 0.5, scene=scene)
    table = read_returns_csv(paths["returns"])
    assert len(table.t_end) == 5
    assert np.all(table.lidar[:, 1] > 100)  # the wall, every window
    assert np.all(table.radar[:, 1] >= 1)  # dead ahead, in the radar's field of view
    config = load_config(paths["config"])
    assert config.lidar.mount.to_mount() == scene.lidar_mount
    assert config.radar.mount.to_mount() == scene.radar_mount


def test_core_bins_leave_out_returns_within_half_a_degree_of_an_edge() -> None:
    from simulator.returns import inside_bin

    bearing = np.radians([0.0, 1.9, 2.1, 2.6, 7.1, -2.2, 176.5])
    inside = inside_bin(np.cos(bearing), np.sin(bearing), math.radians(0.5)).tolist()
    # bin 0 spans -2.5..2.5 deg: 1.9 is 0.6 inside, 2.1 and -2.2 within 0.5 of its edges; 2.6 is bin 1's edge,
    # 7.1 lies 0.4 from bin 1's far edge; 176.5 is 1 deg inside bin 35's
    assert inside == [True, True, False, False, False, False, True]
