"""Five-level motion discriminator (paper 001, sec. 2.3-3, eq. 8, Table 1).

Sparse radar returns wander over a target from frame to frame, so a Kalman filter fed with cluster centres gives a
moored boat a speed of tens of cm/s. The discriminator decides from the overlap of the track's point-group hulls:
a counter D moves by one per comparison, its value maps to a level by Table 1, the level moves at most one step at a
time, and the published speed follows the level (wait: unknown, static: zero, dynamic: the filter's).

Where this departs from the paper, and why (each is a config field; the paper's behaviour is one setting away):
* Sign of eq. 8: the paper prints D + 1 for IoU > c, while Table 1 calls D >= 6 "absolutely dynamic". Hulls that keep
  overlapping are a target that stays put, so here IoU > c counts toward static (D - 1) and IoU <= c toward dynamic.
* Baseline (motion.hull_baseline_s, 0 = consecutive frames as in the paper): at 10 Hz a boat moves a few cm between
  frames, far less than a sparse hull jitters, so the hull is compared with the one about a second older.
* Point group (motion.group_window_s, 0 = one frame): the hull is taken over the last few frames' returns.
* Doppler veto (motion.doppler_veto): a cluster whose own Doppler clearly shows motion counts as "moved"; so does a
  track whose filter speed clearly does (motion.filter_veto_sigmas, the tracker's: a crossing boat has no Doppler).
* The hulls are support polygons in 16 directions laid along the reference group's principal axes
  (hull.support_offsets), not qhull's: the same IoU within a few hundredths, at a quarter of the cost
  (motion.hull_exact: qhull's).
* |D| is clamped (motion.counter_limit) so a boat moored for an hour is seen leaving within seconds.
"""

from __future__ import annotations

import math
from collections import deque

import numpy as np

from tracker.radar.config import RadarTrackerConfig
from tracker.radar.hull import convex_iou, padded_hull, support_frame, support_iou, support_offsets
from tracker.types import MotionState

LEVELS = (
    MotionState.ABSOLUTELY_STATIC,
    MotionState.STATIC,
    MotionState.WAIT,
    MotionState.DYNAMIC,
    MotionState.ABSOLUTELY_DYNAMIC,
)
_RANK = {level: k for k, level in enumerate(LEVELS)}


class MotionDiscriminator:
    """One per track. Feed it the track's point group each time the track is updated."""

    def __init__(self, config: RadarTrackerConfig) -> None:
        self.cfg = config
        self.counter = 0  # D
        self.state = MotionState.WAIT  # every track starts in "wait" (sec. 2.3-3)
        self.last_iou = math.nan
        self._hulls: deque[list] = deque()  # [t, point group, its padded hull once built]
        self._groups: deque[tuple[float, np.ndarray]] = deque()  # recent point groups, for the accumulated hull

    def level_of(self, counter: int) -> MotionState:
        """Table 1."""
        c = self.cfg
        if counter <= c.motion.absolutely_static_max:
            return MotionState.ABSOLUTELY_STATIC
        if counter <= c.motion.static_max:
            return MotionState.STATIC
        if counter < c.motion.dynamic_min:
            return MotionState.WAIT
        if counter < c.motion.absolutely_dynamic_min:
            return MotionState.DYNAMIC
        return MotionState.ABSOLUTELY_DYNAMIC

    def step_iou(self, iou: float) -> MotionState:
        """One comparison of eq. 8 (sign as explained in the module doc)."""
        self.last_iou = float(iou)
        moved = not iou > self.cfg.motion.iou_threshold  # NaN counts as "moved": no overlap to speak of
        lim = self.cfg.motion.counter_limit
        self.counter = min(max(self.counter + (1 if moved else -1), -lim), lim)
        target = _RANK[self.level_of(self.counter)]
        here = _RANK[self.state]
        self.state = LEVELS[min(max(target, here - 1), here + 1)]  # adjacent levels only
        return self.state

    def observe(
        self, t: float, points_ne: np.ndarray, doppler_moving: bool = False, filter_moving: bool = False
    ) -> MotionState:
        """Compare the hull of the track's recent returns with the newest one at least ``motion.hull_baseline_s``
        older.

        The point group is the returns of the last ``motion.group_window_s``: a dozen returns drawn anew each frame
        from the same hull give hulls whose IoU scatters from 0.4 to 0.8 even at rest; three frames' worth do not.
        ``doppler_moving``: the cluster's own Doppler shows it moving (counted with ``motion.doppler_veto``);
        ``filter_moving``: the track's filter does (the tracker applies ``motion.filter_veto_sigmas``). Either makes a
        comparison made this frame count as "moved" whatever the overlap (a 3 m boat at 0.8 m/s still overlaps its
        hull of a second ago by ~0.5).
        """
        pts = np.asarray(points_ne, float).reshape(-1, 2)
        self._groups.append((t, pts))
        while self._groups and self._groups[0][0] <= t - self.cfg.motion.group_window_s:
            self._groups.popleft()
        group = np.concatenate([g for _, g in self._groups]) if len(self._groups) > 1 else pts
        if not np.isfinite(group).all(axis=1).any():
            return self.state
        # Hulls are built only when compared: a vetoed comparison needs neither, and a boat that keeps moving is
        # vetoed every frame. A stored entry is [t, group, its own hull or None].
        entry: list = [t, group, None]
        base = self.cfg.motion.hull_baseline_s
        ref = None
        while self._hulls and self._hulls[0][0] < t and t - self._hulls[0][0] >= base:
            ref = self._hulls.popleft()  # the newest qualifying hull wins; older ones are never needed again
        if ref is not None:
            if (doppler_moving and self.cfg.motion.doppler_veto) or filter_moving:
                self.step_iou(0.0)
                self.last_iou = math.nan  # not computed: the Doppler or the filter decided
            else:
                self.step_iou(self._iou(ref, entry))
            self._hulls.appendleft(ref)  # it may still be the reference next time
        self._hulls.append(entry)
        return self.state

    def _iou(self, ref: list, entry: list) -> float:
        """Eq. 8's hull IoU: qhull's hulls (``motion.hull_exact``), or support polygons (hull.support_offsets) in
        the reference group's frame - centre and principal axes, built once per reference - a quarter of the cost."""
        pad = self.cfg.motion.hull_point_pad_m
        if self.cfg.motion.hull_exact:
            for e in (ref, entry):
                if e[2] is None:
                    e[2] = padded_hull(e[1], pad)
            return convex_iou(ref[2], entry[2])
        if ref[2] is None:
            frame = support_frame(ref[1])
            ref[2] = (frame, support_offsets(ref[1], pad, frame))
        frame, ref_offsets = ref[2]
        return support_iou(ref_offsets, support_offsets(entry[1], pad, frame))

    def velocity(self, filter_velocity: np.ndarray) -> np.ndarray:
        """What to publish: NaN in "wait", zero when static, the filter's otherwise."""
        if self.state is MotionState.WAIT:
            return np.full(2, np.nan)
        if self.state in (MotionState.STATIC, MotionState.ABSOLUTELY_STATIC):
            return np.zeros(2)
        return np.asarray(filter_velocity, float).copy()
