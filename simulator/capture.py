"""`usv-tracker simulate --write DIR`: a scenario as capture files, in the formats a real run is recorded in.

  lidar.pcap          VLP-16 data (2368) and position (8308) packets, classic pcap, the sensor's timing
  radar.dat           AWR1843 data-port bytes exactly as TI's visualizer saves them, plus radar.dat.times
  autopilot.tlog      MAVLink 2 pose messages as the autopilot streams them (pymavlink's tlog format)
  truth.csv           ground truth of every vessel and of the own boat at 10 Hz
  returns.csv         per 0.1 s window, what the sensors returned from each vessel and the shore (simulator/returns.py)
  radar.cfg           the chirp profile the radar was "configured" with
  usv-tracker.toml    the sensor mounts of the scene, for `usv-tracker run --config` (the defaults are another boat's)

All files share one clock: Unix time starting at ``T0_UNIX``, so `usv-tracker run --fast` replays them together.
"""

from __future__ import annotations

import logging
import math
import shutil
import struct
from pathlib import Path

import numpy as np

from daemon.autopilot_geo import LocalTangentPlane
from daemon.mavlink_env import mavlink
from drivers.awr1843.parser import encode_frame
from drivers.awr1843.timed_capture import TimedCaptureWriter
from drivers.frames import euler_rates_to_body
from drivers.mount import Mount
from drivers.vlp16.packet import encode_data_packet, encode_position_packet
from drivers.vlp16.pcap import PcapWriter
from simulator.lidar_model import Vlp16Model
from simulator.radar_model import Awr1843Model
from simulator.returns import ReturnsRecorder
from simulator.run import RADAR_PROFILE
from simulator.scenarios import get_scenario
from simulator.scene import Scene
from simulator.truth import T0_UNIX, write_truth_csv

log = logging.getLogger(__name__)

POSE_RATE_HZ = 20.0
RADAR_TICKS_PER_S = 200_000_000  # xWR18xx R4F cycle counter


def _tlog_record(t_unix: float, msg: object, mav: object) -> bytes:
    buf = msg.pack(mav)  # type: ignore[attr-defined]
    return struct.pack(">Q", int(t_unix * 1e6)) + bytes(buf)


def mounts_toml(scene: Scene) -> str:
    """A config holding the scene's sensor mounts: a replay with the default mounts would put every return at the
    wrong height (the water and solid tests then drop low hulls) and the radar's returns off by the lever arm."""

    def table(m: Mount) -> str:
        deg = (math.degrees(m.roll), math.degrees(m.pitch), math.degrees(m.yaw))
        return (
            f"mount = {{ x = {m.x!r}, y = {m.y!r}, z = {m.z!r}, "
            f"roll = {deg[0]!r}, pitch = {deg[1]!r}, yaw = {deg[2]!r} }}"
        )

    return (
        f"# Sensor mounts of the simulated scene {scene.name!r} (written by `usv-tracker simulate --write`).\n"
        f"[lidar]\n{table(scene.lidar_mount)}\n\n[radar]\n{table(scene.radar_mount)}\n"
    )


def write_captures(
    scenario: str, out_dir: Path, seconds: float, seed: int = 0, scene: Scene | None = None
) -> dict[str, Path]:
    """Write the named scenario (or ``scene``, a ready-made one, when given) as capture files into ``out_dir``."""
    out_dir.mkdir(parents=True, exist_ok=True)
    if scene is None:
        scene = get_scenario(scenario, seed=seed)
    paths = {
        "lidar": out_dir / "lidar.pcap",
        "radar": out_dir / "radar.dat",
        "autopilot": out_dir / "autopilot.tlog",
        "truth": out_dir / "truth.csv",
        "returns": out_dir / "returns.csv",
        "profile": out_dir / "radar.cfg",
        "config": out_dir / "usv-tracker.toml",
    }
    returns = ReturnsRecorder(scene, seconds)
    # LiDAR: every packet at its own time, a position packet once a second.
    model = Vlp16Model(scene, scene.lidar_mount, seed=seed)
    n_packets = 0
    with PcapWriter(paths["lidar"]) as pcap:
        next_position = 0.0
        for pkt in model.packets(0.0, seconds):
            payload = encode_data_packet(pkt.block_azimuth_cdeg, pkt.distance_m, pkt.reflectivity, pkt.timestamp_us)
            pcap.write_udp(T0_UNIX + pkt.t, payload)
            returns.add_lidar_packet(model, pkt)
            n_packets += 1
            if pkt.t >= next_position:
                pcap.write_udp(T0_UNIX + pkt.t, encode_position_packet(pkt.timestamp_us), dst_port=8308, src_port=8308)
                next_position += 1.0
    # Radar: one frame per 100 ms, each chunk stamped when its last byte would have left the UART.
    radar = Awr1843Model(scene, scene.radar_mount, seed=seed)
    n_frames = 0
    with TimedCaptureWriter(paths["radar"]) as dat:
        for k in range(int(seconds / radar.frame_period)):
            t = k * radar.frame_period
            d = radar.frame(t, k)
            returns.add_radar_frame(d)
            frame = encode_frame(
                k + 1, d.xyz_ti, d.doppler, d.snr_db, d.noise_db, int(t * RADAR_TICKS_PER_S) & 0xFFFFFFFF
            )
            dat.write(frame, T0_UNIX + t + len(frame) / 92_160.0)
            n_frames += 1
    shutil.copyfile(RADAR_PROFILE, paths["profile"])
    # Autopilot: ATTITUDE, LOCAL_POSITION_NED and GLOBAL_POSITION_INT at 20 Hz, SYSTEM_TIME at 1 Hz.
    mav = mavlink.MAVLink(None, srcSystem=1, srcComponent=1)
    plane = LocalTangentPlane(59.41, 10.49, 0.0)
    times = np.arange(0.0, seconds, 1.0 / POSE_RATE_HZ)
    with paths["autopilot"].open("wb") as tlog:
        for t in times:
            pose = scene.own.pose(float(t))
            ms = int(t * 1000) + 100_000
            tu = T0_UNIX + float(t)
            pos = np.asarray(pose.position, float)
            vel = np.asarray(pose.velocity, float)
            p, q, r = euler_rates_to_body(pose.roll, pose.pitch, pose.roll_rate, pose.pitch_rate, pose.yaw_rate)
            tlog.write(_tlog_record(tu, mav.attitude_encode(ms, pose.roll, pose.pitch, pose.yaw, p, q, r), mav))
            tlog.write(_tlog_record(tu, mav.local_position_ned_encode(ms, *map(float, pos), *map(float, vel)), mav))
            lat, lon, alt = plane.to_geodetic(pos)
            hdg = round(math.degrees(pose.yaw) % 360.0 * 100.0) % 36000
            gpi = mav.global_position_int_encode(
                ms,
                round(lat * 1e7),
                round(lon * 1e7),
                round(alt * 1000),
                round(-pos[2] * 1000),
                *(round(float(v) * 100) for v in vel),
                hdg,
            )
            tlog.write(_tlog_record(tu, gpi, mav))
            if int(t * POSE_RATE_HZ) % int(POSE_RATE_HZ) == 0:
                tlog.write(_tlog_record(tu, mav.system_time_encode(int(tu * 1e6), ms), mav))
    write_truth_csv(scene, paths["truth"], 0.0, seconds, period=0.1)
    returns.write(paths["returns"])
    paths["config"].write_text(mounts_toml(scene))
    log.info(
        "wrote %s: %d LiDAR packets, %d radar frames, %d pose samples, truth at 10 Hz (t0 = %.0f Unix s)",
        out_dir,
        n_packets,
        n_frames,
        len(times),
        T0_UNIX,
    )
    return paths
