"""Ground truth at a tick: the simulator's truth CSV, or a reference boat's GNSS track brought into the run's frame.

Both give, at any time inside their span, the vessels to score against: centre, velocity, heading, size and hull
footprint in world (north, east) metres and radians. Truth samples (10 Hz for the simulator) are interpolated to the
tick's time, never snapped to the nearest sample: at 5 m/s half a sample period is 25 cm, as much as a good tracker's
whole position error.
"""

from __future__ import annotations

import csv
import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from daemon.autopilot_geo import LocalTangentPlane
from evaluation.errors import EvaluationError
from evaluation.geometry import distance_to_polygon, rotation_ne, wrap_angle
from simulator.truth import CSV_COLUMNS, read_truth_csv

# Truth samples further apart than this are not interpolated across: a missing sample of a 1 Hz GNSS log makes a
# 2 s gap, while its intervals jitter by milliseconds either side of 1 s (at 1.0 half its ticks were dropped).
MAX_SAMPLE_GAP_S = 1.5


@dataclass(frozen=True)
class FrameTruth:
    """The vessels of one tick (V of them) and the own boat, world frame."""

    ids: np.ndarray  # (V,) int
    names: list[str]
    position: np.ndarray  # (V, 2) north, east, m
    velocity: np.ndarray  # (V, 2) m/s
    heading: np.ndarray  # (V,) rad clockwise from north; NaN where unknown (GNSS)
    length: np.ndarray  # (V,) m; NaN where unknown
    width: np.ndarray  # (V,) m
    footprints: list[np.ndarray]  # V polygons (K, 2), world north/east
    margin: np.ndarray  # (V,) m the footprint is grown by (a GNSS antenna's point becomes a disc)
    own: tuple[float, float, float] | None  # truth own pose (north, east, yaw); None when the truth has none

    @staticmethod
    def none() -> FrameTruth:
        """No vessel, and no own pose of the truth's (the tick's own stands in)."""
        empty = np.zeros(0)
        return FrameTruth(
            np.zeros(0, np.int64), [], np.zeros((0, 2)), np.zeros((0, 2)), empty, empty, empty, [], empty, None
        )

    def select(self, keep: np.ndarray) -> FrameTruth:
        idx = np.flatnonzero(keep)
        return FrameTruth(
            ids=self.ids[idx],
            names=[self.names[i] for i in idx],
            position=self.position[idx],
            velocity=self.velocity[idx],
            heading=self.heading[idx],
            length=self.length[idx],
            width=self.width[idx],
            footprints=[self.footprints[i] for i in idx],
            margin=self.margin[idx],
            own=self.own,
        )

    def footprint_distance(self, points: np.ndarray) -> np.ndarray:
        """(V, N): distance from each point to each vessel's footprint (0 inside)."""
        p = np.asarray(points, float).reshape(-1, 2)
        out = np.zeros((len(self.footprints), p.shape[0]))
        for v, poly in enumerate(self.footprints):  # per vessel (a few), vectorised over points
            out[v] = np.maximum(distance_to_polygon(p, poly) - self.margin[v], 0.0)
        return out


def _lerp(a: np.ndarray, b: np.ndarray, f: float) -> np.ndarray:
    return a + (b - a) * f


class SimulatorTruth:
    """truth.csv (simulator/truth.py): one row per vessel per 0.1 s, with the own boat's pose on every row."""

    kind = "simulator"

    def __init__(self, path: Path) -> None:
        self.path = path
        try:
            table = read_truth_csv(path)
        except OSError as exc:
            raise EvaluationError(f"{path}: cannot read the truth CSV: {exc}") from exc
        except (ValueError, IndexError) as exc:
            raise EvaluationError(f"{path}: {exc}") from exc
        numeric = [c for c in CSV_COLUMNS if c not in ("id", "name", "hull", "footprint")]
        for c in numeric:
            bad = np.flatnonzero(~np.isfinite(table[c].astype(float)))
            if bad.size:
                raise EvaluationError(f"{path} line {int(bad[0]) + 2}: {c} is not a finite number")
        for i, fp in enumerate(table.footprints):
            if fp.ndim != 2 or fp.shape[1] != 2 or fp.shape[0] < 3 or not np.all(np.isfinite(fp)):
                raise EvaluationError(f"{path} line {i + 2}: footprint must be at least 3 finite 'north east' pairs")
        t = table["t"].astype(float)
        ids = table["id"].astype(np.int64)
        self.times = np.unique(t)
        self.ids = np.unique(ids)
        k = np.searchsorted(self.times, t)
        v = np.searchsorted(self.ids, ids)
        n_t, n_v = self.times.size, self.ids.size
        if np.any(np.bincount(k * max(n_v, 1) + v, minlength=n_t * n_v) > 1):
            raise EvaluationError(f"{path}: a vessel id appears twice at the same time")
        self.present = np.zeros((n_t, n_v), bool)
        self.present[k, v] = True
        self.position = np.full((n_t, n_v, 2), np.nan)
        self.velocity = np.full((n_t, n_v, 2), np.nan)
        self.heading = np.full((n_t, n_v), np.nan)
        self.position[k, v] = np.stack([table["north"], table["east"]], axis=-1)
        self.velocity[k, v] = np.stack([table["v_north"], table["v_east"]], axis=-1)
        self.heading[k, v] = table["heading"]
        self.length = np.zeros(n_v)
        self.width = np.zeros(n_v)
        self.names = [""] * n_v
        self.outline_body: list[np.ndarray] = [np.zeros((0, 2))] * n_v
        # a round buoy has no axis: its heading is the simulator's bookkeeping, no error of a track's can be scored
        self.axisless = np.zeros(n_v, dtype=bool)
        for row in range(len(table) - 1, -1, -1):  # the first row of each vessel wins
            j = v[row]
            self.length[j], self.width[j], self.names[j] = table["length"][row], table["width"][row], table["name"][row]
            self.axisless[j] = table["hull"][row] == "buoy" and table["length"][row] == table["width"][row]
            # the hull in its own (forward, starboard) frame, to be placed at any interpolated pose
            rel = table.footprints[row] - self.position[k[row], j]
            self.outline_body[j] = rel @ rotation_ne(table["heading"][row])
        self.own = np.full((n_t, 3), np.nan)
        self.own[k] = np.stack([table["own_north"], table["own_east"], table["own_yaw"]], axis=-1)

    @property
    def span(self) -> tuple[float, float] | None:
        return (float(self.times[0]), float(self.times[-1])) if self.times.size else None

    def at(self, t: float, world_origin: tuple[float, float] | None = None) -> FrameTruth | None:
        """The vessels at time ``t`` (truth clock); None outside the samples or across a gap."""
        del world_origin  # the simulator's world is the run's world (the capture's autopilot sends its local NED)
        bracket = _bracket(self.times, t)
        if bracket is None:
            return None
        k0, k1, f = bracket
        present = self.present[k0] & self.present[k1]
        pos = _lerp(self.position[k0], self.position[k1], f)[present]
        vel = _lerp(self.velocity[k0], self.velocity[k1], f)[present]
        h0 = self.heading[k0]
        heading = wrap_angle(h0 + wrap_angle(self.heading[k1] - h0) * f)[present]
        idx = np.flatnonzero(present)
        footprints = [pos[i] + self.outline_body[j] @ rotation_ne(heading[i]).T for i, j in enumerate(idx)]
        o0, o1 = self.own[k0], self.own[k1]
        own = (*_lerp(o0[:2], o1[:2], f), float(wrap_angle(o0[2] + wrap_angle(o1[2] - o0[2]) * f)))
        return FrameTruth(
            ids=self.ids[idx],
            names=[self.names[j] for j in idx],
            position=pos,
            velocity=vel,
            heading=np.where(self.axisless[idx], np.nan, heading),  # after the footprints, which it turned
            length=self.length[idx],
            width=self.width[idx],
            footprints=footprints,
            margin=np.zeros(idx.size),
            own=(float(own[0]), float(own[1]), own[2]),
        )


class GnssTruth:
    """A reference boat's GNSS track, CSV with columns time (Unix s, UTC), lat, lon (deg); other columns ignored.

    It has no hull: its footprint is a disc of ``radius`` m round the antenna. It is put in the run's world frame with
    each tick's world origin (the daemon's tick record), on a tangent plane there (under 1 m of error within 10 km).
    Its velocity is the finite difference of the two samples round the tick; heading and size are not known.
    """

    kind = "gnss"

    def __init__(self, path: Path, radius: float = 0.0) -> None:
        self.path = path
        self.radius = float(radius)
        try:
            with open(path, newline="", encoding="utf-8-sig") as f:  # a spreadsheet's BOM
                rows = list(csv.reader(f))
        except (OSError, UnicodeDecodeError) as exc:
            raise EvaluationError(f"{path}: cannot read the GNSS CSV: {exc}") from exc
        header = [h.strip().lower() for h in rows[0]] if rows else []
        if not {"time", "lat", "lon"} <= set(header):
            raise EvaluationError(f"{path} line 1: a GNSS reference needs the columns time, lat, lon")
        col = [header.index(c) for c in ("time", "lat", "lon")]
        data = []
        for line_no, row in enumerate(rows[1:], start=2):
            if not any(x.strip() for x in row):
                continue
            if len(row) <= max(col):
                raise EvaluationError(
                    f"{path} line {line_no}: {len(row)} column(s), the header names {len(header)} (time, lat, lon)"
                )
            try:
                t, lat, lon = (float(row[c]) for c in col)
            except ValueError as exc:
                raise EvaluationError(f"{path} line {line_no}: {exc}") from exc
            if not all(math.isfinite(x) for x in (t, lat, lon)) or not (-90 <= lat <= 90 and -180 <= lon <= 180):
                raise EvaluationError(f"{path} line {line_no}: time {t}, lat {lat}, lon {lon} out of range")
            if data and t <= data[-1][0]:
                raise EvaluationError(f"{path} line {line_no}: time {t} does not follow {data[-1][0]}")
            data.append((t, lat, lon))
        if not data:
            raise EvaluationError(f"{path}: no GNSS samples")
        arr = np.array(data, float)
        if np.median(arr[:, 0]) > 1e11:  # Unix seconds are ~1.8e9 now; milliseconds ~1.8e12
            raise EvaluationError(
                f"{path}: the time column looks like milliseconds ({arr[0, 0]:.0f}); it is read as Unix seconds (UTC):"
                " divide it by 1000"
            )
        self.times, self.lat, self.lon = arr[:, 0], arr[:, 1], arr[:, 2]

    @property
    def span(self) -> tuple[float, float]:
        return float(self.times[0]), float(self.times[-1])

    def at(self, t: float, world_origin: tuple[float, float] | None = None) -> FrameTruth | None:
        bracket = _bracket(self.times, t)
        if bracket is None or world_origin is None:
            return None
        k0, k1, f = bracket
        plane = LocalTangentPlane(world_origin[0], world_origin[1], 0.0)
        ne = plane.to_ned(self.lat[[k0, k1]], self.lon[[k0, k1]], np.zeros(2))[:, :2]  # world NED of both samples
        pos = _lerp(ne[0], ne[1], f)
        dt = self.times[k1] - self.times[k0]
        vel = (ne[1] - ne[0]) / dt if dt > 0 else np.full(2, np.nan)
        return FrameTruth(
            ids=np.array([0]),
            names=["reference"],
            position=pos[None],
            velocity=vel[None],
            heading=np.array([np.nan]),
            length=np.array([np.nan]),
            width=np.array([np.nan]),
            footprints=[pos[None]],
            margin=np.array([self.radius]),
            own=None,
        )


def _bracket(times: np.ndarray, t: float) -> tuple[int, int, float] | None:
    """Samples k0 <= t <= k1 and the fraction between them; None outside the samples or across a gap."""
    n = times.size
    if n == 0 or not times[0] - 1e-6 <= t <= times[-1] + 1e-6:
        return None
    k1 = int(np.clip(np.searchsorted(times, t, side="left"), 0, n - 1))
    if abs(times[k1] - t) <= 1e-6:
        return k1, k1, 0.0
    k0 = k1 - 1
    dt = times[k1] - times[k0]
    if dt > MAX_SAMPLE_GAP_S:
        return None
    return k0, k1, float((t - times[k0]) / dt)


def detect_truth(path: Path, reference_radius: float = 0.0) -> SimulatorTruth | GnssTruth:
    """A truth CSV or a GNSS CSV, told apart by the header."""
    try:
        with open(path, newline="", encoding="utf-8-sig") as f:  # a spreadsheet's BOM
            first = next(csv.reader(f), [])
    except (OSError, UnicodeDecodeError) as exc:
        raise EvaluationError(f"{path}: cannot read: {exc}") from exc
    if tuple(first) == CSV_COLUMNS:
        return SimulatorTruth(path)
    if {"time", "lat", "lon"} <= {h.strip().lower() for h in first}:
        return GnssTruth(path, reference_radius)
    raise EvaluationError(
        f"{path} line 1: neither a simulator truth CSV (t,id,name,...) nor a GNSS track (time,lat,lon): {first[:4]}"
    )
