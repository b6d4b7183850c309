"""Reading a run's --tracks-out file (daemon/loop.py: tick_record), one JSON object per 10 Hz tick.

Only what the evaluation needs is kept: the tick time, the confirmed tracks, the 72 bins as sent (None when
withheld) and, when the daemon wrote them, the own pose the tick used and the latitude/longitude of its world origin.
Everything stays in the file's units except angles, which become radians.
"""

from __future__ import annotations

import json
import math
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from evaluation.errors import EvaluationError

N_BINS = 72
UNKNOWN_CM = 65535


@dataclass(frozen=True)
class TrackRows:
    """The confirmed tracks of one tick, as arrays (H rows); NaN where the daemon published null."""

    ids: np.ndarray  # (H,) int
    position: np.ndarray  # (H, 2) world north/east, m
    velocity: np.ndarray  # (H, 2) m/s
    heading: np.ndarray  # (H,) rad, clockwise from north
    length: np.ndarray  # (H,) m
    width: np.ndarray  # (H,) m

    @staticmethod
    def empty() -> TrackRows:
        z = np.zeros(0)
        return TrackRows(np.zeros(0, np.int64), np.zeros((0, 2)), np.zeros((0, 2)), z, z, z)

    def __len__(self) -> int:
        return int(self.ids.size)

    def select(self, keep: np.ndarray) -> TrackRows:
        return TrackRows(
            self.ids[keep],
            self.position[keep],
            self.velocity[keep],
            self.heading[keep],
            self.length[keep],
            self.width[keep],
        )


@dataclass(frozen=True)
class Tick:
    t: float  # s, the run's clock (a replay's: the captures' Unix stamps)
    tracks: TrackRows
    bins_cm: np.ndarray | None  # (72,) int as sent, None when withheld
    own: tuple[float, float, float] | None  # world north, east (m), yaw (rad); None when the tick had no ego pose
    own_recorded: bool  # the record has the "own" key at all (files from before it was added do not)
    world_origin: tuple[float, float] | None  # lat, lon (deg) of the world frame's origin
    max_distance_m: float | None = None  # the run's [output] max_distance_m, where the record states it


def read_ticks(path: str | Path) -> list[Tick]:
    """All ticks of a --tracks-out file, in order. Raises EvaluationError naming the file and line."""
    path = Path(path)
    try:
        text = path.read_text(encoding="utf-8")
    except (OSError, UnicodeDecodeError) as exc:
        raise EvaluationError(f"{path}: cannot read the tracks file: {exc}") from exc
    ticks: list[Tick] = []
    for line_no, line in enumerate(text.splitlines(), start=1):
        if not line.strip():
            continue
        try:
            tick = _tick(json.loads(line))
        except json.JSONDecodeError as exc:
            raise EvaluationError(f"{path} line {line_no}: not JSON: {exc.msg}") from exc
        except (ValueError, TypeError, KeyError, IndexError) as exc:
            raise EvaluationError(f"{path} line {line_no}: {exc}") from exc
        if ticks and not tick.t > ticks[-1].t:
            raise EvaluationError(f"{path} line {line_no}: t = {tick.t} does not follow {ticks[-1].t}")
        ticks.append(tick)
    if not ticks:
        raise EvaluationError(f"{path}: no tick records")
    return ticks


def _number(x: Any, what: str) -> float:
    if isinstance(x, bool) or not isinstance(x, (int, float)) or not math.isfinite(x):
        raise ValueError(f"{what} must be a finite number, not {x!r}")
    return float(x)


def _maybe(x: Any, what: str) -> float:
    return math.nan if x is None else _number(x, what)


def _pair(x: Any, what: str) -> list[Any]:
    if not isinstance(x, list) or len(x) != 2:
        raise ValueError(f"{what} must be a list of two numbers, not {x!r}")
    return x


def _tick(rec: Any) -> Tick:
    if not isinstance(rec, dict):
        raise ValueError("a tick record must be a JSON object")
    t = _number(rec["t"], "t")
    tracks = rec["tracks"]
    if not isinstance(tracks, list):
        raise ValueError("tracks must be a list")
    rows: list[tuple[Any, ...]] = []
    for i, tr in enumerate(tracks):
        if not isinstance(tr, dict):
            raise ValueError(f"tracks[{i}] must be an object")
        if not isinstance(tr["confirmed"], bool):
            raise ValueError(f"tracks[{i}].confirmed must be true or false")
        if not tr["confirmed"]:
            continue  # only confirmed tracks are published as such, so only they are scored
        tid = tr["id"]
        if isinstance(tid, bool) or not isinstance(tid, int):
            raise ValueError(f"tracks[{i}].id must be an integer, not {tid!r}")
        pos = [_number(v, f"tracks[{i}].position_ne") for v in _pair(tr["position_ne"], f"tracks[{i}].position_ne")]
        vel = [_maybe(v, f"tracks[{i}].velocity_ne") for v in _pair(tr.get("velocity_ne", [None, None]), "velocity")]
        heading = _maybe(tr.get("heading_deg"), f"tracks[{i}].heading_deg")
        rows.append(
            (
                tid,
                pos,
                vel,
                math.radians(heading),
                _maybe(tr.get("length"), f"tracks[{i}].length"),
                _maybe(tr.get("width"), f"tracks[{i}].width"),
            )
        )
    ids = [r[0] for r in rows]
    if len(set(ids)) != len(ids):
        raise ValueError(f"track ids repeat within the tick: {sorted(ids)}")
    track_rows = (
        TrackRows(
            np.array(ids, np.int64),
            np.array([r[1] for r in rows], float).reshape(-1, 2),
            np.array([r[2] for r in rows], float).reshape(-1, 2),
            np.array([r[3] for r in rows], float),
            np.array([r[4] for r in rows], float),
            np.array([r[5] for r in rows], float),
        )
        if rows
        else TrackRows.empty()
    )
    bins = rec["obstacle_distance_cm"]
    bins_cm = None
    if bins is not None:
        if not isinstance(bins, list) or len(bins) != N_BINS:
            raise ValueError(f"obstacle_distance_cm must be null or a list of {N_BINS} integers")
        if not all(isinstance(v, int) and not isinstance(v, bool) and 0 <= v <= UNKNOWN_CM for v in bins):
            raise ValueError("obstacle_distance_cm values must be integers in 0..65535")
        bins_cm = np.array(bins, np.int64)
    own_rec = rec.get("own")
    own = None
    if own_rec is not None:
        if not isinstance(own_rec, dict):
            raise ValueError("own must be null or an object")
        n, e = (_maybe(v, "own.position_ne") for v in _pair(own_rec["position_ne"], "own.position_ne"))
        yaw = _maybe(own_rec["yaw_deg"], "own.yaw_deg")
        # a pose the daemon could not state (null) is no pose: the tick's tracks are then in no known frame
        own = (n, e, math.radians(yaw)) if all(math.isfinite(x) for x in (n, e, yaw)) else None
    origin_rec = rec.get("world_origin_lat_lon")
    origin = None
    if origin_rec is not None:
        lat, lon = (_number(v, "world_origin_lat_lon") for v in _pair(origin_rec, "world_origin_lat_lon"))
        if not (-90.0 <= lat <= 90.0 and -180.0 <= lon <= 180.0):
            raise ValueError(f"world_origin_lat_lon {origin_rec!r} is not a latitude/longitude")
        origin = (lat, lon)
    max_d = rec.get("max_distance_m")
    max_distance = None if max_d is None else _number(max_d, "max_distance_m")
    return Tick(t, track_rows, bins_cm, own, "own" in rec, origin, max_distance)
