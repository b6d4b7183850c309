"""Autopilots sending values no message should carry, over real MAVLink on loopback: a SYSTEM_TIME with a corrupt
Unix time (all ones) must not become the obstacles' time_usec (packed, it overflowed the field, the send raised,
and the link was closed and reopened every time the array was tried), and ATTITUDEs with an infinite angle must
show on the health line."""

from __future__ import annotations

import contextlib
import threading
import time
from collections.abc import Callable, Iterator
from typing import Any

import numpy as np

from daemon.autopilot import AutopilotLink
from daemon.demo import free_udp_port
from daemon.health import source_status
from daemon.mavlink_env import mavlink, mavutil
from simulator.autopilot import wait_until


@contextlib.contextmanager
def streaming_autopilot(send: Callable[[Any, int], None], period_s: float) -> Iterator[AutopilotLink]:
    """A link listening on loopback and an autopilot (system 1) sending it a heartbeat and ``send(mav, boot_ms)``
    every ``period_s``; the link is yielded, started."""
    port = free_udp_port()
    link = AutopilotLink(f"udpin:127.0.0.1:{port}", reconnect_interval=0.5)
    link.start()
    autopilot = mavutil.mavlink_connection(f"udpout:127.0.0.1:{port}", source_system=1, source_component=1)
    stop = threading.Event()

    def stream() -> None:
        t0 = time.monotonic()
        while not stop.is_set():
            autopilot.mav.heartbeat_send(
                mavlink.MAV_TYPE_SURFACE_BOAT, mavlink.MAV_AUTOPILOT_ARDUPILOTMEGA, 0, 0, mavlink.MAV_STATE_ACTIVE
            )
            send(autopilot.mav, int((time.monotonic() - t0) * 1000) + 10_000)
            time.sleep(period_s)

    streamer = threading.Thread(target=stream, daemon=True)
    streamer.start()
    try:
        yield link
    finally:
        stop.set()
        streamer.join(1.0)
        link.stop()
        autopilot.close()


def test_a_corrupt_system_time_keeps_the_link_and_the_feed() -> None:
    with streaming_autopilot(lambda mav, boot_ms: mav.system_time_send(2**64 - 1, boot_ms), 0.1) as link:
        assert wait_until(lambda: link.counters.get("autopilot_heartbeats", 0) >= 2, 5.0)
        sent = sum(bool(link.send_obstacle_distance(np.full(72, 500), 50, 10_000)) for _ in range(30))
        counters = link.counters
        unix_usec = link.unix_time_usec()
    assert sent == 30
    assert counters.get("link_failures", 0) == 0 and counters.get("tx_errors", 0) == 0
    assert 0 < unix_usec < 4102444800 * 10**6  # the host's own clock, not the corrupt one


def test_an_autopilot_sending_non_finite_attitudes_is_up_without_a_pose_on_the_health_line() -> None:
    """Its heartbeat says it is there; its ATTITUDE carries an infinite roll (an estimator not yet up) beside a good
    LOCAL_POSITION_NED: no pose can be made, and the health line says why rather than "autopilot up" alone."""

    def send(mav: Any, boot_ms: int) -> None:
        mav.local_position_ned_send(boot_ms, 1.0, 2.0, 0.0, 0.5, 0.0, 0.0)
        mav.attitude_send(boot_ms, float("inf"), 0.0, 0.3, 0.0, 0.0, 0.0)

    with streaming_autopilot(send, 0.05) as link:
        assert wait_until(lambda: link.counters.get("pose_rejected", 0) >= 5, 5.0)
        status = source_status(None, None, link)
    assert status.startswith("autopilot up, no pose, pose_rejected ")
    assert int(status.rsplit(" ", 1)[1]) >= 5
