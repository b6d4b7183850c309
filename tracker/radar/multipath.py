"""Multipath ghosts: returns that mirror a real target further out along the same bearing (paper 001, sec. 3.2).

A wave that bounces target -> own hull (or radome) -> target -> radar travels k times the direct path, so the radar
reports a copy of the target at k times its range, on nearly the same bearing, with k times its raw Doppler (the
path length changes k times as fast) and a weaker echo. A return is called a ghost when some other return on a
bearing within the search angle explains it that way, and it is weaker by at least ``min_snr_drop_db``
(tracker.radar.config.MultipathConfig holds the settings). With the own boat and the target both at rest the Doppler
test cannot tell; the SNR drop then keeps a real, larger boat at twice the range of a small one (tested on the
simulated paper scene, where it had been removed for minutes).
"""

from __future__ import annotations

import math

import numpy as np

from tracker.radar.config import MultipathConfig

# Bearings are widened by this much when pairs are gathered; the exact test on each pair then decides (the wrapped
# difference it computes may round a few ulp away from the plain one).
_WINDOW_PAD_RAD = 1e-9


def multipath_ghosts(
    range_m: np.ndarray,
    azimuth: np.ndarray,
    doppler: np.ndarray,
    snr: np.ndarray,
    settings: MultipathConfig,
) -> np.ndarray:
    """(n,) bool, True for returns explained as a k-bounce copy of another return.

    All inputs are per return, measured from the radar: range (m), azimuth (rad), raw Doppler as the radar reports it
    (m/s, not ego-compensated: the k-fold relation holds for the raw value), SNR (dB; NaN skips the "weaker" test).
    """
    r = np.asarray(range_m, float)
    n = r.size
    ghost = np.zeros(n, bool)
    if n < 2 or not settings.range_orders:
        return ghost
    az = np.asarray(azimuth, float)
    dop = np.asarray(doppler, float)
    snr = np.asarray(snr, float)
    # Only pairs on nearby bearings can match: ~1/6 of all pairs for a 120 deg sector and +-10 deg, so the tests
    # run on those instead of on the full n x n matrix (the same tests, the same verdicts).
    j, i = _bearing_pairs(az, settings.search_angle_rad + _WINDOW_PAD_RAD)  # ghost candidate j, original i
    d_az = (az[j] - az[i] + np.pi) % (2.0 * np.pi) - np.pi
    # NaN SNR on either side compares False: the "weaker" test passes
    cand = (np.abs(d_az) <= settings.search_angle_rad) & ~(snr[j] > snr[i] - settings.min_snr_drop_db)
    j, i = j[cand], i[cand]
    hit = np.zeros(j.size, bool)
    for k in settings.range_orders:
        expect = k * r[i]
        ok = np.abs(r[j] - expect) <= settings.range_tolerance_m + settings.range_tolerance_rel * expect
        if settings.doppler_tolerance_mps >= 0:
            dd = np.abs(dop[j] - k * dop[i])
            ok &= ~(dd > settings.doppler_tolerance_mps)  # NaN Doppler: cannot contradict
        hit |= ok
    ghost[j[hit]] = True
    return ghost


def _bearing_pairs(az: np.ndarray, half_width: float) -> tuple[np.ndarray, np.ndarray]:
    """(rows, cols): every ordered pair of different returns whose bearings lie within ``half_width`` of each other
    (wrapping at +-pi), found by sorting the bearings; non-finite bearings pair with nothing."""
    ok = np.flatnonzero(np.isfinite(az))
    if half_width >= math.pi:  # every bearing is near every other
        rows, cols = np.meshgrid(ok, ok, indexing="ij")
        rows, cols = rows.ravel(), cols.ravel()
        return rows[rows != cols], cols[rows != cols]
    wrapped = (az[ok] + math.pi) % (2.0 * math.pi) - math.pi
    order = np.argsort(wrapped, kind="stable")
    s = wrapped[order]
    # Three turns side by side: a window of width < 2 pi then holds at most one copy of each return.
    ring = np.concatenate([s - 2.0 * math.pi, s, s + 2.0 * math.pi])
    owner = np.tile(ok[order], 3)
    lo = np.searchsorted(ring, wrapped - half_width, side="left")
    hi = np.searchsorted(ring, wrapped + half_width, side="right")
    count = hi - lo
    total = int(count.sum())
    first = np.cumsum(count) - count
    rows = np.repeat(ok, count)
    cols = owner[np.repeat(lo - first, count) + np.arange(total)]
    return rows[rows != cols], cols[rows != cols]
