"""The live autopilot a replay is played into (`usv-tracker replay --to URL`).

The link is the daemon's own AutopilotLink, so the autopilot gets what it gets from a live daemon: OBSTACLE_DISTANCE
every tick, the 1 Hz HEARTBEAT with the sensors' state, STATUSTEXT when a sensor goes silent or comes back, and
AIS_VESSEL when `[output] ais_interval_s` asks for it. With the poses from the recording's .tlog (the default) the
autopilot is not asked to stream its own; with `--pose live` it is, as live, and the replay waits for them.
"""

from __future__ import annotations

import contextlib
import logging
import time
from collections.abc import Callable, Iterator

from daemon.autopilot import AutopilotLink
from daemon.config import Config, signing_passphrase
from daemon.ego import HistoryEgo
from daemon.runner import _signing_key

log = logging.getLogger(__name__)

OPEN_TIMEOUT_S = 10.0  # a TCP connect to SITL or a serial port: seconds at most, or something is wrong
HEARTBEAT_WAIT_S = 3.0  # long enough for two of the autopilot's 1 Hz heartbeats
POSE_TIMEOUT_S = 10.0


class LinkError(RuntimeError):
    """The autopilot cannot be reached as asked; the message says what is missing."""


@contextlib.contextmanager
def autopilot_link(config: Config, url: str, live_poses: bool) -> Iterator[AutopilotLink]:
    """An open, started link to ``url`` (ids and signing from ``config.mavlink``); stopped on exit."""
    m = config.mavlink
    link = AutopilotLink(
        url,
        system_id=m.system_id,
        component_id=m.component_id,
        target_system=m.target_system,
        baud=m.baud,
        signing_key=_signing_key(signing_passphrase(m)),
        # the recording's poses need none of the autopilot's: a telemetry radio carries only what is used
        **({} if live_poses else {"message_rates_hz": {}}),
    )
    link.start()
    try:
        if not _wait(lambda: link.link_open, OPEN_TIMEOUT_S):
            raise LinkError(f"{url}: could not be opened within {OPEN_TIMEOUT_S:.0f} s")
        if not _wait(lambda: link.connected, HEARTBEAT_WAIT_S):
            if live_poses:
                raise LinkError(f"{url}: no autopilot heartbeat within {HEARTBEAT_WAIT_S:.0f} s, so no live poses")
            log.warning("%s: no autopilot heartbeat yet; sending to it anyway", url)
        if live_poses and not _wait(lambda: len(link.poses) > 0, POSE_TIMEOUT_S):
            raise LinkError(f"{url}: the autopilot sent no pose within {POSE_TIMEOUT_S:.0f} s ({link.rate_status})")
        log.info("replaying into %s (poses from %s)", url, "the autopilot" if live_poses else "the recording")
        yield link
    finally:
        link.stop()


def live_ego(link: AutopilotLink) -> HistoryEgo:
    """The autopilot's poses as the pipeline takes them, on the host's monotonic clock (the link's)."""
    return HistoryEgo(link.poses, lambda: link.world_epoch)


def _wait(predicate: Callable[[], bool], timeout: float) -> bool:
    deadline = time.monotonic() + timeout
    while not predicate():
        if time.monotonic() >= deadline:
            return False
        time.sleep(0.02)
    return True
