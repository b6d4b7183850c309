"""Cycle time of the daemon's 10 Hz loop at full sensor load, on one core.

    python bench/cycle.py            # about a minute

The worst case for the LiDAR is every firing returning: the scene is the `dense` scenario (20 vessels in view)
inside a closed basin of 15 m walls 60 m around, so all 16 beams hit something on every azimuth (~28.9k points per
revolution). Packets go through the real decoder (ScanAssembler) into LidarScans; radar frames come from the radar
model through the real frame parser. Each cycle = one revolution + one radar frame through
PerceptionPipeline.step (preprocess, both trackers, fusion, obstacle array) - exactly what the loop runs per tick.
The process is pinned to one core. Prints and saves p50/p99/max and the per-stage medians.
"""

from __future__ import annotations

import os
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent.parent))

from bench._common import save
from daemon.config import Config
from daemon.runner import pipeline_for
from drivers.awr1843.parser import RadarFrameParser, encode_frame
from drivers.frames import EgoPose
from drivers.vlp16.decoder import ScanAssembler
from drivers.vlp16.packet import encode_data_packet
from simulator.lidar_model import Vlp16Model
from simulator.radar_model import Awr1843Model
from simulator.scenarios import get_scenario
from simulator.scene import Quay, Scene

SECONDS = 12.0


class SceneEgo:
    """EgoSource straight from the scene's analytic own-boat trajectory."""

    epoch = 0
    available = True

    def __init__(self, scene: Scene) -> None:
        self.scene = scene

    def at_many(self, times: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        p = self.scene.own.poses(np.asarray(times, float))
        pos = np.column_stack([p.position, np.zeros(len(p.t))])
        return pos, p.roll, p.pitch, p.yaw

    def at(self, t: float) -> EgoPose:
        return self.scene.own.pose(t)


def basin_scene() -> Scene:
    scene = get_scenario("dense", seed=0)
    n = 48
    ang = np.linspace(0.0, 2 * np.pi, n + 1)
    ring = np.column_stack([60.0 * np.cos(ang), 60.0 * np.sin(ang)])
    scene.quays.append(Quay(ring, height=15.0, land_side="port", name="basin"))
    return scene


def main() -> None:
    if hasattr(os, "sched_setaffinity"):
        os.sched_setaffinity(0, {sorted(os.sched_getaffinity(0))[0]})
    scene = basin_scene()
    config = Config()
    config.lidar.mount.z = scene.lidar_mount.z
    pipeline = pipeline_for(config)
    ego = SceneEgo(scene)
    lidar = Vlp16Model(scene, scene.lidar_mount, seed=3)
    radar = Awr1843Model(scene, scene.radar_mount, seed=3)
    assembler = ScanAssembler(mount=scene.lidar_mount)
    parser = RadarFrameParser(None, scene.radar_mount)
    t0 = 10.0
    print("preparing revolutions (ray casting + decoding)...", flush=True)
    scans = []
    for pkt in lidar.packets(t0, t0 + SECONDS):
        payload = encode_data_packet(pkt.block_azimuth_cdeg, pkt.distance_m, pkt.reflectivity, pkt.timestamp_us)
        scans += assembler.push(pkt.t, payload)
    scans = scans[1:]  # the first revolution is partial
    frames = []
    for k, scan in enumerate(scans):
        d = radar.frame(scan.stamp, k)
        frames += parser.feed(encode_frame(k + 1, d.xyz_ti, d.doppler, d.snr_db, d.noise_db), scan.stamp)
    durations, stages = [], {}
    for k, scan in enumerate(scans):
        t_tick = scan.stamp + 0.01
        batch = [f for f in frames[k : k + 1]]
        c0 = time.perf_counter()
        out = pipeline.step(t_tick, scan, batch, ego)
        durations.append((time.perf_counter() - c0) * 1e3)
        for key, v in out.timings_ms.items():
            stages.setdefault(key, []).append(v)
    warm = np.array(durations[5:])  # tracks start up in the first revolutions
    points = np.mean([s.n_points for s in scans])
    radar_pts = np.mean([f.n_points for f in frames])
    p50, p99, pmax = (float(np.percentile(warm, q)) for q in (50, 99, 100))
    n_tracks = sum(1 for tr in out.tracks if tr.confirmed)
    print(
        f"{len(warm)} cycles, {points:,.0f} LiDAR points + {radar_pts:.0f} radar points per cycle, "
        f"{n_tracks} confirmed tracks at the end"
    )
    print(f"cycle time on one core: p50 {p50:.1f} ms, p99 {p99:.1f} ms, max {pmax:.1f} ms (budget 100 ms)")
    med = {k: float(np.median(v[5:])) for k, v in stages.items()}
    print("stage medians: " + ", ".join(f"{k} {v:.1f} ms" for k, v in med.items()))
    md = "\n".join(
        [
            f"Full load: {points:,.0f} LiDAR points (every firing returns) + {radar_pts:.0f} radar points per cycle, "
            f"20 vessels in view, {len(warm)} cycles, one core.",
            "",
            "| p50 | p99 | max | stage medians |",
            "|---|---|---|---|",
            f"| {p50:.1f} ms | {p99:.1f} ms | {pmax:.1f} ms | "
            + ", ".join(f"{k} {v:.1f} ms" for k, v in med.items())
            + " |",
        ]
    )
    save("cycle", {"p50_ms": p50, "p99_ms": p99, "max_ms": pmax, "points": points, "stages_ms": med}, md)


if __name__ == "__main__":
    main()
