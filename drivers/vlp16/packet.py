"""VLP-16 UDP packet layout: constants, header checks, and an encoder/decoder for both packet kinds.

The byte layout follows ``shared/specs/vlp16.md`` (all fields little-endian). Decoding *points* is
velodyne-decoder's job (``decoder.py``); this module only reads the fixed header fields the driver needs
to route, time and validate packets, and builds real packets for the simulator and the tests. Everything
is done with numpy structured dtypes so a packet is one ``frombuffer``/``tobytes``, never a per-point loop.
"""

from __future__ import annotations

import struct
from dataclasses import dataclass

import numpy as np

# --- transport ------------------------------------------------------------------------------------------
DATA_PORT = 2368
POSITION_PORT = 8308
DATA_PACKET_SIZE = 1206
POSITION_PACKET_SIZE = 512

# --- data packet layout ---------------------------------------------------------------------------------
BLOCKS_PER_PACKET = 12
CHANNELS_PER_BLOCK = 32
LASERS = 16
BLOCK_FLAG = 0xEEFF  # bytes FF EE on the wire, read little-endian
DISTANCE_UNIT_M = 0.002
MAX_DISTANCE_M = 0xFFFF * DISTANCE_UNIT_M  # 131.07 m, the largest value the field can hold
AZIMUTH_UNITS = 36000  # hundredths of a degree per turn

RETURN_MODE_STRONGEST = 0x37
RETURN_MODE_LAST = 0x38
RETURN_MODE_DUAL = 0x39
RETURN_MODE_NAMES: dict[int, str] = {
    RETURN_MODE_STRONGEST: "strongest",
    RETURN_MODE_LAST: "last",
    RETURN_MODE_DUAL: "dual",
}

PRODUCT_HDL32E = 0x21
PRODUCT_VLP16 = 0x22
# Product byte -> the model name velodyne-decoder's ``Model`` enum uses.
PRODUCT_MODELS: dict[int, str] = {
    0x21: "HDL32E",
    0x22: "VLP16",
    0x23: "VLP32A",
    0x24: "PuckHiRes",
    0x28: "VLP32C",
    0xA1: "AlphaPrime",
}
MODEL_PRODUCTS: dict[str, int] = {name: code for code, name in PRODUCT_MODELS.items()}

# --- timing (spec section 4) ------------------------------------------------------------------------------
FIRING_INTERVAL_US = 2.304  # one laser
SEQUENCE_US = 55.296  # 16 firings + recharge
PACKET_PERIOD_US = 1327.104  # 24 sequences, single-return modes
PACKET_PERIOD_DUAL_US = 663.552  # 12 sequences, dual-return mode
PACKETS_PER_S = 1e6 / PACKET_PERIOD_US  # 753.5 data packets a second, single-return modes
MICROSECONDS_PER_HOUR = 3_600_000_000

# --- lasers (spec section 3), indexed by laser id = channel mod 16 ------------------------------------
LASER_ELEVATION_DEG = np.array([-15, 1, -13, 3, -11, 5, -9, 7, -7, 9, -5, 11, -3, 13, -1, 15], dtype=np.float64)
LASER_ELEVATION_RAD = np.radians(LASER_ELEVATION_DEG)
# Height of each beam's origin above the optical centre (spec table). velodyne-decoder already adds it
# (as 41.91 mm x tan(elevation)); kept here for the simulator and for reference.
LASER_VERTICAL_OFFSET_M = (
    np.array([11.2, -0.7, 9.7, -2.2, 8.1, -3.7, 6.6, -5.1, 5.1, -6.6, 3.7, -8.1, 2.2, -9.7, 0.7, -11.2]) * 1e-3
)
# Ring = rank by elevation (0 = -15 deg), the numbering velodyne-decoder and ROS use.
LASER_RING = np.argsort(np.argsort(LASER_ELEVATION_DEG)).astype(np.uint8)

# --- structured dtypes -------------------------------------------------------------------------------------
CHANNEL_DTYPE = np.dtype([("distance", "<u2"), ("reflectivity", "u1")])
BLOCK_DTYPE = np.dtype([("flag", "<u2"), ("azimuth", "<u2"), ("channels", CHANNEL_DTYPE, (CHANNELS_PER_BLOCK,))])
DATA_PACKET_DTYPE = np.dtype(
    [
        ("blocks", BLOCK_DTYPE, (BLOCKS_PER_PACKET,)),
        ("timestamp", "<u4"),
        ("return_mode", "u1"),
        ("product_id", "u1"),
    ]
)
assert BLOCK_DTYPE.itemsize == 100 and DATA_PACKET_DTYPE.itemsize == DATA_PACKET_SIZE

POSITION_PACKET_DTYPE = np.dtype(
    {
        "names": [
            "temp_top",
            "temp_bottom",
            "temp_adc_calibration",
            "temp_change_since_adc",
            "seconds_since_adc",
            "adc_reason",
            "adc_status",
            "timestamp",
            "pps_status",
            "thermal_status",
            "temp_last_shutdown",
            "temp_power_up",
            "nmea",
        ],
        "formats": ["u1", "u1", "u1", "<i2", "<u4", "u1", "u1", "<u4", "u1", "u1", "u1", "u1", "S128"],
        "offsets": [187, 188, 189, 190, 192, 196, 197, 198, 202, 203, 204, 205, 206],
        "itemsize": POSITION_PACKET_SIZE,
    }
)

PPS_ABSENT, PPS_SYNCHRONIZING, PPS_LOCKED, PPS_ERROR = 0, 1, 2, 3
PPS_STATUS_NAMES = {PPS_ABSENT: "absent", PPS_SYNCHRONIZING: "synchronizing", PPS_LOCKED: "locked", PPS_ERROR: "error"}

_HEADER_TAIL = struct.Struct("<IBB")  # timestamp, return mode, product id at offset 1200
_AZIMUTH = struct.Struct("<H")
_FLAG_LO = bytes([BLOCK_FLAG & 0xFF]) * BLOCKS_PER_PACKET  # 0xFF, first byte of every block
_FLAG_HI = bytes([BLOCK_FLAG >> 8]) * BLOCKS_PER_PACKET  # 0xEE
# (flag, azimuth) of each block, skipping the 96 channel bytes between them
_AZIMUTHS = struct.Struct("<" + "HH96x" * BLOCKS_PER_PACKET)


class PacketError(ValueError):
    """A payload that cannot be a VLP-16 packet (wrong size, bad block flags...)."""


@dataclass(frozen=True)
class DataPacketHeader:
    """The fields of a data packet the driver needs before (and instead of) decoding its points."""

    timestamp_us: int  # microseconds past the hour, sensor clock
    return_mode: int
    product_id: int
    first_azimuth_cdeg: int  # block 0
    last_azimuth_cdeg: int  # block 11

    @property
    def dual(self) -> bool:
        return self.return_mode == RETURN_MODE_DUAL

    @property
    def period_us(self) -> float:
        return PACKET_PERIOD_DUAL_US if self.dual else PACKET_PERIOD_US


def data_packet_problem(payload: bytes | bytearray | memoryview) -> str | None:
    """Why ``payload`` is not a usable VLP-16 data packet, or None if it is.

    Checked before anything reaches velodyne-decoder: a truncated or merged datagram, or a stray packet
    from another device on port 2368, must be counted and dropped, not decoded into garbage points.
    """
    if len(payload) != DATA_PACKET_SIZE:
        return f"size {len(payload)} != {DATA_PACKET_SIZE}"
    # Plain byte slices, not numpy: this runs 754 times a second on a Pi, where a numpy call costs ~10 us.
    raw = bytes(payload)
    if raw[0:1200:100] != _FLAG_LO or raw[1:1200:100] != _FLAG_HI:
        blocks = np.frombuffer(payload, dtype=BLOCK_DTYPE, count=BLOCKS_PER_PACKET)
        bad = int(np.argmax(blocks["flag"] != BLOCK_FLAG))
        return f"block {bad} flag 0x{int(blocks['flag'][bad]):04X} != 0xEEFF"
    # 36000 itself occurs in real captures (2014 firmware writes it instead of 0); it means 0.
    if max(_AZIMUTHS.unpack_from(raw, 0)[1::2]) > AZIMUTH_UNITS:
        return "azimuth > 36000"
    timestamp, mode, _ = _HEADER_TAIL.unpack_from(payload, 1200)
    if mode not in RETURN_MODE_NAMES:
        return f"unknown return mode 0x{mode:02X}"
    if timestamp >= MICROSECONDS_PER_HOUR:
        return f"timestamp {timestamp} us >= 1 hour"
    return None


def read_data_header(payload: bytes | bytearray | memoryview) -> DataPacketHeader:
    """Header fields of a 1206-byte data packet (call ``data_packet_problem`` first to validate)."""
    if len(payload) != DATA_PACKET_SIZE:
        raise PacketError(f"data packet must be {DATA_PACKET_SIZE} bytes, got {len(payload)}")
    timestamp, mode, product = _HEADER_TAIL.unpack_from(payload, 1200)
    (first,) = _AZIMUTH.unpack_from(payload, 2)
    (last,) = _AZIMUTH.unpack_from(payload, 100 * (BLOCKS_PER_PACKET - 1) + 2)
    return DataPacketHeader(timestamp, mode, product, first % AZIMUTH_UNITS, last % AZIMUTH_UNITS)


def decode_data_packet(payload: bytes | bytearray | memoryview) -> np.ndarray:
    """The packet as one ``DATA_PACKET_DTYPE`` record (raw fields; no geometry)."""
    if len(payload) != DATA_PACKET_SIZE:
        raise PacketError(f"data packet must be {DATA_PACKET_SIZE} bytes, got {len(payload)}")
    return np.frombuffer(payload, dtype=DATA_PACKET_DTYPE, count=1)[0]


def encode_data_packet(
    block_azimuth_cdeg: np.ndarray,  # (12,) uint16 hundredths of a degree
    distance_m: np.ndarray,  # (12, 32) float, 0 = no return, quantised to 2 mm
    reflectivity: np.ndarray,  # (12, 32) uint8
    timestamp_us: int,  # microseconds past the hour
    return_mode: int = RETURN_MODE_STRONGEST,
    product_id: int = PRODUCT_VLP16,
) -> bytes:
    """Build a 1206-byte data packet exactly as the sensor sends it.

    Distances are rounded to the nearest 2 mm unit; values that the 16-bit field cannot hold (negative,
    NaN, beyond 131.07 m) raise ``ValueError`` rather than wrapping silently into a wrong range.
    """
    azimuth = np.asarray(block_azimuth_cdeg)
    distance = np.asarray(distance_m, dtype=np.float64)
    refl = np.asarray(reflectivity)
    if azimuth.shape != (BLOCKS_PER_PACKET,):
        raise ValueError(f"block_azimuth_cdeg must have shape (12,), got {azimuth.shape}")
    if distance.shape != (BLOCKS_PER_PACKET, CHANNELS_PER_BLOCK):
        raise ValueError(f"distance_m must have shape (12, 32), got {distance.shape}")
    if refl.shape != (BLOCKS_PER_PACKET, CHANNELS_PER_BLOCK):
        raise ValueError(f"reflectivity must have shape (12, 32), got {refl.shape}")
    if np.any((azimuth < 0) | (azimuth >= AZIMUTH_UNITS)):
        raise ValueError("block azimuths must be in 0..35999 hundredths of a degree")
    if not np.all(np.isfinite(distance)) or np.any(distance < 0) or np.any(distance > MAX_DISTANCE_M):
        raise ValueError(f"distances must be finite and in 0..{MAX_DISTANCE_M:.3f} m")
    if np.any((refl < 0) | (refl > 255)):
        raise ValueError("reflectivity must be 0..255")
    if not 0 <= int(timestamp_us) < MICROSECONDS_PER_HOUR:
        raise ValueError(f"timestamp_us must be in 0..{MICROSECONDS_PER_HOUR - 1}, got {timestamp_us}")
    if not (0 <= return_mode <= 255 and 0 <= product_id <= 255):
        raise ValueError("return_mode and product_id are single bytes")

    packet = np.zeros((), dtype=DATA_PACKET_DTYPE)
    blocks = packet["blocks"]
    blocks["flag"] = BLOCK_FLAG
    blocks["azimuth"] = azimuth.astype(np.uint16)
    blocks["channels"]["distance"] = np.rint(distance / DISTANCE_UNIT_M).astype(np.uint16)
    blocks["channels"]["reflectivity"] = refl.astype(np.uint8)
    packet["timestamp"] = int(timestamp_us)
    packet["return_mode"] = return_mode
    packet["product_id"] = product_id
    return packet.tobytes()


@dataclass(frozen=True)
class PositionPacket:
    """Decoded 512-byte position ("telemetry") packet."""

    timestamp_us: int  # microseconds past the hour, same clock as data packets
    pps_status: int  # 0 absent, 1 synchronizing, 2 locked, 3 error
    nmea: str  # "" when no GPS is connected
    temp_top_c: int  # 0 on firmware before ~2018
    temp_bottom_c: int
    temp_adc_calibration_c: int
    temp_change_since_adc_c: int
    seconds_since_adc: int
    adc_reason: int
    adc_status: int
    thermal_shutdown: bool
    temp_last_shutdown_c: int
    temp_power_up_c: int

    @property
    def pps_locked(self) -> bool:
        return self.pps_status == PPS_LOCKED

    @property
    def pps_name(self) -> str:
        return PPS_STATUS_NAMES.get(self.pps_status, f"unknown({self.pps_status})")


def decode_position_packet(payload: bytes | bytearray | memoryview) -> PositionPacket:
    """Decode a position packet; raises ``PacketError`` for any other length."""
    if len(payload) != POSITION_PACKET_SIZE:
        raise PacketError(f"position packet must be {POSITION_PACKET_SIZE} bytes, got {len(payload)}")
    rec = np.frombuffer(payload, dtype=POSITION_PACKET_DTYPE, count=1)[0]
    # NMEA is NUL-padded ASCII; a corrupted byte must not raise, so undecodable bytes are replaced.
    nmea = bytes(rec["nmea"]).split(b"\0", 1)[0].decode("ascii", errors="replace").strip()
    return PositionPacket(
        timestamp_us=int(rec["timestamp"]),
        pps_status=int(rec["pps_status"]),
        nmea=nmea,
        temp_top_c=int(rec["temp_top"]),
        temp_bottom_c=int(rec["temp_bottom"]),
        temp_adc_calibration_c=int(rec["temp_adc_calibration"]),
        temp_change_since_adc_c=int(rec["temp_change_since_adc"]),
        seconds_since_adc=int(rec["seconds_since_adc"]),
        adc_reason=int(rec["adc_reason"]),
        adc_status=int(rec["adc_status"]),
        thermal_shutdown=int(rec["thermal_status"]) == 1,
        temp_last_shutdown_c=int(rec["temp_last_shutdown"]),
        temp_power_up_c=int(rec["temp_power_up"]),
    )


def encode_position_packet(
    timestamp_us: int,
    pps_status: int = PPS_ABSENT,
    nmea: str = "",
    temp_top_c: int = 0,
    temp_bottom_c: int = 0,
) -> bytes:
    """Build a 512-byte position packet (fields a newer-firmware unit fills; the rest zero)."""
    if not 0 <= int(timestamp_us) < MICROSECONDS_PER_HOUR:
        raise ValueError(f"timestamp_us must be in 0..{MICROSECONDS_PER_HOUR - 1}, got {timestamp_us}")
    raw = nmea.encode("ascii")
    if len(raw) > 128:
        raise ValueError(f"NMEA sentence is {len(raw)} bytes; the field holds 128")
    rec = np.zeros((), dtype=POSITION_PACKET_DTYPE)
    rec["timestamp"] = int(timestamp_us)
    rec["pps_status"] = pps_status
    rec["nmea"] = raw
    rec["temp_top"] = temp_top_c
    rec["temp_bottom"] = temp_bottom_c
    return rec.tobytes()


def nmea_checksum_ok(sentence: str) -> bool:
    """True if ``$...*HH`` carries a correct XOR checksum (a corrupted GPRMC must not set the clock)."""
    body, sep, tail = sentence.strip().lstrip("$").partition("*")
    if not sep or len(tail) < 2:
        return False
    acc = 0
    for ch in body.encode("ascii", errors="replace"):
        acc ^= ch
    try:
        return acc == int(tail[:2], 16)
    except ValueError:
        return False
