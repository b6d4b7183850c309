"""The CLI session against the device emulator, over real pseudo-terminals opened by path."""

from __future__ import annotations

import os
from collections.abc import Iterator
from pathlib import Path

import pytest
import serial

from drivers.awr1843.cli import CliSession
from drivers.awr1843.errors import RadarConfigError, RadarPortError
from drivers.awr1843.profile import RadarProfile, load_profile, parse_profile
from simulator.awr1843_device import Awr1843Emulator

CFG = "awr1843/xwr18xx_best_range_50m_vis3.6.cfg"


@pytest.fixture
def profile(shared_fixtures: Path) -> RadarProfile:
    return load_profile(shared_fixtures / CFG)


@pytest.fixture
def emulator() -> Iterator[Awr1843Emulator]:
    emu = Awr1843Emulator()
    emu.start()
    yield emu
    emu.stop()


def test_full_start_up_sends_every_line_in_order(emulator: Awr1843Emulator, profile: RadarProfile) -> None:
    with CliSession(emulator.cli_path) as cli:
        replies = cli.configure(profile)
    assert emulator.received_lines == ["", "sensorStop", "flushCfg", *[line.text for line in profile.lines]]
    assert [r.command for r in replies] == ["sensorStop", "flushCfg", *[line.text for line in profile.lines]]
    # sensorStop on a stopped sensor: "Ignored: Sensor is already stopped" then Done is success
    assert replies[0].status == "ignored"
    assert replies[0].lines == ("Ignored: Sensor is already stopped", "Done")
    assert all(r.status == "done" and r.lines == ("Done",) for r in replies[1:] if r.command != "sensorStop")
    assert emulator.sensor_running
    assert emulator.frame_period_s == pytest.approx(0.1)


def test_refused_line_names_line_number_text_and_answer(profile: RadarProfile) -> None:
    bad = "cfarCfg -1 1 0 4 2 3 1 15 1"
    with Awr1843Emulator(failing_lines={bad: -1}) as emu, CliSession(emu.cli_path) as cli:
        with pytest.raises(RadarConfigError) as err:
            cli.configure(profile)
        received = list(emu.received_lines)
        running = emu.sensor_running
    e = err.value
    assert (e.line_number, e.line) == (28, bad)
    assert e.reply == "Error: Invalid usage of the CLI command | Error -1"
    assert "cfg line 28: 'cfarCfg -1 1 0 4 2 3 1 15 1'" in str(e)
    assert "Error -1" in str(e)
    assert received[-1] == bad  # nothing was sent after the refused line
    assert not running


def test_unknown_command_is_an_error_with_its_line(emulator: Awr1843Emulator) -> None:
    text = "profileCfg 0 77 7 3 39 0 0 100 1 256 7200 0 0 30\nchirpCfg 0 0 0 0 0 0 0 1\n"
    text += "frameCfg 0 0 16 0 100 1 0\nfancyCfg 1 2\nsensorStart\n"
    with CliSession(emulator.cli_path) as cli, pytest.raises(RadarConfigError) as err:
        cli.configure(parse_profile(text))
    assert err.value.line_number == 4
    assert err.value.reply == "'fancyCfg' is not recognized as a CLI command"


def test_garbage_at_boot_is_absorbed_by_the_wake_up(profile: RadarProfile) -> None:
    with Awr1843Emulator(boot_garbage=b"\xfe?`\x8f") as emu, CliSession(emu.cli_path) as cli:
        cli.configure(profile)
        assert emu.received_lines[0].endswith("?`\ufffd")  # the garbled first "line"
        assert emu.received_lines[1:3] == ["sensorStop", "flushCfg"]
        assert emu.sensor_running


def test_garbled_first_command_is_sent_again() -> None:
    with Awr1843Emulator(boot_garbage=b"?`?") as emu, CliSession(emu.cli_path) as cli:
        reply = cli.command("sensorStop")  # no wake-up first: the line arrives as "?`?sensorStop"
        assert reply.status == "ignored"
        assert emu.received_lines == ["?`?sensorStop", "", "sensorStop"]


def test_a_command_garbled_twice_is_an_error_that_can_mend() -> None:
    # Marked as mendable, the daemon keeps retrying the radar instead of running without it until a restart.
    with Awr1843Emulator(garbled_lines=2) as emu, CliSession(emu.cli_path) as cli:
        with pytest.raises(RadarConfigError, match="garbled twice") as err:
            cli.command("sensorStop")
        assert err.value.silent
        assert emu.received_lines == ["?sensorStop", "", "?sensorStop"]
        assert cli.command("sensorStop").status == "ignored"  # the line is clean again: it answers


def test_silent_port_gives_no_prompt_error(tmp_path: Path) -> None:
    master, slave = os.openpty()  # a port where nobody answers (data port, or board in flashing mode)
    try:
        with CliSession(os.ttyname(slave), wake_timeout=0.1, wake_attempts=3) as cli:
            with pytest.raises(RadarConfigError, match=r"no 'mmwDemo:/>' prompt .* after 3 newlines"):
                cli.wake()
            assert os.read(master, 100) == b"\n\n\n"
    finally:
        os.close(master)
        os.close(slave)


def test_slow_command_times_out_with_its_line(profile: RadarProfile) -> None:
    with (
        Awr1843Emulator(sensor_start_delay_s=1.0) as emu,
        CliSession(emu.cli_path, slow_command_timeout=0.3) as cli,
        pytest.raises(RadarConfigError) as err,
    ):
        cli.configure(profile)
    assert (err.value.line_number, err.value.line) == (43, "sensorStart")
    assert "no prompt within 0.3 s" in str(err.value)


def test_missing_port(tmp_path: Path) -> None:
    with pytest.raises(RadarPortError, match=r"AWR1843 CLI port .*/ttyACM9 does not exist") as err:
        CliSession(str(tmp_path / "ttyACM9")).open()
    assert err.value.errno == 2


def test_busy_port(emulator: Awr1843Emulator) -> None:
    holder = serial.Serial(emulator.cli_path, 115200, exclusive=True)
    try:
        with pytest.raises(RadarPortError, match="is busy: another program has it open"):
            CliSession(emulator.cli_path).open()
    finally:
        holder.close()


@pytest.mark.skipif(os.geteuid() == 0, reason="root opens any device node")
def test_permission_denied_port(emulator: Awr1843Emulator) -> None:
    os.chmod(emulator.cli_path, 0)
    with pytest.raises(RadarPortError, match="permission denied; add the service user to the 'dialout' group"):
        CliSession(emulator.cli_path).open()


def test_by_id_symlink_is_resolved_for_the_log(tmp_path: Path, caplog: pytest.LogCaptureFixture) -> None:
    with Awr1843Emulator(link_dir=tmp_path / "by-id") as emu:
        caplog.set_level("INFO", logger="drivers.awr1843.ports")
        with CliSession(emu.cli_path) as cli:
            cli.wake()
        target = os.path.realpath(emu.cli_path)
        assert target.startswith("/dev/pts/")
    assert f"{tmp_path}/by-id/awr1843-cli -> {target}" in caplog.text
