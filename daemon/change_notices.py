"""Up/down notices, at most a few per quiet time: a link flapping at its timeout must not flood the telemetry radio
with STATUSTEXTs (nor the journal). What the daemon does changes at once; only what it says waits. A plain outage is
said when it starts and when it ends; beyond ``burst`` notices within ``quiet_s`` the changes are counted instead,
and what was last said is brought up to date once the quiet time allows another notice."""

from __future__ import annotations

from collections import deque


class ChangeNotices:
    """One boolean state per key (a sensor up, sensor data flowing); ``note`` is called every tick with the state."""

    def __init__(self, quiet_s: float = 10.0, burst: int = 2) -> None:
        self.quiet_s = quiet_s
        self.burst = burst
        self._seen: dict[str, bool] = {}
        self._said: dict[str, bool] = {}
        self._times: dict[str, deque[float]] = {}
        self._unsaid: dict[str, int] = {}

    def start(self, key: str, state: bool) -> None:
        """The state the key starts in, which needs no notice."""
        self._seen[key] = self._said[key] = state
        self._times[key] = deque(maxlen=self.burst)
        self._unsaid[key] = 0

    def assume(self, key: str, state: bool) -> None:
        """Take the key's state as ``state`` without a notice (what was said of it no longer holds, e.g. the data it
        was about stopped and was said stopped), keeping its recent notices for the rate limit."""
        if key not in self._seen:
            self.start(key, state)
            return
        self._seen[key] = self._said[key] = state
        self._unsaid[key] = 0

    def known(self, key: str) -> bool:
        return key in self._seen

    def note(self, key: str, state: bool, t: float) -> int | None:
        """The state at ``t``. Returns None when nothing is to be said now, else how many changes went unsaid since
        the last notice besides the one said now (0: a plain change; a state said again after unsaid changes that
        came back to it returns their number)."""
        if key not in self._seen:
            self.start(key, state)
            return None
        if state != self._seen[key]:
            self._seen[key] = state
            self._unsaid[key] += 1
        times = self._times[key]
        changed = state != self._said[key]
        if not (changed or self._unsaid[key]) or (len(times) == self.burst and t - times[0] < self.quiet_s):
            return None
        # a change to say, or changes that went unsaid and came back to what was said: said again, with their count
        n = self._unsaid[key] - int(changed)
        self._unsaid[key] = 0
        self._said[key] = state
        times.append(t)
        return n
