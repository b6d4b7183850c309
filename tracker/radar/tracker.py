"""ROTracker (paper 001): radar detector + Kalman tracker with Doppler fusion and the motion discriminator.

Per frame: detect (sec. 2.2), predict every track to the frame time, associate by box IoU with a centre-distance
fallback for sparse clusters whose boxes miss each other (sec. 2.3-1), update with the fused measurement (eq. 7),
feed the point group to the motion discriminator (eq. 8, Table 1), and let the shared lifecycle confirm, coast and
delete. Pure computation: time comes in with the data.
"""

from __future__ import annotations

import logging
import math
from dataclasses import dataclass

import numpy as np
from filterpy.kalman import KalmanFilter

from drivers.frames import EgoPose, RadarFrame
from tracker.assignment import gated_assignment
from tracker.lifecycle import IdSource, Lifecycle, TrackLife
from tracker.radar import kalman
from tracker.radar.config import RadarTrackerConfig
from tracker.radar.detector import DetectorOutput, RadarCluster, RadarDetector
from tracker.radar.motion import MotionDiscriminator
from tracker.radar.static_map import StaticMap
from tracker.radar.velocity_profile import VelocityStatus
from tracker.types import Detection, MotionState, ShapeKind, Track

log = logging.getLogger(__name__)

_GATE = 2.0  # costs: 1 - IoU in [0, 1) for overlapping boxes, 1 + distance / gate in [1, 2] for the fallback


def box_iou_matrix(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """(n, m) IoU of axis-aligned boxes given as (k, 4) [min0, min1, max0, max1]."""
    lo = np.maximum(a[:, None, :2], b[None, :, :2])
    hi = np.minimum(a[:, None, 2:], b[None, :, 2:])
    inter = np.prod(np.clip(hi - lo, 0.0, None), axis=2)
    area_a = np.prod(a[:, 2:] - a[:, :2], axis=1)
    area_b = np.prod(b[:, 2:] - b[:, :2], axis=1)
    union = area_a[:, None] + area_b[None, :] - inter
    return np.where(union > 0, inter / np.where(union > 0, union, 1.0), 0.0)


def association_cost(track_boxes: np.ndarray, det_boxes: np.ndarray, cfg: RadarTrackerConfig) -> np.ndarray:
    """(tracks, detections) cost; inf where neither the boxes overlap nor the centres are within the gate."""
    iou = box_iou_matrix(track_boxes, det_boxes)
    ct = (track_boxes[:, :2] + track_boxes[:, 2:]) / 2
    cd = (det_boxes[:, :2] + det_boxes[:, 2:]) / 2
    dist = np.linalg.norm(ct[:, None, :] - cd[None, :, :], axis=2)
    gate = cfg.association_distance_gate_m
    return np.where(iou >= cfg.association_min_iou, 1.0 - iou, np.where(dist <= gate, 1.0 + dist / gate, np.inf))


@dataclass
class RadarTrackState:
    life: TrackLife
    kf: KalmanFilter
    motion: MotionDiscriminator
    t: float  # time of the filter's state
    points: np.ndarray  # last associated point group, world N/E

    def to_track(self, cfg: RadarTrackerConfig) -> Track:
        x = self.kf.x[:, 0]
        v = x[kalman.VEL].copy()
        motion: MotionState | None = None
        if cfg.motion_discriminator_enabled:
            motion = self.motion.state
            v = self.motion.velocity(v)
        return Track(
            id=self.life.id,
            t=self.t,
            position=x[kalman.POS].copy(),
            velocity=v,
            heading=0.0,  # the box is world-axis-aligned (length = north extent); course is atan2(v_e, v_n)
            yaw_rate=0.0,
            length=float(x[6]),
            width=float(x[7]),
            height=0.0,
            shape=ShapeKind.BOX if len(self.points) >= 3 else ShapeKind.POINT,
            confirmed=self.life.confirmed,
            source="radar",
            motion=motion,
            position_cov=self.kf.P[kalman.POS, kalman.POS].copy(),
            hits=self.life.hits,
            age=self.life.age,
            time_since_update=self.life.time_since_update,
        )


class RadarTracker:
    """``step`` once per radar frame; returns every live track (``Track.confirmed`` tells which to trust)."""

    def __init__(self, config: RadarTrackerConfig | None = None, ids: IdSource | None = None) -> None:
        self.cfg = config or RadarTrackerConfig()
        self.rng = np.random.default_rng(self.cfg.seed)
        self.detector = RadarDetector(self.cfg, self.rng)
        self.lifecycle = Lifecycle(self.cfg.lifecycle(), ids)
        self.tracks: list[RadarTrackState] = []
        self.t_last = -math.inf
        self.last: DetectorOutput | None = None
        self.skipped_frames = 0

    # --- access to the last cycle ------------------------------------------------------------------------------------

    @property
    def last_detections(self) -> list[Detection]:
        return self.last.detections if self.last else []

    @property
    def last_clusters(self) -> list[RadarCluster]:
        """Every cluster of the last frame, shore-removed ones included (see ``RadarCluster.shore``)."""
        return self.last.clusters if self.last else []

    @property
    def static_map(self) -> StaticMap:
        return self.detector.static_map

    def shore_points(self) -> np.ndarray:
        """(k, 2) world N/E of the shore contour, to keep quays in the obstacle map."""
        return self.detector.static_map.shore_points()

    def reset(self) -> None:
        """Forget tracks and the map (ids keep counting up)."""
        self.tracks = []
        self.t_last = -math.inf
        self.last = None
        self.detector.static_map.reset()

    # --- the cycle ---------------------------------------------------------------------------------------------------

    def step_frame(self, frame: RadarFrame, pose: EgoPose | None, use_pose_velocity: bool = True) -> list[Track]:
        """Convenience for the daemon: a driver frame and the pose at its time (None: body frame = world)."""
        if pose is None:
            return self.step(frame.xyz, frame.doppler, frame.snr, frame.stamp, np.zeros(2), 0.0, None, 0.0)
        vel = np.asarray(pose.velocity, float)[:2] if use_pose_velocity else None
        return self.step(
            frame.xyz, frame.doppler, frame.snr, frame.stamp, pose.position[:2], pose.yaw, vel, pose.yaw_rate
        )

    def step(
        self,
        points_body: np.ndarray,
        doppler: np.ndarray,
        snr: np.ndarray | None,
        t: float,
        position: np.ndarray,
        yaw: float,
        velocity: np.ndarray | None = None,
        yaw_rate: float = 0.0,
    ) -> list[Track]:
        """One radar frame at time ``t`` (s).

        ``points_body`` (n, 3) body FRD, ``doppler`` (n,) m/s positive receding, ``snr`` (n,) dB or None; own
        ``position`` (2,) world N/E, ``yaw`` (rad, 0 north, clockwise), ``velocity`` (2,) world N/E over ground or
        None (then estimated from the static returns' Doppler), ``yaw_rate`` (rad/s). Returns every live track.
        """
        pos = np.asarray(position, float).reshape(-1)[:2]
        if not (math.isfinite(t) and np.all(np.isfinite(pos)) and math.isfinite(yaw)):
            self.skipped_frames += 1
            log.warning("radar tracker: frame at t=%r skipped: time or pose not finite", t)
            return self.current_tracks()
        if t < self.t_last:
            log.warning(
                "radar tracker: time went back from %.3f to %.3f s (replay restart?); tracks reset", self.t_last, t
            )
            self.reset()
        if velocity is not None and not np.all(np.isfinite(np.asarray(velocity, float))):
            velocity = None
        yaw_rate = float(yaw_rate) if math.isfinite(float(yaw_rate)) else 0.0
        out = self.detector.detect(points_body, doppler, snr, t, pos, float(yaw), velocity, yaw_rate, update_map=False)
        self.last = out
        self.t_last = t
        cfg = self.cfg
        for tr in self.tracks:
            kalman.predict(tr.kf, t - tr.t, cfg)
            tr.t = t
        dets = out.detections
        clusters = out.kept_clusters
        if self.tracks and dets:
            cost = association_cost(
                np.array([kalman.box_of(tr.kf) for tr in self.tracks]),
                np.array([c.box() for c in clusters]),
                cfg,
            )
            a = gated_assignment(cost, _GATE)
            matches, lost, fresh = a.matches, a.unmatched_rows, a.unmatched_cols
        else:
            matches = np.empty((0, 2), int)
            lost = np.arange(len(self.tracks))
            fresh = np.arange(len(dets))
        for ti, di in matches:
            tr, det, cl = self.tracks[ti], dets[di], clusters[di]
            size = np.array([det.length, det.width])
            kalman.fused_update(tr.kf, det.center, size, det.range_m, cl.velocity, cfg)
            tr.life.hit(t)
            tr.points = cl.points
            if cfg.motion_discriminator_enabled:
                tr.motion.observe(t, cl.points, self._doppler_moving(cl))
        for ti in lost:
            self.tracks[ti].life.miss(t)
        for di in fresh:
            det, cl = dets[di], clusters[di]
            size = np.array([det.length, det.width])
            tr = RadarTrackState(
                life=self.lifecycle.start(t),
                kf=kalman.new_filter(det.center, size, det.range_m, cl.velocity, cfg),
                motion=MotionDiscriminator(cfg),
                t=t,
                points=cl.points,
            )
            if cfg.motion_discriminator_enabled:
                tr.motion.observe(t, cl.points, self._doppler_moving(cl))
            self.tracks.append(tr)
        self._update_static_map(out, matches)
        self.tracks = [tr for tr in self.tracks if tr.life.alive]
        return self.current_tracks()

    def _update_static_map(self, out: DetectorOutput, matches: np.ndarray) -> None:
        """Static returns into the map, except those of clusters that belong to tracks known to move."""
        exclude = np.zeros(len(out.points), bool)
        for ti, di in matches:
            if self._moving(self.tracks[ti]):
                exclude[out.kept_clusters[di].index] = True
        self.detector.update_map(out, exclude)

    def _doppler_moving(self, cl: RadarCluster) -> bool:
        """The cluster's Doppler profile alone shows motion: speed along its best-known direction above the static
        threshold by three standard deviations."""
        v = cl.velocity
        if v.status is VelocityStatus.UNDETERMINED:
            return False
        e = v.radial_direction
        speed = abs(float(e @ v.velocity))
        std = math.sqrt(max(float(e @ v.covariance @ e), 0.0))
        return speed > self.cfg.static_doppler_threshold_mps + 3.0 * std

    def _moving(self, tr: RadarTrackState) -> bool:
        """Clearly faster than a static return may look (speed beyond twice its own standard deviation)."""
        v = tr.kf.x[kalman.VEL, 0]
        speed = float(np.hypot(*v))
        if speed <= self.cfg.static_doppler_threshold_mps:
            return False
        var_along = float(v @ tr.kf.P[kalman.VEL, kalman.VEL] @ v) / speed**2
        return speed > 2.0 * math.sqrt(var_along)

    def current_tracks(self) -> list[Track]:
        return [tr.to_track(self.cfg) for tr in self.tracks]
