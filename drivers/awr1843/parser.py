"""Streaming decoder (and encoder) for the data port of TI's mmWave out-of-box demo.

Frame = 40-byte header (magic ``02 01 04 03 06 05 08 07``), ``numTLVs`` type-length-value items whose
length counts the payload only, then 0..31 filler bytes up to a multiple of 32. See
``shared/specs/awr1843-uart.md`` section 2.

Why the parser is this defensive: a 921600-baud UART behind a USB bridge drops bytes when the host
falls behind, the magic word can occur by chance inside float payloads, and recordings start and end
mid-frame. So every header is sanity-checked before its length is trusted, a frame whose declared
length runs into the next frame's (plausible) header is dropped as damaged, and any failure resyncs on
the next magic word. Whatever happens, it costs at most the damaged frame; every byte is accounted for:

    bytes_received == bytes in delivered frames + bytes_skipped + buffered_bytes

Given the ``ExpectedStream`` of the configuration the daemon sent (``expected.py``), a well-formed frame of another
configuration is rejected whole and counted (``frames_rejected``), never decoded into points.

Frames: points arrive in TI axes (x right, y boresight, z up), go through ``TI_TO_FRD`` into the
sensor-FRD frame and then through the configured ``Mount`` into the body FRD frame. The velocity is the
radial (line-of-sight) speed, a scalar, so the mount does not change it.

Stamps: a frame is stamped on the host clock at the read that found its header; when a read comes late (a busy
host, a stalled USB bridge) it returns several frames at once. With the profile known, each frame's stamp is its
number times the frame period, shifted by the least delay seen (``_frame_time``), so that frames keep the radar's
own spacing: stamped a couple of milliseconds apart, a still boat's returns from three frames read the position
noise as metres per second of speed.
"""

from __future__ import annotations

import logging
import math
import struct
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

from drivers.awr1843.profile import RadarProfile
from drivers.frames import RadarFrame
from drivers.least_delay import LeastDelayOffset
from drivers.mount import TI_TO_FRD, Mount

if TYPE_CHECKING:
    from drivers.awr1843.expected import ExpectedStream

log = logging.getLogger(__name__)

# s of host time over which a frame's stamp takes the least delay of any frame (drivers/least_delay.py): the VLP-16's
# device clock window, 20 frames at 10 Hz.
CLOCK_WINDOW_S = 2.0
REJECTION_LOG_INTERVAL_S = 60.0  # rejected frames: the first is logged at once, then one summary a minute at most

MAGIC = bytes.fromhex("0201040306050807")
HEADER_LEN = 40
HEADER_LEN_XWR14XX = 36  # the xWR14xx demo has no subFrameNumber
PLATFORMS: dict[int, str] = {
    0xA1443: "xWR14xx",
    0xA1642: "xWR16xx",
    0xA1843: "xWR18xx",
    0xA6843: "xWR68xx",
    0xA6443: "xWR64xx",
    0xA2944: "AWR2944",
    0xA6432: "xWRL6432",
    0xA1432: "xWRL1432",
}

TLV_POINTS = 1
TLV_RANGE_PROFILE = 2
TLV_NOISE_PROFILE = 3
TLV_AZIMUTH_HEAT_MAP = 4
TLV_RANGE_DOPPLER_HEAT_MAP = 5
TLV_STATS = 6
TLV_SIDE_INFO = 7
TLV_AZ_EL_HEAT_MAP = 8
TLV_TEMPERATURE = 9

_HEADER = struct.Struct("<8sIIIIIIII")  # magic, version, totalPacketLen, platform, frame, cycles, N, TLVs, sub
_HEADER_14XX = struct.Struct("<8sIIIIIII")
_TL = struct.Struct("<II")
_TEMPERATURE = struct.Struct("<iI10h")
_Q_DESCRIPTOR = struct.Struct("<HH")

POINT_DTYPE = np.dtype([("x", "<f4"), ("y", "<f4"), ("z", "<f4"), ("velocity", "<f4")])
SIDE_INFO_DTYPE = np.dtype([("snr", "<i2"), ("noise", "<i2")])
# SDK 1.x/2.x detected object, coordinates in Q(xyzQFormat) metres
Q_POINT_DTYPE = np.dtype(
    [("range_idx", "<u2"), ("doppler_idx", "<i2"), ("peak", "<u2"), ("x", "<i2"), ("y", "<i2"), ("z", "<i2")]
)
STATS_FIELDS = (
    "interframe_processing_time_us",
    "transmit_output_time_us",
    "interframe_processing_margin_us",
    "interchirp_processing_margin_us",
    "active_frame_cpu_load_pct",
    "interframe_cpu_load_pct",
)
TEMPERATURE_SENSORS = ("rx0", "rx1", "rx2", "rx3", "tx0", "tx1", "tx2", "pm", "dig0", "dig1")

# Beyond these a "point" is a corrupted float, not a reflection.
_MAX_ABS_COORD_M = 1000.0
_MAX_ABS_VELOCITY_MPS = 1000.0


@dataclass(frozen=True)
class FrameHeader:
    version: int
    total_len: int
    platform: int
    frame_number: int
    time_cpu_cycles: int
    num_points: int
    num_tlvs: int
    sub_frame: int
    header_len: int

    @property
    def sdk_version(self) -> tuple[int, int, int, int]:
        v = self.version
        return (v >> 24 & 0xFF, v >> 16 & 0xFF, v >> 8 & 0xFF, v & 0xFF)


@dataclass
class ParserStats:
    """Counters of one stream. ``frames_dropped`` = damaged frames seen; ``frames_lost`` = frame-number gaps."""

    bytes_received: int = 0
    bytes_skipped: int = 0  # garbage, rejected headers and damaged frames
    frames_ok: int = 0
    frames_dropped: int = 0
    frames_lost: int = 0
    headers_rejected: int = 0  # magic word found, header implausible (chance magic or corruption)
    points_dropped: int = 0  # non-finite or absurd coordinates inside an otherwise sound frame
    frame_number_resets: int = 0  # frame number went backwards (device reset, or two recordings joined)
    frames_rejected: int = 0  # sound frames of another configuration than the expected one (their bytes: skipped)
    last_rejection: str = ""  # why the last one was rejected

    def as_dict(self) -> dict[str, int | str]:
        return dict(self.__dict__)


def parse_header(buf: bytes | bytearray | memoryview, offset: int = 0) -> FrameHeader:
    """Decode a header that starts (magic included) at ``offset``; needs 40 bytes there."""
    (_, version, total, platform, frame_no, cycles, n, ntlv, sub) = _HEADER.unpack_from(buf, offset)
    if platform == 0xA1443:
        (_, version, total, platform, frame_no, cycles, n, ntlv) = _HEADER_14XX.unpack_from(buf, offset)
        return FrameHeader(version, total, platform, frame_no, cycles, n, ntlv, 0, HEADER_LEN_XWR14XX)
    return FrameHeader(version, total, platform, frame_no, cycles, n, ntlv, sub, HEADER_LEN)


def header_problem(h: FrameHeader, max_packet_len: int = 65536, max_points: int = 512, max_tlvs: int = 16) -> str:
    """Why a header cannot be trusted, or "" when it is plausible (spec section 2.8 step 3)."""
    major = h.version >> 24
    if not 1 <= major <= 3:
        return f"version major {major}"
    if h.platform not in PLATFORMS and (h.platform >> 16 != 0xA or h.platform & 0xF000 == 0):
        return f"platform {h.platform:#x}"
    if h.total_len % 32 or not HEADER_LEN <= h.total_len <= max_packet_len:
        return f"totalPacketLen {h.total_len}"
    if h.num_tlvs > max_tlvs or h.header_len + 8 * h.num_tlvs > h.total_len:
        return f"numTLVs {h.num_tlvs}"
    # no length check against N here: with guiMonitor detectedObjects = 0 the header still counts
    # points that are not sent; the TLV walk checks N against TLVs 1 and 7 when they are present
    if h.num_points > max_points:
        return f"numDetectedObj {h.num_points}"
    if h.sub_frame > 3:
        return f"subFrameNumber {h.sub_frame}"
    return ""


class FrameDamagedError(ValueError):
    """A frame whose TLVs do not add up; the stream continues at the next magic word."""


class FrameRejectedError(ValueError):
    """A sound frame of another configuration than the expected one; the stream continues after it."""


class RadarFrameParser:
    """Feed it the data port's bytes as they come; it returns the frames completed by each read.

    ``profile`` is needed only for SDK 2.x streams (their points carry Doppler indices); without it
    their velocities are NaN. ``expected``: frames of any other configuration are rejected (None: all decoded).
    """

    def __init__(
        self,
        profile: RadarProfile | None = None,
        mount: Mount | None = None,
        *,
        expected: ExpectedStream | None = None,
        max_packet_len: int = 65536,
        max_points: int = 512,
        max_tlvs: int = 16,
    ) -> None:
        self.profile = profile
        self.mount = mount if mount is not None else Mount()
        self.max_packet_len = max_packet_len
        self.max_points = max_points
        self.max_tlvs = max_tlvs
        self.expected = expected
        self.stats = ParserStats()
        self._firmware: int | None = None  # version word of the first frame accepted since the stream (re)started
        self._rejection_logged_at = -math.inf
        self._rejected_since_log = 0
        # One matrix from TI axes straight into the body frame: body = R_mount @ TI_TO_FRD @ p_ti + t.
        self._ti_to_body = self.mount.rotation @ TI_TO_FRD
        self._translation = self.mount.translation
        self._buf = bytearray()
        self._pos = 0
        self._pending: FrameHeader | None = None
        self._pending_stamp = 0.0
        self._inner_scanned = 8  # bytes of the pending frame already searched for a following magic word
        self._skipped_since_frame = 0
        self._last_frame_number: int | None = None
        self._warned: set[str] = set()
        self._clock = LeastDelayOffset(CLOCK_WINDOW_S)
        self._last_stamp = -math.inf

    # ------------------------------------------------------------------ stream
    @property
    def buffered_bytes(self) -> int:
        """Bytes received but not yet delivered or skipped (a partial frame, or a possible magic prefix)."""
        return len(self._buf) - self._pos

    def feed(self, data: bytes | bytearray | memoryview, host_time: float) -> list[RadarFrame]:
        """Add bytes read at ``host_time``; return the frames they completed, oldest first."""
        if data:
            try:
                self._buf += data
            except BufferError:  # a view of the buffer is held somewhere: grow a copy, leave the old one to it
                self._buf = self._buf + data
            self.stats.bytes_received += len(data)
        frames = self._drain(host_time, final=False)
        self._compact()
        return frames

    def finish(self, host_time: float = 0.0) -> list[RadarFrame]:
        """End of stream (end of a file): decide frames that were waiting for bytes after them.

        A complete frame that contains the start of an unverifiable magic word is dropped as damaged;
        an incomplete frame stays in ``buffered_bytes`` (a recording cut mid-frame).
        """
        frames = self._drain(host_time, final=True)
        self._compact()
        return frames

    def idle(self, host_time: float) -> list[RadarFrame]:
        """The line went quiet (a read returned nothing): decide a complete frame held only because its last bytes
        could be the start of a magic word (a frame whose side info ends in 0x02, as SNR and noise x 10 in 51-76 dB
        often do). The firmware sends a frame in one burst, then pauses until the next: without this, one frame in
        seven waited a whole frame period for the next frame's bytes. Decided as at the end of a stream; the bytes
        of a sound stream give the same frames either way."""
        return self.finish(host_time)

    def reset_stream(self) -> None:
        """Forget buffered bytes (after a reconnect they do not continue the old stream). Counters stay; the
        firmware version is learnt again from the next frame (a reconnect may meet another board, configured anew)."""
        self._skip(len(self._buf) - self._pos)
        self._pending = None
        self._firmware = None
        self._clock.reset()  # the delays before a reconnect say nothing of those after it
        self._compact()

    def _drain(self, host_time: float, final: bool) -> list[RadarFrame]:
        out: list[RadarFrame] = []
        buf = self._buf
        while True:
            if self._pending is None and not self._sync(host_time):
                break
            hdr = self._pending
            assert hdr is not None
            verdict = self._inner_magic(hdr, final)
            if verdict > 0:  # a plausible header inside our span: our length is wrong, or bytes went missing
                self._drop(f"frame {hdr.frame_number}: next frame header found {verdict} bytes into it")
                self._skip(verdict)
                continue
            if verdict < 0 or len(buf) - self._pos < hdr.total_len:
                break  # need more bytes
            try:
                frame = self._decode(memoryview(buf)[self._pos : self._pos + hdr.total_len], hdr)
            except FrameDamagedError as exc:
                self._drop(f"frame {hdr.frame_number}: {exc}")
                self._skip(len(MAGIC))  # resync from inside the frame: its length may be the broken part
                continue
            except FrameRejectedError as exc:
                self._pending = None
                self._skip(hdr.total_len)  # sound: its length holds, and nothing inside it is a frame of ours
                self._reject(hdr, str(exc), host_time)
                continue
            self._pos += hdr.total_len
            self._pending = None
            if self.expected is not None and self._firmware is None:
                self._firmware = hdr.version
            self._count_frame_number(hdr.frame_number)
            frame.stamp = self._frame_time(hdr.frame_number, self._pending_stamp)
            frame.bytes_skipped = self._skipped_since_frame
            self._skipped_since_frame = 0
            self.stats.frames_ok += 1
            out.append(frame)
        return out

    def _sync(self, host_time: float) -> bool:
        """Find the next plausible header at or after the read position; True when one is pending."""
        buf = self._buf
        while True:
            idx = buf.find(MAGIC, self._pos)
            if idx < 0:
                # keep a tail that may be the start of a magic word split across reads
                self._skip(max(0, len(buf) - self._pos - (len(MAGIC) - 1)))
                return False
            self._skip(idx - self._pos)
            if len(buf) - self._pos < HEADER_LEN:
                return False
            hdr = parse_header(buf, self._pos)
            problem = header_problem(hdr, self.max_packet_len, self.max_points, self.max_tlvs)
            if problem:
                self.stats.headers_rejected += 1
                log.debug("AWR1843 data: implausible header (%s), resyncing", problem)
                self._skip(1)
                continue
            self._pending = hdr
            self._pending_stamp = host_time
            self._inner_scanned = len(MAGIC)
            return True

    def _inner_magic(self, hdr: FrameHeader, final: bool) -> int:
        """Offset of a plausible next header inside the pending frame's span; 0 none; -1 cannot tell yet."""
        buf, start = self._buf, self._pos
        span_end = start + hdr.total_len
        end = min(len(buf), span_end + len(MAGIC) - 1)  # a magic may straddle the span's end
        while True:
            idx = buf.find(MAGIC, start + self._inner_scanned, end)
            if idx < 0:
                if not final and end < span_end + len(MAGIC) - 1:
                    # This read ended before the last place a magic word in the span could end: if the buffer's
                    # tail is the start of one, the next read decides (else a frame's fate hangs on read sizes).
                    for at in range(max(start + self._inner_scanned, end - (len(MAGIC) - 1)), min(end, span_end)):
                        if MAGIC.startswith(buf[at:end]):
                            self._inner_scanned = at - start
                            return -1
                self._inner_scanned = max(self._inner_scanned, end - start - (len(MAGIC) - 1))
                return 0
            if len(buf) - idx < HEADER_LEN:
                return idx - start if final else -1
            problem = header_problem(parse_header(buf, idx), self.max_packet_len, self.max_points, self.max_tlvs)
            if not problem:
                return idx - start
            self._inner_scanned = idx - start + 1

    def _skip(self, n: int) -> None:
        if n <= 0:
            return
        self._pos += n
        self.stats.bytes_skipped += n
        self._skipped_since_frame += n

    def _drop(self, why: str) -> None:
        self.stats.frames_dropped += 1
        self._pending = None
        log.warning("AWR1843 data: dropped damaged %s", why)

    def _compact(self) -> None:
        if self._pos:
            try:
                del self._buf[: self._pos]
            except BufferError:
                # A view of the buffer outlived its frame (a traceback, a debugger walking objects): a bytearray
                # with exports cannot shrink, and raising here would stop the radar's reader until a restart.
                self._buf = self._buf[self._pos :]
            self._pos = 0

    def _frame_time(self, frame_number: int, read_time: float) -> float:
        """When the frame was sent, on the host clock: its number times the frameCfg period (the radar's own frame
        timer) shifted by the least delay of the last CLOCK_WINDOW_S (drivers/least_delay.py), so that frames one
        late read returned together keep their period's spacing; never after the read that found it, nor before
        the frame before it. Without a profile the period is unknown and the read time stands."""
        if self.profile is None:
            return read_time
        device = frame_number * self.profile.frame_period_s
        self._clock.accept(device, read_time)
        least = self._clock.offset
        stamp = read_time if least >= read_time - device else min(read_time, device + least)
        stamp = max(stamp, self._last_stamp)
        self._last_stamp = stamp
        return stamp

    def _count_frame_number(self, number: int) -> None:
        last = self._last_frame_number
        self._last_frame_number = number
        if last is None:
            return
        step = number - last
        if step > 1:
            self.stats.frames_lost += step - 1
            log.warning("AWR1843 data: %d frame(s) lost between frame %d and %d", step - 1, last, number)
        elif step <= 0:
            self.stats.frame_number_resets += 1
            self._clock.reset()  # the radar counts from the start again: a new timeline for the stamps
            log.warning("AWR1843 data: frame number went from %d back to %d (device reset?)", last, number)

    def _reject(self, hdr: FrameHeader, why: str, host_time: float) -> None:
        st = self.stats
        st.frames_rejected += 1
        st.last_rejection = why
        self._rejected_since_log += 1
        if self._last_frame_number is not None and hdr.frame_number == self._last_frame_number + 1:
            # The same radar's numbering (reconfigured behind our back): not a loss when our frames resume.
            self._last_frame_number = hdr.frame_number
        if host_time - self._rejection_logged_at >= REJECTION_LOG_INTERVAL_S:
            board = why.startswith("platform")
            # a chip family check-config knows by name, else "any" (a hex code is no value it takes)
            setting = f'"{PLATFORMS[hdr.platform]}" (or "any")' if hdr.platform in PLATFORMS else '"any"'
            log.warning(
                "AWR1843 data: %d frame(s) of another configuration rejected%s (frame %d: %s); %s",
                self._rejected_since_log,
                "" if self._rejection_logged_at == -math.inf else f" in {host_time - self._rejection_logged_at:.0f} s",
                hdr.frame_number,
                why,
                f"another board sends them: if it is meant to, set [radar] platform = {setting}"
                if board
                else "the radar is not running the cfg this daemon sent: another program reconfigured it",
            )
            self._rejection_logged_at = host_time
            self._rejected_since_log = 0

    def _warn_once(self, key: str, message: str, *args: object) -> None:
        if key not in self._warned:
            self._warned.add(key)
            log.warning(message, *args)

    # ------------------------------------------------------------------ one frame
    def _decode(self, frame: memoryview, hdr: FrameHeader) -> RadarFrame:
        tlvs: dict[int, memoryview] = {}
        types: list[int] = []
        off = hdr.header_len
        for _ in range(hdr.num_tlvs):
            if off + _TL.size > hdr.total_len:
                raise FrameDamagedError(f"TLV header at byte {off} past the frame end {hdr.total_len}")
            tlv_type, length = _TL.unpack_from(frame, off)
            if tlv_type == 0 or tlv_type > 0xFFFF:
                raise FrameDamagedError(f"TLV type {tlv_type} at byte {off}")
            if off + _TL.size + length > hdr.total_len:
                raise FrameDamagedError(f"TLV {tlv_type} of {length} bytes runs past the frame end")
            if tlv_type in tlvs:
                raise FrameDamagedError(f"TLV {tlv_type} twice")
            tlvs[tlv_type] = frame[off + _TL.size : off + _TL.size + length]
            types.append(tlv_type)
            off += _TL.size + length
        if hdr.total_len - off >= 32:
            raise FrameDamagedError(f"{hdr.total_len - off} bytes after the last TLV (padding is at most 31)")
        if self.expected is not None:
            problem = self.expected.problem(hdr, tlvs, self._firmware)
            if problem:
                raise FrameRejectedError(problem)

        n = hdr.num_points
        legacy = hdr.version >> 24 < 3
        if legacy:
            xyz_ti, doppler = self._decode_q_points(tlvs.get(TLV_POINTS), n)
        else:
            xyz_ti, doppler = _decode_points(tlvs.get(TLV_POINTS), n)
        snr = np.full(len(doppler), np.nan)
        noise = np.full(len(doppler), np.nan)
        side = tlvs.get(TLV_SIDE_INFO)
        if side is not None:
            if len(side) != SIDE_INFO_DTYPE.itemsize * n or len(doppler) != n:
                raise FrameDamagedError(f"side-info TLV of {len(side)} bytes for {n} points")
            si = np.frombuffer(side, dtype=SIDE_INFO_DTYPE)
            snr = si["snr"] * 0.1
            noise = si["noise"] * 0.1

        if len(doppler):
            ok = (
                np.isfinite(xyz_ti).all(axis=1)
                & (np.abs(xyz_ti) <= _MAX_ABS_COORD_M).all(axis=1)
                & (np.isnan(doppler) | (np.abs(doppler) <= _MAX_ABS_VELOCITY_MPS))
            )
            if not ok.all():
                bad = int((~ok).sum())
                self.stats.points_dropped += bad
                log.warning("AWR1843 data: frame %d: %d point(s) with absurd values skipped", hdr.frame_number, bad)
                xyz_ti, doppler, snr, noise = xyz_ti[ok], doppler[ok], snr[ok], noise[ok]
        xyz = xyz_ti @ self._ti_to_body.T + self._translation

        result = RadarFrame(
            stamp=0.0,
            frame_number=hdr.frame_number,
            xyz=xyz,
            doppler=doppler,
            snr=snr,
            noise=noise,
            time_cpu_cycles=hdr.time_cpu_cycles,
            sdk_version=hdr.sdk_version,
            platform=hdr.platform,
            tlv_types=tuple(types),
        )
        for tlv_type, payload in tlvs.items():
            if tlv_type in (TLV_POINTS, TLV_SIDE_INFO):
                continue
            if tlv_type in (TLV_RANGE_PROFILE, TLV_NOISE_PROFILE):
                if len(payload) % 2:
                    raise FrameDamagedError(f"profile TLV {tlv_type} of odd length {len(payload)}")
                self._check_range_bins(tlv_type, len(payload) // 2)
                profile = np.frombuffer(payload, dtype="<u2") / 512.0  # Q9 log2 magnitude
                if tlv_type == TLV_RANGE_PROFILE:
                    result.range_profile = profile
                else:
                    result.noise_profile = profile
            elif tlv_type == TLV_STATS:
                if len(payload) != 4 * len(STATS_FIELDS):
                    raise FrameDamagedError(f"stats TLV of {len(payload)} bytes")
                values = struct.unpack_from(f"<{len(STATS_FIELDS)}I", payload)
                result.stats = dict(zip(STATS_FIELDS, values, strict=True))
            elif tlv_type == TLV_TEMPERATURE:
                if len(payload) != _TEMPERATURE.size:
                    raise FrameDamagedError(f"temperature TLV of {len(payload)} bytes")
                valid, time_ms, *temps = _TEMPERATURE.unpack_from(payload)
                temperature = {"valid": 1.0 if valid == 0 else 0.0, "time_ms": float(time_ms)}
                temperature.update(zip(TEMPERATURE_SENSORS, map(float, temps), strict=True))
                result.temperature = temperature
            else:  # heat maps (4, 5, 8) and types of other demos: kept raw for whoever wants them
                result.extra[tlv_type] = bytes(payload)
        return result

    def _decode_q_points(self, payload: memoryview | None, n: int) -> tuple[np.ndarray, np.ndarray]:
        """SDK 1.x/2.x: {u16 count, u16 xyzQFormat} then count x 12-byte objects with Q-format x/y/z."""
        if payload is None or len(payload) == 0:
            return np.zeros((0, 3)), np.zeros(0)
        if len(payload) != _Q_DESCRIPTOR.size + Q_POINT_DTYPE.itemsize * n:
            raise FrameDamagedError(f"SDK 2.x points TLV of {len(payload)} bytes for {n} points")
        count, q = _Q_DESCRIPTOR.unpack_from(payload)
        if count != n or q > 15:
            raise FrameDamagedError(f"SDK 2.x points descriptor {count} objects, Q{q}, header says {n}")
        objs = np.frombuffer(payload, dtype=Q_POINT_DTYPE, offset=_Q_DESCRIPTOR.size)
        scale = 1.0 / (1 << q)
        xyz = np.stack([objs["x"], objs["y"], objs["z"]], axis=1) * scale
        if self.profile is None:
            self._warn_once(
                "no-profile",
                "AWR1843 data: SDK 2.x points carry Doppler indices; without the radar cfg their velocity is NaN",
            )
            return xyz, np.full(n, np.nan)
        nd = self.profile.num_doppler_bins
        idx = objs["doppler_idx"].astype(np.int64)
        idx = np.where(idx >= nd // 2, idx - nd, idx)  # some SDK 1.x builds send 0..Nd-1 unsigned
        return xyz, idx * self.profile.velocity_resolution_mps

    def _check_range_bins(self, tlv_type: int, bins: int) -> None:
        if self.profile is not None and bins != self.profile.num_range_bins:
            self._warn_once(
                "range-bins",
                "AWR1843 data: TLV %d has %d range bins but the cfg %s implies %d: is it the cfg the radar runs?",
                tlv_type,
                bins,
                self.profile.source,
                self.profile.num_range_bins,
            )


def _decode_points(payload: memoryview | None, n: int) -> tuple[np.ndarray, np.ndarray]:
    """SDK 3.x: N x {float x, y, z, velocity}; an empty TLV 1 (zero-object frames) is legal."""
    if payload is None or len(payload) == 0:
        if n and payload is not None:
            raise FrameDamagedError(f"empty points TLV but numDetectedObj = {n}")
        return np.zeros((0, 3)), np.zeros(0)
    if len(payload) != POINT_DTYPE.itemsize * n:
        raise FrameDamagedError(f"points TLV of {len(payload)} bytes for {n} points")
    pts = np.frombuffer(payload, dtype=POINT_DTYPE)
    with np.errstate(invalid="ignore"):  # a signalling NaN from a damaged float; such points are dropped later
        xyz = np.stack([pts["x"], pts["y"], pts["z"]], axis=1).astype(np.float64)
        return xyz, pts["velocity"].astype(np.float64)


# ---------------------------------------------------------------------- encoder
def encode_frame(
    frame_number: int,
    xyz_ti: np.ndarray,
    doppler: np.ndarray,
    snr_db: np.ndarray | float,
    noise_db: np.ndarray | float,
    time_cpu_cycles: int = 0,
    version: tuple[int, int, int, int] = (3, 6, 0, 0),
    platform: int = 0xA1843,
    range_profile: np.ndarray | None = None,
    stats: tuple[int, ...] | None = None,
    temperature: Mapping[str, float] | Sequence[float] | None = None,
    side_info: bool = True,
    *,
    noise_profile: np.ndarray | None = None,
    velocity_resolution: float | None = None,
    q_format: int = 9,
    sub_frame: int = 0,
    extra_tlvs: Sequence[tuple[int, bytes]] = (),
) -> bytes:
    """Build one data-port frame the way the OOB demo firmware does (for tests and the simulator).

    ``xyz_ti`` (N, 3) metres in TI axes, ``doppler`` (N,) m/s radial, ``snr_db``/``noise_db`` per point or
    scalars. TLV order 1, 7, 2, 3, 6, 9 as the firmware sends them; an empty TLV 1 (and no TLV 7) when
    N == 0; non-zero filler up to a multiple of 32. ``range_profile``/``noise_profile`` are log2
    magnitudes (as decoded); ``stats`` the six TLV 6 words; ``temperature`` either the decoded dict or
    (valid, time_ms, 10 temperatures). A ``version`` major < 3 writes the SDK 2.x Q-format TLV 1, which
    needs ``velocity_resolution`` (m/s per Doppler bin) and has no side info. ``extra_tlvs`` (type,
    payload) are appended before TLV 6 (heat maps, or types the decoder does not know).
    """
    xyz = np.asarray(xyz_ti, dtype=np.float64).reshape(-1, 3)
    n = xyz.shape[0]
    vel = np.broadcast_to(np.asarray(doppler, dtype=np.float64), (n,))
    legacy = version[0] < 3
    tlvs: list[tuple[int, bytes]] = []
    if legacy:
        if n:
            if velocity_resolution is None:
                raise ValueError("SDK 2.x points need velocity_resolution to encode Doppler indices")
            objs = np.zeros(n, dtype=Q_POINT_DTYPE)
            scale = float(1 << q_format)
            objs["x"], objs["y"], objs["z"] = np.round(xyz * scale).astype(np.int16).T
            objs["doppler_idx"] = np.round(vel / velocity_resolution).astype(np.int16)
            objs["range_idx"] = 0
            objs["peak"] = 1000
            tlvs.append((TLV_POINTS, _Q_DESCRIPTOR.pack(n, q_format) + objs.tobytes()))
    else:
        pts = np.zeros(n, dtype=POINT_DTYPE)
        pts["x"], pts["y"], pts["z"] = xyz.T
        pts["velocity"] = vel
        tlvs.append((TLV_POINTS, pts.tobytes()))  # empty when n == 0, as the firmware does
        if side_info and n:
            si = np.zeros(n, dtype=SIDE_INFO_DTYPE)
            si["snr"] = np.round(np.broadcast_to(np.asarray(snr_db, dtype=np.float64), (n,)) * 10.0)
            si["noise"] = np.round(np.broadcast_to(np.asarray(noise_db, dtype=np.float64), (n,)) * 10.0)
            tlvs.append((TLV_SIDE_INFO, si.tobytes()))
    for tlv_type, prof in ((TLV_RANGE_PROFILE, range_profile), (TLV_NOISE_PROFILE, noise_profile)):
        if prof is not None:
            q9 = np.clip(np.round(np.asarray(prof, dtype=np.float64) * 512.0), 0, 0xFFFF).astype("<u2")
            tlvs.append((tlv_type, q9.tobytes()))
    tlvs.extend((t, bytes(p)) for t, p in extra_tlvs)
    if stats is not None:
        if len(stats) != len(STATS_FIELDS):
            raise ValueError(f"stats needs {len(STATS_FIELDS)} values")
        tlvs.append((TLV_STATS, struct.pack(f"<{len(STATS_FIELDS)}I", *stats)))
    if temperature is not None:
        if isinstance(temperature, Mapping):
            valid = 0 if temperature.get("valid", 1.0) else 1
            values = [valid, int(temperature.get("time_ms", 0))]
            values += [round(temperature.get(k, 0.0)) for k in TEMPERATURE_SENSORS]
        else:
            values = [int(v) for v in temperature]
        tlvs.append((TLV_TEMPERATURE, _TEMPERATURE.pack(*values)))

    body = b"".join(_TL.pack(t, len(p)) + p for t, p in tlvs)
    content = HEADER_LEN + len(body)
    total = -(-content // 32) * 32
    pad_len = total - content
    if legacy:
        padding = b"\x0f" * pad_len  # SDK 2.1 fills with 0x0F
    else:  # SDK 3.x sends stale buffer bytes; any non-zero pattern that cannot form a magic word will do
        padding = bytes(((frame_number * 7 + i * 13) % 255) + 1 for i in range(pad_len))
    version_word = version[0] << 24 | version[1] << 16 | version[2] << 8 | version[3]
    header = _HEADER.pack(
        MAGIC,
        version_word,
        total,
        platform,
        frame_number & 0xFFFFFFFF,
        time_cpu_cycles & 0xFFFFFFFF,
        n,
        len(tlvs),
        sub_frame,
    )
    return header + body + padding


def describe_platform(platform: int) -> str:
    return PLATFORMS.get(platform, f"{platform:#x}")


def sdk_string(version: tuple[int, int, int, int]) -> str:
    return ".".join(str(v) for v in version)
