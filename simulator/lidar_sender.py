"""The simulated VLP-16's sender, in a process of its own.

Ray casting a revolution and packing 754 packets a second is about a quarter of a core here. A real sensor is a
machine of its own, so this one is a process of its own: its work never takes the daemon's interpreter lock, and
the demo's and the end-to-end tests' daemon meets a sensor as it would on the boat (in paired demo runs the cycle
moved within the machine's noise: docs/measured.md, "The demo's cycle").
"""

from __future__ import annotations

import contextlib
import ctypes
import multiprocessing as mp
import os
import signal
import socket
import time
from dataclasses import dataclass
from multiprocessing.synchronize import Event

from drivers.vlp16.packet import encode_data_packet, encode_position_packet
from simulator.lidar_model import Vlp16Model
from simulator.scene import Scene

CHUNK_S = 0.05  # s of packets ray-cast at once: vectorised casting, then paced sending


@dataclass(frozen=True)
class SenderTarget:
    host: str
    data_port: int
    position_port: int
    seed: int
    t_start: float  # time.monotonic() at the simulation's t = 0 (the clock is system-wide, so shared)


class LidarSenderProcess:
    """Start with ``start()``, stop with ``stop()``; ``paused`` drops packets while set (a cable pulled),
    ``packets_sent`` counts what went out."""

    def __init__(self, scene: Scene, target: SenderTarget) -> None:
        ctx = mp.get_context("spawn")  # never fork a process whose other threads hold locks
        self.paused = ctx.Event()
        self._stop = ctx.Event()
        self._sent = ctx.Value("q", 0, lock=False)  # a bare shared c_longlong: only the child writes it
        self._proc = ctx.Process(
            target=play_lidar,
            args=(scene, target, self._stop, self.paused, self._sent, os.getpid()),
            name="sim-lidar",
            daemon=True,
        )

    @property
    def packets_sent(self) -> int:
        return int(self._sent.value)

    def start(self) -> None:
        self._proc.start()

    def is_alive(self) -> bool:
        return self._proc.is_alive()

    def stop(self) -> None:
        self._stop.set()
        self._proc.join(timeout=3.0)
        if self._proc.is_alive():
            self._proc.kill()
            self._proc.join(timeout=1.0)


def play_lidar(
    scene: Scene, target: SenderTarget, stop: Event, paused: Event, sent: ctypes.c_longlong, parent_pid: int
) -> None:
    """The child's whole life: packets at the sensor's cadence on the shared clock until told to stop or orphaned."""
    signal.signal(signal.SIGINT, signal.SIG_IGN)  # Ctrl-C is the parent's to handle; it stops us through `stop`
    model = Vlp16Model(scene, scene.lidar_mount, seed=target.seed)
    dest = (target.host, target.data_port)
    pos_dest = (target.host, target.position_port)
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as sock:
        t_sim = time.monotonic() - target.t_start
        next_position = t_sim
        while not stop.is_set() and os.getppid() == parent_pid:
            for pkt in model.packets(t_sim, t_sim + CHUNK_S):
                delay = target.t_start + pkt.t - time.monotonic()
                if delay > 0 and stop.wait(delay):
                    return
                if paused.is_set():
                    continue
                payload = encode_data_packet(pkt.block_azimuth_cdeg, pkt.distance_m, pkt.reflectivity, pkt.timestamp_us)
                with contextlib.suppress(OSError):  # nobody listening yet: a real sensor does not care either
                    sock.sendto(payload, dest)
                    sent.value += 1
                if pkt.t >= next_position:
                    with contextlib.suppress(OSError):
                        sock.sendto(encode_position_packet(pkt.timestamp_us), pos_dest)
                    next_position += 1.0
            t_sim += CHUNK_S
