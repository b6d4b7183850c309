"""What a recording is made of, found from a directory or a list of files, and the config that replays it.

A directory is what `usv-tracker run --record` or `simulate --write` wrote (lidar.pcap, radar.dat with its .times
sidecar, radar.cfg, autopilot.tlog, and the simulator's usv-tracker.toml); a capture named otherwise is still
found when it is the only one of its kind there (dumpcap's `capture.pcapng`). Files are told apart by their
suffix: .pcap/.pcapng LiDAR, .dat radar, .tlog autopilot, .cfg chirp profile, .toml config.
"""

from __future__ import annotations

import logging
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

from daemon.config import DEFAULT_CONFIG_PATH, Config, load_config

log = logging.getLogger(__name__)

KINDS = {
    ".pcap": "lidar",
    ".pcapng": "lidar",
    ".dat": "radar",
    ".tlog": "tlog",
    ".cfg": "profile",
    ".toml": "config",
}
STANDARD_NAMES = {
    "lidar": ("lidar.pcap", "lidar.pcapng"),
    "radar": ("radar.dat",),
    "tlog": ("autopilot.tlog",),
    "profile": ("radar.cfg",),
    "config": ("usv-tracker.toml",),
}


class RecordingError(ValueError):
    """The paths given do not make a recording; the message says which and why."""


@dataclass
class Recording:
    lidar: Path | None = None
    radar: Path | None = None
    tlog: Path | None = None
    profile: Path | None = None  # the radar's chirp cfg
    config: Path | None = None  # a config that came with the recording (the simulator's sensor mounts)


def find_recording(paths: Sequence[str | Path]) -> Recording:
    """A recording directory (alone), or capture files in any order; raises RecordingError."""
    items = [Path(p) for p in paths]
    if not items:
        raise RecordingError("no recording given: a directory, or capture files")
    if len(items) == 1 and items[0].is_dir():
        return _from_directory(items[0])
    found: dict[str, Path] = {}
    for p in items:
        if p.is_dir():
            raise RecordingError(f"{p}: a directory is replayed alone, not among files")
        if not p.is_file():
            raise RecordingError(f"{p}: no such file")
        kind = KINDS.get(p.suffix.lower())
        if kind is None:
            raise RecordingError(f"{p}: not a capture this replay knows ({', '.join(KINDS)})")
        if kind in found:
            raise RecordingError(f"two {kind} files: {found[kind]} and {p} (one recording at a time)")
        found[kind] = p
    rec = Recording(**found)
    if rec.radar is not None and rec.profile is None and (rec.radar.parent / "radar.cfg").is_file():
        rec.profile = rec.radar.parent / "radar.cfg"  # recorded beside it
    folders = {p.resolve().parent for p in items}
    if rec.config is None and len(folders) == 1 and (items[0].parent / "usv-tracker.toml").is_file():
        # the captures of one recording named one by one are that recording: its config (the simulator's sensor
        # mounts) replays them as the directory would; default mounts put every LiDAR return at the wrong height
        rec.config = items[0].parent / "usv-tracker.toml"
    return _checked(rec)


def _from_directory(d: Path) -> Recording:
    found: dict[str, Path] = {}
    for kind, names in STANDARD_NAMES.items():
        standard = [d / n for n in names if (d / n).is_file()]
        if standard:
            found[kind] = standard[0]
            continue
        if kind == "config":
            continue  # any other .toml there is not assumed to be this recording's
        others = sorted(p for p in d.iterdir() if p.is_file() and KINDS.get(p.suffix.lower()) == kind)
        if len(others) == 1:
            found[kind] = others[0]
        elif others:
            raise RecordingError(f"{d}: {len(others)} {kind} files ({', '.join(p.name for p in others)}): name them")
    return _checked(Recording(**found), d)


def _checked(rec: Recording, where: Path | None = None) -> Recording:
    if rec.lidar is None and rec.radar is None:
        place = f"{where}: " if where is not None else ""
        raise RecordingError(f"{place}no LiDAR capture (.pcap/.pcapng) and no radar capture (.dat) to replay")
    return rec


def replay_config(
    rec: Recording,
    tracks_out: str | Path | None = None,
    *,
    lidar: bool = True,
    radar: bool = True,
    config_path: str | Path | None = None,
) -> Config:
    """The config that replays ``rec``: ``config_path`` if given, else the recording's own, else the installed one
    (on the boat it has the sensor mounts the recording was made with), else the defaults; with the recording's
    captures as sources and nothing written but ``tracks_out``. Raises daemon.config_schema.ConfigError."""
    base = Path(config_path) if config_path is not None else rec.config
    if base is None and DEFAULT_CONFIG_PATH.exists():
        base = DEFAULT_CONFIG_PATH
    log.info("replay config: %s", base if base is not None else "defaults")
    for name, capture in (("LiDAR", rec.lidar), ("radar", rec.radar)):
        if capture is None:
            log.info("the recording holds no %s capture: %s off for this replay", name, name)
    overrides: dict[str, object] = {
        "lidar.enabled": lidar and rec.lidar is not None,
        "radar.enabled": radar and rec.radar is not None,
        "radar.cli": "",
        # a config's own outputs (the boat's tracks log, its recording directory) are never written by a replay
        "output.tracks_out": str(tracks_out) if tracks_out is not None else "",
        "output.record_dir": "",
    }
    if rec.lidar is not None:
        overrides["lidar.source"] = f"pcap://{rec.lidar}"
    if rec.radar is not None:
        overrides["radar.data"] = f"file://{rec.radar}"
    if rec.profile is not None:
        overrides["radar.profile"] = str(rec.profile)
    return load_config(base, overrides)


def data_end(rec: Recording, config: Config) -> float | None:
    """The time (s, the recording's clock) of the last sensor datum the replay will use; None when not known
    cheaply (a radar dump without its .times sidecar, replayed alone)."""
    from drivers.awr1843.timed_capture import read_sidecar
    from drivers.vlp16.pcap import PcapReader

    ends = []
    if config.lidar.enabled and rec.lidar is not None:
        ends.append(PcapReader(rec.lidar).last_time())
    if config.radar.enabled and rec.radar is not None:
        side = read_sidecar(rec.radar)
        ends.append(float(side[1][-1]) if side is not None else None)
    known = [e for e in ends if e is not None]
    return max(known) if known else None
