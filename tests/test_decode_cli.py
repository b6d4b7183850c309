"""`usv-tracker decode` on the public captures and on files that are not captures."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path


def decode(*args: str) -> subprocess.CompletedProcess[str]:
    return subprocess.run(
        [sys.executable, "-m", "daemon.cli", "decode", *args], capture_output=True, text=True, timeout=120
    )


def test_decode_vlp16_capture_json(shared_fixtures: Path) -> None:
    res = decode(str(shared_fixtures / "vlp16" / "rlu_velodyne_example.pcap"), "--json")
    assert res.returncode == 0, res.stderr
    rows = [json.loads(line) for line in res.stdout.splitlines()]
    revs, summary = rows[:-1], rows[-1]
    assert [r["points"] for r in revs] == [24144, 7486]  # cut astern; 31,630 in all as SOURCES.md says
    assert summary["summary"] and summary["points"] == 31630 and summary["data_packets"] == 84
    assert all(r["model"] == "VLP16" and r["return_mode"] == "strongest" for r in revs)


def test_decode_early_firmware_capture_as_vlp16(shared_fixtures: Path) -> None:
    res = decode(str(shared_fixtures / "vlp16" / "veloview_vlp-16-test-90deg-1-50-frames.pcap"), "--model", "VLP16")
    assert res.returncode == 0, res.stderr
    lines = [ln for ln in res.stdout.splitlines() if ln.startswith("rev ")]
    assert len(lines) == 51 and all("VLP16" in ln for ln in lines)
    assert "points 700400" in res.stdout


def test_decode_radar_dump(shared_fixtures: Path) -> None:
    res = decode(str(shared_fixtures / "awr1843" / "xwr18xx_sdk3.6_walk_50m.dat"))
    assert res.returncode == 0, res.stderr
    frames = [ln for ln in res.stdout.splitlines() if ln.startswith("frame ")]
    assert len(frames) == 440
    assert frames[0].split()[1] == "1986" and frames[-1].split()[1] == "2425"
    assert "frames 440" in res.stdout and "trailing_bytes 456" in res.stdout


def test_decode_every_shared_capture(shared_fixtures: Path) -> None:
    for path in sorted((shared_fixtures / "vlp16").glob("*.pcap")) + sorted(
        (shared_fixtures / "awr1843").glob("*.dat")
    ):
        res = decode(str(path), "--json")
        assert res.returncode == 0, (path, res.stderr)
        assert json.loads(res.stdout.splitlines()[-1])["summary"] is True


def test_not_a_capture_is_a_clear_error(tmp_path: Path) -> None:
    junk = tmp_path / "notes.txt"
    junk.write_text("hello, this is not a capture\n" * 20)
    res = decode(str(junk))
    assert res.returncode == 2
    assert "no valid AWR1843 data frame" in res.stderr and "pcap" in res.stderr
    empty_pcap = tmp_path / "empty.pcap"
    empty_pcap.write_bytes(bytes.fromhex("d4c3b2a1020004000000000000000000ffff000001000000"))
    res = decode(str(empty_pcap))
    assert res.returncode == 2 and "no VLP-16 data packets" in res.stderr
