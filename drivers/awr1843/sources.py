"""Where radar frames come from: the live pair of serial ports, or a raw data-port dump.

Both sources have one interface, ``frames(stop) -> Iterator[RadarFrame]``, meant to run in the reader
thread of the daemon: it returns within about ``read_timeout_s`` of ``stop`` being set, and it never
raises for transient trouble (silence, an unplugged cable). Those are logged, counted in ``stats`` and
shown as health flags; only a configuration the device refuses at start-up is raised, because it will
not fix itself.
"""

from __future__ import annotations

import contextlib
import logging
import math
import threading
import time
from collections.abc import Callable, Iterator
from dataclasses import dataclass, field
from pathlib import Path

import serial

from drivers.awr1843.cli import CliSession
from drivers.awr1843.errors import RadarConfigError, RadarPortError
from drivers.awr1843.expected import ExpectedStream
from drivers.awr1843.parser import ParserStats, RadarFrameParser
from drivers.awr1843.ports import describe_port, open_serial
from drivers.awr1843.profile import RadarProfile, load_profile
from drivers.frames import RadarFrame
from drivers.mount import Mount

log = logging.getLogger(__name__)

# A read that waits this long for a byte and gets none is the pause between two frames' bursts: the parser then
# decides a frame held for its last bytes (RadarFrameParser.idle). A replay of timed chunks does the same.
QUIET_READ_S = 0.02

RETRY_LOG_ATTEMPTS = 3  # failed reconnect attempts logged one by one; then once every RETRY_LOG_INTERVAL_S
RETRY_LOG_INTERVAL_S = 60.0

DATA_BAUDRATE = 921600
DEFAULT_FRAME_PERIOD_S = 0.1


@dataclass
class SourceStats:
    """Parser counters plus the link's own: what a health line needs."""

    parser: ParserStats = field(default_factory=ParserStats)
    silent: bool = False  # no frame for silence_timeout_s
    silences: int = 0  # times the stream went silent
    disconnects: int = 0  # port lost (cable, USB reset)
    reconnects: int = 0
    configured: int = 0  # successful CLI configurations
    cfg_resends: int = 0  # cfg sent again to a radar silent with its ports there

    def as_dict(self) -> dict[str, int | bool | str]:
        out: dict[str, int | bool | str] = dict(self.parser.as_dict())
        out.update(
            silent=self.silent,
            silences=self.silences,
            disconnects=self.disconnects,
            reconnects=self.reconnects,
            configured=self.configured,
            cfg_resends=self.cfg_resends,
        )
        return out


def _as_profile(profile: RadarProfile | str | Path | None) -> RadarProfile | None:
    """A parsed profile, a cfg path, or None/"" for none (SDK 3.x streams decode without one)."""
    if profile is None or isinstance(profile, RadarProfile):
        return profile
    if not str(profile):
        return None
    return load_profile(profile)


class SerialRadarSource:
    """The AWR1843 on two serial ports: configure through the CLI port, then stream the data port.

    Ports are paths (``/dev/ttyACM0`` or, better, ``/dev/serial/by-id/...-if00``). ``configure=False``
    leaves an already running radar alone (the cfg, optional then, is only used for decoding).

    ``connect()`` configures now and raises ``RadarConfigError`` / ``RadarPortError`` (start-up checks);
    ``frames(stop)`` connects itself if needed, and afterwards only logs, counts and retries. ``expected``: frames of
    any other configuration are rejected and counted (``ExpectedStream.for_config`` of the cfg sent).
    """

    def __init__(
        self,
        cli_port: str,
        data_port: str,
        profile_path: RadarProfile | str | Path | None,
        mount: Mount | None = None,
        *,
        cli_baudrate: int = 115200,
        data_baudrate: int = DATA_BAUDRATE,
        configure: bool = True,
        expected: ExpectedStream | None = None,
        stop_sensor_on_exit: bool = True,
        silence_timeout_s: float = 2.0,
        resend_cfg_after_s: tuple[float, ...] = (5.0, 15.0, 45.0, 60.0),
        read_timeout_s: float = QUIET_READ_S,
        reconnect_backoff_s: tuple[float, ...] = (0.2, 0.5, 1.0, 2.0, 5.0),
        cli_command_timeout_s: float = 1.0,
        cli_slow_command_timeout_s: float = 3.0,
        clock: Callable[[], float] = time.monotonic,
    ) -> None:
        profile = _as_profile(profile_path)
        if profile is None and configure:
            raise ValueError("SerialRadarSource: configuring the radar needs its cfg (profile_path)")
        self.profile = profile
        self.cli_port = cli_port
        self.data_port = data_port
        self.mount = mount if mount is not None else Mount()
        self.cli_baudrate = cli_baudrate
        self.data_baudrate = data_baudrate
        self.configure = configure
        self.stop_sensor_on_exit = stop_sensor_on_exit
        self.silence_timeout_s = silence_timeout_s
        # Silent this long with its ports still there (a brown-out reset the board, another program stopped it), a
        # radar this source configures gets its cfg again; then again after each next interval, the last repeating.
        self.resend_cfg_after_s = resend_cfg_after_s
        self.read_timeout_s = read_timeout_s
        self.reconnect_backoff_s = reconnect_backoff_s
        self.cli_command_timeout_s = cli_command_timeout_s
        self.cli_slow_command_timeout_s = cli_slow_command_timeout_s
        self.clock = clock
        self.parser = RadarFrameParser(self.profile, self.mount, expected=expected)
        self.stats = SourceStats(parser=self.parser.stats)
        self._data: serial.Serial | None = None
        # Called with every chunk read from the data port, before parsing (the recorder keeps the raw bytes).
        self.raw_sink: Callable[[bytes], None] | None = None

    @property
    def silent(self) -> bool:
        return self.stats.silent

    def _ports_text(self) -> str:
        cli = describe_port(self.cli_port) if self.configure else "not used"
        return f"CLI {cli}, data {describe_port(self.data_port)}"

    # ------------------------------------------------------------------ set-up
    def connect(self) -> None:
        """Open the data port and, with ``configure``, send the cfg now. Raises on a refused line or a
        missing/busy port, so that start-up can fail with the cfg line or the port named."""
        if self._data is None:
            self._connect()

    def close(self) -> None:
        """Release the ports (for a source that was connected but never iterated)."""
        was_open = self._data is not None
        self._close_data()
        if was_open and self.configure and self.stop_sensor_on_exit:
            self._stop_sensor()

    def _cli(self) -> CliSession:
        return CliSession(
            self.cli_port,
            self.cli_baudrate,
            command_timeout=self.cli_command_timeout_s,
            slow_command_timeout=self.cli_slow_command_timeout_s,
        )

    def _connect(self) -> None:
        """Open the data port, then (re)configure the radar, draining stale frames after sensorStop."""
        self._data = open_serial(self.data_port, self.data_baudrate, role="data", timeout=self.read_timeout_s)
        if not self.configure or self.profile is None:
            return
        profile = self.profile
        try:
            with self._cli() as cli:
                cli.configure(profile, after_stop=self._drain_data)
        except BaseException:
            self._close_data()
            raise
        self.stats.configured += 1
        log.info("AWR1843 configured from %s (%s)", profile.source, self._ports_text())

    def _drain_data(self) -> None:
        """Frames of the old configuration still in the USB/OS buffers must not look like new ones."""
        assert self._data is not None
        self._data.reset_input_buffer()
        while self._data.in_waiting:
            self._data.read(self._data.in_waiting)
        self.parser.reset_stream()

    def _close_data(self) -> None:
        if self._data is not None:
            with contextlib.suppress(OSError, serial.SerialException):
                self._data.close()
            self._data = None

    def _stop_sensor(self) -> None:
        try:
            with self._cli() as cli:
                cli.stop_sensor()
        except (RadarConfigError, RadarPortError, serial.SerialException, OSError) as exc:
            log.warning("AWR1843: could not stop the sensor on exit: %s", exc)

    # ------------------------------------------------------------------ stream
    def frames(self, stop: threading.Event) -> Iterator[RadarFrame]:
        """Configure, then yield frames until ``stop`` is set, retrying a radar that is missing or silent. A cfg
        line the radar refuses ends the stream (logged): it will not mend itself, and re-sending it would only
        reconfigure the radar over and over."""
        if self._data is None:
            try:
                self._connect()
            except (RadarConfigError, RadarPortError, serial.SerialException, OSError) as exc:
                self._close_data()
                if self._refused(exc):
                    return
                log.error("AWR1843: %s; will keep retrying", exc)
                if not self._reconnect(stop):
                    return
        try:
            yield from self._stream(stop)
        finally:
            self._close_data()
            if self.configure and self.stop_sensor_on_exit:
                self._stop_sensor()

    def _stream(self, stop: threading.Event) -> Iterator[RadarFrame]:
        last_frame = self.clock()
        resends = 0  # cfg re-sent since the last frame
        while not stop.is_set():
            assert self._data is not None
            try:
                waiting = self._data.in_waiting
                data = self._data.read(waiting if waiting else 1)
            except (serial.SerialException, OSError) as exc:
                self.stats.disconnects += 1
                log.error("AWR1843 data port lost (%s): %s; reconnecting", self._ports_text(), exc)
                self._close_data()
                self.parser.reset_stream()
                if not self._reconnect(stop):
                    return
                last_frame = self.clock()
                resends = 0
                continue
            now = self.clock()
            if data and self.raw_sink is not None:
                self.raw_sink(data)
            # An empty read is the pause between two frames' bursts: a frame held for its last bytes goes out now.
            frames = self.parser.feed(data, now) if data else self.parser.idle(now)
            for frame in frames:
                if self.stats.silent:
                    self.stats.silent = False
                    log.warning("AWR1843: frames flowing again on %s", describe_port(self.data_port))
                yield frame
            if frames:
                last_frame = now
                resends = 0
            elif self._resend_due(now - last_frame, resends):
                resends += 1
                log.warning(
                    "AWR1843: no frame for %.0f s with its ports there (%s): sending the cfg again (%d)",
                    now - last_frame,
                    self._ports_text(),
                    resends,
                )
                self._close_data()
                self.parser.reset_stream()
                if not self._reconnect(stop, resend=True):
                    return
                # last_frame stays: the silence (and its next re-send) runs on until a frame comes
            elif not self.stats.silent and now - last_frame > self.silence_timeout_s:
                self.stats.silent = True
                self.stats.silences += 1
                log.error(
                    "AWR1843: no frame for %.1f s (%s): sensor stopped, ports swapped, wrong baud, "
                    "or cable? (%d bytes skipped so far)",
                    now - last_frame,
                    self._ports_text(),
                    self.stats.parser.bytes_skipped,
                )

    def _resend_due(self, silent_for_s: float, resends: int) -> bool:
        """A silent radar this source configures is due its cfg again: after the first interval of silence, then
        each next one (cumulative), the last repeating."""
        if not (self.configure and self.stats.silent and self.resend_cfg_after_s):
            return False
        steps = self.resend_cfg_after_s
        due = sum(steps[: min(resends + 1, len(steps))]) + steps[-1] * max(resends + 1 - len(steps), 0)
        return silent_for_s >= due

    def _refused(self, exc: BaseException) -> bool:
        """A cfg line the radar answered with an error or did not know: logged, and the stream ends (True)."""
        if not isinstance(exc, RadarConfigError) or exc.silent:
            return False
        log.error(
            "AWR1843 (%s) refused its cfg: %s; radar off until the cfg is fixed and the daemon restarted",
            self._ports_text(),
            exc,
        )
        return True

    def _reconnect(self, stop: threading.Event, resend: bool = False) -> bool:
        """Retry with backoff until the ports are back and the radar accepts its cfg; False if stopped, or if the
        radar refused a cfg line. ``resend``: the ports were never lost, the cfg is sent again to a silent radar.
        The first attempts' failures are logged each, then once a minute: a radar that never comes is not 17,000
        journal lines a day."""
        attempt = 0
        logged_at = -math.inf
        while not stop.is_set():
            delay = self.reconnect_backoff_s[min(attempt, len(self.reconnect_backoff_s) - 1)]
            if stop.wait(delay):
                return False
            attempt += 1
            try:
                self._connect()
            except (RadarPortError, RadarConfigError, serial.SerialException, OSError) as exc:
                self._close_data()
                if self._refused(exc):
                    return False
                now = self.clock()
                if attempt <= RETRY_LOG_ATTEMPTS or now - logged_at >= RETRY_LOG_INTERVAL_S:
                    logged_at = now
                    log.warning(
                        "AWR1843 %s attempt %d failed: %s%s",
                        "cfg" if resend else "reconnect",
                        attempt,
                        exc,
                        "" if attempt < RETRY_LOG_ATTEMPTS else " (said again once a minute while it fails)",
                    )
                continue
            if resend:
                self.stats.cfg_resends += 1
                log.warning("AWR1843 cfg sent again (%s); waiting for its frames", self._ports_text())
            else:
                self.stats.reconnects += 1
                log.warning("AWR1843 reconnected after %d attempt(s) (%s)", attempt, self._ports_text())
            return True
        return False


class FileRadarSource:
    """Replay of a raw data-port dump (the ``.dat`` TI's visualizer saves).

    Frame k gets ``stamp = start_time + (frame_number - first frame_number) * period`` so that lost
    frames keep their slot in time; ``period`` comes from the cfg, else 100 ms. ``speed=None`` replays
    as fast as possible; ``speed=1.0`` in real time.
    """

    def __init__(
        self,
        path: str | Path,
        profile: RadarProfile | str | Path | None = None,
        mount: Mount | None = None,
        *,
        expected: ExpectedStream | None = None,
        speed: float | None = 1.0,
        start_time: float | None = None,
        chunk_size: int = 4096,
        clock: Callable[[], float] = time.monotonic,
    ) -> None:
        self.path = Path(path)
        self.profile = _as_profile(profile)
        self.mount = mount if mount is not None else Mount()
        self.speed = speed
        self.start_time = start_time
        self.chunk_size = chunk_size
        self.clock = clock
        self.period_s = self.profile.frame_period_s if self.profile is not None else DEFAULT_FRAME_PERIOD_S
        self.parser = RadarFrameParser(self.profile, self.mount, expected=expected)
        self.stats = SourceStats(parser=self.parser.stats)

    def frames(self, stop: threading.Event) -> Iterator[RadarFrame]:
        start = self.clock() if self.start_time is None else self.start_time
        wall0 = self.clock()
        first: int | None = None
        last_k = -1
        with self.path.open("rb") as f:
            while not stop.is_set():
                chunk = f.read(self.chunk_size)
                frames = self.parser.feed(chunk, start) if chunk else self.parser.finish(start)
                for frame in frames:
                    if first is None:
                        first = frame.frame_number
                    k = frame.frame_number - first
                    if k <= last_k:  # frame numbers restarted (joined recordings): keep time moving on
                        first = frame.frame_number - last_k - 1
                        k = last_k + 1
                    last_k = k
                    frame.stamp = start + k * self.period_s
                    if self.speed is not None and self.speed > 0:
                        wait = wall0 + k * self.period_s / self.speed - self.clock()
                        if wait > 0 and stop.wait(wait):
                            return
                    yield frame
                    if stop.is_set():
                        return
                if not chunk:
                    break
        if self.parser.buffered_bytes:
            log.info("AWR1843 replay %s: %d trailing bytes of a cut frame", self.path, self.parser.buffered_bytes)
