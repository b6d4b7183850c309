"""TI mmWave demo ``.cfg`` files: the lines to send and the chirp-design numbers derived from them.

The data port never says how to turn a Doppler index into m/s (SDK 2.x points carry indices, not
velocities) nor how long a frame lasts, so both come from the cfg the host sent. Formulas are TI's
(mmWave SDK user guide / sensing estimator), with c = 3e8 m/s as TI uses:

* range bin spacing   = c * fs / (2 * S * Nr)      Nr = range FFT size = next power of two >= N
* range resolution    = c * fs / (2 * S * N)       (equal to the bin spacing when N is a power of two)
* IF-limited range    = c * fs / (2 * S)
* v_max               = lambda / (4 * Ntx * Tc)    Tc = idle + ramp end, Ntx = chirps per loop (TDM-MIMO)
* velocity resolution = lambda / (2 * Ntx * Tc * numLoops)
* frame period        = frameCfg periodicity: the frame-START interval (100 ms -> 10 Hz)

Comments (``%``) and blank lines are skipped but line numbers are kept, so the CLI session can name the
exact file line the device refused.
"""

from __future__ import annotations

import math
import re
from dataclasses import dataclass
from pathlib import Path

from drivers.awr1843.errors import RadarProfileError

SPEED_OF_LIGHT = 3.0e8  # TI's value in the demo and the sensing estimator

# The device's own limits on the counts and indices a cfg sets. A number beyond them is refused by the radar anyway,
# and read here it would size a loop or a list (chirpCfg 0 1e9 once filled a billion-entry table, 2.3 GB).
# mmWave SDK user guide, "Configuration (.cfg) File Format", and mmWaveLink's rlChirpCfg_t / rlFrameCfg_t /
# rlProfileCfg_t (the structures these lines fill on the AWR1843):
MAX_CHIRP_INDEX = 511  # chirpCfg / frameCfg chirp start and end index: 0-511
MAX_PROFILE_ID = 3  # profileCfg profile id, and the profile a chirpCfg names: 0-3
MAX_LOOPS = 255  # frameCfg number of loops: 1-255
MAX_FRAMES = 65535  # frameCfg number of frames: 0-65535 (0 = run until sensorStop)
# profileCfg numAdcSamples: 2..MAX_NUM_SAMPLES, where every enabled RX channel's samples of one chirp must fit the
# xWR1843's 32 kB ADC buffer at 2 bytes per real sample: 16384 with a single RX, the most any cfg can ask for.
MIN_ADC_SAMPLES, MAX_ADC_SAMPLES = 2, 16384
# TI's cfgs are 2-4 kB; a file far larger is not a chirp cfg (and /dev/zero must not be read whole).
MAX_CFG_BYTES = 64 * 1024

# Minimum argument counts of the commands whose numbers we use or check. Counts differ between SDK
# versions (subFrameIdx added in 2.x/3.x), so only a floor is enforced; the device has the last word.
_MIN_ARGS: dict[str, int] = {
    "dfeDataOutputMode": 1,
    "channelCfg": 3,
    "adcCfg": 2,
    "adcbufCfg": 4,
    "profileCfg": 14,
    "chirpCfg": 8,
    "frameCfg": 7,
    "lowPower": 2,
    "guiMonitor": 6,
    "cfarCfg": 7,
    "multiObjBeamForming": 2,
    "clutterRemoval": 1,
    "calibDcRangeSig": 4,
    "extendedMaxVelocity": 2,
    "lvdsStreamCfg": 4,
    "compRangeBiasAndRxChanPhase": 9,
    "measureRangeBiasAndRxChanPhase": 3,
    "CQRxSatMonitor": 5,
    "CQSigImgMonitor": 3,
    "analogMonitor": 2,
    "aoaFovCfg": 5,
    "cfarFovCfg": 4,
    "calibData": 3,
    "sensorStop": 0,
    "sensorStart": 0,
    "flushCfg": 0,
}
# The chirp-design figures the rest of the daemon uses (RadarProfile properties).
_DESIGN_FIGURES = (
    "range_bin_m",
    "range_resolution_m",
    "max_range_m",
    "wavelength_m",
    "chirp_time_s",
    "max_velocity_mps",
    "velocity_resolution_mps",
    "active_frame_time_s",
    "frame_period_s",
)
_NUMBER = re.compile(r"^[+-]?(\d+\.?\d*|\.\d+)([eE][+-]?\d+)?$")
_SDK_HEADER = re.compile(r"SDK\s*ver\s*:\s*(\d+)\.(\d+)", re.IGNORECASE)


@dataclass(frozen=True)
class CfgLine:
    """One command line of a cfg file, with its 1-based line number in that file."""

    number: int
    text: str

    @property
    def command(self) -> str:
        return self.text.split()[0]

    @property
    def args(self) -> tuple[str, ...]:
        return tuple(self.text.split()[1:])


@dataclass(frozen=True)
class ChirpProfile:
    """The numbers of one ``profileCfg`` line (TI units kept in the names)."""

    profile_id: int
    start_freq_ghz: float
    idle_time_us: float
    adc_start_time_us: float
    ramp_end_time_us: float
    freq_slope_mhz_per_us: float
    num_adc_samples: int
    sample_rate_ksps: float


@dataclass(frozen=True)
class RadarProfile:
    """A parsed cfg: the lines to send (in order) and the chirp design they describe."""

    source: str
    lines: tuple[CfgLine, ...]
    chirp: ChirpProfile
    chirp_start: int
    chirp_end: int
    num_loops: int
    num_frames: int
    frame_period_ms: float
    sdk_hint: tuple[int, int] | None = None  # from the "% Created for SDK ver:03.06" header, if any
    gui_monitor: tuple[int, ...] | None = None  # (detectedObjects, logMagRange, noiseProfile, azHeat, dopHeat, stats)
    range_fov_m: tuple[float, float] | None = None  # cfarFovCfg direction 0
    velocity_fov_mps: tuple[float, float] | None = None  # cfarFovCfg direction 1

    @property
    def frame_period_s(self) -> float:
        return self.frame_period_ms / 1000.0

    @property
    def chirps_per_loop(self) -> int:
        """TDM-MIMO factor: chirps (one per TX) between two chirps of the same TX."""
        return self.chirp_end - self.chirp_start + 1

    @property
    def num_range_bins(self) -> int:
        """Range FFT size Nr: the demo pads the ADC samples to the next power of two."""
        return 1 << max(0, math.ceil(math.log2(self.chirp.num_adc_samples)))

    @property
    def num_doppler_bins(self) -> int:
        """Doppler FFT size Nd: the demo requires numLoops to be a power of two; padded if it is not."""
        return 1 << max(0, math.ceil(math.log2(self.num_loops)))

    @property
    def _slope_hz_per_s(self) -> float:
        return self.chirp.freq_slope_mhz_per_us * 1e12

    @property
    def _sample_rate_hz(self) -> float:
        return self.chirp.sample_rate_ksps * 1e3

    @property
    def range_resolution_m(self) -> float:
        return SPEED_OF_LIGHT * self._sample_rate_hz / (2.0 * self._slope_hz_per_s * self.chirp.num_adc_samples)

    @property
    def range_bin_m(self) -> float:
        return SPEED_OF_LIGHT * self._sample_rate_hz / (2.0 * self._slope_hz_per_s * self.num_range_bins)

    @property
    def max_range_m(self) -> float:
        """IF-bandwidth limit; TI's tools advertise about 80 % of it."""
        return SPEED_OF_LIGHT * self._sample_rate_hz / (2.0 * self._slope_hz_per_s)

    @property
    def wavelength_m(self) -> float:
        return SPEED_OF_LIGHT / (self.chirp.start_freq_ghz * 1e9)

    @property
    def chirp_time_s(self) -> float:
        return (self.chirp.idle_time_us + self.chirp.ramp_end_time_us) * 1e-6

    @property
    def max_velocity_mps(self) -> float:
        """Unambiguous radial speed: velocities beyond +-v_max wrap around."""
        return self.wavelength_m / (4.0 * self.chirps_per_loop * self.chirp_time_s)

    @property
    def velocity_resolution_mps(self) -> float:
        """m/s per Doppler bin; turns SDK 2.x ``dopplerIdx`` into a radial velocity."""
        return self.wavelength_m / (2.0 * self.chirps_per_loop * self.chirp_time_s * self.num_loops)

    @property
    def active_frame_time_s(self) -> float:
        return self.chirps_per_loop * self.num_loops * self.chirp_time_s

    @property
    def sends_sensor_start(self) -> bool:
        return any(line.command == "sensorStart" for line in self.lines)

    @property
    def extends_max_velocity(self) -> bool:
        """The demo's own velocity disambiguation is on (``extendedMaxVelocity`` with a non-zero flag): it then
        reports radial speeds beyond ``max_velocity_mps``."""
        return any(line.command == "extendedMaxVelocity" and line.args[1:2] != ("0",) for line in self.lines)


def load_profile(path: str | Path) -> RadarProfile:
    """Parse a cfg file; raises ``RadarProfileError`` naming the file and line on malformed input."""
    p = Path(path)
    try:
        with p.open("rb") as f:
            raw = f.read(MAX_CFG_BYTES + 1)
    except OSError as exc:
        raise RadarProfileError(f"cannot read radar cfg: {exc.strerror or exc}", str(p)) from exc
    if len(raw) > MAX_CFG_BYTES:
        raise RadarProfileError(f"larger than {MAX_CFG_BYTES // 1024} KiB: not a radar cfg", str(p))
    return parse_profile(raw.decode("utf-8", errors="replace"), source=str(p))


def parse_profile(text: str, source: str = "<cfg>") -> RadarProfile:
    """Parse cfg text. Known commands are checked for argument count and numeric arguments."""
    lines: list[CfgLine] = []
    sdk_hint: tuple[int, int] | None = None
    for number, raw in enumerate(text.splitlines(), start=1):
        stripped = raw.strip()
        if not stripped:
            continue
        if stripped.startswith("%"):
            m = _SDK_HEADER.search(stripped)
            if m and sdk_hint is None:
                sdk_hint = (int(m.group(1)), int(m.group(2)))
            continue
        if len(stripped) > 255:
            raise RadarProfileError("line longer than the CLI's 255 characters", source, number, stripped)
        line = CfgLine(number, " ".join(stripped.split()))
        _check_known_command(line, source)
        lines.append(line)

    profiles: dict[int, tuple[CfgLine, ChirpProfile]] = {}
    chirps: dict[int, tuple[CfgLine, int]] = {}  # chirp index -> (line, profile id)
    frame: CfgLine | None = None
    gui: tuple[int, ...] | None = None
    range_fov: tuple[float, float] | None = None
    velocity_fov: tuple[float, float] | None = None
    for line in lines:
        a = line.args
        if line.command == "profileCfg":
            cp = ChirpProfile(
                profile_id=_int(line, 0, source, 0, MAX_PROFILE_ID),
                start_freq_ghz=float(a[1]),
                idle_time_us=float(a[2]),
                adc_start_time_us=float(a[3]),
                ramp_end_time_us=float(a[4]),
                freq_slope_mhz_per_us=float(a[7]),
                num_adc_samples=_int(line, 9, source, MIN_ADC_SAMPLES, MAX_ADC_SAMPLES),
                sample_rate_ksps=float(a[10]),
            )
            if cp.freq_slope_mhz_per_us <= 0 or cp.num_adc_samples <= 0 or cp.sample_rate_ksps <= 0:
                raise RadarProfileError(
                    "profileCfg needs a positive slope, sample count and sample rate", source, line.number, line.text
                )
            if cp.start_freq_ghz <= 0 or cp.idle_time_us + cp.ramp_end_time_us <= 0:
                raise RadarProfileError(
                    "profileCfg needs a positive start frequency and chirp time", source, line.number, line.text
                )
            profiles[cp.profile_id] = (line, cp)
        elif line.command == "chirpCfg":
            start = _int(line, 0, source, 0, MAX_CHIRP_INDEX)
            end = _int(line, 1, source, 0, MAX_CHIRP_INDEX)
            pid = _int(line, 2, source, 0, MAX_PROFILE_ID)
            if end < start:
                raise RadarProfileError("chirpCfg end index before start index", source, line.number, line.text)
            for k in range(start, end + 1):
                chirps[k] = (line, pid)
        elif line.command == "frameCfg":
            frame = line
        elif line.command == "guiMonitor":
            vals = [_int(line, i, source) for i in range(len(a))]
            gui = tuple(vals[-6:])  # SDK 1.x has no leading subFrameIdx; the last six are the flags
        elif line.command == "cfarFovCfg":
            direction = _int(line, 1, source)
            lo, hi = float(a[2]), float(a[3])
            if direction == 0:
                range_fov = (lo, hi)
            elif direction == 1:
                velocity_fov = (lo, hi)

    if frame is None:
        raise RadarProfileError("no frameCfg line: frame period and Doppler size unknown", source)
    if not profiles:
        raise RadarProfileError("no profileCfg line: chirp design unknown", source)
    chirp_start = _int(frame, 0, source, 0, MAX_CHIRP_INDEX)
    chirp_end = _int(frame, 1, source, 0, MAX_CHIRP_INDEX)
    num_loops = _int(frame, 2, source, 1, MAX_LOOPS)
    num_frames = _int(frame, 3, source, 0, MAX_FRAMES)
    period_ms = float(frame.args[4])
    if chirp_end < chirp_start or period_ms <= 0:
        raise RadarProfileError(
            "frameCfg needs chirpEnd >= chirpStart and periodicity > 0", source, frame.number, frame.text
        )
    missing = [k for k in range(chirp_start, chirp_end + 1) if k not in chirps]
    if missing:
        shown = ", ".join(map(str, missing[:8])) + (f", ... ({len(missing)} in all)" if len(missing) > 8 else "")
        raise RadarProfileError(
            f"frameCfg uses chirp(s) [{shown}] that no chirpCfg line defines", source, frame.number, frame.text
        )
    chirp_line, pid = chirps[chirp_start]
    if pid not in profiles:
        raise RadarProfileError(
            f"chirpCfg refers to profile {pid}, which no profileCfg line defines",
            source,
            chirp_line.number,
            chirp_line.text,
        )
    profile = RadarProfile(
        source=source,
        lines=tuple(lines),
        chirp=profiles[pid][1],
        chirp_start=chirp_start,
        chirp_end=chirp_end,
        num_loops=num_loops,
        num_frames=num_frames,
        frame_period_ms=period_ms,
        sdk_hint=sdk_hint,
        gui_monitor=gui,
        range_fov_m=range_fov,
        velocity_fov_mps=velocity_fov,
    )
    # Finite arguments can still multiply out to nothing usable (an idle time of 1e-300 us: infinite v_max), and the
    # data parser would scale every SDK 2.x Doppler index by it.
    unusable = [name for name in _DESIGN_FIGURES if not 0 < getattr(profile, name) < math.inf]
    if unusable:
        line = profiles[pid][0]
        raise RadarProfileError(
            f"profileCfg gives no usable chirp design ({', '.join(unusable)} not a finite positive number)",
            source,
            line.number,
            line.text,
        )
    return profile


def _check_known_command(line: CfgLine, source: str) -> None:
    need = _MIN_ARGS.get(line.command)
    if need is None:
        return  # unknown to us; the device decides (and the CLI session reports its answer)
    args = line.args
    if len(args) < need:
        raise RadarProfileError(
            f"{line.command} needs at least {need} arguments, got {len(args)}", source, line.number, line.text
        )
    for i, arg in enumerate(args):
        if not _NUMBER.match(arg):
            raise RadarProfileError(
                f"{line.command} argument {i + 1} is not a number: {arg!r}", source, line.number, line.text
            )
        if not math.isfinite(float(arg)):  # 1e999 matches the pattern and is infinity
            raise RadarProfileError(
                f"{line.command} argument {i + 1} is not a finite number: {arg!r}", source, line.number, line.text
            )


def _int(line: CfgLine, index: int, source: str, lowest: int | None = None, highest: int | None = None) -> int:
    """Argument ``index`` as an integer, within the device's limits ``lowest..highest`` where given."""
    text = line.args[index]
    value = float(text)
    if not value.is_integer():  # also false for inf and nan
        raise RadarProfileError(
            f"{line.command} argument {index + 1} must be an integer, got {text!r}", source, line.number, line.text
        )
    number = int(value)
    if (lowest is not None and number < lowest) or (highest is not None and number > highest):
        raise RadarProfileError(
            f"{line.command} argument {index + 1} is {text}, outside the device's range {lowest}..{highest}",
            source,
            line.number,
            line.text,
        )
    return number
