"""`usv-tracker replay`: a recording directory or its files, at N x real time or as fast as possible, with a progress
bar on a terminal and one summary line; the output is the deterministic replay's, byte for byte."""

from __future__ import annotations

import json
import os
import pty
import re
import select
import subprocess
import sys
import time
from pathlib import Path

import pytest

from daemon.cli import main
from daemon.replay import recording_config, run_replay
from simulator.capture import write_captures
from simulator.scenarios import get_scenario

SECONDS = 3.0
SUMMARY = re.compile(
    r"replayed ([\d.]+) s of data in ([\d.]+) s \(([\d.]+)x real time\): (\d+) ticks, (\d+) tracks \((\d+) confirmed\)"
)


@pytest.fixture(scope="module")
def recording(tmp_path_factory: pytest.TempPathFactory) -> Path:
    d = tmp_path_factory.mktemp("replay") / "run"
    write_captures("harbour", d, SECONDS, seed=0, scene=get_scenario("harbour"))
    return d


@pytest.fixture(scope="module")
def deterministic(recording: Path) -> dict[str, bytes]:
    """The existing deterministic replay path (run_replay on recording_config, as `run --fast` and the benches)."""
    out = {}
    for mode, lidar, radar in (("fused", True, True), ("lidar", True, False)):
        path = recording / f"deterministic-{mode}.jsonl"
        assert run_replay(recording_config(recording, path, lidar, radar), fast=True) == 0
        out[mode] = path.read_bytes()
    return out


def _ids(jsonl: bytes) -> tuple[set[int], set[int]]:
    every, confirmed = set(), set()
    for line in jsonl.splitlines():
        for t in json.loads(line)["tracks"]:
            every.add(t["id"])
            if t["confirmed"]:
                confirmed.add(t["id"])
    return every, confirmed


def test_replay_dir_fast_writes_exactly_what_the_deterministic_replay_writes(
    recording: Path, deterministic: dict[str, bytes], tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    out = tmp_path / "tracks.jsonl"
    assert main(["replay", str(recording), "--fast", "--tracks-out", str(out)]) == 0
    written = out.read_bytes()
    assert written == deterministic["fused"]
    rows = written.splitlines()
    # 3 s of data: 31 revolutions (the last one partial, flushed at the end of the capture), a tick after each
    assert len(rows) == 31
    assert sum(b'"obstacle_distance_cm":[' in r for r in rows) >= 28  # the premise: bins were sent, not withheld
    # the one summary line says what was replayed and written (stderr is no terminal here: no bar)
    err = capsys.readouterr().err
    assert "%|" not in err
    (m,) = SUMMARY.findall(err)
    every, confirmed = _ids(written)
    assert (float(m[0]), int(m[3]), int(m[4]), int(m[5])) == (3.1, 31, len(every), len(confirmed))
    assert len(confirmed) >= 3  # the harbour's vessels were tracked: the comparison compared something
    # the ratio of the two: all three are printed to 0.1, so the printed ratio must lie within what the two
    # rounded times allow (a 0.3 s wall time is 0.25-0.35 s: 8.9x-12.4x for 3.1 s of data), whatever the machine
    data_s, wall_s, ratio = float(m[0]), float(m[1]), float(m[2])
    lowest = (data_s - 0.05) / (wall_s + 0.05)
    highest = (data_s + 0.05) / max(wall_s - 0.05, 1e-3)
    assert lowest - 0.05 <= ratio <= highest + 0.05


def test_the_readme_run_command_and_the_replay_command_write_the_same(
    recording: Path, deterministic: dict[str, bytes], tmp_path: Path
) -> None:
    d = recording
    out = tmp_path / "run.jsonl"
    args = [
        "run", "--config", str(d / "usv-tracker.toml"),
        "--lidar", f"pcap://{d / 'lidar.pcap'}", "--radar-data", f"file://{d / 'radar.dat'}", "--radar-cli", "",
        "--radar-profile", str(d / "radar.cfg"), "--mavlink", str(d / "autopilot.tlog"),
        "--tracks-out", str(out), "--fast",
    ]  # fmt: skip
    assert main(args) == 0
    assert out.read_bytes() == deterministic["fused"]


def test_files_in_any_order_and_no_radar(recording: Path, deterministic: dict[str, bytes], tmp_path: Path) -> None:
    d = recording
    out = tmp_path / "files.jsonl"
    # radar.cfg found beside radar.dat, and the recording's usv-tracker.toml (its mounts) beside the captures
    files = [d / "autopilot.tlog", d / "radar.dat", d / "lidar.pcap"]
    assert main(["replay", *map(str, files), "--fast", "--tracks-out", str(out)]) == 0
    assert out.read_bytes() == deterministic["fused"]
    lidar_only = tmp_path / "lidar.jsonl"
    assert main(["replay", str(d), "--no-radar", "--fast", "--tracks-out", str(lidar_only)]) == 0
    assert lidar_only.read_bytes() == deterministic["lidar"]


def test_speed_keeps_the_pace_and_the_output(recording: Path, deterministic: dict[str, bytes], tmp_path: Path) -> None:
    out = tmp_path / "paced.jsonl"
    t0 = time.monotonic()
    assert main(["replay", str(recording), "--speed", "6", "--tracks-out", str(out)]) == 0
    took = time.monotonic() - t0
    # 3 s of data at 6x is 0.5 s at the least (a busy machine may take longer, never shorter)
    assert took >= SECONDS / 6 - 0.02
    assert out.read_bytes() == deterministic["fused"]


@pytest.mark.parametrize(
    ("extra", "message"),
    [
        (["--to", "udpout:127.0.0.1:9", "--fast"], "--to plays at the recorded pace"),
        (["--to", "udpout:127.0.0.1:9", "--speed", "2"], "--to plays at the recorded pace"),
        (["--pose", "live"], "--pose live takes the poses from the autopilot of --to URL"),
        (["--no-lidar", "--no-radar"], "leave nothing to replay"),
    ],
)
def test_flags_that_do_not_go_together_are_refused(
    recording: Path, extra: list[str], message: str, caplog: pytest.LogCaptureFixture
) -> None:
    assert main(["replay", str(recording), *extra]) == 2
    assert message in caplog.text


def test_paths_that_are_no_recording_are_refused_by_name(
    recording: Path, tmp_path: Path, caplog: pytest.LogCaptureFixture
) -> None:
    assert main(["replay", str(tmp_path)]) == 2
    assert f"{tmp_path}: no LiDAR capture (.pcap/.pcapng) and no radar capture (.dat) to replay" in caplog.text
    notes = tmp_path / "notes.txt"
    notes.write_text("x")
    assert main(["replay", str(recording / "lidar.pcap"), str(notes)]) == 2
    assert f"{notes}: not a capture this replay knows" in caplog.text
    assert main(["replay", str(recording / "lidar.pcap"), str(recording / "lidar.pcap")]) == 2
    assert "two lidar files" in caplog.text


def _replay_process(recording: Path, stderr_tty: bool, *extra: str) -> str:
    """`usv-tracker replay` as a person runs it; its stderr a real terminal (a pty) or a pipe."""
    args = [sys.executable, "-m", "daemon.cli", "replay", str(recording), *extra]
    if not stderr_tty:
        res = subprocess.run(args, capture_output=True, text=True, timeout=120)
        assert res.returncode == 0, res.stderr
        return res.stderr
    master, slave = pty.openpty()
    proc = subprocess.Popen(args, stdout=subprocess.DEVNULL, stderr=slave, env={**os.environ, "COLUMNS": "120"})
    os.close(slave)
    chunks = []
    try:
        while True:
            ready, _, _ = select.select([master], [], [], 60.0)
            if not ready:
                break
            try:
                data = os.read(master, 4096)
            except OSError:  # EIO: the process closed the terminal
                break
            if not data:
                break
            chunks.append(data)
        assert proc.wait(timeout=60) == 0
    finally:
        if proc.poll() is None:
            proc.kill()
        os.close(master)
    return b"".join(chunks).decode("utf-8", errors="replace")


def test_a_progress_bar_on_a_terminal_and_none_in_a_pipe(recording: Path) -> None:
    # at 3x real time the 3 s of data take a second: the bar is redrawn every 0.25 s meanwhile
    shown = _replay_process(recording, True, "--speed", "3")
    assert re.search(r"replay +\d+%\|.*\| [\d.]+/3\.[01] s of data \[", shown), shown[-2000:]
    assert re.search(r"[\d.]+x real time\]", shown), shown[-2000:]
    assert len(SUMMARY.findall(shown)) == 1
    piped = _replay_process(recording, False, "--speed", "3")
    assert "%|" not in piped and "s of data [" not in piped
    assert len(SUMMARY.findall(piped)) == 1
    quiet = _replay_process(recording, True, "--speed", "3", "--quiet")
    assert "%|" not in quiet and len(SUMMARY.findall(quiet)) == 1


def test_a_tlog_that_ends_early_is_said(recording: Path, tmp_path: Path, caplog: pytest.LogCaptureFixture) -> None:
    """A .tlog cut short (a full disk, a pulled card) leaves the end of the run without an own pose: the replay says
    how many ticks went without one, instead of looking whole."""
    import logging
    import shutil

    cut = tmp_path / "cut"
    shutil.copytree(recording, cut, ignore=shutil.ignore_patterns("*.jsonl"))
    tlog = (cut / "autopilot.tlog").read_bytes()
    (cut / "autopilot.tlog").write_bytes(tlog[: len(tlog) // 2])
    caplog.set_level(logging.WARNING, logger="daemon.replay")
    assert main(["replay", str(cut), "--fast", "--quiet", "--tracks-out", str(tmp_path / "t.jsonl")]) == 0
    said = [r.getMessage() for r in caplog.records if "had no own pose" in r.getMessage()]
    assert len(said) == 1
    n, total = map(int, re.match(r"(\d+) of (\d+) ticks", said[0]).groups())  # type: ignore[union-attr]
    assert total >= 25 and 0.3 * total <= n <= 0.7 * total  # about the half the .tlog no longer covers
    caplog.clear()
    assert main(["replay", str(recording), "--fast", "--quiet", "--tracks-out", str(tmp_path / "w.jsonl")]) == 0
    assert not any("had no own pose" in r.getMessage() for r in caplog.records)  # a whole .tlog: nothing said
