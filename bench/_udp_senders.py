"""Sender processes for bench/load.py: a VLP-16 capture replayed at a speed factor, and junk datagrams.

Each runs in its own process (multiprocessing, spawn), so that neither shares an interpreter lock with the daemon or
with the other, and puts its counts on a queue when done. Sending is paced on an absolute schedule: whatever is due
is sent at once, so a sender descheduled for a moment catches up in a burst (as a switch's buffer would deliver)
instead of stretching the run.
"""

from __future__ import annotations

import socket
import time
from typing import Any

import numpy as np

from drivers.vlp16.packet import DATA_PORT, POSITION_PORT
from drivers.vlp16.pcap import PcapReader


def replay_capture(
    path: str, data_port: int, position_port: int, speed: float, start_at: float, results: Any, host: str = "127.0.0.1"
) -> None:
    """Send the capture's VLP-16 data and position packets to ``host`` at ``speed`` times their recorded pace, from
    one socket (one sender address, as a sensor), starting at monotonic time ``start_at``."""
    datagrams = [(d.timestamp_s, d.dst_port, d.payload) for d in PcapReader(path, {DATA_PORT, POSITION_PORT})]
    t0 = datagrams[0][0]
    sent = {"data": 0, "position": 0}
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as sock:
        sock.bind((host, 0))
        _wait_until(start_at)
        begin, begin_wall = time.monotonic(), time.time()
        for t, port, payload in datagrams:
            _wait_until(begin + (t - t0) / speed)
            if port == DATA_PORT:
                sock.sendto(payload, (host, data_port))
                sent["data"] += 1
            else:
                sock.sendto(payload, (host, position_port))
                sent["position"] += 1
        end = time.monotonic()
        results.put(
            {
                "lidar": {
                    **sent,
                    "sender": f"{host}:{sock.getsockname()[1]}",
                    "begin": begin,
                    "end": end,
                    "begin_wall": begin_wall,
                    "end_wall": time.time(),
                }
            }
        )


def send_junk(
    data_port: int,
    rate_hz: float,
    seconds: float,
    start_at: float,
    results: Any,
    seed: int = 0,
    host: str = "127.0.0.1",
) -> None:
    """Random datagrams (random bytes; sizes 1-1500, one in ten exactly a VLP-16 packet's 1206) to the data port,
    alternately from 127.0.0.2 (another host) and from another port of ``host`` (the sensor's own address)."""
    rng = np.random.default_rng(seed)
    n = int(rate_hz * seconds)
    sizes = np.where(rng.random(n) < 0.1, 1206, rng.integers(1, 1501, n))
    socks = [socket.socket(socket.AF_INET, socket.SOCK_DGRAM) for _ in range(2)]
    socks[0].bind(("127.0.0.2", 0))
    socks[1].bind((host, 0))
    sent = [0, 0]
    try:
        _wait_until(start_at)
        begin = time.monotonic()
        for k, size in enumerate(sizes):
            _wait_until(begin + k / rate_hz)
            socks[k % 2].sendto(rng.bytes(int(size)), (host, data_port))
            sent[k % 2] += 1
        end = time.monotonic()
        senders = [f"{s.getsockname()[0]}:{s.getsockname()[1]}" for s in socks]
    finally:
        for s in socks:
            s.close()
    results.put(
        {"junk": {"sent": sum(sent), "per_sender": dict(zip(senders, sent, strict=True)), "begin": begin, "end": end}}
    )


def _wait_until(t: float) -> None:
    delay = t - time.monotonic()
    if delay > 0:
        time.sleep(delay)
