"""Each tick's output published over Foxglove: a WebSocket server for a live view, an MCAP file, or both.

Topics (frames: daemon/view/frames.py):
  /tf               world -> boat from the own pose (FrameTransforms), every tick the pose is known
  /own_boat         the own boat's box in "boat" (SceneUpdate)
  /lidar/points     every return of the revolution in "boat", coloured by the rule that kept or dropped it
  /lidar/clusters   the LiDAR tracker's clusters in "world", a colour each, structure grey
  /radar/points     the tick's radar returns in "boat", with Doppler (m/s) and SNR fields
  /tracks           tracks in "world": box, id and speed label, velocity arrow; colour by source, faint if tentative
  /obstacles        the 72 bins sent, as 72 points in "boat" with the value, bin and state (PointCloud)
  /obstacles/outline  the same bins as chords at their ranges (SceneUpdate): obstacle red, clear green, unknown grey
  /health           the health figures of the tick (JSON)

The view runs in the loop's thread after the tick's output is complete (DaemonLoop.on_output); it never changes
what the daemon sends. A failure in it is logged once with its traceback and switches the view off: the daemon
goes on. Work is numpy into packed bytes; Python objects only per track and per bin chord.
"""

from __future__ import annotations

import logging
import math
import time
from collections import deque
from pathlib import Path
from typing import Any

import foxglove
import numpy as np
from foxglove.channels import FrameTransformsChannel, PointCloudChannel, SceneUpdateChannel
from foxglove.mcap import MCAPCompression, MCAPWriteOptions
from foxglove.messages import (
    ArrowPrimitive,
    Color,
    CubePrimitive,
    CylinderPrimitive,
    FrameTransform,
    FrameTransforms,
    LinePrimitive,
    LinePrimitiveLineType,
    PackedElementField,
    PackedElementFieldNumericType,
    Point3,
    PointCloud,
    Pose,
    Quaternion,
    SceneEntity,
    SceneEntityDeletion,
    SceneEntityDeletionType,
    SceneUpdate,
    TextPrimitive,
    Timestamp,
    Vector3,
)

from daemon.loop import DaemonLoop
from daemon.view import frames
from tracker.lidar.preprocess import REASON_NAMES
from tracker.pipeline import PerceptionOutput
from tracker.types import ShapeKind, Track

log = logging.getLogger(__name__)

WORLD, BOAT = "world", "boat"
ARROW_HORIZON_S = 3.0  # a velocity arrow reaches where the track will be this many seconds on
MIN_BOX_HEIGHT_M = 0.3  # tentative tracks report a few centimetres: still drawn as a visible slab
SOURCE_RGB = {"lidar": (0.2, 0.55, 1.0), "radar": (1.0, 0.6, 0.1), "fused": (0.25, 0.9, 0.35)}
CONFIRMED_ALPHA, TENTATIVE_ALPHA = 0.55, 0.2
DEFAULT_OWN_BOX = (-2.0, 2.0, -1.0, 1.0, -1.0, 0.5)  # FRD x0 x1 y0 y1 z0 z1 when no LiDAR own-box is configured

_NUMERIC = {
    np.dtype("<f4"): PackedElementFieldNumericType.Float32,
    np.dtype("<f8"): PackedElementFieldNumericType.Float64,
    np.dtype("u1"): PackedElementFieldNumericType.Uint8,
    np.dtype("<u2"): PackedElementFieldNumericType.Uint16,
    np.dtype("<u4"): PackedElementFieldNumericType.Uint32,
}

HEALTH_SCHEMA: dict[str, Any] = {
    "type": "object",
    "title": "usv_tracker.Health",
    "properties": {
        "t": {"type": "number", "description": "tick time, Unix s (the messages' log time)"},
        "lidar_fresh": {"type": "boolean"},
        "radar_fresh": {"type": "boolean"},
        "ego_available": {"type": "boolean"},
        "tracks": {"type": "integer"},
        "confirmed": {"type": "integer"},
        "bins_obstacle": {"type": "integer"},
        "bins_held": {"type": "integer"},
        "bins_clear": {"type": "integer"},
        "bins_unknown": {"type": "integer"},
        "cycle_ms": {"type": "number"},
        "cycle_p50_ms": {"type": "number"},
        "cycle_p99_ms": {"type": "number"},
        "deadline_misses": {"type": "integer"},
        "failed_cycles": {"type": "integer"},
        "sent": {"type": "integer"},
        "withheld": {"type": "integer"},
        "lidar_received": {"type": "integer"},
        "lidar_dropped": {"type": "integer"},
        "radar_received": {"type": "integer"},
        "radar_dropped": {"type": "integer"},
        "view_ms": {"type": "number", "description": "the previous tick's view publishing, ms"},
        "stages_ms": {"type": "object", "additionalProperties": {"type": "number"}},
        "lidar_returns": {"type": ["object", "null"], "additionalProperties": {"type": "integer"}},
        "status": {"type": "string"},
    },
}


def _stamp(ns: int) -> Timestamp:
    return Timestamp(ns // 1_000_000_000, ns % 1_000_000_000)


def _pose(xyz: tuple[float, float, float] | np.ndarray, q: tuple[float, float, float, float]) -> Pose:
    return Pose(
        position=Vector3(x=float(xyz[0]), y=float(xyz[1]), z=float(xyz[2])),
        orientation=Quaternion(x=q[0], y=q[1], z=q[2], w=q[3]),
    )


def _fields(dtype: np.dtype) -> list[PackedElementField]:
    assert dtype.fields is not None
    return [
        PackedElementField(name=name, offset=int(offset), type=_NUMERIC[ftype])
        for name, (ftype, offset, *_) in dtype.fields.items()
    ]


class FoxgloveView:
    """Channels in a context of their own, with a WebSocket server and/or an MCAP writer as its sinks."""

    def __init__(self, host: str | None = None, port: int | None = None, mcap_path: str | Path | None = None) -> None:
        self.context = foxglove.Context()
        ctx = self.context
        self.tf = FrameTransformsChannel("/tf", context=ctx)
        self.own_boat = SceneUpdateChannel("/own_boat", context=ctx)
        self.lidar_points = PointCloudChannel("/lidar/points", context=ctx)
        self.lidar_clusters = PointCloudChannel("/lidar/clusters", context=ctx)
        self.radar_points = PointCloudChannel("/radar/points", context=ctx)
        self.tracks = SceneUpdateChannel("/tracks", context=ctx)
        self.obstacles = PointCloudChannel("/obstacles", context=ctx)
        self.obstacle_outline = SceneUpdateChannel("/obstacles/outline", context=ctx)
        self.health = foxglove.Channel("/health", schema=HEALTH_SCHEMA, context=ctx)
        self.server: Any = None
        self.writer: Any = None
        self.mcap_path = Path(mcap_path) if mcap_path is not None else None
        try:
            if self.mcap_path is not None:
                # Overwritten like --tracks-out: a second run with the same command line replaces the first. LZ4, not
                # the default zstd: a full revolution is ~0.6 MB a tick, and zstd took ~13 ms of the loop's thread
                # for it (bench/view_cost.py), LZ4 ~6 ms, for a file ~30 % larger.
                self.writer = foxglove.open_mcap(
                    self.mcap_path,
                    allow_overwrite=True,
                    context=ctx,
                    writer_options=MCAPWriteOptions(compression=MCAPCompression.Lz4),
                )
            if host is not None:
                self.server = foxglove.start_server(name="usv-tracker", host=host, port=port, context=ctx)
        except Exception:
            self.close()
            raise
        self.loop: DaemonLoop | None = None
        self.time_offset_s = 0.0
        self.enabled = True
        self.failures = 0
        self.ticks = 0
        self.costs_ms: deque[float] = deque(maxlen=600)
        self._last_cost_ms = 0.0
        self._geometry_cache: tuple[Any, ...] | None = None

    @property
    def port(self) -> int | None:
        """The WebSocket server's port (the one the system chose for port 0)."""
        return int(self.server.port) if self.server is not None else None

    def attach(self, loop: DaemonLoop, time_offset_s: float = 0.0) -> None:
        """Publish every tick of ``loop``; ``time_offset_s`` turns its clock into Unix time (0 in a replay, whose
        ticks are on the capture's clock; wall minus monotonic time live)."""
        self.loop = loop
        self.time_offset_s = time_offset_s
        loop.on_output = self.on_output
        loop.pipeline.keep_view_detail = True

    # ---- per tick ----------------------------------------------------------------------------------------------
    def on_output(self, out: PerceptionOutput) -> None:
        if not self.enabled or self.loop is None:
            return
        t0 = time.perf_counter()
        try:
            self.publish(out)
            self.ticks += 1
        except Exception:
            self.failures += 1
            self.enabled = False
            self.loop.pipeline.keep_view_detail = False
            log.exception("foxglove view failed: switched off, the daemon goes on without it")
        finally:
            self._last_cost_ms = (time.perf_counter() - t0) * 1e3
            self.costs_ms.append(self._last_cost_ms)

    def _ns(self, t: float) -> int:
        return round((t + self.time_offset_s) * 1e9)

    def publish(self, out: PerceptionOutput) -> None:
        loop = self.loop
        assert loop is not None
        pipe = loop.pipeline
        ns = self._ns(out.t)
        stamp = _stamp(ns)
        own = self._own_pose(out.t, out.ego_available)
        if own is not None and self.tf.has_sinks():
            pos, roll, pitch, yaw = own
            self.tf.log(
                FrameTransforms(
                    transforms=[
                        FrameTransform(
                            timestamp=stamp,
                            parent_frame_id=WORLD,
                            child_frame_id=BOAT,
                            translation=Vector3(x=float(pos[1]), y=float(pos[0]), z=float(-pos[2])),
                            rotation=_quat(frames.boat_quaternion(roll, pitch, yaw)),
                        )
                    ]
                ),
                log_time=ns,
            )
        if self.own_boat.has_sinks():
            self.own_boat.log(self._own_boat_update(stamp), log_time=ns)
        scan = pipe.last_scan
        pre = pipe.last_preprocess
        if scan is not None and scan.n_points and self.lidar_points.has_sinks():
            reason = getattr(pre, "reason", None)
            if reason is None or reason.shape[0] != scan.n_points:
                # no reasons for this revolution (the view was switched on mid-cycle): all drawn as kept
                reason = np.zeros(scan.n_points, dtype=np.int8)
            cloud = frames.lidar_cloud(scan.xyz, scan.intensity, reason.astype(np.uint8, copy=False))
            self._log_cloud(self.lidar_points, cloud, self._ns(scan.stamp), BOAT, ns)
        tracker = pipe.lidar_tracker
        if scan is not None and tracker is not None and self.lidar_clusters.has_sinks():
            clusters = getattr(tracker, "last_clusters", [])
            structure = np.asarray(getattr(tracker, "last_structure", np.zeros(0, dtype=bool)), dtype=bool)
            self._log_cloud(self.lidar_clusters, frames.cluster_cloud(clusters, structure), ns, WORLD, ns)
        if pipe.last_radar_frames and self.radar_points.has_sinks():
            fs = pipe.last_radar_frames
            cloud = frames.radar_cloud(
                np.concatenate([f.xyz for f in fs]),
                np.concatenate([f.doppler for f in fs]),
                np.concatenate([f.snr for f in fs]),
            )
            self._log_cloud(self.radar_points, cloud, self._ns(fs[-1].stamp), BOAT, ns)
        if self.tracks.has_sinks():
            self.tracks.log(self._track_update(out.tracks, stamp, own, pipe), log_time=ns)
        max_cm = round(loop.s.max_distance_m * 100)
        if self.obstacles.has_sinks():
            self._log_cloud(self.obstacles, frames.obstacle_cloud(out.distances_cm, max_cm), ns, BOAT, ns)
        if self.obstacle_outline.has_sinks():
            self.obstacle_outline.log(self._outline_update(out.distances_cm, max_cm, stamp), log_time=ns)
        if self.health.has_sinks():
            self.health.log(self._health(out, max_cm), log_time=ns)

    def _own_pose(self, t: float, ego_available: bool) -> tuple[np.ndarray, float, float, float] | None:
        """The own pose in world NED, the identity in "no ego pose" mode (the body frame at start is the world, as
        in the pipeline), None while the pose is unknown."""
        loop = self.loop
        assert loop is not None
        if loop.poses is None or not ego_available:
            return np.zeros(3), 0.0, 0.0, 0.0
        p = loop.poses.at(t)
        if p is None:
            return None
        return np.asarray(p.position, dtype=float), float(p.roll), float(p.pitch), float(p.yaw)

    def _log_cloud(self, channel: Any, cloud: np.ndarray, stamp_ns: int, frame_id: str, log_ns: int) -> None:
        channel.log(
            PointCloud(
                timestamp=_stamp(stamp_ns),
                frame_id=frame_id,
                pose=_pose((0.0, 0.0, 0.0), (0.0, 0.0, 0.0, 1.0)),
                point_stride=cloud.dtype.itemsize,
                fields=_fields(cloud.dtype),
                data=cloud.tobytes(),
            ),
            log_time=log_ns,
        )

    # ---- scene entities -----------------------------------------------------------------------------------------
    def _own_boat_update(self, stamp: Timestamp) -> SceneUpdate:
        loop = self.loop
        assert loop is not None
        cfg = loop.pipeline.lidar_preprocess_config
        x0, x1, y0, y1, z0, z1 = tuple(getattr(cfg, "own_box", DEFAULT_OWN_BOX))
        # FRD box -> FLU centre and size; the box reaches from the water line up, so its height is drawn as it is
        centre = ((x0 + x1) / 2, -(y0 + y1) / 2, -(z0 + z1) / 2)
        entity = SceneEntity(
            timestamp=stamp,
            frame_id=BOAT,
            id="own",
            frame_locked=True,
            cubes=[
                CubePrimitive(
                    pose=_pose(centre, (0.0, 0.0, 0.0, 1.0)),
                    size=Vector3(x=x1 - x0, y=y1 - y0, z=z1 - z0),
                    color=Color(r=1.0, g=1.0, b=1.0, a=0.6),
                )
            ],
            arrows=[
                ArrowPrimitive(
                    pose=_pose((x1, 0.0, centre[2]), (0.0, 0.0, 0.0, 1.0)),
                    shaft_length=2.0,
                    shaft_diameter=0.15,
                    head_length=0.6,
                    head_diameter=0.4,
                    color=Color(r=1.0, g=1.0, b=1.0, a=0.9),
                )
            ],
        )
        return SceneUpdate(entities=[entity])

    def _track_update(
        self, tracks: list[Track], stamp: Timestamp, own: tuple[np.ndarray, float, float, float] | None, pipe: Any
    ) -> SceneUpdate:
        # boxes stand on the water: the own boat's height in the world, less the body origin's height above it
        up = -float(own[0][2]) if own is not None else 0.0
        water_up = up - float(pipe.settings.lidar_origin_height_above_water_m)
        entities = []
        for tr in tracks:
            if not np.all(np.isfinite(tr.position)):
                continue
            r, g, b = SOURCE_RGB.get(tr.source, (0.8, 0.8, 0.8))
            alpha = CONFIRMED_ALPHA if tr.confirmed else TENTATIVE_ALPHA
            height = max(float(tr.height), MIN_BOX_HEIGHT_M) if math.isfinite(tr.height) else MIN_BOX_HEIGHT_M
            east, north = float(tr.position[1]), float(tr.position[0])
            centre = (east, north, water_up + height / 2)
            yaw = frames.enu_yaw(float(tr.heading)) if math.isfinite(tr.heading) else 0.0
            length = float(tr.length) if math.isfinite(tr.length) and tr.length > 0 else 1.0
            width = float(tr.width) if math.isfinite(tr.width) and tr.width > 0 else 1.0
            speed = float(np.hypot(*tr.velocity)) if tr.speed_valid else math.nan
            label = f"{tr.id} {tr.source}" + ("" if tr.confirmed else "?")
            label += f" {speed:.1f} m/s" if math.isfinite(speed) else " -- m/s"
            arrows = []
            if math.isfinite(speed) and speed > 0.05:
                heading_enu = math.atan2(float(tr.velocity[0]), float(tr.velocity[1]))
                arrows.append(
                    ArrowPrimitive(
                        pose=_pose((east, north, water_up + height), frames.yaw_quaternion(heading_enu)),
                        shaft_length=speed * ARROW_HORIZON_S * 0.8,
                        shaft_diameter=0.2,
                        head_length=speed * ARROW_HORIZON_S * 0.2,
                        head_diameter=0.6,
                        color=Color(r=r, g=g, b=b, a=1.0),
                    )
                )
            pose, size = _pose(centre, frames.yaw_quaternion(yaw)), Vector3(x=length, y=width, z=height)
            colour = Color(r=r, g=g, b=b, a=alpha)
            # the shape the fit chose: a box, or where an ellipse fitted better (a round hull, a buoy) an elliptic
            # cylinder of the same length and beam
            if tr.shape is ShapeKind.ELLIPSE:
                body = {
                    "cylinders": [
                        CylinderPrimitive(pose=pose, size=size, bottom_scale=1.0, top_scale=1.0, color=colour)
                    ]
                }
            else:
                body = {"cubes": [CubePrimitive(pose=pose, size=size, color=colour)]}
            entities.append(
                SceneEntity(
                    timestamp=stamp,
                    frame_id=WORLD,
                    id=f"track/{tr.id}",
                    **body,
                    arrows=arrows,
                    texts=[
                        TextPrimitive(
                            pose=_pose((east, north, water_up + height + 1.0), (0.0, 0.0, 0.0, 1.0)),
                            billboard=True,
                            font_size=14.0,
                            scale_invariant=True,
                            color=Color(r=1.0, g=1.0, b=1.0, a=1.0),
                            text=label,
                        )
                    ],
                )
            )
        # everything drawn before this tick goes: a track that ended must not stay on the screen
        return SceneUpdate(
            deletions=[SceneEntityDeletion(timestamp=stamp, type=SceneEntityDeletionType.All)], entities=entities
        )

    def _outline_update(self, distances_cm: np.ndarray, max_cm: int, stamp: Timestamp) -> SceneUpdate:
        xyz, state = frames.obstacle_chords(distances_cm, max_cm)
        palette = [Color(r=c[0] / 255, g=c[1] / 255, b=c[2] / 255, a=c[3] / 255) for c in frames.STATE_RGBA]
        line = LinePrimitive(
            type=LinePrimitiveLineType.LineList,
            pose=_pose((0.0, 0.0, 0.0), (0.0, 0.0, 0.0, 1.0)),
            thickness=3.0,
            scale_invariant=True,
            points=[Point3(x=x, y=y, z=z) for x, y, z in xyz.tolist()],
            colors=[palette[s] for s in state.tolist()],
        )
        entity = SceneEntity(timestamp=stamp, frame_id=BOAT, id="bins", frame_locked=True, lines=[line])
        return SceneUpdate(entities=[entity])

    # ---- health -------------------------------------------------------------------------------------------------
    def _health(self, out: PerceptionOutput, max_cm: int) -> dict[str, Any]:
        loop = self.loop
        assert loop is not None
        p50, p99 = loop.stats.percentiles()
        durations = loop.stats._durations_ms
        states = np.bincount(frames.bin_states(out.distances_cm, max_cm), minlength=3)
        li, ra = loop.inputs.lidar.stats, loop.inputs.radar.stats
        pipe = loop.pipeline
        pre = pipe.last_preprocess
        returns = pre.counts() if pre is not None and pipe.last_scan is not None else None
        if returns is not None:
            assert list(returns) == list(REASON_NAMES)

        def num(x: float) -> float | None:
            return round(float(x), 3) if math.isfinite(x) else None

        return {
            "t": round(out.t + self.time_offset_s, 6),
            "lidar_fresh": out.lidar_fresh,
            "radar_fresh": out.radar_fresh,
            "ego_available": out.ego_available,
            "tracks": len(out.tracks),
            "confirmed": sum(1 for tr in out.tracks if tr.confirmed),
            "bins_obstacle": int(states[frames.OBSTACLE]),
            "bins_clear": int(states[frames.CLEAR]),
            "bins_unknown": int(states[frames.UNKNOWN_STATE]),
            "bins_held": int(np.count_nonzero(out.held_bins)),
            "cycle_ms": num(durations[-1]) if durations else None,
            "cycle_p50_ms": num(p50),
            "cycle_p99_ms": num(p99),
            "deadline_misses": loop.stats.deadline_misses,
            "failed_cycles": loop.failed_ticks,
            "sent": loop.sent,
            "withheld": loop.withheld,
            "lidar_received": li.received,
            "lidar_dropped": li.dropped,
            "radar_received": ra.received,
            "radar_dropped": ra.dropped,
            "view_ms": num(self._last_cost_ms),
            "stages_ms": {k: round(v, 3) for k, v in out.timings_ms.items()},
            "lidar_returns": returns,
            "status": loop.status_text() if loop.status_text is not None else "",
        }

    # ---- end ----------------------------------------------------------------------------------------------------
    def cost_percentiles(self) -> tuple[float, float]:
        if not self.costs_ms:
            return math.nan, math.nan
        a = np.fromiter(self.costs_ms, float)
        return float(np.percentile(a, 50)), float(np.percentile(a, 99))

    def close(self) -> None:
        """Finish the MCAP file (its index is written now) and stop the server."""
        if getattr(self, "ticks", 0):
            p50, p99 = self.cost_percentiles()
            log.info("foxglove view: %d ticks published, p50 %.2f ms p99 %.2f ms per tick", self.ticks, p50, p99)
        if self.writer is not None:
            self.writer.close()
            self.writer = None
            log.info("MCAP written: %s", self.mcap_path)
        if self.server is not None:
            self.server.stop()
            self.server = None
        if getattr(self, "loop", None) is not None:
            self.loop.on_output = None  # type: ignore[union-attr]
            self.loop.pipeline.keep_view_detail = False  # type: ignore[union-attr]


def _quat(q: tuple[float, float, float, float]) -> Quaternion:
    return Quaternion(x=q[0], y=q[1], z=q[2], w=q[3])
