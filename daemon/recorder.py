"""Record what the sensors and the autopilot sent, raw, so a run on the water can be replayed at the desk.

One directory per run, the same layout `usv-tracker simulate --write` produces and `run --fast` replays:
  lidar.pcap        every datagram on the VLP-16 data and position ports (bad ones too), host Unix time
  radar.dat         the data port's bytes exactly as read (TI's visualizer format) + radar.dat.times
  autopilot.tlog    every MAVLink message received from the autopilot (pymavlink tlog: 8-byte time + frame)
  radar.cfg         the chirp profile that was sent
Writes happen on the reader threads; each file has its own lock, and a disk error stops that recording (logged
once) but never the daemon.
"""

from __future__ import annotations

import logging
import shutil
import struct
import threading
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

from drivers.awr1843.timed_capture import TimedCaptureWriter
from drivers.vlp16.pcap import PcapWriter

log = logging.getLogger(__name__)


class _Guarded:
    """Serialise writes to one file and turn the first OSError into a log line and a stopped recording."""

    def __init__(self, name: str) -> None:
        self.name = name
        self.lock = threading.Lock()
        self.failed = False
        self.items = 0

    def run(self, fn: Callable[[], None]) -> None:
        if self.failed:
            return
        with self.lock:
            try:
                fn()
                self.items += 1
            except (OSError, ValueError) as exc:
                self.failed = True
                log.error("recording %s stopped: %s", self.name, exc)


def steady_wall_clock() -> Callable[[], float]:
    """Unix time read once, carried forward on the monotonic clock. A Pi boots on the clock it saved at shutdown and
    NTP or the GPS then steps it by minutes or hours: stamped with the stepping clock, a recording's sensors went
    back in time mid-file, and a replay fed the stretch before the step at once and dropped all but one scan of it."""
    wall0, mono0 = time.time(), time.monotonic()
    return lambda: wall0 + (time.monotonic() - mono0)


class Recorder:
    def __init__(self, directory: str | Path, wall_clock: Callable[[], float] | None = None) -> None:
        self.dir = Path(directory)
        self.dir.mkdir(parents=True, exist_ok=True)
        self.wall_clock = wall_clock if wall_clock is not None else steady_wall_clock()
        self._pcap: PcapWriter | None = None
        self._dat: TimedCaptureWriter | None = None
        self._tlog: Any = None
        self.guards = {k: _Guarded(k) for k in ("lidar", "radar", "autopilot")}

    def attach(self, lidar: Any, radar: Any, link: Any, radar_profile: str = "") -> None:
        if lidar is not None and hasattr(lidar, "raw_sink"):
            self._pcap = PcapWriter(self.dir / "lidar.pcap")
            lidar.raw_sink = self.on_lidar
        if radar is not None and hasattr(radar, "raw_sink"):
            self._dat = TimedCaptureWriter(self.dir / "radar.dat")
            radar.raw_sink = self.on_radar
            if radar_profile and Path(radar_profile).exists():
                shutil.copyfile(radar_profile, self.dir / "radar.cfg")
        if link is not None and hasattr(link, "raw_sink"):
            self._tlog = (self.dir / "autopilot.tlog").open("wb")
            link.raw_sink = self.on_mavlink
        log.info("recording raw captures to %s", self.dir)

    def on_lidar(self, port: int, payload: bytes, sender: tuple[str, int]) -> None:
        """``port``: the VLP-16's own (2368 or 8308) whatever the daemon listened on, so that a replay, Wireshark and
        VeloView read the capture without settings. The sender's address is kept as it was, port included: the
        replay locks onto a sender by address just as the live source did."""
        t = self.wall_clock()
        pcap = self._pcap
        if pcap is not None:
            self.guards["lidar"].run(
                lambda: pcap.write_udp(t, payload, src_ip=sender[0], dst_port=port, src_port=sender[1])
            )

    def on_radar(self, chunk: bytes) -> None:
        t = self.wall_clock()
        dat = self._dat
        if dat is not None:
            self.guards["radar"].run(lambda: dat.write(chunk, t))

    def on_mavlink(self, msg: Any) -> None:
        t = self.wall_clock()
        tlog = self._tlog
        if tlog is not None:
            self.guards["autopilot"].run(lambda: tlog.write(struct.pack(">Q", int(t * 1e6)) + bytes(msg.get_msgbuf())))

    def close(self) -> None:
        for name, f in (("lidar", self._pcap), ("radar", self._dat), ("autopilot", self._tlog)):
            if f is not None:
                with self.guards[name].lock:
                    f.close()
        self._pcap = self._dat = self._tlog = None
