"""Assemble VLP-16 data packets into one ``LidarScan`` per revolution, in the body frame.

Packets go in one at a time as ``(host_time, payload)``; velodyne-decoder turns the packets of a
revolution into points (its ``ScanDecoder``, so the revolution boundary, the clocks and the bookkeeping
stay here where they can be tested). What this module adds around it:

* **Revolution cut at a fixed bearing.** With ``cut_angle`` set, the packet whose azimuth span contains
  the cut is decoded on its own and its points are split by their azimuth, so every revolution starts
  exactly at the cut and no point is dropped or duplicated. The default cut is astern (pi): an object
  dead ahead is never split between two scans. ``cut_angle=None`` reproduces velodyne-decoder's own
  rule (close after a full turn from wherever the stream started, whole packets), which is what the
  capture counts in ``shared/fixtures/vlp16/SOURCES.md`` were measured with.
* **Device clock.** The packet stamp is microseconds past the hour. The hour comes from the previous
  packet while the stream is continuous (so the wrap at 3.6e9 us inside a revolution is seamless) and
  from the wall clock when (re)starting. velodyne-decoder is then handed the resolved device time as its
  "host" stamp, so its own +-30 min hour guess can never disagree with ours.
* **Host clock per point.** Arrival times jitter by whole scheduler slices; the device clock does not.
  Point times are device times shifted onto the host clock by the smallest (host - device) seen over the
  last ``clock_window_s`` -- the packet that waited least in buffers is the best estimate of the offset.
* **Bookkeeping.** Wrong-size and malformed payloads are counted and never reach velodyne-decoder;
  gaps in the 1327.104 us packet clock count as missing packets; a stalled stream flushes its partial
  revolution; early firmware's HDL-32E product byte is patched when the model is configured.

Frames: velodyne-decoder returns sensor FLU (x forward, y left, z up, vertical beam offsets applied).
One matrix, ``mount.rotation @ FLU_TO_FRD``, takes the points to body FRD.
"""

from __future__ import annotations

import logging
import math
from dataclasses import dataclass, field

import numpy as np
import velodyne_decoder as vd

from drivers.frames import LidarScan
from drivers.least_delay import LeastDelayOffset
from drivers.mount import FLU_TO_FRD, Mount
from drivers.vlp16.packet import (
    AZIMUTH_UNITS,
    BLOCKS_PER_PACKET,
    DATA_PACKET_SIZE,
    FIRING_INTERVAL_US,
    LASERS,
    MICROSECONDS_PER_HOUR,
    MODEL_PRODUCTS,
    PRODUCT_MODELS,
    RETURN_MODE_NAMES,
    SEQUENCE_US,
    DataPacketHeader,
    data_packet_problem,
    read_data_header,
)

log = logging.getLogger(__name__)

HOUR_S = MICROSECONDS_PER_HOUR * 1e-6
# A gap in the device clock beyond this many packet periods means packets were lost (spec section 7).
MISSING_GAP_PERIODS = 1.5
# Device-clock jumps this large (either way) are a clock reset (reboot, PPS lock), not packet loss.
CLOCK_JUMP_S = 1.0
# A packet older than its predecessor by more than this is a clock stepping back, not reordering: a LAN
# reorders by a packet or two (1-3 ms). Dropping packets until the clock caught up again lost up to a second
# of data, and the offset window then stamped scans that far in the past for its 2 s.
REORDER_WINDOW_S = 0.05
# A drop in azimuth (relative to the cut) bigger than this between packets is a pass over the cut.
_WRAP_DROP_CDEG = 9000
# Offset of a packet's last firing slot from its stamp (block 11 sequence B laser 15; dual: block 10/11).
_LAST_FIRING_US = {False: 23 * SEQUENCE_US + (LASERS - 1) * FIRING_INTERVAL_US, True: 11 * SEQUENCE_US + 34.56}


class ModelError(ValueError):
    """A model name velodyne-decoder does not know."""


def normalise_model(model: str | None) -> str | None:
    """'VLP-16', 'vlp16', 'VLP16' -> 'VLP16' (velodyne-decoder's ``Model`` member names); 'auto' -> None."""
    if model is None or model.strip().lower() in ("", "auto"):
        return None
    key = model.replace("-", "").replace("_", "").replace(" ", "").upper()
    for name in vd.Model.__members__:
        if name.upper() == key:
            return name
    raise ModelError(f"unknown LiDAR model {model!r}; known: {', '.join(vd.Model.__members__)}")


@dataclass
class AssemblerStats:
    """Counters since start; read from any thread (plain ints, updated by the assembling thread)."""

    packets: int = 0  # data packets accepted into revolutions
    wrong_size: int = 0  # payloads that were not 1206 bytes
    malformed: int = 0  # 1206 bytes but bad block flags / azimuth / mode / timestamp
    wrong_product: int = 0  # product byte differs from the stream's model and no override is configured
    out_of_order: int = 0  # device timestamp not after the previous packet's
    missing: int = 0  # packets lost, from gaps in the device clock
    clock_resets: int = 0  # device clock jumped by more than a second
    stalls: int = 0  # partial revolutions flushed because the stream stopped
    decode_errors: int = 0  # batches velodyne-decoder refused (packets dropped with them)
    patched_product: int = 0  # packets whose product byte was rewritten for the configured model
    scans: int = 0
    points: int = 0
    last_problem: str = ""


@dataclass
class _Packet:
    payload: bytes
    header: DataPacketHeader
    device_time: float  # resolved: Unix seconds on the sensor's clock
    host_time: float


@dataclass
class _Revolution:
    head: _Packet | None = None  # straddler carried over from the previous cut: keep its post-cut points
    body: list[_Packet] = field(default_factory=list)
    tail: _Packet | None = None  # straddler that closed this revolution: keep its pre-cut points
    missing: int = 0
    packets: int = 0  # packets that arrived while this revolution was open

    def all_packets(self) -> list[_Packet]:
        out = [self.head] if self.head is not None else []
        out.extend(self.body)
        if self.tail is not None:
            out.append(self.tail)
        return out

    def empty(self) -> bool:
        return self.head is None and not self.body and self.tail is None


class DeviceClock:
    """Resolves microseconds-past-the-hour to absolute sensor time and maps it onto the host clock."""

    def __init__(self, window_s: float = 2.0) -> None:
        self._last_device: float | None = None
        self._last_host: float | None = None
        self._least = LeastDelayOffset(window_s)

    def reset(self) -> None:
        self._last_device = None
        self._last_host = None
        self._least.reset()

    def resolve(self, timestamp_us: int, host_time: float, wall_time: float) -> float:
        """Absolute device time of a packet: the hour chosen to keep the stream continuous.

        While packets keep coming, the reference is the previous packet's device time advanced by the host
        time elapsed, which carries the stream across the top of the hour without a jump; otherwise the
        wall clock (the sensor's own hour is unknown without GPS, so +-30 min of the wall clock it is).
        """
        if self._last_device is not None and self._last_host is not None and abs(host_time - self._last_host) < 60:
            reference = self._last_device + (host_time - self._last_host)
        else:
            reference = wall_time
        seconds = timestamp_us * 1e-6
        device = math.floor(reference / HOUR_S) * HOUR_S + seconds
        if device - reference > HOUR_S / 2:
            device -= HOUR_S
        elif reference - device > HOUR_S / 2:
            device += HOUR_S
        return device

    def accept(self, device_time: float, host_time: float) -> None:
        self._last_device = device_time
        self._last_host = host_time
        self._least.accept(device_time, host_time)

    @property
    def offset(self) -> float:
        """Host time minus device time (s), the least-delayed packet of the window."""
        return self._least.offset

    @property
    def last_device_time(self) -> float | None:
        return self._last_device


class ScanAssembler:
    """Packets in, one body-frame ``LidarScan`` per revolution out. Not thread-safe: one reader owns it.

    ``cut_angle`` is the sensor azimuth (radians, clockwise from the sensor's forward axis seen from above,
    i.e. the bearing in sensor-FRD) where one revolution ends and the next begins; ``None`` closes a
    revolution after a full turn from where the stream started (velodyne-decoder's rule).
    ``model`` "VLP16" (default) decodes every packet as a VLP-16 whatever its product byte says (early
    firmware sends 0x21); ``None`` trusts the product byte.
    """

    def __init__(
        self,
        mount: Mount | None = None,
        cut_angle: float | None = math.pi,
        model: str | None = "VLP16",
        stall_timeout_s: float = 0.3,
        max_revolution_s: float = 0.35,
        min_range_m: float = 0.1,
        max_range_m: float = 200.0,
        clock_window_s: float = 2.0,
    ) -> None:
        self.mount = mount if mount is not None else Mount()
        self.cut_angle = None if cut_angle is None else float(cut_angle) % (2 * math.pi)
        self.model = normalise_model(model)
        self.stall_timeout_s = stall_timeout_s
        self.max_revolution_s = max_revolution_s
        self.min_range_m = min_range_m
        self.max_range_m = max_range_m
        self.clock = DeviceClock(clock_window_s)
        self.stats = AssemblerStats()
        self.pps_locked = False  # set by the source from position packets
        # Sensor FLU -> sensor FRD -> body FRD as one rotation.
        self._rotation = self.mount.rotation @ FLU_TO_FRD
        self._translation = self.mount.translation
        self._cut_cdeg = None if self.cut_angle is None else round(math.degrees(self.cut_angle) * 100) % AZIMUTH_UNITS
        self._forced_product = MODEL_PRODUCTS.get(self.model) if self.model is not None else None
        self._decoders: dict[str, vd.ScanDecoder] = {}
        self._rev = _Revolution()
        self._prev: _Packet | None = None
        self._prev_straddled = False
        self._stream_model: str | None = None
        self._stream_mode: int | None = None
        self._initial_azimuth: int | None = None  # cut_angle=None mode: coverage reference
        self._coverage = 0
        self._warned_patch = False

    # ----------------------------------------------------------------------------------------------------
    def push(
        self, host_time: float, payload: bytes | bytearray | memoryview, wall_time: float | None = None
    ) -> list[LidarScan]:
        """Add one UDP payload received at ``host_time``; return the revolutions it completed (0, 1 or 2).

        ``wall_time`` (Unix s) only picks the sensor clock's hour when the stream (re)starts; it defaults
        to ``host_time``, which is right for pcap replay (pcap time is Unix time).
        """
        out: list[LidarScan] = []
        problem = data_packet_problem(payload)
        if problem is not None:
            if len(payload) != DATA_PACKET_SIZE:
                self.stats.wrong_size += 1
            else:
                self.stats.malformed += 1
            self.stats.last_problem = problem
            log.debug("dropped data payload: %s", problem)
            return out
        data = bytes(payload)
        header = read_data_header(data)

        model = self._model_for(header.product_id)
        if model is None:
            self.stats.wrong_product += 1
            self.stats.last_problem = f"product byte 0x{header.product_id:02X}"
            return out
        if self._forced_product is not None and header.product_id != self._forced_product:
            data = data[:-1] + bytes((self._forced_product,))
            self.stats.patched_product += 1
            if not self._warned_patch:
                self._warned_patch = True
                log.warning(
                    "LiDAR reports product byte 0x%02X; decoding as %s as configured (early VLP-16 firmware "
                    "reports the HDL-32E code 0x21)",
                    header.product_id,
                    self.model,
                )

        # A stalled stream: hand out what we had before this packet starts something new.
        if self._prev is not None and host_time - self._prev.host_time > self.stall_timeout_s:
            out.extend(self._flush(reason="stall"))
        if self._stream_model is not None and (model != self._stream_model or header.return_mode != self._stream_mode):
            log.info(
                "LiDAR stream changed to %s/%s", model, RETURN_MODE_NAMES.get(header.return_mode, header.return_mode)
            )
            out.extend(self._flush(reason="mode change"))

        device_time = self.clock.resolve(header.timestamp_us, host_time, host_time if wall_time is None else wall_time)
        if self._prev is not None:
            dt = device_time - self._prev.device_time
            if dt <= 0 and dt > -REORDER_WINDOW_S:
                self.stats.out_of_order += 1
                self.stats.last_problem = "device timestamp not increasing"
                return out
            if dt >= CLOCK_JUMP_S or dt <= -REORDER_WINDOW_S:
                self.stats.clock_resets += 1
                log.warning("LiDAR device clock jumped by %.3f s; restarting revolution and clock offset", dt)
                out.extend(self._flush(reason="clock jump"))
                self.clock.reset()
                device_time = self.clock.resolve(
                    header.timestamp_us, host_time, host_time if wall_time is None else wall_time
                )
            elif dt > MISSING_GAP_PERIODS * header.period_us * 1e-6:
                lost = round(dt / (header.period_us * 1e-6)) - 1
                self._rev.missing += lost
                self.stats.missing += lost

        self._stream_model = model
        self._stream_mode = header.return_mode
        self.clock.accept(device_time, host_time)
        packet = _Packet(data, header, device_time, host_time)
        self.stats.packets += 1

        first = self._rev.all_packets()[0] if not self._rev.empty() else None
        if first is not None and device_time - first.device_time > self.max_revolution_s:
            # The cut is never reached (motor stopped, azimuth stuck): do not grow without bound.
            out.extend(self._flush(reason="revolution too long"))

        if self.cut_angle is None:
            out.extend(self._push_full_turn(packet))
        else:
            out.extend(self._push_cut(packet))
        self._prev = packet
        return out

    def flush(self) -> list[LidarScan]:
        """End of stream: the partial revolution, if any."""
        return self._flush(reason="end")

    def restart(self) -> list[LidarScan]:
        """Another sensor's stream follows (the source locked onto a new sender): hand out the partial revolution and
        forget the device clock, its offset to the host and the PPS state, which were the previous sensor's."""
        out = self._flush(reason="new sender")
        self.clock.reset()
        self.pps_locked = False
        self._stream_model = None
        self._stream_mode = None
        return out

    def flush_if_stalled(self, host_now: float) -> list[LidarScan]:
        """The partial revolution if no packet arrived for ``stall_timeout_s`` (call from the reader's idle path)."""
        if self._prev is not None and not self._rev.empty() and host_now - self._prev.host_time > self.stall_timeout_s:
            return self._flush(reason="stall")
        return []

    # ----------------------------------------------------------------------------------------------------
    def _model_for(self, product_id: int) -> str | None:
        if self.model is not None:
            return self.model
        return PRODUCT_MODELS.get(product_id)

    def _push_cut(self, packet: _Packet) -> list[LidarScan]:
        """Cut at ``cut_angle``: the straddling packet is split between the two revolutions by azimuth."""
        assert self._cut_cdeg is not None
        h = packet.header
        rel_first = (h.first_azimuth_cdeg - self._cut_cdeg) % AZIMUTH_UNITS
        span = (h.last_azimuth_cdeg - h.first_azimuth_cdeg) % AZIMUTH_UNITS
        steps = _block_steps(h.dual)
        # The packet's last firings sit up to one block step past the last block's azimuth.
        straddles = rel_first + span + span / steps >= AZIMUTH_UNITS
        wrapped_before = False
        if self._prev is not None and not self._prev_straddled:
            prev_rel = (self._prev.header.first_azimuth_cdeg - self._cut_cdeg) % AZIMUTH_UNITS
            wrapped_before = prev_rel - rel_first > _WRAP_DROP_CDEG
        self._prev_straddled = straddles
        out: list[LidarScan] = []
        if wrapped_before and not self._rev.empty():
            # The cut fell in the gap before this packet (lost packets, or a cut between two packets).
            out.extend(self._emit())
        self._rev.packets += 1
        if straddles:
            if self._rev.empty():
                # Nothing before it to close: keep the whole packet in the new revolution.
                self._rev.body.append(packet)
                return out
            self._rev.tail = packet
            out.extend(self._emit())
            self._rev.head = packet
        else:
            self._rev.body.append(packet)
        return out

    def _push_full_turn(self, packet: _Packet) -> list[LidarScan]:
        """velodyne-decoder's rule: close once the last-block azimuth has covered a full turn, whole packets."""
        azimuth = packet.header.last_azimuth_cdeg
        if self._initial_azimuth is None:
            self._initial_azimuth = azimuth
        self._rev.body.append(packet)
        self._rev.packets += 1
        coverage = (azimuth - self._initial_azimuth) % AZIMUTH_UNITS
        complete = self._coverage > AZIMUTH_UNITS // 2 and self._coverage > coverage
        self._coverage = coverage
        if complete:
            self._initial_azimuth = azimuth
            self._coverage = 0
            return self._emit()
        return []

    def _flush(self, reason: str) -> list[LidarScan]:
        out: list[LidarScan] = []
        if not self._rev.empty():
            if reason == "stall":
                self.stats.stalls += 1
            log.debug("flushing partial revolution (%s)", reason)
            out = self._emit()
        # Whatever comes next starts afresh: no straddler carry-over, no missing-packet gap across it.
        self._rev = _Revolution()
        self._prev = None
        self._prev_straddled = False
        self._initial_azimuth = None
        self._coverage = 0
        return out

    def _emit(self) -> list[LidarScan]:
        rev = self._rev
        self._rev = _Revolution()
        scan = self._build_scan(rev)
        return [] if scan is None else [scan]

    # ----------------------------------------------------------------------------------------------------
    def _decoder(self, model: str) -> vd.ScanDecoder:
        decoder = self._decoders.get(model)
        if decoder is None:
            config = vd.Config(
                model=vd.Model.__members__[model], min_range=self.min_range_m, max_range=self.max_range_m
            )
            decoder = self._decoders[model] = vd.ScanDecoder(config)
        return decoder

    def _decode(self, packets: list[_Packet], model: str) -> tuple[np.ndarray, np.ndarray] | None:
        """(points float32 (N, 8) in velodyne-decoder's columns, absolute device time per point float64)."""
        vector = vd.PacketVector()
        for p in packets:
            # Our resolved device time as the "host" stamp: velodyne-decoder then agrees on the hour.
            vector.append(vd.VelodynePacket(p.device_time, p.payload))
        try:
            _stamp, points = self._decoder(model).decode(vector)
        except RuntimeError as exc:
            self.stats.decode_errors += 1
            self.stats.last_problem = f"velodyne-decoder: {exc}"
            log.error("velodyne-decoder refused %d packets: %s", len(packets), exc)
            return None
        # Point times are relative to the last packet's device stamp.
        device_t = packets[-1].device_time + points[:, vd.PointField.time].astype(np.float64)
        return points, device_t

    def _past_cut_cdeg(self, points: np.ndarray) -> np.ndarray:
        """Azimuth past the cut in whole hundredths of a degree, 0..35999 (clockwise from sensor forward).

        velodyne-decoder places every firing at a whole 0.01 deg, so rounding recovers its azimuth exactly
        and a point lying on the cut goes to the same side every time (the new revolution).
        """
        assert self._cut_cdeg is not None
        x = points[:, vd.PointField.x].astype(np.float64)
        y = points[:, vd.PointField.y].astype(np.float64)
        azimuth = np.rint(np.degrees(np.arctan2(-y, x)) * 100.0).astype(np.int64)
        return (azimuth - self._cut_cdeg) % AZIMUTH_UNITS

    def _sweep(self, rev: _Revolution, packets: list[_Packet]) -> tuple[float, float]:
        """Sensor azimuths this scan's firings swept: (start, extent), radians clockwise from sensor forward.

        Block azimuths bound the sweep; a straddling packet cut at ``cut_angle`` contributes up to the cut only,
        and the last block's firings reach about one azimuth step further.
        """
        first, last = packets[0].header, packets[-1].header
        steps = _block_steps(last.dual)
        step = ((last.last_azimuth_cdeg - last.first_azimuth_cdeg) % AZIMUTH_UNITS) / steps
        start = first.first_azimuth_cdeg
        end = last.last_azimuth_cdeg + step
        if self._cut_cdeg is not None:
            if rev.head is not None:
                start = self._cut_cdeg
            if rev.tail is not None:
                end = self._cut_cdeg
        extent = (end - start) % AZIMUTH_UNITS
        full_turn = len(packets) * (steps + 1) * step >= AZIMUTH_UNITS
        if extent == 0 or (rev.head is not None and rev.tail is not None) or full_turn:
            extent = AZIMUTH_UNITS
        return math.radians(start / 100.0), math.radians(min(extent, AZIMUTH_UNITS) / 100.0)

    def _build_scan(self, rev: _Revolution) -> LidarScan | None:
        packets = rev.all_packets()
        if not packets:
            return None
        model = self._stream_model or self._model_for(packets[0].header.product_id) or "VLP16"
        errors_before = self.stats.decode_errors
        parts: list[tuple[np.ndarray, np.ndarray]] = []
        if rev.head is not None:
            decoded = self._decode([rev.head], model)
            if decoded is not None:
                keep = self._past_cut_cdeg(decoded[0]) < AZIMUTH_UNITS // 2
                parts.append((decoded[0][keep], decoded[1][keep]))
        if rev.body:
            decoded = self._decode(rev.body, model)
            if decoded is not None:
                parts.append(decoded)
        if rev.tail is not None:
            decoded = self._decode([rev.tail], model)
            if decoded is not None:
                keep = self._past_cut_cdeg(decoded[0]) >= AZIMUTH_UNITS // 2
                parts.append((decoded[0][keep], decoded[1][keep]))

        if parts:
            points = np.concatenate([p[0] for p in parts])
            device_t = np.concatenate([p[1] for p in parts])
        elif self.stats.decode_errors > errors_before:
            # Nothing decodable: an empty scan would tell the tracker "looked, saw nothing". Say nothing.
            return None
        else:
            points = np.zeros((0, 8), dtype=np.float32)
            device_t = np.zeros(0)
        sweep_start, sweep_extent = self._sweep(rev, packets)
        last = packets[-1]
        if device_t.size:
            stamp_device = float(device_t.max())
        else:
            stamp_device = last.device_time + _LAST_FIRING_US[last.header.dual] * 1e-6
        offset = self.clock.offset

        xyz_flu = points[:, :3].astype(np.float64)
        xyz = xyz_flu @ self._rotation.T + self._translation
        scan = LidarScan(
            stamp=stamp_device + offset,
            stamp_device=stamp_device,
            xyz=xyz,
            intensity=points[:, vd.PointField.intensity].astype(np.float32),
            ring=points[:, vd.PointField.ring].astype(np.uint8),
            t=device_t + offset,
            packets=rev.packets,
            packets_missing=rev.missing,
            return_mode=RETURN_MODE_NAMES.get(last.header.return_mode, "unknown"),
            model=model,
            pps_locked=self.pps_locked,
            sweep_start=sweep_start,
            sweep_extent=sweep_extent,
            packet_sweeps=_packet_sweeps(packets),
        )
        self.stats.scans += 1
        self.stats.points += scan.n_points
        return scan


def _block_steps(dual: bool) -> int:
    """Azimuth steps between a packet's first and last block: 11 in single-return mode; 5 in dual, where
    blocks come in pairs (strongest and last return) sharing one azimuth."""
    return BLOCKS_PER_PACKET // 2 - 1 if dual else BLOCKS_PER_PACKET - 1


def _packet_sweeps(packets: list[_Packet]) -> np.ndarray:
    """(P, 2) sensor azimuth start and extent (rad) of each packet's firings: first to last block azimuth plus
    one azimuth step (the last block's second sequence reaches about that far)."""
    first = np.array([p.header.first_azimuth_cdeg for p in packets], dtype=np.float64)
    last = np.array([p.header.last_azimuth_cdeg for p in packets], dtype=np.float64)
    steps = np.array([_block_steps(p.header.dual) for p in packets], dtype=np.float64)
    span = np.mod(last - first, AZIMUTH_UNITS)
    return np.radians(np.stack([first, span * (steps + 1.0) / steps], axis=1) / 100.0)
