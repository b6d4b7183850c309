"""Cycle time of the daemon's 10 Hz loop at full sensor load, on one core.

    python bench/cycle.py            # about two minutes
    python bench/cycle.py --worst    # the worst case only, printed (run it in two checkouts to pair them)

Five loads: (1) "20 vessels": the `dense` scenario (20 vessels in view) inside a closed basin of 15 m walls 60 m
around - a busy harbour, about half the firings return (the low beams see only water); (2) "every firing returns":
the own boat inside a 5 m ring wall, so all 16 beams return on every azimuth (~28.9k points per revolution), the
most points a VLP-16 can give at 600 rpm; (3) and (4) the `dense` scenario in open water, calm and level, then with
the own boat rolling 5 deg and pitching 3 deg, heaving 0.2 m in a sea-state-3 sea whose water returns to the tilted
beams and whose clutter fills the radar frame: the cost of waves, the same scene otherwise; (5) issue 13's worst
case: (4) plus water returns from nearly every steep firing, rain, a 25 m quay basin and ~200 radar points a frame
(~28k LiDAR points a revolution). Packets go through the real decoder (ScanAssembler) into LidarScans; radar frames come
from the radar model through the real frame parser. Each cycle = one revolution + one radar frame through
PerceptionPipeline.step (preprocess, both trackers, fusion, obstacle array) - exactly what the loop runs per tick.
The process is pinned to one core. Prints and saves p50/p99/max and the per-stage medians.
"""

from __future__ import annotations

import argparse
import dataclasses
import math
import os
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent.parent))

from bench._common import save
from daemon.config import Config
from daemon.runner import freeze_startup_objects, pipeline_for
from drivers.awr1843.parser import RadarFrameParser, encode_frame
from drivers.frames import EgoPose
from drivers.vlp16.decoder import ScanAssembler
from drivers.vlp16.packet import encode_data_packet
from simulator.lidar_model import Vlp16Model
from simulator.radar_model import Awr1843Model
from simulator.scenarios import get_scenario
from simulator.scene import Quay, Scene
from simulator.sea import Sea

SECONDS = 12.0
PASSES = 3


class SceneEgo:
    """EgoSource straight from the scene's analytic own-boat trajectory."""

    epoch = 0
    available = True

    def __init__(self, scene: Scene) -> None:
        self.scene = scene

    def at_many(self, times: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        p = self.scene.own.poses(np.asarray(times, float))
        return p.position_ned, p.roll, p.pitch, p.yaw

    def at(self, t: float) -> EgoPose:
        return self.scene.own.pose(t)


def basin_scene() -> Scene:
    scene = get_scenario("dense", seed=0)
    scene.quays.append(Quay(_ring(60.0), height=15.0, land_side="port", name="basin"))
    return scene


def ring_scene() -> Scene:
    scene = get_scenario("dense", seed=0)
    scene.quays.append(Quay(_ring(5.5), height=4.0, land_side="port", name="ring", depth=1.0))
    return scene


def calm_scene() -> Scene:
    return get_scenario("dense", seed=0)


def waves_scene() -> Scene:
    scene = get_scenario("dense", seed=0)
    scene.own = dataclasses.replace(
        scene.own,
        roll_amplitude=math.radians(5.0),
        roll_period=5.0,
        pitch_amplitude=math.radians(3.0),
        pitch_period=3.7,
        heave_amplitude=0.2,
    )
    scene.sea = Sea.state(3, seed=3)
    return scene


def worst_scene() -> Scene:
    """Issue 13's worst case: the waves load, plus water returns from nearly every steep firing, 1,500 rain drops a
    revolution within 12 m, the spray, a 25 m quay basin 60 m around (every upward beam returns) and radar clutter
    filling the frame to about 200 points (a real AWR1843 best-range profile gives 100-200)."""
    scene = waves_scene()
    scene.quays.append(Quay(_ring(60.0), height=25.0, land_side="port", name="basin"))
    scene.sea = dataclasses.replace(scene.sea, water_return_at_10deg=10.0, rain_rate=15_000.0)
    scene.conditions = dataclasses.replace(scene.conditions, radar_clutter_sea_state_3=220.0)
    return scene


def _ring(radius: float, n: int = 48) -> np.ndarray:
    ang = np.linspace(0.0, 2 * np.pi, n + 1)
    return np.column_stack([radius * np.cos(ang), radius * np.sin(ang)])


def measure(scene: Scene, seconds: float) -> dict[str, object]:
    config = Config()
    config.lidar.mount.z = scene.lidar_mount.z
    config.radar.mount.x, config.radar.mount.z = scene.radar_mount.x, scene.radar_mount.z
    ego = SceneEgo(scene)
    lidar = Vlp16Model(scene, scene.lidar_mount, seed=3)
    radar = Awr1843Model(scene, scene.radar_mount, seed=3)
    assembler = ScanAssembler(mount=scene.lidar_mount)
    parser = RadarFrameParser(None, scene.radar_mount)
    t0 = 10.0
    scans = []
    for pkt in lidar.packets(t0, t0 + seconds):
        payload = encode_data_packet(pkt.block_azimuth_cdeg, pkt.distance_m, pkt.reflectivity, pkt.timestamp_us)
        scans += assembler.push(pkt.t, payload)
    scans = scans[1:]  # the first revolution is partial
    frames = []
    for k, scan in enumerate(scans):
        d = radar.frame(scan.stamp, k)
        frames += parser.feed(encode_frame(k + 1, d.xyz_ti, d.doppler, d.snr_db, d.noise_db), scan.stamp)
    passes = []
    for _ in range(PASSES):
        pipeline = pipeline_for(config)
        durations, cpu, stages = [], [], {}
        out = None
        freeze_startup_objects()  # as the daemon does before its loop starts
        for k, scan in enumerate(scans):
            c0, u0 = time.perf_counter(), time.thread_time()
            out = pipeline.step(scan.stamp + 0.01, scan, frames[k : k + 1], ego)
            durations.append((time.perf_counter() - c0) * 1e3)
            cpu.append((time.thread_time() - u0) * 1e3)
            for key, v in out.timings_ms.items():
                stages.setdefault(key, []).append(v)
        assert out is not None
        warm, warm_cpu = np.array(durations[5:]), np.array(cpu[5:])  # tracks start up in the first revolutions
        passes.append(
            {
                "p50_ms": float(np.percentile(warm, 50)),
                "p99_ms": float(np.percentile(warm, 99)),
                "max_ms": float(warm.max()),
                "cpu_p50_ms": float(np.percentile(warm_cpu, 50)),
                "cpu_p99_ms": float(np.percentile(warm_cpu, 99)),
                "confirmed_tracks": sum(1 for tr in out.tracks if tr.confirmed),
                "stages_ms": {k: float(np.median(v[5:])) for k, v in stages.items()},
            }
        )
    # The machine's cores are shared with other tenants: a slow phase inflates everything by up to 1.5x for
    # seconds at a time, and noise only ever adds. So each load runs PASSES times and the quietest pass (lowest
    # p50) stands for the code; the others are kept in the JSON and their spread is printed.
    best = min(passes, key=lambda r: r["p50_ms"])
    return {
        "cycles": len(scans) - 5,
        "lidar_points": float(np.mean([s.n_points for s in scans])),
        "radar_points": float(np.mean([f.n_points for f in frames])),
        **best,
        "passes": passes,
    }


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument(
        "--worst", action="store_true", help="the worst-case load only, printed and not saved (to pair two checkouts)"
    )
    worst_only = ap.parse_args().worst
    if hasattr(os, "sched_setaffinity"):
        os.sched_setaffinity(0, {sorted(os.sched_getaffinity(0))[0]})
    rows = {}
    loads = (
        ("20 vessels in a walled basin", basin_scene()),
        ("every firing returns", ring_scene()),
        ("20 vessels, calm, level", calm_scene()),
        ("20 vessels, sea state 3, rolling 5 / pitching 3 deg", waves_scene()),
        ("worst case: the above + rain, water returns, a quay basin, 200 radar points", worst_scene()),
    )
    if worst_only:
        loads = loads[-1:]
    for name, scene in loads:
        print(f"{name}: ray casting, decoding, tracking...", flush=True)
        r = measure(scene, SECONDS)
        rows[name] = r
        print(
            f"  {r['lidar_points']:,.0f} LiDAR + {r['radar_points']:.0f} radar points per cycle, {r['cycles']} cycles: "
            f"p50 {r['p50_ms']:.1f} ms, p99 {r['p99_ms']:.1f} ms, max {r['max_ms']:.1f} ms (budget 100 ms); "
            f"CPU p50 {r['cpu_p50_ms']:.1f} ms, p99 {r['cpu_p99_ms']:.1f} ms; "
            + ", ".join(f"{k} {v:.1f}" for k, v in r["stages_ms"].items())
            + "; all passes p50/p99: "
            + ", ".join(f"{q['p50_ms']:.1f}/{q['p99_ms']:.1f}" for q in r["passes"])
        )
    if worst_only:
        return
    lines = [
        "One core, each cycle = one VLP-16 revolution + one radar frame through the whole pipeline. Wall time of the "
        f"quietest of {PASSES} passes over the same {SECONDS:.0f} s (the machine is shared: slow phases inflate "
        "everything by up to 1.5x); CPU is the thread's own CPU time in the same pass (what a slow phase of the "
        "machine does not inflate); the last column lists every pass.",
        "",
        "| load | LiDAR points | radar points | p50 | p99 | max | CPU p50 / p99 | stage medians (ms) "
        "| all passes p50 / p99 (ms) |",
        "|---|---|---|---|---|---|---|---|---|",
    ]
    for name, r in rows.items():
        stages = ", ".join(f"{k} {v:.1f}" for k, v in r["stages_ms"].items())
        lines.append(
            f"| {name} | {r['lidar_points']:,.0f} | {r['radar_points']:.0f} | {r['p50_ms']:.1f} ms | "
            f"{r['p99_ms']:.1f} ms | {r['max_ms']:.1f} ms | {r['cpu_p50_ms']:.1f} / {r['cpu_p99_ms']:.1f} ms "
            f"| {stages} | " + ", ".join(f"{q['p50_ms']:.1f} / {q['p99_ms']:.1f}" for q in r["passes"]) + " |"
        )
    save("cycle", rows, "\n".join(lines))


if __name__ == "__main__":
    main()
