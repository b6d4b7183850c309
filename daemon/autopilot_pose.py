"""Ego pose from the autopilot's separate attitude and position messages.

ATTITUDE (50 Hz) and the position messages (20 Hz) arrive at different instants. One EgoPose is made per
ATTITUDE, with the latest position carried to the attitude's instant by its own velocity, turned by the attitude's
yaw rate over that time (dead reckoning over <= 50 ms). Positions
older than ``position_timeout`` make no pose: a pose with a stale position would place targets wrongly.

World frame (local NED, see design.md):
* LOCAL_POSITION_NED when the autopilot sends it (origin = its EKF origin). Once seen it is the only
  position source, because GLOBAL_POSITION_INT projected around our own first fix is a different plane.
* else GLOBAL_POSITION_INT projected to a NED tangent plane at the first fix used (``autopilot_geo``). Fixes
  only become the world after ``global_grace`` seconds without any LOCAL_POSITION_NED, because at start-up the
  two streams begin in no particular order and an early switch would change the world at once.
A switch of source, or an autopilot reboot while on LOCAL_POSITION_NED (new EKF origin), changes the world
frame: ``world_epoch`` counts up and the history is cleared, so consumers know to drop world-frame state. So does
an estimator reset: a position that lands more than ``POSITION_RESET_M`` from where the last one's velocity carried
it (ArduPilot's EKF resetting to GPS after a glitch, a GPS fix jumping), or a heading more than ``YAW_RESET_RAD``
from where the yaw rate turned it (a yaw reset). Tracks kept in the old frame would sit metres or degrees off the
returns placed in the new one, and coasting tracks would be sent at the wrong bearings.

All times are host monotonic seconds, already mapped from the autopilot clock by the caller.
"""

from __future__ import annotations

import logging
import math
import threading

import numpy as np

from daemon.autopilot_geo import LocalTangentPlane
from daemon.pose_history import PoseHistory
from drivers.frames import EgoPose, body_rates_to_euler

log = logging.getLogger(__name__)

LOCAL = "local_ned"
GLOBAL = "global"
# A boat's own position is reckoned between messages to centimetres (<= 1 s apart, a boat accelerating < 1 m/s^2);
# a GPS fix's noise is under a metre. Beyond 2 m it is a reset, and the fusion gates (1-2 m) would not hold anyway.
POSITION_RESET_M = 2.0
# ATTITUDE comes at 50 Hz: a heading 10 deg off its rate's prediction is no turn a boat makes.
YAW_RESET_RAD = math.radians(10.0)
RESET_CHECK_MAX_GAP_S = 1.0  # beyond this the last message is no base for a prediction


def _turn_horizontal(velocity_ned: np.ndarray, angle: float) -> np.ndarray:
    """``velocity_ned`` (NED) with its north-east part turned by ``angle`` (rad, positive clockwise seen from above,
    as yaw is); the down part kept."""
    c, s = math.cos(angle), math.sin(angle)
    north, east, down = float(velocity_ned[0]), float(velocity_ned[1]), float(velocity_ned[2])
    return np.array([c * north - s * east, s * north + c * east, down])


class PoseAssembler:
    """Turns decoded ATTITUDE / LOCAL_POSITION_NED / GLOBAL_POSITION_INT into EgoPose samples."""

    def __init__(self, history: PoseHistory, position_timeout: float = 1.0, global_grace: float = 2.0) -> None:
        self.history = history
        self.position_timeout = position_timeout
        self.global_grace = global_grace
        self._first_fix_t: float | None = None
        self.position_source: str | None = None
        self.world_epoch = 0
        self.samples = 0
        self.skipped_no_position = 0
        self.rejected = 0  # non-finite attitude (autopilots send NaN before their estimator is up)
        self.global_ignored = 0
        self.local_rejected = 0  # LOCAL_POSITION_NED without a finite position, or velocity with none to hold
        self.velocity_held = 0  # LOCAL_POSITION_NED with a non-finite velocity: the last one was kept
        self._lock = threading.Lock()  # guards the geodetic anchor read by other threads
        self._pos: tuple[float, np.ndarray, np.ndarray] | None = None  # (t, position NED, velocity NED)
        self._plane: LocalTangentPlane | None = None  # projection of GLOBAL_POSITION_INT (first fix)
        self._last_fix: tuple[float, float, float, float] | None = None  # (t, lat, lon, alt) of the newest fix
        self._last_local: tuple[float, np.ndarray, np.ndarray] | None = None
        self._last_yaw: tuple[float, float, float] | None = None  # (t, yaw, Euler yaw rate) of the last attitude
        self.estimator_resets = 0

    # ------------------------------------------------------------------ inputs
    def on_attitude(
        self, t: float, roll: float, pitch: float, yaw: float, p: float, q: float, r: float
    ) -> EgoPose | None:
        """One pose at the attitude's instant ``t``; None without a recent position."""
        # ATTITUDE carries body rates; the history extrapolates Euler angles, so it needs their rates (a rolling
        # boat's roll held still for the 0.3 s the history may extrapolate tilts the water by metres at range)
        if not all(math.isfinite(v) for v in (roll, pitch, yaw, p, q, r)):
            # before any maths: cos(inf) raises, and one such message must not end a replay or a reader
            self.rejected += 1
            return None
        roll_rate, pitch_rate, yaw_rate = body_rates_to_euler(roll, pitch, p, q, r)
        self._check_yaw_reset(t, yaw, yaw_rate)
        if self._pos is None or abs(t - self._pos[0]) > self.position_timeout:
            self.skipped_no_position += 1
            return None
        t_pos, pos, vel = self._pos
        # A boat's velocity turns with its heading: the held 20 Hz velocity is up to 50 ms old, which on a turn at
        # 0.35 rad/s and 5 m/s is 0.09 m/s off across the track. Turned by the yaw rate over its age (the position
        # along the chord's midpoint heading), it is off by the turn's change in rate only.
        age = t - t_pos
        turned = _turn_horizontal(vel, yaw_rate * age) if math.isfinite(yaw_rate) else vel
        midway = _turn_horizontal(vel, 0.5 * yaw_rate * age) if math.isfinite(yaw_rate) else vel
        pose = EgoPose(
            t=t,
            position=pos + midway * age,
            velocity=turned,
            roll=roll,
            pitch=pitch,
            yaw=yaw,
            yaw_rate=yaw_rate,
            roll_rate=roll_rate,
            pitch_rate=pitch_rate,
        )
        if self.history.add(pose):
            self.samples += 1
            return pose
        self.rejected += 1
        return None

    def on_local_position(self, t: float, position: np.ndarray, velocity: np.ndarray) -> None:
        pos = np.asarray(position, dtype=float).reshape(3)
        vel = np.asarray(velocity, dtype=float).reshape(3)
        if not np.isfinite(pos).all():
            self.local_rejected += 1
            return
        if not np.isfinite(vel).all():
            # A position without its velocity (an estimator that has lost one axis): the position still places the
            # boat; the velocity is the last one while it is recent, since a guessed 0 would make every still
            # return move to the radar's Doppler.
            last = self._last_local
            if last is None or not 0.0 <= t - last[0] <= self.position_timeout:
                self.local_rejected += 1
                return
            vel = last[2]
            self.velocity_held += 1
        if self.position_source != LOCAL:
            if self.position_source is not None:
                self._new_world(f"position source {self.position_source} -> LOCAL_POSITION_NED")
            else:
                log.info("world frame: LOCAL_POSITION_NED (autopilot EKF origin)")
            self.position_source = LOCAL
        else:
            self._check_position_reset(t, pos, vel)
        self._pos = (t, pos, vel)
        with self._lock:
            self._last_local = (t, pos, vel)

    def on_global_position(self, t: float, lat_deg: float, lon_deg: float, alt_m: float, velocity: np.ndarray) -> None:
        if lat_deg == 0.0 and lon_deg == 0.0:  # what autopilots send without a fix
            return
        if not (-90.0 <= lat_deg <= 90.0 and -180.0 <= lon_deg <= 180.0 and math.isfinite(alt_m)):
            return
        with self._lock:
            self._last_fix = (t, lat_deg, lon_deg, alt_m)
        if self.position_source == LOCAL:
            self.global_ignored += 1
            return
        if self.position_source is None:
            if self._first_fix_t is None:
                self._first_fix_t = t
            if t - self._first_fix_t < self.global_grace:
                return  # LOCAL_POSITION_NED may still come
            with self._lock:
                self._plane = LocalTangentPlane(lat_deg, lon_deg, alt_m)
                self.position_source = GLOBAL
            log.info("world frame: NED tangent plane at first fix %.7f, %.7f, %.2f m", lat_deg, lon_deg, alt_m)
        plane = self._plane
        if plane is None:
            return
        vel = np.asarray(velocity, dtype=float).reshape(3)
        pos = plane.to_ned(lat_deg, lon_deg, alt_m)
        self._check_position_reset(t, pos, vel)
        self._pos = (t, pos, vel)

    def on_autopilot_reboot(self) -> None:
        """The autopilot restarted: its EKF origin may move, and pre-reboot positions are no base for reckoning."""
        self._pos = None
        self._first_fix_t = None
        if self.position_source == LOCAL:
            self.position_source = None
            self._new_world("autopilot rebooted (EKF origin may have moved)")
        with self._lock:
            self._last_local = None

    def forget_poses(self, why: str) -> None:
        """The poses cannot be trusted (two autopilots' clocks interleaved): a new world frame with no pose in it,
        so the pipeline runs in the boat's frame until poses it can trust come again."""
        self._pos = None
        self._first_fix_t = None
        with self._lock:
            self._last_local = None
            self._plane = None
        self.position_source = None
        self._new_world(why)

    def _check_position_reset(self, t: float, pos: np.ndarray, vel: np.ndarray) -> None:
        if self._pos is None:
            return
        t_prev, pos_prev, vel_prev = self._pos
        dt = t - t_prev
        if not 0.0 < dt <= RESET_CHECK_MAX_GAP_S:
            return
        jump = float(np.linalg.norm(pos - (pos_prev + 0.5 * (vel_prev + vel) * dt)))  # exact for steady acceleration
        if jump > POSITION_RESET_M:
            self.estimator_resets += 1
            self._new_world(f"autopilot position jumped {jump:.1f} m in {dt:.2f} s (estimator reset or GPS glitch)")

    def _check_yaw_reset(self, t: float, yaw: float, yaw_rate: float) -> None:
        if not (math.isfinite(yaw) and math.isfinite(yaw_rate)):
            return
        last, self._last_yaw = self._last_yaw, (t, yaw, yaw_rate)
        if last is None or not 0.0 < t - last[0] <= RESET_CHECK_MAX_GAP_S:
            return
        predicted = last[1] + 0.5 * (last[2] + yaw_rate) * (t - last[0])
        off = math.remainder(yaw - predicted, math.tau)
        if abs(off) > YAW_RESET_RAD:
            self.estimator_resets += 1
            self._new_world(f"autopilot heading jumped {math.degrees(off):+.0f} deg (estimator yaw reset)")

    def _new_world(self, why: str) -> None:
        self.world_epoch += 1
        self.history.clear()
        log.warning("world frame changed (epoch %d): %s", self.world_epoch, why)

    # ------------------------------------------------------------------ output helpers
    def world_to_geodetic(self, ned: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray] | None:
        """World NED points -> (lat deg, lon deg, alt m MSL), or None while the world's anchor is unknown.

        On the tangent plane the anchor is the first fix. On LOCAL_POSITION_NED it is the newest fix minus
        the boat's local position at the same instant (the EKF origin as seen through the two messages).
        """
        with self._lock:
            fix, local, plane, source = self._last_fix, self._last_local, self._plane, self.position_source
        ned = np.asarray(ned, dtype=float)
        if source == GLOBAL and plane is not None:
            return plane.to_geodetic(ned)
        if source == LOCAL and fix is not None and local is not None and abs(fix[0] - local[0]) < 1.0:
            t_fix, lat, lon, alt = fix
            t_loc, pos, vel = local
            boat_at_fix = pos + vel * (t_fix - t_loc)
            return LocalTangentPlane(lat, lon, alt).to_geodetic(ned - boat_at_fix)
        return None
