"""The 72 OBSTACLE_DISTANCE bins as sent, against the solids the sensors returned (simulator/returns.py).

Reference of a tick: the returns.csv windows that ended in the 0.2 s up to the tick (its two latest whole windows).
A VLP-16 revolution sweeps each bin once per 0.1 s, so whatever revolution the daemon used for a tick saw each bin
at the instant one of these two windows did; the radar's frames fall in them too.

Definitions (d = the distance sent in a bin, tol(d) = max(0.5 m, 5 % of d), max = max_distance):
  * false clear: the bin was sent clear (max + 1 cm) or unknown (65535) while a returned solid lay nearer than
    0.8 * max in that bin in every reference window (there throughout, so whatever the daemon's sweep caught, it
    was in it); split into sent-clear and sent-unknown;
  * false obstacle: the bin was sent with an obstacle at d while no returned solid lay at or nearer than d + tol(d)
    in that bin or its two neighbours in any reference window (an obstacle reported nearer than anything returned is
    false; the neighbours absorb a bearing that moved by the boat's turn between sweep and window);
  * within tolerance: an obstacle bin whose d is within tol(d) of the nearest returned solid in that bin in one of
    the reference windows; its share of the obstacle bins is reported.
Withheld ticks (bins null) and ticks without both reference windows are counted apart, not scored.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from evaluation.errors import EvaluationError
from evaluation.ticks import UNKNOWN_CM
from simulator.returns import ReturnsTable

REFERENCE_SPAN_S = 0.2  # two 0.1 s windows
CLEAR_SHARE = 0.8  # a solid nearer than this share of max_distance must not be reported clear
TOL_MIN_M = 0.5
TOL_SHARE = 0.05


@dataclass(frozen=True)
class BinScores:
    ticks_sent: int
    ticks_withheld: int
    ticks_withheld_with_solid: int  # withheld although a solid lay within 0.8 * max in some bin
    ticks_without_reference: int
    ticks_scored: int
    bins_scored: int
    obstacle_bins: int
    clear_bins: int
    unknown_bins: int
    bins_with_solid: int  # bins where a solid lay nearer than 0.8 * max throughout the reference windows
    false_clear: int
    false_clear_sent_clear: int
    false_clear_sent_unknown: int
    false_obstacle: int
    within_tolerance: int

    @property
    def false_clear_rate(self) -> float:
        return self.false_clear / self.bins_with_solid if self.bins_with_solid else math.nan

    @property
    def false_obstacle_rate(self) -> float:
        return self.false_obstacle / self.obstacle_bins if self.obstacle_bins else math.nan

    @property
    def within_tolerance_share(self) -> float:
        return self.within_tolerance / self.obstacle_bins if self.obstacle_bins else math.nan


def reference_windows(returns: ReturnsTable, t: float) -> np.ndarray:
    """Indices of the windows that ended in (t - 0.2 s, t] (truth clock); empty unless both are in the record (the
    first tick has one window before it, and the daemon's sweep then covered only part of the circle)."""
    w = np.flatnonzero((returns.t_end <= t + 1e-6) & (returns.t_end > t - REFERENCE_SPAN_S + 1e-6))
    return w if w.size * returns.window_s >= REFERENCE_SPAN_S - 1e-6 else w[:0]


def score_bins(
    returns: ReturnsTable, times: np.ndarray, bins_cm: list[np.ndarray | None], max_distance_m: float
) -> BinScores:
    """``times``: each tick's time on the truth clock; ``bins_cm``: its 72 values as sent, None when withheld."""
    max_cm = round(max_distance_m * 100)
    clear_cm = max_cm + 1
    n = {k: 0 for k in BinScores.__dataclass_fields__}
    for t, sent in zip(times, bins_cm, strict=True):
        w = reference_windows(returns, float(t))
        near = returns.nearest[w]  # (W, 72) m, inf where nothing came back
        # a solid the bin must show: returned inside the bin, not on its edge, in every reference window
        solid_everywhere = returns.core[w].max(axis=0, initial=-np.inf) if w.size else np.full(72, np.inf)
        has_solid = w.size > 0 and bool(np.any(solid_everywhere < CLEAR_SHARE * max_distance_m))
        if sent is None:
            n["ticks_withheld"] += 1
            n["ticks_withheld_with_solid"] += int(has_solid)
            continue
        n["ticks_sent"] += 1
        if w.size == 0:
            n["ticks_without_reference"] += 1
            continue
        bad = sent[(sent > clear_cm) & (sent != UNKNOWN_CM)]
        if bad.size:
            raise EvaluationError(
                f"a bin holds {int(bad[0])} cm, beyond max_distance + 1 ({clear_cm} cm): the run's max_distance is "
                f"larger than the {max_distance_m:g} m given (pass the run's [output] max_distance_m)"
            )
        n["ticks_scored"] += 1
        n["bins_scored"] += sent.size
        obstacle = sent <= max_cm
        clear = sent == clear_cm
        unknown = sent == UNKNOWN_CM
        n["obstacle_bins"] += int(obstacle.sum())
        n["clear_bins"] += int(clear.sum())
        n["unknown_bins"] += int(unknown.sum())

        should_show = solid_everywhere < CLEAR_SHARE * max_distance_m
        n["bins_with_solid"] += int(should_show.sum())
        n["false_clear_sent_clear"] += int((should_show & clear).sum())
        n["false_clear_sent_unknown"] += int((should_show & unknown).sum())

        d = sent / 100.0
        tol = np.maximum(TOL_MIN_M, TOL_SHARE * d)
        nearest_any = near.min(axis=0)  # (72,) nearest in any window
        around = np.minimum(nearest_any, np.minimum(np.roll(nearest_any, 1), np.roll(nearest_any, -1)))
        n["false_obstacle"] += int((obstacle & ~(around <= d + tol)).sum())
        closest_gap = np.min(np.abs(near - d[None, :]), axis=0)  # inf - d stays inf where nothing came back
        n["within_tolerance"] += int((obstacle & (closest_gap <= tol)).sum())
    n["false_clear"] = n["false_clear_sent_clear"] + n["false_clear_sent_unknown"]
    return BinScores(**n)
