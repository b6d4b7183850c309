"""`evaluate_run`: score one run's --tracks-out file against ground truth. No global state; every call stands alone.

Time alignment. The captures of `simulate --write` are stamped T0_UNIX + scene time and a replay ticks on those
stamps, while truth.csv and returns.csv are in scene time; a replayed recording ticks on the host's Unix time, as a
GNSS track is stamped. So the offset truth time - tick time is, unless given, the candidate (0, or -T0_UNIX for
simulator truth) that puts the most ticks inside the truth's span; none at all is an error asking for an explicit
offset. The chosen offset and how it was found are part of the result. Truth is interpolated to each tick's time.

Fairness. With a returns.csv (simulator truth), a vessel is to be tracked at a tick only if, in one of the tick's
reference windows (those overlapping the 0.2 s up to it), the sensors returned it at least ``min_returns`` times (a
cluster needs 3 points). A vessel in range (footprint within ``max_distance_m`` of the own boat) that was not
returned is counted apart as a sensor limit, not a miss; a confirmed track on such a vessel (within the match
distance of it and of no vessel to be tracked) is neither a match nor a false positive. Without a returns record
every vessel in range is to be tracked. With a GNSS reference only the reference boat is known: it is to be tracked
while in range, and tracks away from it are not scored (they are other boats, not false positives).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from pathlib import Path

import numpy as np

from evaluation.bins import reference_windows, score_bins
from evaluation.defaults import DEFAULT_MATCH_DISTANCE_M, DEFAULT_MAX_DISTANCE_M, DEFAULT_MIN_RETURNS
from evaluation.errors import EvaluationError
from evaluation.reference import FrameTruth, GnssTruth, SimulatorTruth, detect_truth
from evaluation.result import EvaluationResult
from evaluation.ticks import read_ticks
from evaluation.tracking import ScoredFrame, drop_unmatched_on_unreturned, score_tracks
from simulator.returns import ReturnsFormatError, ReturnsTable, read_returns_csv
from simulator.truth import T0_UNIX


def evaluate_run(
    truth: str | Path,
    tracks: str | Path,
    *,
    returns: str | Path | None = None,
    match_distance_m: float = DEFAULT_MATCH_DISTANCE_M,
    max_distance_m: float = DEFAULT_MAX_DISTANCE_M,
    min_returns: int = DEFAULT_MIN_RETURNS,
    warmup_s: float = 0.0,
    time_offset_s: float | None = None,
    reference_radius_m: float = 0.0,
    sensors: Sequence[str] = ("lidar", "radar"),
) -> EvaluationResult:
    """Score ``tracks`` (a --tracks-out JSONL file) against ``truth``.

    ``truth``: a `simulate --write` directory (its truth.csv, and its returns.csv when there), a truth CSV, or a
    reference boat's GNSS CSV (time, lat, lon). ``returns``: a returns.csv to use instead of the directory's.
    ``time_offset_s``: truth time = tick t + offset; None finds it (see the module's doc). ``reference_radius_m``:
    a GNSS reference's hull as a disc of this radius round the antenna. ``sensors``: the sensors the run had; only
    their returns decide what was to be tracked and what a bin had to show (a LiDAR-only run is not judged by what
    the radar returned). Raises EvaluationError for bad input.
    """
    _check_settings(match_distance_m, max_distance_m, min_returns, warmup_s, time_offset_s, reference_radius_m)
    truth_path, returns_path = _resolve(Path(truth), returns)
    reference = detect_truth(truth_path, reference_radius_m)
    table = _read_returns(returns_path) if returns_path is not None and reference.kind == "simulator" else None
    if table is not None:
        try:
            table = table.for_sensors(sensors)
        except ValueError as exc:
            raise EvaluationError(str(exc)) from exc
    ticks = read_ticks(tracks)
    notes: list[str] = []
    if returns_path is not None and reference.kind == "gnss":
        notes.append("a returns record says nothing about a GNSS reference's run: not used")
        returns_path = None

    stated = {tk.max_distance_m for tk in ticks if tk.max_distance_m is not None}
    if any(abs(m - max_distance_m) > 1e-6 for m in stated):
        m = next(v for v in sorted(stated) if abs(v - max_distance_m) > 1e-6)
        raise EvaluationError(
            f"{tracks}: the run sent its bins with [output] max_distance_m = {m:g} m (its tick records say so), "
            f"not the {max_distance_m:g} m given: pass --max-distance {m:g}"
        )
    times = np.array([tk.t for tk in ticks])
    offset, method = _align(times, reference, table, time_offset_s)
    truth_times = times + offset
    span = _span(reference, table)
    in_span = (truth_times >= span[0] - 1e-6) & (truth_times <= span[1] + 1e-6)
    start = truth_times[in_span][0] + warmup_s if in_span.any() else math.inf
    scored_tick = in_span & (truth_times >= start - 1e-9)

    counts = {"outside": int((~in_span).sum()), "warmup": int((in_span & ~scored_tick).sum()), "no_pose": 0}
    counts["no_origin"] = 0
    vis = {"to_track": 0, "limit": 0, "out": 0, "no_record": 0, "dropped": 0, "unknown": 0}
    per_vessel: dict[int, dict[str, object]] = {}
    frames: list[ScoredFrame] = []
    own_err: list[float] = []
    for i in np.flatnonzero(scored_tick):
        tick = ticks[i]
        t = float(truth_times[i])
        if tick.own_recorded and tick.own is None:
            counts["no_pose"] += 1  # "no ego pose" mode: the tracks are in no frame the truth is in
            continue
        if reference.kind == "gnss" and tick.world_origin is None:
            counts["no_origin"] += 1
            continue
        ft = reference.at(t, tick.world_origin)
        if ft is None and reference.kind == "simulator" and reference.span is None and table is not None:
            ft = FrameTruth.none()  # a scene without vessels: within the returns' span every track is false
        if ft is None:
            counts["outside"] += 1
            continue
        if ft.own is not None and tick.own is not None:
            own_err.append(float(np.hypot(ft.own[0] - tick.own[0], ft.own[1] - tick.own[1])))
        own = ft.own if ft.own is not None else tick.own
        care, in_range, known = _to_track(ft, own, table, t, max_distance_m, min_returns)
        limit = in_range & ~care & known
        for j, vid in enumerate(ft.ids):
            row = per_vessel.setdefault(int(vid), {"name": ft.names[j], "to_track": 0, "sensor_limit": 0})
            row["to_track"] = int(row["to_track"]) + int(care[j])
            row["sensor_limit"] = int(row["sensor_limit"]) + int(limit[j])
        vis["to_track"] += int(care.sum())
        vis["limit"] += int(limit.sum())
        vis["out"] += int((~in_range).sum())
        vis["no_record"] += 0 if known else ft.ids.size
        gate = ft.footprint_distance(tick.tracks.position) <= match_distance_m  # (V, H)
        on_care = gate[care].any(axis=0)
        on_other = gate[~care].any(axis=0)
        keep = on_care | (~on_other if reference.kind == "simulator" else np.zeros_like(on_care))
        vis["dropped"] += int((on_other & ~on_care).sum())
        if reference.kind == "gnss":
            vis["unknown"] += int((~on_care & ~on_other).sum())
        frames.append(ScoredFrame(int(i), ft.select(care), tick.tracks.select(keep), on_other[keep]))

    frames, on_unreturned = drop_unmatched_on_unreturned(frames, match_distance_m)
    vis["dropped"] += on_unreturned
    scores = score_tracks(frames, match_distance_m)
    for vid, row in per_vessel.items():
        row.update({k: v for k, v in scores.per_vessel.get(vid, {}).items() if k != "to_track"})
        for k in ("matched", "missed", "switches"):
            row.setdefault(k, 0)

    bins = None
    bins_note = ""
    if table is not None:
        idx = np.flatnonzero(scored_tick)
        bins = score_bins(table, truth_times[idx], [ticks[i].bins_cm for i in idx], max_distance_m)
    else:
        bins_note = (
            "a GNSS reference has no record of the solids the sensors returned"
            if reference.kind == "gnss"
            else "no returns.csv beside the truth (captures written before it existed?)"
        )
        if reference.kind == "simulator":
            notes.append("no returns.csv: every vessel in range is to be tracked, and the bins are not scored")
    if reference.kind == "gnss":
        notes.append(
            f"GNSS reference: {vis['unknown']} track-ticks away from the reference boat were not scored; "
            "heading and size errors need a hull and are not available"
        )
    if own_err and max(own_err) > 1.0:
        notes.append(
            f"the run's own position differs from the truth's by up to {max(own_err):.1f} m: the tracks may not be "
            "in the truth's world frame (was the capture's autopilot.tlog replayed?)"
        )
    alignment = {
        "time_offset_s": offset,
        "method": method,
        "truth_span_s": list(span),
        "ticks_in_file": len(ticks),
        "ticks_scored": len(frames),
        "ticks_outside_truth": counts["outside"],
        "ticks_in_warmup": counts["warmup"],
        "ticks_without_pose": counts["no_pose"],
        "ticks_without_world_origin": counts["no_origin"],
        "own_position_error_m": {
            "mean": float(np.mean(own_err)) if own_err else math.nan,
            "max": float(np.max(own_err)) if own_err else math.nan,
        },
    }
    visibility = {
        "vessel_ticks_to_track": vis["to_track"],
        "vessel_ticks_sensor_limit": vis["limit"],
        "vessel_ticks_out_of_range": vis["out"],
        "vessel_ticks_without_record": vis["no_record"],
        "tracks_on_unreturned_vessels": vis["dropped"],
        "tracks_away_from_reference": vis["unknown"] if reference.kind == "gnss" else None,
        "per_vessel": per_vessel,
        "bins_note": bins_note or None,
    }
    return EvaluationResult(
        truth_kind=reference.kind,
        inputs={"truth": str(truth_path), "tracks": str(tracks), "returns": str(returns_path) if table else None},
        settings={
            "match_distance_m": match_distance_m,
            "max_distance_m": max_distance_m,
            "min_returns": min_returns,
            "warmup_s": warmup_s,
            "reference_radius_m": reference_radius_m,
            "sensors": list(table.sensors) if table is not None else list(sensors),
        },
        alignment=alignment,
        tracks=scores,
        visibility=visibility,
        bins=bins,
        notes=notes,
    )


def _check_settings(
    match: float, max_d: float, min_returns: int, warmup: float, offset: float | None, radius: float
) -> None:
    def finite(x: float) -> bool:
        return isinstance(x, (int, float)) and math.isfinite(x)

    if not (finite(match) and match > 0):
        raise EvaluationError(f"match distance must be a positive number of metres, not {match!r}")
    if not (finite(max_d) and 1.0 <= max_d <= 655.0):
        raise EvaluationError(f"max distance must be 1..655 m (OBSTACLE_DISTANCE's range in cm), not {max_d!r}")
    if isinstance(min_returns, bool) or not isinstance(min_returns, int) or min_returns < 1:
        raise EvaluationError(f"min returns must be an integer >= 1, not {min_returns!r}")
    if not (finite(warmup) and warmup >= 0):
        raise EvaluationError(f"warm-up must be >= 0 s, not {warmup!r}")
    if offset is not None and not finite(offset):
        raise EvaluationError(f"time offset must be a finite number of seconds, not {offset!r}")
    if not (finite(radius) and radius >= 0):
        raise EvaluationError(f"reference radius must be >= 0 m, not {radius!r}")


def _resolve(truth: Path, returns: str | Path | None) -> tuple[Path, Path | None]:
    if truth.is_dir():
        truth_csv = truth / "truth.csv"
        if not truth_csv.is_file():
            raise EvaluationError(
                f"{truth}: no truth.csv in this directory (written by `usv-tracker simulate --write`)"
            )
        beside = truth / "returns.csv"
        return truth_csv, Path(returns) if returns is not None else (beside if beside.is_file() else None)
    if not truth.is_file():
        raise EvaluationError(f"{truth}: no such file or directory")
    if returns is None and truth.name == "truth.csv":
        # the simulator's truth.csv named as a file: the returns it wrote beside it are the same run's, as with the
        # directory (a GNSS reference CSV has no such companion)
        beside = truth.with_name("returns.csv")
        return truth, beside if beside.is_file() else None
    return truth, Path(returns) if returns is not None else None


def _read_returns(path: Path) -> ReturnsTable:
    try:
        return read_returns_csv(path)
    except ReturnsFormatError as exc:
        raise EvaluationError(str(exc)) from exc


def _span(reference: SimulatorTruth | GnssTruth, table: ReturnsTable | None) -> tuple[float, float]:
    span = reference.span
    if span is None and table is not None and table.t_end.size:  # a scene without vessels: the returns' span
        span = (float(table.t_start[0]), float(table.t_end[-1]))
    return span if span is not None else (math.nan, math.nan)


def _align(
    times: np.ndarray, reference: SimulatorTruth | GnssTruth, table: ReturnsTable | None, given: float | None
) -> tuple[float, str]:
    lo, hi = _span(reference, table)
    if given is not None:
        off = float(given)
        if math.isfinite(lo) and not np.any((times + off >= lo - 1e-6) & (times + off <= hi + 1e-6)):
            raise EvaluationError(
                f"no tick (t = {times[0]:.3f} .. {times[-1]:.3f}) falls in the truth's span {lo:.3f} .. {hi:.3f} s "
                f"with the given offset {off:+.3f} s (truth time - tick t): nothing to score"
            )
        return off, "given"
    if not math.isfinite(lo):
        raise EvaluationError(f"{reference.path}: the truth holds no samples to align the ticks with")
    candidates = {0.0: "same clock"}
    if reference.kind == "simulator":
        candidates[-T0_UNIX] = "capture epoch T0_UNIX subtracted"
    inside = {off: int(np.sum((times + off >= lo - 1e-6) & (times + off <= hi + 1e-6))) for off in candidates}
    best = max(inside, key=lambda off: inside[off])
    if inside[best] == 0:
        raise EvaluationError(
            f"no tick (t = {times[0]:.3f} .. {times[-1]:.3f}) falls in the truth's span {lo:.3f} .. {hi:.3f} s "
            f"with offset {' or '.join(f'{o:+.0f}' for o in candidates)}: give the offset (truth time - tick t)"
        )
    return best, f"auto: {candidates[best]}, {inside[best]} of {times.size} ticks inside the truth"


def _to_track(
    ft: FrameTruth,
    own: tuple[float, float, float] | None,
    table: ReturnsTable | None,
    t: float,
    max_distance_m: float,
    min_returns: int,
) -> tuple[np.ndarray, np.ndarray, bool]:
    """(care, in_range) per vessel of the frame, and whether the returns record covers the tick."""
    if own is None:
        in_range = np.ones(ft.ids.size, bool)
    else:
        in_range = ft.footprint_distance(np.array([own[:2]]))[:, 0] <= max_distance_m
    if table is None:
        return in_range.copy(), in_range, True
    w = reference_windows(table, t)
    if w.size == 0:  # the record does not cover this tick: nobody can say what was returned
        return np.zeros(ft.ids.size, bool), in_range, False
    returned = np.array([int(np.max(table.returns_of(int(v))[w])) >= min_returns for v in ft.ids], bool)
    return returned.reshape(-1), in_range | returned, True
