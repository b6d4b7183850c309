"""Multipath ghosts: returns that mirror a real target further out along the same bearing (paper 001, sec. 3.2).

A wave that bounces target -> own hull (or radome) -> target -> radar travels k times the direct path, so the radar
reports a copy of the target at k times its range, on nearly the same bearing, with k times its raw Doppler (the
path length changes k times as fast) and a weaker echo. A return is called a ghost when some other return on a
bearing within the search angle explains it that way, and it is weaker by at least ``min_snr_drop_db``. With the
own boat and the target both at rest the Doppler test cannot tell; the SNR drop then keeps a real, larger boat at
twice the range of a small one (tested on the simulated paper scene, where it had been removed for minutes).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

_CHUNK = 256  # ghost candidates per block: bounds the pairwise matrices to CHUNK x n


@dataclass(frozen=True)
class MultipathSettings:
    search_angle: float  # rad, half-width of the bearing window
    orders: tuple[int, ...]  # path multiples to look for (2 = one extra round trip)
    range_tolerance_m: float
    range_tolerance_rel: float  # of the expected ghost range
    doppler_tolerance: float  # m/s; < 0 skips the Doppler test
    min_snr_drop_db: float = 0.0  # a ghost is at least this much weaker than the return it copies


def multipath_ghosts(
    range_m: np.ndarray,
    azimuth: np.ndarray,
    doppler: np.ndarray,
    snr: np.ndarray,
    settings: MultipathSettings,
) -> np.ndarray:
    """(n,) bool, True for returns explained as a k-bounce copy of another return.

    All inputs are per return, measured from the radar: range (m), azimuth (rad), raw Doppler as the radar reports it
    (m/s, not ego-compensated: the k-fold relation holds for the raw value), SNR (dB; NaN skips the "weaker" test).
    """
    r = np.asarray(range_m, float)
    n = r.size
    ghost = np.zeros(n, bool)
    if n < 2 or not settings.orders:
        return ghost
    az = np.asarray(azimuth, float)
    dop = np.asarray(doppler, float)
    snr = np.asarray(snr, float)
    for start in range(0, n, _CHUNK):
        j = slice(start, min(start + _CHUNK, n))  # ghost candidates (rows) against every return (columns)
        d_az = (az[j, None] - az[None, :] + np.pi) % (2.0 * np.pi) - np.pi
        near = np.abs(d_az) <= settings.search_angle
        # NaN on either side compares False: the test passes
        weaker = ~(snr[j, None] > snr[None, :] - settings.min_snr_drop_db)
        cand = near & weaker
        rows = np.arange(j.stop - j.start)
        cand[rows, rows + start] = False  # a return is no copy of itself
        if not cand.any():
            continue
        hit = np.zeros(cand.shape, bool)
        for k in settings.orders:
            expect = k * r[None, :]
            ok = np.abs(r[j, None] - expect) <= settings.range_tolerance_m + settings.range_tolerance_rel * expect
            if settings.doppler_tolerance >= 0:
                dd = np.abs(dop[j, None] - k * dop[None, :])
                ok &= ~(dd > settings.doppler_tolerance)  # NaN Doppler: cannot contradict
            hit |= ok
        ghost[j] = np.any(cand & hit, axis=1)
    return ghost
