"""Play a scenario's sensors and autopilot over real loopback interfaces, or write them as capture files.

Live play (what the demo and the end-to-end tests use):
  * VLP-16: real 1206-byte UDP packets to 127.0.0.1:<lidar_port> at the sensor's 1327 us cadence (plus one position
    packet per second on the position port), ray-cast from the scene;
  * AWR1843: a device emulator on two pseudo-terminals (CLI answered like the firmware, frames on the data port);
  * autopilot: a pymavlink peer playing ArduPilot Rover (pose streams, TIMESYNC, message-interval acks), which
    also records every OBSTACLE_DISTANCE it receives, i.e. exactly what a real autopilot would get.
The simulation clock is ``time.monotonic() - t_start``; the scene's truth is a function of it.
"""

from __future__ import annotations

import argparse
import contextlib
import logging
import socket
import threading
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path

from drivers.vlp16.packet import encode_data_packet, encode_position_packet
from simulator.autopilot import SimAutopilot
from simulator.awr1843_device import Awr1843Emulator, DevicePoints
from simulator.lidar_model import Vlp16Model
from simulator.radar_model import SHIPPED_PROFILE, Awr1843Model
from simulator.scenarios import get_scenario
from simulator.scene import Scene

log = logging.getLogger(__name__)

RADAR_PROFILE = SHIPPED_PROFILE


@dataclass
class SimulationSettings:
    scenario: str = "harbour"
    seed: int = 0
    lidar: bool = True
    radar: bool = True
    autopilot: bool = True
    lidar_host: str = "127.0.0.1"
    lidar_port: int = 2368
    position_port: int = 8308
    mavlink_url: str = "udpin:127.0.0.1:14550"
    radar_link_dir: str | None = None


@dataclass
class SimulationRun:
    """Start with ``start()``; the daemon then connects to ``lidar_url``, ``radar_cli_url``, ``radar_data_url``
    and the autopilot at ``daemon_mavlink_url``."""

    settings: SimulationSettings = field(default_factory=SimulationSettings)
    clock: Callable[[], float] = time.monotonic
    scene: Scene | None = None  # a ready-made scene instead of the named scenario (tests build their own)
    radar_failing_lines: dict[str, int] | None = None  # cfg lines the emulated radar answers with "Error <n>"

    def __post_init__(self) -> None:
        if self.scene is None:
            self.scene = get_scenario(self.settings.scenario, seed=self.settings.seed)
        self.t_start = 0.0
        self.packets_sent = 0
        self.lidar_paused = threading.Event()
        self._stop = threading.Event()
        self._threads: list[threading.Thread] = []
        self.radar: Awr1843Emulator | None = None
        self.autopilot: SimAutopilot | None = None
        self._radar_model: Awr1843Model | None = None
        self._sock: socket.socket | None = None

    # ---- URLs the daemon uses ------------------------------------------------------------------------------
    @property
    def lidar_url(self) -> str:
        return f"udp://{self.settings.lidar_host}:{self.settings.lidar_port}"

    @property
    def radar_cli_url(self) -> str:
        assert self.radar is not None
        return f"serial://{self.radar.cli_path}?baud=115200"

    @property
    def radar_data_url(self) -> str:
        assert self.radar is not None
        return f"serial://{self.radar.data_path}?baud=921600"

    @property
    def daemon_mavlink_url(self) -> str:
        _, host, port = self.settings.mavlink_url.split(":")
        return f"udpout:{host}:{port}"

    def sim_time(self, host_t: float | None = None) -> float:
        return (self.clock() if host_t is None else host_t) - self.t_start

    # ---- lifecycle ---------------------------------------------------------------------------------------------
    def start(self) -> None:
        self.t_start = self.clock()
        s = self.settings
        if s.autopilot:
            self.autopilot = SimAutopilot(s.mavlink_url, lambda t: self.scene.own.pose(t - self.t_start))
            self.autopilot.start()
        if s.radar:
            self._radar_model = Awr1843Model(self.scene, self.scene.radar_mount, seed=s.seed)
            self.radar = Awr1843Emulator(
                frame_source=self._radar_frame, link_dir=s.radar_link_dir, failing_lines=self.radar_failing_lines
            )
            self.radar.start()
        if s.lidar:
            self._sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
            t = threading.Thread(target=self._lidar_loop, name="sim-lidar", daemon=True)
            t.start()
            self._threads.append(t)

    def stop(self) -> None:
        self._stop.set()
        for t in self._threads:
            t.join(timeout=2.0)
        self._threads.clear()
        if self.radar is not None:
            self.radar.stop()
        if self.autopilot is not None:
            self.autopilot.stop()
        if self._sock is not None:
            self._sock.close()
            self._sock = None

    def __enter__(self) -> SimulationRun:
        self.start()
        return self

    def __exit__(self, *exc: object) -> None:
        self.stop()

    # ---- sensors -----------------------------------------------------------------------------------------------
    def _radar_frame(self, frame_number: int, host_t: float) -> DevicePoints:
        assert self._radar_model is not None
        d = self._radar_model.frame(self.sim_time(host_t), frame_number)
        return DevicePoints(d.xyz_ti, d.doppler, d.snr_db, d.noise_db)

    def _lidar_loop(self) -> None:
        model = Vlp16Model(self.scene, self.scene.lidar_mount, seed=self.settings.seed)
        dest = (self.settings.lidar_host, self.settings.lidar_port)
        pos_dest = (self.settings.lidar_host, self.settings.position_port)
        chunk = 0.05  # s of packets computed at once: vectorised ray casting, then paced sending
        t_sim = self.sim_time()
        next_position = t_sim
        assert self._sock is not None
        while not self._stop.is_set():
            for pkt in model.packets(t_sim, t_sim + chunk):
                delay = self.t_start + pkt.t - self.clock()
                if delay > 0 and self._stop.wait(delay):
                    return
                if self.lidar_paused.is_set():
                    continue
                payload = encode_data_packet(pkt.block_azimuth_cdeg, pkt.distance_m, pkt.reflectivity, pkt.timestamp_us)
                with contextlib.suppress(OSError):  # nobody listening yet: a real sensor does not care either
                    self._sock.sendto(payload, dest)
                    self.packets_sent += 1
                if pkt.t >= next_position:
                    with contextlib.suppress(OSError):
                        self._sock.sendto(encode_position_packet(pkt.timestamp_us), pos_dest)
                    next_position += 1.0
            t_sim += chunk


def run_simulator_cli(args: argparse.Namespace) -> int:
    """`usv-tracker simulate`: play the scenario over loopback for --seconds (or write captures with --write)."""
    if args.write:
        from simulator.capture import write_captures

        write_captures(args.scenario, Path(args.write), args.seconds, seed=args.seed)
        return 0
    settings = SimulationSettings(
        scenario=args.scenario, seed=args.seed, lidar_port=args.lidar_port, mavlink_url=args.mavlink
    )
    with SimulationRun(settings) as sim:
        log.info(
            "simulating %s: lidar %s, radar CLI %s data %s, autopilot %s (daemon: --mavlink %s)",
            args.scenario,
            sim.lidar_url,
            sim.radar_cli_url if sim.radar else "-",
            sim.radar_data_url if sim.radar else "-",
            settings.mavlink_url,
            sim.daemon_mavlink_url,
        )
        with contextlib.suppress(KeyboardInterrupt):
            time.sleep(args.seconds)
    return 0
