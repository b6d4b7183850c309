"""The live daemon for bench/load.py, in its own process, with its counters written out when it stops.

    python -m bench._load_daemon OUT.json run --lidar udp://... --radar-cli ... --mavlink ...
    # `usv-tracker run`'s flags

It starts exactly as `usv-tracker run` does live (daemon.runner: start_daemon, the start-up objects frozen out of the
garbage collector, run_live; logging as the CLI sets it up, stamped to the millisecond), touches OUT.json.ready once
everything is open, and on SIGTERM stops and writes what a bench needs and the health line does not carry: the LiDAR
source's own counters (packets taken, other senders' datagrams dropped, the sender it locked onto), the hand-over
buffers, the radar parser, and the time and duration of every cycle (the health line keeps only the last minute's
p50/p99).
"""

from __future__ import annotations

import dataclasses
import json
import logging
import signal
import sys
import time
from pathlib import Path
from typing import Any


def _plain(obj: Any) -> dict[str, Any]:
    items = dataclasses.asdict(obj) if dataclasses.is_dataclass(obj) else vars(obj)
    return {k: v for k, v in items.items() if isinstance(v, int | float | str | bool | type(None))}


def main(argv: list[str]) -> int:
    from daemon.cli import _run_overrides, _setup_logging, build_parser
    from daemon.config import load_config
    from daemon.runner import freeze_startup_objects, start_daemon

    out = Path(argv[0])
    args = build_parser().parse_args(argv[1:])
    _setup_logging(args.verbose)
    # the CLI's format to the millisecond, so the bench can tell a line of the loaded window from one just before it
    logging.basicConfig(
        force=True,
        level=logging.getLogger().level,
        format="%(asctime)s.%(msecs)03d %(levelname)-7s %(name)s: %(message)s",
        datefmt="%H:%M:%S",
    )
    config = load_config(args.config, _run_overrides(args))
    daemon = start_daemon(config)
    loop = daemon.loop
    cycles: list[tuple[float, float]] = []
    record = loop.stats.record

    def keep(duration_ms: float, stages: dict[str, float]) -> None:
        cycles.append((time.monotonic(), duration_ms))
        record(duration_ms, stages)

    loop.stats.record = keep  # type: ignore[method-assign]
    signal.signal(signal.SIGTERM, lambda *_: daemon.stop_event.set())
    freeze_startup_objects()
    out.with_suffix(".ready").touch()
    try:
        loop.run_live(daemon.stop_event)
    finally:
        daemon.stop()
    lidar, radar = daemon.sources.lidar, daemon.sources.radar
    figures = {
        "lidar_source": _plain(lidar.stats) if lidar is not None else None,
        "lidar_slot": _plain(loop.inputs.lidar.stats),
        "radar_queue": _plain(loop.inputs.radar.stats),
        "radar_parser": _plain(radar.stats.parser) if radar is not None else None,
        "rcvbuf_bytes": getattr(lidar, "rcvbuf_granted", None),
        "loop": {
            "cycles": loop.stats.cycles,
            "deadline_misses": loop.stats.deadline_misses,
            "sent": loop.sent,
            "withheld": loop.withheld,
            "failed_ticks": loop.failed_ticks,
        },
        "cycle_times": cycles,
    }
    out.write_text(json.dumps(figures))
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
