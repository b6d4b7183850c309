"""Track scores: CLEAR MOT and IDF1 through py-motmetrics, HOTA, and the errors of matched pairs.

Matching: a confirmed track can match a vessel when its centre lies within ``match_distance`` of the vessel's hull
footprint (0 inside it), so a track on the visible half of a 43 m ship detects the ship. Among those candidates the
assignment (motmetrics: keep last frame's pairs while they stay candidates, Hungarian for the rest) minimises the
distance between track centre and vessel centre, and MOTP is the mean of that centre distance: a track on half a
ship matches, and its centre error still counts. HOTA's similarity is 1 - footprint distance / match_distance
(0 beyond): 1 for a centre on the hull, so HOTA scores detection and association, not where on the hull the centre
lies (MOTP and the position error do that); its loosest threshold (0.05) admits 0.95 of the match distance.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from evaluation.errors import MissingDependencyError
from evaluation.geometry import wrap_angle
from evaluation.hota import HotaScores, hota
from evaluation.reference import FrameTruth
from evaluation.ticks import TrackRows

EXTRA_HINT = "pip install 'usv-tracker[eval]' (py-motmetrics >= 1.4)"


@dataclass(frozen=True)
class ScoredFrame:
    """One tick to score: the vessels that are to be tracked then and the confirmed tracks that count."""

    index: int  # the tick's position in the tracks file
    truth: FrameTruth
    tracks: TrackRows
    # (H,) bool per track, or None: it also lies within the match distance of a vessel in range that no sensor
    # returned this tick. Left unmatched, such a track is on that vessel (coasting through its unreturned ticks), not
    # false: see drop_unmatched_on_unreturned.
    on_unreturned: np.ndarray | None = None


@dataclass(frozen=True)
class ErrorStats:
    n: int
    mean: float
    median: float
    p95: float

    @staticmethod
    def of(values: np.ndarray) -> ErrorStats:
        v = np.asarray(values, float)
        v = v[np.isfinite(v)]
        if v.size == 0:
            return ErrorStats(0, math.nan, math.nan, math.nan)
        return ErrorStats(int(v.size), float(v.mean()), float(np.median(v)), float(np.percentile(v, 95)))


@dataclass(frozen=True)
class TrackScores:
    frames: int
    objects: int  # vessel-ticks to be tracked
    matches: int  # matched pairs (switches included)
    misses: int
    false_positives: int
    id_switches: int
    fragmentations: int
    mota: float
    motp_m: float
    idf1: float
    idp: float
    idr: float
    precision: float
    recall: float
    unique_objects: int
    mostly_tracked: int
    mostly_lost: int
    hota: HotaScores
    position_error_m: ErrorStats
    speed_error_mps: ErrorStats
    heading_error_deg: ErrorStats
    heading_axis_error_deg: ErrorStats  # the hull's axis, direction ignored (0..90): a still hull has no bow to see
    length_error_m: ErrorStats
    width_error_m: ErrorStats
    velocity_coverage: float  # share of matched pairs whose track published a velocity
    per_vessel: dict[int, dict[str, int]] = field(default_factory=dict)


def _motmetrics() -> Any:
    try:
        import motmetrics
    except ImportError as exc:
        raise MissingDependencyError(
            f"scoring tracks needs py-motmetrics, which is not installed: {EXTRA_HINT}"
        ) from exc
    return motmetrics


def _accumulate(
    frames: Sequence[ScoredFrame], match_distance: float
) -> tuple[Any, dict[int, np.ndarray], list[np.ndarray]]:
    """The motmetrics accumulator over ``frames``, each frame's (V, H) centre distances and HOTA similarities."""
    mm = _motmetrics()
    acc = mm.MOTAccumulator(auto_id=False)
    sims = []
    centre_d: dict[int, np.ndarray] = {}
    for k, fr in enumerate(frames):
        tr = fr.truth
        fp_d = tr.footprint_distance(fr.tracks.position)  # (V, H)
        c_d = np.linalg.norm(tr.position[:, None, :] - fr.tracks.position[None, :, :], axis=2)
        cost = np.where(fp_d <= match_distance, c_d, np.nan)
        acc.update(tr.ids.tolist(), fr.tracks.ids.tolist(), cost, frameid=k)
        centre_d[k] = c_d
        sims.append(np.clip(1.0 - fp_d / match_distance, 0.0, 1.0))
    return acc, centre_d, sims


def drop_unmatched_on_unreturned(frames: Sequence[ScoredFrame], match_distance: float) -> tuple[list[ScoredFrame], int]:
    """``frames`` without the tracks that matched no vessel to be tracked but lie on a vessel no sensor returned
    that tick (``ScoredFrame.on_unreturned``), and how many track-ticks that removed.

    A track on an unreturned vessel is not scored (api.evaluate_run leaves it out before matching). One that also
    lies within the match distance of a returned vessel is kept for matching, since it may be that vessel's track;
    but when the assignment gives that vessel to another track, this one was counted false although it sat on a
    real hull: a buoy 1.6 m off an anchored boat, tracked through the revolutions that missed it, was 92 false
    track-ticks on tuning seed 54. The assignment is per tick, so leaving out a track it left unmatched changes no
    other pair."""
    flagged = [k for k, fr in enumerate(frames) if fr.on_unreturned is not None and fr.on_unreturned.any()]
    if not flagged:
        return list(frames), 0
    acc, _, _ = _accumulate(frames, match_distance)
    fr_id, typ, _, hid = _events(acc)
    false = typ == "FP"
    unmatched: dict[int, set[int]] = {}
    for k, h in zip(fr_id[false].tolist(), hid[false].astype(np.int64).tolist(), strict=True):
        unmatched.setdefault(int(k), set()).add(int(h))
    out = list(frames)
    dropped = 0
    for k in flagged:
        fr = frames[k]
        assert fr.on_unreturned is not None
        gone = fr.on_unreturned & np.isin(fr.tracks.ids, list(unmatched.get(k, ())))
        if gone.any():
            dropped += int(gone.sum())
            out[k] = ScoredFrame(fr.index, fr.truth, fr.tracks.select(~gone), fr.on_unreturned[~gone])
    return out, dropped


def score_tracks(frames: Sequence[ScoredFrame], match_distance: float) -> TrackScores:
    mm = _motmetrics()
    acc, centre_d, sims = _accumulate(frames, match_distance)
    gt_ids = [fr.truth.ids for fr in frames]
    tr_ids = [fr.tracks.ids for fr in frames]
    names = [
        "num_frames",
        "num_objects",
        "num_matches",
        "num_switches",
        "num_misses",
        "num_false_positives",
        "num_fragmentations",
        "mota",
        "motp",
        "idf1",
        "idp",
        "idr",
        "precision",
        "recall",
        "num_unique_objects",
        "mostly_tracked",
        "mostly_lost",
    ]
    summary = mm.metrics.create().compute(acc, metrics=names, name="run") if frames else None

    def get(name: str) -> float:
        if summary is None:
            return 0.0 if name.startswith(("num_", "mostly")) else math.nan
        x = float(summary[name].iloc[0])
        return x if math.isfinite(x) else math.nan

    pairs = _matched_pairs(acc, frames, centre_d)
    per_vessel = _per_vessel(acc, frames)
    n_matches = int(get("num_matches")) + int(get("num_switches"))
    objects = int(get("num_objects"))
    return TrackScores(
        frames=len(frames),
        objects=objects,
        matches=n_matches,
        misses=int(get("num_misses")),
        false_positives=int(get("num_false_positives")),
        id_switches=int(get("num_switches")),
        fragmentations=int(get("num_fragmentations")),
        # motmetrics gives -inf/NaN with no object at all; MOTA is then undefined, not a number
        mota=get("mota") if objects else math.nan,
        motp_m=get("motp") if n_matches else math.nan,
        idf1=get("idf1"),
        idp=get("idp"),
        idr=get("idr"),
        precision=get("precision"),
        recall=get("recall"),
        unique_objects=int(get("num_unique_objects")),
        mostly_tracked=int(get("mostly_tracked")),
        mostly_lost=int(get("mostly_lost")),
        hota=hota(gt_ids, tr_ids, sims),
        position_error_m=ErrorStats.of(pairs["position"]),
        speed_error_mps=ErrorStats.of(pairs["speed"]),
        heading_error_deg=ErrorStats.of(pairs["heading"]),
        heading_axis_error_deg=ErrorStats.of(np.minimum(pairs["heading"], 180.0 - pairs["heading"])),
        length_error_m=ErrorStats.of(pairs["length"]),
        width_error_m=ErrorStats.of(pairs["width"]),
        velocity_coverage=float(np.mean(pairs["has_velocity"])) if pairs["has_velocity"].size else math.nan,
        per_vessel=per_vessel,
    )


def _events(acc: Any) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    ev = acc.mot_events.reset_index()
    if ev.empty:
        z = np.zeros(0)
        return np.zeros(0, np.int64), np.zeros(0, str), z, z
    return (
        ev["FrameId"].to_numpy(np.int64),
        ev["Type"].to_numpy(str),
        ev["OId"].to_numpy(float),
        ev["HId"].to_numpy(float),
    )


def _matched_pairs(acc: Any, frames: Sequence[ScoredFrame], centre_d: dict[int, np.ndarray]) -> dict[str, np.ndarray]:
    """Per matched pair (MATCH or SWITCH events): the absolute errors of the track against its vessel."""
    fr, typ, oid, hid = _events(acc)
    sel = (typ == "MATCH") | (typ == "SWITCH")
    out: dict[str, list[float]] = {k: [] for k in ("position", "speed", "heading", "length", "width", "has_velocity")}
    for k, o, h in zip(fr[sel], oid[sel].astype(np.int64), hid[sel].astype(np.int64), strict=True):
        f = frames[int(k)]
        v = int(np.flatnonzero(f.truth.ids == o)[0])
        i = int(np.flatnonzero(f.tracks.ids == h)[0])
        tr, tk = f.truth, f.tracks
        out["position"].append(float(centre_d[int(k)][v, i]))
        has_v = bool(np.all(np.isfinite(tk.velocity[i])))
        out["has_velocity"].append(float(has_v))
        out["speed"].append(abs(float(np.hypot(*tk.velocity[i]) - np.hypot(*tr.velocity[v]))) if has_v else math.nan)
        out["heading"].append(math.degrees(abs(float(wrap_angle(tk.heading[i] - tr.heading[v])))))
        out["length"].append(abs(float(tk.length[i] - tr.length[v])))
        out["width"].append(abs(float(tk.width[i] - tr.width[v])))
    return {k: np.array(v, float) for k, v in out.items()}


def _per_vessel(acc: Any, frames: Sequence[ScoredFrame]) -> dict[int, dict[str, int]]:
    _, typ, oid, _ = _events(acc)
    out: dict[int, dict[str, int]] = {}
    for f in frames:
        for o in f.truth.ids:
            out.setdefault(int(o), {"to_track": 0, "matched": 0, "missed": 0, "switches": 0})["to_track"] += 1
    for t, o in zip(typ, oid, strict=True):
        if not math.isfinite(o):
            continue
        row = out[int(o)]
        if t in ("MATCH", "SWITCH"):
            row["matched"] += 1
        if t == "MISS":
            row["missed"] += 1
        if t == "SWITCH":
            row["switches"] += 1
    return out
