"""What far returns cost the LiDAR clustering near the boat.

    python bench/clustering.py        # about half a minute

The clustering's neighbour search (tracker.lidar.clustering) pools returns into link cells and looks for pairs of
them within the tolerance, which grows with range from 0.5 m at the boat to 3 m beyond 71 m. Four loads, each a
world-frame point set as `cluster_points` gets it: the own deck and spray (20,000 returns over 6 x 5 m, 1-7 m off,
plus 2,000 drops within 12 m), the same with one return at 95 m, with a 60 m quay wall at 95 m (600 returns at
three heights), and with 20 hulls at 10-90 m. Printed per load: candidate pairs of link cells, and the time of
`cluster_points` (median of 100 calls, the four loads called in turn so that a slow phase of the shared machine
slows all four; one core), with its ratio to the deck alone. Goal (issue 12): one far return changes the near
clustering's cost by no more than 10 %.
"""

from __future__ import annotations

import os
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent.parent))

from bench._common import no_options, save
from tracker.lidar.clustering import candidate_pairs, cluster_points, grid_cells, pool_link_cells
from tracker.lidar.config import ClusterConfig

ROUNDS = 100
OWN = np.zeros(2)


def deck_and_spray(rng: np.random.Generator) -> np.ndarray:
    deck = np.column_stack([rng.uniform(1.0, 7.0, 20000), rng.uniform(-2.5, 2.5, 20000), rng.uniform(-1, 0, 20000)])
    r, az = rng.uniform(1.0, 12.0, 2000), rng.uniform(-np.pi, np.pi, 2000)
    spray = np.column_stack([r * np.cos(az), r * np.sin(az), rng.uniform(-0.5, 0.5, 2000)])
    return np.vstack([deck, spray])


def wall(rng: np.random.Generator) -> np.ndarray:
    east = rng.uniform(-30.0, 30.0, 600)
    return np.column_stack([np.full(600, 95.0), east, rng.choice([-0.2, -0.8, -1.4], 600)])


def hulls(rng: np.random.Generator) -> np.ndarray:
    out = []
    for _ in range(20):
        r, az = rng.uniform(10.0, 90.0), rng.uniform(-np.pi, np.pi)
        side = np.linspace(-4.0, 4.0, 40)
        centre = r * np.array([np.cos(az), np.sin(az)])
        along = np.array([-np.sin(az), np.cos(az)])
        xy = centre + side[:, None] * along
        out.append(np.column_stack([np.repeat(xy, 4, axis=0), np.tile([-0.2, -0.6, -1.0, -1.4], 40)]))
    return np.vstack(out)


def pairs_of(points: np.ndarray, cfg: ClusterConfig) -> int:
    """Candidate pairs of link cells, pooled as cluster_points pools them."""
    _, _, counts, cells = grid_cells(points[:, 0], points[:, 1], cfg.grid_cell)
    a, _ = candidate_pairs(pool_link_cells(cells, counts.astype(float), OWN, cfg), cfg)
    return int(a.size)


def times_ms(loads: list[np.ndarray], cfg: ClusterConfig) -> list[float]:
    """Median time of cluster_points per load, the loads called in turn (round robin), so that a slow phase of a
    shared machine slows them all alike."""
    ts: list[list[float]] = [[] for _ in loads]
    for _ in range(ROUNDS):
        for k, points in enumerate(loads):
            t0 = time.perf_counter()
            cluster_points(points, OWN, cfg)
            ts[k].append(time.perf_counter() - t0)
    return [float(np.median(t)) * 1e3 for t in ts]


def main() -> None:
    no_options(__doc__)
    if hasattr(os, "sched_setaffinity"):
        os.sched_setaffinity(0, {sorted(os.sched_getaffinity(0))[0]})
    rng = np.random.default_rng(0)
    cfg = ClusterConfig()
    base = deck_and_spray(rng)
    loads = {
        "deck and spray": base,
        "+ one return at 95 m": np.vstack([base, [[95.0, 0.0, -1.0]]]),
        "+ a 60 m wall at 95 m": np.vstack([base, wall(rng)]),
        "+ 20 hulls at 10-90 m": np.vstack([base, hulls(rng)]),
    }
    times = times_ms(list(loads.values()), cfg)
    rows = []
    for (name, points), ms in zip(loads.items(), times, strict=True):
        rows.append((name, len(points), pairs_of(points, cfg), ms))
        print(f"{name}: {rows[-1][1]:,} returns, {rows[-1][2]:,} candidate pairs, {ms:.2f} ms", flush=True)
    ref = rows[0][3]
    lines = [
        "`python bench/clustering.py`: `cluster_points` on the own deck and spray, with far returns added; one core, "
        f"median of {ROUNDS} calls, the loads called in turn.",
        "",
        "| load | returns | candidate pairs | time | against the deck alone |",
        "|---|---|---|---|---|",
    ]
    lines += [f"| {n} | {p:,} | {c:,} | {t:.2f} ms | {t / ref - 1:+.1%} |" for n, p, c, t in rows]
    one_far = rows[1][3] / ref - 1
    lines += ["", f"One far return: {one_far:+.1%} (goal: within 10 %)."]
    print(lines[-1])
    save(
        "clustering",
        {"loads": [{"load": n, "returns": p, "pairs": c, "ms": t} for n, p, c, t in rows], "one_far_change": one_far},
        "\n".join(lines),
    )


if __name__ == "__main__":
    main()
