"""Scoring the radar tracker against simulator truth: CLEAR MOT (py-motmetrics) plus velocity and course errors.

The frames take the daemon's own path: the AWR1843 model's point cloud is encoded as the demo firmware's UART frames,
decoded by ``RadarFrameParser`` with the scene's radar mount (body FRD), and fed to ``RadarTracker.step_frame`` with
the own boat's ``EgoPose`` (position, yaw, velocity over ground, yaw rate) at the frame time.

Matching (CLEAR MOT, Bernardin & Stiefelhagen 2008, as py-motmetrics implements it): hypotheses are the tracker's
confirmed tracks (coasting ones included: the daemon publishes them), objects are the simulated vessels; the distance
is the Euclidean distance in metres between the track position and the vessel's centre (truth), and pairs farther
than ``gate_m`` cannot match. A pair matched in the previous frame is kept while it stays inside the gate, the rest is
a Hungarian assignment; a vessel that changes its track is an id switch.

Rates, all relative to the number of truth objects (so MOTA = TP - FP - IDSW): TP % = matched / objects,
FP % = unmatched confirmed tracks / objects. MOTP = mean matched distance (cm). Velocity metrics over matched pairs:
MVE = mean |published speed - true speed|, MVE_vec = mean |v_published - v_true|, both only over pairs whose track
publishes a velocity (a track in the motion discriminator's "wait" level publishes NaN; their share is reported as
coverage). MAE = mean |published course - true course| over pairs whose boat moves (>= ``moving_min_mps``) and whose
track publishes a non-zero velocity; a moving boat published at rest has no course and lowers ``course_cov``.
"""

from __future__ import annotations

import math
import time
from collections.abc import Iterable
from dataclasses import dataclass, field

import motmetrics as mm
import numpy as np

from drivers.awr1843.parser import RadarFrameParser, encode_frame
from drivers.frames import EgoPose
from simulator.radar_model import Awr1843Model
from simulator.scene import Scene
from tracker.radar import RadarTracker, RadarTrackerConfig

GATE_M = 2.0  # CLEAR MOT match threshold
MOVING_MIN_MPS = 0.2  # a boat slower than this has no course to score


@dataclass
class Recording:
    """One sequence: the encoded radar frames, the own boat's poses and the truth at every frame time."""

    name: str
    scene: Scene
    seed: int
    times: np.ndarray  # (F,) s
    packets: list[bytes]  # (F,) UART bytes of each frame
    poses: list[EgoPose]
    truth_pos: np.ndarray  # (F, V, 2) world north/east
    truth_vel: np.ndarray  # (F, V, 2)
    truth_range: np.ndarray  # (F, V) horizontal distance radar -> vessel centre
    vessel_class: list[str]  # (V,) vessel names
    vessel_points: np.ndarray  # (F, V) returns per vessel in the frame (for context, not used in scoring)
    model_note: str = ""


def record(
    scene: Scene, seed: int, duration: float | None = None, name: str | None = None, **model_kwargs: float
) -> Recording:
    """Simulate ``duration`` s (default the scene's) of radar frames at 10 Hz, encoded as the firmware sends them."""
    model = Awr1843Model(scene, scene.radar_mount, seed=seed, **model_kwargs)
    n = round((duration if duration is not None else scene.duration) / model.frame_period)
    times = np.arange(n) * model.frame_period
    packets: list[bytes] = []
    counts = np.zeros((n, scene.n_vessels), int)
    for k, t in enumerate(times):
        d = model.frame(float(t), k)
        packets.append(encode_frame(k, d.xyz_ti, d.doppler, d.snr_db, d.noise_db))
        lab = d.label[d.label >= 0]
        counts[k] = np.bincount(lab, minlength=scene.n_vessels)[: scene.n_vessels]
    states = scene.vessel_states(times)
    own = scene.own.poses(times)
    mount = scene.radar_mount.translation[:2]
    c, s = np.cos(own.yaw), np.sin(own.yaw)
    radar_ne = own.position + np.stack([c * mount[0] - s * mount[1], s * mount[0] + c * mount[1]], axis=1)
    rng = np.linalg.norm(states.position - radar_ne[:, None, :], axis=2)
    return Recording(
        name=name or scene.name,
        scene=scene,
        seed=seed,
        times=times,
        packets=packets,
        poses=[scene.own.pose(float(t)) for t in times],
        truth_pos=states.position,
        truth_vel=states.velocity,
        truth_range=rng,
        vessel_class=[v.name for v in scene.vessels],
        vessel_points=counts,
        model_note=", ".join(f"{k}={v}" for k, v in model_kwargs.items()),
    )


@dataclass
class TrackerRun:
    """Per frame: confirmed track ids (k,), positions (k, 2), published velocities (k, 2); and the frame's cost."""

    ids: list[np.ndarray]
    pos: list[np.ndarray]
    vel: list[np.ndarray]
    seconds: np.ndarray  # (F,) wall time of parse + track per frame
    cpu_seconds: np.ndarray  # (F,) CPU time of this thread for the same (excludes waiting for a shared core)
    all_tracks: list[int] = field(default_factory=list)  # live tracks per frame, confirmed or not


def run_tracker(rec: Recording, cfg: RadarTrackerConfig) -> TrackerRun:
    """Parse each frame's bytes and step the tracker, as the daemon does; time both together."""
    parser = RadarFrameParser(None, rec.scene.radar_mount)
    tracker = RadarTracker(cfg)
    out = TrackerRun([], [], [], np.zeros(len(rec.times)), np.zeros(len(rec.times)))
    for k, (t, data, pose) in enumerate(zip(rec.times, rec.packets, rec.poses, strict=True)):
        t0, c0 = time.perf_counter(), time.thread_time()
        tracks = []
        # The firmware pauses after each frame's burst, and the live reader tells the parser so (idle): a frame
        # held for its last bytes goes out then, not with the next frame
        for frame in parser.feed(data, float(t)) + parser.idle(float(t)):
            tracks = tracker.step_frame(frame, pose)
        out.seconds[k] = time.perf_counter() - t0
        out.cpu_seconds[k] = time.thread_time() - c0
        conf = [tr for tr in tracks if tr.confirmed and tr.part_of is None]  # as the daemon publishes them
        out.ids.append(np.array([tr.id for tr in conf], int))
        out.pos.append(np.array([tr.position for tr in conf], float).reshape(-1, 2))
        out.vel.append(np.array([tr.velocity for tr in conf], float).reshape(-1, 2))
        out.all_tracks.append(len(tracks))
    return out


@dataclass
class Scored:
    """CLEAR MOT events of one run, flattened: one row per matched pair, plus per-frame counts."""

    objects: np.ndarray  # (F, V) bool, truth object present (scored) in the frame
    frame: np.ndarray  # (P,) matched pairs: frame index
    oid: np.ndarray  # (P,) vessel index
    dist: np.ndarray  # (P,) m
    v_trk: np.ndarray  # (P, 2) published velocity (NaN in "wait")
    v_true: np.ndarray  # (P, 2)
    rng: np.ndarray  # (P,) truth range, m
    miss_oid: np.ndarray  # (M,) vessel index of each miss
    miss_rng: np.ndarray  # (M,)
    fp_near: np.ndarray  # (Q,) vessel index nearest to each false positive (attribution for per-class tables)
    fp_rng: np.ndarray  # (Q,) range of that nearest vessel
    switch_oid: np.ndarray  # (S,) vessel index of each id switch
    switch_rng: np.ndarray


def score(rec: Recording, run: TrackerRun, gate_m: float = GATE_M, warmup_s: float = 0.0) -> Scored:
    """CLEAR MOT over the frames after ``warmup_s`` with py-motmetrics, distances in metres (not squared)."""
    acc = mm.MOTAccumulator(auto_id=False)
    n_v = rec.truth_pos.shape[1]
    frames = np.flatnonzero(rec.times >= warmup_s)
    for k in frames:
        hp = run.pos[k]
        d = np.linalg.norm(rec.truth_pos[k][:, None, :] - hp[None, :, :], axis=2) if len(hp) else np.zeros((n_v, 0))
        d = np.where(d <= gate_m, d, np.nan)
        acc.update(np.arange(n_v), run.ids[k], d, frameid=int(k))
    ev = acc.mot_events.reset_index()
    fr = ev["FrameId"].to_numpy(int)
    typ = ev["Type"].to_numpy(str)
    oid = ev["OId"].to_numpy(float)
    hid = ev["HId"].to_numpy(float)
    dist = ev["D"].to_numpy(float)
    pair = (typ == "MATCH") | (typ == "SWITCH")
    pf, po, ph = fr[pair], oid[pair].astype(int), hid[pair].astype(int)
    v_trk = np.full((pf.size, 2), np.nan)
    for i, (k, h) in enumerate(zip(pf, ph, strict=True)):  # one lookup per matched pair, bench only
        v_trk[i] = run.vel[k][np.flatnonzero(run.ids[k] == h)[0]]
    miss = typ == "MISS"
    fp = typ == "FP"
    fp_near, fp_rng = [], []
    for k, h in zip(fr[fp], hid[fp].astype(int), strict=True):
        p = run.pos[k][np.flatnonzero(run.ids[k] == h)[0]]
        j = int(np.argmin(np.linalg.norm(rec.truth_pos[k] - p, axis=1)))
        fp_near.append(j)
        fp_rng.append(rec.truth_range[k, j])
    sw = typ == "SWITCH"
    objects = np.zeros((len(rec.times), n_v), bool)
    objects[frames] = True
    return Scored(
        objects=objects,
        frame=pf,
        oid=po,
        dist=dist[pair],
        v_trk=v_trk,
        v_true=rec.truth_vel[pf, po],
        rng=rec.truth_range[pf, po],
        miss_oid=oid[miss].astype(int),
        miss_rng=rec.truth_range[fr[miss], oid[miss].astype(int)],
        fp_near=np.array(fp_near, int),
        fp_rng=np.array(fp_rng, float),
        switch_oid=oid[sw].astype(int),
        switch_rng=rec.truth_range[fr[sw], oid[sw].astype(int)],
    )


@dataclass(frozen=True)
class Metrics:
    objects: int
    mota: float  # %
    motp_cm: float
    mve_cmps: float  # speed error
    mve_vec_cmps: float  # velocity vector error
    mae_deg: float
    tp: float  # %
    fp: float  # %
    idsw: int
    v_cov: float  # % of matched pairs that publish a velocity
    course_cov: float  # % of matched moving pairs that publish a course

    def row(self) -> dict[str, float]:
        return self.__dict__.copy()


def _angle_deg(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    ca, cb = np.arctan2(a[:, 1], a[:, 0]), np.arctan2(b[:, 1], b[:, 0])
    return np.degrees(np.abs((ca - cb + math.pi) % (2 * math.pi) - math.pi))


def metrics(
    parts: Iterable[tuple[Scored, np.ndarray | None]],
    band: tuple[float, float] | None = None,
    moving_min_mps: float = MOVING_MIN_MPS,
) -> Metrics:
    """Pool scored runs. Each part comes with a (V,) bool mask of the vessels to count (None: all); with ``band``
    only objects (and false positives near objects) whose range lies in [lo, hi) count."""
    n_obj = n_tp = n_fp = n_sw = 0
    dist, v_trk, v_true = [], [], []
    for s, mask in parts:
        keep_v = np.ones(s.objects.shape[1], bool) if mask is None else np.asarray(mask, bool)

        def sel(o: np.ndarray, r: np.ndarray, keep_v: np.ndarray = keep_v) -> np.ndarray:
            ok = keep_v[o] if o.size else np.zeros(0, bool)
            if band is not None:
                ok &= (r >= band[0]) & (r < band[1])
            return ok

        p = sel(s.oid, s.rng)
        m = sel(s.miss_oid, s.miss_rng)
        n_tp += int(p.sum())
        n_obj += int(p.sum() + m.sum())
        n_fp += int(sel(s.fp_near, s.fp_rng).sum())
        n_sw += int(sel(s.switch_oid, s.switch_rng).sum())
        dist.append(s.dist[p])
        v_trk.append(s.v_trk[p])
        v_true.append(s.v_true[p])
    d = np.concatenate(dist) if dist else np.zeros(0)
    vt = np.concatenate(v_trk) if v_trk else np.zeros((0, 2))
    vg = np.concatenate(v_true) if v_true else np.zeros((0, 2))
    known = np.all(np.isfinite(vt), axis=1)
    speed_t, speed_g = np.hypot(vt[:, 0], vt[:, 1]), np.hypot(vg[:, 0], vg[:, 1])
    moving = speed_g >= moving_min_mps
    course = moving & known & (speed_t > 0)
    nan = math.nan
    return Metrics(
        objects=n_obj,
        mota=100.0 * (1.0 - (n_obj - n_tp + n_fp + n_sw) / n_obj) if n_obj else nan,
        motp_cm=100.0 * float(d.mean()) if d.size else nan,
        mve_cmps=100.0 * float(np.abs(speed_t - speed_g)[known].mean()) if known.any() else nan,
        mve_vec_cmps=100.0 * float(np.linalg.norm(vt - vg, axis=1)[known].mean()) if known.any() else nan,
        mae_deg=float(_angle_deg(vt[course], vg[course]).mean()) if course.any() else nan,
        tp=100.0 * n_tp / n_obj if n_obj else nan,
        fp=100.0 * n_fp / n_obj if n_obj else nan,
        idsw=n_sw,
        v_cov=100.0 * float(known.mean()) if known.size else nan,
        course_cov=100.0 * float(course.sum() / moving.sum()) if moving.any() else nan,
    )
