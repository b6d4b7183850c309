"""Shared test helpers: where the public captures live, a skip when they are not there, and UDP senders."""

from __future__ import annotations

import os
import socket
from collections.abc import Callable, Iterator
from pathlib import Path

import pytest

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
