"""Consecutive simulator scenes played live over loopback, for runs longer than one scene (the soak).

Scene k plays over [k * S, (k + 1) * S) of simulation time on its own clock from 0, as `usv-tracker simulate` would
play it alone. The three feeds are the simulator's own parts (simulator/run.py), switched from scene to scene:
  * VLP-16: 1206-byte UDP packets at the sensor's cadence from one socket (one sender address for the whole run, as a
    sensor's), the sensor clock running on across scenes (each scene's model starts its device clock at k * S), and
    S a whole number of revolutions so the rotor angle runs on too: what changes at a switch is the world, not the
    sensor;
  * AWR1843: the device emulator on two ptys, each frame drawn from the scene of its time;
  * autopilot: SimAutopilot streaming the own boat's pose of the scene of its time. Each scene starts its own boat at
    the origin, so the pose jumps at a switch: the daemon sees tracks vanish and a new harbour appear.
"""

from __future__ import annotations

import contextlib
import socket
import threading
import time
from collections.abc import Callable
from typing import Any

from drivers.vlp16.packet import encode_data_packet, encode_position_packet
from simulator.autopilot import SimAutopilot
from simulator.awr1843_device import Awr1843Emulator, DevicePoints
from simulator.lidar_model import Vlp16Model
from simulator.radar_model import Awr1843Model
from simulator.run import RADAR_PROFILE
from simulator.scenarios import get_scenario
from simulator.scene import Scene

CHUNK_S = 0.05  # s of packets ray-cast at once (vectorised), then sent at their times


class SceneChain:
    """Scenes ``names`` each played for ``seconds``; ``at(t)`` says which one is on at simulation time t."""

    def __init__(self, names: list[str], seconds: float, sensor_seed: int = 0) -> None:
        revolutions = seconds * 10.0
        if abs(revolutions - round(revolutions)) > 1e-9:
            raise ValueError(f"scene length must be a whole number of 0.1 s revolutions, not {seconds}")
        self.names = names
        self.seconds = seconds
        self.scenes: list[Scene] = [get_scenario(n, seed=sensor_seed) for n in names]
        self.sensor_seed = sensor_seed
        self._radar: dict[int, Awr1843Model] = {}
        self._lock = threading.Lock()

    @property
    def duration(self) -> float:
        return self.seconds * len(self.scenes)

    def at(self, t: float) -> tuple[int, float]:
        """(scene index, time within it) at simulation time ``t``; past the end, the last scene runs on."""
        k = min(max(int(t // self.seconds), 0), len(self.scenes) - 1)
        return k, t - k * self.seconds

    def own_pose(self, t: float) -> Any:
        k, local = self.at(t)
        return self.scenes[k].own.pose(local)

    def lidar_model(self, k: int) -> Vlp16Model:
        scene = self.scenes[k]
        return Vlp16Model(scene, scene.lidar_mount, seed=self.sensor_seed + k, device_clock_offset_s=k * self.seconds)

    def radar_model(self, k: int) -> Awr1843Model:
        with self._lock:  # the emulator's thread asks; drop the model of the scene before, it is done
            if k not in self._radar:
                scene = self.scenes[k]
                self._radar = {k: Awr1843Model(scene, scene.radar_mount, seed=self.sensor_seed + k)}
            return self._radar[k]


class ChainSimulation:
    """The chain played over loopback: ``start()``, point the daemon at the URLs, ``stop()``."""

    def __init__(
        self,
        chain: SceneChain,
        lidar_port: int,
        position_port: int,
        mavlink_port: int,
        clock: Callable[[], float] = time.monotonic,
    ) -> None:
        self.chain = chain
        self.lidar_port = lidar_port
        self.position_port = position_port
        self.mavlink_port = mavlink_port
        self.clock = clock
        self.t_start = 0.0
        self.packets_sent = 0
        self.radar: Awr1843Emulator | None = None
        self.autopilot: SimAutopilot | None = None
        self._sock: socket.socket | None = None
        self._stop = threading.Event()
        self._thread: threading.Thread | None = None

    # URLs for `usv-tracker run`
    @property
    def lidar_url(self) -> str:
        return f"udp://127.0.0.1:{self.lidar_port}"

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
        return f"udpout:127.0.0.1:{self.mavlink_port}"

    radar_profile = str(RADAR_PROFILE)

    def sim_time(self, host_t: float | None = None) -> float:
        return (self.clock() if host_t is None else host_t) - self.t_start

    def start(self) -> None:
        self.t_start = self.clock()
        self.autopilot = SimAutopilot(
            f"udpin:127.0.0.1:{self.mavlink_port}", lambda t: self.chain.own_pose(t - self.t_start)
        )
        self.autopilot.start()
        self.radar = Awr1843Emulator(frame_source=self._radar_frame)
        self.radar.start()
        self._sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        self._thread = threading.Thread(target=self._lidar_loop, name="chain-lidar", daemon=True)
        self._thread.start()

    def stop(self) -> None:
        self._stop.set()
        if self._thread is not None:
            self._thread.join(timeout=2.0)
        if self.radar is not None:
            self.radar.stop()
        if self.autopilot is not None:
            self.autopilot.stop()
        if self._sock is not None:
            self._sock.close()

    def __enter__(self) -> ChainSimulation:
        self.start()
        return self

    def __exit__(self, *exc: object) -> None:
        self.stop()

    def scene_now(self) -> int:
        return self.chain.at(self.sim_time())[0]

    def _radar_frame(self, frame_number: int, host_t: float) -> DevicePoints:
        k, local = self.chain.at(self.sim_time(host_t))
        d = self.chain.radar_model(k).frame(local, frame_number)
        return DevicePoints(d.xyz_ti, d.doppler, d.snr_db, d.noise_db)

    def _lidar_loop(self) -> None:
        dest = ("127.0.0.1", self.lidar_port)
        pos_dest = ("127.0.0.1", self.position_port)
        k_model, model = -1, None
        t_sim = self.sim_time()
        next_position = t_sim
        assert self._sock is not None
        while not self._stop.is_set():
            k, local = self.chain.at(t_sim)
            if k != k_model:
                k_model, model = k, self.chain.lidar_model(k)
            assert model is not None
            # a chunk never spans a switch: it ends at the scene's end at the latest
            local_end = min(local + CHUNK_S, self.chain.seconds) if k < len(self.chain.scenes) - 1 else local + CHUNK_S
            base = k * self.chain.seconds
            for pkt in model.packets(local, local_end):
                delay = self.t_start + base + pkt.t - self.clock()
                if delay > 0 and self._stop.wait(delay):
                    return
                payload = encode_data_packet(pkt.block_azimuth_cdeg, pkt.distance_m, pkt.reflectivity, pkt.timestamp_us)
                with contextlib.suppress(OSError):  # nobody listening yet: a real sensor does not care either
                    self._sock.sendto(payload, dest)
                    self.packets_sent += 1
                if base + pkt.t >= next_position:
                    with contextlib.suppress(OSError):
                        self._sock.sendto(encode_position_packet(pkt.timestamp_us), pos_dest)
                    next_position += 1.0
            t_sim = base + local_end
