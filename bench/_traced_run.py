"""`usv-tracker` under tracemalloc, for the soak's diagnostic run (`bench/soak.py --trace`).

    python -m bench._traced_run DIR run --lidar ...     # the arguments after DIR are usv-tracker's

Each SIGUSR1 writes a snapshot of the live allocations, DIR/snapshot-N.pickle, then DIR/snapshot-N.done (the file
is complete once that exists). Tracing costs the daemon a few times its allocation time: never measure RSS or cycle
time in such a run, only where the memory goes.
"""

from __future__ import annotations

import signal
import sys
import tracemalloc
from pathlib import Path

FRAMES = 12  # deep enough to see which of the daemon's calls a numpy or pymavlink allocation came from


def main(argv: list[str]) -> int:
    out = Path(argv[0])
    out.mkdir(parents=True, exist_ok=True)
    tracemalloc.start(FRAMES)
    taken = 0

    def dump(_signum: int, _frame: object) -> None:
        nonlocal taken
        taken += 1
        tracemalloc.take_snapshot().dump(str(out / f"snapshot-{taken}.pickle"))
        (out / f"snapshot-{taken}.done").touch()

    signal.signal(signal.SIGUSR1, dump)
    from daemon.cli import main as cli_main

    return cli_main(argv[1:])


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
