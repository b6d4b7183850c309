"""The demo's bird's-eye picture: the scene's truth, what the sensors returned, and the 72 bins the autopilot got."""

from __future__ import annotations

import math
from pathlib import Path
from typing import Any

import numpy as np

from simulator.scene import Scene
from simulator.truth import truth_at
from tracker.ego import world_to_body_2d
from tracker.obstacle_map import N_BINS
from tracker.types import ShapeKind, Track


def save_demo_picture(path: Path, scene: Scene, t_sim: float, output: Any, distances_cm: Any) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    truth = truth_at(scene, t_sim)
    own = truth.own
    fig, ax = plt.subplots(figsize=(9, 9), dpi=110)
    # Plot in the body frame with the bow up: screen x = starboard, screen y = forward.
    for v in truth.vessels:
        # the hull's whole outline (a curved hull's half-rounds; the truth's footprint is a pentagon on the curve)
        hull = scene.vessels[v.id].hull_polygon_body()
        c, s = math.cos(v.heading), math.sin(v.heading)
        world = v.position[:2] + np.column_stack([c * hull[:, 0] - s * hull[:, 1], s * hull[:, 0] + c * hull[:, 1]])
        poly = world_to_body_2d(world, own.position[:2], own.yaw)
        closed = np.vstack([poly, poly[:1]])
        ax.fill(closed[:, 1], closed[:, 0], color="tab:blue", alpha=0.25)
        ax.plot(closed[:, 1], closed[:, 0], color="tab:blue", lw=1)
        c = poly.mean(axis=0)
        ax.annotate(v.name, (c[1], c[0]), fontsize=7, color="tab:blue")
    starts, ends = scene.quay_wall_segments()
    for a, b in zip(starts, ends, strict=True):
        seg_b = world_to_body_2d(np.array([a, b]), own.position[:2], own.yaw)
        ax.plot(seg_b[:, 1], seg_b[:, 0], color="saddlebrown", lw=3, alpha=0.6)
    if output is not None and output.solid_points_body is not None and len(output.solid_points_body):
        p = output.solid_points_body
        ax.scatter(p[:, 1], p[:, 0], s=0.5, color="k", alpha=0.6, label="solid returns (LiDAR + radar)")
    if output is not None:
        for tr in output.tracks:
            if not tr.confirmed:
                continue
            poly = world_to_body_2d(_outline(tr), own.position[:2], own.yaw)
            closed = np.vstack([poly, poly[:1]])
            ax.plot(closed[:, 1], closed[:, 0], color="tab:orange", lw=1.2, ls="--")
            ax.annotate(f"#{tr.id}", (poly[:, 1].max(), poly[:, 0].max()), fontsize=6, color="tab:orange")
    if distances_cm is not None:
        d = np.asarray(distances_cm, dtype=float)
        for j in range(N_BINS):
            b = math.radians(5 * j)
            if d[j] == 65535:
                continue
            r = min(d[j], 10001) / 100.0
            color = "tab:red" if d[j] <= 10000 else "tab:green"
            ax.plot([0, r * math.sin(b)], [0, r * math.cos(b)], color=color, lw=0.6, alpha=0.5)
    ax.plot([0], [0], marker="^", color="tab:orange", ms=10, label="own boat (bow up)")
    ax.set_aspect("equal")
    ax.set_xlim(-60, 60)
    ax.set_ylim(-60, 60)
    ax.set_xlabel("starboard (m)")
    ax.set_ylabel("forward (m)")
    ax.set_title(
        f"usv-tracker demo, t = {t_sim:.1f} s: truth (blue), tracks (orange), returns (black), "
        "bins obstacle red / clear green"
    )
    ax.legend(loc="lower left", fontsize=8)
    ax.grid(alpha=0.3)
    fig.tight_layout()
    fig.savefig(path)
    plt.close(fig)


def _outline(track: Track) -> np.ndarray:
    """(K, 2) world north/east outline of a track as it was fitted: its box, or its ellipse (a round hull, a buoy)."""
    if track.shape is not ShapeKind.ELLIPSE:
        return track.footprint()
    a = np.linspace(0.0, 2.0 * np.pi, 36, endpoint=False)
    along, across = 0.5 * track.length * np.cos(a), 0.5 * track.width * np.sin(a)
    c, s = math.cos(track.heading), math.sin(track.heading)
    return track.position + np.column_stack([c * along - s * across, s * along + c * across])
