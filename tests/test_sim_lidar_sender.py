"""The simulated VLP-16 plays from a process of its own (as a real sensor is a machine of its own): its packets
reach a real UDP socket at the sensor's cadence, a pause stops them, and stopping it ends the process."""

from __future__ import annotations

import socket
import time

import pytest

from drivers.vlp16.packet import DATA_PACKET_SIZE, PACKETS_PER_S
from simulator.lidar_sender import LidarSenderProcess, SenderTarget
from simulator.scene import OwnBoat, Scene, Trajectory

# Real sockets and a child process in real time on a machine that may be busy: retried once.
pytestmark = pytest.mark.flaky(reruns=1)


def _count_for(sock: socket.socket, seconds: float) -> int:
    n, end = 0, time.monotonic() + seconds
    while time.monotonic() < end:
        try:
            data = sock.recv(2048)
        except TimeoutError:
            continue
        n += len(data) == DATA_PACKET_SIZE
    return n


def test_packets_flow_at_the_sensors_rate_pause_and_stop_with_the_process() -> None:
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as sock:
        sock.bind(("127.0.0.1", 0))
        sock.settimeout(0.05)
        port = sock.getsockname()[1]
        scene = Scene("empty", OwnBoat(Trajectory.stationary((0.0, 0.0), 0.0)), [], [], duration=60.0)
        sender = LidarSenderProcess(scene, SenderTarget("127.0.0.1", port, 9, 0, time.monotonic()))
        sender.start()
        try:
            assert _count_for(sock, 3.0) > 0  # the child is up (spawning it takes about a second)
            n = _count_for(sock, 2.0)
            # Two seconds of a 754 packets/s stream; the bounds hold a half-second stall of a busy machine either way
            # (the sender catches up on its clock, so a stall before the window puts its backlog inside it).
            assert 1.5 * PACKETS_PER_S <= n <= 2.5 * PACKETS_PER_S
            sender.paused.set()
            _count_for(sock, 0.3)  # what was already in flight
            assert _count_for(sock, 0.5) == 0
            sender.paused.clear()
            assert _count_for(sock, 1.0) > 0.5 * PACKETS_PER_S
            assert sender.packets_sent > n
        finally:
            sender.stop()
        assert not sender.is_alive()
