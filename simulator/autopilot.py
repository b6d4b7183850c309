"""A pymavlink autopilot on loopback that plays an ArduPilot Rover (boat) for the tests and the demo.

No runnable ArduPilot/PX4 SITL ships on PyPI (specs/mavlink-obstacles.md §8), so this emulates the parts the
daemon depends on, as ArduPilot does them:
* HEARTBEAT 1 Hz as MAV_TYPE_SURFACE_BOAT / MAV_AUTOPILOT_ARDUPILOTMEGA;
* ATTITUDE, GLOBAL_POSITION_INT, LOCAL_POSITION_NED, SYSTEM_TIME streamed only at the intervals asked for
  with MAV_CMD_SET_MESSAGE_INTERVAL (answered with COMMAND_ACK), forgotten at ``reboot()``;
* TIMESYNC answered from its own boot clock, which is the host clock shifted by a known amount
  (``clock_offset_ns``) so tests can check that the link finds it;
* OBSTACLE_DISTANCE recorded with host arrival time and sender ids; proximity health Good while one arrived
  in the last 0.5 s, else NoData; the 8-sector boundary built with ArduPilot's bin rules (0, 65535, < min,
  > max dropped; each sector keeps its nearest bin);
* optional MAVLink 2 signing (unsigned or wrongly signed packets dropped, as ArduPilot does).

The trajectory is a callable ``trajectory(t) -> pose`` with t on the host clock (``clock``), returning any
object with ``position`` (NED m), ``velocity`` (NED m/s), ``roll``, ``pitch``, ``yaw`` (rad) and optionally
``yaw_rate`` (rad/s), e.g. drivers.frames.EgoPose. Each streamed message samples it at the exact host instant
that its integer ``time_boot_ms`` stands for, so a correct time alignment reproduces it without a 1 ms bias.

URL: any pymavlink string (``udpin:``, ``udpout:``, ``tcpin:``, ``tcp:``, serial path), or ``fd:N`` for an
already open file descriptor such as the master side of a pty (the link then opens the slave by path).
"""

from __future__ import annotations

import errno
import logging
import math
import os
import threading
import time
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import numpy as np

from daemon.autopilot_geo import LocalTangentPlane
from daemon.mavlink_env import mavlink, mavutil
from drivers.frames import euler_rates_to_body

log = logging.getLogger(__name__)

PROXIMITY_TIMEOUT_S = 0.5  # AP_Proximity: no message for 500 ms -> NoData
N_SECTORS = 8
SECTOR_WIDTH_DEG = 45.0

ATTITUDE = mavlink.MAVLINK_MSG_ID_ATTITUDE
GLOBAL_POSITION_INT = mavlink.MAVLINK_MSG_ID_GLOBAL_POSITION_INT
LOCAL_POSITION_NED = mavlink.MAVLINK_MSG_ID_LOCAL_POSITION_NED
SYSTEM_TIME = mavlink.MAVLINK_MSG_ID_SYSTEM_TIME
STREAMABLE = frozenset({ATTITUDE, GLOBAL_POSITION_INT, LOCAL_POSITION_NED, SYSTEM_TIME})


@dataclass(frozen=True)
class ReceivedObstacleDistance:
    host_time: float
    src_system: int
    src_component: int
    signed: bool
    time_usec: int
    sensor_type: int
    distances: np.ndarray  # (72,) uint16, cm
    increment: int
    min_distance: int
    max_distance: int
    increment_f: float
    angle_offset: float
    frame: int


@dataclass(frozen=True)
class ReceivedObstacle3D:
    host_time: float
    src_system: int
    src_component: int
    time_boot_ms: int
    sensor_type: int
    frame: int
    obstacle_id: int
    xyz: tuple[float, float, float]
    min_distance: float
    max_distance: float


@dataclass(frozen=True)
class ReceivedHeartbeat:
    host_time: float
    src_system: int
    src_component: int
    type: int
    autopilot: int
    base_mode: int
    custom_mode: int
    system_status: int
    mavlink_version: int
    signed: bool


@dataclass(frozen=True)
class ReceivedStatusText:
    host_time: float
    src_system: int
    src_component: int
    severity: int
    text: str
    id: int
    chunk_seq: int


@dataclass(frozen=True)
class ReceivedAisVessel:
    host_time: float
    src_system: int
    src_component: int
    mmsi: int
    lat_deg: float
    lon_deg: float
    cog_deg: float | None  # None: not valid
    heading_deg: float | None
    velocity_mps: float | None
    length_m: int | None  # bow + stern, None when the dimensions are not valid
    beam_m: int | None
    name: str
    flags: int


@dataclass(frozen=True)
class IntervalRequest:
    host_time: float
    src_system: int
    src_component: int
    msg_id: int
    interval_us: float
    result: int


def proximity_sectors(msg: ReceivedObstacleDistance) -> tuple[np.ndarray, np.ndarray]:
    """ArduPilot's reduction of one OBSTACLE_DISTANCE to its 8 sectors: (distance m, bearing deg) per sector,
    NaN where no valid bin fell. Frame is ignored (AP treats every array as body-relative)."""
    inc = msg.increment_f if msg.increment_f != 0.0 else float(msg.increment)
    dist_m = np.full(N_SECTORS, np.nan)
    bearing = np.full(N_SECTORS, np.nan)
    if inc == 0.0:
        return dist_m, bearing
    n = min(int(360.0 / abs(inc) + 0.5), msg.distances.shape[0])
    d = msg.distances[:n].astype(np.int64)
    angle = (np.arange(n) * inc + msg.angle_offset) % 360.0
    valid = (d != 0) & (d != 65535) & (d >= msg.min_distance) & (d <= msg.max_distance)
    if not valid.any():
        return dist_m, bearing
    d, angle = d[valid] * 0.01, angle[valid]
    sector = (((angle + SECTOR_WIDTH_DEG / 2) % 360.0) // SECTOR_WIDTH_DEG).astype(int) % N_SECTORS
    order = np.lexsort((d, sector))  # by sector, nearest first within each
    first = np.ones(order.shape[0], dtype=bool)
    first[1:] = sector[order][1:] != sector[order][:-1]
    pick = order[first]
    dist_m[sector[pick]] = d[pick]
    bearing[sector[pick]] = angle[pick]
    return dist_m, bearing


class _FdLink(mavutil.mavfile):
    """pymavlink port over a raw file descriptor (the master side of a pty)."""

    def __init__(self, fd: int, source_system: int, source_component: int) -> None:
        os.set_blocking(fd, False)
        super().__init__(fd, f"fd:{fd}", source_system=source_system, source_component=source_component, input=False)

    def recv(self, n: int | None = None) -> bytes:
        try:
            return os.read(self.fd, n if n else 1024)
        except BlockingIOError:
            return b""
        except OSError as exc:
            if exc.errno == errno.EIO:  # pty slave not open (yet / any more)
                return b""
            raise

    def write(self, buf: bytes) -> int:
        try:
            return os.write(self.fd, bytes(buf))
        except (BlockingIOError, OSError):
            return -1

    def close(self) -> None:
        os.close(self.fd)


class SimAutopilot:
    """ArduPilot-Rover-like MAVLink peer; ``start()`` / ``stop()``; records what the companion sends."""

    def __init__(
        self,
        url: str,
        trajectory: Callable[[float], Any],
        system_id: int = 1,
        component_id: int = 1,
        *,
        boot_uptime_s: float = 100.0,
        clock: Callable[[], float] = time.monotonic,
        wall_clock: Callable[[], float] = time.time,
        origin: tuple[float, float, float] = (59.4100, 10.4900, 0.0),
        local_position: bool = True,
        default_rates_hz: dict[int, float] | None = None,
        refuse_messages: frozenset[int] = frozenset(),
        signing_key: bytes | None = None,
        timesync_request_hz: float = 0.0,
        heartbeat_hz: float = 1.0,
        baud: int = 115200,
    ) -> None:
        self.url = url
        self.trajectory = trajectory
        self.system_id = system_id
        self.component_id = component_id
        self.clock = clock
        self.wall_clock = wall_clock
        self.plane = LocalTangentPlane(*origin)
        self.local_position = local_position
        self.default_rates_hz = dict(default_rates_hz or {})
        self.refuse_messages = frozenset(refuse_messages)
        self.signing_key = signing_key
        self.timesync_request_hz = timesync_request_hz
        self.heartbeat_period = 1.0 / heartbeat_hz
        self.baud = baud

        self._lock = threading.Lock()  # records and the pymavlink writer
        self._offset_ns = int(boot_uptime_s * 1e9) - self._now_ns()
        self._intervals: dict[int, float] = {}
        self._next_due: dict[int, float] = {}
        self._reset_intervals()
        self._paused = False
        self._stop = threading.Event()
        self._thread: threading.Thread | None = None
        self._conn: Any = None
        self._next_heartbeat = 0.0
        self._next_timesync_request = 0.0
        self.reboots = 0
        self.dropped_while_paused = 0
        self.bad_packets = 0

        self._obstacle_distances: list[ReceivedObstacleDistance] = []
        self._obstacles_3d: list[ReceivedObstacle3D] = []
        self._heartbeats: list[ReceivedHeartbeat] = []
        self._statustexts: list[ReceivedStatusText] = []
        self._ais_vessels: list[ReceivedAisVessel] = []
        self._interval_requests: list[IntervalRequest] = []
        self._timesync_requests = 0
        self._timesync_answers: list[tuple[float, int, int]] = []  # (host time, tc1, ts1) answers to OUR requests

    # ------------------------------------------------------------------ clocks
    def _now_ns(self) -> int:
        return int(self.clock() * 1e9)

    @property
    def clock_offset_ns(self) -> int:
        """Autopilot boot clock minus host clock, ns (what the link's TimeSync should find)."""
        return self._offset_ns

    def boot_ns(self, host_s: float | None = None) -> int:
        host_ns = self._now_ns() if host_s is None else int(host_s * 1e9)
        return host_ns + self._offset_ns

    def host_time_of_boot_ms(self, time_boot_ms: int) -> float:
        return (time_boot_ms * 1_000_000 - self._offset_ns) / 1e9

    # ------------------------------------------------------------------ life cycle and test controls
    def start(self) -> None:
        if self._thread is not None:
            raise RuntimeError("SimAutopilot already started")
        self._conn = self._open()
        self._stop.clear()
        self._thread = threading.Thread(target=self._run, name="sim-autopilot", daemon=True)
        self._thread.start()

    def stop(self) -> None:
        self._stop.set()
        if self._thread is not None:
            self._thread.join(2.0)
            self._thread = None
        with self._lock:
            conn, self._conn = self._conn, None
        if conn is not None:
            conn.close()

    def __enter__(self) -> SimAutopilot:
        self.start()
        return self

    def __exit__(self, *exc: object) -> None:
        self.stop()

    def reboot(self) -> None:
        """Boot clock restarts at 0 now; requested intervals are forgotten (as ArduPilot does)."""
        with self._lock:
            self._offset_ns = -self._now_ns()
            self._reset_intervals()
            self.reboots += 1

    def pause(self) -> None:
        """Go silent: send nothing and drop everything received (a cut cable)."""
        self._paused = True

    def resume(self) -> None:
        self._paused = False
        self._next_heartbeat = 0.0

    @property
    def message_intervals(self) -> dict[int, float]:
        """Current stream intervals in seconds, by message id."""
        with self._lock:
            return dict(self._intervals)

    def _reset_intervals(self) -> None:
        self._intervals = {m: 1.0 / hz for m, hz in self.default_rates_hz.items() if hz > 0}
        now = self.clock()
        self._next_due = dict.fromkeys(self._intervals, now)

    # ------------------------------------------------------------------ records
    def obstacle_distances(self) -> list[ReceivedObstacleDistance]:
        with self._lock:
            return list(self._obstacle_distances)

    def obstacles_3d(self) -> list[ReceivedObstacle3D]:
        with self._lock:
            return list(self._obstacles_3d)

    def heartbeats(self) -> list[ReceivedHeartbeat]:
        with self._lock:
            return list(self._heartbeats)

    def statustexts(self) -> list[ReceivedStatusText]:
        with self._lock:
            return list(self._statustexts)

    def ais_vessels(self) -> list[ReceivedAisVessel]:
        with self._lock:
            return list(self._ais_vessels)

    def interval_requests(self) -> list[IntervalRequest]:
        with self._lock:
            return list(self._interval_requests)

    def timesync_answers(self) -> list[tuple[float, int, int]]:
        with self._lock:
            return list(self._timesync_answers)

    @property
    def timesync_requests(self) -> int:
        return self._timesync_requests

    def proximity_health(self, now: float | None = None) -> str:
        """'Good' when an OBSTACLE_DISTANCE or OBSTACLE_DISTANCE_3D arrived within 0.5 s of ``now``, else 'NoData'."""
        now = self.clock() if now is None else now
        with self._lock:
            times = [r.host_time for r in self._obstacle_distances[-1:]] + [
                r.host_time for r in self._obstacles_3d[-1:]
            ]
        return "Good" if times and now - max(times) <= PROXIMITY_TIMEOUT_S else "NoData"

    def proximity_sectors(self) -> tuple[np.ndarray, np.ndarray]:
        """The 8-sector boundary of the newest OBSTACLE_DISTANCE (recent AP rebuilds it per message)."""
        with self._lock:
            last = self._obstacle_distances[-1] if self._obstacle_distances else None
        if last is None:
            return np.full(N_SECTORS, np.nan), np.full(N_SECTORS, np.nan)
        return proximity_sectors(last)

    # ------------------------------------------------------------------ sending as the autopilot
    def send_obstacle_distance(self, distances_cm: np.ndarray, min_cm: int, max_cm: int) -> None:
        """OBSTACLE_DISTANCE from the autopilot itself, as PX4 streams its fused map back on onboard links."""
        bins = [int(v) for v in np.asarray(distances_cm).reshape(72)]
        self._send(
            lambda mav: mav.obstacle_distance_send(
                0, mavlink.MAV_DISTANCE_SENSOR_UNKNOWN, bins, 0, min_cm, max_cm, 5.0, 0.0, mavlink.MAV_FRAME_BODY_FRD
            )
        )

    def _send(self, fn: Callable[[Any], None]) -> None:
        with self._lock:
            if self._conn is None or self._paused:
                return
            try:
                fn(self._conn.mav)
            except OSError as exc:
                log.debug("sim autopilot send failed: %s", exc)

    # ------------------------------------------------------------------ thread
    def _open(self) -> Any:
        if self.url.startswith("fd:"):
            conn: Any = _FdLink(int(self.url[3:]), self.system_id, self.component_id)
        else:
            conn = mavutil.mavlink_connection(
                self.url, baud=self.baud, source_system=self.system_id, source_component=self.component_id
            )
        if self.signing_key is not None:
            conn.setup_signing(self.signing_key, sign_outgoing=True)
        return conn

    def _run(self) -> None:
        while not self._stop.is_set():
            conn = self._conn
            now = self.clock()
            wait = 0.02
            if self._next_due:
                wait = max(0.0, min(wait, min(self._next_due.values()) - now))
            try:
                conn.select(wait)
                for _ in range(1000):
                    msg = conn.recv_msg()
                    if msg is None:
                        break
                    self._handle(msg)
            except Exception as exc:  # the peer went away; keep the sim alive for the test to inspect
                log.debug("sim autopilot read: %s", exc)
                self._stop.wait(0.05)
            if not self._paused:
                self._emit(self.clock())

    def _emit(self, now: float) -> None:
        if now >= self._next_heartbeat:
            self._next_heartbeat = now + self.heartbeat_period
            self._send(
                lambda mav: mav.heartbeat_send(
                    mavlink.MAV_TYPE_SURFACE_BOAT,
                    mavlink.MAV_AUTOPILOT_ARDUPILOTMEGA,
                    mavlink.MAV_MODE_FLAG_CUSTOM_MODE_ENABLED,
                    0,
                    mavlink.MAV_STATE_ACTIVE,
                )
            )
        if self.timesync_request_hz > 0 and now >= self._next_timesync_request:
            self._next_timesync_request = now + 1.0 / self.timesync_request_hz
            ts1 = self.boot_ns(now)
            self._send(lambda mav: mav.timesync_send(0, ts1))
        with self._lock:
            due = [m for m, t in self._next_due.items() if now >= t]
            for m in due:
                interval = self._intervals[m]
                nxt = self._next_due[m] + interval
                self._next_due[m] = nxt if nxt > now else now + interval
        for m in due:
            self._stream(m)

    def _stream(self, msg_id: int) -> None:
        ms = self.boot_ns() // 1_000_000
        t = self.host_time_of_boot_ms(ms)
        if msg_id == SYSTEM_TIME:
            self._send(lambda mav: mav.system_time_send(int(self.wall_clock() * 1e6), ms))
            return
        pose = self.trajectory(t)
        pos = np.asarray(pose.position, dtype=float)
        vel = np.asarray(pose.velocity, dtype=float)
        if msg_id == ATTITUDE:
            roll, pitch, yaw = float(pose.roll), float(pose.pitch), float(pose.yaw)
            p, q, r = euler_rates_to_body(
                roll,
                pitch,
                float(getattr(pose, "roll_rate", 0.0)),
                float(getattr(pose, "pitch_rate", 0.0)),
                float(getattr(pose, "yaw_rate", 0.0)),
            )
            self._send(lambda mav: mav.attitude_send(ms, roll, pitch, yaw, p, q, r))
        elif msg_id == LOCAL_POSITION_NED:
            self._send(lambda mav: mav.local_position_ned_send(ms, *(float(v) for v in pos), *(float(v) for v in vel)))
        elif msg_id == GLOBAL_POSITION_INT:
            lat, lon, alt = self.plane.to_geodetic(pos)
            vcm = [round(float(v) * 100.0) for v in vel]
            hdg = round(math.degrees(float(pose.yaw)) % 360.0 * 100.0) % 36000
            self._send(
                lambda mav: mav.global_position_int_send(
                    ms,
                    round(float(lat) * 1e7),
                    round(float(lon) * 1e7),
                    round(float(alt) * 1000.0),
                    round(-float(pos[2]) * 1000.0),
                    *vcm,
                    hdg,
                )
            )

    # ------------------------------------------------------------------ receiving
    def _handle(self, msg: Any) -> None:
        if self._paused:
            self.dropped_while_paused += 1
            return
        now = self.clock()
        mtype = msg.get_type()
        src = (msg.get_srcSystem(), msg.get_srcComponent())
        if mtype == "BAD_DATA":
            self.bad_packets += 1
        elif mtype == "OBSTACLE_DISTANCE":
            rec = ReceivedObstacleDistance(
                now,
                *src,
                bool(msg.get_signed()),
                int(msg.time_usec),
                int(msg.sensor_type),
                np.array(msg.distances, dtype=np.uint16),
                int(msg.increment),
                int(msg.min_distance),
                int(msg.max_distance),
                float(msg.increment_f),
                float(msg.angle_offset),
                int(msg.frame),
            )
            with self._lock:
                self._obstacle_distances.append(rec)
        elif mtype == "OBSTACLE_DISTANCE_3D":
            rec3 = ReceivedObstacle3D(
                now,
                *src,
                int(msg.time_boot_ms),
                int(msg.sensor_type),
                int(msg.frame),
                int(msg.obstacle_id),
                (float(msg.x), float(msg.y), float(msg.z)),
                float(msg.min_distance),
                float(msg.max_distance),
            )
            with self._lock:
                self._obstacles_3d.append(rec3)
        elif mtype == "HEARTBEAT":
            hb = ReceivedHeartbeat(
                now,
                *src,
                msg.type,
                msg.autopilot,
                msg.base_mode,
                msg.custom_mode,
                msg.system_status,
                msg.mavlink_version,
                bool(msg.get_signed()),
            )
            with self._lock:
                self._heartbeats.append(hb)
        elif mtype == "STATUSTEXT":
            st = ReceivedStatusText(now, *src, msg.severity, msg.text, msg.id, msg.chunk_seq)
            with self._lock:
                self._statustexts.append(st)
        elif mtype == "AIS_VESSEL":
            self._on_ais_vessel(msg, src, now)
        elif mtype == "TIMESYNC":
            self._on_timesync(msg, now)
        elif mtype == "COMMAND_LONG":
            self._on_command_long(msg, src, now)

    def _on_ais_vessel(self, msg: Any, src: tuple[int, int], now: float) -> None:
        flags = int(msg.flags)

        def valid(flag: int, value: float) -> float | None:
            return value if flags & flag else None

        dims = flags & mavlink.AIS_FLAGS_VALID_DIMENSIONS
        rec = ReceivedAisVessel(
            now,
            *src,
            int(msg.MMSI),
            msg.lat * 1e-7,
            msg.lon * 1e-7,
            valid(mavlink.AIS_FLAGS_VALID_COG, msg.COG / 100.0),
            None if msg.heading == 65535 else msg.heading / 100.0,
            valid(mavlink.AIS_FLAGS_VALID_VELOCITY, msg.velocity / 100.0),
            int(msg.dimension_bow + msg.dimension_stern) if dims else None,
            int(msg.dimension_port + msg.dimension_starboard) if dims else None,
            str(msg.name),  # pymavlink decodes char arrays to str, NULs stripped
            flags,
        )
        with self._lock:
            self._ais_vessels.append(rec)

    def _on_timesync(self, msg: Any, now: float) -> None:
        if msg.tc1 == 0:
            self._timesync_requests += 1
            tc1, ts1 = self.boot_ns(now), msg.ts1  # ArduPilot stamps with the packet's receive time
            self._send(lambda mav: mav.timesync_send(tc1, ts1))
        else:
            with self._lock:
                self._timesync_answers.append((now, int(msg.tc1), int(msg.ts1)))

    def _on_command_long(self, msg: Any, src: tuple[int, int], now: float) -> None:
        if msg.target_system not in (0, self.system_id) or msg.target_component not in (0, self.component_id):
            return
        if msg.command != mavlink.MAV_CMD_SET_MESSAGE_INTERVAL:
            result = mavlink.MAV_RESULT_UNSUPPORTED
        else:
            msg_id, interval_us = int(msg.param1), float(msg.param2)
            if msg_id in self.refuse_messages:
                result = mavlink.MAV_RESULT_DENIED
            elif msg_id not in STREAMABLE or (msg_id == LOCAL_POSITION_NED and not self.local_position):
                result = mavlink.MAV_RESULT_FAILED
            else:
                result = mavlink.MAV_RESULT_ACCEPTED
                with self._lock:
                    if interval_us < 0:
                        self._intervals.pop(msg_id, None)
                        self._next_due.pop(msg_id, None)
                    else:
                        hz = self.default_rates_hz.get(msg_id, 4.0) if interval_us == 0 else 1e6 / interval_us
                        self._intervals[msg_id] = 1.0 / hz
                        self._next_due[msg_id] = now
            with self._lock:
                self._interval_requests.append(IntervalRequest(now, *src, msg_id, interval_us, result))
        self._send(lambda mav: mav.command_ack_send(msg.command, result, 0, 0, src[0], src[1]))


def wait_until(predicate: Callable[[], bool], timeout: float = 5.0, poll: float = 0.01) -> bool:
    """Poll ``predicate`` until it holds or ``timeout`` passes (for tests and the demo)."""
    deadline = time.monotonic() + timeout
    while True:
        if predicate():
            return True
        if time.monotonic() >= deadline:
            return False
        time.sleep(poll)
