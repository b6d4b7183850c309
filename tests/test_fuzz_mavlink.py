"""Property tests of the MAVLink input path: random and mutated bytes arrive in UDP datagrams at the daemon's own
AutopilotLink port, are parsed by pymavlink as the daemon's reader does and taken by its handler. The link never
drops for them, and no non-finite pose enters the history."""

from __future__ import annotations

import random
import struct

from hypothesis import given
from hypothesis import strategies as st

from daemon.autopilot_port import MAX_REMEMBERED_TYPES
from daemon.mavlink_env import mavlink
from tests.fuzz_strategies import FUZZ, mutated, randoms
from tests.fuzz_targets import TARGETS, MavlinkInput, mavlink_messages, run_mavlink

MAVLINK = TARGETS["mavlink"]
_floats = st.floats(width=32)


@st.composite
def messages_with_any_values(draw: st.DrawFn) -> bytes:
    """Well-formed messages of the kinds the daemon uses, from its autopilot, carrying any values (NaN, inf,
    latitudes past the poles, times going backwards): the handlers' side of the property."""
    mav = mavlink.MAVLink(None, srcSystem=1, srcComponent=1)
    u32 = st.integers(0, 2**32 - 1)
    i32 = st.integers(-(2**31), 2**31 - 1)
    kind = draw(st.sampled_from(["hb", "att", "local", "global", "time", "sync", "ack"]))
    if kind == "hb":
        msg = mav.heartbeat_encode(
            draw(st.integers(0, 255)), draw(st.integers(0, 255)), 0, 0, draw(st.integers(0, 255))
        )
    elif kind == "att":
        msg = mav.attitude_encode(draw(u32), *[draw(_floats) for _ in range(6)])
    elif kind == "local":
        msg = mav.local_position_ned_encode(draw(u32), *[draw(_floats) for _ in range(6)])
    elif kind == "global":
        i16 = st.integers(-(2**15), 2**15 - 1)
        msg = mav.global_position_int_encode(
            draw(u32), *[draw(i32) for _ in range(4)], *[draw(i16) for _ in range(3)], 0
        )
    elif kind == "time":
        msg = mav.system_time_encode(draw(st.integers(0, 2**64 - 1)), draw(u32))
    elif kind == "sync":
        msg = mav.timesync_encode(draw(st.integers(-(2**63), 2**63 - 1)), draw(st.integers(-(2**63), 2**63 - 1)))
    else:
        msg = mav.command_ack_encode(draw(st.integers(0, 65535)), draw(st.integers(0, 255)), 0, 0, 1, 196)
    return bytes(msg.pack(mav))


@FUZZ
@given(st.binary(max_size=600), randoms())
def test_mavlink_random_bytes(data: bytes, rnd: random.Random) -> None:
    run_mavlink(data, rnd)


@FUZZ
@given(mutated(MAVLINK, "own"), randoms())
def test_mavlink_mutated_messages(data: bytes, rnd: random.Random) -> None:
    run_mavlink(data, rnd)


@FUZZ
@given(st.lists(messages_with_any_values(), min_size=1, max_size=6).map(b"".join), randoms())
def test_mavlink_messages_with_any_values(data: bytes, rnd: random.Random) -> None:
    run_mavlink(data, rnd)


def test_the_input_path_takes_real_messages() -> None:
    """The harness is live: good messages from the autopilot are parsed and handled, not silently lost."""
    feeder = MavlinkInput()  # a fresh link: the shared one has seen other autopilots' heartbeats
    try:
        for message in mavlink_messages()[:11]:  # system 1, component 1: the autopilot
            feeder.feed(message)
        counters = feeder.link.counters
    finally:
        feeder.close()
    assert counters.get("link_failures", 0) == 0
    # the first attitude came before the first position (no pose yet), the second's NaN roll is rejected before
    # that is asked; the TIMESYNC with tc1 = 0 asked for our clock
    expected = {
        "rx_messages": 11,
        "autopilot_heartbeats": 1,
        "pose_skipped_no_position": 1,
        "pose_rejected": 1,
        "global_ignored_local_active": 1,
        "timesync_answered": 1,
        "obstacle_distance_ignored": 1,
    }
    assert {k: counters.get(k) for k in expected} == expected


def _unknown_message(msgid: int) -> bytes:
    """A MAVLink 2 frame with an id outside the dialect: pymavlink cannot check its CRC and makes up a type."""
    return bytes([0xFD, 1, 0, 0, 0, 1, 1]) + struct.pack("<I", msgid)[:3] + b"\x00" + b"\x00\x00"


def test_line_noise_does_not_grow_pymavlinks_table_of_message_types() -> None:
    """Found by bench/fuzz.py (peak RSS +22 MiB in 600,000 inputs): every made-up 'UNKNOWN_<id>' was kept forever."""
    feeder = MavlinkInput()
    try:
        feeder.feed(mavlink_messages()[0])  # the autopilot's heartbeat: a real type, remembered
        for i in range(MAX_REMEMBERED_TYPES + 200):
            feeder.feed(_unknown_message(0x800000 + i))
        messages = feeder.link.port._conn.sysid_state[1].messages
        counters = feeder.link.counters
    finally:
        feeder.close()
    assert counters["rx_messages"] == MAX_REMEMBERED_TYPES + 201 and counters.get("link_failures", 0) == 0
    assert len(messages) <= MAX_REMEMBERED_TYPES and "HEARTBEAT" in messages
