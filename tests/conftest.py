"""Shared test helpers: where the public captures live, a skip when they are not there, UDP senders, and an
autopilot link paired with the simulated autopilot."""

from __future__ import annotations

import os
import socket
import threading
from collections.abc import Callable, Iterator
from pathlib import Path

import pytest

from daemon.autopilot import AutopilotLink
from daemon.demo import free_udp_port
from simulator.autopilot import SimAutopilot
from tests.turning_boat import circle

REPO = Path(__file__).resolve().parent.parent
OWN_FIXTURES = REPO / "tests" / "fixtures"
# CI clones the repo with shared/ beside it; a developer checkout has it one level up as well.
SHARED = Path(os.environ.get("USV_TRACKER_SHARED", REPO.parent / "shared"))
SHARED_FIXTURES = SHARED / "fixtures"


@pytest.fixture
def shared_fixtures() -> Path:
    if not SHARED_FIXTURES.is_dir():
        pytest.skip(f"public captures not found at {SHARED_FIXTURES} (set USV_TRACKER_SHARED to the shared/ folder)")
    return SHARED_FIXTURES


@pytest.fixture
def sender() -> Iterator[Callable[[str], socket.socket]]:
    """``sender(ip)``: a UDP socket bound to ``ip`` (127.0.0.x: Linux routes all of 127/8 to loopback), closed after
    the test. Each gets its own source port, so two on one address are two senders too."""
    made: list[socket.socket] = []

    def make(ip: str) -> socket.socket:
        sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        sock.bind((ip, 0))
        made.append(sock)
        return sock

    yield make
    for sock in made:
        sock.close()


@pytest.fixture
def pair() -> Iterator[tuple[AutopilotLink, SimAutopilot]]:
    """Sim listens (udpin), the link sends to it (udpout), as with a companion on an autopilot's UDP port."""
    port = free_udp_port()
    sim = SimAutopilot(f"udpin:127.0.0.1:{port}", circle, heartbeat_hz=5.0)
    link = AutopilotLink(f"udpout:127.0.0.1:{port}", heartbeat_timeout=0.6)
    sim.start()
    link.start()
    try:
        yield link, sim
    finally:
        link.stop()
        sim.stop()
        assert not [t for t in threading.enumerate() if t.name in ("autopilot-link", "sim-autopilot") and t.is_alive()]
