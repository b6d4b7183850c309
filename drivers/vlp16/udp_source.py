"""Live VLP-16 source: UDP data (port 2368) and position (port 8308) packets -> ``LidarScan`` per revolution.

Meant to run in one reader thread: ``scans(stop)`` blocks on the sockets with a short timeout, so a set
``stop`` is honoured within ``poll_s``. Bad input never raises: wrong sizes, other senders and garbage are
counted in ``stats`` and dropped. Data is taken from one sender only, ``accept_ip`` or else the first that
looks like a VLP-16 (``sender_lock.py``): other Velodynes on the network send to the same port. A silent
cable is logged (naming the port and the expected sender) at most once per ``silence_timeout_s`` while the
source keeps listening, because cables come back.

Bind to 0.0.0.0 for a sensor on its factory settings: it broadcasts to 255.255.255.255, and Linux does not
deliver broadcasts to a socket bound to a unicast address. A multicast group (newer firmware can send to one)
is bound and joined on every interface, since which one the sensor is cabled to is not known here.
"""

from __future__ import annotations

import errno
import ipaddress
import logging
import math
import selectors
import socket
import struct
import threading
import time
from collections.abc import Callable, Iterator

from drivers.frames import LidarScan
from drivers.mount import Mount
from drivers.vlp16.decoder import ScanAssembler
from drivers.vlp16.packet import DATA_PACKET_SIZE, DATA_PORT, POSITION_PORT
from drivers.vlp16.sender_lock import LOCK_TIMEOUT_S, SenderLock
from drivers.vlp16.source_stats import LidarSourceStats

log = logging.getLogger(__name__)

RCVBUF_BYTES = 4 * 1024 * 1024  # ~2 s of dual-return data; a reader stall must not drop packets
_RECV_BUFFER = 65536  # a merged or jumbo datagram is read whole so its real size is counted
_DRAIN_MAX = 512  # datagrams per socket per wake-up, so a flood cannot starve the stop check
SILENCE_REPEAT_S = 30.0  # a lasting outage is logged again this often (the health line shows it every 5 s)


class LidarPortError(OSError):
    """The UDP port cannot be bound (in use, address not on this host, privileged)."""


def _bind_udp(host: str, port: int, what: str) -> socket.socket:
    sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    try:
        # No SO_REUSEADDR: a second listener (another daemon, VeloView, a ROS driver) must be an error,
        # not a silent split of the packets between the two.
        sock.bind((host, port))
    except OSError as exc:
        sock.close()
        if exc.errno == errno.EADDRINUSE:
            msg = (
                f"VLP-16 {what} port: UDP {host}:{port} is already in use by another program "
                "(another usv-tracker, VeloView or a ROS velodyne driver?); stop it or configure another port"
            )
        elif exc.errno == errno.EADDRNOTAVAIL:
            msg = f"VLP-16 {what} port: cannot bind UDP {host}:{port}: {host} is not an address of this host"
        elif exc.errno == errno.EACCES:
            msg = f"VLP-16 {what} port: UDP port {port} needs privileges on this host"
        else:
            msg = f"VLP-16 {what} port: cannot bind UDP {host}:{port}: {exc.strerror}"
        raise LidarPortError(exc.errno, msg) from exc
    if _is_multicast(host):
        try:
            _join_group_everywhere(sock, host)
        except OSError as exc:
            sock.close()
            raise LidarPortError(
                exc.errno, f"VLP-16 {what} port: cannot join multicast group {host} on any interface: {exc.strerror}"
            ) from exc
    sock.setblocking(False)
    return sock


def _is_multicast(host: str) -> bool:
    try:
        return ipaddress.ip_address(host).is_multicast
    except ValueError:  # a host name: resolved by bind, never a group
        return False


def _join_group_everywhere(sock: socket.socket, group: str) -> None:
    """Join ``group`` on every interface that accepts it (struct ip_mreqn by interface index, Linux).

    Bound to the group address, the socket still receives only that group; joining on one interface only
    (the kernel's pick by route) misses a sensor cabled to another, and on a host without a default route
    picks none at all.
    """
    joined = 0
    last_error: OSError | None = None
    for index, _name in socket.if_nameindex():
        request = struct.pack("=4s4si", socket.inet_aton(group), socket.inet_aton("0.0.0.0"), index)
        try:
            sock.setsockopt(socket.IPPROTO_IP, socket.IP_ADD_MEMBERSHIP, request)
            joined += 1
        except OSError as exc:  # an interface that is down or cannot multicast
            last_error = exc
    if joined == 0:
        raise last_error or OSError(errno.ENODEV, "no network interface")
    log.info("UDP multicast group %s joined on %d interfaces", group, joined)


def _grow_receive_buffer(sock: socket.socket, wanted: int, port: int) -> int:
    """Ask for ``wanted`` bytes of socket buffer; return (and log) what the kernel granted."""
    force = getattr(socket, "SO_RCVBUFFORCE", None)
    granted_by_force = False
    if force is not None:
        try:  # beyond net.core.rmem_max, only with CAP_NET_ADMIN
            sock.setsockopt(socket.SOL_SOCKET, force, wanted)
            granted_by_force = True
        except OSError:
            pass
    if not granted_by_force:
        sock.setsockopt(socket.SOL_SOCKET, socket.SO_RCVBUF, wanted)
    # Linux reports twice the asked size (it counts its bookkeeping); anything below `wanted` is a cap.
    granted = sock.getsockopt(socket.SOL_SOCKET, socket.SO_RCVBUF)
    if granted < wanted:
        log.warning(
            "UDP port %d: receive buffer %d bytes granted, %d asked; raise it with "
            "`sysctl -w net.core.rmem_max=%d` to ride out reader stalls without losing packets",
            port,
            granted,
            wanted,
            wanted,
        )
    else:
        log.info("UDP port %d: receive buffer %d bytes", port, granted)
    return granted


class VelodyneUdpSource:
    """Listen for one VLP-16; iterate revolutions with ``scans(stop)``.

    ``accept_ip`` keeps only datagrams from that sender; None: the first sender that looks like a VLP-16,
    until it has been silent for ``lock_timeout_s``. ``clock`` is the host clock that stamps packets (and
    so scans); ``wall_clock`` only picks the hour of the sensor's clock.
    ``position_port=None`` disables the position socket; if that port is taken the source logs an error
    and runs without PPS/NMEA status, because point data matter more than telemetry.
    """

    def __init__(
        self,
        host: str = "0.0.0.0",
        port: int = DATA_PORT,
        position_port: int | None = POSITION_PORT,
        accept_ip: str | None = None,
        mount: Mount | None = None,
        cut_angle: float | None = math.pi,
        model: str | None = "VLP16",
        min_range_m: float = 0.1,
        max_range_m: float = 200.0,
        silence_timeout_s: float = 2.0,
        lock_timeout_s: float = LOCK_TIMEOUT_S,
        rcvbuf_bytes: int = RCVBUF_BYTES,
        poll_s: float = 0.1,
        batch_s: float = 0.03,
        clock: Callable[[], float] = time.monotonic,
        wall_clock: Callable[[], float] = time.time,
    ) -> None:
        self.host = host
        self.port = port
        self.position_port = position_port
        self.accept_ip = accept_ip or None
        self.silence_timeout_s = silence_timeout_s
        self.rcvbuf_bytes = rcvbuf_bytes
        self.poll_s = poll_s
        # After draining the socket, let packets gather for this long before the next wake-up: one wake per ~23
        # packets instead of one per packet cuts the reader's CPU from 6.9 to 4.0 % of a core (bench/drivers.py),
        # for at most 30 ms of extra latency on a 100 ms revolution. The 4 MB+ socket buffer holds seconds.
        self.batch_s = batch_s
        self.clock = clock
        self.wall_clock = wall_clock
        self.assembler = ScanAssembler(
            mount=mount, cut_angle=cut_angle, model=model, min_range_m=min_range_m, max_range_m=max_range_m
        )
        self.stats = LidarSourceStats()
        self.lock = SenderLock(self.stats, self.assembler.model, self.accept_ip, lock_timeout_s, port=port)
        self.rcvbuf_granted = 0
        self._data: socket.socket | None = None
        self._position: socket.socket | None = None
        self._buffer = bytearray(_RECV_BUFFER)
        self._silent_since: float = 0.0
        self._last_silence_log: float | None = None
        self.polls = 0  # wake-ups of the reader loop (a health counter; lets tests step an injected clock)
        self._caught_up = True  # the last wake-up read the data socket empty
        # Called with (port, payload, (src_ip, src_port)) for every datagram received on either port, before any check:
        # the recorder keeps the raw stream, bad packets and other senders included, so a replay meets what the daemon
        # met. ``port`` is the sensor's own (2368 data, 8308 position), whatever ports this source listens on.
        self.raw_sink: Callable[[int, bytes, tuple[str, int]], None] | None = None

    # --- sockets ------------------------------------------------------------------------------------------
    @property
    def is_open(self) -> bool:
        return self._data is not None

    @property
    def bound_port(self) -> int:
        """The data port actually bound (useful with port 0 in tests)."""
        if self._data is None:
            raise RuntimeError("source is not open")
        return int(self._data.getsockname()[1])

    @property
    def bound_position_port(self) -> int | None:
        return None if self._position is None else int(self._position.getsockname()[1])

    def open(self) -> None:
        """Bind the sockets now (``scans`` does it otherwise); raises ``LidarPortError`` naming the port."""
        if self._data is not None:
            return
        self._data = _bind_udp(self.host, self.port, "data")
        self.rcvbuf_granted = _grow_receive_buffer(self._data, self.rcvbuf_bytes, self.bound_port)
        self.lock.port = self.bound_port
        if self.position_port is not None:
            try:
                self._position = _bind_udp(self.host, self.position_port, "position")
            except LidarPortError as exc:
                log.error("%s; running without PPS/NMEA status", exc.strerror)
                self._position = None
        log.info(
            "listening for VLP-16 data on UDP %s:%d%s%s",
            self.host,
            self.bound_port,
            "" if self._position is None else f", position on {self.bound_position_port}",
            "" if self.accept_ip is None else f", accepting only {self.accept_ip}",
        )
        self._silent_since = self.clock()
        self._last_silence_log = None

    def close(self) -> None:
        for sock in (self._data, self._position):
            if sock is not None:
                sock.close()
        self._data = None
        self._position = None

    def __enter__(self) -> VelodyneUdpSource:
        self.open()
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    # --- reading ----------------------------------------------------------------------------------------
    def scans(self, stop: threading.Event) -> Iterator[LidarScan]:
        """Revolutions as they complete, until ``stop`` is set. Closes the sockets when it ends."""
        self.open()
        assert self._data is not None
        selector = selectors.DefaultSelector()
        selector.register(self._data, selectors.EVENT_READ, "data")
        if self._position is not None:
            selector.register(self._position, selectors.EVENT_READ, "position")
        try:
            while not stop.is_set():
                self._caught_up = True
                for key, _ in selector.select(timeout=self.poll_s):
                    if key.data == "data":
                        yield from self._drain_data(key.fileobj)  # type: ignore[arg-type]
                    else:
                        self._drain_position(key.fileobj)  # type: ignore[arg-type]
                    if stop.is_set():
                        break
                now = self.clock()
                for scan in self.assembler.flush_if_stalled(now):
                    self.stats.take_assembler(self.assembler)
                    yield scan
                self.stats.position_stale(now, self.silence_timeout_s, self.assembler)
                # Only with the socket read empty: after a reader stall the backlog holds the sender's packets too.
                if self._caught_up:
                    self.lock.expire(now)
                self.lock.report(now)
                self._check_silence(now)
                self.polls += 1
                if self.batch_s > 0:
                    stop.wait(self.batch_s)
        finally:
            selector.close()
            self.close()

    def _drain_data(self, sock: socket.socket) -> Iterator[LidarScan]:
        view = memoryview(self._buffer)
        lock = self.lock
        for _ in range(_DRAIN_MAX):
            try:
                n, address = sock.recvfrom_into(self._buffer)
            except (BlockingIOError, InterruptedError):
                return
            now = self.clock()
            payload = bytes(view[:n])
            if self.raw_sink is not None:
                self.raw_sink(DATA_PORT, payload, address)
            if lock.owns(address):
                lock.last_heard = now
                yield from self._take(now, payload, address)
                continue
            held = lock.offer(address, payload, now)
            if held:  # this datagram completed a sender's qualification: a new stream starts
                yield from self._restart_stream()
                for t, p in held:
                    yield from self._take(t, p, address)
                for t, p, _ in lock.held_positions:
                    self.stats.take_position(t, p, self.assembler)
        self._caught_up = False

    def _take(self, now: float, payload: bytes, address: tuple[str, int]) -> Iterator[LidarScan]:
        n = len(payload)
        if n != DATA_PACKET_SIZE:
            self.stats.wrong_size += 1
            log.debug("dropped %d-byte datagram from %s on port %d", n, address[0], self.port)
            return
        self.stats.packets += 1
        self.stats.bytes += n
        self.stats.last_packet_time = now
        if self.stats.silent:
            log.info("VLP-16 data on UDP port %d resumed after %.1f s", self.bound_port, now - self._silent_since)
            self.stats.silent = False
        self._silent_since = now
        completed = self.assembler.push(now, payload, self.wall_clock())
        self.stats.take_assembler(self.assembler)
        yield from completed

    def _restart_stream(self) -> Iterator[LidarScan]:
        """A sender took the lock: whatever came before was another sensor's, revolution, clock and PPS alike."""
        scans = self.assembler.restart()
        self.stats.take_assembler(self.assembler)
        self.stats.forget_position()
        yield from scans

    def _drain_position(self, sock: socket.socket) -> None:
        for _ in range(_DRAIN_MAX):
            try:
                n, address = sock.recvfrom_into(self._buffer)
            except (BlockingIOError, InterruptedError):
                return
            now = self.clock()
            if self.raw_sink is not None:
                self.raw_sink(POSITION_PORT, bytes(self._buffer[:n]), address)
            if self.lock.owns_host(address):
                self.stats.take_position(now, bytes(self._buffer[:n]), self.assembler)
            else:
                self.lock.offer_position(address, bytes(self._buffer[:n]), now)

    def _check_silence(self, now: float) -> None:
        quiet = now - self._silent_since
        if quiet < self.silence_timeout_s:
            return
        self.stats.silent = True
        # Said when it starts, then every SILENCE_REPEAT_S while it lasts: an outage of an hour is not 1,700 lines.
        repeat = max(self.silence_timeout_s, SILENCE_REPEAT_S)
        if self._last_silence_log is not None and now - self._last_silence_log < repeat:
            return
        self._last_silence_log = now
        sender = self.lock.describe()
        extra = []
        if self.stats.foreign_source:
            extra.append(
                f"{self.stats.foreign_source} datagrams from other senders ignored (last {self.stats.last_foreign})"
            )
        if self.stats.wrong_size:
            extra.append(f"{self.stats.wrong_size} wrong-size datagrams dropped")
        log.error(
            "no VLP-16 data on UDP %s:%d from %s for %.1f s (check power, cable, sensor IP and destination)%s",
            self.host,
            self.bound_port,
            sender,
            quiet,
            "; " + "; ".join(extra) if extra else "",
        )
