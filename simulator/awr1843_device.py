"""An AWR1843 running the out-of-box demo, emulated on two real pseudo-terminals.

The driver under test opens the slave ends BY PATH with pyserial, exactly as it opens
``/dev/ttyACM0``/``/dev/ttyACM1`` on the boat; this module owns the master ends and behaves like the
firmware where it matters to a host: banner and prompt at boot, character echo, ``Done`` /
``Ignored: Sensor is already stopped`` / ``Error -N`` / ``'x' is not recognized as a CLI command``,
garbage at first contact, a data stream that starts only after ``sensorStart`` at the ``frameCfg``
period, frame numbers that survive stop/start, and TLVs chosen by ``guiMonitor``.

Fault injection on the data stream (keyed by frame number) lets tests check resync and counters:
garbage before a frame, a frame cut short, a byte range deleted from a frame. ``unplug()``/``replug()``
model a USB cable pulled and put back when the ports are reached through stable symlinks
(``link_dir``, like ``/dev/serial/by-id``).
"""

from __future__ import annotations

import contextlib
import logging
import math
import os
import select
import threading
import time
import tty
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from pathlib import Path
from types import TracebackType

import numpy as np

from drivers.awr1843.parser import encode_frame

log = logging.getLogger(__name__)

PROMPT = b"mmwDemo:/>"
BANNER = (
    b"\r\n******************************************\r\n"
    b"xWR18xx MMW Demo 03.06.00.00\r\n"
    b"******************************************\r\n"
)
CPU_CLOCK_HZ = 200e6  # R4F cycle counter of xWR18xx SDK 3.x, stamped into every header
# Commands of the SDK 3.x xWR18xx OOB demo (anything else is "not recognized").
KNOWN_COMMANDS = frozenset(
    {
        "sensorStart",
        "sensorStop",
        "flushCfg",
        "dfeDataOutputMode",
        "channelCfg",
        "adcCfg",
        "adcbufCfg",
        "profileCfg",
        "chirpCfg",
        "frameCfg",
        "advFrameCfg",
        "subFrameCfg",
        "lowPower",
        "guiMonitor",
        "cfarCfg",
        "multiObjBeamForming",
        "clutterRemoval",
        "calibDcRangeSig",
        "extendedMaxVelocity",
        "lvdsStreamCfg",
        "compRangeBiasAndRxChanPhase",
        "measureRangeBiasAndRxChanPhase",
        "CQRxSatMonitor",
        "CQSigImgMonitor",
        "analogMonitor",
        "aoaFovCfg",
        "cfarFovCfg",
        "calibData",
        "bpmCfg",
        "help",
    }
)


@dataclass
class DevicePoints:
    """One frame's detections as the firmware reports them: TI axes (x right, y boresight, z up)."""

    xyz_ti: np.ndarray  # (N, 3) m
    doppler: np.ndarray  # (N,) m/s radial, positive = receding
    snr_db: np.ndarray | float = 20.0
    noise_db: np.ndarray | float = 60.0


# (frame_number, time.monotonic() at emission) -> detections of that frame
FrameSource = Callable[[int, float], DevicePoints]

DEFAULT_TARGETS = DevicePoints(
    xyz_ti=np.array([[-2.0, 20.0, 0.0], [5.0, 35.0, 0.0], [0.5, 8.0, 0.0]]),
    doppler=np.array([-0.5, 0.25, 0.0]),
    snr_db=np.array([22.0, 18.5, 30.1]),
    noise_db=np.array([61.2, 58.0, 64.5]),
)


def default_frame_source(frame_number: int, t: float) -> DevicePoints:
    return DEFAULT_TARGETS


@dataclass
class StreamFaults:
    """Damage done to the data stream, keyed by frame number."""

    garbage_before: dict[int, bytes] = field(default_factory=dict)  # written just before the frame
    truncate: dict[int, int] = field(default_factory=dict)  # only the first k bytes of the frame are sent
    delete: dict[int, tuple[int, int]] = field(default_factory=dict)  # (offset, length) cut out of the frame


@dataclass(frozen=True)
class SentFrame:
    frame_number: int
    size: int  # bytes actually written
    intact: bool  # False when truncated or cut


class _PtyPair:
    """A master fd kept by the emulator and the slave's path for the host. The emulator also keeps the
    slave open so that the master never sees EIO while the host has the port closed."""

    def __init__(self) -> None:
        self.master, self._slave = os.openpty()
        self.path = os.ttyname(self._slave)
        tty.setraw(self._slave)  # bytes pass unchanged: no CR/LF mapping, no echo by the line discipline
        os.set_blocking(self.master, False)

    def close(self) -> None:
        for fd in (self.master, self._slave):
            with contextlib.suppress(OSError):
                os.close(fd)


class Awr1843Emulator:
    """Two ptys speaking the OOB demo's CLI and data protocols. ``start()``, use, ``stop()``."""

    def __init__(
        self,
        *,
        frame_source: FrameSource | None = None,
        first_frame_number: int = 1,
        failing_lines: Mapping[str, int] | None = None,
        boot_garbage: bytes = b"",
        garbled_lines: int = 0,
        faults: StreamFaults | None = None,
        default_period_s: float = 0.1,
        version: tuple[int, int, int, int] = (3, 6, 0, 0),
        platform: int = 0xA1843,
        link_dir: str | Path | None = None,
        sensor_start_delay_s: float = 0.0,
    ) -> None:
        """``failing_lines`` maps an exact line text or a command name to the error code it gets.
        ``boot_garbage`` is glued in front of the first line the host sends (as after power-up);
        ``garbled_lines`` more non-empty lines after it arrive with ``?`` in front (a noisy line)."""
        self.frame_source = frame_source or default_frame_source
        self.first_frame_number = first_frame_number
        self.failing_lines = dict(failing_lines or {})
        self.boot_garbage = boot_garbage
        self.garbled_lines = garbled_lines
        self.faults = faults or StreamFaults()
        self.default_period_s = default_period_s
        self.version = version
        self.platform = platform
        self.link_dir = Path(link_dir) if link_dir is not None else None
        self.sensor_start_delay_s = sensor_start_delay_s

        self.received_lines: list[str] = []  # every CLI line as the device heard it
        self.frames_sent: list[SentFrame] = []
        self.bytes_dropped = 0  # data bytes the host did not take in time (a real UART drops them too)

        self._lock = threading.Lock()
        self._stop = threading.Event()
        self._running = threading.Event()
        self._plugged = threading.Event()
        self._threads: list[threading.Thread] = []
        self._cli: _PtyPair | None = None
        self._data: _PtyPair | None = None
        self._reset_device_state()

    # ------------------------------------------------------------------ lifecycle
    def __enter__(self) -> Awr1843Emulator:
        self.start()
        return self

    def __exit__(
        self, exc_type: type[BaseException] | None, exc: BaseException | None, tb: TracebackType | None
    ) -> None:
        self.stop()

    def start(self) -> None:
        if self._threads:
            raise RuntimeError("emulator already started")
        self._plug()
        self._stop.clear()
        self._threads = [
            threading.Thread(target=self._cli_loop, name="awr1843-emu-cli", daemon=True),
            threading.Thread(target=self._data_loop, name="awr1843-emu-data", daemon=True),
        ]
        for t in self._threads:
            t.start()

    def stop(self) -> None:
        self._stop.set()
        self._running.clear()
        for t in self._threads:
            t.join(timeout=5.0)
        self._threads = []
        self._unplug()

    def unplug(self) -> None:
        """Cable out: both ports vanish (the host's reads fail, the symlinks go away)."""
        self._unplug()

    def replug(self, power_cycle: bool = True) -> None:
        """Cable back in: new ptys behind the same link paths. A power cycle forgets the
        configuration, stops the sensor and restarts frame numbering."""
        if power_cycle:
            self._reset_device_state()
        self._plug()

    @property
    def cli_path(self) -> str:
        return self._path("cli")

    @property
    def data_path(self) -> str:
        return self._path("data")

    @property
    def sensor_running(self) -> bool:
        return self._running.is_set()

    @property
    def frame_period_s(self) -> float:
        with self._lock:
            return self._period_s

    # ------------------------------------------------------------------ ports
    def _path(self, role: str) -> str:
        if self.link_dir is not None:
            return str(self.link_dir / f"awr1843-{role}")
        pair = self._cli if role == "cli" else self._data
        if pair is None:
            raise RuntimeError("emulator is unplugged")
        return pair.path

    def _plug(self) -> None:
        with self._lock:
            self._cli, self._data = _PtyPair(), _PtyPair()
            os.write(self._cli.master, BANNER + PROMPT)
            if self.link_dir is not None:
                self.link_dir.mkdir(parents=True, exist_ok=True)
                for role, pair in (("cli", self._cli), ("data", self._data)):
                    link = self.link_dir / f"awr1843-{role}"
                    tmp = self.link_dir / f".awr1843-{role}.tmp"
                    with contextlib.suppress(FileNotFoundError):
                        tmp.unlink()
                    tmp.symlink_to(pair.path)
                    os.replace(tmp, link)
            self._plugged.set()

    def _unplug(self) -> None:
        with self._lock:
            self._plugged.clear()
            for pair in (self._cli, self._data):
                if pair is not None:
                    pair.close()
            self._cli = self._data = None
            if self.link_dir is not None:
                for role in ("cli", "data"):
                    with contextlib.suppress(FileNotFoundError):
                        (self.link_dir / f"awr1843-{role}").unlink()

    def _reset_device_state(self) -> None:
        with self._lock:
            self._running.clear()
            self._config: dict[str, list[str]] = {}
            self._period_s = self.default_period_s
            self._frame_number = self.first_frame_number
            self._boot_time = time.monotonic()
            self._first_contact = True

    # ------------------------------------------------------------------ CLI
    def _cli_loop(self) -> None:
        line = bytearray()
        while not self._stop.is_set():
            if not self._plugged.wait(0.05):
                line.clear()
                continue
            with self._lock:
                fd = self._cli.master if self._cli is not None else -1
            if fd < 0:
                continue
            try:
                ready, _, _ = select.select([fd], [], [], 0.05)
                if not ready:
                    continue
                data = os.read(fd, 1024)
            except OSError:
                continue  # unplugged under our feet, or nobody has the slave open
            for byte in data:
                if byte in (0x0A, 0x0D):
                    self._answer(fd, bytes(line))
                    line.clear()
                else:
                    line.append(byte)
                    self._write_cli(fd, bytes([byte]))  # the UART driver echoes every character

    def _answer(self, fd: int, raw: bytes) -> None:
        with self._lock:
            if self._first_contact and self.boot_garbage:
                raw = self.boot_garbage + raw
                self._write_cli(fd, self.boot_garbage)
            self._first_contact = False
            if self.garbled_lines > 0 and raw.strip():
                self.garbled_lines -= 1
                raw = b"?" + raw
        text = raw.decode("ascii", errors="replace").strip()
        self.received_lines.append(text)
        reply = self._execute(text)
        self._write_cli(fd, b"\r\n" + b"".join(r.encode("ascii", "replace") + b"\r\n" for r in reply) + PROMPT)

    def _execute(self, text: str) -> list[str]:
        if not text:
            return []
        if text.startswith("%"):
            return ["Skipped"]
        words = text.split()
        name = words[0]
        if name not in KNOWN_COMMANDS:
            return [f"'{name}' is not recognized as a CLI command"]
        code = self.failing_lines.get(text, self.failing_lines.get(name))
        if code is not None:
            return ["Error: Invalid usage of the CLI command", f"Error {code}"]
        if name == "sensorStop":
            if not self._running.is_set():
                return ["Ignored: Sensor is already stopped", "Done"]
            self._running.clear()
            time.sleep(min(self._period_s, 0.2))  # the firmware finishes the frame in flight
            return ["Done"]
        if name == "sensorStart":
            with self._lock:
                configured = "frameCfg" in self._config and "profileCfg" in self._config
            if not configured:
                return ["Error: sensor is not configured", "Error -1"]
            if self.sensor_start_delay_s:
                time.sleep(self.sensor_start_delay_s)
            self._running.set()
            return ["Done"]
        with self._lock:
            if name == "flushCfg":
                self._config.clear()
            else:
                self._config[name] = words[1:]
                if name == "frameCfg" and len(words) >= 6:
                    with contextlib.suppress(ValueError):
                        self._period_s = float(words[5]) / 1000.0
        return ["Done"]

    def _write_cli(self, fd: int, data: bytes) -> None:
        with contextlib.suppress(OSError):
            os.write(fd, data)

    # ------------------------------------------------------------------ data
    def _data_loop(self) -> None:
        next_t: float | None = None
        while not self._stop.is_set():
            if not (self._running.is_set() and self._plugged.is_set()):
                next_t = None
                self._stop.wait(0.02)
                continue
            now = time.monotonic()
            if next_t is None:
                next_t = now + self._period_s  # first frame one period after sensorStart
            if now < next_t:
                self._stop.wait(min(next_t - now, 0.05))
                continue
            next_t += self._period_s
            self._emit_frame(time.monotonic())

    def _tlv_flags(self) -> tuple[bool, bool, bool, int]:
        """(points+side info, range profile, stats+temperature, range bins) from guiMonitor/profileCfg."""
        with self._lock:
            gui = self._config.get("guiMonitor")
            prof = self._config.get("profileCfg")
        flags = [int(float(v)) for v in gui[-6:]] if gui and len(gui) >= 6 else [1, 0, 0, 0, 0, 0]
        bins = 256
        if prof and len(prof) >= 10:
            with contextlib.suppress(ValueError):
                bins = 1 << max(0, math.ceil(math.log2(int(float(prof[9])))))
        return flags[0] == 1, flags[1] == 1, flags[5] == 1, bins

    def _emit_frame(self, now: float) -> None:
        with self._lock:
            number = self._frame_number
            self._frame_number += 1
            cycles = int((now - self._boot_time) * CPU_CLOCK_HZ)
        side_info, with_profile, with_stats, bins = self._tlv_flags()
        pts = self.frame_source(number, now)
        frame = encode_frame(
            number,
            pts.xyz_ti,
            pts.doppler,
            pts.snr_db,
            pts.noise_db,
            time_cpu_cycles=cycles,
            version=self.version,
            platform=self.platform,
            range_profile=np.full(bins, 10.0) if with_profile else None,
            stats=(700, 7300, 83000, 0, 0, 0) if with_stats else None,
            temperature=(0, int((now - self._boot_time) * 1000), 40, 40, 41, 40, 42, 42, 43, 43, 42, 41)
            if with_stats
            else None,
            side_info=side_info,
        )
        intact = True
        if number in self.faults.delete:
            off, length = self.faults.delete[number]
            frame = frame[:off] + frame[off + length :]
            intact = False
        if number in self.faults.truncate:
            frame = frame[: self.faults.truncate[number]]
            intact = False
        payload = self.faults.garbage_before.get(number, b"") + frame
        if self._write_data(payload):
            self.frames_sent.append(SentFrame(number, len(frame), intact))

    def _write_data(self, data: bytes) -> bool:
        """Write like a UART with a small FIFO: wait a little for room, then drop (and count) the rest."""
        view = memoryview(data)
        while view:
            with self._lock:
                fd = self._data.master if self._data is not None else -1
            if fd < 0 or self._stop.is_set():
                return False
            try:
                _, ready, _ = select.select([], [fd], [], 0.2)
                if not ready:
                    self.bytes_dropped += len(view)
                    return False
                view = view[os.write(fd, view) :]
            except BlockingIOError:
                continue
            except OSError:
                return False
        return True
