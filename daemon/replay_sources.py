"""The streams a replay is fed from: LiDAR revolutions from a pcap, radar frames from a data-port dump, poses from a
MAVLink .tlog, each in its recorded order with its recorded stamps.

By default the tick loop pulls each item out of its decoder itself. With ``prefetch`` every stream runs through
``Prefetch`` instead, a producer thread that decodes ahead while the tracker ticks; bench/replay_speed.py measured
that slower on every run (fused 5.1x against 5.6x real time at stop 39, 6.9x against 8.4x at stop 37): the decoder
threads hold the interpreter lock the tracker then waits for.
"""

from __future__ import annotations

import logging
import math
from collections.abc import Iterator
from pathlib import Path
from typing import Any, Generic, TypeVar

import numpy as np

from daemon.config import Config
from daemon.prefetch import Prefetch
from daemon.source_url import parse_source_url
from drivers.frames import LidarScan, RadarFrame

log = logging.getLogger(__name__)

T = TypeVar("T")

# How far each producer may run ahead: a revolution is ~1 MB, a radar frame and a pose message are small. Enough
# for a second of data, so that a slow tick is absorbed without the decoders stopping.
LIDAR_AHEAD = 10
RADAR_AHEAD = 32
POSES_AHEAD = 256
POSE_TYPES = ("ATTITUDE", "LOCAL_POSITION_NED", "GLOBAL_POSITION_INT")


class Peekable(Generic[T]):
    def __init__(self, it: Iterator[T]) -> None:
        self._it = it
        self._next: T | None = None
        self.done = False
        self._advance()

    def _advance(self) -> None:
        try:
            self._next = next(self._it)
        except StopIteration:
            self._next = None
            self.done = True

    def peek(self) -> T | None:
        return self._next

    def pop(self) -> T:
        item = self._next
        assert item is not None
        self._advance()
        return item


def _ahead(name: str, it: Iterator[T], maxsize: int, prefetch: bool) -> Iterator[T]:
    return Prefetch(name, it, maxsize) if prefetch else it


def lidar_scans(config: Config, prefetch: bool = False) -> Iterator[LidarScan] | None:
    if not config.lidar.enabled:
        return None
    from daemon.runner import build_lidar_source

    src, url = build_lidar_source(config, fast=True)
    if url.scheme != "pcap":
        raise ValueError(f"replay needs a pcap:// LiDAR source, not {url.text} (live and recorded sources cannot mix)")
    return _ahead("lidar", src.scans(None), LIDAR_AHEAD, prefetch)


def radar_frames(config: Config, start_time: float | None, prefetch: bool = False) -> Iterator[RadarFrame] | None:
    """``start_time``: where frames of a dump without a ``.times`` sidecar begin (the LiDAR's first revolution)."""
    if not config.radar.enabled:
        return None
    url = parse_source_url(config.radar.data)
    if url.scheme != "file":
        raise ValueError(f"replay needs a file:// radar source, not {url.text} (live and recorded sources cannot mix)")
    from daemon.runner import expected_radar_stream
    from drivers.awr1843.parser import RadarFrameParser
    from drivers.awr1843.profile import load_profile
    from drivers.awr1843.sources import QUIET_READ_S
    from drivers.awr1843.timed_capture import read_sidecar, timed_chunks

    profile = (
        load_profile(config.radar.profile) if config.radar.profile and Path(config.radar.profile).exists() else None
    )
    mount = config.radar.mount.to_mount()
    expected = expected_radar_stream(config, profile)  # the live run rejected the same frames
    if read_sidecar(url.path) is not None:
        parser = RadarFrameParser(profile, mount, expected=expected)

        def gen() -> Iterator[RadarFrame]:
            prev = -math.inf
            for chunk, t in timed_chunks(url.path):
                if t - prev > QUIET_READ_S:  # the live reader's read went quiet before this chunk came
                    yield from parser.idle(prev + QUIET_READ_S)
                yield from parser.feed(chunk, t)
                prev = t
            yield from parser.finish(math.inf)

        return _ahead("radar", gen(), RADAR_AHEAD, prefetch)
    from drivers.awr1843.sources import FileRadarSource

    log.info(
        "%s has no .times sidecar: frames paced by the frame period from %s",
        url.path,
        "the LiDAR's first revolution" if start_time is not None else "t = 0 s",
    )
    frames = FileRadarSource(
        url.path, profile, mount, expected=expected, speed=None, start_time=start_time or 0.0
    ).frames(_NeverStop())
    return _ahead("radar", frames, RADAR_AHEAD, prefetch)


class _NeverStop:
    def is_set(self) -> bool:
        return False

    def wait(self, timeout: float | None = None) -> bool:
        return False


def tlog_messages(path: str, prefetch: bool = False) -> Iterator[Any]:
    """The pose messages of a .tlog in file order, each with its recorded time in ``_timestamp``."""

    def gen() -> Iterator[Any]:
        from daemon.mavlink_env import mavutil

        conn = mavutil.mavlink_connection(path, dialect="ardupilotmega")
        try:
            while True:
                msg = conn.recv_match(type=list(POSE_TYPES))
                if msg is None:
                    return
                yield msg
        finally:
            conn.close()

    return _ahead("poses", gen(), POSES_AHEAD, prefetch)


def feed_pose(assembler: Any, msg: Any) -> None:
    """One recorded pose message into a PoseAssembler, stamped with its recorded time."""
    t = float(msg._timestamp)
    kind = msg.get_type()
    if kind == "ATTITUDE":
        assembler.on_attitude(t, msg.roll, msg.pitch, msg.yaw, msg.rollspeed, msg.pitchspeed, msg.yawspeed)
    elif kind == "LOCAL_POSITION_NED":
        assembler.on_local_position(t, np.array([msg.x, msg.y, msg.z]), np.array([msg.vx, msg.vy, msg.vz]))
    elif kind == "GLOBAL_POSITION_INT":
        vel = np.array([msg.vx, msg.vy, msg.vz]) * 0.01
        assembler.on_global_position(t, msg.lat * 1e-7, msg.lon * 1e-7, msg.alt * 1e-3, vel)


def close_stream(it: object) -> None:
    close = getattr(it, "close", None)
    if close is not None:
        close()
