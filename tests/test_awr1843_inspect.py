"""``summarise_dat``: per-frame summaries and totals of real dumps; a clear error for other files."""

from __future__ import annotations

from pathlib import Path

import pytest

from drivers.awr1843.inspect import NotARadarDumpError, summarise_dat
from drivers.awr1843.parser import encode_frame


def test_walk_dump_summary(shared_fixtures: Path) -> None:
    rows = list(summarise_dat(shared_fixtures / "awr1843/xwr18xx_sdk3.6_walk_50m.dat"))
    frames, summary = rows[:-1], rows[-1]
    assert frames[0] == {
        "frame_number": 1986,
        "points": 0,
        "tlv_types": [1, 2, 6, 9],
        "bytes_skipped": 0,
        "sdk": "3.6.0.0",
        "platform": "xWR18xx",
    }
    assert summary == {
        "summary": True,
        "frames": 440,
        "points": 411,
        "first_frame_number": 1986,
        "last_frame_number": 2425,
        "gaps": 0,
        "dropped": 0,
        "skipped_bytes": 0,
        "trailing_bytes": 456,
        "tlv_type_counts": {1: 440, 2: 440, 6: 440, 7: 244, 9: 440},
        "bytes": 294_600,
    }


def test_legacy_dump_with_leading_partial_frame(shared_fixtures: Path) -> None:
    rows = list(summarise_dat(shared_fixtures / "awr1843/xwr16xx_sdk2.1_legacy_qformat.dat"))
    assert rows[0]["bytes_skipped"] == 216
    assert (rows[0]["sdk"], rows[0]["platform"], rows[0]["points"]) == ("2.1.0.4", "xWR16xx", 5)
    summary = rows[-1]
    assert (summary["frames"], summary["points"], summary["skipped_bytes"], summary["trailing_bytes"]) == (
        99,
        551,
        216,
        584,
    )


def test_gap_in_a_dump_is_reported(tmp_path: Path) -> None:
    path = tmp_path / "gappy.dat"
    blobs = [encode_frame(n, [[0.0, 5.0, 0.0]], [0.0], 20.0, 50.0) for n in (10, 11, 14)]
    path.write_bytes(b"junk" + b"".join(blobs))
    summary = list(summarise_dat(path))[-1]
    assert (summary["frames"], summary["gaps"], summary["skipped_bytes"]) == (3, 2, 4)


def test_not_a_radar_dump(tmp_path: Path, shared_fixtures: Path) -> None:
    with pytest.raises(NotARadarDumpError, match=r"no valid AWR1843 data frame in 1214 bytes"):
        list(summarise_dat(shared_fixtures / "awr1843/xwr18xx_best_range_50m_vis3.6.cfg"))
    empty = tmp_path / "empty.dat"
    empty.write_bytes(b"")
    with pytest.raises(NotARadarDumpError):
        list(summarise_dat(empty))


def test_own_synthetic_dump_is_current_and_decodes_as_documented() -> None:
    from tests.fixtures.awr1843_make_synthetic import DAT, synthetic_dump

    assert DAT.read_bytes() == synthetic_dump(), "regenerate with tests/fixtures/awr1843_make_synthetic.py"
    rows = list(summarise_dat(DAT))
    assert [r["frame_number"] for r in rows[:-1]] == [500, 501, 502, 503, 504, 506, 508, 509]
    assert [r["points"] for r in rows[:-1]] == [0, 1, 2, 3, 0, 2, 0, 1]
    assert [r["bytes_skipped"] for r in rows[:-1]] == [100, 0, 0, 29, 0, 120, 688, 0]
    summary = rows[-1]
    assert (summary["frames"], summary["dropped"], summary["gaps"]) == (8, 2, 2)
    assert (summary["skipped_bytes"], summary["trailing_bytes"], summary["bytes"]) == (937, 200, 6513)
    assert summary["tlv_type_counts"] == {1: 8, 2: 8, 6: 8, 7: 5, 9: 8}
