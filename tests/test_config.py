"""Config loading and `usv-tracker check-config`: every bad key named, with why."""

from __future__ import annotations

import math
import subprocess
import sys
from pathlib import Path

import pytest

from daemon.config import load_config
from daemon.config_schema import ConfigError
from tests.conftest import OWN_FIXTURES, REPO

EXAMPLE = REPO / "config" / "usv-tracker.toml"
PACKAGED_PROFILE = REPO / "daemon" / "profiles" / "awr1843_50m.cfg"
LATIN1 = OWN_FIXTURES / "fuzz" / "config_latin1.toml"


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


def check_config(path: Path) -> subprocess.CompletedProcess[str]:
    return subprocess.run(
        [sys.executable, "-m", "daemon.cli", "check-config", str(path)], capture_output=True, text=True, timeout=60
    )


def installed_example(tmp_path: Path) -> Path:
    """The example config with its radar cfg where the README's install steps put it (here: the packaged one)."""
    text = EXAMPLE.read_text().replace('"/etc/usv-tracker/awr1843.cfg"', f'"{PACKAGED_PROFILE}"')
    path = tmp_path / "usv-tracker.toml"
    path.write_text(text)
    return path


def test_check_config_command(tmp_path: Path) -> None:
    ok = check_config(installed_example(tmp_path))
    assert ok.returncode == 0, ok.stderr
    assert "OK" in ok.stdout
    bad = tmp_path / "bad.toml"
    bad.write_text('[radar]\ndata = "com3"\n')
    res = check_config(bad)
    assert res.returncode == 2
    assert "radar.data: 'com3' is not a source URL" in res.stderr


def test_lidar_sender_settings_are_checked() -> None:
    assert load_config(EXAMPLE).lidar.lock_timeout_s == 2.0 and load_config(EXAMPLE).lidar.accept_ip == ""
    assert load_config(None, {"lidar.accept_ip": "192.168.1.201"}).lidar.accept_ip == "192.168.1.201"
    with pytest.raises(ConfigError) as err:
        load_config(None, {"lidar.accept_ip": "velodyne.local", "lidar.lock_timeout_s": 0.0})
    assert err.value.problems == [
        "lidar.lock_timeout_s: must be > 0",
        "lidar.accept_ip: 'velodyne.local' is not an IPv4 address (the VLP-16 sends from one, e.g. 192.168.1.201)",
    ]


def test_a_file_that_is_not_utf8_is_named_not_a_traceback() -> None:
    with pytest.raises(ConfigError) as err:
        load_config(LATIN1)
    assert err.value.problems == ["not UTF-8 text: byte 0xb0 on line 3 (TOML files are UTF-8)"]
    res = check_config(LATIN1)
    assert res.returncode == 2
    assert res.stderr == f"{LATIN1}: 1 problem(s):\n  not UTF-8 text: byte 0xb0 on line 3 (TOML files are UTF-8)\n"


def test_what_toml_reads_but_python_cannot_hold_is_named(tmp_path: Path) -> None:
    cases = {
        'source = "udp://[::1"': "lidar.source: 'udp://[::1': not a valid URL (Invalid IPv6 URL)",
        "cut_angle_deg = 1" + "0" * 400: "lidar.cut_angle_deg: too large a number (beyond 1.8e308)",
    }
    for line, problem in cases.items():
        path = tmp_path / "c.toml"
        path.write_text(f"[lidar]\n{line}\n")
        with pytest.raises(ConfigError) as err:
            load_config(path)
        assert err.value.problems == [problem]
    path.write_text("a = " + "[" * 5000)
    with pytest.raises(ConfigError) as err:
        load_config(path)
    assert err.value.problems == ["not valid TOML: arrays or tables nested too deeply"]
    path.write_text("a = " + "1" * 5000)
    with pytest.raises(ConfigError, match="not valid TOML: Exceeds the limit"):
        load_config(path)
    with pytest.raises(ConfigError) as err:
        load_config("/dev/zero")
    assert err.value.problems == ["larger than 1024 KiB: not a configuration file"]


def test_a_tracker_table_that_is_not_a_table(tmp_path: Path) -> None:
    path = tmp_path / "c.toml"
    path.write_text("[tracker]\nlidar = [1, 2]\nradar = 5\n")
    with pytest.raises(ConfigError) as err:
        load_config(path)
    assert err.value.problems == [
        "tracker.lidar: expected a table, got [1, 2]",
        "tracker.radar: expected a table, got 5",
    ]
    # a section given as a value, with a command-line override below it, is named too
    path.write_text('lidar = "udp://0.0.0.0:2368"\n')
    with pytest.raises(ConfigError) as err:
        load_config(path, {"lidar.source": "pcap://x.pcap"})
    assert err.value.problems == ["lidar: expected a table, got 'udp://0.0.0.0:2368'"]


def test_the_radar_tracker_is_set_by_role_and_an_old_flat_key_is_pointed_to_its_group(tmp_path: Path) -> None:
    from daemon.tracker_adapters import tracker_factories

    path = tmp_path / "c.toml"
    path.write_text("[tracker.radar.clustering]\nmin_points = 4\n[tracker.radar.lifecycle]\nmax_unseen_time = 1.5\n")
    _, radar, _ = tracker_factories(load_config(path))
    assert radar is not None
    cfg = radar().cfg
    assert (cfg.clustering.min_points, cfg.lifecycle.max_unseen_time) == (4, 1.5)
    # the rest keeps the daemon's defaults (tracker_adapters.DAEMON_RADAR_DEFAULTS) and the classes' own
    assert (cfg.clustering.radius_m, cfg.kalman.motion_model, cfg.lifecycle.max_unseen_time_occluded) == (
        2.0,
        "ct",
        4.0,
    )
    assert cfg.roi.max_range_m == load_config(path).radar.max_range_m

    path.write_text("[tracker.radar]\ncluster_min_points = 3\n[tracker.radar.clustering]\nmin_points = 0\n")
    out = check_config(path)
    assert out.returncode == 2, out.stdout + out.stderr
    assert "tracker.radar.cluster_min_points: unknown key (did you mean 'clustering.min_points'?)" in out.stderr
    assert "tracker.radar.clustering: ClusteringConfig.min_points: must be >= 1, got 0" in out.stderr


def test_the_lidar_lifecycle_is_set_from_the_config_and_its_problems_name_the_key_once(tmp_path: Path) -> None:
    from daemon.tracker_adapters import tracker_factories

    path = tmp_path / "c.toml"
    path.write_text("[tracker.lidar.lifecycle]\nmin_hits_reported_unseen = 0\n")
    lidar, _, _ = tracker_factories(load_config(path))
    assert lidar is not None and lidar().config.lifecycle.min_hits_reported_unseen == 0  # 0: the rule off
    path.write_text("[tracker.lidar.lifecycle]\nmin_hits_reported_unseen = -1\n")
    out = check_config(path)
    assert out.returncode == 2, out.stdout + out.stderr
    assert "tracker.lidar.lifecycle: min_hits_reported_unseen: must be >= 0 (0: off), got -1" in out.stderr
    path.write_text("[tracker.lidar.lifecycle]\nmin_hits_reported_unseen = -1\nconfirm_hits = 9\n")
    out = check_config(path)
    assert out.returncode == 2, out.stdout + out.stderr
    # the first problem the group's class finds is named, with its key, under the group's path (not "lifecycle: "
    # twice, as before)
    assert (
        "tracker.lidar.lifecycle: confirm_hits, confirm_window: need 1 <= confirm_hits <= confirm_window, got 9 of 5"
        in out.stderr
    )


def test_values_that_load_but_cannot_work_are_named(tmp_path: Path) -> None:
    path = tmp_path / "c.toml"
    path.write_text(
        '[lidar]\ncut_angle_deg = 1000\naccept_ip = "not-an-ip"\n'
        '[radar]\nsilence_timeout_s = -1.0\ncli = "serial:///dev/ttyACM0?baud=fast"\n'
        '[mavlink]\nurl = "bogus:thing"\nbaud = -5\n'
        "[output]\nhealth_interval_s = -2.0\n"
    )
    with pytest.raises(ConfigError) as err:
        load_config(path)
    assert err.value.problems == [
        "lidar.cut_angle_deg: 1000.0 must be within -360..360 degrees",
        "lidar.accept_ip: 'not-an-ip' is not an IPv4 address (the VLP-16 sends from one, e.g. 192.168.1.201)",
        "radar.cli: 'serial:///dev/ttyACM0?baud=fast': baud 'fast' is not a positive whole number, e.g. ?baud=921600",
        "radar.silence_timeout_s: -1.0 must be > 0",
        "mavlink.url: 'bogus:thing' is not an autopilot connection (udpin:/udpout:/tcp:/tcpin:HOST:PORT, a serial "
        "path, or serial://PATH?baud=N)",
        "mavlink.baud: -5 must be > 0 (e.g. 921600)",
        "output.health_interval_s: -2.0 must be > 0",
    ]
    # a value of the wrong type is named once; the section's range checks cannot run on it (and do not crash)
    path.write_text("[mavlink]\nurl = true\n")
    with pytest.raises(ConfigError) as err:
        load_config(path)
    assert err.value.problems == ["mavlink.url: expected a string, got True"]
    path.write_text('[mavlink]\nurl = "run/autopilot.tlog"\n')
    assert load_config(path).mavlink.url == "run/autopilot.tlog"  # replayed, not opened as a live link
    path.write_text('[mavlink]\nurl = "udpout:127.0.0.1"\n')
    with pytest.raises(ConfigError) as err:
        load_config(path)
    assert err.value.problems == [
        "mavlink.url: 'udpout:127.0.0.1': expected SCHEME:HOST:PORT, e.g. udpout:127.0.0.1:14550"
    ]


def test_a_wrong_type_does_not_hide_the_sections_other_problems(tmp_path: Path) -> None:
    """A value of the wrong type is named and its default stands in, so the rest of its section is still checked;
    a bad distance is named once, not again through the settings measured against it."""
    path = tmp_path / "c.toml"
    path.write_text('[output]\nrate_hz = "ten"\nmax_distance_m = -5\n')
    with pytest.raises(ConfigError) as err:
        load_config(path)
    assert err.value.problems == [
        "output.rate_hz: expected a number, got 'ten'",
        "output.min_distance_m/max_distance_m: need 0 < min < max",
    ]
    path.write_text("[output]\nno_data_timeout_s = 0.05\n")
    with pytest.raises(ConfigError) as err:
        load_config(path)
    assert err.value.problems == [
        "output.no_data_timeout_s: 0.05 is under two ticks (0.20 s at 10 Hz): a sensor delivering once a tick would"
        " be reported silent between deliveries"
    ]


def test_the_simulator_is_pointed_to_the_demo_not_accepted_as_a_source(tmp_path: Path) -> None:
    """`run` reads sensors and captures; a config that names the simulator must fail check-config, not the start."""
    path = tmp_path / "c.toml"
    path.write_text('[lidar]\nsource = "sim://harbour"\n[radar]\ndata = "sim://harbour"\n')
    with pytest.raises(ConfigError) as err:
        load_config(path)
    assert len(err.value.problems) == 2
    for problem, key in zip(err.value.problems, ("lidar.source", "radar.data"), strict=True):
        assert problem.startswith(f"{key}: 'sim://harbour': the simulator is not a sensor source")
        assert "usv-tracker demo --scene NAME" in problem


def test_a_bare_key_that_several_groups_hold_is_pointed_to_each(tmp_path: Path) -> None:
    path = tmp_path / "c.toml"
    path.write_text("[tracker.radar]\nmin_points = 3\n")
    out = check_config(path)
    assert out.returncode == 2, out.stdout + out.stderr
    assert (
        "tracker.radar.min_points: unknown key (did you mean one of 'clustering.min_points', 'ego.min_points', "
        "'velocity.min_points'?)"
    ) in out.stderr


def test_check_config_opens_the_files_the_config_names(tmp_path: Path) -> None:
    path = tmp_path / "c.toml"
    absent_pcap, absent_cfg = tmp_path / "absent.pcap", tmp_path / "absent.cfg"
    path.write_text(f'[lidar]\nsource = "pcap://{absent_pcap}"\n[radar]\nrequired = true\nprofile = "{absent_cfg}"\n')
    load_config(path)  # `run` leaves them to start-up (a radar that cannot start leaves the daemon LiDAR-only)
    with pytest.raises(ConfigError) as err:
        load_config(path, check_files=True)
    assert err.value.problems == [
        f"lidar.source: capture file not found: {absent_pcap}",
        f"radar.profile: {absent_cfg}: cannot read radar cfg: No such file or directory",
    ]
    # the cfg is parsed by the driver's own parser: a cfg it refuses is named with its line
    bad_cfg = tmp_path / "bad.cfg"
    bad_cfg.write_text(PACKAGED_PROFILE.read_text().replace("frameCfg 0 1 ", "frameCfg 0 9 "))
    path.write_text(f'[radar]\nrequired = true\nprofile = "{bad_cfg}"\n')
    with pytest.raises(ConfigError) as err:
        load_config(path, check_files=True)
    (problem,) = err.value.problems
    assert (
        problem.startswith(f"radar.profile: {bad_cfg}:")
        and "frameCfg uses chirp(s) [2, 3, 4, 5, 6, 7, 8, 9]" in problem
    )
    res = check_config(path)
    assert res.returncode == 2 and "radar.profile:" in res.stderr and "Traceback" not in res.stderr


def test_a_radar_the_daemon_can_run_without_warns_but_does_not_stop_the_start(tmp_path: Path) -> None:
    """systemd runs check-config before every start: a radar that is not required and whose cfg is missing leaves
    the daemon LiDAR-only at start-up, so it must not keep the LiDAR from running."""
    path = tmp_path / "c.toml"
    absent_cfg = tmp_path / "absent.cfg"
    path.write_text(f'[radar]\nrequired = false\nprofile = "{absent_cfg}"\n')
    res = check_config(path)
    assert res.returncode == 0
    assert res.stdout == f"{path}: OK with 1 warning(s)\n"
    assert res.stderr == (
        f"  warning: radar.profile: {absent_cfg}: cannot read radar cfg: No such file or directory"
        " (radar.required = false: the daemon will run without the radar)\n"
    )


def test_the_signing_passphrase_comes_from_a_secret_file_and_is_never_shown(tmp_path: Path) -> None:
    from daemon.config import signing_passphrase

    secret = tmp_path / "mavlink-signing"
    secret.write_text("correct horse battery\n")
    secret.chmod(0o600)
    path = tmp_path / "c.toml"
    path.write_text(f'[radar]\nenabled = false\n[mavlink]\nsigning_passphrase_file = "{secret}"\n')
    assert signing_passphrase(load_config(path, check_files=True).mavlink) == "correct horse battery"
    res = check_config(path)
    assert (res.returncode, res.stdout, res.stderr) == (0, f"{path}: OK\n", "")
    # a file that is not there is named by check-config (exit 2), before systemd starts the daemon
    path.write_text(f'[radar]\nenabled = false\n[mavlink]\nsigning_passphrase_file = "{tmp_path / "absent"}"\n')
    res = check_config(path)
    assert res.returncode == 2
    assert (
        f"mavlink.signing_passphrase_file: cannot read {tmp_path / 'absent'}: No such file or directory" in res.stderr
    )
    # written in the config itself it still works, with a warning that never repeats it
    path.write_text('[radar]\nenabled = false\n[mavlink]\nsigning_passphrase = "correct horse battery"\n')
    res = check_config(path)
    assert res.returncode == 0 and "move it to a file" in res.stderr
    assert "correct horse" not in res.stdout + res.stderr
    path.write_text(
        f'[radar]\nenabled = false\n[mavlink]\nsigning_passphrase = "x"\nsigning_passphrase_file = "{secret}"\n'
    )
    with pytest.raises(ConfigError) as err:
        load_config(path)
    assert err.value.problems == [
        "mavlink.signing_passphrase, signing_passphrase_file: give one of them (the file, to keep it secret)"
    ]


def test_the_cycle_budget_must_leave_the_tick_room(tmp_path: Path) -> None:
    path = tmp_path / "c.toml"
    path.write_text("[output]\nrate_hz = 20.0\ncycle_budget_ms = 50.0\n")
    with pytest.raises(ConfigError) as err:
        load_config(path)
    assert err.value.problems == ["output.cycle_budget_ms: 50.0 must be within [0, the tick period) (0 = never skip)"]
    path.write_text("[output]\nrate_hz = 20.0\ncycle_budget_ms = 40.0\n")
    assert load_config(path).output.cycle_budget_ms == 40.0


def test_a_mount_table_that_sets_one_angle_keeps_the_shipped_offsets(tmp_path: Path) -> None:
    # A crew levelling the radar writes only its pitch: the radar must stay 0.5 m forward and 0.5 m up (its shipped
    # place, from which its height above the water and its coverage follow), not move to the body origin as a bare
    # mount table's defaults would put it. Before, [radar.mount] pitch = 5 alone put it at x = z = 0.
    path = tmp_path / "usv-tracker.toml"
    path.write_text("[radar.mount]\npitch = 5.0\n\n[lidar.mount]\nyaw = 10.0\n", encoding="utf-8")
    config = load_config(path)
    radar, lidar = config.radar.mount, config.lidar.mount
    assert (radar.x, radar.y, radar.z, radar.pitch) == (0.5, 0.0, -0.5, 5.0)
    assert (lidar.x, lidar.z, lidar.yaw) == (0.0, -1.0, 10.0)
    overridden = load_config(None, {"radar.mount.yaw": -30.0}).radar.mount
    assert (overridden.x, overridden.z, overridden.yaw) == (0.5, -0.5, -30.0)
