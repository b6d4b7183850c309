"""The unit file and the notify protocol, against a real systemd-analyze and a real datagram socket."""

from __future__ import annotations

import os
import shutil
import socket
import subprocess
import sys
from pathlib import Path

import pytest

from daemon.sdnotify import SystemdNotifier
from tests.conftest import REPO

UNIT = REPO / "systemd" / "usv-tracker.service"


def test_unit_has_the_service_contract() -> None:
    text = UNIT.read_text()
    for line in (
        "Type=notify",
        "WatchdogSec=5s",
        "Restart=on-failure",
        "User=usv-tracker",
        "SupplementaryGroups=dialout",
        "ProtectSystem=strict",
        "ProtectHome=yes",
        "PrivateTmp=yes",
        "NoNewPrivileges=yes",
    ):
        assert line in text.splitlines(), line


@pytest.mark.skipif(shutil.which("systemd-analyze") is None, reason="systemd-analyze not installed")
def test_systemd_analyze_verify(tmp_path: Path) -> None:
    # Point ExecStart at the usv-tracker installed next to this Python so verify can check the command exists.
    exe = Path(sys.executable).parent / "usv-tracker"
    if not exe.exists():
        pytest.skip(f"{exe} not installed (pip install -e .)")
    unit = tmp_path / "usv-tracker.service"
    unit.write_text(UNIT.read_text().replace("/opt/usv-tracker/venv/bin/usv-tracker", str(exe)))
    res = subprocess.run(["systemd-analyze", "verify", str(unit)], capture_output=True, text=True, cwd=tmp_path)
    problems = [ln for ln in (res.stdout + res.stderr).splitlines() if "usv-tracker.service" in ln]
    assert res.returncode == 0 and not problems, res.stdout + res.stderr


def test_notify_protocol_on_a_real_socket(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    path = str(tmp_path / "notify.sock")
    server = socket.socket(socket.AF_UNIX, socket.SOCK_DGRAM)
    server.bind(path)
    server.settimeout(2.0)
    try:
        monkeypatch.setenv("NOTIFY_SOCKET", path)
        monkeypatch.setenv("WATCHDOG_USEC", "5000000")
        monkeypatch.setenv("WATCHDOG_PID", str(os.getpid()))
        n = SystemdNotifier()
        assert n.enabled and n.watchdog_interval_s() == 2.5
        assert n.ready("tracking")
        assert server.recv(256) == b"READY=1\nSTATUS=tracking"
        assert n.watchdog()
        assert server.recv(256) == b"WATCHDOG=1"
        assert n.status("lidar 10.0/s")
        assert server.recv(256) == b"STATUS=lidar 10.0/s"
        n.close()
    finally:
        server.close()


def test_notify_abstract_namespace(monkeypatch: pytest.MonkeyPatch) -> None:
    name = f"usv-tracker-test-{os.getpid()}"
    server = socket.socket(socket.AF_UNIX, socket.SOCK_DGRAM)
    server.bind("\0" + name)
    server.settimeout(2.0)
    try:
        n = SystemdNotifier("@" + name)
        assert n.stopping()
        assert server.recv(64) == b"STOPPING=1"
    finally:
        server.close()


def test_no_notify_socket_is_a_no_op(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.delenv("NOTIFY_SOCKET", raising=False)
    n = SystemdNotifier()
    assert not n.enabled and not n.ready() and not n.watchdog()
