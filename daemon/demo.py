"""`usv-tracker demo`: the simulator plays the sensors and the autopilot, the real daemon runs against them.

Same code path as on the boat: real UDP packets, real pseudo-terminal serial ports, real MAVLink on loopback. What
the live view prints is what the simulated autopilot RECEIVED (as ArduPilot would reduce it to 8 sectors), not what
the daemon thinks it sent.
"""

from __future__ import annotations

import logging
import math
import socket
import sys
import threading
import time
from pathlib import Path
from typing import Any

import numpy as np

from daemon.config import Config, MountConfig
from daemon.runner import StartupError, freeze_startup_objects, start_daemon
from drivers.mount import Mount
from simulator.run import RADAR_PROFILE, SimulationRun, SimulationSettings

log = logging.getLogger(__name__)

SECTOR_NAMES = ("N", "NE", "E", "SE", "S", "SW", "W", "NW")  # body-relative: bow, bow-starboard, ...
SECTOR_LABELS = ("bow", "bow-stbd", "stbd", "qtr-stbd", "stern", "qtr-port", "port", "bow-port")


def free_udp_port() -> int:
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as s:
        s.bind(("127.0.0.1", 0))
        return int(s.getsockname()[1])


def mount_config(m: Mount) -> MountConfig:
    return MountConfig(m.x, m.y, m.z, math.degrees(m.roll), math.degrees(m.pitch), math.degrees(m.yaw))


def config_for_simulation(sim: SimulationRun, base: Config | None = None) -> Config:
    """The daemon's configuration pointed at a running simulation (what `run --lidar sim://` amounts to)."""
    c = base or Config()
    c.lidar.source = sim.lidar_url
    c.lidar.position_port = sim.settings.position_port
    c.lidar.mount = mount_config(sim.scene.lidar_mount)
    c.radar.enabled = sim.radar is not None
    if sim.radar is not None:
        c.radar.cli = sim.radar_cli_url
        c.radar.data = sim.radar_data_url
        c.radar.profile = str(RADAR_PROFILE)
        c.radar.mount = mount_config(sim.scene.radar_mount)
    c.mavlink.url = sim.daemon_mavlink_url
    return c


def simulation_settings(scenario: str, seed: int = 0, radar: bool = True) -> SimulationSettings:
    return SimulationSettings(
        scenario=scenario,
        seed=seed,
        radar=radar,
        lidar_port=free_udp_port(),
        position_port=free_udp_port(),
        mavlink_url=f"udpin:127.0.0.1:{free_udp_port()}",
    )


def _fmt_sector(d_m: float) -> str:
    return "  --  " if not math.isfinite(d_m) else f"{d_m:5.1f}m"


def run_demo(
    seconds: float = 30.0,
    scenario: str = "harbour",
    out_dir: Path = Path("demo-output"),
    live_view: bool = True,
    view: Any = None,
) -> int:
    out_dir.mkdir(parents=True, exist_ok=True)
    print(f"usv-tracker demo: scenario '{scenario}' for {seconds:.0f} s (simulated VLP-16, AWR1843 and ArduPilot)")
    with SimulationRun(simulation_settings(scenario)) as sim:
        config = config_for_simulation(sim)
        config.output.tracks_out = str(out_dir / "tracks.jsonl")
        config.output.ais_interval_s = 1.0  # the tracks on the ground station's map (off by default on a boat)
        try:
            daemon = start_daemon(config, view=view)
        except StartupError as exc:
            print(f"demo: the daemon could not start: {exc}", file=sys.stderr)
            return 1
        freeze_startup_objects()  # as `usv-tracker run` does
        loop_thread = threading.Thread(
            target=daemon.loop.run_live, args=(daemon.stop_event, seconds), name="daemon-loop", daemon=True
        )
        t0 = time.monotonic()
        loop_thread.start()
        try:
            if live_view:
                print("nearest obstacle per 45-degree sector, as the autopilot reduces OBSTACLE_DISTANCE ('--': none)")
                print(
                    f"{'time':>5} {'msgs/s':>6}  "
                    + " ".join(f"{n:>6}" for n in SECTOR_LABELS)
                    + "  tracks  cycle p50/p99"
                )
            last_n, last_t = 0, t0
            while loop_thread.is_alive():
                loop_thread.join(timeout=1.0)
                if not loop_thread.is_alive():
                    break  # the run ended inside this second: a rate over the stub would read as a dropped feed
                now = time.monotonic()
                ap = sim.autopilot
                assert ap is not None
                n = len(ap.obstacle_distances())
                rate = (n - last_n) / max(now - last_t, 1e-6)
                last_n, last_t = n, now
                if live_view:
                    dist, _bearing = ap.proximity_sectors()
                    p50, p99 = daemon.loop.stats.percentiles()
                    out = daemon.loop.last_output
                    n_tracks = sum(1 for tr in out.tracks if tr.confirmed) if out else 0
                    print(
                        f"{now - t0:5.1f} {rate:6.1f}  "
                        + " ".join(_fmt_sector(d) for d in dist)
                        + f"  {n_tracks:6d}  {p50:4.1f}/{p99:4.1f} ms",
                        flush=True,
                    )
        except KeyboardInterrupt:
            daemon.stop_event.set()
        finally:
            loop_thread.join(timeout=2.0)
            last = daemon.loop.last_output
            stats = daemon.loop.stats
            daemon.stop()
        ap = sim.autopilot
        assert ap is not None
        received = ap.obstacle_distances()
        p50, p99 = stats.percentiles()
        t_end = sim.sim_time()
        print()
        print("summary")
        print(
            f"  autopilot received {len(received)} OBSTACLE_DISTANCE messages "
            f"({len(received) / max(seconds, 1e-6):.1f}/s), proximity health: {ap.proximity_health()}"
        )
        print(
            f"  loop: {stats.cycles} cycles, p50 {p50:.1f} ms, p99 {p99:.1f} ms, "
            f"deadline misses {stats.deadline_misses}"
        )
        ais = ap.ais_vessels()
        if ais:
            print(
                f"  ground station: {len(ais)} AIS_VESSEL messages for {len({v.mmsi for v in ais})} tracked vessels"
                f" (last: {ais[-1].name} at {ais[-1].lat_deg:.6f} N {ais[-1].lon_deg:.6f} E)"
            )
        if received:
            d = np.asarray(received[-1].distances, dtype=float)
            obstacles = d[(d > 0) & (d <= config.output.max_distance_m * 100)]
            print(
                f"  last message: {obstacles.size} of 72 bearings with an obstacle, "
                f"nearest {obstacles.min() / 100:.1f} m"
                if obstacles.size
                else "  last message: no obstacle in range"
            )
        picture = out_dir / "demo.png"
        try:
            from daemon.demo_picture import save_demo_picture

            save_demo_picture(picture, sim.scene, t_end, last, received[-1].distances if received else None)
            print(f"  picture: {picture}")
        except ImportError:
            print("  (install matplotlib for the picture: pip install -e '.[plot]')")
        print(f"  per-tick tracks and bins: {config.output.tracks_out}")
    return 0 if received else 1
