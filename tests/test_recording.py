"""Finding a recording's captures from a directory or a list of files, and the config that replays them."""

from __future__ import annotations

from pathlib import Path

import pytest

from daemon.recording import Recording, RecordingError, find_recording, replay_config


def touch(*paths: Path) -> None:
    for p in paths:
        p.parent.mkdir(parents=True, exist_ok=True)
        p.write_bytes(b"")


def test_a_recorded_directory_by_its_standard_names(tmp_path: Path) -> None:
    d = tmp_path / "run"
    touch(*(d / n for n in ("lidar.pcap", "radar.dat", "radar.cfg", "autopilot.tlog", "usv-tracker.toml")))
    touch(d / "other.toml", d / "truth.csv")
    assert find_recording([d]) == Recording(
        d / "lidar.pcap", d / "radar.dat", d / "autopilot.tlog", d / "radar.cfg", d / "usv-tracker.toml"
    )


def test_a_directory_of_captures_named_otherwise_when_each_is_the_only_one_of_its_kind(tmp_path: Path) -> None:
    touch(tmp_path / "capture.pcapng", tmp_path / "2026-05-01.tlog", tmp_path / "extra.toml")
    rec = find_recording([tmp_path])
    assert (rec.lidar, rec.radar, rec.tlog, rec.config) == (
        tmp_path / "capture.pcapng",
        None,
        tmp_path / "2026-05-01.tlog",
        None,  # a .toml of another name is not taken for the recording's config
    )
    touch(tmp_path / "second.pcap")
    with pytest.raises(RecordingError, match=r"2 lidar files \(capture.pcapng, second.pcap\): name them"):
        find_recording([tmp_path])


def test_files_by_suffix_with_the_profile_found_beside_the_radar_dump(tmp_path: Path) -> None:
    touch(tmp_path / "a" / "x.dat", tmp_path / "a" / "radar.cfg", tmp_path / "b" / "y.PCAP")
    rec = find_recording([tmp_path / "a" / "x.dat", tmp_path / "b" / "y.PCAP"])
    assert rec == Recording(tmp_path / "b" / "y.PCAP", tmp_path / "a" / "x.dat", None, tmp_path / "a" / "radar.cfg")
    with pytest.raises(RecordingError, match="no such file"):
        find_recording([tmp_path / "missing.pcap"])
    with pytest.raises(RecordingError, match="a directory is replayed alone"):
        find_recording([tmp_path / "a", tmp_path / "b" / "y.PCAP"])


def test_captures_named_one_by_one_take_their_recordings_config(tmp_path: Path) -> None:
    """The simulator's usv-tracker.toml (the sensor mounts) beside captures named one by one is theirs, as it is
    when the directory is named; captures from two places have no one recording's config."""
    d = tmp_path / "run"
    touch(*(d / n for n in ("lidar.pcap", "radar.dat", "autopilot.tlog", "usv-tracker.toml")))
    assert find_recording([d / "radar.dat", d / "lidar.pcap"]).config == d / "usv-tracker.toml"
    assert find_recording([d / "lidar.pcap"]).config == d / "usv-tracker.toml"
    touch(tmp_path / "elsewhere" / "a.tlog")
    assert find_recording([d / "lidar.pcap", tmp_path / "elsewhere" / "a.tlog"]).config is None


def test_the_config_replays_the_captures_and_writes_nothing_but_the_tracks(tmp_path: Path) -> None:
    toml = tmp_path / "boat.toml"
    toml.write_text(
        '[output]\ntracks_out = "/var/log/usv-tracker/tracks.jsonl"\nrecord_dir = "/var/lib/usv-tracker"\n'
        "[lidar]\nmount = { x = 0.5, y = 0.0, z = -1.6, roll = 0.0, pitch = 0.0, yaw = 0.0 }\n"
    )
    rec = Recording(lidar=tmp_path / "l.pcap", tlog=tmp_path / "a.tlog")
    c = replay_config(rec, None, config_path=toml)
    assert (c.output.tracks_out, c.output.record_dir) == ("", "")  # the boat's logs are never overwritten
    assert c.lidar.mount.x == 0.5  # the boat's mounts are kept
    assert (c.lidar.enabled, c.lidar.source, c.radar.enabled) == (True, f"pcap://{tmp_path / 'l.pcap'}", False)
    c = replay_config(rec, tmp_path / "t.jsonl", lidar=False, config_path=toml)
    assert (c.lidar.enabled, c.output.tracks_out) == (False, str(tmp_path / "t.jsonl"))
