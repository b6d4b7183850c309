"""The daemon's configuration: one TOML file, sections lidar, radar, mavlink, boat, output, tracker.

Every paper parameter lives in the tracker sections with the paper's value as its default, so an empty file is a
valid configuration of the algorithms as published. Lengths in metres, angles in DEGREES in the file (people edit
it) and radians inside (converted here, once).
"""

from __future__ import annotations

import ipaddress
import math
import sys
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from daemon.autopilot_url import parse_autopilot_url
from daemon.config_schema import ConfigError, build_with_problems
from daemon.source_url import SourceUrlError, parse_source_url
from daemon.tracker_configs import tracker_config_problems
from drivers.awr1843.expected import platform_code
from drivers.mount import Mount

if sys.version_info >= (3, 11):
    import tomllib
else:  # Ubuntu 22.04 / Jetson ships Python 3.10
    import tomli as tomllib

DEFAULT_CONFIG_PATH = Path("/etc/usv-tracker/usv-tracker.toml")
# "9" followed by the MID "00": the ITU allocates no station there, so a tracked boat sent as AIS_VESSEL cannot take
# the MMSI of a real one on the ground station's map.
AIS_MMSI_BASE = 900_000_000
# The example file is 4 KiB; a path to a capture or to /dev/zero must not be read whole.
MAX_CONFIG_BYTES = 1 << 20


def _is_ipv4(text: str) -> bool:
    try:
        ipaddress.IPv4Address(text)
    except ValueError:
        return False
    return True


@dataclass
class MountConfig:
    """Sensor pose in the body frame (FRD): metres and degrees."""

    x: float = 0.0
    y: float = 0.0
    z: float = 0.0
    roll: float = 0.0
    pitch: float = 0.0
    yaw: float = 0.0

    def to_mount(self) -> Mount:
        return Mount.from_degrees(self.x, self.y, self.z, self.roll, self.pitch, self.yaw)

    def validate(self) -> list[str]:
        bad = [
            f"{k}: must be within -360..360 degrees" for k in ("roll", "pitch", "yaw") if abs(getattr(self, k)) > 360
        ]
        bad += [
            f"{k}: {getattr(self, k)} m is not a plausible mount offset" for k in "xyz" if abs(getattr(self, k)) > 50
        ]
        return bad


@dataclass
class LidarConfig:
    enabled: bool = True
    source: str = "udp://0.0.0.0:2368"
    position_port: int = 8308
    accept_ip: str = ""  # the sensor's IPv4 address; empty: the first sender that looks like a VLP-16 (sender_lock.py)
    lock_timeout_s: float = 2.0  # with accept_ip empty: silence of the locked sender after which another may take over
    model: str = "VLP16"  # VLP16: VLP-16 geometry whatever the product byte says (early firmware: 0x21); auto: trust it
    cut_angle_deg: float = 180.0  # revolution boundary in the sensor frame; astern keeps the bow whole
    silence_timeout_s: float = 2.0
    min_range_m: float = 0.5
    max_range_m: float = 100.0
    mount: MountConfig = field(default_factory=lambda: MountConfig(z=-1.0))

    def validate(self) -> list[str]:
        out = []
        if self.enabled:
            try:
                parse_source_url(self.source, {"udp", "pcap"})
            except SourceUrlError as exc:
                out.append(f"source: {exc}")
        if self.model not in ("auto", "VLP16"):
            out.append(f"model: expected 'auto' or 'VLP16', got {self.model!r}")
        if not 0 < self.position_port < 65536:
            out.append(f"position_port: {self.position_port} is not a UDP port")
        if not 0 <= self.min_range_m < self.max_range_m:
            out.append("min_range_m/max_range_m: need 0 <= min_range_m < max_range_m")
        if self.silence_timeout_s <= 0:
            out.append("silence_timeout_s: must be > 0")
        if self.lock_timeout_s <= 0:
            out.append("lock_timeout_s: must be > 0")
        if not -360 <= self.cut_angle_deg <= 360:
            out.append(f"cut_angle_deg: {self.cut_angle_deg} must be within -360..360 degrees")
        if self.accept_ip and not _is_ipv4(self.accept_ip):
            out.append(
                f"accept_ip: {self.accept_ip!r} is not an IPv4 address (the VLP-16 sends from one, e.g. 192.168.1.201)"
            )
        return out

    def file_problems(self, prefix: str) -> list[str]:
        """The capture a pcap:// source replays must be there and be a capture."""
        if not self.enabled:
            return []
        from drivers.vlp16.pcap import NotAPcapError, capture_format

        try:
            url = parse_source_url(self.source, {"udp", "pcap"})
        except SourceUrlError:
            return []  # already named by validate()
        if url.scheme != "pcap":
            return []
        try:
            capture_format(url.path)
        except FileNotFoundError:
            return [f"{prefix}.source: capture file not found: {url.path}"]
        except OSError as exc:
            return [f"{prefix}.source: cannot read {url.path}: {exc.strerror or exc}"]
        except NotAPcapError as exc:
            return [f"{prefix}.source: {exc}"]
        return []


@dataclass
class RadarConfig:
    enabled: bool = True
    cli: str = "serial:///dev/ttyACM0?baud=115200"
    data: str = "serial:///dev/ttyACM1?baud=921600"
    profile: str = "/etc/usv-tracker/awr1843.cfg"
    # The chip family the data port's frames must name (drivers/awr1843/expected.py): frames of another board are
    # rejected. "any": not checked.
    platform: str = "xWR18xx"
    required: bool = False  # false: a radar that fails to start leaves the daemon running LiDAR-only
    silence_timeout_s: float = 2.0
    fov_deg: float = 120.0  # horizontal field of view, centred on the mount's yaw
    max_range_m: float = 50.0
    mount: MountConfig = field(default_factory=lambda: MountConfig(x=0.5, z=-0.5))

    def validate(self) -> list[str]:
        out = []
        if self.enabled:
            for key in ("cli", "data"):
                value = getattr(self, key)
                if key == "cli" and not value:
                    continue  # no CLI port: replay, or a radar configured by someone else
                try:
                    parse_source_url(value, {"serial", "file"})
                except SourceUrlError as exc:
                    out.append(f"{key}: {exc}")
        try:
            platform_code(self.platform)
        except ValueError as exc:
            out.append(f"platform: {exc}")
        if not 0 < self.fov_deg <= 360:
            out.append(f"fov_deg: {self.fov_deg} must be in (0, 360]")
        if self.max_range_m <= 0:
            out.append("max_range_m: must be > 0")
        if self.silence_timeout_s <= 0:
            out.append(f"silence_timeout_s: {self.silence_timeout_s} must be > 0")
        return out

    def file_problems(self, prefix: str) -> list[str]:
        """The chirp cfg is opened and parsed by the driver's own parser; a file:// dump must be there."""
        if not self.enabled:
            return []
        from drivers.awr1843.errors import RadarProfileError
        from drivers.awr1843.profile import load_profile

        out = []
        try:
            data = parse_source_url(self.data, {"serial", "file"})
        except SourceUrlError:
            data = None  # already named by validate()
        if self.profile:
            try:
                load_profile(self.profile)
            except RadarProfileError as exc:
                out.append(f"{prefix}.profile: {exc}")
        elif self.cli and data is not None and data.scheme == "serial":
            out.append(f"{prefix}.profile: empty, but a radar configured through its CLI port needs its chirp cfg")
        if data is not None and data.scheme == "file" and not Path(data.path).is_file():
            out.append(f"{prefix}.data: radar dump not found: {data.path}")
        return out


@dataclass
class MavlinkConfig:
    url: str = "udpout:127.0.0.1:14550"
    system_id: int = 1
    component_id: int = 196  # MAV_COMP_ID_OBSTACLE_AVOIDANCE
    target_system: int = 1
    baud: int = 921600
    # MAVLink 2 signing: key = SHA-256 of the passphrase (MAVProxy's convention). Keep the passphrase out of the
    # config: signing_passphrase_file names a file (root-owned, 0600) whose first line is it. With a key, every
    # message the autopilot sends must be signed with it (RADIO_STATUS excepted: a SiK radio cannot sign).
    signing_passphrase_file: str = ""
    signing_passphrase: str = ""  # the passphrase itself, in the config: accepted, but check-config warns
    send_obstacle_distance_3d: bool = False

    def validate(self) -> list[str]:
        out = []
        if not self.url:
            out.append("url: empty (use e.g. udpout:127.0.0.1:14550 or /dev/ttyAMA0)")
        elif not self.url.endswith(".tlog"):  # a .tlog is replayed (daemon/replay.py), not opened as a link
            try:
                parse_autopilot_url(self.url, max(1, self.baud))
            except ValueError as exc:
                out.append(f"url: {exc}")
        for k in ("system_id", "component_id", "target_system"):
            if not 1 <= getattr(self, k) <= 255:
                out.append(f"{k}: {getattr(self, k)} must be 1..255")
        if self.baud <= 0:
            out.append(f"baud: {self.baud} must be > 0 (e.g. 921600)")
        if self.signing_passphrase and self.signing_passphrase_file:
            out.append("signing_passphrase, signing_passphrase_file: give one of them (the file, to keep it secret)")
        return out

    def file_problems(self, prefix: str) -> list[str]:
        """The signing passphrase file must be readable and hold a passphrase (its content is never shown)."""
        if not self.signing_passphrase_file:
            return []
        try:
            signing_passphrase(self)
        except ConfigError as exc:
            return [f"{prefix}.{p}" for p in exc.problems]
        return []


def signing_passphrase(m: MavlinkConfig) -> str:
    """The MAVLink signing passphrase: from ``signing_passphrase_file`` (its first line) when set, else the config's
    own value ("" = no signing). Raises ConfigError naming the file, never its content."""
    if not m.signing_passphrase_file:
        return m.signing_passphrase
    path = Path(m.signing_passphrase_file)
    try:
        with path.open("rb") as f:
            raw = f.read(4096)
    except OSError as exc:
        raise ConfigError([f"signing_passphrase_file: cannot read {path}: {exc.strerror or exc}"], str(path)) from None
    first = raw.splitlines()[0].strip() if raw.strip() else b""
    if not first:
        raise ConfigError([f"signing_passphrase_file: {path} holds no passphrase on its first line"], str(path))
    try:
        return first.decode()
    except UnicodeDecodeError:
        raise ConfigError([f"signing_passphrase_file: {path}: the passphrase is not UTF-8 text"], str(path)) from None


def secret_warnings(config: Config) -> list[str]:
    """A signing passphrase written in the config itself: it works, but the config is not a secret's place."""
    if config.mavlink.signing_passphrase:
        return [
            "mavlink.signing_passphrase: the passphrase is in the config; move it to a file (0600) named by "
            "mavlink.signing_passphrase_file"
        ]
    return []


@dataclass
class BoatConfig:
    """The own boat's box in the body frame: returns inside it are the boat itself (hull, mast, crew)."""

    bow_m: float = 0.8  # x of the bow
    stern_m: float = -0.8  # x of the stern
    port_m: float = -0.5  # y of the port side
    starboard_m: float = 0.5
    water_z_m: float = 0.0  # water line in body z (down positive)

    def validate(self) -> list[str]:
        out = []
        if self.stern_m >= self.bow_m:
            out.append("stern_m: must be less than bow_m")
        if self.port_m >= self.starboard_m:
            out.append("port_m: must be less than starboard_m")
        return out


@dataclass
class OutputConfig:
    rate_hz: float = 10.0
    min_distance_m: float = 0.5
    max_distance_m: float = 100.0
    no_data_timeout_s: float = 0.5  # both autopilots time a proximity sensor out after 0.5 s
    # The least height above the water surface a LiDAR return must have to be solid; the measured sea state raises
    # it (tracker/lidar/water.py).
    min_height_above_water_m: float = 0.15
    # "Clear" is sent only where a solid this tall above the water would have been returned by a live sensor all the
    # way from clear_inner_m (0: min_distance_m) out to max_distance_m; elsewhere "unknown" (README: coverage).
    min_obstacle_height_m: float = 0.5
    clear_inner_m: float = 0.0
    tracks_out: str = ""  # JSON lines, one per tick
    record_dir: str = ""  # raw captures of every source, for replay at the desk
    health_interval_s: float = 5.0
    # Live, the obstacle array must be ready this long after a tick starts; a tracker whose recent time would carry
    # the cycle past it is skipped for that cycle (its tracks coast; the health line counts it). 0 = never skip.
    # 70 ms of the 100 ms tick leaves the rest to publishing and to a Pi 4's ArduPilot.
    cycle_budget_ms: float = 70.0
    # Confirmed tracks as AIS_VESSEL for the ground station's map, every ais_interval_s (0 = off: it costs radio
    # bandwidth, ~60 bytes per vessel, and ArduPilot's forwarding to the GCS link is to be checked per setup).
    ais_interval_s: float = 0.0
    ais_max_tracks: int = 10  # the nearest ones
    ais_mmsi_base: int = AIS_MMSI_BASE  # MMSI = base + track id

    def validate(self) -> list[str]:
        out = []
        if not 1 <= self.rate_hz <= 50:
            out.append(f"rate_hz: {self.rate_hz} must be within 1..50")
        if not 0 < self.min_distance_m < self.max_distance_m:
            out.append("min_distance_m/max_distance_m: need 0 < min < max")
        if self.max_distance_m * 100 + 1 >= 65535:
            out.append("max_distance_m: must be below 655 m (OBSTACLE_DISTANCE carries uint16 centimetres)")
        if self.no_data_timeout_s <= 0:
            out.append("no_data_timeout_s: must be > 0")
        elif 1 <= self.rate_hz <= 50 and self.no_data_timeout_s < 2.0 / self.rate_hz:
            out.append(
                f"no_data_timeout_s: {self.no_data_timeout_s} is under two ticks ({2.0 / self.rate_hz:.2f} s at"
                f" {self.rate_hz:g} Hz): a sensor delivering once a tick would be reported silent between deliveries"
            )
        if not (math.isfinite(self.min_height_above_water_m) and self.min_height_above_water_m > 0):
            out.append(f"min_height_above_water_m: {self.min_height_above_water_m} must be > 0")
        if not (math.isfinite(self.min_obstacle_height_m) and self.min_obstacle_height_m > 0):
            out.append(f"min_obstacle_height_m: {self.min_obstacle_height_m} must be > 0")
        distances_ok = 0 < self.min_distance_m < self.max_distance_m
        if distances_ok and not (math.isfinite(self.clear_inner_m) and 0 <= self.clear_inner_m < self.max_distance_m):
            out.append(f"clear_inner_m: {self.clear_inner_m} must be within [0, max_distance_m) (0 = min_distance_m)")
        if not (math.isfinite(self.ais_interval_s) and self.ais_interval_s >= 0):
            out.append(f"ais_interval_s: {self.ais_interval_s} must be >= 0 (0 = no AIS_VESSEL)")
        period_ms = 1000.0 / self.rate_hz if 1 <= self.rate_hz <= 50 else math.inf  # a bad rate is named above
        if not (math.isfinite(self.cycle_budget_ms) and 0 <= self.cycle_budget_ms < period_ms):
            out.append(f"cycle_budget_ms: {self.cycle_budget_ms} must be within [0, the tick period) (0 = never skip)")
        if not self.health_interval_s > 0:
            out.append(f"health_interval_s: {self.health_interval_s} must be > 0")
        if self.ais_max_tracks < 1:
            out.append(f"ais_max_tracks: {self.ais_max_tracks} must be >= 1")
        if not 0 <= self.ais_mmsi_base <= 999_000_000:
            out.append(f"ais_mmsi_base: {self.ais_mmsi_base} must leave room for track ids below 10^9")
        return out


@dataclass
class TrackerConfig:
    """Tracker tables are passed through to the trackers' own config classes, which check them."""

    lidar: dict[str, Any] = field(default_factory=dict)
    radar: dict[str, Any] = field(default_factory=dict)


@dataclass
class Config:
    lidar: LidarConfig = field(default_factory=LidarConfig)
    radar: RadarConfig = field(default_factory=RadarConfig)
    mavlink: MavlinkConfig = field(default_factory=MavlinkConfig)
    boat: BoatConfig = field(default_factory=BoatConfig)
    output: OutputConfig = field(default_factory=OutputConfig)
    tracker: TrackerConfig = field(default_factory=TrackerConfig)


def load_config(
    path: str | Path | None, overrides: dict[str, Any] | None = None, *, check_files: bool = False
) -> Config:
    """Read a TOML file (None: built-in defaults), apply dotted-key overrides, check everything.

    ``check_files`` also opens the files the configuration names (a pcap to replay, the radar's chirp cfg), as
    ``check-config`` does before the daemon starts; ``run`` leaves them to start-up, where a radar that cannot
    start leaves the daemon LiDAR-only.
    """
    table: dict[str, Any] = {}
    source = str(path) if path else "<defaults>"
    if path is not None:
        table = _read_table(Path(path), source)
    for dotted, value in (overrides or {}).items():
        node: Any = table
        *parents, leaf = dotted.split(".")
        for part in parents:
            node = node.setdefault(part, {})
            if not isinstance(node, dict):
                break  # the file has a value where a table belongs: the schema names it below
        else:
            node[leaf] = value
    config, problems = build_with_problems(Config, table)
    if not problems:  # the tracker tables take values from the other sections: check those first
        problems += tracker_config_problems(config)
    if check_files:
        if not any(p.startswith("mavlink.") for p in problems):
            problems += config.mavlink.file_problems("mavlink")
        for name, section in (("lidar", config.lidar), ("radar", config.radar)):
            if not any(p.startswith(f"{name}.") for p in problems):  # else it may hold defaults, not the file's
                problems += [] if name == "radar" and not config.radar.required else section.file_problems(name)
    if problems:
        raise ConfigError(problems, source)
    return config


def file_warnings(config: Config) -> list[str]:
    """Problems with the files of a sensor the daemon can run without: a radar that is not ``required`` and whose
    chirp cfg or dump is missing or refused leaves the daemon LiDAR-only at start-up, so ``check-config`` (which
    systemd runs before every start) says so but does not stop the boat's LiDAR from running."""
    if config.radar.required:
        return []
    return [
        f"{p} (radar.required = false: the daemon will run without the radar)"
        for p in config.radar.file_problems("radar")
    ]


def _read_table(p: Path, source: str) -> dict[str, Any]:
    try:
        with p.open("rb") as f:
            raw = f.read(MAX_CONFIG_BYTES + 1)
    except FileNotFoundError:
        raise ConfigError([f"file not found: {p}"], source) from None
    except OSError as exc:
        raise ConfigError([f"cannot read {p}: {exc.strerror or exc}"], source) from None
    if len(raw) > MAX_CONFIG_BYTES:
        raise ConfigError([f"larger than {MAX_CONFIG_BYTES // 1024} KiB: not a configuration file"], source)
    try:
        text = raw.decode("utf-8")
    except UnicodeDecodeError as exc:
        line = raw.count(b"\n", 0, exc.start) + 1
        raise ConfigError(
            [f"not UTF-8 text: byte 0x{raw[exc.start]:02x} on line {line} (TOML files are UTF-8)"], source
        ) from None
    try:
        return tomllib.loads(text)
    except ValueError as exc:  # TOMLDecodeError, or an integer of more digits than Python converts
        raise ConfigError([f"not valid TOML: {exc}"], source) from None
    except RecursionError:
        raise ConfigError(["not valid TOML: arrays or tables nested too deeply"], source) from None
