"""Seas without solids, in exact VLP-16 geometry: does the LiDAR path turn any of them into an obstacle or a track?

    python bench/sea_probe.py          # 160 seas x 10 revolutions, both cores, about 2 minutes

The simulator draws its sea one way (wave trains, water returns rising with the square of the grazing angle); a rule
tuned on its scenes can lean on that model. This probe builds each revolution with the tests' geometry instead
(tests/sea_geometry.py: the 16 lasers fired every 0.2 deg from a boat with a given attitude, meeting a wave surface
that stands still, a random share of the firings returning) and runs it through the pipeline as `usv-tracker run`
builds it, LiDAR only. Seas: heeled steadily (roll 5 deg with pitch 3 deg, or roll 8 deg) or rolling (5 / 3 deg
over 4 / 3 s, or 8 deg over 3 s); the tests' chop with crests +-0.3 m (the simulator's sea state 3) or 1.5 times
that; 5, 10, 30, 60 or 90 % of the firings meeting the water returning; heading 0.3 or 1.2 rad; heave 0 or 0.2 m.
Ten revolutions each. There is nothing but water: any bin reported nearer than max_distance, and any track, is
false. Saves bench/results/sea_probe.md and .json.
"""

from __future__ import annotations

import itertools
import math
import multiprocessing as mp
import sys
import time
from collections.abc import Callable
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent.parent))

from bench._common import no_options, save
from drivers.mount import Mount
from tests.sea_geometry import SteadyEgo, chop, lidar_pipeline, revolution_over_water, scan_of

MOUNT = Mount(z=-1.6)  # the VLP-16 1.6 m above the water
REVOLUTIONS = 10
ATTITUDES = ("heeled 5/3 deg", "heeled 8 deg", "rolling 5/3 deg", "rolling 8 deg")
CRESTS = (1.0, 1.5)  # x the tests' chop, crests +-0.3 m
SHARES = (0.05, 0.1, 0.3, 0.6, 0.9)
HEADINGS = (0.3, 1.2)
HEAVES = (0.0, 0.2)


Attitude = Callable[[np.ndarray], tuple[np.ndarray, np.ndarray]]


def heeled(roll_deg: float, pitch_deg: float) -> Attitude:
    return lambda t: (np.full(np.shape(t), math.radians(roll_deg)), np.full(np.shape(t), math.radians(pitch_deg)))


def attitude(kind: str) -> Attitude:
    if kind == "heeled 5/3 deg":
        return heeled(5.0, 3.0)
    if kind == "heeled 8 deg":
        return heeled(8.0, 0.0)
    if kind == "rolling 5/3 deg":
        return lambda t: (
            math.radians(5.0) * np.sin(2 * math.pi * np.asarray(t) / 4.0 + 0.3),
            math.radians(3.0) * np.sin(2 * math.pi * np.asarray(t) / 3.0 + 1.0),
        )
    return lambda t: (math.radians(8.0) * np.sin(2 * math.pi * np.asarray(t) / 3.0), np.zeros(np.shape(t)))


def one_sea(args: tuple[int, tuple[str, float, float, float, float]]) -> dict[str, object]:
    index, (kind, crest, share, heading, heave) = args
    att = attitude(kind)
    pipeline = lidar_pipeline(MOUNT)
    ego = SteadyEgo(att, heading)
    false_bins, tracks, confirmed, first = 0, 0, 0, None
    for k in range(REVOLUTIONS):
        ret = revolution_over_water(
            MOUNT,
            att,
            yaw=heading,
            origin_height=heave,
            elevation=lambda n, e, c=crest: c * chop(n, e),
            t0=0.1 * k,
            water_share=(share, 1000 * index + k),
        )
        out = pipeline.step(0.1 * k + 0.1, scan_of(ret, 0.1 * k + 0.1), [], ego)
        bins = np.flatnonzero(out.distances_cm <= 10000)
        false_bins += bins.size
        tracks = max(tracks, len(out.tracks))
        confirmed = max(confirmed, sum(1 for tr in out.tracks if tr.confirmed))
        if bins.size and first is None:
            first = f"revolution {k}: bins {bins.tolist()} at {(out.distances_cm[bins] / 100).round(1).tolist()} m"
    return {
        "attitude": kind,
        "crest_m": round(0.3 * crest, 2),
        "share": share,
        "heading_rad": heading,
        "heave_m": heave,
        "false_bin_revolutions": false_bins,
        "most_tracks": tracks,
        "most_confirmed_tracks": confirmed,
        "first": first,
    }


def main() -> None:
    no_options(__doc__)
    seas = list(itertools.product(ATTITUDES, CRESTS, SHARES, HEADINGS, HEAVES))
    t0 = time.monotonic()
    with mp.get_context("fork").Pool(2) as pool:
        rows = pool.map(one_sea, list(enumerate(seas)), chunksize=1)
    wall = time.monotonic() - t0
    bad = [r for r in rows if r["false_bin_revolutions"] or r["most_tracks"]]
    lines = [
        "`python bench/sea_probe.py`: seas without solids in exact VLP-16 geometry (tests/sea_geometry.py), "
        f"{len(seas)} seas x {REVOLUTIONS} revolutions through the LiDAR path ({wall:.0f} s, 2 cores).",
        "",
        f"Seas with any false obstacle bin or track: **{len(bad)} of {len(seas)}**; false bin-revolutions in all: "
        f"{sum(int(r['false_bin_revolutions']) for r in rows)} of {len(seas) * REVOLUTIONS * 72}.",
        "",
        "| attitude | crests (m) | firings returning | heading (rad) | heave (m) | false bin-revolutions | "
        "tracks (confirmed) | first |",
        "|---|---|---|---|---|---|---|---|",
    ]
    lines += [
        f"| {r['attitude']} | {r['crest_m']} | {r['share']:.0%} | {r['heading_rad']} | {r['heave_m']} | "
        f"{r['false_bin_revolutions']} | {r['most_tracks']} ({r['most_confirmed_tracks']}) | {r['first'] or ''} |"
        for r in bad
    ]
    print("\n".join(lines))
    save("sea_probe", {"seas": rows, "bad": len(bad), "wall_s": wall}, "\n".join(lines))


if __name__ == "__main__":
    main()
