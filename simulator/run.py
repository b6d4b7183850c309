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
import time
from dataclasses import dataclass, field
from multiprocessing.synchronize import Event
from pathlib import Path

from simulator.autopilot import SimAutopilot
from simulator.awr1843_device import Awr1843Emulator, DevicePoints
from simulator.lidar_sender import LidarSenderProcess, SenderTarget
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
    scene: Scene | None = None  # a ready-made scene instead of the named scenario (tests build their own)
    radar_failing_lines: dict[str, int] | None = None  # cfg lines the emulated radar answers with "Error <n>"

    def __post_init__(self) -> None:
        if self.scene is None:
            self.scene = get_scenario(self.settings.scenario, seed=self.settings.seed)
        self.t_start = 0.0
        self.radar: Awr1843Emulator | None = None
        self.autopilot: SimAutopilot | None = None
        self._radar_model: Awr1843Model | None = None
        self._lidar: LidarSenderProcess | None = None

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
        return (time.monotonic() if host_t is None else host_t) - self.t_start

    # ---- lifecycle ---------------------------------------------------------------------------------------------
    def start(self) -> None:
        self.t_start = time.monotonic()  # system-wide, so the LiDAR's own process shares it
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
            assert self.scene is not None
            target = SenderTarget(s.lidar_host, s.lidar_port, s.position_port, s.seed, self.t_start)
            self._lidar = LidarSenderProcess(self.scene, target)
            self._lidar.start()

    def stop(self) -> None:
        if self._lidar is not None:
            self._lidar.stop()
        if self.radar is not None:
            self.radar.stop()
        if self.autopilot is not None:
            self.autopilot.stop()

    @property
    def lidar_paused(self) -> Event:
        """Set: the LiDAR's packets stop (a pulled cable); clear: they flow again."""
        assert self._lidar is not None, "the LiDAR is not simulated in this run"
        return self._lidar.paused

    @property
    def packets_sent(self) -> int:
        return self._lidar.packets_sent if self._lidar is not None else 0

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
