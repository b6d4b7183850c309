"""An autopilot's SYSTEM_TIME with a corrupt Unix time (all ones) must not become the obstacles' time_usec: packed,
it overflowed the field, the send raised, and the link was closed and reopened every time the array was tried."""

from __future__ import annotations

import threading
import time

import numpy as np

from daemon.autopilot import AutopilotLink
from daemon.demo import free_udp_port
from daemon.mavlink_env import mavlink, mavutil
from simulator.autopilot import wait_until


def test_a_corrupt_system_time_keeps_the_link_and_the_feed() -> None:
    port = free_udp_port()
    link = AutopilotLink(f"udpin:127.0.0.1:{port}", reconnect_interval=0.5)
    link.start()
    autopilot = mavutil.mavlink_connection(f"udpout:127.0.0.1:{port}", source_system=1, source_component=1)
    stop = threading.Event()

    def stream() -> None:
        t0 = time.monotonic()
        while not stop.is_set():
            boot_ms = int((time.monotonic() - t0) * 1000) + 10_000
            autopilot.mav.heartbeat_send(
                mavlink.MAV_TYPE_SURFACE_BOAT, mavlink.MAV_AUTOPILOT_ARDUPILOTMEGA, 0, 0, mavlink.MAV_STATE_ACTIVE
            )
            autopilot.mav.system_time_send(2**64 - 1, boot_ms)
            time.sleep(0.1)

    streamer = threading.Thread(target=stream, daemon=True)
    streamer.start()
    try:
        assert wait_until(lambda: link.counters.get("autopilot_heartbeats", 0) >= 2, 5.0)
        sent = sum(bool(link.send_obstacle_distance(np.full(72, 500), 50, 10_000)) for _ in range(30))
        counters = link.counters
    finally:
        stop.set()
        streamer.join(1.0)
        link.stop()
        autopilot.close()
    assert sent == 30
    assert counters.get("link_failures", 0) == 0 and counters.get("tx_errors", 0) == 0
    assert 0 < link.unix_time_usec() < 4102444800 * 10**6  # the host's own clock, not the corrupt one
