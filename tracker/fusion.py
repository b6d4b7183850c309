"""Track-level fusion of the LiDAR and radar trackers' outputs.

The LiDAR gives shape, heading and centimetre positions to ~100 m in clear air; the radar gives Doppler speed and
keeps seeing in rain, fog and spray. Both trackers run on their own data and share one id source; here a confirmed
radar track that lies on a confirmed LiDAR track is folded into it (source "fused"), so the autopilot gets one
object, not two. Radar tracks the LiDAR does not explain (fog, beyond LiDAR range) stay as radar-only objects.
"""

from __future__ import annotations

import math
from dataclasses import replace

import numpy as np

from tracker.line_of_sight import in_shadow
from tracker.types import Track


def _reach(track: Track) -> float:
    """Half the larger side of a track's box: how far round its centre fusion takes it to extend."""
    return 0.5 * max(track.length, track.width)


def fuse_track_groups(
    lidar: list[Track],
    radar: list[Track],
    gate_m: float = 3.0,
    sensor_ne: np.ndarray | None = None,
    shadow_m: float = 0.0,
) -> list[tuple[Track, tuple[int, ...]]]:
    """Each object with the ids of the tracks it is made of (its own first). LiDAR tracks (ids kept), each absorbing the
    confirmed radar tracks for which it is the nearest confirmed LiDAR track that reaches them. Nearest, not first: a
    radar track between two moored boats belongs to the one it lies on, whichever the LiDAR tracker listed first. A
    LiDAR track reaches a radar track when their extents (half the larger side of each, around its centre) come within
    ``gate_m``, or when the radar track lies in its shadow seen from ``sensor_ne`` (world north/east of the own boat):
    beyond its centre by at most its half-size plus ``shadow_m`` and off its line of sight by at most its half-size plus
    ``gate_m``."""
    if not lidar or not radar:
        return [(t, (t.id,)) for t in (*lidar, *radar)]
    lidar_pos = np.array([t.position for t in lidar]).reshape(-1, 2)
    radar_pos = np.array([r.position for r in radar]).reshape(-1, 2)
    d = np.hypot(*(radar_pos[None, :, :] - lidar_pos[:, None, :]).transpose(2, 0, 1))  # (L, R)
    lidar_reach = np.array([_reach(t) for t in lidar])
    radar_reach = np.array([_reach(r) for r in radar])
    ok = d <= lidar_reach[:, None] + radar_reach[None, :] + gate_m
    if sensor_ne is not None and shadow_m > 0:
        ok |= in_shadow(lidar_pos, lidar_reach, radar_pos, sensor_ne, shadow_m, gate_m)
    ok &= np.array([t.confirmed for t in lidar])[:, None] & np.array([r.confirmed for r in radar])[None, :]
    owner = np.where(ok.any(axis=0), np.argmin(np.where(ok, d, np.inf), axis=0), -1)  # (R,) LiDAR index or -1
    out: list[tuple[Track, tuple[int, ...]]] = []
    for i, lt in enumerate(lidar):
        mine = np.flatnonzero(owner == i)
        if mine.size == 0:
            out.append((lt, (lt.id,)))
            continue
        fused = replace(lt, source="fused")
        if not lt.speed_valid:
            # The LiDAR has not settled a speed yet; a radar track on the same hull has Doppler behind it.
            best = int(mine[np.argmin(d[i, mine])])
            if radar[best].speed_valid:
                fused = replace(fused, velocity=radar[best].velocity.copy())
        out.append((fused, (lt.id, *(radar[k].id for k in mine.tolist()))))
    out.extend((r, (r.id,)) for r, o in zip(radar, owner, strict=True) if o < 0)
    return out


class PublishedIds:
    """The id each object is published under, kept while the other sensor's track joins it or leaves it.

    The LiDAR and radar trackers number their tracks from one id source, and a fused object carries its LiDAR
    track's id. A boat seen first by the radar alone (in the LiDAR's blind gap, or beyond its range in rain) and
    then by both would change id at the hand-over, and again when the LiDAR lost it: to whatever reads the tracks
    (the track file, the live view) and to a track-level scorer, a new vessel each time. So every member id of an
    object maps to the id the object was first sent under as a confirmed track; an object takes the oldest such id
    among its members, and a track that leaves the object keeps that id while no other object holds it."""

    def __init__(self, forget_s: float = 5.0) -> None:
        self.forget_s = forget_s
        self._alias: dict[int, int] = {}  # member track id -> the id its object is published under
        self._since: dict[int, float] = {}  # published id -> when it was first sent confirmed
        self._seen: dict[int, float] = {}  # member track id or published id -> when last seen

    def reset(self) -> None:
        self._alias.clear()
        self._since.clear()
        self._seen.clear()

    def same_object(self, a: int, b: int) -> bool:
        """Tracks ``a`` and ``b`` were last published as one object (both still remembered)."""
        return a in self._alias and b in self._alias and self._alias[a] == self._alias[b]

    def hold_coasting_partners(
        self, groups: list[tuple[Track, tuple[int, ...]]], gate_m: float
    ) -> list[tuple[Track, tuple[int, ...]]]:
        """``groups`` with each LiDAR track that coasts reported tentative folded into the confirmed radar track it
        was last published with, when the two still lie within ``gate_m`` (their extents, as in fuse_track_groups).

        A small boat the LiDAR loses for a few revolutions (between two beams, in a dropout) has its track reported
        tentative while it coasts with an unsettled velocity; the radar track on the same boat then stood alone and,
        the LiDAR track's id still being live, was published under its own id; when the LiDAR saw the boat again the
        object took the LiDAR id back: two id switches for one boat the radar never lost. Folded in, the radar track
        is published under the object's id meanwhile, with its own kinematics and source: the LiDAR track's coasting
        position is where the boat was. A LiDAR track tentative for anything else (structure) is left alone."""
        radar = [
            k for k, (tr, members) in enumerate(groups) if tr.source == "radar" and tr.confirmed and members == (tr.id,)
        ]
        if not radar:
            return groups
        absorbed: dict[int, int] = {}  # radar group index -> the LiDAR track id it takes in
        drop: set[int] = set()
        for k, (lt, members) in enumerate(groups):
            if lt.source != "lidar" or lt.confirmed or lt.time_since_update <= 0.0 or members != (lt.id,):
                continue
            for r in radar:
                rt = groups[r][0]
                if r in absorbed or not self.same_object(lt.id, rt.id):
                    continue
                reach = _reach(lt) + _reach(rt) + gate_m
                if float(np.hypot(*(np.asarray(lt.position[:2]) - np.asarray(rt.position[:2])))) <= reach:
                    absorbed[r] = lt.id
                    drop.add(k)
                    break
        if not absorbed:
            return groups
        out = []
        for k, (tr, members) in enumerate(groups):
            if k in drop:
                continue
            out.append((tr, (*members, absorbed[k])) if k in absorbed else (tr, members))
        return out

    def publish(self, t: float, groups: list[tuple[Track, tuple[int, ...]]]) -> list[Track]:
        """The objects of one cycle, in order, each with the id it is published under."""
        for i in [i for i, seen in self._seen.items() if t - seen > self.forget_s]:
            del self._seen[i]
            self._alias.pop(i, None)
            self._since.pop(i, None)
        inf = float("inf")
        own = {track.id for track, _ in groups}
        choices: list[list[int]] = []
        for track, members in groups:
            # Another object's own track id stays that object's: an old alias never takes it from a live track.
            ids = [i for i in dict.fromkeys(self._alias.get(m, m) for m in members) if i == track.id or i not in own]
            ids.sort(key=lambda i: (self._since.get(i, inf), i != track.id))  # sent longest ago first; then its own
            choices.append(ids)
        taken: set[int] = set()
        out: list[Track] = [track for track, _ in groups]
        # Objects holding the oldest ids choose first, so that a track leaving an object does not take its id.
        for k in sorted(range(len(groups)), key=lambda k: self._since.get(choices[k][0], inf) if choices[k] else inf):
            track, members = groups[k]
            pub = next((i for i in choices[k] if i not in taken), track.id)  # its own id: no other object's
            taken.add(pub)
            for m in members:
                self._alias[m] = pub
                self._seen[m] = t
            self._seen[pub] = t
            if track.confirmed:
                self._since.setdefault(pub, t)
            if pub != track.id:
                out[k] = replace(track, id=pub)
        return out


def report_second_tracks_tentative(
    tracks: list[Track], gap_m: float, max_speed_difference_mps: float, settled_s: float = math.inf
) -> list[Track]:
    """The tracks, with each confirmed one that lies on another's hull reported tentative: its centre within
    ``gap_m`` of the box of an older confirmed track (a lower id: started earlier) at least as long, the two not
    moving apart (velocities within ``max_speed_difference_mps`` where both are known), and not both tracked for
    ``settled_s`` or longer. A long hull seen in parts gives its pieces tracks of their own beside the hull's, whose
    box covers only what was seen of it; a vessel passing close by moves differently, or is older than the track
    beside it; a buoy or a small boat at anchor a metre off a bigger one keeps its own track beside it for as long
    as both are there. ``gap_m`` < 0: none."""
    if gap_m < 0 or len(tracks) < 2:
        return tracks
    conf = np.array([tr.confirmed for tr in tracks])
    if conf.sum() < 2:
        return tracks
    pos = np.array([tr.position[:2] for tr in tracks], float)
    vel = np.array([tr.velocity[:2] for tr in tracks], float)
    heading = np.array([tr.heading for tr in tracks])
    length = np.array([tr.length for tr in tracks])
    width = np.array([tr.width for tr in tracks])
    ids = np.array([tr.id for tr in tracks])
    # (piece, host): the piece's centre in the host's box frame (along its heading, across it)
    d = pos[:, None, :] - pos[None, :, :]
    along = np.abs(d[..., 0] * np.cos(heading)[None, :] + d[..., 1] * np.sin(heading)[None, :])
    across = np.abs(-d[..., 0] * np.sin(heading)[None, :] + d[..., 1] * np.cos(heading)[None, :])
    with np.errstate(invalid="ignore"):
        on_hull = (along <= length[None, :] / 2 + gap_m) & (across <= width[None, :] / 2 + gap_m)
        apart = np.hypot(*(vel[:, None, :] - vel[None, :, :]).transpose(2, 0, 1)) > max_speed_difference_mps
    age = np.array([tr.age for tr in tracks])
    both_settled = (age[:, None] >= settled_s) & (age[None, :] >= settled_s)
    host = (
        on_hull
        & ~both_settled
        & ~apart  # NaN (a velocity not known yet) compares False: not known to move apart
        & conf[:, None]
        & conf[None, :]
        & (ids[None, :] < ids[:, None])
        & (length[None, :] >= length[:, None])
        & np.all(np.isfinite(pos), axis=1)[:, None]
    )
    piece = host.any(axis=1)
    return [replace(tr, confirmed=False) if p else tr for tr, p in zip(tracks, piece.tolist(), strict=True)]
