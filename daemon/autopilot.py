"""The daemon's MAVLink 2 link to the autopilot (ArduPilot or PX4): ego pose in, obstacles out.

One reader thread owns the connection: it opens it (and reopens it after a failure), reads with short
``select`` timeouts, keeps the time sync and the message-rate requests going, and sends the 1 Hz HEARTBEAT.
Any thread may call the ``send_*`` methods; one lock serialises every use of the pymavlink writer (its
sequence number and signing timestamp are not thread-safe).

Failure policy: the daemon must keep tracking while the autopilot is absent, rebooting, or unplugged. So no
link problem raises into a caller: sends return False and are counted, state changes are logged once, and
the reader keeps retrying the connection every ``reconnect_interval`` seconds. Connections are opened in a
short-lived helper thread because a TCP connect or a serial open can block far longer than ``stop()`` may.

What is accepted (see specs/mavlink-obstacles.md §3-4): ATTITUDE, LOCAL_POSITION_NED, GLOBAL_POSITION_INT,
SYSTEM_TIME, TIMESYNC, HEARTBEAT, COMMAND_ACK from the autopilot (``target_system`` and the component of its
heartbeat). OBSTACLE_DISTANCE from anyone is counted and ignored (PX4 streams its own fused map back).
"""

from __future__ import annotations

import logging
import math
import threading
import time
from collections import deque
from collections.abc import Callable
from typing import Any, ClassVar

import numpy as np

from daemon.ais import AisVessel
from daemon.autopilot_port import MavlinkPort
from daemon.autopilot_pose import PoseAssembler
from daemon.autopilot_rates import IntervalRequester
from daemon.mavlink_env import mavlink
from daemon.pose_history import PoseHistory
from daemon.timesync import NS_PER_S, TimeSync

log = logging.getLogger(__name__)

N_BINS = 72
BIN_WIDTH_DEG = 5.0
STATUSTEXT_CHUNK = 50
STATUSTEXT_MAX_CHUNKS = 6  # a runaway message must not flood a telemetry radio
SANE_UNIX_TIME_S = 1577836800.0  # 2020-01-01: a host clock before this was never set (no RTC, no NTP yet)
# 2100-01-01: a time past this is a corrupt field (a SYSTEM_TIME of all ones), which no uint64 time_usec can carry
# forward without overflowing
LATEST_UNIX_TIME_S = 4102444800.0
MAV_STATE_MAX = 8  # MAV_STATE_FLIGHT_TERMINATION
# This many autopilot clock resets within the window are two clocks on the link, not reboots (_clock_conflict).
CLOCK_CONFLICT_RESETS = 3  # an autopilot's reboot takes longer than the window, and is one reset
CLOCK_CONFLICT_WINDOW_S = 10.0

DEFAULT_RATES_HZ: dict[int, float] = {
    mavlink.MAVLINK_MSG_ID_ATTITUDE: 50.0,
    mavlink.MAVLINK_MSG_ID_LOCAL_POSITION_NED: 20.0,  # before GLOBAL: it is the preferred world frame
    mavlink.MAVLINK_MSG_ID_GLOBAL_POSITION_INT: 20.0,
    mavlink.MAVLINK_MSG_ID_SYSTEM_TIME: 1.0,
}

# Heartbeats of these types come from other members of the vehicle's system (GCS, companions, gimbals).
_NOT_AUTOPILOT_TYPES = frozenset(
    {
        mavlink.MAV_TYPE_GCS,
        mavlink.MAV_TYPE_ONBOARD_CONTROLLER,
        mavlink.MAV_TYPE_GIMBAL,
        mavlink.MAV_TYPE_ADSB,
        mavlink.MAV_TYPE_CAMERA,
    }
)


def host_clock_sane(wall_s: float) -> bool:
    return SANE_UNIX_TIME_S < wall_s < LATEST_UNIX_TIME_S


class AutopilotLink:
    """MAVLink 2 link to one autopilot; see the module docstring. ``start()`` / ``stop()``; thread-safe sends."""

    def __init__(
        self,
        url: str,
        system_id: int = 1,
        component_id: int = 196,
        target_system: int = 1,
        baud: int = 921600,
        signing_key: bytes | None = None,
        clock: Callable[[], float] = time.monotonic,
        *,
        pose_history: PoseHistory | None = None,
        message_rates_hz: dict[int, float] | None = None,
        heartbeat_timeout: float = 3.0,
        reconnect_interval: float = 1.0,
        timesync: TimeSync | None = None,
        wall_clock: Callable[[], float] = time.time,
        system_status: int = mavlink.MAV_STATE_STANDBY,
        global_position_grace: float = 2.0,
    ) -> None:
        self.url = url
        for name, v in (("system_id", system_id), ("component_id", component_id), ("target_system", target_system)):
            if not 1 <= v <= 255:
                raise ValueError(f"{name} must be 1..255, got {v}")
        if signing_key is not None and len(signing_key) != 32:
            raise ValueError(f"MAVLink signing key must be 32 bytes, got {len(signing_key)}")
        self.system_id = system_id
        self.component_id = component_id
        self.target_system = target_system
        self.signing_key = signing_key
        self.clock = clock
        self.wall_clock = wall_clock
        self.heartbeat_timeout = heartbeat_timeout
        self.reconnect_interval = reconnect_interval
        self.poses = pose_history if pose_history is not None else PoseHistory()
        self.timesync = timesync if timesync is not None else TimeSync()
        self.rates = IntervalRequester(message_rates_hz if message_rates_hz is not None else DEFAULT_RATES_HZ)
        self._assembler = PoseAssembler(self.poses, global_grace=global_position_grace)
        self._system_status = self._check_status(system_status)

        self._counts_lock = threading.Lock()
        self._counters: dict[str, int] = {}
        self.port = MavlinkPort(url, baud, system_id, component_id, signing_key, reconnect_interval, clock, self._count)
        self._stop = threading.Event()
        self._reader: threading.Thread | None = None

        self.autopilot_component = mavlink.MAV_COMP_ID_AUTOPILOT1
        self.autopilot_type: int | None = None
        self.autopilot_kind: int | None = None  # MAV_AUTOPILOT of its heartbeat
        self._ap_component_locked = False
        self._last_ap_heartbeat: float | None = None
        self._was_connected = False
        self._next_heartbeat = 0.0
        self._next_timesync = 0.0
        self._unix_anchor: tuple[int, float] | None = None  # (autopilot unix us, host monotonic s)
        self._timesync_resets_seen = self.timesync.resets
        self._clock_resets: deque[float] = deque(maxlen=CLOCK_CONFLICT_RESETS)
        self._conflicted_until = -math.inf  # poses ignored until then: two clocks answer as the autopilot
        self._conflict_logged = -math.inf
        self._scan_id_3d = 0
        self.raw_sink: Callable[[Any], None] | None = None  # every message received (the recorder's .tlog)
        self._statustext_id = 0

    # ------------------------------------------------------------------ life cycle
    def start(self) -> None:
        if self._reader is not None:
            raise RuntimeError("AutopilotLink already started")
        if self.signing_key is not None and not host_clock_sane(self.wall_clock()):
            log.warning(
                "MAVLink signing with an unset host clock: the autopilot rejects our first packets as replays "
                "until its own signed packets have moved our signing timestamp forward"
            )
        self._stop.clear()
        self._reader = threading.Thread(target=self._run, name="autopilot-link", daemon=True)
        self._reader.start()

    def stop(self, timeout: float = 1.0) -> None:
        """Stop the reader and close the port; returns within ``timeout`` seconds."""
        self._stop.set()
        if self._reader is not None:
            self._reader.join(timeout)
            if self._reader.is_alive():
                log.error("autopilot reader thread did not stop within %.1f s", timeout)
            self._reader = None
        self.port.close()

    def __enter__(self) -> AutopilotLink:
        self.start()
        return self

    def __exit__(self, *exc: object) -> None:
        self.stop()

    # ------------------------------------------------------------------ state for the daemon
    @property
    def connected(self) -> bool:
        """True while the autopilot's heartbeat is younger than ``heartbeat_timeout``."""
        last = self._last_ap_heartbeat
        return last is not None and self.clock() - last < self.heartbeat_timeout

    @property
    def link_open(self) -> bool:
        return self.port.is_open

    @property
    def pose_age(self) -> float | None:
        """Seconds since the newest pose sample's instant (host clock); None before the first one."""
        newest = self.poses.newest_time
        return None if newest is None else max(0.0, self.clock() - newest)

    @property
    def position_source(self) -> str | None:
        """'local_ned', 'global' (tangent plane at first fix) or None (no position yet)."""
        return self._assembler.position_source

    @property
    def world_epoch(self) -> int:
        """Counts world-frame changes (source switch, reboot on LOCAL_POSITION_NED); world state must reset."""
        return self._assembler.world_epoch

    @property
    def system_status(self) -> int:
        return self._system_status

    @property
    def counters(self) -> dict[str, int]:
        """Event counts: rx_*, tx_*, link_*, rate_*, timesync_*, pose_*, autopilot_*, obstacle_distance_ignored."""
        with self._counts_lock:
            out = dict(self._counters)
        a = self._assembler
        out.update(
            pose_samples=a.samples,
            pose_skipped_no_position=a.skipped_no_position,
            pose_rejected=a.rejected,
            global_ignored_local_active=a.global_ignored,
            pose_local_rejected=a.local_rejected,
            pose_velocity_held=a.velocity_held,
        )
        return out

    @property
    def rate_status(self) -> dict[str, str]:
        """Per requested message name: accepted / pending / no-ack / refused:<MAV_RESULT>."""
        return {mavlink.mavlink_map[m].msgname: s for m, s in dict(self.rates.status).items()}

    def status(self) -> dict[str, Any]:
        """One snapshot for the daemon's health line."""
        age = self.pose_age
        return {
            "link_open": self.link_open,
            "connected": self.connected,
            "pose_age_s": None if age is None else round(age, 3),
            "position_source": self.position_source,
            "world_epoch": self.world_epoch,
            "timesync_synced": self.timesync.synced,
            "timesync_offset_s": None if self.timesync.offset_ns is None else self.timesync.offset_ns / NS_PER_S,
            "rates": self.rate_status,
            "counters": self.counters,
        }

    def world_to_geodetic(self, ned: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray] | None:
        """World NED -> (lat deg, lon deg, alt m) for AIS_VESSEL and logs; None while the anchor is unknown."""
        return self._assembler.world_to_geodetic(ned)

    def unix_time_usec(self) -> int:
        """Unix time in µs for ``time_usec`` fields: the autopilot's GPS time (SYSTEM_TIME) carried forward on the
        host monotonic clock, else the host clock if it is sane, else 0 ("unknown"). GPS time first: a Pi without
        an RTC or network boots on the clock it saved at shutdown (fake-hwclock), plausible and hours wrong."""
        anchor = self._unix_anchor
        if anchor is not None:
            return int(anchor[0] + (self.clock() - anchor[1]) * 1e6)
        wall = self.wall_clock()
        return int(wall * 1e6) if host_clock_sane(wall) else 0

    # ------------------------------------------------------------------ sending
    def set_system_status(self, status: int) -> None:
        """MAV_STATE for our HEARTBEAT (ACTIVE when tracking, CRITICAL/EMERGENCY when degraded); sent at once."""
        status = self._check_status(status)
        if status != self._system_status:
            self._system_status = status
            self._send_heartbeat()

    @staticmethod
    def _check_status(status: int) -> int:
        status = int(status)
        if not 0 <= status <= MAV_STATE_MAX:
            raise ValueError(f"system_status must be a MAV_STATE (0..{MAV_STATE_MAX}), got {status}")
        return status

    def send_obstacle_distance(
        self,
        distances_cm: np.ndarray,
        min_cm: int,
        max_cm: int,
        sensor_type: int = mavlink.MAV_DISTANCE_SENSOR_LASER,
        time_usec: int | None = None,
    ) -> bool:
        """OBSTACLE_DISTANCE: 72 bins of 5° clockwise from the bow, MAV_FRAME_BODY_FRD, increment_f 5.0.

        ``distances_cm``: (72,) integers (or finite floats, rounded) in 0..65535, semantics as in the spec
        (max_cm + 1 = clear, 65535 = unknown). ``time_usec`` None = ``unix_time_usec()``. Bad arguments raise
        ValueError; a dead link returns False.
        """
        d = np.asarray(distances_cm)
        if d.shape != (N_BINS,):
            raise ValueError(f"distances_cm must have shape ({N_BINS},), got {d.shape}")
        if not np.issubdtype(d.dtype, np.integer):
            if not np.issubdtype(d.dtype, np.floating) or not np.isfinite(d).all():
                raise ValueError("distances_cm must be integers or finite floats")
            d = np.rint(d)
        if d.min() < 0 or d.max() > 65535:
            raise ValueError(f"distances_cm out of 0..65535 (min {d.min()}, max {d.max()})")
        min_cm, max_cm = int(min_cm), int(max_cm)
        if not 0 <= min_cm <= max_cm <= 65534:
            raise ValueError(f"need 0 <= min_cm <= max_cm <= 65534, got {min_cm}, {max_cm}")
        if time_usec is None:
            time_usec = self.unix_time_usec()
        bins = [int(v) for v in d]
        return self._send(
            "obstacle_distance",
            lambda mav: mav.obstacle_distance_send(
                int(time_usec),
                int(sensor_type),
                bins,
                0,  # increment (uint8) unused: increment_f wins when non-zero
                min_cm,
                max_cm,
                BIN_WIDTH_DEG,
                0.0,
                mavlink.MAV_FRAME_BODY_FRD,  # pymavlink's default would be 0 = GLOBAL (north-aligned on PX4)
            ),
        )

    def send_obstacle_distance_3d(
        self,
        points_frd: np.ndarray,
        min_m: float,
        max_m: float,
        sensor_type: int = mavlink.MAV_DISTANCE_SENSOR_LASER,
        obstacle_ids: np.ndarray | None = None,
    ) -> int:
        """OBSTACLE_DISTANCE_3D, one message per body-FRD point (m), all with one ``time_boot_ms`` so that
        ArduPilot groups them into one scan. Non-finite rows are skipped. Returns the number sent."""
        pts = np.asarray(points_frd, dtype=float).reshape(-1, 3)
        ids = np.full(pts.shape[0], 65535) if obstacle_ids is None else np.asarray(obstacle_ids).reshape(-1)
        if ids.shape[0] != pts.shape[0]:
            raise ValueError("obstacle_ids must have one id per point")
        if not (math.isfinite(min_m) and math.isfinite(max_m) and 0 <= min_m <= max_m):
            raise ValueError(f"need 0 <= min_m <= max_m, got {min_m}, {max_m}")
        finite = np.isfinite(pts).all(axis=1)
        if not finite.all():
            self._count("obstacle_3d_nonfinite_skipped", int((~finite).sum()))
        # AP only compares the stamp for equality; a fresh value per call starts a new scan
        self._scan_id_3d = (self._scan_id_3d + 1) & 0xFFFFFFFF
        scan = self._scan_id_3d
        sent = 0
        for (x, y, z), oid in zip(pts[finite], ids[finite], strict=True):
            ok = self._send(
                "obstacle_distance_3d",
                lambda mav, x=x, y=y, z=z, oid=oid: mav.obstacle_distance_3d_send(
                    scan,
                    int(sensor_type),
                    mavlink.MAV_FRAME_BODY_FRD,
                    int(oid) & 0xFFFF,
                    float(x),
                    float(y),
                    float(z),
                    float(min_m),
                    float(max_m),
                ),
            )
            sent += ok
        return sent

    def send_ais_vessel(self, v: AisVessel) -> bool:
        """AIS_VESSEL for the ground station's map (daemon.ais); False on a dead link."""
        return self._send(
            "ais_vessel",
            lambda mav: mav.ais_vessel_send(
                v.mmsi,
                v.lat_e7,
                v.lon_e7,
                v.cog_cdeg,
                v.heading_cdeg,
                v.velocity_cms,
                v.turn_rate,
                v.navigational_status,
                v.vessel_type,
                v.dimension_bow,
                v.dimension_stern,
                v.dimension_port,
                v.dimension_starboard,
                b"",
                v.name,
                v.tslc,
                v.flags,
            ),
        )

    def send_statustext(self, severity: int, text: str) -> int:
        """STATUSTEXT, split into 50-character chunks (MAVLink 2 id/chunk_seq). Returns chunks sent."""
        severity = int(severity)
        if not 0 <= severity <= 7:
            raise ValueError(f"severity must be a MAV_SEVERITY (0..7), got {severity}")
        raw = text.encode("ascii", errors="replace")
        chunks = [raw[i : i + STATUSTEXT_CHUNK] for i in range(0, len(raw), STATUSTEXT_CHUNK)] or [b""]
        if len(chunks) > 1 and len(chunks[-1]) == STATUSTEXT_CHUNK:
            chunks.append(b"")  # a full last chunk has no NUL: an empty one tells the reader the text ended
        if len(chunks) > STATUSTEXT_MAX_CHUNKS:
            log.warning("STATUSTEXT truncated to %d chunks: %r", STATUSTEXT_MAX_CHUNKS, text[:80])
            chunks = chunks[:STATUSTEXT_MAX_CHUNKS]
        msg_id = 0
        if len(chunks) > 1:
            self._statustext_id = self._statustext_id % 65535 + 1
            msg_id = self._statustext_id
        sent = 0
        for seq, chunk in enumerate(chunks):
            sent += self._send(
                "statustext",
                lambda mav, chunk=chunk, seq=seq: mav.statustext_send(severity, chunk, msg_id, seq),
            )
        return sent

    def _send_heartbeat(self) -> bool:
        status = self._system_status
        return self._send(
            "heartbeat",
            lambda mav: mav.heartbeat_send(
                mavlink.MAV_TYPE_ONBOARD_CONTROLLER, mavlink.MAV_AUTOPILOT_INVALID, 0, 0, status
            ),
        )

    def _send(self, what: str, fn: Callable[[Any], None]) -> bool:
        return self.port.send(what, fn)

    # ------------------------------------------------------------------ reader thread
    def _count(self, key: str, n: int = 1) -> None:
        with self._counts_lock:
            self._counters[key] = self._counters.get(key, 0) + n

    def _run(self) -> None:
        port = self.port
        while not self._stop.is_set():
            if not port.is_open:
                if port.service_open():
                    self._next_heartbeat = 0.0
                self._update_presence(self.clock())
                self._stop.wait(0.05)
                continue
            if port.read(self._handle_safely, 0.02):
                self._periodic(self.clock())
        port.close()

    def _update_presence(self, now: float) -> bool:
        connected = self._last_ap_heartbeat is not None and now - self._last_ap_heartbeat < self.heartbeat_timeout
        if connected != self._was_connected:
            self._was_connected = connected
            if connected:
                log.info(
                    "autopilot %d/%d present (type %s, autopilot %s)",
                    self.target_system,
                    self.autopilot_component,
                    self.autopilot_type,
                    self.autopilot_kind,
                )
            else:
                log.warning("autopilot %d heartbeat lost (> %.1f s)", self.target_system, self.heartbeat_timeout)
                self._count("autopilot_lost")
                self.rates.stop()
        return connected

    def _periodic(self, now: float) -> None:
        if now >= self._next_heartbeat:
            self._next_heartbeat = now + 1.0
            self._send_heartbeat()
        if not self._update_presence(now):
            return
        if now >= self._next_timesync:
            self._next_timesync = now + (1.0 if self.timesync.synced else 0.2)
            tc1, ts1 = self.timesync.make_request(int(now * NS_PER_S))
            if self._send("timesync", lambda mav: mav.timesync_send(tc1, ts1)):
                self._count("timesync_requests")
        request = self.rates.poll(now)
        if request is not None:
            msg_id, interval_us, confirmation = request
            target = (self.target_system, self.autopilot_component)
            self._count("rate_requests")
            self._send(
                "command_long",
                lambda mav: mav.command_long_send(
                    *target,
                    mavlink.MAV_CMD_SET_MESSAGE_INTERVAL,
                    confirmation,
                    float(msg_id),
                    float(interval_us),
                    0,
                    0,
                    0,
                    0,
                    0,  # param7 = 0: response to the requester
                ),
            )

    # ------------------------------------------------------------------ message handling
    def _handle_safely(self, msg: Any) -> None:
        """A message our handlers choke on is counted and dropped; it must not look like a dead link."""
        if self.raw_sink is not None and msg.get_type() != "BAD_DATA":
            self.raw_sink(msg)
        try:
            self._handle(msg, self.clock())
        except Exception as exc:
            self._count("rx_handler_errors")
            log.debug("autopilot link: could not use %s: %s", msg.get_type(), exc)

    def _handle(self, msg: Any, rx: float) -> None:
        mtype = msg.get_type()
        self._count("rx_messages")
        if mtype == "BAD_DATA":
            reason = str(getattr(msg, "reason", ""))
            self._count("rx_bad_signature" if "signature" in reason.lower() else "rx_bad_data")
            return
        if mtype == "OBSTACLE_DISTANCE":
            self._count("obstacle_distance_ignored")
            return
        src_sys, src_comp = msg.get_srcSystem(), msg.get_srcComponent()
        if src_sys != self.target_system:
            self._count("rx_other_system")
            return
        if mtype == "HEARTBEAT":
            self._on_heartbeat(msg, src_comp, rx)
            return
        if src_comp != self.autopilot_component:
            self._count("rx_other_component")
            return
        handler = self._handlers.get(mtype)
        if handler is not None:
            handler(self, msg, rx)

    def _on_heartbeat(self, msg: Any, src_comp: int, rx: float) -> None:
        if msg.autopilot == mavlink.MAV_AUTOPILOT_INVALID or msg.type in _NOT_AUTOPILOT_TYPES:
            return
        if self._ap_component_locked and src_comp != self.autopilot_component:
            self._count("rx_other_component")
            return
        self.autopilot_component = src_comp
        self._ap_component_locked = True
        self.autopilot_type = msg.type
        self.autopilot_kind = msg.autopilot
        self._count("autopilot_heartbeats")
        last = self._last_ap_heartbeat
        self._last_ap_heartbeat = rx
        if last is None or rx - last >= self.heartbeat_timeout:
            # first contact, or back after a gap: ArduPilot may have rebooted and forgotten our rates
            self.rates.restart()
            self._next_timesync = 0.0
            self._update_presence(rx)

    def _stamp(self, time_boot_ms: int, rx: float) -> float:
        """Host time of an autopilot-stamped message; watches for reboots on the way."""
        self.timesync.check_boot_time(time_boot_ms, int(rx * NS_PER_S))
        self._check_clock_reset()
        if self.timesync.quiet and rx >= self._conflicted_until:
            self.timesync.quiet = False
            log.warning("autopilot clock steady again: poses used from now on (a new world frame)")
        return self.timesync.to_host(time_boot_ms, rx)

    def _check_clock_reset(self) -> None:
        """The autopilot's clock restarted or jumped (seen in a time_boot_ms or a TIMESYNC reply): it has
        most likely rebooted, so it forgot our rates, and its EKF origin may have moved. Several times within
        CLOCK_CONFLICT_WINDOW_S it is no reboot but two clocks (_clock_conflict)."""
        if self.timesync.resets == self._timesync_resets_seen:
            return
        self._timesync_resets_seen = self.timesync.resets
        self._count("autopilot_clock_resets")
        if self._clock_conflict(self.clock()):
            return
        self._assembler.on_autopilot_reboot()
        self.rates.restart()
        self._next_timesync = 0.0
        self._unix_anchor = None

    def _clock_conflict(self, now: float) -> bool:
        """Two autopilots answering as one system and component (a second vehicle, a bench unit or SITL left on
        the network): their boot clocks alternate in the messages, each one a "reboot" that restarted the world
        frame and the tracks, 160 times a second in a test. A real reboot takes far longer than
        CLOCK_CONFLICT_WINDOW_S. While the clocks alternate, and CLOCK_CONFLICT_WINDOW_S after, poses are ignored:
        the daemon runs without an own pose (the boat's frame), as with no autopilot, and says why once a minute."""
        self._clock_resets.append(now)
        resets = self._clock_resets
        if len(resets) == resets.maxlen and now - resets[0] < CLOCK_CONFLICT_WINDOW_S:
            if now >= self._conflicted_until:
                self._assembler.forget_poses("two autopilot clocks on the link")
            self._conflicted_until = now + CLOCK_CONFLICT_WINDOW_S
            self.timesync.quiet = True
            if now - self._conflict_logged >= 60.0:
                self._conflict_logged = now
                log.error(
                    "autopilot clock went back %d times in %.1f s: two autopilots answer as system %d component %d "
                    "on this link (another vehicle, a bench unit, SITL?); their poses are ignored while it lasts",
                    len(resets),
                    now - resets[0],
                    self.target_system,
                    self.autopilot_component,
                )
            return True
        return now < self._conflicted_until

    def _poses_usable(self, rx: float) -> bool:
        """Not while two clocks alternate (_clock_conflict): neither's pose, nor its time of day."""
        if rx < self._conflicted_until:
            self._count("rx_pose_clock_conflict")
            return False
        return True

    def _on_attitude(self, msg: Any, rx: float) -> None:
        t = self._stamp(msg.time_boot_ms, rx)
        if not self._poses_usable(rx):
            return
        self._assembler.on_attitude(t, msg.roll, msg.pitch, msg.yaw, msg.rollspeed, msg.pitchspeed, msg.yawspeed)

    def _on_local_position(self, msg: Any, rx: float) -> None:
        t = self._stamp(msg.time_boot_ms, rx)
        if not self._poses_usable(rx):
            return
        self._assembler.on_local_position(t, np.array([msg.x, msg.y, msg.z]), np.array([msg.vx, msg.vy, msg.vz]))

    def _on_global_position(self, msg: Any, rx: float) -> None:
        t = self._stamp(msg.time_boot_ms, rx)
        if not self._poses_usable(rx):
            return
        vel = np.array([msg.vx, msg.vy, msg.vz], dtype=float) / 100.0
        self._assembler.on_global_position(t, msg.lat * 1e-7, msg.lon * 1e-7, msg.alt * 1e-3, vel)

    def _on_system_time(self, msg: Any, rx: float) -> None:
        self._stamp(msg.time_boot_ms, rx)
        if not self._poses_usable(rx):
            self._unix_anchor = None
            return
        if host_clock_sane(msg.time_unix_usec * 1e-6):
            t = self.timesync.to_host(msg.time_boot_ms, rx)
            self._unix_anchor = (int(msg.time_unix_usec), t)

    def _on_timesync(self, msg: Any, rx: float) -> None:
        rx_ns = int(rx * NS_PER_S)
        if msg.tc1 == 0:
            # the autopilot asks for OUR clock (PX4 does, at 10 Hz): answer, it costs nothing
            ts1 = msg.ts1
            if self._send("timesync", lambda mav: mav.timesync_send(rx_ns, ts1)):
                self._count("timesync_answered")
            return
        if self.timesync.on_reply(msg.tc1, msg.ts1, rx_ns):
            self._count("timesync_samples")
        self._check_clock_reset()

    def _on_command_ack(self, msg: Any, rx: float) -> None:
        if msg.command != mavlink.MAV_CMD_SET_MESSAGE_INTERVAL:
            return
        target_comp = getattr(msg, "target_component", 0)
        if target_comp not in (0, self.component_id):
            return
        msg_id = self.rates.on_ack(msg.result)
        if msg_id is not None:
            accepted = msg.result == mavlink.MAV_RESULT_ACCEPTED
            self._count("rate_acks_accepted" if accepted else "rate_acks_refused")

    _handlers: ClassVar[dict[str, Callable[[AutopilotLink, Any, float], None]]] = {
        "ATTITUDE": _on_attitude,
        "LOCAL_POSITION_NED": _on_local_position,
        "GLOBAL_POSITION_INT": _on_global_position,
        "SYSTEM_TIME": _on_system_time,
        "TIMESYNC": _on_timesync,
        "COMMAND_ACK": _on_command_ack,
    }
