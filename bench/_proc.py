"""What a running process holds, read from /proc: resident memory, open descriptors, threads (Linux only)."""

from __future__ import annotations

import os
import statistics
import threading
import time
from dataclasses import asdict, dataclass
from typing import Any


@dataclass(frozen=True)
class ProcSample:
    t: float  # s since the sampler started
    rss_kb: int  # VmRSS
    fds: int  # entries of /proc/PID/fd
    threads: int  # Threads


def sample(pid: int, t: float = 0.0) -> ProcSample | None:
    """One sample of ``pid``; None once the process is gone (or a zombie: it has no VmRSS line any more)."""
    try:
        with open(f"/proc/{pid}/status", encoding="ascii") as f:
            fields = dict(line.split(":", 1) for line in f if ":" in line)
        fds = len(os.listdir(f"/proc/{pid}/fd"))
    except (FileNotFoundError, ProcessLookupError):
        return None
    if "VmRSS" not in fields:
        return None
    return ProcSample(t, int(fields["VmRSS"].split()[0]), fds, int(fields["Threads"]))


class Sampler(threading.Thread):
    """Samples ``pid`` every ``period_s`` into ``samples`` until stopped or the process ends.

    Ticks are on an absolute schedule, so the samples stay one per period over an hour instead of drifting by the
    time each read takes.
    """

    def __init__(self, pid: int, period_s: float = 1.0) -> None:
        super().__init__(name=f"sampler-{pid}", daemon=True)
        self.pid = pid
        self.period_s = period_s
        self.samples: list[ProcSample] = []
        self.t0 = time.monotonic()
        self._stop_event = threading.Event()

    def run(self) -> None:
        k = 0
        while not self._stop_event.is_set():
            s = sample(self.pid, time.monotonic() - self.t0)
            if s is None:
                return
            self.samples.append(s)
            k += 1
            self._stop_event.wait(max(0.0, self.t0 + k * self.period_s - time.monotonic()))

    def stop(self) -> None:
        self._stop_event.set()
        self.join(timeout=2.0)

    def at(self, t: float) -> ProcSample | None:
        """The first sample at or after ``t`` s."""
        return next((s for s in self.samples if s.t >= t), None)

    def as_json(self) -> list[dict[str, Any]]:
        return [asdict(s) for s in self.samples]


def summarise(samples: list[ProcSample], after_s: float, window_s: float = 60.0) -> dict[str, Any]:
    """The soak's figures: RSS at ``after_s`` and at the end, the growth between, maxima, first/last/max counts.

    A numpy-heavy process's RSS swings by tens of MB from one second to the next (arrays of a busy revolution
    allocated and given back), so two single samples can show a growth or a shrink that is neither. Besides them:
    the median and the minimum over ``window_s`` from ``after_s`` and over the last ``window_s`` (the minimum is the
    floor between the swings, what the process keeps), and a fitted slope.
    """
    if not samples:
        return {}
    ref = next((s for s in samples if s.t >= after_s), samples[-1])
    last = samples[-1]
    tail = [s for s in samples if s.t >= ref.t]
    first_w = [s.rss_kb / 1024 for s in tail if s.t < ref.t + window_s]
    last_w = [s.rss_kb / 1024 for s in tail if s.t > last.t - window_s]
    return {
        "rss_ref_window_median_mb": statistics.median(first_w),
        "rss_end_window_median_mb": statistics.median(last_w),
        "rss_ref_window_min_mb": min(first_w),
        "rss_end_window_min_mb": min(last_w),
        "samples": len(samples),
        "rss_first_mb": samples[0].rss_kb / 1024,
        "rss_ref_t_s": ref.t,
        "rss_ref_mb": ref.rss_kb / 1024,
        "rss_end_mb": last.rss_kb / 1024,
        "rss_growth_mb": (last.rss_kb - ref.rss_kb) / 1024,
        "rss_max_mb": max(s.rss_kb for s in samples) / 1024,
        # the slope of a line fitted through the samples after the reference: one late spike does not make a trend
        "rss_slope_mb_per_h": _slope(tail) * 3600 / 1024,
        "fds": {**_counts([s.fds for s in samples]), "ref": ref.fds},
        "threads": {**_counts([s.threads for s in samples]), "ref": ref.threads},
    }


def rss_windows(samples: list[ProcSample], n: int = 6) -> list[tuple[float, float, float, float]]:
    """The run cut into ``n`` equal windows: (start s, end s, minimum MB, median MB) of each, to show a trend
    (a leak raises every window's floor) apart from the swings."""
    if not samples:
        return []
    t0 = samples[0].t
    span = (samples[-1].t - t0) / n
    out = []
    for k in range(n):
        a, b = t0 + k * span, t0 + (k + 1) * span
        w = [s.rss_kb / 1024 for s in samples if a <= s.t < b or (k == n - 1 and s is samples[-1])]
        if w:
            out.append((a, b, min(w), statistics.median(w)))
    return out


def _counts(values: list[int]) -> dict[str, int]:
    return {"first": values[0], "last": values[-1], "max": max(values), "min": min(values)}


def _slope(samples: list[ProcSample]) -> float:
    """Least-squares kB per second."""
    n = len(samples)
    if n < 2:
        return 0.0
    mt = sum(s.t for s in samples) / n
    mr = sum(s.rss_kb for s in samples) / n
    var = sum((s.t - mt) ** 2 for s in samples)
    return sum((s.t - mt) * (s.rss_kb - mr) for s in samples) / var if var > 0 else 0.0


def udp_socket(port: int, ip: str = "127.0.0.1") -> tuple[int, int] | None:
    """(bytes waiting in its receive queue, datagrams the kernel dropped for a full buffer) of the IPv4 UDP socket
    bound to ``ip``:``port``, from /proc/net/udp; None when there is none."""
    a, b, c, d = (int(x) for x in ip.split("."))
    local = f"{d:02X}{c:02X}{b:02X}{a:02X}:{port:04X}"  # little-endian address, as the kernel prints it on x86/ARM
    with open("/proc/net/udp", encoding="ascii") as f:
        next(f)
        for line in f:
            cols = line.split()
            if cols[1] == local:
                return int(cols[4].split(":")[1], 16), int(cols[-1])
    return None
