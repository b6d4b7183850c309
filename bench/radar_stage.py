"""CPU time of the radar stage alone (RadarTracker.step_frame) at the worst case's ~200 radar points a frame.

    python bench/radar_stage.py            # about half a minute

The frames are bench/cycle.py's worst case (20 vessels, sea state 3, a quay basin, radar clutter filling the frame),
made by the radar model and parsed by the real frame parser, with the own boat's pose from the scene. Each pass runs
a fresh tracker, built as the daemon builds it, over the same frames and takes the thread's CPU time per frame (wall
time on a shared machine measures the neighbours too). Prints p50/p99/max over the frames after the first few of
each pass (tracks start up there), per pass, and saves them to bench/results/radar_stage.md (and .json). Issue 12's
goal is p99 <= 5 ms.
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent.parent))

from bench._common import save
from bench.cycle import worst_scene
from daemon.config import Config
from daemon.tracker_adapters import tracker_factories
from drivers.awr1843.parser import RadarFrameParser, encode_frame
from drivers.frames import EgoPose, RadarFrame
from simulator.radar_model import Awr1843Model
from simulator.scene import Scene

WARMUP_FRAMES = 5


def radar_frames(scene: Scene, t0: float, n: int) -> list[tuple[RadarFrame, EgoPose]]:
    """``n`` frames at 10 Hz from ``t0`` through the parser, each with the own boat's pose at its stamp."""
    model = Awr1843Model(scene, scene.radar_mount, seed=3)
    parser = RadarFrameParser(None, scene.radar_mount)
    out = []
    for k in range(n):
        t = t0 + 0.1 * k
        d = model.frame(t, k)
        for frame in parser.feed(encode_frame(k + 1, d.xyz_ti, d.doppler, d.snr_db, d.noise_db), t):
            out.append((frame, scene.own.pose(frame.stamp)))
    return out


def one_pass(scene: Scene, frames: list[tuple[RadarFrame, EgoPose]]) -> np.ndarray:
    """Thread CPU ms of each frame's step_frame, with a fresh tracker."""
    config = Config()
    config.radar.mount.x, config.radar.mount.z = scene.radar_mount.x, scene.radar_mount.z
    _, factory, _ = tracker_factories(config)
    assert factory is not None
    tracker = factory()
    cpu = []
    for frame, pose in frames:
        c0 = time.thread_time()
        tracker.step_frame(frame, pose)
        cpu.append((time.thread_time() - c0) * 1e3)
    return np.array(cpu[WARMUP_FRAMES:])


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--frames", type=int, default=120)
    ap.add_argument("--passes", type=int, default=3)
    args = ap.parse_args()
    scene = worst_scene()
    frames = radar_frames(scene, 10.0, args.frames)
    points = float(np.mean([f.n_points for f, _ in frames]))
    print(f"{len(frames)} frames, {points:.0f} radar points a frame")
    passes = []
    for k in range(args.passes):
        cpu = one_pass(scene, frames)
        p50, p99 = np.percentile(cpu, [50, 99])
        passes.append(
            {"p50_ms": round(float(p50), 2), "p99_ms": round(float(p99), 2), "max_ms": round(float(cpu.max()), 2)}
        )
        print(f"  pass {k + 1}: CPU p50 {p50:.2f} ms, p99 {p99:.2f} ms, max {cpu.max():.2f} ms")
    rows = "\n".join(
        f"| {k + 1} | {p['p50_ms']:.2f} | {p['p99_ms']:.2f} | {p['max_ms']:.2f} |" for k, p in enumerate(passes)
    )
    quiet = min(passes, key=lambda p: p["p99_ms"])
    markdown = f"""`python bench/radar_stage.py`: the radar stage alone (`RadarTracker.step_frame`, built as the \
daemon builds it)
on bench/cycle.py's worst case, {len(frames)} frames of {points:.0f} radar points on average through the real parser;
thread CPU time per frame after the first {WARMUP_FRAMES} of each pass, a fresh tracker each pass. \
Goal (issue 12): p99 <= 5 ms.

| pass | CPU p50 (ms) | p99 (ms) | max (ms) |
|---|---|---|---|
{rows}

Quietest pass: p50 {quiet["p50_ms"]:.2f} ms, p99 {quiet["p99_ms"]:.2f} ms.
"""
    save("radar_stage", {"frames": len(frames), "points_per_frame": round(points, 1), "passes": passes}, markdown)


if __name__ == "__main__":
    main()
