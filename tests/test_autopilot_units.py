"""The link's pure parts: TIMESYNC offset filter, tangent-plane projection, rate-request state machine,
connection strings, pose assembly, and the simulator's ArduPilot sector reduction."""

from __future__ import annotations

import math

import numpy as np
import pytest

from daemon.autopilot_geo import LocalTangentPlane
from daemon.autopilot_port import parse_autopilot_url
from daemon.autopilot_pose import GLOBAL, LOCAL, PoseAssembler
from daemon.autopilot_rates import ACCEPTED, NO_ACK, IntervalRequester
from daemon.mavlink_env import mavlink, signing_key_from_passphrase
from daemon.pose_history import PoseHistory
from daemon.timesync import NS_PER_MS, NS_PER_S, TimeSync
from drivers.frames import body_rates_to_euler, euler_rates_to_body
from simulator.autopilot import ReceivedObstacleDistance, proximity_sectors
from tracker.ego import rotation_matrices

OFFSET = 123_456_789_012  # autopilot clock - host clock, ns


def exchange(ts: TimeSync, send_ns: int, out_ns: int, back_ns: int) -> bool:
    """One TIMESYNC round trip with the given one-way delays (the autopilot stamps at receipt)."""
    _tc1, ts1 = ts.make_request(send_ns)
    tc1 = send_ns + out_ns + OFFSET
    return ts.on_reply(tc1, ts1, send_ns + out_ns + back_ns)


def test_timesync_offset_from_min_rtt_samples_despite_slow_asymmetric_ones() -> None:
    ts = TimeSync(window=32, min_samples=3)
    assert not ts.synced
    assert ts.to_host(5000, 7.25) == 7.25  # unsynced: host receive time
    t = 10 * NS_PER_S
    rng = np.random.default_rng(1)
    for i in range(24):
        if i % 3 == 0:  # fast, symmetric exchanges: 0.2 ms each way
            exchange(ts, t, 200_000, 200_000)
        else:  # slow ones, delayed on the way back only (a busy serial buffer): would bias the mean by ms
            exchange(ts, t, 200_000, int(rng.uniform(5, 40) * NS_PER_MS))
        t += NS_PER_S
    assert ts.synced
    assert ts.offset_ns == OFFSET
    assert ts.rtt_ns == 400_000
    # a message stamped by the autopilot at boot time ms maps back onto the host clock
    host = ts.to_host_ns(777_000, 0)
    assert host == 777_000 * NS_PER_MS - OFFSET


def test_timesync_rejects_foreign_and_impossible_replies() -> None:
    ts = TimeSync(min_samples=1)
    assert not ts.on_reply(OFFSET, 42, 100)  # nobody asked with ts1 = 42 (another GCS's exchange)
    _, ts1 = ts.make_request(1_000)
    assert not ts.on_reply(OFFSET, ts1, 1_000 + 2 * NS_PER_S)  # 2 s round trip: useless
    assert not ts.on_reply(OFFSET, ts1, 2_000)  # answered twice: the first answer used the request up
    assert ts.rejected == 3 and not ts.synced


def test_timesync_reboot_and_jump_reset_the_estimate() -> None:
    ts = TimeSync(min_samples=1)
    rx = 50 * NS_PER_S
    exchange(ts, rx, 100_000, 100_000)
    assert ts.synced
    boot_ms = (rx + OFFSET) // NS_PER_MS
    assert not ts.check_boot_time(boot_ms, rx)
    assert not ts.check_boot_time(boot_ms + 20, rx + 20 * NS_PER_MS)
    assert not ts.check_boot_time(boot_ms - 100, rx)  # 100 ms out of order: within tolerance
    # reboot: boot time restarts near zero
    assert ts.check_boot_time(1500, rx + NS_PER_S)
    assert not ts.synced and ts.resets == 1 and "reboot" in ts.last_reset_reason
    assert ts.to_host(1500, 51.0) == 51.0  # fallback again
    # synced again, then a boot time 10 s ahead of where the clock should be: a jump
    exchange(ts, rx + 2 * NS_PER_S, 100_000, 100_000)
    assert ts.synced
    good_ms = (rx + 3 * NS_PER_S + OFFSET) // NS_PER_MS
    assert not ts.check_boot_time(good_ms, rx + 3 * NS_PER_S)
    assert ts.check_boot_time(good_ms + 10_000, rx + 3 * NS_PER_S)
    assert ts.resets == 2


def test_tangent_plane_round_trip_and_known_distances() -> None:
    plane = LocalTangentPlane(59.41, 10.49, 12.0)
    ned = plane.to_ned(59.41 + 1e-3, 10.49, 2.0)
    assert ned[0] == pytest.approx(111.2, abs=0.3)  # one millidegree of latitude ~ 111 m
    assert ned[1] == pytest.approx(0.0, abs=1e-9)
    assert ned[2] == pytest.approx(10.0)
    east = plane.to_ned(59.41, 10.49 + 1e-3, 12.0)
    assert east[1] == pytest.approx(111.4 * math.cos(math.radians(59.41)), abs=0.3)
    pts = np.array([[100.0, -250.0, 1.5], [-3000.0, 4000.0, -2.0]])
    lat, lon, alt = plane.to_geodetic(pts)
    np.testing.assert_allclose(plane.to_ned(lat, lon, alt), pts, atol=1e-6)
    # across the antimeridian
    fiji = LocalTangentPlane(-17.0, 179.9995, 0.0)
    e = fiji.to_ned(-17.0, -179.9995, 0.0)
    assert e[1] == pytest.approx(106.5, abs=0.5)


def test_interval_requester_is_sequential_with_retries() -> None:
    att, gpi = mavlink.MAVLINK_MSG_ID_ATTITUDE, mavlink.MAVLINK_MSG_ID_GLOBAL_POSITION_INT
    r = IntervalRequester({att: 50.0, gpi: 20.0}, ack_timeout=0.5, max_attempts=2)
    assert r.poll(0.0) is None  # nothing until restart()
    r.restart()
    assert r.poll(0.0) == (att, 20_000, 0)
    assert r.poll(0.1) is None  # waiting for the ACK
    assert r.on_ack(mavlink.MAV_RESULT_ACCEPTED) == att
    assert r.poll(0.2) == (gpi, 50_000, 0)
    assert r.poll(0.8) == (gpi, 50_000, 1)  # timed out: resent with confirmation 1
    assert r.poll(1.4) is None  # second timeout: given up
    assert r.status == {att: ACCEPTED, gpi: NO_ACK}
    assert not r.busy
    r.restart()
    assert r.poll(2.0) == (att, 20_000, 0)
    assert r.on_ack(mavlink.MAV_RESULT_DENIED) == att
    assert r.status[att] == "refused:MAV_RESULT_DENIED"
    assert r.on_ack(mavlink.MAV_RESULT_ACCEPTED) is None  # nothing pending


def test_parse_autopilot_url() -> None:
    assert parse_autopilot_url("udpout:127.0.0.1:14550", 921600) == ("udpout:127.0.0.1:14550", 921600)
    assert parse_autopilot_url("tcpin:0.0.0.0:5760", 57600) == ("tcpin:0.0.0.0:5760", 57600)
    assert parse_autopilot_url("/dev/ttyAMA0", 921600) == ("/dev/ttyAMA0", 921600)
    assert parse_autopilot_url("/dev/ttyAMA0,57600", 921600) == ("/dev/ttyAMA0", 57600)
    assert parse_autopilot_url("serial:///dev/ttyACM0?baud=115200", 921600) == ("/dev/ttyACM0", 115200)
    for bad in ("", "udpout:127.0.0.1", "udpout:host:notaport", "run.tlog", "ttyS0", "/dev/ttyS0,fast"):
        with pytest.raises(ValueError):
            parse_autopilot_url(bad, 921600)


def test_signing_key_from_passphrase_is_mavproxy_sha256() -> None:
    key = signing_key_from_passphrase("abc")
    assert key.hex() == "ba7816bf8f01cfea414140de5dae2223b00361a396177a9cb410ff61f20015ad"
    with pytest.raises(ValueError):
        signing_key_from_passphrase("")


def test_pose_assembler_prefers_local_and_waits_for_it() -> None:
    h = PoseHistory()
    a = PoseAssembler(h, position_timeout=1.0, global_grace=1.0)
    assert a.on_attitude(0.0, 0, 0, 0.5, 0, 0, 0) is None  # no position yet
    a.on_global_position(0.0, 59.41, 10.49, 0.0, np.zeros(3))
    assert a.position_source is None  # grace: LOCAL_POSITION_NED may still come
    a.on_local_position(0.5, np.array([10.0, 20.0, 0.0]), np.array([2.0, 0.0, 0.0]))
    assert a.position_source == LOCAL and a.world_epoch == 0
    p = a.on_attitude(0.55, 0.0, 0.0, 0.5, 0.0, 0.0, 0.2)
    assert p is not None
    # Reckoned 50 ms ahead along the turn: 2 m/s north turning at 0.2 rad/s has turned 0.01 rad east by then, and
    # the chord runs at half that.
    np.testing.assert_allclose(p.position, [10.0 + 0.1 * np.cos(0.005), 20.0 + 0.1 * np.sin(0.005), 0.0], atol=1e-12)
    np.testing.assert_allclose(p.velocity, [2.0 * np.cos(0.01), 2.0 * np.sin(0.01), 0.0], atol=1e-12)
    assert p.yaw_rate == pytest.approx(0.2)
    a.on_global_position(3.0, 59.41, 10.49, 0.0, np.zeros(3))
    assert a.position_source == LOCAL and a.global_ignored == 1
    assert a.on_attitude(2.0, 0, 0, 0, 0, 0, 0) is None  # position 1.5 s old: no pose
    a.on_autopilot_reboot()
    assert a.world_epoch == 1 and len(h) == 0 and a.position_source is None


def test_pose_assembler_turns_attitudes_body_rates_into_euler_rates() -> None:
    """ATTITUDE's rollspeed/pitchspeed/yawspeed are body rates; on a boat rolled 5 deg and pitched 3 deg they
    differ from the Euler rates the pose history extrapolates with, and the conversion round-trips exactly."""
    roll, pitch = math.radians(5.0), math.radians(3.0)
    euler = (0.11, -0.07, 0.2)  # rad/s: roll, pitch, yaw rates
    p, q, r = euler_rates_to_body(roll, pitch, *euler)
    assert (p, q, r) != pytest.approx(euler, abs=1e-3)  # not the same numbers at this attitude
    assert body_rates_to_euler(roll, pitch, p, q, r) == pytest.approx(euler, abs=1e-12)
    assert euler_rates_to_body(0.0, 0.0, *euler) == pytest.approx(euler, abs=1e-15)  # level: they coincide
    # independent of both: the body rates are R^T dR/dt of the body->NED rotation R = Rz(yaw) Ry(pitch) Rx(roll)
    h, yaw = 1e-6, 0.4
    r0 = rotation_matrices(np.array([roll]), np.array([pitch]), np.array([yaw]))[0]
    r1 = rotation_matrices(
        np.array([roll + euler[0] * h]), np.array([pitch + euler[1] * h]), np.array([yaw + euler[2] * h])
    )[0]
    w = r0.T @ (r1 - r0) / h  # skew matrix of (p, q, r)
    assert (w[2, 1], w[0, 2], w[1, 0]) == pytest.approx((p, q, r), abs=1e-5)
    a = PoseAssembler(PoseHistory())
    a.on_local_position(0.0, np.zeros(3), np.zeros(3))
    got = a.on_attitude(0.02, roll, pitch, 0.0, p, q, r)
    assert got is not None
    assert (got.roll_rate, got.pitch_rate, got.yaw_rate) == pytest.approx(euler, abs=1e-12)


def test_pose_assembler_global_after_grace_and_geodetic_anchor() -> None:
    plane = LocalTangentPlane(59.41, 10.49, 3.0)
    a = PoseAssembler(PoseHistory(), global_grace=0.5)
    for i in range(12):
        t = 0.1 * i
        lat, lon, alt = plane.to_geodetic(np.array([t * 4.0, 0.0, 0.0]))
        a.on_global_position(t, float(lat), float(lon), float(alt), np.array([4.0, 0.0, 0.0]))
    assert a.position_source == GLOBAL
    p = a.on_attitude(1.1, 0, 0, 0, 0, 0, 0)
    assert p is not None
    # the plane starts at the first fix used (t = 0.5, 2 m north of the sim's origin)
    np.testing.assert_allclose(p.position, [4.4 - 2.0, 0.0, 0.0], atol=1e-6)
    lat, lon, _alt = a.world_to_geodetic(np.array([0.0, 0.0, 0.0]))
    np.testing.assert_allclose(plane.to_ned(lat, lon, 3.0), [2.0, 0.0, 0.0], atol=1e-6)


def test_pose_assembler_starts_a_new_world_on_an_estimator_reset_but_not_on_a_hard_turn() -> None:
    """Tracks kept in the world frame across an EKF position or yaw reset would sit metres or degrees off the returns
    placed after it; a boat accelerating and turning hard is no reset."""
    h = PoseHistory()
    a = PoseAssembler(h)
    # 12 s: accelerating 1 m/s^2 north from 2 m/s, turning at up to 1 rad/s with 2 rad/s^2 swings; positions at
    # 10 Hz (velocity from the same motion), attitude at 50 Hz
    for i in range(600):
        t = 0.02 * i
        yaw = 0.5 * math.sin(2.0 * t)
        if i % 5 == 0:
            a.on_local_position(t, np.array([2.0 * t + 0.5 * t * t, 0.0, 0.0]), np.array([2.0 + t, 0.0, 0.0]))
        assert a.on_attitude(t, 0.0, 0.0, yaw, 0.0, 0.0, math.cos(2.0 * t)) is not None
    assert a.world_epoch == 0 and a.estimator_resets == 0
    # the EKF resets its position 3 m east (GPS glitch recovered)
    a.on_local_position(12.0, np.array([96.0, 3.0, 0.0]), np.array([14.0, 0.0, 0.0]))
    assert a.world_epoch == 1 and a.estimator_resets == 1 and len(h) == 0
    a.on_local_position(12.1, np.array([97.4, 3.0, 0.0]), np.array([14.0, 0.0, 0.0]))  # continues from there
    assert a.world_epoch == 1
    # a yaw reset: 15 deg at once, on top of where the turn was going
    yaw = 0.5 * math.sin(2.0 * 12.12)
    a.on_attitude(12.12, 0.0, 0.0, yaw, 0.0, 0.0, math.cos(2.0 * 12.12))
    assert a.world_epoch == 1
    assert a.on_attitude(12.14, 0.0, 0.0, yaw + math.radians(15.0), 0.0, 0.0, 0.0) is not None
    assert a.world_epoch == 2 and a.estimator_resets == 2 and len(h) == 1  # the new world's first pose
    # across +-pi at 1 rad/s: a turn, not a reset
    b = PoseAssembler(PoseHistory())
    b.on_local_position(0.0, np.zeros(3), np.zeros(3))
    b.on_attitude(0.00, 0.0, 0.0, math.pi - 0.01, 0.0, 0.0, 1.0)
    b.on_attitude(0.02, 0.0, 0.0, -math.pi + 0.01, 0.0, 0.0, 1.0)
    assert b.world_epoch == 0 and b.estimator_resets == 0


def _od(distances: np.ndarray, inc_f: float = 5.0, inc: int = 0, offset: float = 0.0) -> ReceivedObstacleDistance:
    return ReceivedObstacleDistance(0.0, 1, 196, False, 0, 0, distances, inc, 50, 10000, inc_f, offset, 12)


def test_sim_sector_reduction_follows_ardupilot_rules() -> None:
    d = np.full(72, 10001, dtype=np.uint16)  # clear everywhere: > max, dropped
    d[0] = 2500  # 0 deg -> sector 0
    d[4] = 2000  # 20 deg -> sector 0 (centred on 0, +-22.5), nearer: wins
    d[5] = 1200  # 25 deg -> sector 1
    d[18] = 1000  # 90 deg -> sector 2
    d[36] = 65535  # unknown: dropped
    d[40] = 0  # 200 deg, zero: dropped by AP
    d[50] = 30  # 250 deg, below min: dropped
    d[71] = 900  # 355 deg -> sector 0, nearest of all
    dist, bearing = proximity_sectors(_od(d))
    np.testing.assert_allclose(dist, [9.0, 12.0, 10.0, np.nan, np.nan, np.nan, np.nan, np.nan])
    np.testing.assert_allclose(bearing[:3], [355.0, 25.0, 90.0])
    # uint8 increment is used when increment_f is 0; angle_offset shifts every bin
    d2 = np.full(72, 65535, dtype=np.uint16)
    d2[1] = 700
    dist2, bearing2 = proximity_sectors(_od(d2, inc_f=0.0, inc=10, offset=80.0))
    assert bearing2[2] == pytest.approx(90.0) and dist2[2] == pytest.approx(7.0)
