"""Replay of recorded captures through the same pipeline and loop as live, on the data's own clock.

Sources (daemon/replay_sources.py): a VLP-16 pcap (`pcap://`), a radar data-port dump (`file://`, with its `.times`
sidecar when the project recorded it, else paced by the cfg's frame period from the LiDAR's start), and the
autopilot's poses from a MAVLink `.tlog`. Ticks are placed every 1/rate s of DATA time and fed exactly the items
stamped before them, so the output does not depend on the CPU or on the pace: as fast as possible (`--fast`) or at
N times real time, the same capture gives the same ticks. A publisher (`usv-tracker replay --to URL`) receives what
the live daemon would send, at the pace the replay keeps.
"""

from __future__ import annotations

import logging
import math
import signal
import threading
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Protocol

from daemon.buffers import BoundedQueue, LatestSlot
from daemon.config import Config
from daemon.ego import HistoryEgo, ShiftedEgo
from daemon.loop import DaemonLoop, LoopSettings, ObstaclePublisher, SensorInputs, sendable
from daemon.pose_history import PoseHistory
from daemon.replay_sources import Peekable, close_stream, feed_pose, lidar_scans, radar_frames, tlog_messages
from daemon.runner import pipeline_for, sensors_off
from daemon.source_url import parse_source_url
from drivers.frames import LidarScan, RadarFrame
from tracker.pipeline import EgoSource, PerceptionOutput

log = logging.getLogger(__name__)


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


class ReplayProgress(Protocol):
    """Told where the replay is; daemon/replay_progress.py draws it."""

    def start(self, t0: float) -> None:
        """The data time the first tick counts from."""

    def advance(self, data_seconds: float) -> None:
        """Seconds of data replayed so far."""

    def close(self) -> None: ...


@dataclass
class ReplayOptions:
    speed: float | None = None  # times real time; None: as fast as the CPU allows
    duration_s: float | None = None  # stop after this much data
    tlog: str | None = None  # poses from this recording of the autopilot
    # Poses from a live autopilot instead (an EgoSource on the host's monotonic clock); needs speed 1.
    live_ego: EgoSource | None = None
    publisher: ObstaclePublisher | None = None  # where OBSTACLE_DISTANCE & co. go (`--to URL`)
    progress: ReplayProgress | None = None
    # Decoders in producer threads; the default decodes in the tick loop, which bench/replay_speed.py measured
    # faster (fused 5.6x against 5.1x real time): the threads hold the interpreter lock the tracker waits for.
    prefetch: bool = False
    view: Any = None  # daemon.view.publisher.FoxgloveView (--foxglove/--mcap): every tick published to it


@dataclass
class ReplaySummary:
    ticks: int = 0
    scans: int = 0
    radar_frames: int = 0
    poses: int = 0
    sent: int = 0  # ticks whose bins were sent (or would have been, without a publisher): daemon.loop.sendable
    data_seconds: float = 0.0
    wall_seconds: float = 0.0  # from opening the captures to the last tick
    track_ids: set[int] = field(default_factory=set)  # every track written
    confirmed_ids: set[int] = field(default_factory=set)
    decoder_waits: int | None = None  # items the tick loop found not yet decoded (producer threads only)
    cycle_p50_ms: float = 0.0  # one tick's pipeline and publishing
    cycle_p99_ms: float = 0.0
    interrupted: bool = False
    no_pose: int = 0  # ticks with poses in use but none for the tick's time
    tracks_out_failed: str | None = None  # why the tracks file stopped being written (a full disk), if it did

    @property
    def ratio(self) -> float:
        """Data seconds per wall second: the replay's speed in times real time."""
        return self.data_seconds / max(self.wall_seconds, 1e-9)

    def details(self) -> str:
        return (
            f"{self.ticks} ticks over {self.data_seconds:.1f} s of data in {self.wall_seconds:.2f} s "
            f"({self.ratio:.1f}x real time); {self.scans} revolutions, {self.radar_frames} radar frames, "
            f"{self.poses} poses; cycle p50 {self.cycle_p50_ms:.1f} ms p99 {self.cycle_p99_ms:.1f} ms; "
            + (
                "decoded in the tick loop"
                if self.decoder_waits is None
                else f"waited {self.decoder_waits} times for a decoder"
            )
        )

    def count(self, out: PerceptionOutput) -> None:
        self.ticks += 1
        self.sent += sendable(out)
        self.no_pose += not out.pose_known
        for tr in out.tracks:
            self.track_ids.add(tr.id)
            if tr.confirmed:
                self.confirmed_ids.add(tr.id)


def run_replay(config: Config, duration_s: float | None = None, fast: bool = True, view: Any = None) -> int:
    """`usv-tracker run` on captures: the poses from ``[mavlink] url`` when it is a .tlog; 0, or 130 when
    interrupted."""
    tlog = config.mavlink.url if config.mavlink.url.endswith(".tlog") else None
    summary = replay(config, ReplayOptions(speed=None if fast else 1.0, duration_s=duration_s, tlog=tlog, view=view))
    log.info("replay: %s", summary.details())
    if summary.tracks_out_failed is not None:  # a replay's tracks file is its result: a part of it is a failure
        log.error("replay: the tracks file %s is cut short: %s", config.output.tracks_out, summary.tracks_out_failed)
        return 2
    return 130 if summary.interrupted else 0


def _stop_on_sigterm() -> Any:
    """SIGTERM (``kill``, ``timeout``) ends a replay as Ctrl-C does: the tick loop stops, the summary is printed and
    an --mcap file is finished (killed outright, it was left unreadable). The previous handler, or None when not
    on the main thread (signals cannot be set there)."""
    if threading.current_thread() is not threading.main_thread():
        return None

    def interrupt(_signum: int, _frame: object) -> None:
        raise KeyboardInterrupt

    return signal.signal(signal.SIGTERM, interrupt)


def replay(config: Config, options: ReplayOptions) -> ReplaySummary:
    """Replay the captures ``config`` names; raises OSError/ValueError for captures that cannot be read."""
    if options.speed is not None and not (math.isfinite(options.speed) and options.speed > 0):
        raise ValueError(f"replay speed must be a positive factor, got {options.speed}")
    if options.live_ego is not None and options.speed != 1.0:
        raise ValueError("live poses need the recorded pace (speed 1)")
    wall_start = time.monotonic()
    sensors_off(config)
    streams: list[Any] = []
    previous = _stop_on_sigterm()
    try:
        return _replay(config, options, streams, wall_start)
    finally:
        if previous is not None:
            signal.signal(signal.SIGTERM, previous)
        for it in streams:
            try:
                close_stream(it)
            except OSError as exc:  # the tracks file's last flush on a full disk
                log.error("closing %s failed: %s", getattr(it, "name", "a replay stream"), exc.strerror or exc)


def _replay(config: Config, options: ReplayOptions, streams: list[Any], wall_start: float) -> ReplaySummary:
    from daemon.autopilot_pose import PoseAssembler

    summary = ReplaySummary()
    lidar_it = lidar_scans(config, options.prefetch)
    streams.append(lidar_it)
    lidar = Peekable(lidar_it) if lidar_it is not None else None
    first_lidar = lidar.peek().stamp if lidar is not None and lidar.peek() is not None else None  # type: ignore[union-attr]
    radar_it = radar_frames(config, first_lidar, options.prefetch)
    streams.append(radar_it)
    radar = Peekable(radar_it) if radar_it is not None else None
    poses: EgoSource | None = None
    pose_msgs: Peekable[Any] | None = None
    assembler = None
    if options.live_ego is not None:
        poses = options.live_ego  # put on the recording's clock below, once the first tick's time is known
    elif options.tlog is not None:
        history = PoseHistory(capacity=100_000)
        assembler = PoseAssembler(history)
        poses = HistoryEgo(history, lambda: assembler.world_epoch)
        msgs = tlog_messages(options.tlog, options.prefetch)
        streams.append(msgs)
        pose_msgs = Peekable(msgs)
    else:
        # said once, here, for `replay` and `run --fast` alike
        log.warning("replay without a .tlog: no own pose, the boat's frame at the start is the world frame")

    starts = [p.peek().stamp for p in (lidar, radar) if p is not None and p.peek() is not None]  # type: ignore[union-attr]
    if not starts:
        raise ValueError("the captures hold no LiDAR revolution and no radar frame")
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
    streams.append(tracks_file)
    loop = DaemonLoop(
        pipeline_for(config),
        inputs,
        options.publisher,
        poses,
        LoopSettings(
            o.rate_hz,
            o.min_distance_m,
            o.max_distance_m,
            o.no_data_timeout_s,
            o.health_interval_s,
            lidar_expected=config.lidar.enabled,
            radar_expected=config.radar.enabled,
            ais_interval_s=o.ais_interval_s,
            ais_max_tracks=o.ais_max_tracks,
            ais_mmsi_base=o.ais_mmsi_base,
        ),
        tracks_out=tracks_file,
        clock=lambda: t_now,
    )
    if assembler is not None:
        loop.world_to_geodetic = assembler.world_to_geodetic  # the recorded autopilot's anchor, not the live one's
    if options.view is not None:
        options.view.attach(loop, time_offset_s=0.0)  # ticks are on the capture's clock: Unix time already
    speed = options.speed
    progress = options.progress
    if progress is not None:
        progress.start(t0)
    waits_before = _waits(lidar_it, radar_it)
    mono0 = time.monotonic()
    if options.live_ego is not None:
        # data time t is host time mono0 + (t - t0) at the recorded pace
        loop.poses = ShiftedEgo(options.live_ego, mono0 - t0)
    k = 0
    t_now = t0
    try:
        while True:
            k += 1
            t_now = t0 + k * period
            if options.duration_s is not None and t_now - t0 > options.duration_s:
                break
            if pose_msgs is not None and assembler is not None:
                while (m := pose_msgs.peek()) is not None and m._timestamp <= t_now + 0.2:
                    feed_pose(assembler, pose_msgs.pop())
                    summary.poses += 1
            if lidar is not None:
                while (s := lidar.peek()) is not None and s.stamp <= t_now:
                    inputs.lidar.put(lidar.pop(), t_now)
                    summary.scans += 1
            if radar is not None:
                while (f := radar.peek()) is not None and f.stamp <= t_now:
                    inputs.radar.put(radar.pop(), t_now)
                    summary.radar_frames += 1
            if speed is not None:
                delay = (t_now - t0) / speed - (time.monotonic() - mono0)
                if delay > 0:
                    time.sleep(delay)
            summary.count(loop.tick(t_now))
            if progress is not None:
                progress.advance(t_now - t0)
            if all(p is None or p.done for p in (lidar, radar)):
                break
    except KeyboardInterrupt:
        log.info("replay interrupted")
        summary.interrupted = True
    finally:
        if progress is not None:
            progress.close()
    summary.data_seconds = summary.ticks * period
    summary.wall_seconds = time.monotonic() - wall_start
    summary.decoder_waits = _waits(lidar_it, radar_it) - waits_before if options.prefetch else None
    summary.cycle_p50_ms, summary.cycle_p99_ms = loop.stats.percentiles()
    if loop.tracks_out is not None:
        try:  # the buffered last lines: a full disk shows here, not in the writes that fitted the buffer
            loop.tracks_out.flush()
        except OSError as exc:
            loop.tracks_out_failed = exc.strerror or str(exc)
    summary.tracks_out_failed = loop.tracks_out_failed
    if summary.no_pose:
        # A .tlog cut short, or captures on another clock (a radar dump without its .times sidecar is paced from
        # t = 0): without this the run looked whole, and half of it had gone without tracking.
        log.warning(
            "%d of %d ticks had no own pose: the .tlog ends before the captures or does not cover their times "
            "(a radar dump without its .times sidecar starts at t = 0); tracking waited, the radar's bearings "
            "were unknown there, and with the radar alone no obstacle array was sent",
            summary.no_pose,
            summary.ticks,
        )
    return summary


def _waits(*streams: Any) -> int:
    return sum(getattr(s, "waits", 0) for s in streams)
