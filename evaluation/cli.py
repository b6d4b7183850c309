"""`usv-tracker evaluate`: the command-line face of evaluate_run (exit 0, or 2 with a message for bad input)."""

from __future__ import annotations

import argparse
import json
import sys

from evaluation.defaults import DEFAULT_MATCH_DISTANCE_M, DEFAULT_MAX_DISTANCE_M, DEFAULT_MIN_RETURNS


def add_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("tracks", help="the run's --tracks-out file (JSON lines)")
    p.add_argument(
        "--truth",
        required=True,
        help="a `simulate --write` directory (truth.csv, returns.csv), a truth CSV, or a GNSS CSV (time,lat,lon)",
    )
    p.add_argument("--returns", help="returns.csv to use (default: the one in the truth directory)")
    p.add_argument(
        "--match-distance",
        type=float,
        default=DEFAULT_MATCH_DISTANCE_M,
        help="m; a track matches a vessel whose hull footprint its centre lies within "
        f"(default {DEFAULT_MATCH_DISTANCE_M:g})",
    )
    p.add_argument(
        "--max-distance",
        type=float,
        default=DEFAULT_MAX_DISTANCE_M,
        help=f"m; the run's [output] max_distance_m (default {DEFAULT_MAX_DISTANCE_M:g})",
    )
    p.add_argument(
        "--min-returns",
        type=int,
        default=DEFAULT_MIN_RETURNS,
        help=f"returns in a 0.1 s window that make a vessel one to track (default {DEFAULT_MIN_RETURNS})",
    )
    p.add_argument("--warmup", type=float, default=0.0, help="s after the first tick that are not scored")
    p.add_argument("--time-offset", type=float, help="s, truth time - tick t (default: found from the files)")
    p.add_argument("--reference-radius", type=float, default=0.0, help="m, a GNSS reference boat's hull as a disc")
    p.add_argument(
        "--sensors",
        default="lidar,radar",
        help="the sensors the run had (lidar, radar or both, comma-separated): only their returns count",
    )
    p.add_argument("--json", action="store_true", help="print the result as JSON")


def run(args: argparse.Namespace) -> int:
    from evaluation.api import evaluate_run  # only here: the daemon's own commands never load the evaluation
    from evaluation.errors import EvaluationError

    try:
        result = evaluate_run(
            args.truth,
            args.tracks,
            returns=args.returns,
            match_distance_m=args.match_distance,
            max_distance_m=args.max_distance,
            min_returns=args.min_returns,
            warmup_s=args.warmup,
            time_offset_s=args.time_offset,
            reference_radius_m=args.reference_radius,
            sensors=[x.strip() for x in args.sensors.split(",") if x.strip()],
        )
    except EvaluationError as exc:
        print(f"usv-tracker evaluate: {exc}", file=sys.stderr)
        return 2
    if args.json:
        print(json.dumps(result.to_dict(), indent=2, allow_nan=False))
    else:
        print(result.to_text())
    return 0
