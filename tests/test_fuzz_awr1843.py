"""Property tests of the AWR1843 driver's parsers: the data-port stream (fed in random read sizes), the CLI's
answer handling (pure, and over a real pseudo-terminal), and the TI .cfg parser."""

from __future__ import annotations

import os
import random
import struct
import threading
import tty

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from drivers.awr1843.cli import PROMPT, CliReply, CliSession
from drivers.awr1843.errors import RadarConfigError
from drivers.awr1843.parser import HEADER_LEN, MAGIC, encode_frame
from tests.fuzz_strategies import EDGE_INTS, FUZZ, mutated, needs_public_captures, randoms
from tests.fuzz_targets import _CLI_ANSWERS, TARGETS, run_awr1843_cli, run_awr1843_stream, run_cfg

STREAM, CLI, CFG = TARGETS["awr1843_stream"], TARGETS["awr1843_cli"], TARGETS["cfg"]

# --- data port ---------------------------------------------------------------------------------------------------
_floats = st.floats(width=32, allow_nan=True, allow_infinity=True)


@st.composite
def frames(draw: st.DrawFn) -> bytes:
    """A frame as the firmware builds it, with any float in its points (NaN, inf, 1e38), any SDK major and TLVs."""
    n = draw(st.integers(0, 6))
    xyz = np.array(draw(st.lists(st.tuples(_floats, _floats, _floats), min_size=n, max_size=n)), dtype=np.float64)
    legacy = draw(st.booleans())
    return encode_frame(
        draw(st.integers(0, 2**32 - 1)),
        xyz.reshape(-1, 3) if not legacy else np.nan_to_num(xyz, posinf=10, neginf=-10).reshape(-1, 3).clip(-60, 60),
        np.array(draw(st.lists(_floats, min_size=n, max_size=n)), dtype=np.float64) if not legacy else np.zeros(n),
        20.0,
        60.0,
        version=(2, 1, 0, 4) if legacy else (3, 6, 0, 0),
        velocity_resolution=0.1,
        stats=draw(st.none() | st.just((1, 2, 3, 4, 5, 6))),
        extra_tlvs=draw(st.lists(st.tuples(st.integers(4, 0xFFFF), st.binary(max_size=40)), max_size=2)),
    )


@st.composite
def header_with_random_fields(draw: st.DrawFn) -> bytes:
    """A magic word and a header whose lengths and counts are edge values: where a trusting parser overreads."""
    fields = [draw(EDGE_INTS | st.integers(0, 2**32 - 1)) & 0xFFFFFFFF for _ in range(8)]
    if draw(st.booleans()):
        fields[0] = 0x03060000  # SDK 3.6: past the version check
        fields[2] = draw(st.sampled_from([0xA1843, 0xA1642, 0xA1443]))
    return MAGIC + struct.pack("<8I", *fields) + draw(st.binary(max_size=200))


stream_pieces = st.lists(
    st.one_of(frames(), header_with_random_fields(), st.binary(max_size=64), st.just(MAGIC)), max_size=8
).map(b"".join)


@FUZZ
@given(stream_pieces, randoms())
def test_data_stream_of_frames_headers_and_garbage(data: bytes, rnd: random.Random) -> None:
    run_awr1843_stream(data, rnd)


@FUZZ
@given(st.binary(max_size=2048), randoms())
def test_data_stream_random_bytes(data: bytes, rnd: random.Random) -> None:
    run_awr1843_stream(data, rnd)


@FUZZ
@given(mutated(STREAM, "own"), randoms())
def test_data_stream_mutated_synthetic_dump(data: bytes, rnd: random.Random) -> None:
    run_awr1843_stream(data, rnd)


@needs_public_captures
@FUZZ
@given(mutated(STREAM, "public"), randoms())
def test_data_stream_mutated_public_dumps(data: bytes, rnd: random.Random) -> None:
    run_awr1843_stream(data, rnd)


def test_a_frame_stream_read_byte_by_byte_gives_every_frame() -> None:
    """The chunking property on a stream with nothing wrong in it: every frame, whatever the read sizes."""
    stream = b"".join(encode_frame(k, np.array([[1.0, 5.0 + k, 0.0]]), [0.5], 20.0, 60.0) for k in range(5))
    run_awr1843_stream(stream, random.Random(3))
    assert len(stream) >= 5 * (HEADER_LEN + 8 + 16)


# --- CLI answers -------------------------------------------------------------------------------------------------
@FUZZ
@given(st.one_of(st.binary(max_size=300), mutated(CLI, "own")), randoms())
def test_cli_answer_handling(data: bytes, rnd: random.Random) -> None:
    run_awr1843_cli(data, rnd)


class _FakeDeviceAnswer:
    """The device side of a real pseudo-terminal: to every line it receives, it answers the same given bytes."""

    def __init__(self, answer: bytes) -> None:
        self.master, slave = os.openpty()
        tty.setraw(slave)
        self.path = os.ttyname(slave)
        self._slave = slave
        self.answer = answer
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._serve, daemon=True)
        self._thread.start()

    def _serve(self) -> None:
        import select

        while not self._stop.is_set():
            ready, _, _ = select.select([self.master], [], [], 0.02)
            if not ready:
                continue
            try:
                data = os.read(self.master, 4096)
            except OSError:
                return
            if b"\n" in data:
                os.write(self.master, self.answer)

    def close(self) -> None:
        self._stop.set()
        self._thread.join(1.0)
        os.close(self.master)
        os.close(self._slave)


@settings(FUZZ, max_examples=15)  # each example waits out real serial timeouts
@given(
    answer=st.one_of(st.binary(max_size=200), st.sampled_from(_CLI_ANSWERS)),
    prompt=st.booleans(),
    line=st.sampled_from(["sensorStop", "profileCfg 0 77 7 3 39 0 0 100 1 256 7200 0 0 30", "flushCfg"]),
)
def test_cli_session_over_a_real_pty(answer: bytes, prompt: bool, line: str) -> None:
    """Whatever comes back on the wire, ``command`` returns a reply or raises RadarConfigError, within its timeouts."""
    device = _FakeDeviceAnswer(line.encode() + answer + (PROMPT.encode() if prompt else b""))
    try:
        with CliSession(device.path, command_timeout=0.1, wake_timeout=0.05, wake_attempts=1) as cli:
            try:
                reply = cli.command(line, line_number=3)
            except RadarConfigError as exc:
                assert exc.line == line and exc.line_number == 3
            else:
                assert isinstance(reply, CliReply) and reply.command == line
    finally:
        device.close()


# --- TI .cfg ----------------------------------------------------------------------------------------------------
_NUMBERS = st.one_of(
    EDGE_INTS.map(str),
    st.sampled_from(["-1", "0.5", "1e9", "1e999", "-1e999", "1e-310", "1e300", "nan", "inf", ".", "1.", "+0", "-0"]),
    st.floats(allow_nan=False, allow_infinity=False).map(repr),
)
_COMMANDS = ["profileCfg", "chirpCfg", "frameCfg", "guiMonitor", "cfarFovCfg", "channelCfg", "sensorStart", "xCfg"]


@st.composite
def cfg_texts(draw: st.DrawFn) -> bytes:
    """The lines of a working cfg, some of them replaced by a known command with edge-value arguments."""
    lines = CFG.seeds("own")[0].decode().splitlines()
    for _ in range(draw(st.integers(1, 4))):
        command = draw(st.sampled_from(_COMMANDS))
        args = draw(st.lists(_NUMBERS, max_size=16))
        index = draw(st.integers(0, len(lines)))
        lines.insert(index, " ".join([command, *args]))
    return "\n".join(lines).encode()


@FUZZ
@given(cfg_texts(), randoms())
def test_cfg_parser_edge_numbers(data: bytes, rnd: random.Random) -> None:
    run_cfg(data, rnd)


@FUZZ
@given(st.one_of(st.binary(max_size=400), mutated(CFG, "own")), randoms())
def test_cfg_parser_random_and_mutated(data: bytes, rnd: random.Random) -> None:
    run_cfg(data, rnd)


@needs_public_captures
@FUZZ
@given(mutated(CFG, "public"), randoms())
def test_cfg_parser_mutated_public_cfgs(data: bytes, rnd: random.Random) -> None:
    run_cfg(data, rnd)
