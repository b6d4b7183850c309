"""AutopilotLink over a real pty serial port and TCP, with MAVLink 2 signing, and with a dead link."""

from __future__ import annotations

import math
import os
import socket
import threading
import time
import tty

import numpy as np

from daemon.autopilot import AutopilotLink
from daemon.mavlink_env import mavlink, signing_key_from_passphrase
from drivers.frames import EgoPose
from simulator.autopilot import SimAutopilot, wait_until


def still(t: float) -> EgoPose:
    """A boat drifting north at 1 m/s, heading 30 deg."""
    return EgoPose(t, np.array([t % 1000.0, 5.0, 0.0]), np.array([1.0, 0.0, 0.0]), 0.0, 0.0, math.radians(30), 0.0)


def free_port(kind: int) -> int:
    with socket.socket(socket.AF_INET, kind) as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def no_link_threads_left() -> bool:
    return not any(t.name in ("autopilot-link", "sim-autopilot") and t.is_alive() for t in threading.enumerate())


def bins() -> np.ndarray:
    d = np.full(72, 10001, dtype=np.uint16)
    d[9] = 4321
    return d


def test_serial_pty_pose_and_obstacles_then_unplugged() -> None:
    master, slave = os.openpty()
    tty.setraw(slave)  # no echo before pyserial configures its side
    path = os.ttyname(slave)
    sim = SimAutopilot(f"fd:{master}", still, heartbeat_hz=5.0)
    link = AutopilotLink(path, baud=921600, heartbeat_timeout=0.6, reconnect_interval=0.2)
    sim.start()
    link.start()
    try:
        assert wait_until(lambda: link.timesync.synced and len(link.poses) >= 10, 5.0), link.status()
        pose = link.poses.latest()
        assert pose is not None
        assert pose.yaw == np.float32(math.radians(30))
        assert pose.position[1] == 5.0
        assert link.send_obstacle_distance(bins(), 50, 10000)
        assert wait_until(lambda: len(sim.obstacle_distances()) == 1, 3.0)
        np.testing.assert_array_equal(sim.obstacle_distances()[0].distances, bins())

        sim.stop()  # closes the pty master: the cable is pulled
        # (our slave fd stays open until the end so that the kernel cannot hand this pty number to another
        # process while the link keeps retrying the path: it finds a hung-up port, as with a dead USB adapter)
        assert wait_until(lambda: link.counters.get("link_failures", 0) >= 1, 3.0), link.status()
        assert wait_until(lambda: not link.connected, 3.0)
        # the caller never sees an exception; sends return False and are counted while the port is gone
        assert not any(link.send_obstacle_distance(bins(), 50, 10000) for _ in range(3))
        assert link.send_statustext(mavlink.MAV_SEVERITY_CRITICAL, "autopilot link down") == 0
        assert wait_until(lambda: link.counters.get("link_open_failures", 0) >= 1, 3.0)
        c = link.counters
        assert c.get("tx_dropped_no_link", 0) + c.get("tx_errors", 0) >= 4
    finally:
        link.stop()
        sim.stop()
        os.close(slave)
    assert no_link_threads_left()


def test_tcp_client_connects_late_and_reconnects_after_autopilot_restart() -> None:
    port = free_port(socket.SOCK_STREAM)
    link = AutopilotLink(f"tcp:127.0.0.1:{port}", heartbeat_timeout=0.6, reconnect_interval=0.1)
    link.start()
    sim = SimAutopilot(f"tcpin:127.0.0.1:{port}", still, heartbeat_hz=5.0)
    sim2 = SimAutopilot(f"tcpin:127.0.0.1:{port}", still, heartbeat_hz=5.0)
    try:
        assert wait_until(lambda: link.counters.get("link_open_failures", 0) >= 1, 3.0)  # refused, retried
        assert not link.link_open
        sim.start()
        assert wait_until(lambda: link.connected and len(link.poses) >= 5, 5.0), link.status()
        opens = link.counters["link_opens"]
        sim.stop()  # autopilot side closes the TCP connection
        assert wait_until(lambda: link.counters.get("link_failures", 0) >= 1, 3.0), link.status()
        sim2.start()
        assert wait_until(lambda: link.counters["link_opens"] > opens and link.connected, 5.0), link.status()
        assert link.send_statustext(mavlink.MAV_SEVERITY_INFO, "back")
        assert wait_until(lambda: [s.text for s in sim2.statustexts()] == ["back"], 3.0)
    finally:
        link.stop()
        sim.stop()
        sim2.stop()
    assert no_link_threads_left()


def test_signed_link_talks_to_signed_autopilot_only() -> None:
    key = signing_key_from_passphrase("usv-tracker test key")
    port = free_port(socket.SOCK_DGRAM)
    sim = SimAutopilot(f"udpin:127.0.0.1:{port}", still, signing_key=key, heartbeat_hz=5.0)
    link = AutopilotLink(f"udpout:127.0.0.1:{port}", signing_key=key)
    sim.start()
    link.start()
    try:
        assert wait_until(lambda: link.timesync.synced and len(link.poses) >= 5, 5.0), link.status()
        assert link.send_obstacle_distance(bins(), 50, 10000)
        assert wait_until(lambda: len(sim.obstacle_distances()) == 1, 3.0)
        rec = sim.obstacle_distances()[0]
        assert rec.signed
        np.testing.assert_array_equal(rec.distances, bins())
        assert all(hb.signed for hb in sim.heartbeats())
    finally:
        link.stop()
        sim.stop()

    # a wrong key: every autopilot packet fails its signature, and the autopilot hears nothing from us
    port = free_port(socket.SOCK_DGRAM)
    sim = SimAutopilot(f"udpin:127.0.0.1:{port}", still, signing_key=key, heartbeat_hz=5.0)
    link = AutopilotLink(f"udpout:127.0.0.1:{port}", signing_key=signing_key_from_passphrase("wrong"))
    sim.start()
    link.start()
    try:
        assert wait_until(lambda: sim.bad_packets >= 2, 3.0)  # our heartbeats, rejected
        link.send_obstacle_distance(bins(), 50, 10000)
        time.sleep(0.3)
        assert sim.obstacle_distances() == [] and sim.heartbeats() == []
        assert not link.connected and len(link.poses) == 0
        assert link.counters.get("rx_bad_signature", 0) >= 2
    finally:
        link.stop()
        sim.stop()


def test_missing_serial_device_never_raises_and_stops_promptly() -> None:
    link = AutopilotLink("/dev/ttyUSB-does-not-exist", reconnect_interval=0.1)
    link.start()
    try:
        assert wait_until(lambda: link.counters.get("link_open_failures", 0) >= 2, 3.0)
        assert not link.send_obstacle_distance(bins(), 50, 10000)
        assert link.send_statustext(4, "x") == 0
        assert link.send_obstacle_distance_3d(np.array([[1.0, 2.0, 0.0]]), 0.5, 50.0) == 0
        link.set_system_status(mavlink.MAV_STATE_CRITICAL)
        assert link.counters["tx_dropped_no_link"] == 4
        assert not link.link_open and not link.connected and link.pose_age is None
    finally:
        link.stop()
    assert no_link_threads_left()
