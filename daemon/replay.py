"""Replay of recorded captures through the same pipeline and loop as live, on the data's own clock.

Sources: a VLP-16 pcap (`pcap://`), a radar data-port dump (`file://`, with its `.times` sidecar when the project
recorded it, else paced by the cfg's frame period from the LiDAR's start), and the autopilot's poses from a
MAVLink `.tlog` (`--mavlink run.tlog`). Ticks are placed every 1/rate s of DATA time and fed exactly the items
stamped before them, so the output does not depend on the CPU: `--fast` runs as fast as it can, without it the
replay keeps real-time pace for watching.
"""

from __future__ import annotations

import logging
import math
import time
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Generic, TypeVar

from daemon.buffers import BoundedQueue, LatestSlot
from daemon.config import Config
from daemon.ego import HistoryEgo
from daemon.loop import DaemonLoop, LoopSettings, SensorInputs
from daemon.pose_history import PoseHistory
from daemon.runner import pipeline_for, sensors_off
from daemon.source_url import parse_source_url
from drivers.frames import LidarScan, RadarFrame

log = logging.getLogger(__name__)

T = TypeVar("T")


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


@dataclass
class ReplaySummary:
    ticks: int = 0
    scans: int = 0
    radar_frames: int = 0
    poses: int = 0
    data_seconds: float = 0.0
    wall_seconds: float = 0.0


def recording_config(directory: str | Path, tracks_out: str | Path, lidar: bool = True, radar: bool = True) -> Config:
    """The config that replays a recording directory (`run --record DIR` or `simulate --write DIR`: lidar.pcap,
    radar.dat, radar.cfg, autopilot.tlog, and usv-tracker.toml with the mounts when the simulator wrote one) with
    the chosen sensors, writing ``tracks_out``."""
    from daemon.config import load_config

    d = Path(directory)
    toml = d / "usv-tracker.toml"
    return load_config(
        toml if toml.is_file() else None,
        {
            "lidar.enabled": lidar,
            "radar.enabled": radar,
            "lidar.source": f"pcap://{d / 'lidar.pcap'}",
            "radar.data": f"file://{d / 'radar.dat'}",
            "radar.cli": "",
            "radar.profile": str(d / "radar.cfg"),
            "mavlink.url": str(d / "autopilot.tlog"),
            "output.tracks_out": str(tracks_out),
        },
    )


def is_replay(config: Config) -> bool:
    schemes = []
    if config.lidar.enabled:
        schemes.append(parse_source_url(config.lidar.source).scheme)
    if config.radar.enabled:
        schemes.append(parse_source_url(config.radar.data).scheme)
    return any(s in ("pcap", "file") for s in schemes) or config.mavlink.url.endswith(".tlog")


def _lidar_scans(config: Config) -> Iterator[LidarScan] | None:
    if not config.lidar.enabled:
        return None
    from daemon.runner import build_lidar_source

    src, url = build_lidar_source(config, fast=True)
    if url.scheme != "pcap":
        raise ValueError(f"replay needs a pcap:// LiDAR source, not {url.text} (live and recorded sources cannot mix)")
    return src.scans(None)


def _radar_frames(config: Config, start_time: float | None) -> Iterator[RadarFrame] | None:
    if not config.radar.enabled:
        return None
    url = parse_source_url(config.radar.data)
    if url.scheme != "file":
        raise ValueError(f"replay needs a file:// radar source, not {url.text} (live and recorded sources cannot mix)")
    from drivers.awr1843.parser import RadarFrameParser
    from drivers.awr1843.profile import load_profile
    from drivers.awr1843.timed_capture import read_sidecar, timed_chunks

    profile = (
        load_profile(config.radar.profile) if config.radar.profile and Path(config.radar.profile).exists() else None
    )
    mount = config.radar.mount.to_mount()
    from daemon.runner import expected_radar_stream

    expected = expected_radar_stream(config, profile)  # the live run rejected the same frames
    if read_sidecar(url.path) is not None:
        parser = RadarFrameParser(profile, mount, expected=expected)

        def gen() -> Iterator[RadarFrame]:
            for chunk, t in timed_chunks(url.path):
                yield from parser.feed(chunk, t)
            yield from parser.finish(math.inf)

        return gen()
    from drivers.awr1843.sources import FileRadarSource

    log.info("%s has no .times sidecar: frames paced by the frame period from t = %s", url.path, start_time)
    return FileRadarSource(
        url.path, profile, mount, expected=expected, speed=None, start_time=start_time or 0.0
    ).frames(_NeverStop())


class _NeverStop:
    def is_set(self) -> bool:
        return False

    def wait(self, timeout: float | None = None) -> bool:
        return False


def _tlog_messages(path: str) -> Iterator[Any]:
    from daemon.mavlink_env import mavutil

    conn = mavutil.mavlink_connection(path, dialect="ardupilotmega")
    try:
        while True:
            msg = conn.recv_match(type=["ATTITUDE", "LOCAL_POSITION_NED", "GLOBAL_POSITION_INT"])
            if msg is None:
                return
            yield msg
    finally:
        conn.close()


def run_replay(config: Config, duration_s: float | None = None, fast: bool = True) -> int:
    from daemon.autopilot_pose import PoseAssembler

    sensors_off(config)
    lidar_it = _lidar_scans(config)
    lidar = Peekable(lidar_it) if lidar_it is not None else None
    first_lidar = lidar.peek().stamp if lidar is not None and lidar.peek() is not None else None
    radar_it = _radar_frames(config, first_lidar)
    radar = Peekable(radar_it) if radar_it is not None else None
    poses: HistoryEgo | None = None
    pose_msgs: Peekable[Any] | None = None
    assembler = None
    if config.mavlink.url.endswith(".tlog"):
        history = PoseHistory(capacity=100_000)
        assembler = PoseAssembler(history)
        poses = HistoryEgo(history, lambda: assembler.world_epoch)
        pose_msgs = Peekable(_tlog_messages(config.mavlink.url))
    else:
        log.info("replay without a .tlog: no ego pose, the boat frame at the start is the world frame")

    starts = [p.peek().stamp for p in (lidar, radar) if p is not None and p.peek() is not None]  # type: ignore[union-attr]
    if not starts:
        log.error("replay: the captures hold no LiDAR revolution and no radar frame")
        return 2
    period = 1.0 / config.output.rate_hz
    # Ticks fall halfway between revolutions, as the live loop's phase lock puts them: a tick grid started by the
    # radar's first frame could sit on the revolutions' arrivals, and jitter then gives one interval two of them
    # (the older dropped) and the next none - a fused replay tracked worse than a LiDAR-only one of the same data.
    t0 = min(starts)
    if first_lidar is not None:  # the LiDAR's phase, from no later than the first item of either sensor
        t0 = first_lidar - period / 2 - math.ceil(max(first_lidar - period / 2 - t0, 0.0) / period) * period
    inputs = SensorInputs(LatestSlot[LidarScan](), BoundedQueue[RadarFrame](10_000))
    o = config.output
    tracks_file = open(o.tracks_out, "w", encoding="utf-8") if o.tracks_out else None  # noqa: SIM115
    loop = DaemonLoop(
        pipeline_for(config),
        inputs,
        None,
        poses,
        LoopSettings(
            o.rate_hz,
            o.min_distance_m,
            o.max_distance_m,
            o.no_data_timeout_s,
            o.health_interval_s,
            lidar_expected=config.lidar.enabled,
            radar_expected=config.radar.enabled,
        ),
        tracks_out=tracks_file,
        clock=lambda: t_now,
    )
    if assembler is not None:
        loop.world_to_geodetic = assembler.world_to_geodetic
    summary = ReplaySummary()
    wall0 = time.monotonic()
    k = 0
    try:
        while True:
            k += 1
            t_now = t0 + k * period
            if duration_s is not None and t_now - t0 > duration_s:
                break
            if pose_msgs is not None and assembler is not None:
                while (m := pose_msgs.peek()) is not None and m._timestamp <= t_now + 0.2:
                    _feed_pose(assembler, pose_msgs.pop())
                    summary.poses += 1
            if lidar is not None:
                while (s := lidar.peek()) is not None and s.stamp <= t_now:
                    inputs.lidar.put(lidar.pop(), t_now)
                    summary.scans += 1
            if radar is not None:
                while (f := radar.peek()) is not None and f.stamp <= t_now:
                    inputs.radar.put(radar.pop(), t_now)
                    summary.radar_frames += 1
            if not fast:
                delay = (t_now - t0) - (time.monotonic() - wall0)
                if delay > 0:
                    time.sleep(delay)
            loop.tick(t_now)
            summary.ticks += 1
            if all(p is None or p.done for p in (lidar, radar)):
                break
    except KeyboardInterrupt:
        log.info("replay interrupted")
    finally:
        if tracks_file is not None:
            tracks_file.close()
    summary.data_seconds = summary.ticks * period
    summary.wall_seconds = time.monotonic() - wall0
    p50, p99 = loop.stats.percentiles()
    log.info(
        "replay: %d ticks over %.1f s of data in %.2f s (%.1fx real time); %d revolutions, %d radar frames, "
        "%d poses; cycle p50 %.1f ms p99 %.1f ms",
        summary.ticks,
        summary.data_seconds,
        summary.wall_seconds,
        summary.data_seconds / max(summary.wall_seconds, 1e-9),
        summary.scans,
        summary.radar_frames,
        summary.poses,
        p50,
        p99,
    )
    return 0


def _feed_pose(assembler: Any, msg: Any) -> None:
    import numpy as np

    t = float(msg._timestamp)
    kind = msg.get_type()
    if kind == "ATTITUDE":
        assembler.on_attitude(t, msg.roll, msg.pitch, msg.yaw, msg.rollspeed, msg.pitchspeed, msg.yawspeed)
    elif kind == "LOCAL_POSITION_NED":
        assembler.on_local_position(t, np.array([msg.x, msg.y, msg.z]), np.array([msg.vx, msg.vy, msg.vz]))
    elif kind == "GLOBAL_POSITION_INT":
        vel = np.array([msg.vx, msg.vy, msg.vz]) * 0.01
        assembler.on_global_position(t, msg.lat * 1e-7, msg.lon * 1e-7, msg.alt * 1e-3, vel)
