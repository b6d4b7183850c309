"""The 72 OBSTACLE_DISTANCE bins as sent, against the solids the sensors returned (simulator/returns.py).

Reference of a tick: the returns.csv windows that overlap the 0.2 s up to the tick (two or three of them). A VLP-16
revolution sweeps each bin once per 0.1 s and the tick uses the newest revolution completed before it, so whatever
revolution the daemon used for a tick saw each bin at an instant these windows hold; the radar's frames fall in them
too.

Definitions (d = the distance sent in a bin, tol(d) = max(0.5 m, 5 % of d), max = max_distance):
  * false clear: the bin was sent clear (max + 1 cm) or unknown (65535) while a returned solid lay nearer than
    0.8 * max in that bin in every reference window (there throughout, so whatever the daemon's sweep caught, it
    was in it); split into sent-clear and sent-unknown;
  * false obstacle: the bin was sent with an obstacle at d while no solid lay at or nearer than d + tol(d) in that
    bin or its two neighbours in any reference window, neither a returned one nor, where the record has them
    (returns.csv's present columns), one that was there unreturned (an obstacle reported nearer than anything
    there is false; the neighbours absorb a bearing that moved by the boat's turn between sweep and window). An
    obstacle on a solid that was there but that no sensor returned in those windows (the daemon held it from an
    earlier sweep) is counted apart as ``obstacle_unreturned``, not as false;
  * too far: the bin was sent with an obstacle at d while a returned solid lay nearer than d - tol(d) (and nearer
    than 0.8 * max) in that bin in every reference window: the autopilot is told of more room than there is, as
    unsafe as a false clear, which it is in all but name;
  * within tolerance: an obstacle bin whose d is within tol(d) of the nearest returned solid in that bin in one of
    the reference windows; its share of the obstacle bins is reported.
Withheld ticks (bins null) and ticks whose reference windows do not cover the span are counted apart, not scored.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from evaluation.errors import EvaluationError
from evaluation.ticks import UNKNOWN_CM
from simulator.returns import ReturnsTable

REFERENCE_SPAN_S = 0.2  # two sweeps of a bin: the revolution a tick uses ends up to 0.1 s before it
_OVERLAP_S = 1e-3  # a window must overlap the span by more than this (tick stamps fall microseconds off the grid)
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
    obstacle_unreturned: int  # obstacle bins on a solid that was there but not returned in the reference windows
    false_clear_sent_clear: int
    false_clear_sent_unknown: int
    false_obstacle: int
    too_far: int  # obstacle bins beyond a solid returned nearer throughout the reference windows (by the tolerance)
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
    """Indices of the windows that overlap (t - 0.2 s, t] (truth clock): every sweep the daemon's newest revolution
    at tick t can have made of a bin lies in them; empty unless they cover that whole span (the first tick has less
    before it, and the daemon's sweep then covered only part of the circle).

    Overlap, not "ended by t": a revolution completes up to 0.1 s before the tick that uses it, so it can lie across
    the window that holds the tick. Ticks on the windows' edges (the held-out bench's, within a microsecond) get the
    same two windows either way. A live run's ticks fall anywhere: one halfway through a window was judged by windows
    that ended 0.05 s before it, missing the last part of the sweep it used, and one 0.4 ms before an edge (a short
    replay's) by the two windows before its revolution's.
    """
    span = REFERENCE_SPAN_S - _OVERLAP_S
    w = np.flatnonzero((returns.t_start < t - _OVERLAP_S) & (returns.t_end > t - span))
    if w.size == 0 or returns.t_start[w[0]] > t - span or returns.t_end[w[-1]] < t - _OVERLAP_S:
        return w[:0]
    return w


def _around(nearest: np.ndarray) -> np.ndarray:
    """(72,) the nearest in each bin or its two neighbours."""
    return np.minimum(nearest, np.minimum(np.roll(nearest, 1), np.roll(nearest, -1)))


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
        n["too_far"] += int((should_show & obstacle & (solid_everywhere < d - tol)).sum())
        nearest_any = near.min(axis=0)  # (72,) nearest in any window
        unreturned = obstacle & ~(_around(nearest_any) <= d + tol)
        if returns.present is not None:
            there = _around(returns.present[w].min(axis=0)) <= d + tol
            n["obstacle_unreturned"] += int((unreturned & there).sum())
            unreturned &= ~there
        n["false_obstacle"] += int(unreturned.sum())
        closest_gap = np.min(np.abs(near - d[None, :]), axis=0)  # inf - d stays inf where nothing came back
        n["within_tolerance"] += int((obstacle & (closest_gap <= tol)).sum())
    n["false_clear"] = n["false_clear_sent_clear"] + n["false_clear_sent_unknown"]
    return BinScores(**n)
