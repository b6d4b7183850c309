"""What the sensors actually returned from each solid, per 0.1 s window: the record `usv-tracker evaluate` judges by.

A tracker cannot be blamed for a boat no sensor returned (beyond range, hidden behind another hull or the quay, out
of the radar's field of view), nor an obstacle array for a bearing where nothing solid came back. The simulator knows
what each return hit (``PacketContent.label`` for the LiDAR, ``RadarDetections.label`` for the radar), so it writes
that down beside the captures as ``returns.csv``, one row per window [k * 0.1, (k + 1) * 0.1) of scene time:

  t_start, t_end                    s, scene time (the captures are stamped T0_UNIX + scene time)
  own_north, own_east, own_yaw      the own boat's pose at t_end: world NED metres, radians clockwise from north
  lidar_shore, radar_shore          returns from quay walls and the land behind them in the window
  lidar_<id>, radar_<id>            returns from vessel <id> (the truth CSV's id), one pair of columns per vessel
  lidar_bin_00 .. lidar_bin_71      nearest solid the LiDAR returned per bearing bin, horizontal range in metres
                                    from the own boat's origin, in its level frame at t_end: bin j is centred 5 * j
                                    degrees clockwise from the bow (heading at t_end) and spans +-2.5 degrees;
                                    empty where no solid was returned in that bin
  lidar_core_00 .. lidar_core_71    the same from the returns at least EDGE_MARGIN_DEG inside their bin: a hull's
                                    edge that the daemon, placing its returns at its own instant, puts a tenth of a
                                    degree into the next bin, is not a miss in this one
  radar_bin_.., radar_core_..       the same for the radar
  present_00 .. present_71          nearest solid that was there per bin, returned or not: the hulls' and quay
                                    blocks' outlines at the window's start, middle and end, in the same frame (so
                                    an obstacle the daemon held from an earlier sweep, on a hull that is there, is
                                    not a false obstacle); empty where none lay within PRESENT_RANGE_M. Files
                                    written before it have no such columns.

A "returned solid" is a LiDAR or radar return labelled as a vessel or the shore; clutter, water, rain and radar
multipath ghosts never count. LiDAR returns are placed along their true ray at the measured (noisy) distance and
counted in the window of their own firing time; a radar frame counts in the window its frame time falls in, at the
true position of each scatterer (the solid that was returned, not the radar's noisy estimate of it).
"""

from __future__ import annotations

import csv
import math
from collections.abc import Sequence
from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np

from drivers.mount import FLU_TO_FRD
from simulator.lidar_model import (
    ELEVATION_DEG,
    LASER_PERIOD_S,
    SEQUENCE_PERIOD_S,
    VERTICAL_OFFSET_M,
    PacketContent,
    Vlp16Model,
)
from simulator.radar_model import RadarDetections
from simulator.scene import LABEL_SHORE, MAX_VERTICES, Scene
from tracker.ego import rotation_matrices

N_BINS = 72
BIN_WIDTH_RAD = 2 * math.pi / N_BINS
WINDOW_S = 0.1
SHORE = "shore"
SENSORS = ("lidar", "radar")
BIN_COLUMNS = tuple(f"{s}_{kind}_{j:02d}" for s in SENSORS for kind in ("bin", "core") for j in range(N_BINS))
EDGE_MARGIN_DEG = 0.5
POSE_COLUMNS = ("t_start", "t_end", "own_north", "own_east", "own_yaw")
PRESENT_COLUMNS = tuple(f"present_{j:02d}" for j in range(N_BINS))
PRESENT_RANGE_M = 150.0  # beyond any max_distance the daemon takes
_PRESENT_STEP_M = 0.1  # outline sampling: a bin 5 m off is 0.44 m wide

# (block, channel) of a packet -> laser id and firing offset from the packet's first firing (vlp16.md §4):
# channel c of block k is laser c % 16 of sequence 2k + (c >= 16).
_CHANNEL_LASER = np.tile(np.arange(32) % 16, (12, 1))
_CHANNEL_SEQUENCE = 2 * np.arange(12)[:, None] + (np.arange(32)[None, :] >= 16)
_CHANNEL_OFFSET_S = _CHANNEL_SEQUENCE * SEQUENCE_PERIOD_S + _CHANNEL_LASER * LASER_PERIOD_S
_ELEVATION = np.radians(ELEVATION_DEG)


def bearing_bin(fwd: np.ndarray, stbd: np.ndarray) -> np.ndarray:
    """Bin of each level-frame (forward, starboard) offset: bin j is centred 5 j deg clockwise from the bow."""
    return np.mod(np.rint(np.arctan2(stbd, fwd) / BIN_WIDTH_RAD).astype(np.int64), N_BINS)


def inside_bin(fwd: np.ndarray, stbd: np.ndarray, margin_rad: float) -> np.ndarray:
    """Whether each offset's bearing lies at least ``margin_rad`` inside its bin (away from both edges)."""
    frac = np.arctan2(stbd, fwd) / BIN_WIDTH_RAD
    return np.abs(frac - np.rint(frac)) * BIN_WIDTH_RAD <= BIN_WIDTH_RAD / 2 - margin_rad


def solid_columns(n_vessels: int) -> list[str]:
    cols = ["lidar_shore", "radar_shore"]
    for v in range(n_vessels):
        cols += [f"lidar_{v}", f"radar_{v}"]
    return cols


class ReturnsRecorder:
    """Accumulates labelled returns into windows; ``write`` makes returns.csv.

    Solid index s: 0 = shore, 1 + v = vessel v. Windows are fixed at construction (k = 0 .. n - 1), so the LiDAR
    and the radar can be fed one after the other, each in time order or not.
    """

    def __init__(self, scene: Scene, seconds: float, window_s: float = WINDOW_S) -> None:
        self.scene = scene
        self.window_s = float(window_s)
        self.n_windows = max(math.ceil(seconds / window_s - 1e-9), 0)
        self.n_vessels = scene.n_vessels
        self.t_end = (np.arange(self.n_windows) + 1) * self.window_s
        own = scene.own.poses(self.t_end) if self.n_windows else None
        self.own_ne = own.position if own is not None else np.zeros((0, 2))
        self.own_yaw = own.yaw if own is not None else np.zeros(0)
        self.lidar_counts = np.zeros((self.n_windows, 1 + self.n_vessels), np.int64)
        self.radar_counts = np.zeros((self.n_windows, 1 + self.n_vessels), np.int64)
        # (sensor, window, bin): all returns of a bin, and those away from its edges
        self.nearest = np.full((2, self.n_windows, N_BINS), np.inf)
        self.core = np.full((2, self.n_windows, N_BINS), np.inf)
        self._pending: list[PacketContent] = []
        self._lidar: Vlp16Model | None = None

    # -- inputs --------------------------------------------------------------------------------------------------
    def add_lidar_packet(self, model: Vlp16Model, pkt: PacketContent) -> None:
        """One data packet as the model made it (its ``label`` says what each return hit)."""
        self._lidar = model
        self._pending.append(pkt)
        if len(self._pending) >= 256:  # vectorised over many packets: per-packet numpy calls would dominate
            self.flush()

    def add_radar_frame(self, det: RadarDetections) -> None:
        solid = (det.label >= 0) | (det.label == LABEL_SHORE)
        self._add(np.full(int(solid.sum()), det.t), det.xyz_world[solid, :2], det.label[solid], 1)

    def flush(self) -> None:
        if not self._pending:
            return
        assert self._lidar is not None
        model, pkts = self._lidar, self._pending
        self._pending = []
        dist = np.stack([p.distance_m for p in pkts])  # (P, 12, 32), 0 = no return
        label = np.stack([p.label if p.label is not None else np.full((12, 32), -99) for p in pkts])
        t_fire = np.array([p.t for p in pkts])[:, None, None] + _CHANNEL_OFFSET_S[None]
        laser = np.broadcast_to(_CHANNEL_LASER, dist.shape)
        keep = (dist > 0) & ((label >= 0) | (label == LABEL_SHORE))
        t, d, lab, las = t_fire[keep], dist[keep], label[keep], laser[keep]
        self._add(t, _lidar_points_world(model, t, las, d), lab, 0)

    def _add(self, t: np.ndarray, ne: np.ndarray, label: np.ndarray, sensor: int) -> None:
        """Returns of ``sensor`` (0 LiDAR, 1 radar) at times ``t`` and world (north, east) positions into their
        windows."""
        counts = self.lidar_counts if sensor == 0 else self.radar_counts
        w = np.floor(t / self.window_s + 1e-9).astype(np.int64)
        ok = (w >= 0) & (w < self.n_windows)
        w, ne, label = w[ok], ne[ok], label[ok]
        solid = np.where(label == LABEL_SHORE, 0, label + 1)
        np.add.at(counts, (w, solid), 1)
        # world -> the own boat's level frame at the window's end (rotate by -yaw about down)
        rel = ne - self.own_ne[w]
        c, s = np.cos(self.own_yaw[w]), np.sin(self.own_yaw[w])
        fwd = c * rel[:, 0] + s * rel[:, 1]
        stbd = -s * rel[:, 0] + c * rel[:, 1]
        b, r = bearing_bin(fwd, stbd), np.hypot(fwd, stbd)
        np.minimum.at(self.nearest[sensor], (w, b), r)
        inner = inside_bin(fwd, stbd, math.radians(EDGE_MARGIN_DEG))
        np.minimum.at(self.core[sensor], (w[inner], b[inner]), r[inner])

    def present_nearest(self) -> np.ndarray:
        """(W, 72) m: per window, the nearest solid outline in each bin at the window's start, middle or end (the
        own boat's level frame at its end), inf where none lies within PRESENT_RANGE_M."""
        out = np.full((self.n_windows, N_BINS), np.inf)
        for k in range(self.n_windows):
            t = self.t_end[k] - self.window_s * np.array([1.0, 0.5, 0.0])
            pts = _outline_samples(self.scene.prisms_at(t).vertices.reshape(-1, MAX_VERTICES, 2))
            rel = pts - self.own_ne[k]
            c, s = math.cos(self.own_yaw[k]), math.sin(self.own_yaw[k])
            fwd, stbd = c * rel[:, 0] + s * rel[:, 1], -s * rel[:, 0] + c * rel[:, 1]
            r = np.hypot(fwd, stbd)
            near = r <= PRESENT_RANGE_M
            np.minimum.at(out[k], bearing_bin(fwd[near], stbd[near]), r[near])
        return out

    # -- output --------------------------------------------------------------------------------------------------
    def write(self, path: str | Path) -> int:
        """Write returns.csv; returns the number of windows (rows)."""
        self.flush()
        with open(path, "w", newline="") as f:
            w = csv.writer(f)
            w.writerow([*POSE_COLUMNS, *solid_columns(self.n_vessels), *BIN_COLUMNS, *PRESENT_COLUMNS])
            present = self.present_nearest()
            for k in range(self.n_windows):
                counts = []
                for s in range(1 + self.n_vessels):
                    counts += [int(self.lidar_counts[k, s]), int(self.radar_counts[k, s])]
                per_sensor = [a for sensor in range(2) for a in (self.nearest[sensor, k], self.core[sensor, k])]
                per_sensor.append(present[k])
                bins = ["" if not np.isfinite(r) else f"{r:.3f}" for r in np.concatenate(per_sensor)]
                w.writerow(
                    [
                        f"{k * self.window_s:.6f}",
                        f"{self.t_end[k]:.6f}",
                        f"{self.own_ne[k, 0]:.4f}",
                        f"{self.own_ne[k, 1]:.4f}",
                        f"{self.own_yaw[k]:.6f}",
                        *counts,
                        *bins,
                    ]
                )
        return self.n_windows


def _outline_samples(vertices: np.ndarray) -> np.ndarray:
    """(M, 2) points every _PRESENT_STEP_M along the closed outlines (P, 5, 2) (padded vertices repeat)."""
    a = vertices.reshape(-1, 2)
    b = np.roll(vertices, -1, axis=1).reshape(-1, 2)
    n = np.ceil(np.hypot(*(b - a).T) / _PRESENT_STEP_M).astype(np.int64)
    seg = np.repeat(np.arange(a.shape[0]), n)
    frac = (np.arange(seg.size) - np.repeat(np.cumsum(n) - n, n)) / np.repeat(np.maximum(n, 1), n)
    return a[seg] + (b[seg] - a[seg]) * frac[:, None]


def _lidar_points_world(model: Vlp16Model, t: np.ndarray, laser: np.ndarray, distance: np.ndarray) -> np.ndarray:
    """World (north, east) of LiDAR returns: each laser's own origin and ray at its firing time (the model's true
    rotor angle and the own boat's pose then), out to the measured distance."""
    az = model.azimuth_at(t)
    cos_e = np.cos(_ELEVATION[laser])
    d_flu = np.stack([cos_e * np.cos(az), -cos_e * np.sin(az), np.sin(_ELEVATION[laser])], axis=-1)
    o_flu = np.zeros((t.size, 3))
    o_flu[:, 2] = VERTICAL_OFFSET_M[laser]
    flu_to_body = model.mount.rotation @ FLU_TO_FRD  # sensor FLU -> body FRD
    p_body = (o_flu + distance[:, None] * d_flu) @ flu_to_body.T + model.mount.translation
    poses = model.scene.own.poses(t)
    r_wb = rotation_matrices(poses.roll, poses.pitch, poses.yaw)  # body FRD -> world NED, one per return
    p_world = np.einsum("nij,nj->ni", r_wb, p_body)
    return p_world[:, :2] + poses.position


@dataclass(frozen=True)
class ReturnsTable:
    """returns.csv read back: per window (W rows) the pose, the counts per solid and the nearest range per bin."""

    t_start: np.ndarray  # (W,) s
    t_end: np.ndarray  # (W,) s
    own_ne: np.ndarray  # (W, 2) world north/east at t_end, m
    own_yaw: np.ndarray  # (W,) rad
    lidar: np.ndarray  # (W, 1 + V) returns per solid: column 0 the shore, 1 + v vessel v
    radar: np.ndarray  # (W, 1 + V)
    sensor_nearest: np.ndarray  # (2, W, 72) m per sensor (LiDAR, radar), inf where nothing was returned
    sensor_core: np.ndarray  # (2, W, 72) m, the same from returns at least EDGE_MARGIN_DEG inside their bin
    vessel_ids: tuple[int, ...]  # (V,) the ids of columns 1..V
    present: np.ndarray | None = None  # (W, 72) m, nearest solid there, returned or not; None in older files
    window_s: float = WINDOW_S
    sensors: tuple[str, ...] = SENSORS  # whose returns count (``for_sensors``)

    def for_sensors(self, sensors: Sequence[str]) -> ReturnsTable:
        """The record as seen by a run that had only ``sensors`` ("lidar", "radar"): a LiDAR-only run is not
        judged by what the radar returned."""
        bad = [s for s in sensors if s not in SENSORS]
        if bad or not sensors:
            raise ValueError(f"sensors must be some of {', '.join(SENSORS)}, got {list(sensors)!r}")
        return replace(self, sensors=tuple(s for s in SENSORS if s in sensors))

    @property
    def _picked(self) -> list[int]:
        return [SENSORS.index(s) for s in self.sensors]

    @property
    def nearest(self) -> np.ndarray:
        """(W, 72) m: nearest solid the chosen sensors returned per bin."""
        return self.sensor_nearest[self._picked].min(axis=0)

    @property
    def core(self) -> np.ndarray:
        """(W, 72) m: the same from returns away from the bin's edges."""
        return self.sensor_core[self._picked].min(axis=0)

    def returns_of(self, vessel_id: int) -> np.ndarray:
        """(W,) returns of one vessel from the chosen sensors; zeros for an id the file does not know."""
        if vessel_id not in self.vessel_ids:
            return np.zeros(self.t_end.shape, np.int64)
        c = 1 + self.vessel_ids.index(vessel_id)
        return sum(getattr(self, s)[:, c] for s in self.sensors)


class ReturnsFormatError(ValueError):
    """A malformed returns.csv; the message names the file and the line."""


def read_returns_csv(path: str | Path) -> ReturnsTable:
    """Read returns.csv; raises ReturnsFormatError naming the file and line for anything malformed."""
    path = Path(path)
    try:
        with open(path, newline="") as f:
            rows = list(csv.reader(f))
    except (OSError, UnicodeDecodeError) as exc:
        raise ReturnsFormatError(f"{path}: cannot read: {exc}") from exc
    if not rows:
        raise ReturnsFormatError(f"{path}: empty file (expected a returns.csv header)")
    header = rows[0]
    has_present = tuple(header[-len(PRESENT_COLUMNS) :]) == PRESENT_COLUMNS
    if has_present:
        header = header[: -len(PRESENT_COLUMNS)]
    ids = _parse_header(path, header)
    n_solid = 1 + len(ids)
    width = len(header) + (len(PRESENT_COLUMNS) if has_present else 0)
    out = {k: [] for k in ("t_start", "t_end", "north", "east", "yaw", "lidar", "radar", "bins")}
    for line_no, row in enumerate(rows[1:], start=2):
        if not row:
            continue
        if len(row) != width:
            raise ReturnsFormatError(f"{path} line {line_no}: {len(row)} fields, expected {width}")
        try:
            pose = [_finite(x) for x in row[:5]]
            counts = [int(x) for x in row[5 : 5 + 2 * n_solid]]
            bins = [math.inf if x == "" else _finite(x) for x in row[5 + 2 * n_solid :]]
        except ValueError as exc:
            raise ReturnsFormatError(f"{path} line {line_no}: {exc}") from exc
        if min(counts, default=0) < 0 or min(bins, default=0.0) < 0:
            raise ReturnsFormatError(f"{path} line {line_no}: negative count or range")
        for key, value in zip(("t_start", "t_end", "north", "east", "yaw"), pose, strict=True):
            out[key].append(value)
        out["lidar"].append(counts[0::2])
        out["radar"].append(counts[1::2])
        out["bins"].append(bins)
    t_start, t_end = np.array(out["t_start"], float), np.array(out["t_end"], float)
    n_sensor_bins = len(BIN_COLUMNS)
    bins = np.array(out["bins"], float).reshape(len(out["bins"]), n_sensor_bins + (N_BINS if has_present else 0))
    if np.any(t_end <= t_start) or np.any(np.diff(t_start) <= 0):
        raise ReturnsFormatError(f"{path}: windows must have t_end > t_start and follow each other in time")
    return ReturnsTable(
        window_s=float(np.median(t_end - t_start)) if t_end.size else WINDOW_S,
        t_start=t_start,
        t_end=t_end,
        own_ne=np.stack([np.array(out["north"], float), np.array(out["east"], float)], axis=-1).reshape(-1, 2),
        own_yaw=np.array(out["yaw"], float),
        lidar=np.array(out["lidar"], np.int64).reshape(-1, n_solid),
        radar=np.array(out["radar"], np.int64).reshape(-1, n_solid),
        # (W, sensor, kind, 72) -> per sensor (2, W, 72)
        sensor_nearest=bins[:, :n_sensor_bins].reshape(-1, 2, 2, N_BINS)[:, :, 0].transpose(1, 0, 2),
        sensor_core=bins[:, :n_sensor_bins].reshape(-1, 2, 2, N_BINS)[:, :, 1].transpose(1, 0, 2),
        vessel_ids=ids,
        present=bins[:, n_sensor_bins:] if has_present else None,
    )


def _parse_header(path: Path, header: Sequence[str]) -> tuple[int, ...]:
    n_counts = len(header) - len(POSE_COLUMNS) - len(BIN_COLUMNS)
    if (
        tuple(header[:5]) != POSE_COLUMNS
        or tuple(header[-len(BIN_COLUMNS) :]) != BIN_COLUMNS
        or n_counts < 2
        or n_counts % 2
        or tuple(header[5:7]) != ("lidar_shore", "radar_shore")
    ):
        raise ReturnsFormatError(f"{path} line 1: not a returns.csv header: {','.join(header[:8])}...")
    ids = []
    for a, b in zip(header[7 : 5 + n_counts : 2], header[8 : 5 + n_counts : 2], strict=True):
        va, vb = a.removeprefix("lidar_"), b.removeprefix("radar_")
        if not (a.startswith("lidar_") and b.startswith("radar_") and va == vb and va.isdigit()):
            raise ReturnsFormatError(f"{path} line 1: bad column pair {a!r}, {b!r} (expected lidar_<id>, radar_<id>)")
        ids.append(int(va))
    return tuple(ids)


def _finite(text: str) -> float:
    x = float(text)
    if not math.isfinite(x):
        raise ValueError(f"{text!r} is not a finite number")
    return x
