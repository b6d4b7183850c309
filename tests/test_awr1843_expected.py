"""Radar frames of another configuration than the one the daemon sent are rejected and counted, never decoded.

Real captures with the cfg that made them must pass untouched (no false rejection); captures of other boards must
not. On a live port (a real pty opened by path through pyserial, as the daemon opens the radar) a stream that
switches configuration in mid-flight loses exactly the foreign frames.
"""

from __future__ import annotations

import logging
import os
import threading
import tty
from pathlib import Path

import numpy as np
import pytest

from drivers.awr1843.expected import XWR18XX, ExpectedStream, platform_code
from drivers.awr1843.parser import ParserStats, RadarFrameParser, encode_frame
from drivers.awr1843.profile import load_profile
from drivers.awr1843.sources import FileRadarSource, SerialRadarSource
from tests.conftest import REPO
from tests.test_awr1843_sources import CFG, WALK, Reader

NOISEPROF = "awr1843/xwr18xx_sdk3.6_profile2d_noiseprof.dat"
PROFILE_2D = "awr1843/xwr18xx_sdk3.5_profile_2d.cfg"
DOORS = "awr1843/xwr68xx_sdk3.3_ti_doors.dat"
LEGACY = "awr1843/xwr16xx_sdk2.1_legacy_qformat.dat"


def replay(path: Path, expected: ExpectedStream | None) -> tuple[int, ParserStats]:
    """(frames delivered, parser counters) of a capture read with ``expected``."""
    source = FileRadarSource(path, None, expected=expected, speed=None, start_time=0.0)
    frames = list(source.frames(threading.Event()))
    return len(frames), source.parser.stats


def test_the_daemon_cfg_expects_an_xwr18xx_with_its_tlvs_and_range_bins() -> None:
    e = ExpectedStream.for_config(load_profile(REPO / "daemon" / "profiles" / "awr1843_50m.cfg"))
    # guiMonitor -1 1 0 0 0 0 1: points with side info, stats (and temperature); no profile, no heat map
    assert e == ExpectedStream(XWR18XX, None, False, frozenset({1, 7, 6, 9}), 256)
    assert platform_code("xwr68xx") == 0xA6843 and platform_code("any") is None
    with pytest.raises(ValueError, match="unknown radar platform 'AWR1843'"):
        platform_code("AWR1843")


def test_real_captures_pass_with_the_cfg_that_made_them(shared_fixtures: Path) -> None:
    n, st = replay(shared_fixtures / WALK, ExpectedStream.for_config(load_profile(shared_fixtures / CFG)))
    assert (n, st.frames_rejected) == (440, 0)
    n, st = replay(shared_fixtures / NOISEPROF, ExpectedStream.for_config(load_profile(shared_fixtures / PROFILE_2D)))
    assert (n, st.frames_rejected) == (196, 0)


def test_captures_of_other_configurations_and_boards_are_rejected(shared_fixtures: Path) -> None:
    walk_cfg = ExpectedStream.for_config(load_profile(shared_fixtures / CFG))
    # the walk cfg sends no noise profile: the capture that has one came from another configuration
    n, st = replay(shared_fixtures / NOISEPROF, walk_cfg)
    assert (n, st.frames_rejected, st.frames_dropped) == (0, 196, 0)
    assert st.last_rejection == "TLV type(s) [3] the cfg's guiMonitor does not enable"
    assert st.bytes_skipped == st.bytes_received  # the file ends on a frame boundary: every byte accounted for
    n, st = replay(shared_fixtures / DOORS, walk_cfg)
    assert (n, st.frames_rejected, st.last_rejection) == (0, 101, "platform xWR68xx, configured xWR18xx")
    n, st = replay(shared_fixtures / LEGACY, walk_cfg)
    assert (n, st.frames_rejected, st.last_rejection) == (0, 99, "platform xWR16xx, configured xWR18xx")
    # An IWR6843 named in radar.platform is accepted (its cfg unknown here: the platform alone is checked).
    n, st = replay(shared_fixtures / DOORS, ExpectedStream.for_config(None, platform_code("xWR68xx")))
    assert (n, st.frames_rejected) == (101, 0)


# ------------------------------------------------------------------------------------------------------ live
OURS = np.array([[-2.0, 20.0, 0.0], [5.0, 35.0, 0.0]])
THEIRS = np.array([[4.0, 6.0, 0.0], [-7.0, 12.0, 0.0], [1.0, 3.0, 0.0]])
STATS = (700, 7300, 83000, 0, 0, 0)
TEMPS = (0, 1000, 40, 40, 41, 40, 42, 42, 43, 43, 42, 41)


def frame(number: int, xyz: np.ndarray = OURS, **kwargs) -> bytes:  # type: ignore[no-untyped-def]
    """A frame as the fixture cfg makes the firmware send it (TLVs 1, 7, 2 of 256 bins, 6, 9), unless overridden."""
    args = dict(range_profile=np.full(256, 10.0), stats=STATS, temperature=TEMPS)
    args.update(kwargs)
    return encode_frame(number, xyz, np.zeros(len(xyz)), 20.0, 60.0, **args)  # type: ignore[arg-type]


def test_a_live_stream_switching_configuration_loses_exactly_the_foreign_frames(
    shared_fixtures: Path, caplog: pytest.LogCaptureFixture
) -> None:
    caplog.set_level(logging.INFO, logger="drivers.awr1843")
    profile = load_profile(shared_fixtures / CFG)
    foreign = {
        105: frame(105, THEIRS, platform=0xA6843),  # another board: an IWR6843
        106: frame(106, THEIRS, platform=0xA6843),
        107: frame(107, THEIRS, extra_tlvs=[(4, bytes(64))]),  # an azimuth heat map the cfg turns off
        108: frame(108, THEIRS, range_profile=np.full(512, 10.0)),  # 1024 ADC samples, not 256
        109: frame(109, THEIRS, noise_profile=np.full(256, 8.0)),  # a noise profile the cfg turns off
        110: frame(110, THEIRS, sub_frame=1),  # an advanced sub-frame configuration
        111: frame(111, THEIRS, version=(2, 1, 0, 4), velocity_resolution=0.1),  # SDK 2.x, the cfg is for 3.x
        112: frame(112, THEIRS, version=(3, 5, 0, 4)),  # another firmware than the one this stream started with
    }
    stream = [frame(n) for n in range(100, 105)] + list(foreign.values()) + [frame(n) for n in range(113, 118)]
    master, slave = os.openpty()
    tty.setraw(slave)  # bytes pass unchanged
    source = SerialRadarSource(
        "", os.ttyname(slave), profile, configure=False, expected=ExpectedStream.for_config(profile)
    )
    try:
        source.connect()  # pyserial opens the pty by its path, as the daemon opens /dev/serial/by-id/...
        reader = Reader(source)
        try:
            os.write(master, b"".join(stream))  # one burst: the parser meets every boundary mid-read too
            st = source.stats.parser
            reader.wait_for(lambda: st.frames_ok == 10 and st.frames_rejected == 8)
        finally:
            reader.close()
    finally:
        os.close(master)
        os.close(slave)
    assert [f.frame_number for f in reader.frames] == [100, 101, 102, 103, 104, 113, 114, 115, 116, 117]
    assert (st.frames_rejected, st.frames_dropped, st.frames_lost, st.frame_number_resets) == (8, 0, 0, 0)
    assert st.bytes_skipped == sum(len(f) for f in foreign.values())
    assert st.last_rejection == "firmware 3.5.0.4 after frames of 3.6.0.0"
    # TI (x, y, z) -> body FRD (y, x, -z) with the default mount: only our points, in every delivered frame
    for f in reader.frames:
        np.testing.assert_allclose(f.xyz, OURS[:, [1, 0, 2]] * [1, 1, -1], atol=1e-5)
    assert reader.frames[5].bytes_skipped == st.bytes_skipped
    # one warning, not eight: the first rejection is logged at once, the rest summed up after a minute
    warnings = [r.getMessage() for r in caplog.records if "of another configuration rejected" in r.getMessage()]
    assert warnings == [
        "AWR1843 data: 1 frame(s) of another configuration rejected (frame 105: platform xWR68xx, configured "
        'xWR18xx); another board sends them: if it is meant to, set [radar] platform = "xWR68xx" (or "any")'
    ]


def test_the_firmware_is_learnt_again_after_a_reconnect() -> None:
    parser = RadarFrameParser(expected=ExpectedStream())
    assert [f.frame_number for f in parser.feed(frame(1) + frame(2, version=(3, 5, 0, 4)), 0.0)] == [1]
    assert parser.stats.frames_rejected == 1
    parser.reset_stream()  # what a reconnect does: possibly another board, configured anew
    assert [f.frame_number for f in parser.feed(frame(3, version=(3, 5, 0, 4)), 1.0)] == [3]
    assert [f.frame_number for f in parser.feed(frame(4), 2.0)] == []
    assert parser.stats.frames_rejected == 2
