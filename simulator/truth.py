"""Ground truth of a simulated scene, and the CSV file that goes with a capture.

The truth comes straight from the analytic trajectories (scene.py), so it is exact at any time, not sampled from a
simulation loop. The CSV has one row per vessel per tick, plus the own boat's pose on every row, so that a benchmark
can score a recorded run without the simulator.
"""

from __future__ import annotations

import csv
import io
import math
from dataclasses import dataclass
from pathlib import Path
from typing import TextIO

import numpy as np

from drivers.frames import EgoPose
from simulator.scene import Scene

# The captures' clock: `simulate --write` stamps every file at this Unix time + scene time, and the truth CSV and
# returns.csv are in scene time, so an evaluation subtracts it from a replayed run's tick times.
T0_UNIX = 1_767_225_600.0  # 2026-01-01 00:00:00 UTC: a fixed epoch keeps the files reproducible

CSV_COLUMNS = (
    "t",
    "id",
    "name",
    "north",
    "east",
    "v_north",
    "v_east",
    "heading",
    "yaw_rate",
    "length",
    "width",
    "height",
    "hull",
    "own_north",
    "own_east",
    "own_v_north",
    "own_v_east",
    "own_yaw",
    "own_yaw_rate",
    "own_roll",
    "own_pitch",
    "footprint",
)


@dataclass(frozen=True)
class VesselTruth:
    """One vessel at one time, world frame (north, east), SI units, heading 0 = north clockwise."""

    id: int
    name: str
    t: float
    position: np.ndarray  # (2,)
    velocity: np.ndarray  # (2,)
    heading: float
    yaw_rate: float
    length: float
    width: float
    height: float
    hull: str
    footprint: np.ndarray  # (K, 2) hull outline, counter-clockwise (north, east), without padding

    @property
    def speed(self) -> float:
        return float(np.hypot(*self.velocity))


@dataclass(frozen=True)
class SceneTruth:
    t: float
    own: EgoPose
    vessels: list[VesselTruth]

    def by_id(self, vessel_id: int) -> VesselTruth:
        for v in self.vessels:
            if v.id == vessel_id:
                return v
        raise KeyError(vessel_id)


def truth_at(scene: Scene, t: float) -> SceneTruth:
    """Exact state of every vessel (id = index in ``scene.vessels``) and of the own boat at time ``t``."""
    vessels: list[VesselTruth] = []
    if scene.vessels:
        s = scene.vessel_states(t)
        fp = scene.footprints(t)[0]
        for j, v in enumerate(scene.vessels):
            outline = fp[j, :4] if v.hull == "box" else fp[j]
            vessels.append(
                VesselTruth(
                    id=j,
                    name=v.name,
                    t=float(t),
                    position=s.position[0, j].copy(),
                    velocity=s.velocity[0, j].copy(),
                    heading=float(s.heading[0, j]),
                    yaw_rate=float(s.yaw_rate[0, j]),
                    length=v.length,
                    width=v.width,
                    height=v.height,
                    hull=v.hull,
                    footprint=outline.copy(),
                )
            )
    return SceneTruth(float(t), scene.own.pose(t), vessels)


def _fmt(x: float) -> str:
    return f"{x:.6f}"


class TruthCsvWriter:
    """Writes SceneTruth snapshots as CSV rows (one per vessel); the footprint column is "n e;n e;..."."""

    def __init__(self, target: str | Path | TextIO) -> None:
        if isinstance(target, (str, Path)):
            self._file: TextIO = open(target, "w", newline="")  # noqa: SIM115 - closed by close()
            self._owns_file = True
        else:
            self._file = target
            self._owns_file = False
        self._writer = csv.writer(self._file)
        self._writer.writerow(CSV_COLUMNS)
        self.rows = 0

    def write(self, truth: SceneTruth) -> None:
        own = truth.own
        own_cols = [
            _fmt(own.position[0]),
            _fmt(own.position[1]),
            _fmt(own.velocity[0]),
            _fmt(own.velocity[1]),
            _fmt(own.yaw),
            _fmt(own.yaw_rate),
            _fmt(own.roll),
            _fmt(own.pitch),
        ]
        for v in truth.vessels:
            footprint = ";".join(f"{n:.4f} {e:.4f}" for n, e in v.footprint)
            self._writer.writerow(
                [
                    _fmt(truth.t),
                    v.id,
                    v.name,
                    _fmt(v.position[0]),
                    _fmt(v.position[1]),
                    _fmt(v.velocity[0]),
                    _fmt(v.velocity[1]),
                    _fmt(v.heading),
                    _fmt(v.yaw_rate),
                    _fmt(v.length),
                    _fmt(v.width),
                    _fmt(v.height),
                    v.hull,
                    *own_cols,
                    footprint,
                ]
            )
            self.rows += 1

    def flush(self) -> None:
        self._file.flush()

    def close(self) -> None:
        if self._owns_file:
            self._file.close()
        else:
            self._file.flush()

    def __enter__(self) -> TruthCsvWriter:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()


def write_truth_csv(scene: Scene, target: str | Path | TextIO, t0: float, t1: float, period: float = 0.1) -> int:
    """Truth on the tick grid t = k * period within [t0, t1); returns the number of rows written."""
    with TruthCsvWriter(target) as w:
        for k in range(math.ceil(t0 / period - 1e-9), math.ceil(t1 / period - 1e-9)):
            w.write(truth_at(scene, k * period))
        return w.rows


@dataclass(frozen=True)
class TruthTable:
    """A truth CSV read back as columns (arrays of equal length, one entry per row)."""

    columns: dict[str, np.ndarray]
    footprints: list[np.ndarray]

    def __len__(self) -> int:
        return len(self.footprints)

    def __getitem__(self, name: str) -> np.ndarray:
        return self.columns[name]


def read_truth_csv(source: str | Path | TextIO) -> TruthTable:
    """Read a file written by TruthCsvWriter. Raises ValueError naming the line for a malformed row."""
    if isinstance(source, (str, Path)):
        with open(source, newline="") as f:
            text = f.read()
    else:
        text = source.read()
    reader = csv.reader(io.StringIO(text))
    header = next(reader, None)
    if header is None or tuple(header) != CSV_COLUMNS:
        raise ValueError(f"not a truth CSV: header {header!r}")
    text_cols = {"name", "hull", "footprint"}
    cols: dict[str, list] = {c: [] for c in CSV_COLUMNS if c != "footprint"}
    footprints: list[np.ndarray] = []
    for line_no, row in enumerate(reader, start=2):
        if len(row) != len(CSV_COLUMNS):
            raise ValueError(f"truth CSV line {line_no}: {len(row)} fields, expected {len(CSV_COLUMNS)}")
        try:
            for name, value in zip(CSV_COLUMNS, row, strict=True):
                if name == "footprint":
                    footprints.append(np.array([[float(x) for x in p.split()] for p in value.split(";")]))
                elif name == "id":
                    cols[name].append(int(value))
                elif name in text_cols:
                    cols[name].append(value)
                else:
                    cols[name].append(float(value))
        except ValueError as exc:
            raise ValueError(f"truth CSV line {line_no}: {exc}") from exc
    arrays = {k: np.array(v, dtype=object if k in text_cols else None) for k, v in cols.items()}
    return TruthTable(arrays, footprints)
