"""`usv-tracker decode FILE`: what is in a capture, one line per revolution or radar frame, then a summary.

The file type is decided by its first bytes (pcap/pcapng magic -> VLP-16; anything else is tried as an AWR1843
data-port dump), so a misnamed file still decodes, and a file that is neither gets a clear "not a capture".
"""

from __future__ import annotations

import json
import sys
from pathlib import Path
from typing import Any

PCAP_MAGICS = {
    b"\xd4\xc3\xb2\xa1",
    b"\xa1\xb2\xc3\xd4",
    b"\x4d\x3c\xb2\xa1",
    b"\xa1\xb2\x3c\x4d",
    b"\x0a\x0d\x0d\x0a",  # pcapng section header block
}


def _emit(obj: dict[str, Any], as_json: bool, text: str) -> None:
    print(json.dumps(obj, separators=(",", ":"), default=str) if as_json else text, flush=False)


def decode_file(path: Path, as_json: bool = False, model: str = "auto", profile: str | None = None) -> int:
    try:
        with path.open("rb") as f:
            head = f.read(4)
    except OSError as exc:
        print(f"usv-tracker decode: cannot read {path}: {exc.strerror}", file=sys.stderr)
        return 2
    if head in PCAP_MAGICS:
        return _decode_pcap(path, as_json, None if model == "auto" else model)
    return _decode_radar(path, as_json, profile)


def _decode_pcap(path: Path, as_json: bool, model: str | None) -> int:
    from drivers.vlp16.inspect import NoLidarDataError, summarise_pcap
    from drivers.vlp16.pcap import NotAPcapError

    try:
        summary = summarise_pcap(path, model=model)
        for rev in summary:
            _emit(
                rev,
                as_json,
                f"rev {rev['index']:4d}  points {rev['points']:6d}  packets {rev['packets']:3d}  "
                f"missing {rev['packets_missing']:3d}  {rev['return_mode']:9s} {rev['model']}  pps {rev['pps']}",
            )
    except (NotAPcapError, NoLidarDataError) as exc:
        print(f"usv-tracker decode: {exc}", file=sys.stderr)
        return 2
    totals = summary.totals or {}
    if as_json:
        _emit({"summary": True, **totals}, True, "")
    else:
        print(
            "summary: " + ", ".join(f"{k} {v}" for k, v in totals.items() if k != "hint" and v not in (None, "", {}, 0))
        )
        if totals.get("hint"):
            print(f"hint: {totals['hint']}")
    return 0


def _decode_radar(path: Path, as_json: bool, profile: str | None) -> int:
    from drivers.awr1843.errors import RadarProfileError
    from drivers.awr1843.inspect import NotARadarDumpError, summarise_dat

    try:
        for row in summarise_dat(path, profile):
            if row.get("summary"):
                if as_json:
                    _emit(row, True, "")
                else:
                    print("summary: " + ", ".join(f"{k} {v}" for k, v in row.items() if k != "summary"))
                continue
            tlvs = ",".join(str(t) for t in row["tlv_types"])
            _emit(
                row,
                as_json,
                f"frame {row['frame_number']:8d}  points {row['points']:4d}  tlv {tlvs:14s} "
                f"skipped {row['bytes_skipped']:5d}  SDK {row['sdk']} {row['platform']}",
            )
    except NotARadarDumpError as exc:
        print(
            f"usv-tracker decode: {exc}. (A VLP-16 capture must be a pcap or pcapng file.)",
            file=sys.stderr,
        )
        return 2
    except RadarProfileError as exc:
        print(f"usv-tracker decode: radar cfg refused: {exc}", file=sys.stderr)
        return 2
    return 0
