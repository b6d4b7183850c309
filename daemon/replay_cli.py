"""`usv-tracker replay DIR|FILES [--speed N|--fast] [--to URL [--pose tlog|live]] [--tracks-out FILE]`."""

from __future__ import annotations

import argparse
import contextlib
import logging
import math
import sys
from pathlib import Path

from daemon.view.options import ViewError, add_view_arguments, open_view

log = logging.getLogger("usv-tracker")


def _speed(text: str) -> float:
    try:
        value = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"not a number: {text!r}") from None
    if not (math.isfinite(value) and value > 0):
        raise argparse.ArgumentTypeError(f"must be a positive factor of real time, got {text}")
    return value


def add_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument(
        "recording",
        nargs="+",
        metavar="DIR|FILE",
        help="a recording directory (run --record, simulate --write), or its files: .pcap/.pcapng LiDAR, .dat radar "
        "(with its .times sidecar), .tlog autopilot, .cfg chirp profile",
    )
    pace = p.add_mutually_exclusive_group()
    pace.add_argument("--speed", type=_speed, default=1.0, metavar="N", help="times real time (default 1)")
    pace.add_argument("--fast", action="store_true", help="as fast as the CPU allows (the output is the same)")
    p.add_argument(
        "--to",
        metavar="URL",
        help="play into a live autopilot at the recorded pace, e.g. udpout:127.0.0.1:14550 or tcp:127.0.0.1:5762",
    )
    p.add_argument(
        "--pose",
        choices=("tlog", "live"),
        default="tlog",
        help="with --to: the own boat's pose from the recording's .tlog (default) or from the live autopilot",
    )
    p.add_argument("--tracks-out", metavar="FILE", help="write one JSON object per tick to this file")
    p.add_argument("--config", type=Path, help="TOML config (default: the recording's, else the installed one)")
    p.add_argument("--no-lidar", action="store_true", help="replay the radar only")
    p.add_argument("--no-radar", action="store_true", help="replay the LiDAR only")
    p.add_argument("--seconds", type=float, default=None, help="stop after this many seconds of data")
    p.add_argument("--quiet", action="store_true", help="no progress bar (there is none when stderr is no terminal)")
    add_view_arguments(p)


def _check(args: argparse.Namespace) -> str | None:
    """What is wrong with the combination of flags, or None."""
    if args.to:
        if args.fast or args.speed != 1.0:
            return "--to plays at the recorded pace: an autopilot takes OBSTACLE_DISTANCE at 10 Hz, not faster"
    elif args.pose == "live":
        return "--pose live takes the poses from the autopilot of --to URL"
    if args.no_lidar and args.no_radar:
        return "--no-lidar and --no-radar leave nothing to replay"
    return None


def run(args: argparse.Namespace) -> int:
    from daemon.config_schema import ConfigError
    from daemon.recording import RecordingError, data_end, find_recording, replay_config
    from daemon.replay import ReplayOptions, replay
    from daemon.replay_link import LinkError, autopilot_link, live_ego
    from daemon.replay_progress import ProgressBar, logs_above_bar, summary_line, wants_bar

    problem = _check(args)
    if problem is not None:
        log.error("%s", problem)
        return 2
    try:
        rec = find_recording(args.recording)
        config = replay_config(
            rec, args.tracks_out, lidar=not args.no_lidar, radar=not args.no_radar, config_path=args.config
        )
    except RecordingError as exc:
        log.error("%s", exc)
        return 2
    except ConfigError as exc:
        log.error("configuration rejected: %s", "; ".join(exc.problems))
        return 2
    if not (config.lidar.enabled or config.radar.enabled):
        log.error("nothing to replay: the recording's only sensor is switched off")
        return 2
    live = args.pose == "live"
    try:
        view = open_view(args)
    except ViewError as exc:
        log.error("%s", exc)
        return 2
    bar = wants_bar(sys.stderr, args.quiet)
    options = ReplayOptions(
        speed=None if args.fast else args.speed,
        duration_s=args.seconds,
        tlog=None if live or rec.tlog is None else str(rec.tlog),
        progress=ProgressBar(data_end(rec, config), args.seconds) if bar else None,
        view=view,
    )
    try:
        with contextlib.ExitStack() as stack:
            if view is not None:
                stack.callback(view.close)
            if args.to:
                link = stack.enter_context(autopilot_link(config, args.to, live))
                options.publisher = link
                options.live_ego = live_ego(link) if live else None
            stack.enter_context(logs_above_bar(bar))
            summary = replay(config, options)
    except (OSError, ValueError, LinkError) as exc:
        log.error("cannot replay: %s", exc)
        return 2
    log.debug("replay: %s", summary.details())
    print(summary_line(summary, args.tracks_out), file=sys.stderr, flush=True)
    if summary.tracks_out_failed is not None:
        log.error("the tracks file %s is cut short: %s", args.tracks_out, summary.tracks_out_failed)
        return 2
    return 130 if summary.interrupted else 0
