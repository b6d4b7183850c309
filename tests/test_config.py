"""Config loading and `usv-tracker check-config`: every bad key named, with why."""

from __future__ import annotations

import math
import subprocess
import sys
from pathlib import Path

import pytest

from daemon.config import load_config
from daemon.config_schema import ConfigError
from tests.conftest import REPO

EXAMPLE = REPO / "config" / "usv-tracker.toml"


def test_example_config_loads_with_degrees_converted_once() -> None:
    c = load_config(EXAMPLE)
    assert c.lidar.source == "udp://0.0.0.0:2368"
    assert c.mavlink.component_id == 196
    m = load_config(EXAMPLE, {"radar.mount.yaw": 90.0}).radar.mount.to_mount()
    assert math.isclose(m.yaw, math.pi / 2)


def test_every_problem_is_named(tmp_path: Path) -> None:
    bad = tmp_path / "bad.toml"
    bad.write_text(
        '[lidar]\nsource = "udp://0.0.0.0"\nmax_ditance_m = 3\n'
        '[radar.mount]\nyaw = "left"\n'
        "[output]\nrate_hz = 100\n"
        "[mavlink]\nsystem_id = 0\n"
    )
    with pytest.raises(ConfigError) as err:
        load_config(bad)
    assert err.value.problems == [
        "lidar.max_ditance_m: unknown key (did you mean 'max_range_m'?)",
        "lidar.source: 'udp://0.0.0.0': a UDP source needs a port, e.g. udp://0.0.0.0:2368",
        "radar.mount.yaw: expected a number, got 'left'",
        "output.rate_hz: 100.0 must be within 1..50",
        "mavlink.system_id: 0 must be 1..255",
    ]


def test_not_toml_and_missing_file(tmp_path: Path) -> None:
    broken = tmp_path / "broken.toml"
    broken.write_text("[lidar\nsource=1")
    with pytest.raises(ConfigError, match="not valid TOML"):
        load_config(broken)
    with pytest.raises(ConfigError, match="file not found"):
        load_config(tmp_path / "absent.toml")


def test_check_config_command(tmp_path: Path) -> None:
    ok = subprocess.run(
        [sys.executable, "-m", "daemon.cli", "check-config", str(EXAMPLE)], capture_output=True, text=True
    )
    assert ok.returncode == 0, ok.stderr
    assert "OK" in ok.stdout
    bad = tmp_path / "bad.toml"
    bad.write_text('[radar]\ndata = "com3"\n')
    res = subprocess.run([sys.executable, "-m", "daemon.cli", "check-config", str(bad)], capture_output=True, text=True)
    assert res.returncode == 2
    assert "radar.data: 'com3' is not a source URL" in res.stderr


def test_lidar_sender_settings_are_checked() -> None:
    assert load_config(EXAMPLE).lidar.lock_timeout_s == 2.0 and load_config(EXAMPLE).lidar.accept_ip == ""
    assert load_config(None, {"lidar.accept_ip": "192.168.1.201"}).lidar.accept_ip == "192.168.1.201"
    with pytest.raises(ConfigError) as err:
        load_config(None, {"lidar.accept_ip": "velodyne.local", "lidar.lock_timeout_s": 0.0})
    assert err.value.problems == [
        "lidar.lock_timeout_s: must be > 0",
        "lidar.accept_ip: 'velodyne.local' is not an IPv4 address (the sensor's, e.g. 192.168.1.201)",
    ]
