"""The `usv-tracker` command: run, replay, demo, simulate, decode, check-config, evaluate."""

from __future__ import annotations

import argparse
import logging
import math
import sys
from pathlib import Path
from typing import Any

from daemon.config import DEFAULT_CONFIG_PATH
from daemon.view.options import add_view_arguments

log = logging.getLogger("usv-tracker")

SCENE_HELP = (
    "harbour (default), crossing, container, crew_boat, fisher, radar_paper[:static|low|mid|high], dense, moorings, or "
    "random:SEED[:SECONDS], a whole harbour drawn from SEED (seeds 1-100 for tuning, 1001-1100 held out)"
)


def _setup_logging(verbose: bool) -> None:
    logging.basicConfig(
        level=logging.DEBUG if verbose else logging.INFO,
        format="%(asctime)s %(levelname)-7s %(name)s: %(message)s",
        datefmt="%H:%M:%S",
    )


def cmd_check_config(args: argparse.Namespace) -> int:
    from daemon.config import file_warnings, load_config, secret_warnings
    from daemon.config_schema import ConfigError

    try:
        config = load_config(args.file, check_files=True)
    except ConfigError as exc:
        print(f"{args.file}: {len(exc.problems)} problem(s):", file=sys.stderr)
        for problem in exc.problems:
            print(f"  {problem}", file=sys.stderr)
        return 2
    warnings = file_warnings(config) + secret_warnings(config)
    for warning in warnings:
        print(f"  warning: {warning}", file=sys.stderr)
    print(f"{args.file}: OK" + (f" with {len(warnings)} warning(s)" if warnings else ""))
    return 0


def cmd_decode(args: argparse.Namespace) -> int:
    from daemon.decode import decode_file

    return decode_file(Path(args.file), as_json=args.json, model=args.model, profile=args.profile)


def _run_overrides(args: argparse.Namespace) -> dict[str, object]:
    overrides: dict[str, object] = {}
    for flag, key in (
        ("lidar", "lidar.source"),
        ("radar_cli", "radar.cli"),
        ("radar_data", "radar.data"),
        ("radar_profile", "radar.profile"),
        ("mavlink", "mavlink.url"),
        ("tracks_out", "output.tracks_out"),
        ("record", "output.record_dir"),
    ):
        value = getattr(args, flag, None)
        if value is not None:
            overrides[key] = value
    if getattr(args, "no_radar", False):
        overrides["radar.enabled"] = False
    if getattr(args, "no_lidar", False):
        overrides["lidar.enabled"] = False
    return overrides


def _open_view(args: argparse.Namespace) -> tuple[Any, int | None]:
    """(the view the options ask for or None, None), or (None, 2) after saying why it cannot be had."""
    from daemon.view.options import ViewError, open_view

    try:
        return open_view(args), None
    except ViewError as exc:
        log.error("%s", exc)
        return None, 2


def cmd_run(args: argparse.Namespace) -> int:
    from daemon.config import load_config
    from daemon.config_schema import ConfigError
    from daemon.runner import run_daemon

    path = args.config
    if path is None and DEFAULT_CONFIG_PATH.exists():
        path = DEFAULT_CONFIG_PATH
    try:
        config = load_config(path, _run_overrides(args))
    except ConfigError as exc:
        log.error("configuration rejected: %s", "; ".join(exc.problems))
        return 2
    view, failed = _open_view(args)
    if failed is not None:
        return failed
    try:
        return run_daemon(config, fast=args.fast, duration_s=args.seconds, view=view)
    finally:
        if view is not None:
            view.close()


def cmd_replay(args: argparse.Namespace) -> int:
    from daemon.replay_cli import run

    return run(args)


def _scene_ready(name: str, seconds: float, out_dir: str | None) -> bool:
    """Check what a simulation needs before any port or file is opened: a scene of that name, a positive duration
    and a directory that can be written. Prints what a ``random:SEED`` scene holds (it is known by its seed alone).
    False, with the problem logged, when one of them is not so."""
    from simulator.scenarios import get_scenario

    if not (math.isfinite(seconds) and seconds > 0):
        log.error("--seconds %s: must be a positive number of seconds", seconds)
        return False
    try:
        scene = get_scenario(name)
    except ValueError as exc:
        log.error("%s", exc)
        return False
    if out_dir is not None:
        try:
            Path(out_dir).mkdir(parents=True, exist_ok=True)
        except OSError as exc:
            log.error("cannot write to %s: %s", out_dir, exc.strerror or exc)
            return False
    if name.partition(":")[0] != "random":
        return True
    print(scene.description, flush=True)
    if seconds > scene.duration:
        log.warning(
            "%s is drawn collision-free for %.0f s; after that vessels hold their last leg and may meet "
            "(random:SEED:SECONDS draws it for longer)",
            name,
            scene.duration,
        )
    return True


def cmd_demo(args: argparse.Namespace) -> int:
    from daemon.demo import run_demo

    if not _scene_ready(args.scenario, args.seconds, args.out):
        return 2
    view, failed = _open_view(args)
    if failed is not None:
        return failed
    try:
        return run_demo(
            seconds=args.seconds, scenario=args.scenario, out_dir=Path(args.out), live_view=not args.quiet, view=view
        )
    finally:
        if view is not None:
            view.close()


def cmd_simulate(args: argparse.Namespace) -> int:
    from simulator.run import run_simulator_cli

    if not _scene_ready(args.scenario, args.seconds, args.write):
        return 2
    return run_simulator_cli(args)


def cmd_evaluate(args: argparse.Namespace) -> int:
    from evaluation.cli import run

    return run(args)


def build_parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(prog="usv-tracker", description=__doc__)
    p.add_argument("-v", "--verbose", action="store_true", help="debug logging")
    sub = p.add_subparsers(dest="command", required=True)

    run = sub.add_parser("run", help="run the daemon (sensors -> tracks -> MAVLink)")
    run.add_argument("--config", type=Path, help=f"TOML file (default {DEFAULT_CONFIG_PATH} if it exists)")
    run.add_argument("--lidar", help="LiDAR source: udp://HOST:PORT or pcap://FILE")
    run.add_argument("--radar-cli", help="radar CLI port: serial:///dev/ttyACM0?baud=115200 ('' for none)")
    run.add_argument("--radar-data", help="radar data: serial:///dev/ttyACM1?baud=921600 or file://DUMP.dat")
    run.add_argument("--radar-profile", help="TI chirp .cfg sent through the CLI port")
    run.add_argument("--no-radar", action="store_true", help="run LiDAR-only")
    run.add_argument("--no-lidar", action="store_true", help="run radar-only")
    run.add_argument("--mavlink", help="pymavlink connection string, e.g. udpout:127.0.0.1:14550 or /dev/ttyAMA0")
    run.add_argument("--tracks-out", help="write one JSON object per tick to this file")
    run.add_argument("--record", help="record raw sensor captures into this directory")
    run.add_argument("--fast", action="store_true", help="replay captures on the data's clock, as fast as possible")
    run.add_argument("--seconds", type=float, default=None, help="stop after this many seconds (default: run on)")
    add_view_arguments(run)
    run.set_defaults(func=cmd_run)

    from daemon.replay_cli import add_arguments as add_replay_arguments

    rep = sub.add_parser(
        "replay",
        help="replay a recording through the daemon: at N x real time, as fast as possible, or into a live autopilot",
    )
    add_replay_arguments(rep)
    rep.set_defaults(func=cmd_replay)

    demo = sub.add_parser("demo", help="built-in demo: simulator plays sensors and autopilot, the real daemon runs")
    demo.add_argument("--seconds", type=float, default=30.0)
    demo.add_argument("--scene", "--scenario", dest="scenario", default="harbour", help=SCENE_HELP)
    demo.add_argument("--out", default="demo-output", help="directory for the summary picture and logs")
    demo.add_argument("--quiet", action="store_true", help="no live view, summary only")
    add_view_arguments(demo)
    demo.set_defaults(func=cmd_demo)

    sim = sub.add_parser("simulate", help="play sensors and autopilot over loopback, or write capture files")
    sim.add_argument("--scene", "--scenario", dest="scenario", default="harbour", help=SCENE_HELP)
    sim.add_argument("--seconds", type=float, default=30.0)
    sim.add_argument("--lidar-port", type=int, default=2368)
    sim.add_argument("--mavlink", default="udpin:127.0.0.1:14550", help="where the simulated autopilot listens")
    sim.add_argument("--write", metavar="DIR", help="write capture files (pcap, .dat, .tlog, truth.csv) instead")
    sim.add_argument("--seed", type=int, default=0, help="seed of the sensors' noise (and of the scene, unless named)")
    sim.set_defaults(func=cmd_simulate)

    dec = sub.add_parser("decode", help="decode a capture: a VLP-16 pcap/pcapng or an AWR1843 data-port dump")
    dec.add_argument("file")
    dec.add_argument("--json", action="store_true", help="one JSON object per line")
    dec.add_argument("--model", choices=["auto", "VLP16"], default="auto", help="VLP16: force VLP-16 geometry")
    dec.add_argument("--profile", help="radar .cfg (needed for SDK 2.x Doppler)")
    dec.set_defaults(func=cmd_decode)

    chk = sub.add_parser(
        "check-config", help="check a TOML config and the files it names (pcap, radar cfg); names each problem and why"
    )
    chk.add_argument("file", type=Path)
    chk.set_defaults(func=cmd_check_config)

    from evaluation.cli import add_arguments

    ev = sub.add_parser("evaluate", help="score a run's --tracks-out against simulator truth or a GNSS reference")
    add_arguments(ev)
    ev.set_defaults(func=cmd_evaluate)
    return p


def main(argv: list[str] | None = None) -> int:
    args = build_parser().parse_args(argv)
    _setup_logging(args.verbose)
    try:
        return int(args.func(args) or 0)
    except KeyboardInterrupt:
        return 130
    except BrokenPipeError:  # `usv-tracker decode x.pcap | head`
        return 0


if __name__ == "__main__":
    sys.exit(main())
