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

from drivers.vlp16.packet import (
    DATA_PACKET_DTYPE,
    DATA_PORT,
    MICROSECONDS_PER_HOUR,
    POSITION_PACKET_DTYPE,
    POSITION_PORT,
)
from drivers.vlp16.pcap import PcapReader


def replay_capture(
    path: str,
    data_port: int,
    position_port: int,
    speed: float,
    start_at: float,
    results: Any,
    host: str = "127.0.0.1",
    seconds: float | None = None,
) -> None:
    """Send the capture's VLP-16 data and position packets to ``host`` at ``speed`` times their recorded pace, from
    one socket (one sender address, as a sensor), starting at monotonic time ``start_at``. ``seconds``: play the
    capture over again until this many seconds have been sent (None: once); each pass carries the device clock on
    (``_restamped``), so the sensor looks like one that kept running, not one whose clock jumped back."""
    datagrams = [(d.timestamp_s, d.dst_port, d.payload) for d in PcapReader(path, {DATA_PORT, POSITION_PORT})]
    t0 = datagrams[0][0]
    # One pass lasts the capture plus one packet period, so the next pass's first packet follows on time.
    span = datagrams[-1][0] - t0 + (datagrams[-1][0] - datagrams[-2][0] if len(datagrams) > 1 else 0.0)
    passes = 1 if seconds is None else max(1, int(np.ceil(seconds * speed / span)))
    sent = {"data": 0, "position": 0}
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as sock:
        sock.bind((host, 0))
        _wait_until(start_at)
        begin, begin_wall = time.monotonic(), time.time()
        for k in range(passes):
            for t, port, payload in datagrams:
                offset = k * span + (t - t0)
                if seconds is not None and offset > seconds * speed:
                    break
                _wait_until(begin + offset / speed)
                if k:
                    payload = _restamped(payload, port, round(k * span * 1e6))
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


def _restamped(payload: bytes, port: int, shift_us: int) -> bytes:
    """The packet with its device timestamp (microseconds past the hour) moved on by ``shift_us``."""
    dtype = DATA_PACKET_DTYPE if port == DATA_PORT else POSITION_PACKET_DTYPE
    offset = dtype.fields["timestamp"][1]
    stamp = int.from_bytes(payload[offset : offset + 4], "little")
    new = ((stamp + shift_us) % MICROSECONDS_PER_HOUR).to_bytes(4, "little")
    return payload[:offset] + new + payload[offset + 4 :]


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
