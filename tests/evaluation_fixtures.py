"""Hand-made inputs for `usv-tracker evaluate` whose scores are known exactly: truth from the simulator's own
writer for a scene built here, tick records and returns.csv rows written out by hand."""

from __future__ import annotations

import json
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np

from simulator.returns import BIN_COLUMNS, POSE_COLUMNS, PRESENT_COLUMNS, solid_columns
from simulator.scene import OwnBoat, Scene, Trajectory, Vessel
from simulator.truth import write_truth_csv

CLEAR = 10001  # max_distance 100 m + 1 cm
UNKNOWN = 65535


def two_boats() -> Scene:
    """Own boat still at the origin heading north. Vessel 0: a 4 x 2 m box at (10, 0) heading north (footprint north
    8..12, east -1..1). Vessel 1: the same at (0, 20) (north -2..2, east 19..21)."""
    own = OwnBoat(Trajectory.stationary((0.0, 0.0), 0.0))
    a = Vessel("a", 4.0, 2.0, 1.5, Trajectory.stationary((10.0, 0.0), 0.0))
    b = Vessel("b", 4.0, 2.0, 1.5, Trajectory.stationary((0.0, 20.0), 0.0))
    return Scene("two_boats", own, [a, b], [])


def write_truth(directory: Path, scene: Scene, seconds: float) -> Path:
    directory.mkdir(parents=True, exist_ok=True)
    path = directory / "truth.csv"
    write_truth_csv(scene, path, 0.0, seconds)
    return path


def track(tid: int, north: float, east: float, **kw: Any) -> dict[str, Any]:
    """A tick record's track; confirmed, at rest, heading north, 4 x 2 m unless given."""
    rec = {
        "id": tid,
        "source": "lidar",
        "confirmed": True,
        "position_ne": [north, east],
        "velocity_ne": [0.0, 0.0],
        "heading_deg": 0.0,
        "yaw_rate_dps": 0.0,
        "length": 4.0,
        "width": 2.0,
        "height": 1.5,
        "shape": "box",
        "motion": "static",
    }
    rec.update(kw)
    return rec


def tick(t: float, tracks: Sequence[dict[str, Any]], bins: Sequence[int] | None = None, **kw: Any) -> dict[str, Any]:
    rec: dict[str, Any] = {
        "t": t,
        "tracks": list(tracks),
        "obstacle_distance_cm": list(bins) if bins is not None else [CLEAR] * 72,
        "lidar_fresh": True,
        "radar_fresh": True,
        "own": {"position_ne": [0.0, 0.0], "yaw_deg": 0.0},
        "world_origin_lat_lon": [59.41, 10.49],
    }
    rec.update(kw)
    return rec


def write_ticks(path: Path, ticks: Sequence[dict[str, Any]]) -> Path:
    path.write_text("".join(json.dumps(t) + "\n" for t in ticks))
    return path


def write_returns(
    path: Path,
    counts: np.ndarray,
    nearest: np.ndarray,
    window_s: float = 0.1,
    core: np.ndarray | None = None,
    present: np.ndarray | None = None,
) -> Path:
    """``counts``: (W, 1 + V, 2) LiDAR/radar returns of the shore and each vessel; ``nearest``: (W, 72) m (inf: none),
    as the LiDAR returned them (the radar's bins are empty); ``core``: the same from returns inside their bins, away
    from the edges (default: ``nearest``); ``present``: (W, 72) m, the nearest solid there, returned or not (default:
    no such columns, as in files written before them). The own boat sits at the origin heading north, as in
    two_boats()."""
    n_vessels = counts.shape[1] - 1
    core = nearest if core is None else core
    extra = list(PRESENT_COLUMNS) if present is not None else []
    lines = [",".join([*POSE_COLUMNS, *solid_columns(n_vessels), *BIN_COLUMNS, *extra])]
    for k in range(counts.shape[0]):
        pose = [f"{k * window_s:.6f}", f"{(k + 1) * window_s:.6f}", "0", "0", "0"]
        c = [str(int(x)) for x in counts[k].reshape(-1)]
        none = np.full(72, np.inf)
        there = () if present is None else tuple(present[k])
        b = ["" if not np.isfinite(r) else f"{r:.3f}" for r in (*nearest[k], *core[k], *none, *none, *there)]
        lines.append(",".join(pose + c + b))
    path.write_text("\n".join(lines) + "\n")
    return path
