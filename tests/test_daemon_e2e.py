"""The daemon end to end: the simulator plays VLP-16 (UDP), AWR1843 (ptys) and ArduPilot (MAVLink) on loopback, the
real daemon runs against them, and the assertions are on what the simulated autopilot RECEIVED.

Scene: the own boat lies still at the origin facing north; one 6 x 2.5 m box lies broadside 20 m away on the
bearing 30 deg (starboard bow). Its near face is 20 - 1.25 = 18.75 m from the LiDAR.
"""

from __future__ import annotations

import logging
import math
import socket
import subprocess
import sys
import threading
import time
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path

import numpy as np
import pytest

from daemon import heap
from daemon.config import Config
from daemon.demo import config_for_simulation, free_udp_port, simulation_settings
from daemon.runner import RunningDaemon, StartupError, start_daemon
from drivers.vlp16.packet import PACKETS_PER_S
from simulator.autopilot import PROXIMITY_TIMEOUT_S, SimAutopilot
from simulator.run import SimulationRun
from simulator.scene import OwnBoat, Scene, Trajectory, Vessel
from simulator.sea import Sea

BEARING = math.radians(30.0)
NEAR_FACE_M = 18.75
# The bin holds the NEAREST of ~100 returns on the face, each with 2 cm range noise: 5-8 cm short of the face.
NEAR_TOL_CM = 15
# Below this share of the sensor's packet rate the simulated LiDAR is not keeping real time (its sender process is
# starved of CPU): the packets reach the daemon too late to be fresh, as a real sensor's never would.
LIDAR_REAL_TIME_SHARE = 0.9

# Real sockets, ptys and threads in real time on a 2-core machine that may be busy: a missed deadline is retried once
# (a deterministic failure still fails); the assertions themselves are not loosened.
pytestmark = pytest.mark.flaky(reruns=1)


def one_box_scene() -> Scene:
    centre = (20.0 * math.cos(BEARING), 20.0 * math.sin(BEARING))
    box = Vessel("box", 6.0, 2.5, 1.5, Trajectory.stationary(centre, BEARING + math.pi / 2))
    return Scene("one_box", OwnBoat(Trajectory.stationary((0.0, 0.0), 0.0)), [box], [], duration=60.0)


@contextmanager
def running(sim: SimulationRun, config: Config) -> Iterator[RunningDaemon]:
    daemon = start_daemon(config)
    thread = threading.Thread(target=daemon.loop.run_live, args=(daemon.stop_event,), daemon=True)
    thread.start()
    try:
        yield daemon
    finally:
        daemon.stop_event.set()
        thread.join(timeout=2.0)
        daemon.stop()
        assert not thread.is_alive()


def wait_for(predicate, timeout: float = 5.0) -> bool:  # type: ignore[no-untyped-def]
    end = time.monotonic() + timeout
    while time.monotonic() < end:
        if predicate():
            return True
        time.sleep(0.02)
    return False


def test_obstacle_distance_reaches_autopilot_at_10_hz_with_the_vessel_in_its_bin() -> None:
    with (
        SimulationRun(simulation_settings("one_box"), scene=one_box_scene()) as sim,
        running(sim, config_for_simulation(sim)),
    ):
        ap = sim.autopilot
        assert ap is not None
        assert wait_for(lambda: len(ap.obstacle_distances()) >= 10)
        sent_before = sim.packets_sent
        time.sleep(2.0)
        lidar_share = (sim.packets_sent - sent_before) / (2.0 * PACKETS_PER_S)
        msgs = ap.obstacle_distances()
        recent = [m for m in msgs if m.host_time >= msgs[-1].host_time - 2.0]
        assert 15 <= len(recent) <= 25, len(recent)  # 10 Hz over 2 s (a loaded CI machine may slip a tick)
        last = msgs[-1]
        assert (last.src_system, last.src_component) == (1, 196)
        assert last.frame == 12 and last.increment_f == 5.0 and last.angle_offset == 0.0
        assert (last.min_distance, last.max_distance) == (50, 10000)
        d = np.asarray(last.distances)
        # the hull spans about +-9 deg around 30 deg: bins 4..8 are obstacles, all nearer than its far corners
        # (LiDAR returns or, without them, the radar track's outline)
        assert np.all(d[4:9] < 2100), d[4:9]
        # Nothing else is an obstacle, and nothing is claimed clear: the LiDAR 1.6 m up cannot see a 0.5 m solid
        # within 4 m of it (its lowest beam passes over), and the radar reaches 50 of the 100 m.
        rest = np.r_[0:3, 10:72]
        assert np.all(d[rest] == 65535), {int(j): int(d[j]) for j in rest if d[j] != 65535}
        assert ap.proximity_health() == "Good"
        if lidar_share < LIDAR_REAL_TIME_SHARE:
            # The simulated sensor, not the daemon, fell behind: with its packets late the daemon rightly treats the
            # LiDAR as silent and the bin holds the radar's coarser outline, so the LiDAR's precision cannot be judged.
            pytest.skip(f"the simulated VLP-16 sent {lidar_share:.0%} of its packets in real time (CPU-starved)")
        # the near face, seen by the LiDAR (at the body origin)
        assert abs(int(d[6]) - NEAR_FACE_M * 100) <= NEAR_TOL_CM, d[4:9]


def test_tracked_box_reaches_the_ground_station_as_an_ais_vessel() -> None:
    with SimulationRun(simulation_settings("one_box", radar=False), scene=one_box_scene()) as sim:
        config = config_for_simulation(sim)
        config.output.ais_interval_s = 0.5
        with running(sim, config):
            ap = sim.autopilot
            assert ap is not None
            assert wait_for(lambda: len(ap.ais_vessels()) >= 3, timeout=10.0)
            vessels = ap.ais_vessels()
            times = [v.host_time for v in vessels[-3:]]
            assert 0.8 <= times[-1] - times[0] <= 1.4  # one per 0.5 s (a single confirmed track)
            v = vessels[-1]
            assert (v.src_system, v.src_component) == (1, 196)
            assert 900_000_000 < v.mmsi < 901_000_000 and v.name.startswith("USV-TRK ")
            # where the box lies on the simulated autopilot's own map (its EKF origin at 59.41 N 10.49 E)
            lat, lon, _ = ap.plane.to_geodetic(np.array([20.0 * math.cos(BEARING), 20.0 * math.sin(BEARING), 0.0]))
            north_err = (v.lat_deg - float(lat)) * 111_320.0
            east_err = (v.lon_deg - float(lon)) * 111_320.0 * math.cos(math.radians(float(lat)))
            # a hull seen from one side has its centre biased towards the sensor (README, known limitations)
            assert math.hypot(north_err, east_err) < 1.5, (north_err, east_err)
            assert v.velocity_mps is not None and v.velocity_mps < 0.3  # the box lies still
            assert v.cog_deg is None  # too slow for a course
            assert v.length_m is not None and v.beam_m is not None and 4 <= v.length_m <= 8 and v.beam_m >= 1


def test_radar_only_leaves_uncovered_bearings_unknown() -> None:
    settings = simulation_settings("one_box")
    settings.lidar = False
    with SimulationRun(settings, scene=one_box_scene()) as sim:
        config = config_for_simulation(sim)
        config.lidar.enabled = False
        # The radar vouches out to its 50 m; with the array's range at 40 m and the blind 3 m next to the hull
        # accepted, its wedge can be sent clear: its elevation beam passes over a 0.5 m solid nearer than 1.5 m to
        # it, and it sits 1.2 m forward of the body origin, from which the bins are judged (2.7 m ahead, 2.4 m at 30
        # deg off the bow).
        config.output.max_distance_m = 40.0
        config.output.clear_inner_m = 3.0
        with running(sim, config):
            ap = sim.autopilot
            assert ap is not None
            assert wait_for(lambda: len(ap.obstacle_distances()) >= 15, timeout=8.0)

            def vouched() -> np.ndarray | None:
                """The latest message with the radar's wedge sent clear. On a busy machine a late radar frame lets
                its coverage lapse for a tick, and the wedge then goes out unknown, as it should."""
                for msg in reversed(ap.obstacle_distances()):
                    d = np.asarray(msg.distances)
                    if d[66] == 4001 and d[0] == 4001:
                        return d
                return None

            assert wait_for(lambda: vouched() is not None, timeout=15.0)
            d = vouched()
            assert d is not None
            # the radar (fov 120 deg about the bow) covers bins 60..71 and 0..12
            assert np.all(d[13:60] == 65535), d[13:60]
            # The box at 30 deg, seen by the radar 1.2 m forward of the body origin, reaches the array as a confirmed
            # radar track. A radar track at rest is published north/east-aligned (its filter's box; only one under
            # way is turned to its course): each obstacle bin lies between the nearest point of the hull's
            # axis-aligned bounding box (minus 30 cm of radar noise) and the farthest point of the hull (plus 25 cm):
            # never farther than the hull, possibly nearer (cautious side).
            # A bin beside the hull's (3 or 9) may hold it too: the radar's track of a still box seen as its two ends
            # after the world frame's change at the first pose (a frame of two 3-return clusters first) drifts a few
            # degrees across the line of sight, which the Doppler does not measure, before it ends. There the
            # obstacle lies within the hull's distances: never farther than the hull.
            obstacle_bins = np.flatnonzero(d <= 4000)
            assert set(obstacle_bins) <= {3, 4, 5, 6, 7, 8, 9}, obstacle_bins
            assert 6 in obstacle_bins
            near_box, _ = hull_range_per_bin(axis_aligned=True)
            _, far = hull_range_per_bin()
            for j in obstacle_bins:
                near_j = near_box[j] if np.isfinite(near_box[j]) else near_box.min()
                far_j = far[j] if np.isfinite(far[j]) else far.max()
                assert near_j - 30 <= d[j] <= far_j + 25, (j, d[j], near_box[j], far[j])


def hull_range_per_bin(axis_aligned: bool = False) -> tuple[np.ndarray, np.ndarray]:
    """Nearest and farthest hull point of the box per 5-degree bin, cm from the body origin (own boat at rest).

    ``axis_aligned``: of the box's north/east-aligned bounding box instead (a radar track's shape).
    """
    from tracker.obstacle_map import bearing_bins, outline_points

    scene = one_box_scene()
    corners = np.asarray(scene.footprints(0.0))[0, 0][:4]  # world (north, east) = body (fwd, stbd) here
    if axis_aligned:
        (n0, e0), (n1, e1) = corners.min(axis=0), corners.max(axis=0)
        corners = np.array([[n0, e0], [n0, e1], [n1, e1], [n1, e0]])
    pts = outline_points(corners, spacing=0.01)
    j, r = bearing_bins(pts), np.hypot(*pts.T) * 100
    near, far = np.full(72, np.inf), np.full(72, -np.inf)
    np.minimum.at(near, j, r)
    np.maximum.at(far, j, r)
    return near, far


def test_silent_sensors_stop_the_output_and_it_comes_back() -> None:
    settings = simulation_settings("one_box", radar=False)
    with SimulationRun(settings, scene=one_box_scene()) as sim:
        config = config_for_simulation(sim)
        with running(sim, config):
            ap = sim.autopilot
            assert ap is not None
            assert wait_for(lambda: len(ap.obstacle_distances()) >= 10)
            sim.lidar_paused.set()
            t_pause = time.monotonic()
            time.sleep(1.5)
            msgs = ap.obstacle_distances()
            last_before = msgs[-1].host_time
            # the last revolution ends <= 0.1 s after the pause; 0.5 s later the daemon must be silent
            assert last_before - t_pause <= 0.75
            n_silent = len(msgs)
            time.sleep(1.0)
            assert len(ap.obstacle_distances()) == n_silent  # nothing at all, not an all-unknown array
            assert ap.proximity_health() == "NoData"
            assert any("no sensor data" in s.text for s in ap.statustexts())
            assert any("LiDAR silent" in s.text for s in ap.statustexts())
            ours = [h for h in ap.heartbeats() if h.src_component == 196]
            assert ours[-1].system_status == 6  # MAV_STATE_EMERGENCY: no sensor at all
            sim.lidar_paused.clear()
            assert wait_for(lambda: len(ap.obstacle_distances()) >= n_silent + 5, timeout=3.0)
            assert wait_for(lambda: [h for h in ap.heartbeats() if h.src_component == 196][-1].system_status == 4)
            d = np.asarray(ap.obstacle_distances()[-1].distances)
            assert abs(int(d[6]) - NEAR_FACE_M * 100) <= NEAR_TOL_CM


def test_a_second_lidar_on_the_port_changes_nothing_and_is_reported(caplog: pytest.LogCaptureFixture) -> None:
    """The field finding: another LiDAR-like source sending to the VLP-16 port. Its returns (1 to 10 m all around,
    from tests.test_vlp16_decoder.sweep) would put obstacles in bins where the scene has none if they were mixed in."""
    from tests.test_vlp16_decoder import PERIOD_US, sweep

    settings = simulation_settings("one_box", radar=False)
    with SimulationRun(settings, scene=one_box_scene()) as sim:
        config = config_for_simulation(sim)
        config.output.health_interval_s = 0.5
        with caplog.at_level(logging.INFO), running(sim, config) as daemon:
            ap = sim.autopilot
            assert ap is not None
            stats = daemon.sources.lidar.stats
            assert wait_for(lambda: stats.sender.startswith("127.0.0.1:") and len(ap.obstacle_distances()) >= 5)
            n_before = len(ap.obstacle_distances())
            other = sweep(1500, start_us=2_000_000_000).payloads  # 2 s of a second VLP-16
            with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as foreign:
                foreign.bind(("127.0.0.2", 0))
                start = time.perf_counter()
                for n, payload in enumerate(other):
                    delay = start + n * PERIOD_US * 1e-6 - time.perf_counter()
                    if delay > 0:
                        time.sleep(delay)
                    foreign.sendto(payload, ("127.0.0.1", sim.settings.lidar_port))
            assert wait_for(lambda: stats.foreign_source == 1500)
            assert wait_for(lambda: len(ap.obstacle_distances()) >= n_before + 25)
            assert wait_for(lambda: "lidar_rejected 1500 (other senders 1, last 127.0.0.2:" in caplog.text)
            # every message sent while the foreign packets arrived shows the scene alone: the box, nothing else
            for m in ap.obstacle_distances()[n_before:]:
                d = np.asarray(m.distances)
                assert abs(int(d[6]) - NEAR_FACE_M * 100) <= NEAR_TOL_CM
                rest = np.r_[0:3, 10:72]
                assert np.all(d[rest] == 65535), {int(j): int(d[j]) for j in rest if d[j] != 65535}
            alert = "usv-tracker: other LiDAR 127.0.0.2 ignored"
            assert wait_for(lambda: alert in [s.text for s in ap.statustexts()])
            assert [s.text for s in ap.statustexts()].count(alert) == 1  # once, not per packet
            assert stats.sender.startswith("127.0.0.1:") and stats.lock_moves == 0
            assert f"lidar_from {stats.sender}" in caplog.text


def test_radar_frames_of_another_board_are_rejected_and_reported(caplog: pytest.LogCaptureFixture) -> None:
    settings = simulation_settings("one_box")
    settings.lidar = False
    with SimulationRun(settings, scene=one_box_scene()) as sim:
        config = config_for_simulation(sim)
        config.lidar.enabled = False
        config.output.health_interval_s = 0.5
        with caplog.at_level(logging.INFO), running(sim, config) as daemon:
            ap, emulator = sim.autopilot, sim.radar
            assert ap is not None and emulator is not None
            parser = daemon.sources.radar.stats.parser
            assert wait_for(lambda: parser.frames_ok >= 5)
            emulator.platform = 0xA6843  # as if the data port now belonged to an IWR6843 board
            assert wait_for(lambda: parser.frames_rejected >= 5)
            alert = "usv-tracker: radar frames of other config dropped"
            assert wait_for(lambda: alert in [s.text for s in ap.statustexts()])
            assert wait_for(lambda: "radar_rejected" in caplog.text)
            assert "(platform xWR68xx, configured xWR18xx)" in caplog.text
            ok = parser.frames_ok
            emulator.platform = 0xA1843
            assert wait_for(lambda: parser.frames_ok >= ok + 5)
            assert [s.text for s in ap.statustexts()].count(alert) == 1


def test_the_live_daemon_trims_its_heap_after_each_health_line(caplog: pytest.LogCaptureFixture) -> None:
    # glibc keeps freed memory in its heap resident (bench/soak.py found up to 36 MB); the loop hands it back
    with SimulationRun(simulation_settings("one_box", radar=False), scene=one_box_scene()) as sim:
        config = config_for_simulation(sim)
        config.output.health_interval_s = 0.5
        with caplog.at_level(logging.INFO, logger="daemon.loop"), running(sim, config) as daemon:
            trim = daemon.loop.release_memory
            assert trim is heap.release_free_memory
            lines_at_trim: list[int] = []

            def spy() -> object:
                lines_at_trim.append(sum(r.getMessage().startswith("health: ") for r in list(caplog.records)))
                return trim()

            daemon.loop.release_memory = spy
            assert wait_for(lambda: len(lines_at_trim) >= 4)
    assert np.all(np.diff(lines_at_trim[:4]) == 1), lines_at_trim  # one trim per health line, right after it


def test_no_data_at_start_is_waiting_first_and_an_error_after_the_grace(caplog: pytest.LogCaptureFixture) -> None:
    # A crew starting the daemon before the sensors deliver must not read an error at every start.
    settings = simulation_settings("one_box", radar=False)
    with SimulationRun(settings, scene=one_box_scene()) as sim:
        sim.lidar_paused.set()
        config = config_for_simulation(sim)
        with caplog.at_level(logging.INFO, logger="daemon.loop"), running(sim, config):
            ap = sim.autopilot
            assert ap is not None
            time.sleep(1.5)  # within the 3 s start-up grace
            assert "waiting for sensor data" in caplog.text
            assert "no sensor has delivered" not in caplog.text
            assert not any("no sensor data" in s.text for s in ap.statustexts())
            # still nothing after the grace: now it is an error, and the autopilot is told
            assert wait_for(lambda: any("no sensor data" in s.text for s in ap.statustexts()), timeout=4.0)
            assert "no sensor has delivered since start-up (3 s)" in caplog.text
            assert ap.obstacle_distances() == []
            sim.lidar_paused.clear()
            assert wait_for(lambda: len(ap.obstacle_distances()) >= 5, timeout=3.0)


def test_a_failing_cycle_is_survived_and_a_broken_loop_gives_up() -> None:
    with SimulationRun(simulation_settings("one_box", radar=False), scene=one_box_scene()) as sim:
        daemon = start_daemon(config_for_simulation(sim))
        real_step = daemon.loop.pipeline.step
        calls = {"n": 0, "fail": {15}}

        def step(*args, **kwargs):  # type: ignore[no-untyped-def]
            calls["n"] += 1
            if calls["n"] in calls["fail"]:
                raise FloatingPointError("injected: a tracker meets a frame it cannot handle")
            return real_step(*args, **kwargs)

        daemon.loop.pipeline.step = step  # type: ignore[method-assign]
        errors: list[BaseException] = []

        def run() -> None:
            try:
                daemon.loop.run_live(daemon.stop_event)
            except BaseException as exc:
                errors.append(exc)

        thread = threading.Thread(target=run, daemon=True)
        thread.start()
        try:
            ap = sim.autopilot
            assert ap is not None
            assert wait_for(lambda: calls["n"] >= 30, timeout=6.0)
            assert thread.is_alive() and daemon.loop.failed_ticks == 1
            times = [m.host_time for m in ap.obstacle_distances()]
            # One tick lost (failed_ticks above) leaves 0.2 s between two messages; what must hold is the autopilot's
            # own 0.5 s timeout. The simulated autopilot stamps a message when its thread gets to it: beside two
            # busy processes that came 0.15 s late once (a gap of 0.354 s), so the 0.3 s of slack is the margin.
            assert len(times) >= 20 and max(np.diff(times)) < PROXIMITY_TIMEOUT_S
            # broken for good: 20 failures in a row end the loop with the error, for systemd to restart the daemon
            calls["fail"] = set(range(calls["n"] + 1, calls["n"] + 1000))
            thread.join(timeout=5.0)
            assert not thread.is_alive() and isinstance(errors[0], FloatingPointError)
            assert daemon.loop.failed_ticks >= 21
        finally:
            daemon.stop_event.set()
            thread.join(timeout=2.0)
            daemon.stop()


def test_autopilot_absent_at_start_connects_later() -> None:
    settings = simulation_settings("one_box", radar=False)
    settings.autopilot = False
    with SimulationRun(settings, scene=one_box_scene()) as sim:
        config = config_for_simulation(sim)
        port = free_udp_port()
        config.mavlink.url = f"udpout:127.0.0.1:{port}"
        with running(sim, config) as daemon:
            # no autopilot: the daemon tracks in the boat frame at start and still publishes
            assert wait_for(lambda: daemon.loop.sent >= 10)
            assert not daemon.link.connected
            late = SimAutopilot(f"udpin:127.0.0.1:{port}", lambda t: sim.scene.own.pose(t - sim.t_start))
            late.start()
            try:
                assert wait_for(lambda: len(late.obstacle_distances()) >= 5, timeout=5.0)
                assert wait_for(lambda: daemon.link.connected, timeout=5.0)
                assert wait_for(lambda: daemon.link.poses.latest() is not None, timeout=5.0)
                assert any(h.src_component == 196 and h.type == 18 for h in late.heartbeats())
            finally:
                late.stop()


def test_run_with_a_bad_config_names_the_key(tmp_path: Path) -> None:
    bad = tmp_path / "bad.toml"
    bad.write_text('[output]\nmax_distance_m = "far"\n')
    res = subprocess.run(
        [sys.executable, "-m", "daemon.cli", "run", "--config", str(bad)], capture_output=True, text=True, timeout=60
    )
    assert res.returncode == 2
    assert "output.max_distance_m: expected a number, got 'far'" in res.stderr


def test_lidar_port_taken_fails_before_ready() -> None:
    settings = simulation_settings("one_box", radar=False)
    settings.autopilot = False
    with SimulationRun(settings, scene=one_box_scene()) as sim:
        config = config_for_simulation(sim)
        with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as squatter:
            squatter.bind(("127.0.0.1", sim.settings.lidar_port))
            with pytest.raises(StartupError, match=str(sim.settings.lidar_port)):
                start_daemon(config)


def test_radar_cli_error_stops_startup_naming_the_line_when_required() -> None:
    settings = simulation_settings("one_box")
    settings.autopilot = False
    with SimulationRun(settings, scene=one_box_scene(), radar_failing_lines={"channelCfg": -1}) as sim:
        config = config_for_simulation(sim)
        config.radar.required = True
        with pytest.raises(StartupError) as err:
            start_daemon(config)
        message = str(err.value)
        assert "cfg line 13: 'channelCfg 15 5 0'" in message and "Error -1" in message


def test_radar_cli_error_runs_lidar_only_when_not_required() -> None:
    with SimulationRun(
        simulation_settings("one_box"), scene=one_box_scene(), radar_failing_lines={"channelCfg": -1}
    ) as sim:
        config = config_for_simulation(sim)
        config.radar.required = False
        with running(sim, config) as daemon:
            assert daemon.sources.radar is None
            assert any("LiDAR-only" in note for note in daemon.sources.notes)
            ap = sim.autopilot
            assert ap is not None
            assert wait_for(lambda: len(ap.obstacle_distances()) >= 5)
            d = np.asarray(ap.obstacle_distances()[-1].distances)
            assert abs(int(d[6]) - NEAR_FACE_M * 100) <= NEAR_TOL_CM


def radar_only_config(cli_path: str, data_path: str) -> Config:
    """The radar alone, not required (so a start-up failure leaves the daemon running), on the shipped profile."""
    config = Config()
    config.lidar.enabled = False
    config.radar.required = False
    config.radar.cli = f"serial://{cli_path}?baud=115200"
    config.radar.data = f"serial://{data_path}?baud=921600"
    config.radar.profile = str(Path(__file__).resolve().parent.parent / "daemon" / "profiles" / "awr1843_50m.cfg")
    return config


def test_a_radar_not_there_at_start_is_retried_when_not_required(tmp_path: Path) -> None:
    """At boot the AWR1843's USB ports may enumerate after the daemon starts: with radar.required = false the radar
    is kept and retried in the background (not left off for good), and streams once its ports appear."""
    from daemon.runner import open_sources
    from simulator.awr1843_device import Awr1843Emulator

    by_id = tmp_path / "by-id"
    config = radar_only_config(str(by_id / "awr1843-cli"), str(by_id / "awr1843-data"))
    sources = open_sources(config, fast=False)
    assert sources.radar is not None
    assert any(note.startswith("radar not ready at start, running without it and retrying") for note in sources.notes)
    stop = threading.Event()
    frames: list[object] = []
    reader = threading.Thread(target=lambda: frames.extend(f for f in sources.radar.frames(stop) if not stop.is_set()))
    reader.start()
    try:
        time.sleep(0.3)  # the ports do not exist yet: retried, no exception
        assert reader.is_alive()
        with Awr1843Emulator(link_dir=by_id):
            assert wait_for(lambda: len(frames) >= 2, timeout=15.0)
            stop.set()
            reader.join(timeout=10.0)
    finally:
        stop.set()
        reader.join(timeout=10.0)
    assert not reader.is_alive()
    assert sources.radar.stats.configured == 1


def test_a_radar_that_hears_its_first_command_garbled_twice_is_retried() -> None:
    """A noisy CLI line at start is not a refused cfg: the radar is kept and retried, and streams once the line is
    clean (before, it stayed off until the daemon was restarted)."""
    from daemon.runner import open_sources
    from simulator.awr1843_device import Awr1843Emulator

    with Awr1843Emulator(garbled_lines=2) as emu:
        config = radar_only_config(emu.cli_path, emu.data_path)
        sources = open_sources(config, fast=False)
        assert sources.radar is not None
        (note,) = sources.notes
        assert note.startswith("radar not ready at start, running without it and retrying") and "garbled" in note
        stop = threading.Event()
        frames: list[object] = []
        reader = threading.Thread(
            target=lambda: frames.extend(f for f in sources.radar.frames(stop) if not stop.is_set())
        )
        reader.start()
        try:
            assert wait_for(lambda: len(frames) >= 2, timeout=15.0)
        finally:
            stop.set()
            reader.join(timeout=10.0)
        assert not reader.is_alive()
        assert sources.radar.stats.configured == 1


def test_a_rolling_boat_in_a_rough_sea_reports_only_the_box() -> None:
    """The issue's waves, live: the boat rolls 5 deg and pitches 3 deg (ATTITUDE at 50 Hz carries it), heaves
    0.2 m (which the autopilot's position does not help with), crests stand 0.3 m and the tilted beams' water
    returns come back. Over 30 ticks of what the simulated ArduPilot received, only the box's bins hold obstacles."""
    scene = one_box_scene()
    scene.own = OwnBoat(
        Trajectory.stationary((0.0, 0.0), 0.0),
        roll_amplitude=math.radians(5.0),
        roll_period=5.0,
        pitch_amplitude=math.radians(3.0),
        pitch_period=3.7,
        heave_amplitude=0.2,
    )
    scene.sea = Sea.state(3, seed=4)
    with SimulationRun(simulation_settings("one_box", radar=False), scene=scene) as sim:
        config = config_for_simulation(sim)
        with running(sim, config):
            ap = sim.autopilot
            assert ap is not None
            assert wait_for(lambda: len(ap.obstacle_distances()) >= 10, timeout=8.0)
            start = len(ap.obstacle_distances())
            # 30 ticks of what the autopilot received, however long a busy machine takes to send them: the rate is
            # test_obstacle_distance_reaches_autopilot_at_10_hz's to hold (here 18 came in 3 s where 30 were due,
            # with both cores taken by other work)
            assert wait_for(lambda: len(ap.obstacle_distances()) >= start + 30, timeout=30.0), (
                len(ap.obstacle_distances()) - start
            )
            msgs = ap.obstacle_distances()[start:]
            for m in msgs:
                d = np.asarray(m.distances)
                obstacle = set(np.flatnonzero(d <= 10000).tolist())
                # the box spans about +-9 deg around 30 deg: bins 4..8 (one either side for the roll's lean)
                assert obstacle <= {3, 4, 5, 6, 7, 8, 9}, sorted(obstacle)
                assert {5, 6, 7} <= obstacle, sorted(obstacle)
