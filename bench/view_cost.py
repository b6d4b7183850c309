"""What the Foxglove view (`--foxglove` / `--mcap`) costs the loop per tick, on full VLP-16 revolutions.

    python bench/view_cost.py        # about a minute

Two of bench/cycle.py's loads: "every firing returns" (the own boat in a 5 m ring wall: ~28.9k returns a
revolution, the most a VLP-16 gives at 600 rpm) and the `dense` scene in a sea-state-3 sea, rolling and pitching
(water returns, spray, radar clutter: every drop rule at work). Each revolution and its radar frame go through a
real DaemonLoop tick with the view attached to an MCAP sink, so every channel has a subscriber and every message
is built, encoded and written: the view's worst case (a WebSocket server with no client skips the work). Printed:
the view's own time per tick (after the loop's cycle, in the same thread), and the pipeline's LiDAR stage with the
per-point drop reasons kept (view on) and not (view off). One core, quietest of 3 passes.
"""

from __future__ import annotations

import os
import sys
import tempfile
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent.parent))

from bench._common import no_options
from bench.cycle import SceneEgo, ring_scene, waves_scene
from daemon.config import Config
from daemon.loop import DaemonLoop, LoopSettings, SensorInputs
from daemon.runner import freeze_startup_objects, pipeline_for
from daemon.view.publisher import FoxgloveView
from drivers.awr1843.parser import RadarFrameParser, encode_frame
from drivers.vlp16.decoder import ScanAssembler
from drivers.vlp16.packet import encode_data_packet
from simulator.lidar_model import Vlp16Model
from simulator.radar_model import Awr1843Model
from simulator.scene import Scene

SECONDS = 4.0
PASSES = 3
WARM = 5  # tracks start up in the first revolutions


def inputs_for(scene: Scene) -> tuple[list, list]:
    lidar = Vlp16Model(scene, scene.lidar_mount, seed=3)
    radar = Awr1843Model(scene, scene.radar_mount, seed=3)
    assembler = ScanAssembler(mount=scene.lidar_mount)
    parser = RadarFrameParser(None, scene.radar_mount)
    scans = []
    for pkt in lidar.packets(10.0, 10.0 + SECONDS):
        payload = encode_data_packet(pkt.block_azimuth_cdeg, pkt.distance_m, pkt.reflectivity, pkt.timestamp_us)
        scans += assembler.push(pkt.t, payload)
    scans = scans[1:]  # the first revolution is partial
    frames = []
    for k, scan in enumerate(scans):
        d = radar.frame(scan.stamp, k)
        frames.append(parser.feed(encode_frame(k + 1, d.xyz_ti, d.doppler, d.snr_db, d.noise_db), scan.stamp))
    return scans, frames


def one_pass(scene: Scene, scans: list, frames: list, view_on: bool, mcap: Path) -> tuple[list[float], list[float]]:
    config = Config()
    config.lidar.mount.z = scene.lidar_mount.z
    config.radar.mount.x, config.radar.mount.z = scene.radar_mount.x, scene.radar_mount.z
    inputs = SensorInputs()
    loop = DaemonLoop(pipeline_for(config), inputs, None, SceneEgo(scene), LoopSettings())
    view = FoxgloveView(mcap_path=mcap) if view_on else None
    if view is not None:
        view.attach(loop)
    freeze_startup_objects()
    lidar_ms = []
    try:
        for scan, fs in zip(scans, frames, strict=True):
            inputs.lidar.put(scan, scan.stamp)
            for f in fs:
                inputs.radar.put(f, scan.stamp)
            out = loop.tick(scan.stamp + 0.01)
            lidar_ms.append(out.timings_ms.get("lidar", 0.0))
    finally:
        if view is not None:
            view.close()
    assert view is None or (view.enabled and view.ticks == len(scans))
    return (list(view.costs_ms)[WARM:] if view is not None else []), lidar_ms[WARM:]


def main() -> None:
    no_options(__doc__)
    if hasattr(os, "sched_setaffinity"):
        os.sched_setaffinity(0, {sorted(os.sched_getaffinity(0))[0]})
    with tempfile.TemporaryDirectory() as tmp:
        for name, scene in (("every firing returns", ring_scene()), ("sea state 3, rolling", waves_scene())):
            print(f"{name}: ray casting...", flush=True)
            scans, frames = inputs_for(scene)
            points = np.mean([s.n_points for s in scans])
            best: dict[str, tuple[float, float]] = {}
            for on in (True, False):
                runs = []
                for _ in range(PASSES):
                    view_ms, lidar_ms = one_pass(scene, scans, frames, on, Path(tmp) / "v.mcap")
                    runs.append((view_ms, lidar_ms))
                key = min(runs, key=lambda r: float(np.median(r[1])))
                best["on" if on else "off"] = (
                    float(np.median(key[1])),
                    float(np.percentile(key[0], 50)) if key[0] else 0.0,
                )
                if on:
                    view_all = np.concatenate([r[0] for r in runs])
                    best["view"] = (float(np.percentile(view_all, 50)), float(np.percentile(view_all, 99)))
            size = (Path(tmp) / "v.mcap").stat().st_size / len(scans)
            print(
                f"  {points:,.0f} returns a revolution, {len(scans) - WARM} ticks x {PASSES} passes: "
                f"view p50 {best['view'][0]:.2f} ms, p99 {best['view'][1]:.2f} ms per tick; "
                f"LiDAR stage p50 {best['on'][0]:.1f} ms with the drop reasons, {best['off'][0]:.1f} ms without; "
                f"MCAP {size / 1e3:.0f} kB a tick",
                flush=True,
            )


if __name__ == "__main__":
    main()
