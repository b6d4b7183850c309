"""How far out each bearing is vouched for: a solid of a given height there would have been returned.

A VLP-16 1.6 m above the water cannot see a 0.5 m-high hull between about 30 and 63 m: the -3 deg beam has passed
below 0.5 m by 28 m and the -1 deg beam only comes down to 0.5 m at 63 m. Nor anything below its lowest beam close
in: the -15 deg beam is still 1.06 m up at 2 m. And the water hides the lowest part of every solid: a return within
the sea margin of the surface is taken for water (water.py). So "nothing returned" means "clear" only at ranges
where some beam crosses the band between the sea margin and the obstacle height.

For each bearing the 16 beams are placed with the boat's roll and pitch at the time the bearing was swept; beam k
at horizontal range r is h_s + r tan(e_k) above the water (h_s the sensor's height above the estimated surface,
e_k the beam's elevation in the level frame). It covers the ranges where that height lies in [margin, height]. The
bearing is vouched out to the end of the covered stretch that starts at ``inner`` (the own hull's edge): a gap
anywhere before it could hide a solid, so coverage beyond a gap does not count.

A bearing is vouched for only where the sensor is known to have measured: the received packets swept it and it
returned something (a sector that returned nothing at all may be a fouled window, not open water).

Frames: sensor FLU -> sensor FRD -> body FRD (mount) -> level (roll, pitch); bearings clockwise from the bow, rad.
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import lru_cache

import numpy as np

from drivers.mount import FLU_TO_FRD, Mount
from drivers.vlp16.packet import LASER_ELEVATION_DEG, LASER_ELEVATION_RAD
from tracker.ego import rotation_matrices
from tracker.lidar.water import WaterEstimate

# Column of the beam arrays (laser id order, as LASER_ELEVATION_RAD) that holds each ring (0 = the lowest beam).
RING_COLUMNS = np.argsort(LASER_ELEVATION_DEG, kind="stable")


def beam_elevations_level(
    bearings: np.ndarray, roll: np.ndarray, pitch: np.ndarray, mount: Mount
) -> tuple[np.ndarray, np.ndarray]:
    """Elevation (rad, up positive) in the level frame of each of the 16 beams fired toward each body bearing,
    (B, 16), and the sensor origin's height above the body origin in the level frame, (B,) m."""
    b = np.ascontiguousarray(bearings, dtype=float)
    d_body = _beam_directions_body(b.tobytes(), mount)  # (B, 16, 3)
    level = rotation_matrices(np.asarray(roll, float), np.asarray(pitch, float), np.zeros(b.size))  # (B, 3, 3)
    # Only the level frame's vertical component is needed: the level rotation's third row against each beam (the
    # same sum einsum takes for that component of the whole rotated direction, a third of the work).
    up = np.einsum("bj,bkj->bk", level[:, 2, :], d_body)
    elevation = -np.arcsin(np.clip(up, -1.0, 1.0))
    origin_up = -np.einsum("bj,j->b", level[:, 2, :], mount.translation)
    return elevation, origin_up


@lru_cache(maxsize=8)
def _beam_directions_body(bearings_key: bytes, mount: Mount) -> np.ndarray:
    """(B, 16, 3) body-frame direction of each beam fired toward each body bearing (``bearings_key``: the float64
    bearings' bytes): the same every revolution for the same bearings, so computed once."""
    b = np.frombuffer(bearings_key, dtype=float)
    # The sensor azimuth that points along body bearing b (an upside-down sensor sweeps the other way round; a
    # tilted one's roll and pitch tilt the beams, which the full rotation below carries).
    az = mount.sensor_azimuths(b)  # sensor-FRD azimuth, clockwise
    cos_e, sin_e = np.cos(LASER_ELEVATION_RAD), np.sin(LASER_ELEVATION_RAD)
    # sensor FLU direction of a firing at FRD azimuth az: (cos e cos az, -cos e sin az, sin e)
    d_flu = np.stack(
        [
            cos_e[None, :] * np.cos(az)[:, None],
            -cos_e[None, :] * np.sin(az)[:, None],
            np.broadcast_to(sin_e, (b.size, 16)),
        ],
        axis=-1,
    )
    d_body = d_flu @ (mount.rotation @ FLU_TO_FRD).T
    d_body.setflags(write=False)
    return d_body


def band_intervals(
    elevation: np.ndarray, sensor_height: np.ndarray, margin: float, obstacle_height: float, max_range: float
) -> tuple[np.ndarray, np.ndarray]:
    """(B, K) start and end of the horizontal ranges where each beam (level-frame ``elevation``, rad; the sensor
    ``sensor_height`` above the water surface, (B,) m) lies between ``margin`` and ``obstacle_height`` above the
    water, capped at ``max_range``. An empty interval has start > end."""
    elevation = np.atleast_2d(elevation)
    h_s = np.asarray(sensor_height, float).reshape(-1, 1)
    if obstacle_height <= margin:
        return np.full(elevation.shape, np.inf), np.full(elevation.shape, -np.inf)
    slope = np.tan(elevation)  # height change per metre of horizontal range
    flat = np.abs(slope) < 1e-12
    safe = np.where(flat, 1.0, slope)
    r_top = (obstacle_height - h_s) / safe  # where the beam's height is obstacle_height
    r_low = (margin - h_s) / safe  # and where it is the margin
    down = slope < 0
    # falling beam: in the band from r_top to r_low (if it starts above the margin at all); rising: r_low to r_top
    lo = np.where(down, r_top, r_low)
    hi = np.where(down, r_low, r_top)
    inside_at_sensor = (h_s >= margin) & (h_s <= obstacle_height)
    lo = np.where(flat, np.where(inside_at_sensor, 0.0, np.inf), np.maximum(lo, 0.0))
    hi = np.where(flat, np.where(inside_at_sensor, np.inf, -np.inf), np.minimum(hi, max_range))
    return lo, hi


def reach_from(lo: np.ndarray, hi: np.ndarray, inner: float, max_range: float) -> np.ndarray:
    """(B,) end of the stretch from ``inner`` outward that the intervals [lo, hi] (B, K) cover without a gap; 0 when
    no interval covers ``inner`` itself (then nothing is vouched for)."""
    order = np.argsort(lo, axis=1)
    lo_s = np.take_along_axis(lo, order, axis=1)
    hi_s = np.take_along_axis(hi, order, axis=1)
    reach = np.full(lo.shape[0], float(inner))
    # sorted by start, an interval extends the reach only if it starts within it; a loop over the few intervals,
    # vectorised over bearings
    for k in range(lo_s.shape[1]):
        joins = lo_s[:, k] <= reach + 1e-9
        reach = np.where(joins, np.maximum(reach, hi_s[:, k]), reach)
    reach = np.minimum(reach, max_range)
    return np.where(reach > inner + 1e-9, reach, 0.0)


SUB_BEARINGS = np.array([-2.0, 0.0, 2.0])  # deg about each bin's centre where coverage is judged (the worst wins)
N_BINS = 72
# The bins' centres among the judged bearings (bin_bearings): rows of a (72 * 3, ...) array, one per bin.
BIN_CENTRES = slice(int(np.flatnonzero(SUB_BEARINGS == 0.0)[0]), None, SUB_BEARINGS.size)


def bands_turned(lo: np.ndarray, hi: np.ndarray, turned_rad: float) -> tuple[np.ndarray, np.ndarray]:
    """A sensor's covered intervals per judged bearing (216, K), measured in the body frame of its measurement, as
    the body frame of a boat that has turned ``turned_rad`` (clockwise) since sees them: its bearing b looked along
    b + turned at the measurement. Between two judged bearings it takes what both vouch for (each column's
    intervals intersected), so a turn never carries a neighbour's coverage into a bearing that had none. A boat
    turning 30 deg/s turns 3 deg in a frame period."""
    if turned_rad == 0.0:
        return lo, hi
    query = np.mod(_JUDGED + turned_rad, 2 * np.pi)
    right = np.searchsorted(_RING, query) % _RING.size
    on = np.abs(np.angle(np.exp(1j * (_RING[right] - query)))) < 1e-9
    left = np.where(on, right, (right - 1) % _RING.size)
    a, b = _RING_ORDER[left], _RING_ORDER[right]
    return np.maximum(lo[a], lo[b]), np.minimum(hi[a], hi[b])


def bin_bearings() -> np.ndarray:
    """(72 * 3,) body bearings, rad: three per 5-degree bin, the bin's centre and 2 deg either side."""
    return np.radians((np.arange(N_BINS)[:, None] * 5.0 + SUB_BEARINGS[None, :]).ravel())


# The judged bearings in [0, 2 pi), and their order round the circle (bands_turned looks up between neighbours).
_JUDGED = np.mod(bin_bearings(), 2 * np.pi)
_RING_ORDER = np.argsort(_JUDGED, kind="stable")
_RING = _JUDGED[_RING_ORDER]


@dataclass(frozen=True)
class BeamGeometry:
    """The 16 beams at the judged bearings (bin_bearings) during one revolution, placed with the roll and pitch at
    which each bin was swept: level-frame elevation (216, 16) rad, up positive, in laser id order, and the sensor
    origin's height above the body origin in the level frame (216,) m."""

    elevation: np.ndarray
    origin_up: np.ndarray

    @classmethod
    def at_bins(cls, roll_bin: np.ndarray, pitch_bin: np.ndarray, mount: Mount) -> BeamGeometry:
        """From each of the 72 bins' roll and pitch (rad)."""
        per = SUB_BEARINGS.size
        elevation, origin_up = beam_elevations_level(
            bin_bearings(), np.repeat(roll_bin, per), np.repeat(pitch_bin, per), mount
        )
        return cls(elevation, origin_up)

    def over_surface(self, water: WaterEstimate, origin_height_above_water: float) -> tuple[np.ndarray, np.ndarray]:
        """(216, 16) elevations against the estimated water surface and (216,) the sensor's height above it: the
        surface's own tilt along each bearing lowers or raises it under the beams. ``origin_height_above_water``:
        the body origin above the configured waterline, m."""
        bearings = bin_bearings()
        tilt = water.slope_x * np.cos(bearings) + water.slope_y * np.sin(bearings)
        elevation = np.arctan(np.tan(self.elevation) - tilt[:, None])
        return elevation, self.origin_up + origin_height_above_water - water.offset


def swept_bins(packet_sweeps: np.ndarray, mount: Mount, min_share: float = 0.95) -> np.ndarray:
    """(72,) bool: bins whose bearings the received packets swept (at least ``min_share`` of each). A lost packet
    leaves 4.8 deg unmeasured. ``packet_sweeps`` (n, 2): each packet's first sensor azimuth and the azimuth it swept
    (rad, clockwise from the sensor's forward); the mount turns them into body bearings (Mount.body_bearings: an
    upside-down sensor's sweep runs anticlockwise, so it starts at its last azimuth seen from the boat)."""
    cells = 3600  # 0.1 deg
    first = packet_sweeps[:, 0] + packet_sweeps[:, 1] if mount.mirrored else packet_sweeps[:, 0]
    start = np.floor(np.mod(mount.body_bearings(first), 2 * np.pi) * (cells / (2 * np.pi))).astype(np.int64)
    length = np.ceil(np.clip(packet_sweeps[:, 1], 0.0, 2 * np.pi) * (cells / (2 * np.pi))).astype(np.int64)
    # +1 where a packet's sweep starts, -1 where it ends: counts, so exact in floats whatever the order of sums
    ends = np.minimum(start + length, 2 * cells)
    edge = (np.bincount(start, minlength=2 * cells + 1) - np.bincount(ends, minlength=2 * cells + 1)).astype(float)
    run = np.cumsum(edge)[: 2 * cells]
    covered = (run[:cells] + run[cells:]) > 0
    # bin j spans bearings 5j - 2.5 .. 5j + 2.5 deg: cells shifted by 25 so that bin 0 is one block of 50
    share = np.count_nonzero(np.roll(covered, 25).reshape(N_BINS, 50), axis=1) / 50  # np.mean's value, a third the cost
    return share >= min_share
