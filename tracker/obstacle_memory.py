"""A short memory of the obstacles the sensors measured: for bins that would otherwise go out "unknown", and for a
hull's bins that one revolution missed.

Why: a solid seen one revolution is often unresolved the next. A low hull at 20 m in a sea-state-3 chop is met only
by the -3 deg beam, 0.5 m up, and its returns fall in and out of the sea margin from one sweep to the next; a far
hull met by one beam drops out with that beam's dropout. Such a bin goes out 65535, and ArduPilot drops unknown
bins and rebuilds its whole boundary from each message: for it the hull is gone until the next sweep that resolves
it. The memory keeps, per bin, the nearest solid the sensors returned in the last ``hold_s`` seconds (in the world
frame, so the boat's own motion moves it to its right bearing and range) and puts it in a bin whose value would
be "unknown" now, moved on by the velocity of the confirmed track whose hull it lay on (a boat overtaking at
3 m/s is a metre further on after 0.3 s; held where it was, its stern's bins showed open water). It never overrides
an obstacle measured now (the nearer truth) or a bin sent "clear" (the beams vouched for the whole bin out to
max_distance: the solid left), and a held value is never held again, so a solid the sensors stop returning is gone
``hold_s`` after the data that last showed it; one that lay on a LiDAR-held confirmed track's hull, ``hull_hold_s``
after (a hull, not spray, and a low hull drops out of the sweeps for longer than half a second).

A hull's returns also keep its obstacle bins from opening for a revolution or two: a bin whose obstacle now lies
beyond a LiDAR return that lay on a LiDAR-held confirmed track's hull in a revolution of the last ``hull_nearer_s``
seconds (moved on by the track's velocity) shows that return. One revolution misses a hull's end in a bin (a laser
dropping out for 0.1 s, its bow in a wave's shadow, the returns at a bin's edge of a hull moving across it), and the
bin went out with the quay 40 m behind a boat 8 m off. Only the LiDAR's returns: a track's outline is an estimate
(offset from the hull by a metre at times, and held, it put obstacles where nothing stood).

What it does not judge: a bin the beams vouch for only part of the way is "unknown", and a held solid inside the
vouched part fills it although the beams would have returned it (dropping such points, tried on tuning seeds, cost
more false clears than it saved false obstacles: 8 scenes, 119 -> 135 against 564 -> 517). And "measured" is what
the array held: track outlines and the radar's shore map are held like returns.

Frames: bins and points body (forward, starboard) at the tick; memory world (north, east), m.
"""

from __future__ import annotations

from collections import deque
from collections.abc import Callable, Sequence

import numpy as np

from tracker.ego import body_to_world_2d, world_to_body_2d
from tracker.lidar.hull_gate import tracked_hull_of
from tracker.obstacle_map import (
    BIN_WIDTH_RAD,
    N_BINS,
    UNKNOWN,
    BinnedPoints,
    nearest_and_edge_points_per_bin,
    nearest_per_bin,
    to_distances_cm,
)
from tracker.types import Track

# A solid within this (m) of a confirmed track's footprint is that hull's and moves with it: the returns of a hull
# lie on its sides, and a box fitted to a partial view is short by a metre or so.
HULL_GROW_M = 1.0


class ObstacleMemory:
    """Per-bin nearest measured solids of the last seconds, in the world frame."""

    def __init__(self) -> None:
        # (measurement time, (K, 2) world north/east, (K, 2) their velocity north/east m/s, (K,) whether each lay on
        # the hull of a confirmed track the LiDAR holds)
        self._held: deque[tuple[float, np.ndarray, np.ndarray, np.ndarray]] = deque()
        self.bins_filled = 0  # bins sent with a held solid instead of "unknown", since start
        self.bins_hull_nearer = 0  # obstacle bins brought in to a hull's return of an earlier revolution, since start
        self.last_filled = np.zeros(N_BINS, dtype=bool)  # the bins the newest call filled
        self._newest = -np.inf  # the measurement time of the newest entry
        # (revolution time, (K, 2) world north/east, (K, 2) velocity): LiDAR returns on LiDAR-held confirmed hulls
        self._hull_returns: deque[tuple[float, np.ndarray, np.ndarray]] = deque()
        self._newest_lidar = -np.inf

    def reset(self) -> None:
        """Forget everything (the world frame changed)."""
        self._held.clear()
        self._newest = -np.inf
        self._hull_returns.clear()
        self._newest_lidar = -np.inf

    def fill_unknown(
        self,
        t: float,
        measured_at: float,
        distances_cm: np.ndarray,
        solid_body: np.ndarray | BinnedPoints,
        own: tuple[np.ndarray, float],
        tracks: Sequence[Track],
        hold_s: float,
        min_distance_m: float,
        max_distance_m: float,
        hull_hold_s: float | None = None,
        on_structure: Callable[[np.ndarray], np.ndarray] | None = None,
        lidar: tuple[float, np.ndarray | BinnedPoints] | None = None,
        hull_nearer_s: float = 0.0,
    ) -> np.ndarray:
        """This tick's array (tick time ``t``) with its unknown bins filled from what was measured in the last
        ``hold_s`` seconds, and this tick's obstacles (``solid_body``'s nearest per obstacle bin) remembered as
        measured at ``measured_at``: the oldest of the live sensors' newest data. A tick without new data (the same
        revolution again) remembers nothing, so a solid is gone ``hold_s`` after the data that last showed it.
        ``distances_cm``: as build_obstacle_distances made it from ``solid_body``; ``own``: the boat's world
        (north, east) and yaw (rad) at the tick; ``tracks``: the tick's tracks, whose velocities move the solids
        on their hulls (footprints grown by HULL_GROW_M). A solid on the hull of a confirmed track the LiDAR holds
        (source lidar or fused) is held for ``hull_hold_s`` (None: ``hold_s``) if that is longer: it was a hull, not
        spray or a wave crest, and a hull does not vanish within a second. Not on a radar-only track's: radar alone,
        tuning seeds 45-52, that cost 1,768 false-obstacle bins (2,736 -> 4,504) for 1,705 false clears, and fused
        it moved nothing. Whether the track still lives was tried as a condition too: fused, false-clear bins 36 ->
        41 for the same false obstacles. ``on_structure`` ((n, 2) world points -> (n,) bool), where given, names
        solids on remembered structure (a quay), held ``hull_hold_s`` too: they do not move either. ``lidar``: the
        LiDAR's newest revolution (its time, its solid returns in the body frame at the tick) and ``hull_nearer_s``
        (0: off): see :meth:`_hull_nearer`."""
        own_ne, own_yaw = own
        self.last_filled = np.zeros(N_BINS, dtype=bool)
        if hold_s <= 0:
            self.reset()
            return distances_cm
        hull_hold_s = hold_s if hull_hold_s is None else hull_hold_s
        while self._held and t - self._held[0][0] > max(hold_s, hull_hold_s):
            self._held.popleft()
        out = distances_cm
        unknown = distances_cm == UNKNOWN
        if self._held and unknown.any():
            moved = [
                (p + v * (t - t_held))[(t - t_held <= hold_s) | (on_hull & (t - t_held <= hull_hold_s))]
                for t_held, p, v, on_hull in self._held
            ]
            held_body = world_to_body_2d(np.concatenate(moved), own_ne, own_yaw)
            held_cm = to_distances_cm(
                nearest_per_bin(held_body), np.zeros(N_BINS, bool), min_distance_m, max_distance_m
            )
            fill = unknown & (held_cm != UNKNOWN)
            if fill.any():
                out = np.where(fill, held_cm, distances_cm)
                self.bins_filled += int(fill.sum())
                self.last_filled = fill
        measured = distances_cm <= round(max_distance_m * 100)
        if hull_nearer_s > 0:
            out = self._hull_nearer(t, out, measured, own, tracks, lidar, hull_nearer_s, min_distance_m, max_distance_m)
        if measured.any() and measured_at > self._newest:
            # an obstacle bin's value came from solid_body: its nearest point there is the one measured, and its
            # points nearest the bin's edges say how far across the bin the solid reached (a hull ending 0.2 deg
            # inside a bin, held by its nearest point alone, left the bin once the boat had moved a metre)
            pts = nearest_and_edge_points_per_bin(solid_body, measured)
            if pts.shape[0]:
                world = body_to_world_2d(pts, own_ne, own_yaw)
                hull = tracked_hull_of(world, tracks, HULL_GROW_M)
                vel = np.zeros_like(world)
                on = hull >= 0
                on_hull = np.zeros(len(world), dtype=bool)
                if on.any():
                    v = np.array([tracks[i].velocity[:2] for i in hull[on]], dtype=float)
                    vel[on] = np.where(np.isfinite(v), v, 0.0)
                    # a hull the LiDAR tracks; a radar-only track is clutter too often (see hull_hold_s)
                    on_hull[on] = [tracks[i].confirmed and tracks[i].source != "radar" for i in hull[on]]
                if on_structure is not None:
                    on_hull |= ~on & on_structure(world)
                self._held.append((measured_at, world, vel, on_hull))
                self._newest = measured_at
        return out

    def _hull_nearer(
        self,
        t: float,
        out: np.ndarray,
        measured: np.ndarray,
        own: tuple[np.ndarray, float],
        tracks: Sequence[Track],
        lidar: tuple[float, np.ndarray | BinnedPoints] | None,
        hull_nearer_s: float,
        min_distance_m: float,
        max_distance_m: float,
    ) -> np.ndarray:
        """``out`` with each obstacle bin (``measured``) brought in to the LiDAR's hull returns of the revolutions of
        the last ``hull_nearer_s`` seconds, moved on by their tracks' velocities, where those lie nearer; then this
        tick's LiDAR returns (``lidar``: the revolution's time, (N, 2) body points at the tick) on a LiDAR-held
        confirmed track's hull (its footprint grown by HULL_GROW_M) remembered for the next ticks."""
        own_ne, own_yaw = own
        while self._hull_returns and t - self._hull_returns[0][0] > hull_nearer_s:
            self._hull_returns.popleft()
        if self._hull_returns and measured.any():
            moved = np.concatenate([p + v * (t - t_rev) for t_rev, p, v in self._hull_returns])
            if moved.shape[0]:
                hull_cm = to_distances_cm(
                    nearest_per_bin(world_to_body_2d(moved, own_ne, own_yaw)),
                    np.zeros(N_BINS, bool),
                    min_distance_m,
                    max_distance_m,
                )
                nearer = measured & (hull_cm < out)
                if nearer.any():
                    out = np.where(nearer, hull_cm, out)
                    self.bins_hull_nearer += int(nearer.sum())
        if lidar is None or lidar[0] <= self._newest_lidar:
            return out
        t_rev, body = lidar
        self._newest_lidar = t_rev
        # a hull the LiDAR holds; a radar-only track is clutter too often (see fill_unknown's hull_hold_s)
        held_by_lidar = np.array([tr.confirmed and tr.source != "radar" for tr in tracks], dtype=bool)
        wanted = _bins_under(
            [tr for tr, held in zip(tracks, held_by_lidar, strict=True) if held], own_ne, own_yaw, HULL_GROW_M
        )
        # the bins those hulls span, not the revolution's thousands of returns elsewhere
        pts = nearest_and_edge_points_per_bin(body, wanted) if wanted.any() else np.empty((0, 2))
        if pts.shape[0] == 0:
            return out
        world = body_to_world_2d(pts, own_ne, own_yaw)
        hull = tracked_hull_of(world, tracks, HULL_GROW_M)
        velocity = np.array([tr.velocity[:2] if tr.speed_valid else (0.0, 0.0) for tr in tracks], dtype=float)
        keep = np.flatnonzero(hull >= 0)
        keep = keep[held_by_lidar[hull[keep]]]
        self._hull_returns.append((t_rev, world[keep], velocity[hull[keep]]))
        return out


def _bins_under(tracks: Sequence[Track], own_ne: np.ndarray, own_yaw: float, grow_m: float) -> np.ndarray:
    """(72,) bool: the bins (body frame of the own pose) that the tracks' footprint boxes, grown by ``grow_m`` on every
    side, reach into: from the least to the greatest bearing of a box's corners (a box that holds the boat: every
    bin). A track without a finite size or heading reaches none."""
    wanted = np.zeros(N_BINS, dtype=bool)
    boxes = [tr for tr in tracks if np.isfinite([tr.length, tr.width, tr.heading, *tr.position[:2]]).all()]
    if not boxes:
        return wanted
    world = np.concatenate([tr.footprint(grow_m) for tr in boxes])
    corners = world_to_body_2d(world, own_ne, own_yaw).reshape(-1, 4, 2)
    # the boat (the body origin) on the same side of all four sides of a box: inside it
    side = np.roll(corners, -1, axis=1) - corners
    turn = side[..., 1] * corners[..., 0] - side[..., 0] * corners[..., 1]
    if np.any((turn >= 0).all(axis=1) | (turn <= 0).all(axis=1)):
        wanted[:] = True
        return wanted
    bearing = np.arctan2(corners[..., 1], corners[..., 0])  # (T, 4)
    # a box that does not hold the boat spans less than half a turn: its corners' bearings about the first one's
    off = np.remainder(bearing - bearing[:, :1] + np.pi, 2 * np.pi) - np.pi
    first = np.rint((bearing[:, 0] + off.min(axis=1)) / BIN_WIDTH_RAD).astype(np.int64)
    last = np.rint((bearing[:, 0] + off.max(axis=1)) / BIN_WIDTH_RAD).astype(np.int64)
    for a, b in zip(first, last, strict=True):
        wanted[np.arange(a, b + 1) % N_BINS] = True
    return wanted
