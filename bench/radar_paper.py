"""Paper 001 (ROTracker, Xu et al. 2024) evaluated on the simulator: Tables 3, 4 and 5, the settings and the runtime.

    python bench/radar_paper.py            # about 4 minutes on 2 cores
    python bench/radar_paper.py --quick    # one seed, 20 s sequences: a smoke run of the whole script

Writes bench/results/radar_paper.md (+ .json) and radar_paper_*.png. Every frame takes the daemon's path: the AWR1843
model's point cloud is encoded as UART frames, decoded by RadarFrameParser with the scene's radar mount, and stepped
through RadarTracker.step_frame with the own boat's pose; scoring is CLEAR MOT with py-motmetrics (bench/radar_eval.py).

Sequences: the paper's four (Table 2: static, low, mid, high speed; here scenario "radar_paper", Smurf, Titan and Xi
at 0 / 0.5 / 1.5 / 3 m/s on closed laps 12-47 m ahead, a quay 28 m to starboard), 60 s each with two radar-model
seeds; for Table 5 the three boats in each distance band (bench/radar_scenes.py), at rest and moving, with the model
set up for 100 m like the paper's radar.
"""

from __future__ import annotations

import argparse
import gc
import math
import sys
import time
from pathlib import Path
from typing import Any

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent.parent))

from bench._common import RESULTS, save
from bench.radar_eval import GATE_M, MOVING_MIN_MPS, Metrics, Recording, Scored, metrics, record, run_tracker, score
from bench.radar_scenes import BAND_MODEL, BANDS, DAEMON_OVERRIDES, band_scene, daemon_config
from simulator.scenarios import get_scenario
from tracker.radar import RadarTrackerConfig

SPEEDS = ("static", "low", "mid", "high")
VESSELS = ("smurf", "titan", "xi")
# Paper 001, Table 3 ("Ours", MMW radar), per boat class: MOTA %, MOTP cm, MVE cm/s, MAE deg, TP %, FP %.
PAPER_T3 = {
    "smurf": (88.7, 55.1, 19.6, 14.3, 93.8, 3.7),
    "titan": (91.9, 59.4, 23.9, 15.9, 94.1, 2.3),
    "xi": (95.3, 78.0, 26.5, 17.3, 95.2, 1.1),
}
# Table 4: MVE cm/s, MAE deg, MVE and MAE at low speed.
PAPER_T4 = {
    "full": (23.3, 15.8, 18.9, 22.3),
    "no_velocity": (43.7, 26.4, 58.5, 37.7),
    "no_md": (25.6, 17.8, 36.5, 27.9),
}
# Table 5: MOTA %, MOTP cm, MVE cm/s, MAE deg per distance band.
PAPER_T5 = {
    (0.0, 30.0): (97.2, 34.2, 13.5, 11.3),
    (30.0, 60.0): (93.4, 63.0, 21.6, 14.8),
    (60.0, 90.0): (90.1, 92.5, 30.2, 19.2),
}
ABLATIONS = {
    "full": {},
    "no_velocity": {"doppler": {"enabled": False}},
    "no_md": {"motion": {"enabled": False}},
}
ABLATION_NAMES = {
    "full": "Full (ours)",
    "no_velocity": "Remove velocity measurement",
    "no_md": "Remove motion discriminator",
}
SWEEP_MIN_POINTS = (2, 3, 4, 5, 6)


def fmt(x: float, digits: int = 1) -> str:
    return "n/a" if x is None or not math.isfinite(x) else f"{x:.{digits}f}"


def run_all(recs: list[Recording], cfg: RadarTrackerConfig) -> list[Scored]:
    """Track and score each recording (timing is time_tracker's)."""
    return [score(rec, run_tracker(rec, cfg)) for rec in recs]


def time_tracker(recs: list[Recording], cfg: RadarTrackerConfig) -> tuple[np.ndarray, np.ndarray]:
    """Per-frame wall and thread CPU seconds of parser + tracker over ``recs``, nothing else running in the process.

    Everything alive before the pass (recordings, earlier passes' results) is frozen out of the garbage collector
    first, as the daemon freezes its start-up objects: a full collection walking the bench's own data inside a timed
    frame is not the tracker's cost."""
    gc.collect()
    gc.freeze()
    wall, cpu = [], []
    for rec in recs:
        run = run_tracker(rec, cfg)
        wall.append(run.seconds)
        cpu.append(run.cpu_seconds)
    return np.concatenate(wall), np.concatenate(cpu)


def vessel_mask(name: str) -> np.ndarray:
    return np.array([v == name for v in VESSELS])


def metrics_row(m: Metrics) -> list[str]:
    return [fmt(m.mota), fmt(m.motp_cm), fmt(m.mve_cmps), fmt(m.mae_deg), fmt(m.tp), fmt(m.fp), str(m.idsw)]


def table(header: list[str], rows: list[list[str]]) -> str:
    out = ["| " + " | ".join(header) + " |", "|" + "|".join("---" for _ in header) + "|"]
    out += ["| " + " | ".join(r) + " |" for r in rows]
    return "\n".join(out)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true", help="one seed, 20 s sequences (smoke run)")
    args = ap.parse_args()
    seeds = (1,) if args.quick else (1, 2)
    duration = 20.0 if args.quick else None
    t_start = time.perf_counter()
    mount = get_scenario("radar_paper").radar_mount
    ours = daemon_config(mount.x, mount.y)
    paper_defaults = RadarTrackerConfig().replaced(sensor_position_body=(mount.x, mount.y))

    # --- recordings ---------------------------------------------------------------------------------------------
    seqs: dict[str, list[Recording]] = {sp: [] for sp in SPEEDS}
    for sp in SPEEDS:
        for seed in seeds:
            seqs[sp].append(record(get_scenario("radar_paper", seed, speed=sp), seed, duration, name=f"{sp}/{seed}"))
    all_recs = [r for sp in SPEEDS for r in seqs[sp]]
    bands: dict[tuple[float, float], list[Recording]] = {}
    for band in BANDS:
        bands[band] = [
            record(band_scene(band, motion), 1, duration, name=f"{band}/{motion}", **BAND_MODEL)
            for motion in ("static", "moving")
        ]
    n_frames = sum(len(r.times) for r in all_recs)
    print(f"recorded {n_frames} + {sum(len(r.times) for b in bands.values() for r in b)} frames", flush=True)

    # --- Table 3 -----------------------------------------------------------------------------------------------
    full = run_all(all_recs, ours)
    # Runtime: the same frames timed in TIMING_PASSES passes and the quietest reported (this machine's cores are
    # shared; a neighbour's burst in one pass is not the tracker's cost), every pass listed.
    passes = [time_tracker(all_recs, ours) for _ in range(TIMING_PASSES)]
    wall, cpu = min(passes, key=lambda wc: float(np.percentile(wc[0], 99)))
    pass_p99 = [float(np.percentile(w, 99) * 1e3) for w, _ in passes]
    # Each frame's fastest pass: the same deterministic work each time, so the minimum bounds the frame's own cost
    # from below (it also drops whatever slowed the frame in the other passes; reported beside, not judged on).
    frame_best = np.min(np.array([w for w, _ in passes]), axis=0)
    by_speed = {sp: full[i * len(seeds) : (i + 1) * len(seeds)] for i, sp in enumerate(SPEEDS)}
    m_speed = {sp: metrics([(s, None) for s in by_speed[sp]]) for sp in SPEEDS}
    m_vessel = {v: metrics([(s, vessel_mask(v)) for s in full]) for v in VESSELS}
    m_all = metrics([(s, None) for s in full])
    print(f"ours: MOTA {m_all.mota:.1f} % ({time.perf_counter() - t_start:.0f} s)", flush=True)
    paper_run = run_all(all_recs, paper_defaults)
    m_paper_cfg = metrics([(s, None) for s in paper_run])

    # --- Table 4: ablation -------------------------------------------------------------------------------------
    ablation: dict[str, tuple[Metrics, Metrics]] = {}
    for key, change in ABLATIONS.items():
        sc = full if not change else run_all(all_recs, ours.replaced(**change))
        low = sc[SPEEDS.index("low") * len(seeds) : (SPEEDS.index("low") + 1) * len(seeds)]
        ablation[key] = (metrics([(s, None) for s in sc]), metrics([(s, None) for s in low]))
    print(f"ablation done ({time.perf_counter() - t_start:.0f} s)", flush=True)

    # --- Table 5: distance bands -------------------------------------------------------------------------------
    band_metrics: dict[tuple[float, float], Metrics] = {}
    for band, recs in bands.items():
        sc = run_all(recs, ours)
        band_metrics[band] = metrics([(s, None) for s in sc], band=band)
    print(f"bands done ({time.perf_counter() - t_start:.0f} s)", flush=True)

    # --- settings sweep (one seed): clustering.min_points, and the paper's cluster radius ---------------------------
    sweep_recs = [seqs[sp][0] for sp in SPEEDS]
    sweep: list[tuple[str, Metrics]] = []
    for k in SWEEP_MIN_POINTS:
        cfg = ours.replaced(clustering={"min_points": k, "velocity_min_points": k})
        sweep.append(
            (
                f"min points {k}, radius {ours.clustering.radius_m} m",
                metrics([(s, None) for s in run_all(sweep_recs, cfg)]),
            )
        )
    for k in (3, 4):
        cfg = ours.replaced(clustering={"min_points": k, "velocity_min_points": k, "radius_m": 1.2})
        sweep.append((f"min points {k}, radius 1.2 m (paper)", metrics([(s, None) for s in run_all(sweep_recs, cfg)])))
    sweep.append(
        (
            "ours with constant velocity instead of the turn model (cv, 2 m/s^2)",
            metrics(
                [(s, None) for s in run_all(sweep_recs, ours.replaced(kalman={"motion_model": "cv", "accel_std": 2.0}))]
            ),
        )
    )
    cfg = ours.replaced(
        kalman={"motion_model": RadarTrackerConfig().kalman.motion_model},
        lifecycle={"max_unseen_time": RadarTrackerConfig().lifecycle.max_unseen_time},
    )
    sweep.append(
        (
            "ours with the config's filter defaults (CA, coast 2 s)",
            metrics([(s, None) for s in run_all(sweep_recs, cfg)]),
        )
    )
    elapsed = time.perf_counter() - t_start
    print(f"sweep done ({elapsed:.0f} s)", flush=True)

    # --- figures -----------------------------------------------------------------------------------------------
    figures = make_figures(seqs, ours, m_vessel, sweep, wall, cpu)

    # --- report ------------------------------------------------------------------------------------------------
    md, summary = report(
        seeds,
        duration,
        ours,
        m_speed,
        m_vessel,
        m_all,
        m_paper_cfg,
        ablation,
        band_metrics,
        sweep,
        wall,
        cpu,
        pass_p99,
        frame_best,
        figures,
        elapsed,
        n_frames,
    )
    save("radar_paper", summary, md)


TIMING_PASSES = 3


def runtime_stats(wall: np.ndarray, cpu: np.ndarray) -> dict[str, float]:
    return {
        "wall_mean_ms": float(wall.mean() * 1e3),
        "wall_p50_ms": float(np.percentile(wall, 50) * 1e3),
        "wall_p99_ms": float(np.percentile(wall, 99) * 1e3),
        "wall_max_ms": float(wall.max() * 1e3),
        "cpu_mean_ms": float(cpu.mean() * 1e3),
        "cpu_p99_ms": float(np.percentile(cpu, 99) * 1e3),
    }


def report(
    seeds: tuple[int, ...],
    duration: float | None,
    ours: RadarTrackerConfig,
    m_speed: dict[str, Metrics],
    m_vessel: dict[str, Metrics],
    m_all: Metrics,
    m_paper_cfg: Metrics,
    ablation: dict[str, tuple[Metrics, Metrics]],
    band_metrics: dict[tuple[float, float], Metrics],
    sweep: list[tuple[str, Metrics]],
    wall: np.ndarray,
    cpu: np.ndarray,
    pass_p99: list[float],
    frame_best: np.ndarray,
    figures: list[str],
    elapsed: float,
    n_frames: int,
) -> tuple[str, dict[str, Any]]:
    rt = runtime_stats(wall, cpu)
    rt["own_p99_ms"] = float(np.percentile(frame_best, 99) * 1e3)
    hdr = ["", "MOTA % ↑", "MOTP cm ↓", "MVE cm/s ↓", "MAE deg ↓", "TP % ↑", "FP % ↓", "IDSW"]
    seq_len = f"{duration:.0f} s" if duration else "60 s"
    lines = [
        "# ROTracker (paper 001) on the simulated AWR1843",
        "",
        f"`python bench/radar_paper.py`: {len(SPEEDS)} sequences x {len(seeds)} radar-model seeds x {seq_len} at 10 Hz "
        f"({n_frames} frames) for Tables 3-4, 6 band sequences for Table 5; {elapsed:.0f} s on this machine. Frames "
        "take the daemon's path (AWR1843 model -> UART frame -> `RadarFrameParser` with the radar mount -> "
        "`RadarTracker.step_frame` with the own boat's `EgoPose`).",
        "",
        "**Scoring.** CLEAR MOT with py-motmetrics 1.4: hypotheses are the tracker's *confirmed* tracks (coasting ones "
        "included, as the daemon publishes them), objects the simulated boats; distance = Euclidean distance in metres "
        f"between the track position and the hull centre, no match beyond {GATE_M:.0f} m; a pair matched in the "
        "previous frame is kept while inside the gate, the rest is a Hungarian assignment; a boat changing track is an "
        "id switch. TP % and FP % are per truth object (MOTA = TP - FP - IDSW). MVE = mean |published speed - true "
        f"speed| and MAE = mean |published course - true course| (boats moving >= {MOVING_MIN_MPS} m/s, tracks "
        "publishing a non-zero velocity), over matched pairs whose track publishes a velocity (the motion "
        "discriminator's \"wait\" level publishes none; see the coverage columns). Track ids are the tracker's own; "
        "the truth's are the scene's vessel indices (0 Smurf, 1 Titan, 2 Xi).",
        "",
        f'**Settings** ("ours"): the config defaults (paper values) plus `{_overrides_text()}` and the radar mount '
        f"`sensor_position_body={ours.sensor_position_body}`. With the paper's own settings (20 returns per cluster) "
        f"the simulated AWR1843 (3-10 returns per boat per frame) forms no cluster: MOTA {fmt(m_paper_cfg.mota)} %, "
        f"TP {fmt(m_paper_cfg.tp)} %.",
        "",
        "## Table 3: per class",
        "",
        "By speed class (the brief's classes; the paper has no per-speed table):",
        "",
        table(hdr, [[sp, *metrics_row(m_speed[sp])] for sp in SPEEDS] + [["**all**", *metrics_row(m_all)]]),
        "",
        "By boat class, the paper's layout (ours / paper). A false track counts for the boat nearest to it:",
        "",
        table(
            ["", "MOTA %", "MOTP cm", "MVE cm/s", "MAE deg", "TP %", "FP %"],
            [
                [v]
                + [
                    f"{fmt(o)} / {p}"
                    for o, p in zip((m.mota, m.motp_cm, m.mve_cmps, m.mae_deg, m.tp, m.fp), PAPER_T3[v], strict=True)
                ]
                for v, m in m_vessel.items()
            ],
        ),
        "",
        "Coverage: velocity published for "
        + ", ".join(f"{sp} {fmt(m_speed[sp].v_cov)} %" for sp in SPEEDS)
        + " of matched pairs; course published for "
        + ", ".join(f"{sp} {fmt(m_speed[sp].course_cov)} %" for sp in SPEEDS if sp != "static")
        + " of matched pairs of moving boats. MVE of the velocity vector (speed and course together): "
        + ", ".join(f"{sp} {fmt(m_speed[sp].mve_vec_cmps)}" for sp in SPEEDS)
        + " cm/s.",
        "",
        "## Table 4: ablation",
        "",
        table(
            [
                "",
                "MVE cm/s",
                "MAE deg",
                "MVE low cm/s",
                "MAE low deg",
                "paper (MVE, MAE, MVE_L, MAE_L)",
                "vector error cm/s (all, low)",
                "MOTA %",
            ],
            [
                [
                    ABLATION_NAMES[k],
                    fmt(a.mve_cmps),
                    fmt(a.mae_deg),
                    fmt(lo.mve_cmps),
                    fmt(lo.mae_deg),
                    ", ".join(str(x) for x in PAPER_T4[k]),
                    f"{fmt(a.mve_vec_cmps)}, {fmt(lo.mve_vec_cmps)}",
                    fmt(a.mota),
                ]
                for k, (a, lo) in ablation.items()
            ],
        ),
        "",
        "MVE is the speed error; the vector error |v_published - v_true| also counts the course. The velocity "
        "measurement fixes the radial component of the velocity and, through its row for the turn rate, the turn: "
        "on the simulated laps a third of the time is spent in 2.5 m radius turns (1.2 rad/s at 3 m/s), where a "
        "hull's returns differ in Doppler by yaw rate x lever arm (2-3 m/s bow to stern). Without it the turn rate "
        "is fitted to positions alone, which is why removing it costs more here than in the paper.",
        "",
        "## Table 5: by distance",
        "",
        f"Band scenes (bench/radar_scenes.py), radar model {BAND_MODEL} (the paper's 100 m configuration). "
        "Objects and the false tracks nearest to them count in the band of the object's range.",
        "",
        table(
            ["band", "MOTA %", "MOTP cm", "MVE cm/s", "MAE deg", "TP %", "FP %", "paper (MOTA, MOTP, MVE, MAE)"],
            [
                [f"{lo:.0f}-{hi:.0f} m", *metrics_row(m)[:6], ", ".join(str(x) for x in PAPER_T5[lo, hi])]
                for (lo, hi), m in band_metrics.items()
            ],
        ),
        "",
        "## Settings sweep (seed 1, the four sequences)",
        "",
        table(["setting", *hdr[1:]], [[name, *metrics_row(m)] for name, m in sweep]),
        "",
        "## Runtime",
        "",
        f'Parser + tracker per frame over {len(wall)} frames of Table 3 ("ours"), the quietest of {len(pass_p99)} '
        f"passes (p99 per pass: {', '.join(f'{v:.2f}' for v in pass_p99)} ms): mean {rt['wall_mean_ms']:.2f} ms, "
        f"p50 {rt['wall_p50_ms']:.2f} ms, p99 {rt['wall_p99_ms']:.2f} ms, max {rt['wall_max_ms']:.2f} ms wall clock; "
        f"CPU time of the thread mean {rt['cpu_mean_ms']:.2f} ms, p99 {rt['cpu_p99_ms']:.2f} ms "
        "(2 shared cores; paper: 24.5 ms mean on a Jetson Xavier NX). Each frame's fastest of the "
        f"{len(pass_p99)} passes (the work is the same each time), a lower bound of what the frame itself costs: "
        f"p99 {rt['own_p99_ms']:.2f} ms.",
        "",
        "## Goals",
        "",
    ]
    lines += goals(m_speed, m_all, ablation, rt)
    lines += ["", "## Figures", ""] + [f"![{f}]({f})" for f in figures]
    summary = {
        "seeds": list(seeds),
        "frames": n_frames,
        "elapsed_s": elapsed,
        "config_overrides": DAEMON_OVERRIDES,
        "by_speed": {sp: m.row() for sp, m in m_speed.items()},
        "by_vessel": {v: m.row() for v, m in m_vessel.items()},
        "all": m_all.row(),
        "paper_settings": m_paper_cfg.row(),
        "ablation": {k: {"all": a.row(), "low": lo.row()} for k, (a, lo) in ablation.items()},
        "bands": {f"{lo:.0f}-{hi:.0f}": m.row() for (lo, hi), m in band_metrics.items()},
        "sweep": {name: m.row() for name, m in sweep},
        "runtime": rt,
    }
    return "\n".join(lines), summary


def _overrides_text() -> str:
    return ", ".join(f"{k}={v!r}" for k, v in DAEMON_OVERRIDES.items())


def goals(
    m_speed: dict[str, Metrics], m_all: Metrics, ablation: dict[str, tuple[Metrics, Metrics]], rt: dict[str, float]
) -> list[str]:
    def line(ok: bool, text: str) -> str:
        return f"- {'met' if ok else '**not met**'}: {text}"

    motas = [m_speed[sp].mota for sp in SPEEDS]
    full, no_v, no_md = ablation["full"], ablation["no_velocity"], ablation["no_md"]
    v_helps = no_v[0].mve_cmps > full[0].mve_cmps and no_v[1].mve_cmps > full[1].mve_cmps
    md_helps = no_md[1].mve_cmps > full[1].mve_cmps
    v_helps_vec = no_v[0].mve_vec_cmps > full[0].mve_vec_cmps and no_v[0].mae_deg > full[0].mae_deg
    return [
        line(
            min(motas) >= 95.0,
            "MOTA >= 95 % in every class: " + ", ".join(f"{sp} {fmt(m)}" for sp, m in zip(SPEEDS, motas, strict=True)),
        ),
        line(
            m_all.motp_cm <= 50.0,
            f"MOTP <= 50 cm: {fmt(m_all.motp_cm)} cm overall, "
            f"worst class {fmt(max(m_speed[sp].motp_cm for sp in SPEEDS))}",
        ),
        line(
            m_all.mve_cmps <= 15.0,
            f"MVE <= 15 cm/s: {fmt(m_all.mve_cmps)} cm/s overall, "
            f"worst class {fmt(max(m_speed[sp].mve_cmps for sp in SPEEDS))}",
        ),
        line(m_all.mae_deg <= 10.0, f"MAE <= 10 deg: {fmt(m_all.mae_deg)} deg overall"),
        line(
            m_all.fp <= 1.0,
            f"FP <= 1 %: {fmt(m_all.fp)} % overall, " + ", ".join(f"{sp} {fmt(m_speed[sp].fp)}" for sp in SPEEDS),
        ),
        line(
            v_helps,
            f"removing the velocity measurement hurts MVE (overall {fmt(full[0].mve_cmps)} -> {fmt(no_v[0].mve_cmps)}, "
            f"low {fmt(full[1].mve_cmps)} -> {fmt(no_v[1].mve_cmps)} cm/s)",
        ),
        line(
            v_helps_vec,
            f"removing the velocity measurement hurts the velocity vector and the course (vector error "
            f"{fmt(full[0].mve_vec_cmps)} -> {fmt(no_v[0].mve_vec_cmps)} cm/s, MAE {fmt(full[0].mae_deg)} -> "
            f"{fmt(no_v[0].mae_deg)} deg)",
        ),
        line(
            md_helps,
            f"removing the motion discriminator hurts low-speed MVE ({full[1].mve_cmps:.2f} -> {no_md[1].mve_cmps:.2f}"
            f" cm/s; low-speed MAE {fmt(full[1].mae_deg)} -> {fmt(no_md[1].mae_deg)} deg, vector error"
            f" {fmt(full[1].mve_vec_cmps)} -> {fmt(no_md[1].mve_vec_cmps)} cm/s; overall MVE {fmt(full[0].mve_cmps)} ->"
            f" {fmt(no_md[0].mve_cmps)} cm/s)"
            + f" - {100 * (no_md[1].mve_cmps / full[1].mve_cmps - 1):.1f} % at low speed",
        ),
        line(
            rt["wall_p99_ms"] < 5.0,
            f"radar pipeline p99 < 5 ms: {rt['wall_p99_ms']:.2f} ms wall, {rt['cpu_p99_ms']:.2f} ms CPU in the "
            "quietest pass (each frame's fastest of the passes, a lower bound of its own cost: "
            f"p99 {rt['own_p99_ms']:.2f} ms)",
        ),
    ]


def make_figures(
    seqs: dict[str, list[Recording]],
    ours: RadarTrackerConfig,
    m_vessel: dict[str, Metrics],
    sweep: list[tuple[str, Metrics]],
    wall: np.ndarray,
    cpu: np.ndarray,
) -> list[str]:
    try:
        import matplotlib

        matplotlib.use("Agg")
        import matplotlib.pyplot as plt
    except ImportError:
        print("matplotlib not installed: no figures")
        return []
    names = []
    # 1. tracks over truth, mid speed
    rec = seqs["mid"][0]
    run = run_tracker(rec, ours)
    fig, ax = plt.subplots(figsize=(7, 6))
    for j, name in enumerate(rec.vessel_class):
        ax.plot(
            rec.truth_pos[:, j, 1], rec.truth_pos[:, j, 0], "k-", lw=3, alpha=0.25, label="truth" if j == 0 else None
        )
        ax.annotate(name, (rec.truth_pos[0, j, 1], rec.truth_pos[0, j, 0]), fontsize=8)
    ids = np.concatenate(run.ids)
    pos = np.concatenate(run.pos)
    for tid in np.unique(ids):
        p = pos[ids == tid]
        ax.plot(p[:, 1], p[:, 0], ".", ms=2, label=None)
    ax.plot([28, 28], [-10, 60], "c-", lw=2, label="quay")
    ax.plot(0, 0, "r^", label="own boat")
    ax.set_xlabel("east m")
    ax.set_ylabel("north m")
    ax.set_aspect("equal")
    ax.set_title(f"mid speed, seed {rec.seed}: confirmed tracks (one colour per id) over truth")
    ax.legend(loc="lower right", fontsize=8)
    names.append(_save(fig, "radar_paper_tracks.png"))
    # 2. ours vs paper per boat class
    fig, axes = plt.subplots(1, 2, figsize=(9, 3.5))
    x = np.arange(len(VESSELS))
    for ax, (idx, label) in zip(axes, ((0, "MOTA %"), (1, "MOTP cm")), strict=True):
        ours_v = [(m_vessel[v].mota, m_vessel[v].motp_cm)[idx] for v in VESSELS]
        paper_v = [PAPER_T3[v][idx] for v in VESSELS]
        ax.bar(x - 0.2, ours_v, 0.4, label="ours (simulated)")
        ax.bar(x + 0.2, paper_v, 0.4, label="paper (real)")
        ax.set_xticks(x, VESSELS)
        ax.set_title(label)
    axes[0].legend(fontsize=8)
    names.append(_save(fig, "radar_paper_classes.png"))
    # 3. sweep and runtime
    fig, axes = plt.subplots(1, 2, figsize=(9, 3.5))
    ks = [m for _, m in sweep[: len(SWEEP_MIN_POINTS)]]  # the min-points rows come first
    axes[0].plot(SWEEP_MIN_POINTS, [m.mota for m in ks], "o-", label="MOTA %")
    axes[0].plot(SWEEP_MIN_POINTS, [m.tp for m in ks], "s-", label="TP %")
    axes[0].plot(SWEEP_MIN_POINTS, [m.fp for m in ks], "^-", label="FP %")
    axes[0].set_xlabel("cluster_min_points = clustering.velocity_min_points")
    axes[0].legend(fontsize=8)
    axes[1].hist(wall * 1e3, bins=60, alpha=0.6, label="wall")
    axes[1].hist(cpu * 1e3, bins=60, alpha=0.6, label="CPU")
    axes[1].axvline(5.0, color="r", lw=1)
    axes[1].set_xlabel("parser + tracker per frame, ms")
    axes[1].set_yscale("log")
    axes[1].legend(fontsize=8)
    names.append(_save(fig, "radar_paper_settings_runtime.png"))
    return names


def _save(fig: Any, name: str) -> str:
    RESULTS.mkdir(parents=True, exist_ok=True)
    fig.tight_layout()
    fig.savefig(RESULTS / name, dpi=110)
    import matplotlib.pyplot as plt

    plt.close(fig)
    return name


if __name__ == "__main__":
    main()
