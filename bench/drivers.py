"""Driver throughput: the VLP-16 path (UDP socket -> revolutions in the body frame) and the radar data parser.

    python bench/drivers.py            # about 20 s

Figures:
  * VLP-16 decode throughput: packets/s through the ScanAssembler (velodyne-decoder + body-frame conversion), with
    every firing returning (the own boat inside a 5 m ring wall: ~28.9k points per revolution, the worst case).
  * VLP-16 live CPU share: a second process sends the simulator's packets to 127.0.0.1 at the sensor's 753.5 packets/s;
    the reader's thread CPU time over wall time is the share of one core the LiDAR path costs on the boat.
  * Radar: frames/s through RadarFrameParser.feed for a stream of 30-point frames (TLVs 1, 7, 6, 9).
"""

from __future__ import annotations

import multiprocessing as mp
import socket
import sys
import threading
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent.parent))

from bench._common import no_options, save
from bench.cycle import ring_scene
from drivers.awr1843.parser import RadarFrameParser, encode_frame
from drivers.vlp16.decoder import ScanAssembler
from drivers.vlp16.packet import PACKET_PERIOD_US, PACKETS_PER_S, encode_data_packet
from drivers.vlp16.udp_source import VelodyneUdpSource
from simulator.lidar_model import Vlp16Model

SENSOR_RATE = PACKETS_PER_S


def simulated_packets(seconds: float) -> list[bytes]:
    """The worst case for the decoder: the own boat inside a 5 m ring wall, so every firing returns."""
    scene = ring_scene()
    model = Vlp16Model(scene, scene.lidar_mount, seed=1)
    return [
        encode_data_packet(p.block_azimuth_cdeg, p.distance_m, p.reflectivity, p.timestamp_us)
        for p in model.packets(5.0, 5.0 + seconds)
    ]


def decode_throughput(packets: list[bytes], repeats: int = 3) -> tuple[float, int]:
    best = 0.0
    points = 0
    for _ in range(repeats):
        asm = ScanAssembler()
        points = 0
        t0 = time.perf_counter()
        for k, p in enumerate(packets):
            for scan in asm.push(k * PACKET_PERIOD_US * 1e-6, p):
                points += scan.n_points
        best = max(best, len(packets) / (time.perf_counter() - t0))
    return best, points


def _sender(port: int, packets: list[bytes], rate: float) -> None:
    sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    t0 = time.perf_counter()
    for k, p in enumerate(packets):
        delay = t0 + k / rate - time.perf_counter()
        if delay > 0:
            time.sleep(delay)
        sock.sendto(p, ("127.0.0.1", port))
    sock.close()


def live_cpu_share(packets: list[bytes]) -> dict[str, float]:
    src = VelodyneUdpSource(host="127.0.0.1", port=0, position_port=None)
    src.open()
    stop = threading.Event()
    sender = mp.get_context("spawn").Process(target=_sender, args=(src.bound_port, packets, SENSOR_RATE))
    scans = 0
    cpu0 = time.thread_time()
    wall0 = time.perf_counter()
    sender.start()
    deadline = wall0 + len(packets) / SENSOR_RATE + 3.0
    for _scan in src.scans(stop):
        scans += 1
        if src.stats.packets >= len(packets) or time.perf_counter() > deadline:
            break
    wall = time.perf_counter() - wall0
    cpu = time.thread_time() - cpu0
    sender.join()
    src.close()
    return {
        "packets_sent": len(packets),
        "packets_received": src.stats.packets,
        "scans": scans,
        "wall_s": wall,
        "cpu_s": cpu,
        "cpu_share_one_core_pct": 100.0 * cpu / wall,
    }


def radar_throughput(n_frames: int = 3000) -> float:
    rng = np.random.default_rng(0)
    frames = []
    for k in range(n_frames):
        xyz = np.column_stack([rng.uniform(-20, 20, 30), rng.uniform(1, 50, 30), np.zeros(30)])
        frames.append(
            encode_frame(
                k + 1,
                xyz,
                rng.uniform(-5, 5, 30),
                rng.uniform(15, 40, 30),
                rng.uniform(60, 90, 30),
                stats=(1, 2, 3, 4, 5, 6),
                temperature=[0, 1000] + [40.0] * 10,
            )
        )
    stream = b"".join(frames)
    chunks = [stream[i : i + 4096] for i in range(0, len(stream), 4096)]  # like 4 kB UART reads
    best = 0.0
    for _ in range(3):
        parser = RadarFrameParser()
        got = 0
        t0 = time.perf_counter()
        for c in chunks:
            got += len(parser.feed(c, 0.0))
        best = max(best, got / (time.perf_counter() - t0))
    return best


def main() -> None:
    no_options(__doc__)
    packets = simulated_packets(10.0)
    pps, points = decode_throughput(packets)
    print(
        f"VLP-16 decode: {pps:,.0f} packets/s ({pps / SENSOR_RATE:.1f}x the sensor's {SENSOR_RATE:.1f}/s); "
        f"{points / len(packets) * SENSOR_RATE:,.0f} points/s at the sensor's rate in this scene"
    )
    live = live_cpu_share(packets)
    print(
        f"VLP-16 live UDP at the sensor's rate: {live['packets_received']}/{live['packets_sent']} packets, "
        f"{live['scans']} revolutions, reader CPU {live['cpu_share_one_core_pct']:.1f} % of one core"
    )
    fps = radar_throughput()
    print(f"AWR1843 parser: {fps:,.0f} frames/s (30 points, TLVs 1/7/6/9) = {fps / 10:,.0f}x the radar's 10 Hz")
    md = "\n".join(
        [
            "| figure | value |",
            "|---|---|",
            f"| VLP-16 decode throughput | {pps:,.0f} packets/s ({pps / SENSOR_RATE:.1f}x the sensor's 753.5/s) |",
            f"| VLP-16 live path CPU at the sensor's rate | {live['cpu_share_one_core_pct']:.1f} % of one core "
            f"({live['packets_received']}/{live['packets_sent']} packets received) |",
            f"| AWR1843 frames parsed | {fps:,.0f} frames/s (30-point frames) |",
        ]
    )
    save("drivers", {"vlp16_decode_pps": pps, "vlp16_live": live, "radar_fps": fps}, md)


if __name__ == "__main__":
    main()
