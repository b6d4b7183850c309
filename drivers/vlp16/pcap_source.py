"""Replay a VLP-16 capture through the same ``ScanAssembler`` as the live source.

Host time is the capture's time, so a replay is deterministic: the same file gives the same scans with
the same stamps however fast it runs. Senders are locked exactly as live (``sender_lock.py``), on the capture's
clock: a recording of a network with two Velodynes replays one of them, the one the daemon took. ``speed=1`` paces
packets at the recorded timing (a live-like feed for the daemon), ``speed=None`` (or 0) goes as fast as the CPU allows.
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
from drivers.vlp16.sender_lock import LOCK_TIMEOUT_S, SenderLock
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
        lock_timeout_s: float = LOCK_TIMEOUT_S,
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
        self.lock = SenderLock(self.stats, self.assembler.model, self.accept_ip, lock_timeout_s, port=port)
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
            lock = self.lock
            lock.expire(t)  # a capture is read in order, so the backlog question of the live source does not arise
            lock.report(t)
            address = (datagram.src_ip, datagram.src_port)
            if datagram.dst_port == self.port:
                if lock.owns(address):
                    lock.last_heard = t
                    yield from self._take(t, datagram.payload)
                    continue
                held = lock.offer(address, datagram.payload, t)
                if held:  # a new stream starts: whatever came before was another sensor's
                    restarted = self.assembler.restart()
                    self.stats.take_assembler(self.assembler)
                    self.stats.forget_position()
                    yield from restarted
                    for ht, p in held:
                        yield from self._take(ht, p)
                    for ht, p, _ in lock.held_positions:
                        self.stats.take_position(ht, p, self.assembler)
            elif lock.owns_host(address):
                self.stats.take_position(t, datagram.payload, self.assembler)
            else:
                lock.offer_position(address, datagram.payload, t)
        for scan in self.assembler.flush():
            self.stats.take_assembler(self.assembler)
            yield scan
        self.finished = True
        log.info(
            "%s: replay finished, %d scans from %d data packets of %s (%d wrong size, %d missing, %d datagrams of "
            "other senders dropped)",
            self.path,
            self.stats.scans,
            self.stats.packets,
            self.stats.sender or "no sender",
            self.stats.wrong_size,
            self.stats.missing,
            self.stats.foreign_source,
        )

    def _take(self, t: float, payload: bytes) -> Iterator[LidarScan]:
        if len(payload) != DATA_PACKET_SIZE:
            self.stats.wrong_size += 1
            return
        self.stats.packets += 1
        self.stats.bytes += len(payload)
        self.stats.last_packet_time = t
        completed = self.assembler.push(t, payload)
        self.stats.take_assembler(self.assembler)
        yield from completed
