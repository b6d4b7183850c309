"""Offset between the autopilot's boot clock and the host monotonic clock, from MAVLink TIMESYNC exchanges.

Exchange (MAVLink TIMESYNC, id 111): we send ``tc1 = 0, ts1 = host ns``; the autopilot answers with ``ts1``
echoed and ``tc1`` = its own clock in ns since boot (ArduPilot takes it at packet receipt). With the reply's
host receive time ``rx``, the round trip is ``rtt = rx - ts1`` and, assuming a symmetric path,

    offset = tc1 - (ts1 + rx) / 2        (autopilot ns - host ns)

The link's latency is not symmetric when a serial buffer or a busy USB hub holds one direction, and those
delays show up as a longer round trip. So the estimate is the median offset of the lowest-RTT quarter of a
sliding window of samples (the NTP "minimum filter" idea): slow exchanges say little about the offset.

Reboots: the autopilot's ``time_boot_ms`` restarts from zero, so a boot time going backwards, or a boot time
that maps to a host time far from its receive time once synced, resets the estimate. Until enough samples
are in, callers fall back to the host receive time of each message (a few ms late, never wrong by seconds).

Not thread-safe: one reader thread owns an instance; other threads only read the plain attributes.
"""

from __future__ import annotations

import logging
from collections import deque

log = logging.getLogger(__name__)

NS_PER_S = 1_000_000_000
NS_PER_MS = 1_000_000
# time_boot_ms is a uint32: it wraps after 49.7 days up, while TIMESYNC's tc1 (ns, 64 bits) runs on. A boot time
# that falls back by more than half the range is that wrap, and is counted on, not taken for a reboot.
BOOT_MS_WRAP = 1 << 32


class TimeSync:
    """Estimate of ``offset_ns = autopilot boot clock - host monotonic clock`` (both in ns)."""

    def __init__(
        self,
        window: int = 32,
        min_samples: int = 3,
        max_rtt_s: float = 0.5,
        max_sample_age_s: float = 60.0,
        boot_backwards_tolerance_s: float = 0.5,
        future_tolerance_s: float = 0.2,
        past_tolerance_s: float = 3.0,
        outstanding: int = 16,
    ) -> None:
        if window < 1 or min_samples < 1:
            raise ValueError("window and min_samples must be >= 1")
        self.window = window
        self.min_samples = min(min_samples, window)
        self.max_rtt_ns = int(max_rtt_s * NS_PER_S)
        self.max_sample_age_ns = int(max_sample_age_s * NS_PER_S)
        self.boot_backwards_tolerance_ms = int(boot_backwards_tolerance_s * 1000)
        self.future_tolerance_ns = int(future_tolerance_s * NS_PER_S)
        self.past_tolerance_ns = int(past_tolerance_s * NS_PER_S)
        self._samples: deque[tuple[int, int, int]] = deque(maxlen=window)  # (rx_ns, rtt_ns, offset_ns)
        self._outstanding: deque[int] = deque(maxlen=outstanding)  # ts1 of our requests not yet answered
        self._last_boot_ms: int | None = None  # unwrapped (with _boot_wraps x BOOT_MS_WRAP)
        self._boot_wraps = 0
        self.offset_ns: int | None = None
        self.rtt_ns: int | None = None  # smallest round trip in the window
        self.resets = 0
        self.quiet = False  # resets not logged (the link is reporting two clocks on it)
        self.last_reset_reason = ""
        self.rejected = 0  # replies to nobody's request, or with an impossible round trip
        self.accepted = 0

    @property
    def synced(self) -> bool:
        return self.offset_ns is not None

    @property
    def n_samples(self) -> int:
        return len(self._samples)

    def reset(self, reason: str) -> None:
        """Forget the estimate (the autopilot rebooted or its clock jumped)."""
        self._samples.clear()
        self._outstanding.clear()
        self._last_boot_ms = None
        self._boot_wraps = 0
        self.offset_ns = None
        self.rtt_ns = None
        self.resets += 1
        self.last_reset_reason = reason
        if not self.quiet:  # the link says once a minute why the clock keeps jumping (two autopilots)
            log.info("timesync reset: %s", reason)

    # ------------------------------------------------------------------ exchanges
    def make_request(self, now_ns: int) -> tuple[int, int]:
        """(tc1, ts1) for an outgoing TIMESYNC request sent at host time ``now_ns``."""
        now_ns = int(now_ns)
        self._outstanding.append(now_ns)
        return 0, now_ns

    def on_reply(self, tc1: int, ts1: int, rx_ns: int) -> bool:
        """Feed a TIMESYNC reply (tc1 != 0) received at host ``rx_ns``; True if it became a sample."""
        if ts1 not in self._outstanding:
            # an answer to someone else's request (a GCS on the same network) or a stale duplicate
            self.rejected += 1
            return False
        self._outstanding.remove(ts1)
        rtt = rx_ns - ts1
        if tc1 <= 0 or rtt < 0 or rtt > self.max_rtt_ns:
            self.rejected += 1
            return False
        offset = tc1 - (ts1 + rx_ns) // 2
        if self.offset_ns is not None and abs(offset - self.offset_ns) > self.past_tolerance_ns:
            self.reset(f"TIMESYNC offset jumped by {(offset - self.offset_ns) / NS_PER_S:.3f} s")
            # the reset dropped our outstanding requests; this reply is still a valid sample
        self._samples.append((rx_ns, rtt, offset))
        self.accepted += 1
        self._update(rx_ns)
        return True

    def _update(self, now_ns: int) -> None:
        while self._samples and now_ns - self._samples[0][0] > self.max_sample_age_ns:
            self._samples.popleft()
        if len(self._samples) < self.min_samples:
            return
        by_rtt = sorted(self._samples, key=lambda s: s[1])
        best = by_rtt[: max(1, len(by_rtt) // 4)]
        offsets = sorted(s[2] for s in best)
        mid = len(offsets) // 2
        median = offsets[mid] if len(offsets) % 2 else (offsets[mid - 1] + offsets[mid]) // 2
        if self.offset_ns is None:
            log.info("timesync: offset %.6f s, rtt %.3f ms", median / NS_PER_S, by_rtt[0][1] / NS_PER_MS)
        self.offset_ns = median
        self.rtt_ns = by_rtt[0][1]

    # ------------------------------------------------------------------ stamping
    def unwrapped_ms(self, time_boot_ms: int, rx_ns: int) -> int:
        """A message's uint32 ``time_boot_ms`` carried past its wraps: synced, the wraps that put it nearest to
        where the offset (from TIMESYNC's 64-bit clock) expects it at ``rx_ns``, host ns; else those counted."""
        raw = int(time_boot_ms) % BOOT_MS_WRAP
        if self.offset_ns is not None:
            wraps = round(((rx_ns + self.offset_ns) / NS_PER_MS - raw) / BOOT_MS_WRAP)
            return raw + max(wraps, 0) * BOOT_MS_WRAP
        return raw + self._boot_wraps * BOOT_MS_WRAP

    def check_boot_time(self, time_boot_ms: int, rx_ns: int) -> bool:
        """Watch a message's ``time_boot_ms``; True (and state reset) on a reboot or a clock jump."""
        last = self._last_boot_ms
        raw = int(time_boot_ms) % BOOT_MS_WRAP
        time_boot_ms = self.unwrapped_ms(raw, rx_ns)
        if (
            self.offset_ns is None
            and last is not None
            and last % BOOT_MS_WRAP > BOOT_MS_WRAP - 60_000
            and raw < 60_000
            and time_boot_ms < last
        ):  # not synced: from the range's last minute to its first is the wrap
            self._boot_wraps += 1
            time_boot_ms += BOOT_MS_WRAP
        self._boot_wraps = time_boot_ms // BOOT_MS_WRAP
        if last is not None and time_boot_ms + self.boot_backwards_tolerance_ms < last:
            self.reset(f"autopilot boot time went back from {last} ms to {time_boot_ms} ms (reboot)")
            self._last_boot_ms = raw
            return True
        if self.offset_ns is not None:
            predicted = time_boot_ms * NS_PER_MS - self.offset_ns
            if predicted - rx_ns > self.future_tolerance_ns or rx_ns - predicted > self.past_tolerance_ns:
                self.reset(f"autopilot boot time {time_boot_ms} ms is {(predicted - rx_ns) / NS_PER_S:+.3f} s off")
                self._last_boot_ms = raw
                return True
        if last is None or time_boot_ms > last:
            self._last_boot_ms = time_boot_ms
        return False

    def to_host_ns(self, time_boot_ms: int, rx_ns: int) -> int:
        """Host monotonic ns of an autopilot ``time_boot_ms``; the receive time until synced."""
        if self.offset_ns is None:
            return int(rx_ns)
        return self.unwrapped_ms(time_boot_ms, rx_ns) * NS_PER_MS - self.offset_ns

    def to_host(self, time_boot_ms: int, rx_s: float) -> float:
        """Same as ``to_host_ns`` in seconds (host monotonic)."""
        if self.offset_ns is None:
            return float(rx_s)
        return (self.unwrapped_ms(time_boot_ms, int(rx_s * NS_PER_S)) * NS_PER_MS - self.offset_ns) / NS_PER_S
