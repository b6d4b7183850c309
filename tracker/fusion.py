"""Track-level fusion of the LiDAR and radar trackers' outputs.

The LiDAR gives shape, heading and centimetre positions to ~100 m in clear air; the radar gives Doppler speed and
keeps seeing in rain, fog and spray. Both trackers run on their own data and share one id source; here a confirmed
radar track that lies on a confirmed LiDAR track is folded into it (source "fused"), so the autopilot gets one
object, not two. Radar tracks the LiDAR does not explain (fog, beyond LiDAR range) stay as radar-only objects.
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np

from tracker.line_of_sight import in_shadow
from tracker.types import Track


def fuse_tracks(
    lidar: list[Track],
    radar: list[Track],
    gate_m: float = 3.0,
    sensor_ne: np.ndarray | None = None,
    shadow_m: float = 0.0,
) -> list[Track]:
    """LiDAR tracks (ids kept), each absorbing the confirmed radar tracks for which it is the nearest confirmed
    LiDAR track that reaches them. Nearest, not first: a radar track between two moored boats belongs to the one it
    lies on, whichever the LiDAR tracker listed first. A LiDAR track reaches a radar track when their extents (half
    the larger side of each, around its centre) come within ``gate_m``, or when the radar track lies in its shadow
    seen from ``sensor_ne`` (world north/east of the own boat): beyond its centre by at most its half-size plus
    ``shadow_m`` and off its line of sight by at most its half-size plus ``gate_m``."""
    if not lidar or not radar:
        return [*lidar, *radar]
    lidar_pos = np.array([t.position for t in lidar]).reshape(-1, 2)
    radar_pos = np.array([r.position for r in radar]).reshape(-1, 2)
    d = np.hypot(*(radar_pos[None, :, :] - lidar_pos[:, None, :]).transpose(2, 0, 1))  # (L, R)
    lidar_reach = np.array([0.5 * max(t.length, t.width) for t in lidar])
    radar_reach = np.array([0.5 * max(r.length, r.width) for r in radar])
    ok = d <= lidar_reach[:, None] + radar_reach[None, :] + gate_m
    if sensor_ne is not None and shadow_m > 0:
        ok |= in_shadow(lidar_pos, lidar_reach, radar_pos, sensor_ne, shadow_m, gate_m)
    ok &= np.array([t.confirmed for t in lidar])[:, None] & np.array([r.confirmed for r in radar])[None, :]
    owner = np.where(ok.any(axis=0), np.argmin(np.where(ok, d, np.inf), axis=0), -1)  # (R,) LiDAR index or -1
    out: list[Track] = []
    for i, lt in enumerate(lidar):
        mine = np.flatnonzero(owner == i)
        if mine.size == 0:
            out.append(lt)
            continue
        fused = replace(lt, source="fused")
        if not lt.speed_valid:
            # The LiDAR has not settled a speed yet; a radar track on the same hull has Doppler behind it.
            best = int(mine[np.argmin(d[i, mine])])
            if radar[best].speed_valid:
                fused = replace(fused, velocity=radar[best].velocity.copy())
        out.append(fused)
    out.extend(r for r, o in zip(radar, owner, strict=True) if o < 0)
    return out
