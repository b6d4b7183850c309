"""The cfg parser on TI's real cfg files: derived chirp-design numbers pinned against the cfg headers."""

from __future__ import annotations

import resource
import subprocess
import sys
from pathlib import Path

import pytest

from drivers.awr1843.errors import RadarProfileError
from drivers.awr1843.profile import MAX_CFG_BYTES, load_profile, parse_profile
from tests.conftest import OWN_FIXTURES

BEST_RANGE_50M = "awr1843/xwr18xx_best_range_50m_vis3.6.cfg"
PROFILE_2D = "awr1843/xwr18xx_sdk3.5_profile_2d.cfg"

MINIMAL = """\
% a comment
profileCfg 0 77 7 3 39 0 0 100 1 256 7200 0 0 30

chirpCfg 0 0 0 0 0 0 0 1
chirpCfg 1 1 0 0 0 0 0 4
frameCfg 0 1 32 0 50 1 0
sensorStart
"""


def test_best_range_50m_cfg(shared_fixtures: Path) -> None:
    p = load_profile(shared_fixtures / BEST_RANGE_50M)
    # frameCfg 0 1 16 0 100 1 0: periodicity 100 ms is the frame-start interval
    assert p.frame_period_ms == 100.0
    assert p.frame_period_s == pytest.approx(0.1)
    assert (p.chirp_start, p.chirp_end, p.num_loops, p.num_frames) == (0, 1, 16, 0)
    assert p.chirps_per_loop == 2
    assert p.num_range_bins == 256
    assert p.num_doppler_bins == 16
    # c*fs/(2*S*Nr) = 3e8 * 12.499e6 / (2 * 30e12 * 256); the Visualizer header says 0.244 m
    assert p.range_bin_m == pytest.approx(3e8 * 12.499e6 / (2 * 30e12 * 256))
    assert p.range_bin_m == pytest.approx(0.244, abs=5e-4)
    assert p.range_resolution_m == pytest.approx(p.range_bin_m)  # 256 samples: power of two
    assert p.max_range_m == pytest.approx(62.495)  # IF limit; the Visualizer advertises 50 m
    # lambda = c / 77 GHz, Tc = 458 + 28.49 us: v_max = lambda / (4 * 2 * Tc) ~ 1 m/s (header: 1)
    lam = 3e8 / 77e9
    tc = 486.49e-6
    assert p.wavelength_m == pytest.approx(lam)
    assert p.max_velocity_mps == pytest.approx(lam / (8 * tc))
    assert p.max_velocity_mps == pytest.approx(1.0, abs=0.01)
    assert p.velocity_resolution_mps == pytest.approx(lam / (2 * 2 * tc * 16))
    assert p.velocity_resolution_mps == pytest.approx(0.125, abs=0.001)  # header: 0.13
    assert p.active_frame_time_s == pytest.approx(2 * 16 * tc)
    assert p.sdk_hint == (3, 6)
    assert p.gui_monitor == (1, 1, 0, 0, 0, 1)
    assert p.range_fov_m == (0.0, 49.99)
    assert p.velocity_fov_mps == (-1.0, 1.0)
    # 14 comment lines skipped, line numbers kept
    assert len(p.lines) == 29
    assert (p.lines[0].number, p.lines[0].text) == (15, "sensorStop")
    assert (p.lines[13].number, p.lines[13].text) == (28, "cfarCfg -1 1 0 4 2 3 1 15 1")
    assert (p.lines[-1].number, p.lines[-1].text) == (43, "sensorStart")
    assert p.sends_sensor_start


def test_sdk_profile_2d_cfg_matches_its_own_header(shared_fixtures: Path) -> None:
    p = load_profile(shared_fixtures / PROFILE_2D)
    assert p.frame_period_s == pytest.approx(0.1)
    assert p.num_range_bins == 256
    assert p.range_bin_m == pytest.approx(0.0421875)  # header: 0.042 m/bin
    assert p.max_range_m == pytest.approx(10.8)  # header: 8.64 m = 80 % of it
    assert p.max_velocity_mps == pytest.approx(10.587, abs=1e-3)  # header: 10.59
    assert p.velocity_resolution_mps == pytest.approx(0.6617, abs=1e-4)  # header: 0.66
    assert p.active_frame_time_s == pytest.approx(2.944e-3)  # header: "Frame time (total) 2.944 ms"
    assert p.sdk_hint is None
    assert p.gui_monitor == (1, 1, 1, 0, 0, 1)
    assert p.range_fov_m == (0.25, 8.64)
    assert p.lines[0].number == 36


def test_non_power_of_two_samples_pad_the_range_fft() -> None:
    p = parse_profile(MINIMAL.replace(" 256 7200 ", " 200 7200 "), source="x.cfg")
    assert p.num_range_bins == 256
    assert p.range_resolution_m == pytest.approx(3e8 * 7.2e6 / (2 * 100e12 * 200))
    assert p.range_bin_m == pytest.approx(3e8 * 7.2e6 / (2 * 100e12 * 256))
    assert p.frame_period_s == pytest.approx(0.05)
    assert [line.number for line in p.lines] == [2, 4, 5, 6, 7]


@pytest.mark.parametrize(
    ("bad_line", "replaces", "number", "message"),
    [
        ("frameCfg 0 1 32 0", "frameCfg 0 1 32 0 50 1 0", 6, "frameCfg needs at least 7 arguments, got 4"),
        ("frameCfg 0 1 32 0 fifty 1 0", "frameCfg 0 1 32 0 50 1 0", 6, "argument 5 is not a number: 'fifty'"),
        ("chirpCfg 1 1 0 0 0 0 0 4.5x", "chirpCfg 1 1 0 0 0 0 0 4", 5, "argument 8 is not a number"),
        (
            "frameCfg 0 1 0 0 50 1 0",
            "frameCfg 0 1 32 0 50 1 0",
            6,
            "argument 3 is 0, outside the device's range 1..255",
        ),
        (
            "profileCfg 0 77 7 3 39 0 0 100 1 256.5 7200 0 0 30",
            "profileCfg 0 77 7 3 39 0 0 100 1 256 7200 0 0 30",
            2,
            "argument 10 must be an integer",
        ),
    ],
)
def test_malformed_known_command_names_the_line(bad_line: str, replaces: str, number: int, message: str) -> None:
    with pytest.raises(RadarProfileError) as err:
        parse_profile(MINIMAL.replace(replaces, bad_line), source="boat.cfg")
    assert err.value.line_number == number
    assert err.value.line == bad_line
    assert message in str(err.value)
    assert str(err.value).startswith(f"boat.cfg:{number}: ")


def test_missing_chirp_and_frame_lines() -> None:
    with pytest.raises(RadarProfileError, match="no frameCfg line"):
        parse_profile(MINIMAL.replace("frameCfg 0 1 32 0 50 1 0", ""), source="a.cfg")
    with pytest.raises(RadarProfileError, match=r"chirp\(s\) \[1\] that no chirpCfg line defines") as err:
        parse_profile(MINIMAL.replace("chirpCfg 1 1 0 0 0 0 0 4", ""), source="a.cfg")
    assert err.value.line_number == 6
    with pytest.raises(RadarProfileError, match="profile 3, which no profileCfg") as err:
        parse_profile(MINIMAL.replace("chirpCfg 0 0 0 0", "chirpCfg 0 0 3 0"), source="a.cfg")
    assert err.value.line_number == 4


def test_unknown_commands_are_kept_for_the_device_to_judge() -> None:
    p = parse_profile(MINIMAL.replace("sensorStart", "fancyNewCfg a b\nsensorStart"))
    assert [line.command for line in p.lines][-2:] == ["fancyNewCfg", "sensorStart"]


def test_unreadable_file_is_a_clear_error(tmp_path: Path) -> None:
    with pytest.raises(RadarProfileError, match="cannot read radar cfg"):
        load_profile(tmp_path / "missing.cfg")


def _one_gib_address_space() -> None:
    # The unfixed parser filled a table of a billion chirps (2.3 GB): under this limit it fails in seconds.
    resource.setrlimit(resource.RLIMIT_AS, (1 << 30, 1 << 30))


@pytest.mark.parametrize(
    ("name", "number", "message"),
    [
        ("awr1843_chirp_inf.cfg", 4, "chirpCfg argument 2 is not a finite number: '1e999'"),
        ("awr1843_chirp_billion.cfg", 4, "chirpCfg argument 2 is 1e9, outside the device's range 0..511"),
        ("awr1843_frame_billion.cfg", 5, "frameCfg argument 2 is 1e9, outside the device's range 0..511"),
    ],
)
def test_counts_beyond_the_device_are_named_by_decode(name: str, number: int, message: str) -> None:
    cfg = OWN_FIXTURES / "fuzz" / name
    res = subprocess.run(
        [
            sys.executable,
            "-m",
            "daemon.cli",
            "decode",
            str(OWN_FIXTURES / "awr1843_synthetic.dat"),
            "--profile",
            str(cfg),
        ],
        capture_output=True,
        text=True,
        timeout=120,
        preexec_fn=_one_gib_address_space,
    )
    assert (res.returncode, res.stdout) == (2, "")
    assert res.stderr.startswith(f"usv-tracker decode: radar cfg refused: {cfg}:{number}: {message} (line: ")
    with pytest.raises(RadarProfileError) as err:
        load_profile(cfg)
    assert err.value.line_number == number
    assert message in str(err.value)


@pytest.mark.parametrize(
    ("bad_line", "replaces", "message"),
    [
        (
            "profileCfg 4 77 7 3 39 0 0 100 1 256 7200 0 0 30",
            "profileCfg 0 ",
            "argument 1 is 4, outside the device's range 0..3",
        ),
        (
            "profileCfg 0 77 7 3 39 0 0 100 1 1e6 7200 0 0 30",
            "profileCfg 0 ",
            "argument 10 is 1e6, outside the device's range 2..16384",
        ),
        ("chirpCfg 0 0 7 0 0 0 0 1", "chirpCfg 0 0 ", "argument 3 is 7, outside the device's range 0..3"),
        ("frameCfg 0 1 256 0 50 1 0", "frameCfg ", "argument 3 is 256, outside the device's range 1..255"),
        ("frameCfg 0 1 32 70000 50 1 0", "frameCfg ", "argument 4 is 70000, outside the device's range 0..65535"),
        ("frameCfg 0 1 32 0 nan 1 0", "frameCfg ", "argument 5 is not a number: 'nan'"),
        ("frameCfg 0 1 32 0 -1e999 1 0", "frameCfg ", "argument 5 is not a finite number: '-1e999'"),
    ],
)
def test_every_count_and_index_is_held_to_the_device_limits(bad_line: str, replaces: str, message: str) -> None:
    lines = MINIMAL.splitlines()
    number = next(i for i, line in enumerate(lines, start=1) if line.startswith(replaces))
    lines[number - 1] = bad_line
    with pytest.raises(RadarProfileError) as err:
        parse_profile("\n".join(lines), source="boat.cfg")
    assert (err.value.line_number, err.value.line) == (number, bad_line)
    assert message in str(err.value)


def test_a_file_far_larger_than_any_cfg_is_not_read_whole() -> None:
    with pytest.raises(RadarProfileError) as err:
        load_profile("/dev/zero")
    assert str(err.value) == f"/dev/zero: larger than {MAX_CFG_BYTES // 1024} KiB: not a radar cfg"


@pytest.mark.parametrize(
    ("bad_line", "unusable"),
    [
        ("profileCfg 0 77 1e-310 3 0 0 0 100 1 256 7200 0 0 30", "max_velocity_mps, velocity_resolution_mps"),
        ("profileCfg 0 77 7 3 39 0 0 100 1 256 1e300 0 0 30", "range_bin_m, range_resolution_m, max_range_m"),
    ],
)
def test_finite_numbers_that_multiply_out_to_no_chirp_design(bad_line: str, unusable: str) -> None:
    with pytest.raises(RadarProfileError) as err:
        parse_profile(MINIMAL.replace("profileCfg 0 77 7 3 39 0 0 100 1 256 7200 0 0 30", bad_line), source="b.cfg")
    assert (err.value.line_number, err.value.line) == (2, bad_line)
    assert f"profileCfg gives no usable chirp design ({unusable} not a finite positive number)" in str(err.value)
