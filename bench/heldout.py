"""The daemon on harbour scenes nobody tuned for: LiDAR only, radar only and fused, scored by `usv-tracker evaluate`.

    python bench/heldout.py                    # the 50 held-out scenes random:1001 .. random:1050 (about 25 min)
    python bench/heldout.py --train 1-12       # tuning scenes (seeds 1-100), printed only: never quoted
    python bench/heldout.py --seeds 1007,1033  # replay particular scenes (e.g. the worst ones named below)

Each scene (simulator/random_scene.py) is simulated to capture files exactly as a boat records them (VLP-16 pcap,
AWR1843 data-port dump, autopilot .tlog), replayed through the daemon's own replay path three times (LiDAR only,
radar only, both), and each run's --tracks-out file is scored against the scene's truth and its record of what each
sensor returned (evaluation/). A process pool runs the scenes over both cores.

Reported per mode: MOTA, IDF1, false track-frames (false positives / matches), id switches, position and speed error
of matched pairs, false-clear bins (sent clear or unknown while a returned solid lay nearer than 80 m) and
false-obstacle bins (share of the bins scored); the mean, the worst scene, and the three worst seeds by name.
Only held-out runs are written to bench/results/heldout.{md,json}.
"""

from __future__ import annotations

import argparse
import logging
import math
import os
import sys
import tempfile
import time
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path
from typing import Any

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent.parent))

from bench._common import save

MODES = {"lidar": ("lidar",), "radar": ("radar",), "fused": ("lidar", "radar")}
HELD_OUT = range(1001, 1051)
# A confirmed track whose centre lies on a quay, or this close off its face (m), is on the quay: a boat moored against
# it lies 0.3 m off the face (simulator/random_scene.py), so even a 1 m wide one has its centre 0.8 m out.
QUAY_MARGIN_M = 0.5
TRAINING = range(1, 101)
SECONDS = 60.0


def _seeds(text: str) -> list[int]:
    out: list[int] = []
    for part in text.split(","):
        a, _, b = part.partition("-")
        out += list(range(int(a), int(b) + 1)) if b else [int(a)]
    return out


def _num(x: float | None) -> float:
    """The evaluator's JSON has null where a figure is undefined (no vessel to track yet): NaN here."""
    return math.nan if x is None else float(x)


def run_scene(seed: int, seconds: float, modes: tuple[str, ...] = tuple(MODES)) -> dict[str, Any]:
    """Simulate one scene, replay it in each mode and score it; a dict of figures per mode."""
    logging.disable(logging.WARNING)  # the daemon's per-run INFO lines would bury the table
    from daemon.replay import recording_config, run_replay
    from evaluation import evaluate_run
    from simulator.capture import write_captures
    from simulator.scenarios import get_scenario

    # the scene `usv-tracker simulate --scene random:SEED` plays (drawn for its own 60 s), the first ``seconds`` of it
    scene = get_scenario(f"random:{seed}", seed=seed)
    lines = scene.description.splitlines()
    out: dict[str, Any] = {"seed": seed, "description": lines[1] if len(lines) > 1 else lines[0]}  # the day's line
    with tempfile.TemporaryDirectory(prefix=f"heldout-{seed}-") as tmp:
        d = Path(tmp)
        t0 = time.perf_counter()
        write_captures(f"random:{seed}", d, seconds, seed=seed, scene=scene)
        out["simulate_s"] = time.perf_counter() - t0
        for mode in modes:
            sensors = MODES[mode]
            config = recording_config(d, d / f"tracks-{mode}.jsonl", "lidar" in sensors, "radar" in sensors)
            t0 = time.perf_counter()
            run_replay(config, fast=True)
            replay_s = time.perf_counter() - t0
            r = evaluate_run(d, d / f"tracks-{mode}.jsonl", sensors=sensors).to_dict()
            tr, bins = r["tracks"], r["bins"] or {}
            matches = tr["matches"]
            out[mode] = {
                "mota": _num(tr["mota"]),
                "idf1": _num(tr["idf1"]),
                "false_track_frames": tr["false_positives"] / matches if matches else math.nan,
                "false_positives": tr["false_positives"],
                "matches": matches,
                "id_switches": tr["id_switches"],
                "position_error_m": _num(tr["position_error_m"]["mean"]),
                "speed_error_mps": _num(tr["speed_error_mps"]["mean"]),
                # the hull's axis, bow or stern either way: a still hull shows no bow, its heading is a guess
                "heading_axis_error_deg": _num(tr["heading_axis_error_deg"]["mean"]),
                "false_clear_bins": bins.get("false_clear", 0),
                # of those, the bins that went out "clear" (free water to ArduPilot); the rest went out "unknown"
                "false_clear_sent_clear": bins.get("false_clear_sent_clear", 0),
                "bins_with_solid": bins.get("bins_with_solid", 0),
                "false_obstacle_bins": bins.get("false_obstacle", 0),
                # an obstacle sent beyond a solid returned nearer throughout: more room said than there is
                "too_far_bins": bins.get("too_far", 0),
                "obstacle_unreturned_bins": bins.get("obstacle_unreturned", 0),
                # ticks that sent no array at all while a returned solid lay within 80 m: silence, not a false clear
                "ticks_withheld_with_solid": bins.get("ticks_withheld_with_solid", 0),
                "bins_scored": bins.get("bins_scored", 0),
                "false_obstacle_share": bins.get("false_obstacle", 0) / max(bins.get("bins_scored", 0), 1),
                "replay_s": replay_s,
                "by_hull": _by_hull(scene, r["visibility"]["per_vessel"]),
                "on_quay": tracks_on_quays(scene.quays, d / f"tracks-{mode}.jsonl"),
            }
            # Each mode above is scored on what its own sensors returned, so fused answers for more vessels than
            # either sensor alone. "Does the second sensor help?" needs one truth for all three: every vessel
            # either sensor returned.
            if sensors != MODES["fused"]:
                tr = evaluate_run(d, d / f"tracks-{mode}.jsonl", sensors=MODES["fused"]).to_dict()["tracks"]
            out[mode]["mota_all_returned"] = _num(tr["mota"])
            out[mode]["idf1_all_returned"] = _num(tr["idf1"])
    return out


def tracks_on_quays(quays: list[Any], tracks_path: Path, margin_m: float = QUAY_MARGIN_M) -> dict[str, int]:
    """Confirmed track-ticks whose centre lies on a quay (the wall and the land strip behind it, ``Quay.blocks``) or
    within ``margin_m`` off it, and how many tracks those were: issue 12's goal is none. No vessel's centre can be
    there, so each is a piece of quay published as an object, whether or not the evaluator matched it."""
    from evaluation.geometry import distance_to_polygon
    from evaluation.ticks import read_ticks

    blocks = [b for q in quays for b in q.blocks()]
    ticks, ids = 0, set()
    if not blocks:
        return {"track_ticks": 0, "tracks": 0}
    for tick in read_ticks(tracks_path):
        if not len(tick.tracks):
            continue
        d = np.min([distance_to_polygon(tick.tracks.position, b) for b in blocks], axis=0)
        on = d <= margin_m
        ticks += int(on.sum())
        ids.update(tick.tracks.ids[on].tolist())
    return {"track_ticks": ticks, "tracks": len(ids)}


def _hull_group(vessel: Any) -> str:
    """The group a vessel is counted in by ``by_hull``: its hull's shape, buoys apart, moored boats apart."""
    if vessel.hull == "buoy":
        return "buoy"
    return f"{vessel.hull}, moored" if "-moored" in vessel.name else vessel.hull


HULL_GROUPS = ("pointed", "box", "round", "buoy", "pointed, moored", "box, moored", "round, moored")


def _by_hull(scene: Any, per_vessel: dict[str, dict[str, Any]]) -> dict[str, list[int]]:
    """[vessel-ticks to be tracked, of them matched] per hull group: do curved hulls and buoys fare as prisms do?"""
    out: dict[str, list[int]] = {}
    for vid, row in per_vessel.items():
        counts = out.setdefault(_hull_group(scene.vessels[int(vid)]), [0, 0])
        counts[0] += int(row.get("to_track", 0))
        counts[1] += int(row.get("matched", 0))
    return out


def by_hull_line(rows: list[dict[str, Any]], mode: str = "fused") -> str:
    """Pooled over the scenes: the share of each hull group's vessel-ticks to be tracked that a track matched."""
    cells = []
    for group in HULL_GROUPS:
        to_track = sum(r[mode]["by_hull"].get(group, [0, 0])[0] for r in rows)
        matched = sum(r[mode]["by_hull"].get(group, [0, 0])[1] for r in rows)
        if to_track:
            cells.append(f"{group} {matched / to_track:.3f} ({to_track:,} ticks)")
    return f"Vessel-ticks tracked by hull ({mode}, pooled): " + "; ".join(cells) + "."


# (key, label, format, worse is "low" or "high")
COLUMNS = (
    ("mota", "MOTA", "{:.3f}", "low"),
    ("idf1", "IDF1", "{:.3f}", "low"),
    ("false_track_frames", "false track-frames / matches", "{:.1%}", "high"),
    ("id_switches", "id switches", "{:.0f}", "high"),
    ("position_error_m", "position error (m)", "{:.2f}", "high"),
    ("speed_error_mps", "speed error (m/s)", "{:.2f}", "high"),
    ("heading_axis_error_deg", "heading axis error (deg)", "{:.1f}", "high"),
    ("false_clear_bins", "false-clear bins", "{:.0f}", "high"),
    ("too_far_bins", "too-far bins", "{:.0f}", "high"),
    ("false_obstacle_share", "false-obstacle bins (share)", "{:.2%}", "high"),
)


def summarise(rows: list[dict[str, Any]], modes: tuple[str, ...] = tuple(MODES)) -> dict[str, Any]:
    summary: dict[str, Any] = {}
    for mode in modes:
        per: dict[str, Any] = {}
        for key, _label, _fmt, worse in COLUMNS:
            vals = np.array([r[mode][key] for r in rows], float)
            ok = np.isfinite(vals)
            if not ok.any():
                per[key] = {"mean": math.nan, "worst": math.nan, "worst_seeds": []}
                continue
            order = np.argsort(vals[ok] if worse == "high" else -vals[ok])[::-1]
            seeds = np.array([r["seed"] for r in rows])[ok]
            per[key] = {
                "mean": float(vals[ok].mean()),
                "worst": float(vals[ok][order[0]]),
                "worst_seeds": [int(s) for s in seeds[order[:3]]],
            }
        summary[mode] = per
    return summary


def table(summary: dict[str, Any], modes: tuple[str, ...] = tuple(MODES)) -> str:
    lines = [
        "| mode | " + " | ".join(c[1] for c in COLUMNS) + " |",
        "|---|" + "---|" * len(COLUMNS),
    ]
    for mode in modes:
        cells = []
        for key, _label, fmt, _worse in COLUMNS:
            s = summary[mode][key]
            cells.append(
                f"{fmt.format(s['mean'])} (worst {fmt.format(s['worst'])}: {', '.join(map(str, s['worst_seeds']))})"
            )
        lines.append(f"| {mode} | " + " | ".join(cells) + " |")
    return "\n".join(lines)


def false_clear_line(rows: list[dict[str, Any]], mode: str = "fused") -> str:
    """Pooled false-clear bins split by what went out: "clear" tells the autopilot there is free water, "unknown"
    only that the daemon cannot vouch; both count against the goal of none."""
    total = sum(r[mode]["false_clear_bins"] for r in rows)
    sent_clear = sum(r[mode]["false_clear_sent_clear"] for r in rows)
    too_far = sum(r[mode].get("too_far_bins", 0) for r in rows)
    withheld = [r[mode]["ticks_withheld_with_solid"] for r in rows if "ticks_withheld_with_solid" in r[mode]]
    return (
        f'False-clear bins ({mode}, pooled): {total}, of which {sent_clear} went out "clear" and '
        f'{total - sent_clear} "unknown"; too-far bins (an obstacle sent beyond a solid returned nearer): {too_far}'
        + (f"; ticks withheld with a returned solid within 80 m: {sum(withheld)}." if withheld else ".")
    )


def false_tracks_line(rows: list[dict[str, Any]], mode: str = "fused") -> str:
    """Pooled false track-frames, all false positives over all matches: a scene with false tracks and no match has
    no ratio of its own, and the table's mean leaves it out."""
    fp = sum(r[mode]["false_positives"] for r in rows)
    matches = sum(r[mode]["matches"] for r in rows)
    unmatched = [r for r in rows if r[mode]["false_positives"] and not r[mode]["matches"]]
    pooled = f"{fp / matches:.2%}" if matches else "undefined (no match)"
    named = ", ".join(f"{r['seed']} ({r[mode]['false_positives']})" for r in unmatched)
    return (
        f"False track-frames ({mode}, pooled): {fp:,} false positives over {matches:,} matches, {pooled}; "
        f"{len(unmatched)} scenes with false positives and no match (left out of the mean above)"
        + (f": {named}." if named else ".")
    )


def on_quay_line(rows: list[dict[str, Any]], mode: str = "fused") -> str:
    """Pooled confirmed tracks on a quay (``tracks_on_quays``) and the scenes that had any."""
    ticks = sum(r[mode]["on_quay"]["track_ticks"] for r in rows)
    tracks = sum(r[mode]["on_quay"]["tracks"] for r in rows)
    worst = sorted(rows, key=lambda r: -r[mode]["on_quay"]["track_ticks"])[:3]
    named = ", ".join(
        f"{r['seed']} ({r[mode]['on_quay']['track_ticks']})" for r in worst if r[mode]["on_quay"]["tracks"]
    )
    scenes = sum(1 for r in rows if r[mode]["on_quay"]["tracks"])
    return (
        f"Confirmed tracks on a quay ({mode}, pooled; centre on the quay or within {QUAY_MARGIN_M} m off its face): "
        f"{tracks} tracks, {ticks} track-ticks, in {scenes} of {len(rows)} scenes"
        + (f"; most in {named}." if named else ".")
    )


def same_truth(rows: list[dict[str, Any]]) -> str:
    """Each mode's MOTA and IDF1 on one truth (every vessel either sensor returned) and the scenes where fused is
    above and below each sensor alone: whether fusing helps, which the per-mode table cannot say."""
    fused = np.array([r["fused"]["mota_all_returned"] for r in rows])
    parts = []
    for mode in ("lidar", "radar"):
        alone = np.array([r[mode]["mota_all_returned"] for r in rows])
        idf1 = np.nanmean([r[mode]["idf1_all_returned"] for r in rows])
        parts.append(
            f"{mode} alone MOTA {np.nanmean(alone):.4f} (worst {np.nanmin(alone):.3f}), IDF1 {idf1:.3f}; "
            f"fused above it in {int((fused > alone).sum())} scenes, below in {int((fused < alone).sum())}"
        )
    idf1 = np.nanmean([r["fused"]["idf1_all_returned"] for r in rows])
    return (
        f"Scored on one truth (every vessel either sensor returned): fused MOTA {np.nanmean(fused):.4f} "
        f"(worst {np.nanmin(fused):.3f}), IDF1 {idf1:.3f}; " + "; ".join(parts) + "."
    )


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    group = ap.add_mutually_exclusive_group()
    group.add_argument("--train", help="tuning seeds, e.g. 1-12 (1-100): printed, never saved")
    group.add_argument("--seeds", help="particular seeds, e.g. 1007,1033: printed, never saved")
    ap.add_argument("--seconds", type=float, default=SECONDS, help="scene length (default 60 s)")
    ap.add_argument("--modes", default=",".join(MODES), help="modes to run with --train/--seeds (default all)")
    ap.add_argument("--workers", type=int, default=min(2, os.cpu_count() or 1))
    args = ap.parse_args()
    if args.train:
        seeds = _seeds(args.train)
        if any(s not in TRAINING for s in seeds):
            ap.error("--train takes seeds 1-100 only: 1001-1100 are held out")
    elif args.seeds:
        seeds = _seeds(args.seeds)
    else:
        seeds = list(HELD_OUT)
    held_out = not args.train and not args.seeds
    modes = tuple(m for m in args.modes.split(",") if m)
    if any(m not in MODES for m in modes) or not modes:
        ap.error(f"--modes takes a comma list of {', '.join(MODES)}")
    if held_out and set(modes) != set(MODES):
        ap.error("the held-out run saves every mode: --modes only with --train or --seeds")
    t0 = time.perf_counter()
    rows = []
    with ProcessPoolExecutor(max_workers=args.workers) as pool:
        for r in pool.map(run_scene, seeds, [args.seconds] * len(seeds), [modes] * len(seeds)):
            rows.append(r)
            cells = [
                f"{m} MOTA {f['mota']:.3f} IDF1 {f['idf1']:.3f} FP/match {f['false_track_frames']:.1%} "
                f"false clear {f['false_clear_bins']} false obstacle {f['false_obstacle_share']:.2%} "
                f"id switches {f['id_switches']} on quay {f['on_quay']['track_ticks']}"
                for m, f in ((m, r[m]) for m in modes)
            ]
            print(f"seed {r['seed']}: " + " | ".join(cells) + f" | {r['description']}", flush=True)
    summary = summarise(rows, modes)
    text = table(summary, modes)
    print(text)
    if set(modes) == set(MODES):
        print(same_truth(rows))
    for mode in modes:
        print(false_clear_line(rows, mode))
        print(false_tracks_line(rows, mode))
        print(on_quay_line(rows, mode))
        print(by_hull_line(rows, mode))
    print(f"{len(rows)} scenes in {time.perf_counter() - t0:.0f} s")
    if held_out:
        save("heldout", {"summary": summary, "scenes": rows}, markdown(summary, rows, args.seconds))


def markdown(summary: dict[str, Any], rows: list[dict[str, Any]], seconds: float) -> str:
    """The committed record: the summary table, then one line per scene so a bad one can be found and replayed."""
    seeds = [r["seed"] for r in rows]
    lines = [
        f"Held-out scenes random:{min(seeds)} .. random:{max(seeds)} ({len(rows)} scenes, {seconds:.0f} s each), "
        "simulated to captures and replayed through the daemon; `python bench/heldout.py`.",
        "Mean over the scenes, the worst scene's figure and the three worst seeds (replay one with "
        f"`usv-tracker simulate --scene random:SEED --seconds {seconds:.0f} --write DIR`).",
        "",
        table(summary),
        "",
        "Each mode above is scored on the vessels its own sensors returned. " + same_truth(rows),
        "",
        by_hull_line(rows) + " " + by_hull_line(rows, "lidar"),
        "",
        " ".join(false_clear_line(rows, mode) for mode in MODES),
        "",
        " ".join(false_tracks_line(rows, mode) for mode in MODES),
        "",
        " ".join(on_quay_line(rows, mode) for mode in MODES),
        "",
        "Per scene (fused; LiDAR-only and radar-only MOTA beside):",
        "",
        "| seed | MOTA | IDF1 | false track-frames | false-clear bins (sent clear) / with a solid | "
        "false-obstacle bins | held obstacle bins on an unreturned solid | track-ticks on a quay (tracks) | "
        "LiDAR MOTA | radar MOTA | the day |",
        "|---|---|---|---|---|---|---|---|---|---|---|",
    ]
    for r in rows:
        f = r["fused"]
        lines.append(
            f"| {r['seed']} | {f['mota']:.3f} | {f['idf1']:.3f} | {f['false_track_frames']:.1%} | "
            f"{f['false_clear_bins']} ({f['false_clear_sent_clear']}) / {f['bins_with_solid']} | "
            f"{f['false_obstacle_bins']} | "
            f"{f['obstacle_unreturned_bins']} | "
            f"{f['on_quay']['track_ticks']} ({f['on_quay']['tracks']}) | "
            f"{r['lidar']['mota']:.3f} | {r['radar']['mota']:.3f} | {r['description'].removeprefix('day: ')} |"
        )
    return "\n".join(lines)


if __name__ == "__main__":
    main()
