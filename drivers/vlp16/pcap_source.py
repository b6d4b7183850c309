"""Replay a VLP-16 capture through the same ``ScanAssembler`` as the live source.

Host time is the capture's time, so a replay is deterministic: the same file gives the same scans with
the same stamps however fast it runs. ``speed=1`` paces packets at the recorded timing (a live-like
feed for the daemon), ``speed=None`` (or 0) goes as fast as the CPU allows.
"""

from __future__ import annotations

import logging
import math
import os
import threading
import time
from collections.abc import Callable, Iterator

from drivers.frames import LidarScan
from drivers.mount import Mount
from drivers.vlp16.decoder import ScanAssembler
from drivers.vlp16.packet import DATA_PACKET_SIZE, DATA_PORT, POSITION_PORT
from drivers.vlp16.pcap import PcapReader
from drivers.vlp16.source_stats import LidarSourceStats

log = logging.getLogger(__name__)

# Never sleep longer than this at once, so a set ``stop`` is honoured promptly even across a long pause
# in the capture.
_MAX_WAIT_S = 0.1


class VelodynePcapSource:
    """Iterate the revolutions of a pcap/pcapng capture with ``scans(stop)`` (same interface as the live source).

    The file is checked on construction: ``NotAPcapError`` for anything that is not a capture.
    """

    def __init__(
        self,
        path: str | os.PathLike[str],
        port: int = DATA_PORT,
        position_port: int | None = POSITION_PORT,
        accept_ip: str | None = None,
        speed: float | None = 1.0,
        mount: Mount | None = None,
        cut_angle: float | None = math.pi,
        model: str | None = "VLP16",
        min_range_m: float = 0.1,
        max_range_m: float = 200.0,
        clock: Callable[[], float] = time.monotonic,
    ) -> None:
        if speed is not None and (not math.isfinite(speed) or speed < 0):
            raise ValueError(f"replay speed must be a positive factor or None (as fast as possible), got {speed}")
        self.path = os.fspath(path)
        self.port = port
        self.position_port = position_port
        self.accept_ip = accept_ip or None
        self.speed = speed or None
        self.clock = clock
        ports = {port} if position_port is None else {port, position_port}
        self.reader = PcapReader(self.path, ports)  # raises NotAPcapError now, not in the reader thread
        self.assembler = ScanAssembler(
            mount=mount, cut_angle=cut_angle, model=model, min_range_m=min_range_m, max_range_m=max_range_m
        )
        self.stats = LidarSourceStats()
        self.finished = False

    def scans(self, stop: threading.Event | None = None) -> Iterator[LidarScan]:
        """Revolutions in capture order; the last partial one is flushed at the end of the file."""
        stop = stop or threading.Event()
        start_capture: float | None = None
        start_host = 0.0
        for datagram in self.reader:
            if stop.is_set():
                return
            t = datagram.timestamp_s
            if self.speed is not None:
                if start_capture is None:
                    start_capture, start_host = t, self.clock()
                due = start_host + (t - start_capture) / self.speed
                while (wait := due - self.clock()) > 0:
                    if stop.wait(min(wait, _MAX_WAIT_S)):
                        return
            if self.accept_ip is not None and datagram.src_ip != self.accept_ip:
                self.stats.foreign_source += 1
                self.stats.last_foreign_ip = datagram.src_ip
                continue
            if datagram.dst_port == self.port:
                if len(datagram.payload) != DATA_PACKET_SIZE:
                    self.stats.wrong_size += 1
                    continue
                self.stats.packets += 1
                self.stats.bytes += len(datagram.payload)
                self.stats.last_packet_time = t
                completed = self.assembler.push(t, datagram.payload)
                self.stats.take_assembler(self.assembler)
                yield from completed
            else:
                self.stats.take_position(t, datagram.payload, self.assembler)
        for scan in self.assembler.flush():
            self.stats.take_assembler(self.assembler)
            yield scan
        self.finished = True
        log.info(
            "%s: replay finished, %d scans from %d data packets (%d wrong size, %d missing)",
            self.path,
            self.stats.scans,
            self.stats.packets,
            self.stats.wrong_size,
            self.stats.missing,
        )
