"""Track-level fusion of the LiDAR and radar trackers' outputs.

The LiDAR gives shape, heading and centimetre positions to ~100 m in clear air; the radar gives Doppler speed and
keeps seeing in rain, fog and spray. Both trackers run on their own data and share one id source; here a confirmed
radar track that lies on a confirmed LiDAR track is folded into it (source "fused"), so the autopilot gets one
object, not two. Radar tracks the LiDAR does not explain (fog, beyond LiDAR range) stay as radar-only objects.
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np

from tracker.types import Track


def fuse_tracks(lidar: list[Track], radar: list[Track], gate_m: float = 3.0) -> list[Track]:
    """LiDAR tracks first (ids kept), each absorbing the radar tracks within its footprint plus ``gate_m``."""
    out: list[Track] = []
    used = np.zeros(len(radar), dtype=bool)
    radar_pos = np.array([r.position for r in radar]).reshape(-1, 2)
    for lt in lidar:
        if not lt.confirmed or not radar:
            out.append(lt)
            continue
        reach = 0.5 * max(lt.length, lt.width) + gate_m
        d = np.hypot(*(radar_pos - lt.position).T)
        near = (d <= reach) & ~used & np.array([r.confirmed for r in radar])
        if not near.any():
            out.append(lt)
            continue
        used |= near
        fused = replace(lt, source="fused")
        if not lt.speed_valid:
            # The LiDAR has not settled a speed yet; a radar track on the same hull has Doppler behind it.
            best = int(np.flatnonzero(near)[np.argmin(d[near])])
            if radar[best].speed_valid:
                fused = replace(fused, velocity=radar[best].velocity.copy())
        out.append(fused)
    out.extend(r for r, u in zip(radar, used, strict=True) if not u)
    return out
