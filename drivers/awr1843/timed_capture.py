"""The project's own time-stamped radar capture: TI's raw ``.dat`` bytes plus a ``.times`` sidecar.

TI's visualizer saves the data port's bytes and nothing else, so a replay can only pace frames by the nominal frame
period. Recording on the boat we know when each chunk of bytes arrived; the sidecar keeps that, so a replay puts
every frame at the time the daemon saw it. The ``.dat`` stays byte-identical to what TI's tools read.

Sidecar format: text, one line per chunk, ``<byte offset> <host time in s>``, offsets increasing; a line starting
with ``#`` is a comment.
"""

from __future__ import annotations

import logging
from collections.abc import Iterator
from pathlib import Path
from typing import IO

import numpy as np

log = logging.getLogger(__name__)


def sidecar_path(dat_path: str | Path) -> Path:
    return Path(str(dat_path) + ".times")


class TimedCaptureWriter:
    """Append chunks of data-port bytes with the host time they arrived."""

    def __init__(self, dat_path: str | Path) -> None:
        self.path = Path(dat_path)
        self._dat: IO[bytes] = self.path.open("wb")
        self._times: IO[str] = sidecar_path(self.path).open("w", encoding="ascii")
        self._times.write("# usv-tracker radar capture: byte offset, host time (s) of the chunk starting there\n")
        self._offset = 0

    def write(self, chunk: bytes, host_time: float) -> None:
        if not chunk:
            return
        self._times.write(f"{self._offset} {host_time:.6f}\n")
        self._dat.write(chunk)
        self._offset += len(chunk)

    def flush(self) -> None:
        self._dat.flush()
        self._times.flush()

    def close(self) -> None:
        self._dat.close()
        self._times.close()

    def __enter__(self) -> TimedCaptureWriter:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()


def read_sidecar(dat_path: str | Path) -> tuple[np.ndarray, np.ndarray] | None:
    """(offsets, times) from the sidecar, or None when there is none (a plain TI capture)."""
    side = sidecar_path(dat_path)
    if not side.exists():
        return None
    rows = []
    for n, line in enumerate(side.read_text(encoding="ascii", errors="replace").splitlines(), 1):
        if not line.strip() or line.startswith("#"):
            continue
        parts = line.split()
        try:
            rows.append((int(parts[0]), float(parts[1])))
        except (ValueError, IndexError):
            log.warning("%s line %d: not '<offset> <time>': %r (skipped)", side, n, line[:60])
    if not rows:
        return None
    arr = np.array(rows)
    order = np.argsort(arr[:, 0], kind="stable")
    return arr[order, 0].astype(np.int64), arr[order, 1]


def timed_chunks(dat_path: str | Path) -> Iterator[tuple[bytes, float]]:
    """The capture's bytes in the chunks they were recorded in, each with its host time."""
    side = read_sidecar(dat_path)
    if side is None:
        raise FileNotFoundError(f"{sidecar_path(dat_path)}: no time sidecar")
    offsets, times = side
    data = Path(dat_path).read_bytes()
    ends = np.append(offsets[1:], len(data))
    for start, end, t in zip(offsets, ends, times, strict=True):
        if start < len(data):
            yield data[int(start) : int(end)], float(t)
