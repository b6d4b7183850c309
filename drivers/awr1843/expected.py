"""What the data port must carry for the configuration the daemon sent; a frame of another is rejected, not mixed.

The frames on the data port are not always those of the cfg the daemon sent: TI's Visualizer or another program
reconfigured the radar through the same USB, the board was re-flashed, the by-id links point at another board after a
USB reset, or stale frames of the previous configuration are still in the buffers. Points of another configuration
have another range, resolution, velocity scale and field of view; tracked as ours they are silently wrong.

What a frame tells about the configuration that made it (shared/specs/awr1843-uart.md, section 2):

* header ``platform``: the chip family. The daemon drives an AWR1843 (xWR18xx); ``radar.platform`` names another.
* header ``version``: the firmware's SDK. Major versions differ in layout (SDK 2.x sends Q-format points), so the
  major must match the cfg's ``% Created for SDK ver:`` line when it has one. Beyond that, the version is pinned by
  the first frame accepted after each (re)configuration: another version in mid-stream is another firmware, so
  another board.
* header ``subFrameNumber``: only advanced sub-frame configurations (``dfeDataOutputMode 3``) count sub-frames.
* the TLV types: ``guiMonitor`` decides which come. A type the cfg did not enable (a heat map, a noise profile) comes
  from another configuration; so does the number of virtual antennas, which only the heat maps would carry.
* the range and noise profiles hold Nr values, the range FFT size of the cfg's ``numAdcSamples``.

Missing TLVs are not judged: TLV 1/7 come and go with the number of points, TLV 9 with the SDK version.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass

from drivers.awr1843.parser import (
    PLATFORMS,
    TLV_AZ_EL_HEAT_MAP,
    TLV_AZIMUTH_HEAT_MAP,
    TLV_NOISE_PROFILE,
    TLV_POINTS,
    TLV_RANGE_DOPPLER_HEAT_MAP,
    TLV_RANGE_PROFILE,
    TLV_SIDE_INFO,
    TLV_STATS,
    TLV_TEMPERATURE,
    FrameHeader,
    describe_platform,
    sdk_string,
)
from drivers.awr1843.profile import RadarProfile

XWR18XX = 0xA1843
PLATFORM_NAMES: dict[str, int] = {name: code for code, name in PLATFORMS.items()}

# guiMonitor flags in order (detectedObjects, logMagRange, noiseProfile, rangeAzimuthHeatMap, rangeDopplerHeatMap,
# statsInfo) -> the TLV types each enables. detectedObjects = 2 sends points without side info.
_GUI_TLVS: tuple[frozenset[int], ...] = (
    frozenset({TLV_POINTS, TLV_SIDE_INFO}),
    frozenset({TLV_RANGE_PROFILE}),
    frozenset({TLV_NOISE_PROFILE}),
    frozenset({TLV_AZIMUTH_HEAT_MAP, TLV_AZ_EL_HEAT_MAP}),
    frozenset({TLV_RANGE_DOPPLER_HEAT_MAP}),
    frozenset({TLV_STATS, TLV_TEMPERATURE}),
)


def platform_code(name: str) -> int | None:
    """'xWR18xx' -> 0xA1843; 'any' -> None (no check). Raises ValueError for a name not in ``PLATFORMS``."""
    if name.strip().lower() == "any":
        return None
    for known, code in PLATFORM_NAMES.items():
        if known.lower() == name.strip().lower():
            return code
    raise ValueError(f"unknown radar platform {name!r}; known: {', '.join(PLATFORM_NAMES)}, or 'any'")


@dataclass(frozen=True)
class ExpectedStream:
    platform: int | None = XWR18XX  # None: any
    sdk_major: int | None = None  # None: any
    sub_frames: bool = False  # the cfg sets up advanced sub-frames
    tlv_types: frozenset[int] | None = None  # None: any
    range_bins: int | None = None  # None: not checked

    @classmethod
    def for_config(cls, profile: RadarProfile | None, platform: int | None = XWR18XX) -> ExpectedStream:
        """What the cfg (None: unknown, only the platform is checked) makes the radar send."""
        if profile is None:
            return cls(platform=platform)
        tlvs: frozenset[int] | None = None
        gui = profile.gui_monitor
        if gui is not None and len(gui) == len(_GUI_TLVS):
            tlvs = frozenset().union(*(types for flag, types in zip(gui, _GUI_TLVS, strict=True) if flag))
            if gui[0] == 2:
                tlvs -= {TLV_SIDE_INFO}
        advanced = any(line.command == "dfeDataOutputMode" and line.args[:1] == ("3",) for line in profile.lines)
        return cls(
            platform=platform,
            sdk_major=profile.sdk_hint[0] if profile.sdk_hint is not None else None,
            sub_frames=advanced,
            tlv_types=tlvs,
            range_bins=profile.num_range_bins,
        )

    def problem(self, header: FrameHeader, tlvs: Mapping[int, memoryview], firmware: int | None) -> str:
        """Why a well-formed frame is not of this configuration ("" if it is). ``firmware``: the version word the
        stream was pinned to, None before its first frame."""
        if self.platform is not None and header.platform != self.platform:
            return f"platform {describe_platform(header.platform)}, configured {describe_platform(self.platform)}"
        major = header.version >> 24
        if self.sdk_major is not None and major != self.sdk_major:
            return f"SDK {sdk_string(header.sdk_version)}, the cfg is for SDK {self.sdk_major}.x"
        if firmware is not None and header.version != firmware:
            pinned = (firmware >> 24 & 0xFF, firmware >> 16 & 0xFF, firmware >> 8 & 0xFF, firmware & 0xFF)
            return f"firmware {sdk_string(header.sdk_version)} after frames of {sdk_string(pinned)}"
        if header.sub_frame and not self.sub_frames:
            return f"sub-frame {header.sub_frame}, the cfg has none"
        if self.tlv_types is not None:
            other = sorted(set(tlvs) - self.tlv_types)
            if other:
                return f"TLV type(s) {other} the cfg's guiMonitor does not enable"
        if self.range_bins is not None:
            for tlv_type in (TLV_RANGE_PROFILE, TLV_NOISE_PROFILE):
                payload = tlvs.get(tlv_type)
                if payload is not None and len(payload) != 2 * self.range_bins:
                    return f"TLV {tlv_type} with {len(payload) // 2} range bins, the cfg makes {self.range_bins}"
        return ""
