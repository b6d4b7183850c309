"""What a person watching `usv-tracker replay` sees: a progress bar on stderr, then one summary line.

The bar counts seconds of DATA replayed, with the pace in times real time and the time left; it is drawn only when
stderr is a terminal (and not with --quiet), so logs, pipes and CI get the summary line alone. Log lines written
while it is drawn go above it instead of through it.
"""

from __future__ import annotations

import contextlib
import logging
import os
import shutil
import sys
from collections.abc import Iterator
from typing import IO

from tqdm import tqdm
from tqdm.contrib.logging import logging_redirect_tqdm

from daemon.replay import ReplaySummary

BAR_FORMAT = "replay {percentage:3.0f}%|{bar}| {n:.1f}/{total:.1f} s of data [{elapsed}<{remaining}{postfix}]"
# Without a known end (a radar dump without its sidecar) there is no percentage and no time left.
OPEN_FORMAT = "replay {n:.1f} s of data [{elapsed}{postfix}]"
REFRESH_S = 0.25  # a bar redrawn 10 times a second costs a 20x replay more than it tells


def wants_bar(stream: IO[str], quiet: bool) -> bool:
    return not quiet and stream.isatty()


class ProgressBar:
    """ReplayProgress (daemon/replay.py) drawn with tqdm; ``end``: where the data ends (None: unknown),
    ``duration_s``: the data seconds the replay is limited to (None: all)."""

    def __init__(self, end: float | None, duration_s: float | None = None, stream: IO[str] | None = None) -> None:
        self.end = end
        self.duration_s = duration_s
        self.stream = stream if stream is not None else sys.stderr
        self._bar: tqdm | None = None
        self._shown = 0.0

    def start(self, t0: float) -> None:
        total = None if self.end is None else max(self.end - t0, 0.0)
        if self.duration_s is not None:
            total = self.duration_s if total is None else min(total, self.duration_s)
        size = _unset_terminal_size(self.stream)
        self._bar = tqdm(
            total=total,
            file=self.stream,
            bar_format=BAR_FORMAT if total else OPEN_FORMAT,
            mininterval=REFRESH_S,
            dynamic_ncols=size is None,  # follows a resized window
            ncols=size[0] if size else None,
            nrows=size[1] if size else None,
            leave=False,  # the summary line takes its place
        )
        self._bar.set_postfix_str("?x real time", refresh=False)

    def advance(self, data_seconds: float) -> None:
        bar = self._bar
        if bar is None:
            return
        step = data_seconds - self._shown
        self._shown = data_seconds
        rate = bar.format_dict.get("rate")  # tqdm's smoothed n per second: data seconds per wall second
        if rate:
            bar.set_postfix_str(f"{rate:.1f}x real time", refresh=False)
        if bar.total is not None and bar.n + step > bar.total:
            bar.total = bar.n + step  # the data ran a tick past the estimate: never more than 100 %
        bar.update(step)

    def close(self) -> None:
        if self._bar is not None:
            self._bar.close()
            self._bar = None


def _unset_terminal_size(stream: IO[str]) -> tuple[int, int] | None:
    """None when the terminal tells its size; else ($COLUMNS or 80, $LINES or 24). A terminal whose size was never
    set (a pty opened by a program, `script` without a terminal around it) says 0 x 0, and tqdm then draws nothing."""
    try:
        size = os.get_terminal_size(stream.fileno())
        if size.columns > 0 and size.lines > 0:
            return None
    except (OSError, ValueError):
        pass
    fallback = shutil.get_terminal_size((80, 24))
    return fallback.columns, fallback.lines


@contextlib.contextmanager
def logs_above_bar(enabled: bool) -> Iterator[None]:
    """While the bar is drawn, log lines are written above it (through tqdm) rather than through it."""
    if not enabled:
        yield
        return
    with logging_redirect_tqdm(loggers=[logging.getLogger()]):
        yield


def summary_line(summary: ReplaySummary, tracks_out: str | None) -> str:
    """One line for the end of a replay: data and wall seconds, their ratio, ticks and what was written."""
    where = f" written to {tracks_out}" if tracks_out else ", no --tracks-out"
    stopped = " (interrupted)" if summary.interrupted else ""
    return (
        f"replayed {summary.data_seconds:.1f} s of data in {summary.wall_seconds:.1f} s "
        f"({summary.ratio:.1f}x real time){stopped}: {summary.ticks} ticks, "
        f"{len(summary.track_ids)} tracks ({len(summary.confirmed_ids)} confirmed){where}"
    )
