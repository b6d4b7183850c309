"""`usv-tracker run` as systemd runs it: a separate process, READY/WATCHDOG on a real notify socket, SIGTERM."""

from __future__ import annotations

import os
import re
import signal
import socket
import subprocess
import sys
import time
from pathlib import Path

import pytest

from daemon.demo import config_for_simulation, simulation_settings
from simulator.run import SimulationRun
from tests.test_daemon_e2e import one_box_scene, wait_for
from tests.test_heap import GLIBC, thread_arenas

# Real sockets, ptys and threads in real time on a 2-core machine that may be busy: a missed deadline is retried once
# (a deterministic failure still fails); the assertions themselves are not loosened.
pytestmark = pytest.mark.flaky(reruns=1)


def test_run_process_notifies_systemd_and_stops_on_sigterm(tmp_path: Path) -> None:
    sock_path = str(tmp_path / "notify.sock")
    notify = socket.socket(socket.AF_UNIX, socket.SOCK_DGRAM)
    notify.bind(sock_path)
    notify.settimeout(10.0)
    with SimulationRun(simulation_settings("one_box"), scene=one_box_scene()) as sim:
        c = config_for_simulation(sim)
        args = [
            sys.executable, "-m", "daemon.cli", "run",
            "--lidar", c.lidar.source,
            "--radar-cli", c.radar.cli,
            "--radar-data", c.radar.data,
            "--radar-profile", c.radar.profile,
            "--mavlink", c.mavlink.url,
        ]  # fmt: skip
        env = {**os.environ, "NOTIFY_SOCKET": sock_path, "WATCHDOG_USEC": "5000000"}
        proc = subprocess.Popen(args, env=env, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
        try:
            messages = []
            while not any(m.startswith("READY=1") for m in messages):
                messages.append(notify.recv(4096).decode())
            assert "STATUS=tracking with LiDAR, radar" in messages[-1]
            assert notify.recv(4096) == b"WATCHDOG=1"
            ap = sim.autopilot
            assert ap is not None
            assert wait_for(lambda: len(ap.obstacle_distances()) >= 5, timeout=10.0)
            if GLIBC:  # its reader threads share one malloc arena beside the main heap (daemon.heap)
                assert thread_arenas(proc.pid) <= 1
            # a hang-up (the terminal it was started from closed) leaves the feed running
            proc.send_signal(signal.SIGHUP)
            sent = len(ap.obstacle_distances())
            assert wait_for(lambda: len(ap.obstacle_distances()) >= sent + 5, timeout=10.0)
            assert proc.poll() is None
            t_term = time.monotonic()
            proc.send_signal(signal.SIGTERM)
            rc = proc.wait(timeout=10.0)
            took = time.monotonic() - t_term
        finally:
            if proc.poll() is None:
                proc.kill()
            notify.close()
        _, err = proc.communicate()
    assert rc == 0, err
    # Within systemd's TimeoutStopSec (5 s, systemd/usv-tracker.service) with margin: no thread or port is waited
    # out. The 1 s goal is a benchmark figure (bench/soak.py: 0.32 s, process exit included); here, with four busy
    # loops on the 2 cores, the same stop took 1.2 s, and a wall-clock 1 s bound failed one run in three.
    assert took < 3.0, f"stopping took {took:.2f} s"
    assert "SIGTERM received: stopping" in err and "stopped" in err
    assert "SIGHUP received: ignored, still running" in err


NAMES = {"lidar": "LiDAR", "radar": "radar"}


@pytest.mark.parametrize("off", ["lidar", "radar"])
def test_a_sensor_switched_off_is_said_once_at_start_and_never_reported_silent(tmp_path: Path, off: str) -> None:
    # Both sensors simulated; the daemon runs with one switched off for 6 s of its own loop: past the 3 s start-up grace
    # plus the 0.5 s after which a sensor that stays quiet is reported silent (as an ERROR and a STATUSTEXT).
    with SimulationRun(simulation_settings("one_box"), scene=one_box_scene()) as sim:
        c = config_for_simulation(sim)
        toml = tmp_path / "usv-tracker.toml"
        toml.write_text(f"[lidar]\nposition_port = {c.lidar.position_port}\n[output]\nhealth_interval_s = 2.0\n")
        args = [
            sys.executable, "-m", "daemon.cli", "run", "--config", str(toml),
            "--lidar", c.lidar.source,
            "--radar-cli", c.radar.cli,
            "--radar-data", c.radar.data,
            "--radar-profile", c.radar.profile,
            "--mavlink", c.mavlink.url,
            f"--no-{off}", "--seconds", "6",
        ]  # fmt: skip
        res = subprocess.run(args, capture_output=True, text=True, timeout=60)
        ap = sim.autopilot
        assert ap is not None
        texts = [s.text for s in ap.statustexts()]
        sent = len(ap.obstacle_distances())
    assert res.returncode == 0, res.stderr
    name = NAMES[off]
    assert res.stderr.count(f"{name} off by configuration: not expected, not reported silent") == 1
    assert f"{name} silent" not in res.stderr and not any(name in t for t in texts)
    on = NAMES["radar" if off == "lidar" else "lidar"]
    assert f"usv-tracker running: {on} ->" in res.stderr and sent > 0  # the other sensor did deliver
    health = [line for line in res.stderr.splitlines() if "health: " in line]
    assert health and all(f"{off} off " in line for line in health)


@pytest.mark.parametrize("off", ["lidar", "radar"])
def test_a_replay_with_a_sensor_switched_off_never_reports_it_silent(tmp_path: Path, off: str) -> None:
    # 5 s of recorded data, replayed on the data's clock: the ticks pass the 3 s grace and the 0.5 s timeout.
    from simulator.capture import write_captures
    from simulator.scenarios import get_scenario

    d = tmp_path / "run"
    write_captures("harbour", d, 5.0, seed=0, scene=get_scenario("harbour"))
    args = [
        sys.executable, "-m", "daemon.cli", "run", "--fast",
        "--lidar", f"pcap://{d / 'lidar.pcap'}",
        "--radar-cli", "",
        "--radar-data", f"file://{d / 'radar.dat'}",
        "--radar-profile", str(d / "radar.cfg"),
        "--mavlink", str(d / "autopilot.tlog"),
        f"--no-{off}",
        "--record", str(tmp_path / "rec"),
    ]  # fmt: skip
    res = subprocess.run(args, capture_output=True, text=True, timeout=120)
    assert res.returncode == 0, res.stderr
    # a replay records nothing, and says so rather than ignoring --record
    assert f"not recording to {tmp_path / 'rec'}: a replay's captures are already its recording" in res.stderr
    assert not (tmp_path / "rec").exists()
    name = NAMES[off]
    assert res.stderr.count(f"{name} off by configuration: not expected, not reported silent") == 1
    assert f"{name} silent" not in res.stderr
    ticks = re.search(r"replay: (\d+) ticks over ([\d.]+) s of data", res.stderr)
    # the test's premise held: ticks went on past the 3 s grace and the 0.5 s timeout (radar frames are stamped at
    # when they were sent, up to 29 ms before their recorded reads, so 5 s of captures replay as 4.9 s or more)
    assert ticks is not None and int(ticks[1]) >= 40 and float(ticks[2]) >= 4.0
