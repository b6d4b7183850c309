"""Paper 000 (adaptive shape fitting for maritime LiDAR tracking) reproduced on the project's simulator.

    python bench/lidar_paper.py        # about a minute; writes bench/results/lidar_paper.{md,json} and PNGs

Everything goes the daemon's way (bench/lidar_sim.py): the simulator's noisy packets are encoded as real VLP-16
packets, decoded by the driver's ScanAssembler, put in the world with the own boat's pose at each point's time and
preprocessed. The ground truth only picks which cluster / track to score and scores it; the tracker never sees it.
Seeds are fixed, so the numbers repeat (timings aside).

1. Table 1: the container (8.6 x 3.6 m) and crew boat (43 x 10.4 m) scenes, every revolution: each shape fit of the
   paper on the target's cluster, then ours (the tracker's detection step, and the tracker's output), against the
   true footprint: IoU, centre error, heading error (modulo 180 deg: a shape has no bow), relative length and width
   error, the fit's MSE and the runtime per cluster (median; each fitter timed alone over all clusters).
2. Figure 4: the fisher boat tracked over its drive: position, speed, heading (full circle) and size (area) error
   histograms, adaptive vs L-shape only, both with the paper's tracker and with ours.
3. The goals set for this project, met or not, and the LiDAR pipeline's cost on a revolution with 20 vessels.
"""

from __future__ import annotations

import contextlib
import math
import os
import sys
import time
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent.parent))

from bench._common import RESULTS, no_options, save
from bench.lidar_sim import Frame, iou, points_in_convex, shape_polygon, simulate
from simulator.scenarios import get_scenario
from simulator.scene import Scene
from simulator.truth import VesselTruth, truth_at
from tracker.lidar import LidarTracker, LidarTrackerConfig
from tracker.lidar.clustering import ClusterResult, cluster_points
from tracker.lidar.config import ShapeConfig
from tracker.lidar.ekf import faces_seen
from tracker.lidar.preprocess import preprocess
from tracker.lidar.shape_fit import ShapeFit, fit_shape
from tracker.types import ShapeKind, Track

SEED = 1
METHODS = ["ellipse", "lshape-bruteforce", "lshape-rotation", "lshape-corner", "adaptive"]
METHOD_NAMES = {
    "ellipse": "Ellipse fitting",
    "lshape-bruteforce": "Brute force",
    "lshape-rotation": "Rotation",
    "lshape-corner": "Corner point",
    "adaptive": "Adaptive (Alg. 4)",
}
# Table 1 of the paper: IoU %, position m, heading deg, length %, width %, MSE (printed in m), runtime ms.
PAPER_TABLE1: dict[tuple[str, str], tuple[float, float, float, float, float, float, float]] = {
    ("container", "ellipse"): (20, 2.0, 10, 204, 354, 0.05, 0.465),
    ("container", "lshape-bruteforce"): (27, 1.6, 9, 163, 52.8, 0.025, 0.882),
    ("container", "lshape-rotation"): (39, 1.6, 15, 58, 22, 0.022, 2.36),
    ("container", "lshape-corner"): (35, 1.5, 7, 7, 33, 0.021, 0.065),
    ("crew_boat", "ellipse"): (61, 2.1, 1.8, 6, 27, 0.02, 0.918),
    ("crew_boat", "lshape-bruteforce"): (53, 2.4, 2.1, 13.5, 35.6, 0.045, 4.722),
    ("crew_boat", "lshape-rotation"): (53, 2.4, 19.1, 13, 60, 0.053, 8.612),
    ("crew_boat", "lshape-corner"): (54, 2.7, 7, 102, 27.8, 0.043, 0.284),
}
DENSE_WINDOW = (10.0, 20.0)  # s of the "dense" scene: all 20 boats within ~60 m


def paper_tracker_config(mode: str = "adaptive") -> LidarTrackerConfig:
    """The tracker as the paper describes it: our additions (view-aware update, heading guard, sweep
    compensation) switched off."""
    cfg = LidarTrackerConfig()
    cfg.shape.mode = mode  # type: ignore[assignment]
    cfg.shape.heading_guard = False
    cfg.ekf.view_aware = False
    cfg.ekf.compensate_sweep = False
    return cfg


def our_tracker_config(mode: str = "adaptive") -> LidarTrackerConfig:
    cfg = LidarTrackerConfig()
    cfg.shape.mode = mode  # type: ignore[assignment]
    return cfg


# ---------------------------------------------------------------------------------------------------------------------
# Scoring


def heading_error(estimate: float, truth: float, period: float) -> float:
    """Absolute heading difference in degrees, modulo ``period`` (pi for shapes, 2 pi for tracks)."""
    d = (estimate - truth + 0.5 * period) % period - 0.5 * period
    return abs(math.degrees(d))


@dataclass
class Score:
    iou: float  # 0..1
    position: float  # m
    heading: float  # deg
    length: float  # relative, 0..
    width: float
    mse: float = math.nan  # m^2 (fits only)
    speed: float = math.nan  # m/s (tracks only)
    area: float = math.nan  # relative size (length x width) error, signed


def score_shape(
    center: np.ndarray, heading: float, length: float, width: float, ellipse: bool, truth: VesselTruth, period: float
) -> Score:
    poly = shape_polygon(center, heading, length, width, ellipse)
    return Score(
        iou=iou(poly, truth.footprint),
        position=float(np.hypot(*(center - truth.position))),
        heading=heading_error(heading, truth.heading, period),
        length=abs(length - truth.length) / truth.length,
        width=abs(width - truth.width) / truth.width,
        area=length * width / (truth.length * truth.width) - 1.0,
    )


def score_fit(fit: ShapeFit, truth: VesselTruth) -> Score:
    s = score_shape(fit.center, fit.heading, fit.length, fit.width, fit.kind is ShapeKind.ELLIPSE, truth, math.pi)
    s.mse = fit.mse
    return s


def score_track(track: Track, truth: VesselTruth, period: float) -> Score:
    s = score_shape(
        track.position, track.heading, track.length, track.width, track.shape is ShapeKind.ELLIPSE, truth, period
    )
    if np.all(np.isfinite(track.velocity)):
        s.speed = abs(float(np.hypot(*track.velocity)) - truth.speed)
    return s


def mean_row(scores: list[Score]) -> dict[str, float]:
    if not scores:
        return {k: math.nan for k in ("iou", "position", "heading", "length", "width", "mse", "speed", "area", "n")}
    a = {k: np.array([getattr(s, k) for s in scores], dtype=float) for k in Score.__dataclass_fields__}
    out = {k: float(np.nanmean(v)) if np.isfinite(v).any() else math.nan for k, v in a.items()}
    out["position_median"] = float(np.median(a["position"]))
    out["heading_median"] = float(np.median(a["heading"]))
    out["n"] = float(len(scores))
    return out


# ---------------------------------------------------------------------------------------------------------------------
# Table 1: shape fits per revolution


@dataclass
class Sample:
    """The target's cluster in one revolution, and the truth when the sensor swept it."""

    frame: Frame
    footprint: np.ndarray  # (m, 2) the cluster's footprint as the tracker fits it
    truth: VesselTruth
    two_sided: bool  # the true hull shows a side and an end to the sensor (evaluation only)


def target_samples(scene: Scene, frames: list[Frame]) -> list[Sample]:
    """Per revolution, the cluster holding most returns inside the true hull (grown by 1 m); truth at its sweep."""
    cfg = LidarTrackerConfig().cluster
    out = []
    for f in frames:
        result: ClusterResult = cluster_points(f.points_world, f.own_position, cfg)
        if not result.clusters:
            continue
        truth = truth_at(scene, f.stamp).vessels[0]
        grown = grown_polygon(truth.footprint, 1.0)
        hits = [int(np.count_nonzero(points_in_convex(c[:, :2], grown))) for c in result.clusters]
        k = int(np.argmax(hits))
        if hits[k] == 0:
            continue
        swept = float(np.mean(f.point_t[result.labels == k]))
        truth = truth_at(scene, swept).vessels[0]
        seen = faces_seen(truth.position, truth.heading, truth.length, truth.width, f.own_position, 0.01)
        out.append(Sample(f, result.footprints[k], truth, seen[0] and seen[1]))
    return out


def grown_polygon(poly: np.ndarray, margin: float) -> np.ndarray:
    centre = poly.mean(axis=0)
    d = poly - centre
    r = np.hypot(d[:, 0], d[:, 1])[:, None]
    return centre + d * (r + margin) / np.maximum(r, 1e-9)


def time_per_cluster(fn: Callable[[np.ndarray, np.ndarray], Any], samples: list[Sample], passes: int = 3) -> float:
    """Median seconds per call over all clusters, best of ``passes`` (other processes share the machine)."""
    best = math.inf
    for _ in range(passes):
        ts = np.empty(len(samples))
        for i, s in enumerate(samples):
            t0 = time.perf_counter()
            fn(s.footprint, s.frame.own_position)
            ts[i] = time.perf_counter() - t0
        best = min(best, float(np.median(ts)))
    return best


def run_tracker(
    scene: Scene, frames: list[Frame], config: LidarTrackerConfig, with_times: bool, period: float
) -> tuple[list[Score | None], list[float]]:
    """Track a one-vessel scene; per revolution the score of the confirmed track nearest the truth (None: none)."""
    tracker = LidarTracker(config)
    scores: list[Score | None] = []
    step_ms = []
    for f in frames:
        t0 = time.perf_counter()
        tracks = tracker.step(
            f.points_world, f.stamp, f.own_position, f.own_yaw, point_times=f.point_t if with_times else None
        )
        step_ms.append((time.perf_counter() - t0) * 1e3)
        truth = truth_at(scene, f.stamp).vessels[0]
        confirmed = [t for t in tracks if t.confirmed]
        if not confirmed:
            scores.append(None)
            continue
        best = min(confirmed, key=lambda t: float(np.hypot(*(t.position - truth.position))))
        scores.append(score_track(best, truth, period))
    return scores, step_ms


def table1(name: str, frames: list[Frame]) -> dict[str, Any]:
    scene = get_scenario(name, seed=SEED)
    samples = target_samples(scene, frames)
    rows: dict[str, dict[str, float]] = {}
    for mode in METHODS:
        cfg = ShapeConfig(mode=mode)  # type: ignore[arg-type]
        rows[mode] = mean_row([score_fit(fit_shape(s.footprint, cfg, s.frame.own_position), s.truth) for s in samples])
        rows[mode]["ms"] = 1e3 * time_per_cluster(lambda p, own, c=cfg: fit_shape(p, c, own), samples)
        kinds = [fit_shape(s.footprint, cfg, s.frame.own_position).kind for s in samples]
        rows[mode]["ellipse_share"] = float(np.mean([k is ShapeKind.ELLIPSE for k in kinds]))
    # Ours, one scan: the tracker's detection step (adaptive fit, heading guard).
    ours = LidarTracker(our_tracker_config())
    fits = [ours.fit_footprint(s.footprint, s.frame.own_position) for s in samples]
    rows["ours-scan"] = mean_row([score_fit(f, s.truth) for f, s in zip(fits, samples, strict=True)])
    rows["ours-scan"]["ms"] = 1e3 * time_per_cluster(ours.fit_footprint, samples)
    # Tracked: the track's box each revolution (the tracker keeps what earlier views showed).
    frame_index = {id(f): i for i, f in enumerate(frames)}
    two_sided = np.array([s.two_sided for s in samples])
    for key, cfg, times in (
        ("paper-track", paper_tracker_config(), False),
        ("ours-track", our_tracker_config(), True),
    ):
        scores, _ = run_tracker(scene, frames, cfg, times, math.pi)
        by_sample = [scores[frame_index[id(s.frame)]] for s in samples]
        got = [sc for sc in by_sample if sc is not None]
        rows[key] = mean_row(got)
        rows[key]["coverage"] = len(got) / max(len(samples), 1)
        steady = [sc for sc, two in zip(by_sample, np.maximum.accumulate(two_sided), strict=True) if sc and two]
        rows[key + "-after-two-sides"] = mean_row(steady)
    first_two = next((s.frame.stamp for s in samples if s.two_sided), math.nan)
    return {"rows": rows, "n_revolutions": len(frames), "n_samples": len(samples), "first_two_sided_t": first_two}


# ---------------------------------------------------------------------------------------------------------------------
# Figure 4: the fisher boat tracked


def figure4(frames: list[Frame]) -> dict[str, Any]:
    scene = get_scenario("fisher", seed=SEED)
    out: dict[str, Any] = {}
    for key, cfg, times in (
        ("paper adaptive", paper_tracker_config("adaptive"), False),
        ("paper L-shape (corner)", paper_tracker_config("lshape-corner"), False),
        ("paper L-shape (brute force)", paper_tracker_config("lshape-bruteforce"), False),
        ("ours adaptive", our_tracker_config("adaptive"), True),
        ("ours L-shape (corner)", our_tracker_config("lshape-corner"), True),
        ("ours L-shape (brute force)", our_tracker_config("lshape-bruteforce"), True),
    ):
        scores, step_ms = run_tracker(scene, frames, cfg, times, 2.0 * math.pi)
        got = [s for s in scores if s is not None]
        pos = np.array([s.position for s in got])
        out[key] = {
            "position": pos,
            "speed": np.array([s.speed for s in got if math.isfinite(s.speed)]),
            "heading": np.array([s.heading for s in got]),
            "area": np.array([s.area for s in got]),
            "length": np.array([s.length for s in got]),
            "width": np.array([s.width for s in got]),
            "coverage": len(got) / max(len(scores), 1),
            "step_ms": float(np.median(step_ms)),
        }
    return out


def fig4_summary(data: dict[str, Any]) -> dict[str, dict[str, float]]:
    rows = {}
    for key, d in data.items():
        pos = d["position"]
        rows[key] = {
            "pos_mean": float(pos.mean()),
            "pos_p95": float(np.percentile(pos, 95)),
            "within_1m": float(np.mean(pos <= 1.0)),
            "within_2m": float(np.mean(pos <= 2.0)),
            "speed_mean": float(d["speed"].mean()) if d["speed"].size else math.nan,
            "heading_mean": float(d["heading"].mean()),
            "heading_p95": float(np.percentile(d["heading"], 95)),
            "area_mean": float(np.mean(np.abs(d["area"]))),
            "area_signed": float(np.mean(d["area"])),
            "length_mean": float(d["length"].mean()),
            "width_mean": float(d["width"].mean()),
            "coverage": d["coverage"],
        }
    return rows


def plot_figure4(data: dict[str, Any], path: Path) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    panels = [
        ("position", "2-D position error (m)", np.linspace(0.0, 2.0, 41)),
        ("speed", "speed error (m/s)", np.linspace(0.0, 1.0, 41)),
        ("heading", "heading error (deg)", np.linspace(0.0, 10.0, 41)),
        ("area", "size error (length x width, relative)", np.linspace(-0.8, 0.4, 49)),
    ]
    fig, axes = plt.subplots(2, 4, figsize=(17, 7.5))
    for row, prefix in enumerate(("paper", "ours")):
        for col, (key, label, bins) in enumerate(panels):
            ax = axes[row, col]
            for name, colour in ((f"{prefix} adaptive", "tab:blue"), (f"{prefix} L-shape (corner)", "tab:green")):
                v = np.clip(data[name][key], bins[0], bins[-1])
                w = np.full(v.size, 1.0 / max(v.size, 1))
                ax.hist(v, bins=bins, weights=w, alpha=0.55, color=colour, label=name)
            ax.set_xlabel(label)
            if col == 0:
                ax.set_ylabel(f"{prefix} tracker: share of revolutions")
            ax.legend(fontsize=7)
    fig.suptitle("Fisher boat (12 x 4 m) circling at 25 m, 3 m/s: tracking errors per revolution (cf. paper Fig. 4)")
    fig.tight_layout()
    fig.savefig(path, dpi=80)
    plt.close(fig)


def plot_examples(examples: dict[str, tuple[Sample, dict[str, ShapeFit]]], path: Path) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(1, len(examples), figsize=(8 * len(examples), 6))
    colours = {"lshape-corner": "tab:red", "lshape-rotation": "tab:green", "ellipse": "tab:purple", "ours": "tab:blue"}
    for ax, (name, (sample, fits)) in zip(np.atleast_1d(axes), examples.items(), strict=True):
        fp = sample.footprint
        ax.plot(fp[:, 1], fp[:, 0], "k.", ms=3, label="footprint (returns)")
        truth = np.vstack([sample.truth.footprint, sample.truth.footprint[:1]])
        ax.plot(truth[:, 1], truth[:, 0], "k-", lw=2, label="true hull")
        for key, fit in fits.items():
            poly = shape_polygon(fit.center, fit.heading, fit.length, fit.width, fit.kind is ShapeKind.ELLIPSE)
            poly = np.vstack([poly, poly[:1]])
            ax.plot(poly[:, 1], poly[:, 0], color=colours[key], lw=1.5, label=key)
        ax.set_aspect("equal")
        ax.set_xlabel("east (m)")
        ax.set_ylabel("north (m)")
        ax.set_title(f"{name}, t = {sample.frame.stamp:.1f} s (sensor at {np.round(sample.frame.own_position, 1)})")
        ax.legend(fontsize=7)
    fig.tight_layout()
    fig.savefig(path, dpi=80)
    plt.close(fig)


# ---------------------------------------------------------------------------------------------------------------------
# Throughput: a full revolution with 20 vessels


def dense_runtime() -> dict[str, float]:
    """preprocess + step per revolution of the "dense" scene, on one core: CPU time and wall time."""
    scene = get_scenario("dense", seed=SEED)
    raw = simulate_raw(scene, *DENSE_WINDOW)
    with contextlib.suppress(AttributeError, OSError):  # one core, as the goal says (Linux only)
        os.sched_setaffinity(0, {min(os.sched_getaffinity(0))})
    cpu: list[float] = []
    wall: list[float] = []
    clusters: list[int] = []
    confirmed: list[int] = []
    for rep in range(3):  # the first pass warms caches and is not counted; the other two are
        tracker = LidarTracker()
        if rep == 1:
            cpu, wall, clusters, confirmed = [], [], [], []
        for xyz, t, stamp in raw:
            poses = scene.own.poses(t)
            c0, w0 = time.thread_time(), time.perf_counter()
            pre = preprocess(xyz, poses.position_ned, poses.roll, poses.pitch, poses.yaw, tracker.config.preprocess)
            tracks = tracker.step(
                pre.points_world, stamp, poses.position[-1], float(poses.yaw[-1]), point_times=t[pre.keep]
            )
            cpu.append((time.thread_time() - c0) * 1e3)
            wall.append((time.perf_counter() - w0) * 1e3)
            clusters.append(len(tracker.last_detections))
            confirmed.append(sum(tr.confirmed for tr in tracks))
    in_view = [
        sum(np.hypot(*(v.position - truth.own.position[:2])) < 100.0 for v in truth.vessels)
        for truth in (truth_at(scene, s) for _, _, s in raw)
    ]
    return {
        "revolutions": len(raw),
        "revolutions_timed": len(cpu),
        "points_per_revolution": float(np.mean([len(x) for x, _, _ in raw])),
        "vessels_in_view_min": float(min(in_view)),
        "detections_median": float(np.median(clusters)),
        "confirmed_tracks_median": float(np.median(confirmed)),
        "cpu_p50_ms": float(np.percentile(cpu, 50)),
        "cpu_p99_ms": float(np.percentile(cpu, 99)),
        "wall_p50_ms": float(np.percentile(wall, 50)),
        "wall_p99_ms": float(np.percentile(wall, 99)),
    }


def simulate_raw(scene: Scene, t0: float, t1: float) -> list[tuple[np.ndarray, np.ndarray, float]]:
    """Decoded body-frame revolutions (xyz, per-point time, stamp): the input the daemon's LiDAR cycle gets."""
    from drivers.vlp16.decoder import ScanAssembler
    from drivers.vlp16.packet import encode_data_packet
    from simulator.lidar_model import Vlp16Model

    model = Vlp16Model(scene, scene.lidar_mount, seed=SEED)
    assembler = ScanAssembler(mount=scene.lidar_mount)
    out = []
    for p in model.packets(t0, t1):
        payload = encode_data_packet(p.block_azimuth_cdeg, p.distance_m, p.reflectivity, p.timestamp_us)
        out += [(s.xyz, s.t, float(s.stamp)) for s in assembler.push(p.t, payload)]
    return out[1:]  # the first revolution is a partial turn


# ---------------------------------------------------------------------------------------------------------------------
# Report


def fmt(v: float, digits: int = 2, pct: bool = False) -> str:
    if not math.isfinite(v):
        return "-"
    return f"{100 * v:.0f} %" if pct else f"{v:.{digits}f}"


def table1_markdown(name: str, res: dict[str, Any]) -> list[str]:
    rows = res["rows"]
    lines = [
        f"#### {name.replace('_', ' ')} ({res['n_samples']} revolutions scored of {res['n_revolutions']})",
        "",
        "| method | IoU | position (m) | heading (deg) | length err | width err | MSE (m^2) | ms / cluster |",
        "|---|---|---|---|---|---|---|---|",
    ]

    def line(label: str, r: dict[str, float], paper: tuple[float, ...] | None) -> str:
        cells = [
            (fmt(r["iou"], pct=True), f"{paper[0]:.0f} %" if paper else ""),
            (fmt(r["position"]), f"{paper[1]:g}" if paper else ""),
            (fmt(r["heading"], 1), f"{paper[2]:g}" if paper else ""),
            (fmt(r["length"], pct=True), f"{paper[3]:g} %" if paper else ""),
            (fmt(r["width"], pct=True), f"{paper[4]:g} %" if paper else ""),
            (fmt(r["mse"], 4), f"{paper[5]:g} m" if paper else ""),
            (fmt(r.get("ms", math.nan), 3), f"{paper[6]:g}" if paper else ""),
        ]
        body = " | ".join(f"{ours} ({p})" if p else ours for ours, p in cells)
        return f"| {label} | {body} |"

    for mode in METHODS:
        lines.append(line(METHOD_NAMES[mode], rows[mode], PAPER_TABLE1.get((name, mode))))
    lines.append(line("**ours, one scan** (adaptive + guard)", rows["ours-scan"], None))
    lines.append(line("paper tracker (AEKF, adaptive), track box", rows["paper-track"], None))
    lines.append(line("**ours, tracked** (view-aware AEKF), track box", rows["ours-track"], None))
    lines.append(
        line(
            f"ours, tracked, from the first view of two sides (t >= {res['first_two_sided_t']:.1f} s)",
            rows["ours-track-after-two-sides"],
            None,
        )
    )
    lines += [
        "",
        "Paper values in parentheses. Adaptive picked the ellipse in "
        f"{fmt(rows['adaptive']['ellipse_share'], pct=True)} of revolutions. Medians, "
        f"ours tracked: position {fmt(rows['ours-track']['position_median'])} m, heading "
        f"{fmt(rows['ours-track']['heading_median'], 1)} deg.",
        "",
    ]
    return lines


def goals(t1: dict[str, Any], f4: dict[str, dict[str, float]], dense: dict[str, float]) -> list[tuple[str, bool, str]]:
    c, b = t1["container"]["rows"], t1["crew_boat"]["rows"]
    ct, bt = c["ours-track"], b["ours-track"]
    cs = c["ours-track-after-two-sides"]
    oa, ol = f4["ours adaptive"], f4["ours L-shape (corner)"]
    pa, pl = f4["paper adaptive"], f4["paper L-shape (corner)"]
    out = [
        ("container IoU >= 70 % (paper 39 %)", ct["iou"] >= 0.70, f"{fmt(ct['iou'], pct=True)} tracked"),
        (
            "container position <= 0.5 m (paper 1.5 m)",
            ct["position"] <= 0.5,
            f"{fmt(ct['position'])} m tracked over the drive; {fmt(cs['position'])} m from the first two-sided view",
        ),
        (
            "container heading <= 3 deg (paper 7 deg)",
            ct["heading"] <= 3.0,
            f"{fmt(ct['heading'], 1)} deg over the drive; {fmt(cs['heading'], 1)} deg from the first two-sided view",
        ),
        ("crew boat IoU >= 75 % (paper 61 %)", bt["iou"] >= 0.75, f"{fmt(bt['iou'], pct=True)} tracked"),
        ("crew boat position <= 1.0 m (paper 2.1 m)", bt["position"] <= 1.0, f"{fmt(bt['position'])} m tracked"),
        (
            "fisher tracking: mean position <= 0.5 m (paper ~1.5 m)",
            oa["pos_mean"] <= 0.5,
            f"{fmt(oa['pos_mean'])} m",
        ),
        ("fisher tracking: > 95 % of errors within 1 m", oa["within_1m"] > 0.95, fmt(oa["within_1m"], pct=True)),
        (
            "adaptive better than L-shape only on size and heading",
            oa["area_mean"] < ol["area_mean"] and oa["heading_mean"] < ol["heading_mean"],
            f"ours: size {fmt(oa['area_mean'], pct=True)} vs {fmt(ol['area_mean'], pct=True)}, heading "
            f"{fmt(oa['heading_mean'], 2)} vs {fmt(ol['heading_mean'], 2)} deg; paper tracker: size "
            f"{fmt(pa['area_mean'], pct=True)} vs {fmt(pl['area_mean'], pct=True)}, heading "
            f"{fmt(pa['heading_mean'], 2)} vs {fmt(pl['heading_mean'], 2)} deg",
        ),
    ]
    for mode in ("lshape-corner", "ellipse", "lshape-bruteforce", "lshape-rotation"):
        paper_ms = PAPER_TABLE1[("container", mode)][6]
        ours_ms = c[mode]["ms"]
        out.append((f"runtime {METHOD_NAMES[mode]} <= {paper_ms} ms", ours_ms <= paper_ms, f"{ours_ms:.3f} ms"))
    out.append(
        (
            "pipeline on 20 vessels: p99 < 15 ms on one core (CPU time of the thread)",
            dense["cpu_p99_ms"] < 15.0,
            f"CPU p99 {dense['cpu_p99_ms']:.1f} ms, wall p99 {dense['wall_p99_ms']:.1f} ms "
            f"(p50 {dense['cpu_p50_ms']:.1f} / {dense['wall_p50_ms']:.1f})",
        )
    )
    return out


def main() -> None:
    no_options(__doc__)
    t_start = time.perf_counter()
    RESULTS.mkdir(parents=True, exist_ok=True)
    # Throughput first, while the heap is small as in the daemon (later, the stored revolutions make every garbage
    # collection pass walk megabytes of objects, which is the benchmark's cost, not the pipeline's).
    dense = dense_runtime()
    print(f"dense: preprocess + step CPU p50 {dense['cpu_p50_ms']:.1f} ms, p99 {dense['cpu_p99_ms']:.1f} ms")
    frames = {}
    for name in ("container", "crew_boat", "fisher"):
        scene = get_scenario(name, seed=SEED)
        frames[name] = simulate(scene, 0.0, scene.duration, seed=SEED)
        print(f"{name}: {len(frames[name])} revolutions through packets -> decoder -> preprocess")
    t1 = {name: table1(name, frames[name]) for name in ("container", "crew_boat")}
    f4_data = figure4(frames["fisher"])
    f4 = fig4_summary(f4_data)
    plot_figure4(f4_data, RESULTS / "lidar_paper_fig4.png")
    examples = {}
    for name, at in (("container", 12.0), ("crew_boat", 8.0)):
        scene = get_scenario(name, seed=SEED)
        sample = min(target_samples(scene, frames[name]), key=lambda s: abs(s.frame.stamp - at))
        fits = {m: fit_shape(sample.footprint, ShapeConfig(mode=m), sample.frame.own_position) for m in METHODS[:4]}
        fits.pop("lshape-bruteforce")
        fits["ours"] = LidarTracker().fit_footprint(sample.footprint, sample.frame.own_position)
        examples[name] = (sample, fits)
    plot_examples(examples, RESULTS / "lidar_paper_fits.png")
    checks = goals(t1, f4, dense)

    md = [
        "# Paper 000 (adaptive shape fitting, LiDAR MOT) reproduced on the simulator",
        "",
        "`python bench/lidar_paper.py` (seed 1). Honest path: simulated noisy packets -> `encode_data_packet` -> "
        "`ScanAssembler` -> per-point own pose -> `preprocess` -> fits / `LidarTracker`. Ground truth only picks and "
        "scores the target. Heading errors of shapes are modulo 180 deg (a box has no bow); the fisher's tracked "
        "heading is scored over the full circle. MSE: the fit's mean squared point-to-shape distance, m^2 (the "
        "paper prints m). Means over revolutions unless noted.",
        "",
        "### Table 1: shape fitting per revolution (ours (paper))",
        "",
    ]
    for name in ("container", "crew_boat"):
        md += table1_markdown(name, t1[name])
    md += [
        "### Figure 4: fisher boat tracked (`lidar_paper_fig4.png`)",
        "",
        "| tracker | mean pos (m) | p95 pos (m) | within 1 m | within 2 m | speed err (m/s) | heading err (deg) "
        "| size err abs (signed) | coverage |",
        "|---|---|---|---|---|---|---|---|---|",
    ]
    for key, r in f4.items():
        md.append(
            f"| {key} | {fmt(r['pos_mean'])} | {fmt(r['pos_p95'])} | {fmt(r['within_1m'], pct=True)} | "
            f"{fmt(r['within_2m'], pct=True)} | {fmt(r['speed_mean'])} | {fmt(r['heading_mean'], 2)} | "
            f"{fmt(r['area_mean'], pct=True)} ({fmt(r['area_signed'], pct=True)}) | {fmt(r['coverage'], pct=True)} |"
        )
    md += [
        "",
        "Paper: mean position error ~1.5 m, > 90 % within 2 m, size underestimated by ~30 %; adaptive better than "
        "L-shape on size and heading. Coverage: revolutions with a confirmed track (the first ones build it up).",
        "",
        "### LiDAR pipeline on a revolution with 20 vessels (scene `dense`, one core)",
        "",
        f"{dense['revolutions']} revolutions ({DENSE_WINDOW[0]:.0f}-{DENSE_WINDOW[1]:.0f} s, timed twice after a "
        "warm-up pass), "
        f"{dense['points_per_revolution']:.0f} returns each, {dense['vessels_in_view_min']:.0f} vessels within "
        f"100 m, {dense['detections_median']:.0f} detections and {dense['confirmed_tracks_median']:.0f} confirmed "
        f"tracks (median). preprocess + step: CPU p50 {dense['cpu_p50_ms']:.1f} ms, p99 {dense['cpu_p99_ms']:.1f} ms; "
        f"wall p50 {dense['wall_p50_ms']:.1f} ms, p99 {dense['wall_p99_ms']:.1f} ms. The machine's 2 cores are "
        "shared with other jobs: wall time includes their preemptions, and even CPU time grows ~1.5x when the other "
        "core is busy.",
        "",
        "### Goals",
        "",
        "| goal | met | ours |",
        "|---|---|---|",
    ]
    md += [f"| {g} | {'met' if ok else '**not met**'} | {detail} |" for g, ok, detail in checks]
    md += ["", f"Run time of this benchmark: {time.perf_counter() - t_start:.0f} s.", ""]
    text = "\n".join(md)
    print(text)
    figures = {
        "table1": t1,
        "figure4": f4,
        "dense": dense,
        "goals": [{"goal": g, "met": ok, "detail": d} for g, ok, d in checks],
    }
    save("lidar_paper", figures, text)


if __name__ == "__main__":
    main()
