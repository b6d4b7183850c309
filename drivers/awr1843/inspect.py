"""What is in a raw AWR1843 data-port dump: one summary per frame and a total (``usv-tracker decode``)."""

from __future__ import annotations

from collections import Counter
from collections.abc import Iterator
from pathlib import Path
from typing import Any

from drivers.awr1843.parser import RadarFrameParser, describe_platform, sdk_string
from drivers.awr1843.profile import load_profile


class NotARadarDumpError(ValueError):
    """The file holds no valid OOB-demo frame (wrong file, CLI log, or data read at the wrong baud)."""


def summarise_dat(path: str | Path, profile_path: str | Path | None = None) -> Iterator[dict[str, Any]]:
    """Yield ``{frame_number, points, tlv_types, bytes_skipped, sdk, platform}`` per frame, then one
    ``{"summary": True, frames, points, gaps, dropped, skipped_bytes, trailing_bytes, ...}``.

    Raises ``NotARadarDumpError`` (after reading the whole file) when not a single frame decodes.
    """
    path = Path(path)
    profile = load_profile(profile_path) if profile_path is not None else None
    parser = RadarFrameParser(profile)
    frames = points = 0
    first: int | None = None
    last: int | None = None
    tlv_counts: Counter[int] = Counter()
    with path.open("rb") as f:
        while True:
            chunk = f.read(65536)
            batch = parser.feed(chunk, 0.0) if chunk else parser.finish(0.0)
            for frame in batch:
                frames += 1
                points += frame.n_points
                tlv_counts.update(frame.tlv_types)
                first = frame.frame_number if first is None else first
                last = frame.frame_number
                yield {
                    "frame_number": frame.frame_number,
                    "points": frame.n_points,
                    "tlv_types": list(frame.tlv_types),
                    "bytes_skipped": frame.bytes_skipped,
                    "sdk": sdk_string(frame.sdk_version),
                    "platform": describe_platform(frame.platform),
                }
            if not chunk:
                break
    st = parser.stats
    if frames == 0:
        raise NotARadarDumpError(
            f"{path}: no valid AWR1843 data frame in {st.bytes_received} bytes "
            f"({st.headers_rejected} magic words with implausible headers); not a data-port dump, "
            "or recorded from the CLI port / at the wrong baud rate"
        )
    yield {
        "summary": True,
        "frames": frames,
        "points": points,
        "first_frame_number": first,
        "last_frame_number": last,
        "gaps": st.frames_lost,
        "dropped": st.frames_dropped,
        "skipped_bytes": st.bytes_skipped,
        "trailing_bytes": parser.buffered_bytes,
        "tlv_type_counts": dict(sorted(tlv_counts.items())),
        "bytes": st.bytes_received,
    }
