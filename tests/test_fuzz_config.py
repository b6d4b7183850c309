"""Property tests of the TOML config loader and its validation: any file gives a Config whose every section checks
out, or a ConfigError naming its problems; never another exception."""

from __future__ import annotations

import dataclasses
import json
import math
import random
from typing import Any

from hypothesis import given
from hypothesis import strategies as st

from daemon.config import Config
from tests.fuzz_strategies import EDGE_INTS, FUZZ, mutated, randoms
from tests.fuzz_targets import TARGETS, run_config

CONFIG = TARGETS["config"]


def _toml(value: Any) -> str:
    """A TOML literal; json's string escapes are TOML's, and a lone surrogate is simply invalid TOML."""
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, float):
        return (
            ("nan" if math.isnan(value) else ("inf" if value > 0 else "-inf"))
            if not math.isfinite(value)
            else repr(value)
        )
    if isinstance(value, int):
        return str(value)
    if isinstance(value, str):
        return json.dumps(value)
    if isinstance(value, list):
        return "[" + ", ".join(_toml(v) for v in value) + "]"
    return "{" + ", ".join(f"{k} = {_toml(v)}" for k, v in value.items()) + "}"


_URLS = st.sampled_from(
    [
        "udp://0.0.0.0:2368",
        "udp://[::1",
        "udp://[::1]:99999",
        "pcap://",
        "serial:///dev/ttyACM0?baud=fast",
        "serial:///dev/ttyACM0?baud=-1",
        "serial:///dev/ttyACM0?baud=²",
        "file://",
        "sim://harbour",
        "udpout:127.0.0.1",
        "udpout:127.0.0.1:14550",
        "tcp:host:0",
        "/dev/ttyAMA0,0",
        "/dev/ttyAMA0,9" * 3,
        "bogus:thing",
        "run.tlog",
        "",
    ]
)
_SCALARS = st.one_of(
    st.booleans(),
    EDGE_INTS,
    EDGE_INTS.map(lambda v: -v),
    st.integers(-(10**400), 10**400),
    st.floats(),
    st.text(max_size=20),
    _URLS,
)
_VALUES = st.recursive(
    _SCALARS,
    lambda inner: st.lists(inner, max_size=3) | st.dictionaries(st.sampled_from(["x", "yaw", "a"]), inner, max_size=3),
    max_leaves=6,
)  # fmt: skip


def _fields(cls: type) -> list[str]:
    return [f.name for f in dataclasses.fields(cls)]


_SECTIONS = {f.name: f.type for f in dataclasses.fields(Config)}


@st.composite
def config_files(draw: st.DrawFn) -> bytes:
    """Sections with known and unknown keys holding values of every TOML type, edge numbers and bad URLs."""
    lines = []
    config = Config()
    for section in draw(st.lists(st.sampled_from(sorted(_SECTIONS)), max_size=4, unique=True)):
        obj = getattr(config, section)
        names = [*_fields(type(obj)), "max_ditance_m", "lidar", "mount"]
        lines.append(f"[{section}]")
        for key in draw(st.lists(st.sampled_from(names), max_size=5, unique=True)):
            lines.append(f"{key} = {_toml(draw(_VALUES))}")
    if draw(st.booleans()):
        lines.insert(0, f"{draw(st.sampled_from(sorted(_SECTIONS)))} = {_toml(draw(_SCALARS))}")
    return "\n".join(lines).encode("utf-8", errors="surrogatepass")


@FUZZ
@given(config_files(), randoms())
def test_config_files_of_any_shape(data: bytes, rnd: random.Random) -> None:
    run_config(data, rnd)


@FUZZ
@given(st.one_of(st.binary(max_size=300), mutated(CONFIG, "own")), randoms())
def test_config_random_and_mutated(data: bytes, rnd: random.Random) -> None:
    run_config(data, rnd)
