"""Wire a Config into a running daemon: sources, reader threads, autopilot link, pipeline, loop, signals.

Start-up order matters for the crew: everything that can be wrong in the configuration (ports taken, radar refusing
its cfg) is found BEFORE systemd is told READY=1, with an error that names the port or the cfg line.
"""

from __future__ import annotations

import atexit
import contextlib
import gc
import hashlib
import logging
import math
import signal
import threading
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import IO, Any

from daemon.buffers import BoundedQueue, LatestSlot
from daemon.config import Config, signing_passphrase
from daemon.config_schema import ConfigError
from daemon.ego import HistoryEgo
from daemon.health import source_status
from daemon.heap import limit_arenas
from daemon.loop import DaemonLoop, LoopSettings, SensorInputs
from daemon.readers import ReaderThread
from daemon.sdnotify import SystemdNotifier
from daemon.source_alerts import SourceAlerts
from daemon.source_url import SourceUrl, parse_source_url
from drivers.frames import LidarScan, RadarFrame
from tracker.pipeline import PerceptionPipeline, PipelineSettings

log = logging.getLogger(__name__)


class StartupError(RuntimeError):
    """The daemon cannot start as configured; the message says what to fix."""


@dataclass
class Sources:
    lidar: Any | None = None
    radar: Any | None = None
    lidar_url: SourceUrl | None = None
    radar_url: SourceUrl | None = None
    notes: list[str] = field(default_factory=list)


def _speed(fast: bool) -> float | None:
    return None if fast else 1.0


def build_lidar_source(config: Config, fast: bool) -> tuple[Any, SourceUrl]:
    c = config.lidar
    url = parse_source_url(c.source, {"udp", "pcap"})
    common = dict(
        mount=c.mount.to_mount(),
        cut_angle=math.radians(c.cut_angle_deg),
        model=None if c.model == "auto" else c.model,
        min_range_m=c.min_range_m,
        max_range_m=c.max_range_m,
    )
    if url.scheme == "udp":
        from drivers.vlp16.udp_source import VelodyneUdpSource

        src = VelodyneUdpSource(
            host=url.host,
            port=url.port or 2368,
            position_port=c.position_port,
            accept_ip=c.accept_ip or None,
            silence_timeout_s=c.silence_timeout_s,
            lock_timeout_s=c.lock_timeout_s,
            **common,
        )
        src.open()  # a taken port fails here, before READY, naming the port
        return src, url
    from drivers.vlp16.pcap_source import VelodynePcapSource

    src = VelodynePcapSource(
        url.path,
        position_port=c.position_port,
        accept_ip=c.accept_ip or None,
        lock_timeout_s=c.lock_timeout_s,
        speed=_speed(fast),
        **common,
    )
    return src, url


def expected_radar_stream(config: Config, profile: Any) -> Any:
    """Frames the radar must send for its cfg (``profile``, or None) and ``radar.platform``; others are rejected."""
    from drivers.awr1843.expected import ExpectedStream, platform_code

    return ExpectedStream.for_config(profile, platform_code(config.radar.platform))


def build_radar_source(config: Config, fast: bool, connect: bool = True) -> tuple[Any, SourceUrl]:
    from drivers.awr1843.profile import load_profile

    c = config.radar
    data = parse_source_url(c.data, {"serial", "file"})
    profile = load_profile(c.profile) if c.profile else None
    expected = expected_radar_stream(config, profile)
    if data.scheme == "file":
        from drivers.awr1843.sources import FileRadarSource

        return FileRadarSource(data.path, profile, c.mount.to_mount(), expected=expected, speed=_speed(fast)), data
    from drivers.awr1843.sources import SerialRadarSource

    cli = parse_source_url(c.cli, {"serial"}) if c.cli else None
    src = SerialRadarSource(
        cli.path if cli else "",
        data.path,
        profile,
        c.mount.to_mount(),
        cli_baudrate=int(cli.params.get("baud", 115200)) if cli else 115200,
        data_baudrate=int(data.params.get("baud", 921600)),
        configure=cli is not None,
        expected=expected,
        silence_timeout_s=c.silence_timeout_s,
    )
    if connect:
        src.connect()  # the chirp cfg is sent now: an Error answer stops start-up with the cfg line named
    return src, data


def sensors_off(config: Config) -> list[str]:
    """The sensors switched off in the configuration (``enabled = false``, ``--no-lidar``/``--no-radar``), said once at
    start: the loop does not expect them, so they are never reported silent."""
    off = [name for name, c in (("LiDAR", config.lidar), ("radar", config.radar)) if not c.enabled]
    for name in off:
        log.info("%s off by configuration: not expected, not reported silent", name)
    return off


def open_sources(config: Config, fast: bool) -> Sources:
    out = Sources()
    sensors_off(config)
    if config.lidar.enabled:
        try:
            out.lidar, out.lidar_url = build_lidar_source(config, fast)
        except (OSError, ValueError) as exc:
            raise StartupError(f"LiDAR ({config.lidar.source}): {exc}") from exc
    if config.radar.enabled:
        try:
            out.radar, out.radar_url = build_radar_source(config, fast)
        except Exception as exc:
            if config.radar.required:
                raise StartupError(f"radar: {exc}") from exc
            if _radar_may_come(exc):
                # Its ports are not there yet or it does not answer (a USB radar enumerating after the daemon at
                # boot, a board still powering up): its reader keeps trying, and the loop reports it silent.
                note = f"radar not ready at start, running without it and retrying (radar.required = false): {exc}"
                out.radar, out.radar_url = build_radar_source(config, fast, connect=False)
            else:
                note = f"radar failed to start, running LiDAR-only (radar.required = false): {exc}"
                out.radar = None
            log.error(note)
            out.notes.append(note)
    if out.lidar is None and out.radar is None:
        raise StartupError("no sensor could be started (both disabled or failed)")
    return out


def _radar_may_come(exc: BaseException) -> bool:
    """A radar start-up failure that can mend itself: a missing or busy port, or a device that did not answer (not a
    cfg line it refused, not a config or file problem)."""
    import serial

    from drivers.awr1843.errors import RadarConfigError, RadarPortError

    if isinstance(exc, RadarConfigError):
        return exc.silent
    return isinstance(exc, (RadarPortError, serial.SerialException))


def _radar_min_range(config: Config) -> float:
    """The radar detector's nearest range (its ROI, ``[tracker.radar.roi] min_range_m``), m."""
    from daemon.tracker_adapters import radar_tracker_table
    from tracker.radar.config import RoiConfig

    roi = radar_tracker_table(config).get("roi", {})
    value = roi.get("min_range_m", RoiConfig.min_range_m) if isinstance(roi, dict) else RoiConfig.min_range_m
    return float(value) if isinstance(value, int | float) and math.isfinite(value) else RoiConfig.min_range_m


def pipeline_for(config: Config) -> PerceptionPipeline:
    from daemon.tracker_adapters import tracker_factories

    settings = PipelineSettings(
        min_distance_m=config.output.min_distance_m,
        max_distance_m=config.output.max_distance_m,
        lidar_max_range_m=config.lidar.max_range_m,
        radar_fov_rad=math.radians(config.radar.fov_deg),
        radar_yaw_rad=math.radians(config.radar.mount.yaw),
        radar_pitch_rad=math.radians(config.radar.mount.pitch),
        radar_max_range_m=config.radar.max_range_m,
        lidar_mount=config.lidar.mount.to_mount(),
        min_obstacle_height_m=config.output.min_obstacle_height_m,
        clear_inner_m=config.output.clear_inner_m or None,
        lidar_origin_height_above_water_m=config.boat.water_z_m,
        radar_height_m=config.boat.water_z_m - config.radar.mount.z,
        radar_offset_fwd_stbd_m=(config.radar.mount.x, config.radar.mount.y),
        radar_min_range_m=_radar_min_range(config),
    )
    lidar, radar, preprocess = tracker_factories(config)
    return PerceptionPipeline(
        settings,
        lidar_tracker_factory=lidar,
        radar_tracker_factory=radar,
        lidar_preprocess_config=preprocess,
        freshness_s=config.output.no_data_timeout_s,
    )


def _signing_key(passphrase: str) -> bytes | None:
    # MAVProxy's convention: the 32-byte key is the SHA-256 of the passphrase.
    return hashlib.sha256(passphrase.encode()).digest() if passphrase else None


@dataclass
class RunningDaemon:
    """Everything a live daemon holds; ``stop()`` tears it down in reverse order within about a second."""

    config: Config
    loop: DaemonLoop
    sources: Sources
    link: Any
    readers: list[ReaderThread[Any]]
    stop_event: threading.Event
    tracks_file: IO[str] | None = None
    recorder: Any = None

    def stop(self) -> None:
        self.stop_event.set()
        for r in self.readers:
            r.join(timeout=1.5)
        if self.link is not None:
            self.link.stop()
        if self.recorder is not None:
            self.recorder.close()
            self.recorder = None
        for src in (self.sources.lidar, self.sources.radar):
            close = getattr(src, "close", None)
            if close is not None:
                with contextlib.suppress(Exception):
                    close()
        if self.tracks_file is not None:
            try:
                self.tracks_file.close()
            except OSError as exc:  # the last lines' flush on a full disk: the loop has said so already
                log.error("tracks file: closing it failed: %s", exc.strerror or exc)
            self.tracks_file = None


def open_tracks_out(path: str) -> IO[str] | None:
    """The ``--tracks-out`` file opened for line-by-line writing (None when not asked for); StartupError naming the
    path when it cannot be created."""
    if not path:
        return None
    try:
        Path(path).parent.mkdir(parents=True, exist_ok=True)
        return open(path, "w", encoding="utf-8", buffering=1)
    except OSError as exc:
        raise StartupError(f"--tracks-out: cannot write {path}: {exc.strerror or exc}") from None


def start_daemon(
    config: Config,
    fast: bool = False,
    notifier: SystemdNotifier | None = None,
    clock: Callable[[], float] = time.monotonic,
    view: Any = None,
) -> RunningDaemon:
    """Open everything and start reader threads; the caller drives ``result.loop``. ``view`` (daemon/view, opened
    and closed by the caller) is given every tick."""
    from daemon.autopilot import AutopilotLink

    limit_arenas()  # before any reader thread allocates (daemon.heap)
    m = config.mavlink
    # What can fail without a sensor is settled before the sensors open: a radar once started must be stopped, and
    # a half-started daemon would leave it running.
    try:
        signing_key = _signing_key(signing_passphrase(m))
    except ConfigError as exc:
        raise StartupError(str(exc)) from None
    tracks_file = open_tracks_out(config.output.tracks_out)
    recorder = None
    try:
        if config.output.record_dir:
            from daemon.recorder import Recorder

            run_dir = Path(config.output.record_dir) / time.strftime("%Y%m%d-%H%M%S")
            try:
                recorder = Recorder(run_dir)
            except OSError as exc:
                raise StartupError(f"--record: cannot create {run_dir}: {exc.strerror or exc}") from None
        sources = open_sources(config, fast)
    except BaseException:
        if tracks_file is not None:
            with contextlib.suppress(OSError):
                tracks_file.close()
        raise
    stop = threading.Event()
    inputs = SensorInputs(LatestSlot[LidarScan](), BoundedQueue[RadarFrame](64))
    link = AutopilotLink(
        m.url,
        system_id=m.system_id,
        component_id=m.component_id,
        target_system=m.target_system,
        baud=m.baud,
        signing_key=signing_key,
        clock=clock,
    )
    if recorder is not None:
        recorder.attach(sources.lidar, sources.radar, link, config.radar.profile)
    link.start()
    o = config.output
    loop = DaemonLoop(
        pipeline_for(config),
        inputs,
        link,
        HistoryEgo(link.poses, lambda: link.world_epoch),
        LoopSettings(
            rate_hz=o.rate_hz,
            min_distance_m=o.min_distance_m,
            max_distance_m=o.max_distance_m,
            no_data_timeout_s=o.no_data_timeout_s,
            health_interval_s=o.health_interval_s,
            lidar_expected=sources.lidar is not None,
            radar_expected=sources.radar is not None,
            ais_interval_s=o.ais_interval_s,
            ais_max_tracks=o.ais_max_tracks,
            ais_mmsi_base=o.ais_mmsi_base,
            cycle_budget_s=o.cycle_budget_ms / 1e3,
        ),
        notifier=notifier,
        tracks_out=tracks_file,
        clock=clock,
    )
    readers: list[ReaderThread[Any]] = []
    if sources.lidar is not None:
        readers.append(ReaderThread("lidar", sources.lidar.scans, inputs.lidar.put, stop, clock))
    if sources.radar is not None:
        readers.append(ReaderThread("radar", sources.radar.frames, inputs.radar.put, stop, clock))
    for r in readers:
        r.start()
    loop.status_text = lambda: source_status(sources.lidar, sources.radar, link)
    loop.alerts = SourceAlerts(sources.lidar, sources.radar).poll
    if view is not None:
        view.attach(loop, time_offset_s=time.time() - clock())  # the loop ticks on the monotonic clock
    return RunningDaemon(config, loop, sources, link, readers, stop, tracks_file, recorder)


def freeze_startup_objects() -> None:
    """Take everything start-up created (pymavlink's message classes, numpy, scipy: ~10^5 objects) out of the
    garbage collector's view, so that a full collection during the 10 Hz loop only walks what was made since
    instead of stalling a cycle by several milliseconds."""
    gc.collect()
    gc.freeze()
    # Frozen objects are never collected, not even at exit, where extension modules (velodyne-decoder's nanobind)
    # would then report them as leaked.
    atexit.register(gc.unfreeze)


def run_daemon(config: Config, fast: bool = False, duration_s: float | None = None, view: Any = None) -> int:
    """`usv-tracker run`: exit 0 on SIGTERM/SIGINT, 2 when start-up is impossible (systemd then restarts us)."""
    notifier = SystemdNotifier()
    from daemon.replay import is_replay, run_replay

    if fast or is_replay(config):
        if config.output.record_dir:
            log.warning(
                "not recording to %s: a replay's captures are already its recording (--record is for live sensors)",
                config.output.record_dir,
            )
        try:
            return run_replay(config, duration_s, fast=fast, view=view)
        except (OSError, ValueError) as exc:
            log.error("cannot replay: %s", exc)
            return 2
    try:
        daemon = start_daemon(config, fast=False, notifier=notifier, view=view)
    except StartupError as exc:
        log.error("cannot start: %s", exc)
        notifier.status(f"cannot start: {exc}"[:200])
        return 2
    stop = daemon.stop_event

    def on_signal(signum: int, _frame: object) -> None:
        log.info("%s received: stopping", signal.Signals(signum).name)
        stop.set()

    def on_hangup(signum: int, _frame: object) -> None:
        # A terminal closing (ssh or tmux dropped on the quay) must not take the obstacle feed with it; nothing is
        # reloaded either: a new config takes a restart, after check-config.
        log.warning("SIGHUP received: ignored, still running (a changed config needs a restart)")

    previous = {s: signal.signal(s, on_signal) for s in (signal.SIGTERM, signal.SIGINT)}
    previous[signal.SIGHUP] = signal.signal(signal.SIGHUP, on_hangup)
    sensors = ", ".join(
        n for n, s in (("LiDAR", daemon.sources.lidar), ("radar", daemon.sources.radar)) if s is not None
    )
    off = [n for n, c in (("LiDAR", config.lidar), ("radar", config.radar)) if not c.enabled]
    freeze_startup_objects()
    notifier.ready(f"tracking with {sensors}" + (f" ({', '.join(off)} off by configuration)" if off else ""))
    log.info("usv-tracker running: %s -> %s at %.0f Hz", sensors, config.mavlink.url, config.output.rate_hz)
    try:
        daemon.loop.run_live(stop, duration_s)
    finally:
        notifier.stopping()
        daemon.stop()
        for s, h in previous.items():
            signal.signal(s, h)
    log.info("stopped")
    return 0
