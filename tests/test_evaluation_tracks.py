"""Track scores of `usv-tracker evaluate` on hand-made runs whose answers are known exactly."""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np
import pytest

from daemon.autopilot_geo import LocalTangentPlane
from evaluation import EvaluationError, evaluate_run
from evaluation.hota import hota
from simulator.scene import OwnBoat, Scene, Trajectory, Vessel
from simulator.truth import T0_UNIX
from tests.evaluation_fixtures import tick as tick_rec
from tests.evaluation_fixtures import track, two_boats, write_returns, write_ticks, write_truth


def mot_run(tmp_path: Path, t_shift: float = 0.0) -> tuple[Path, Path]:
    """10 ticks on the truth's own samples (t = 0.0 .. 0.9) over two still boats a (id 0) and b (id 1).

    a: track 1 at (13.5, 0): 1.5 m off a's footprint (a match), 3.5 m from its centre (the centre error).
    b: track 2 at (0, 20.4) on ticks 0-4, track 3 on 5, 6, 8, 9 (an id switch at 5, a miss at 7).
    tick 3: track 9 at (0, 23.5), 2.5 m east of b's footprint: beyond the 2 m match distance, a false positive.
    every tick: an unconfirmed track on a, which does not count.
    """
    write_truth(tmp_path, two_boats(), 1.0)
    ticks = []
    for k in range(10):
        t = 0.1 * k
        trs = [
            track(1, 13.5, 0.0, length=4.5),
            track(50, 10.0, 0.0, confirmed=False),
        ]
        b_id = 2 if k < 5 else 3
        if k != 7:
            trs.append(track(b_id, 0.0, 20.4, velocity_ne=[None, None], heading_deg=180.0))
        if k == 3:
            trs.append(track(9, 0.0, 23.5))
        ticks.append(tick_rec(round(t + t_shift, 4), trs))
    return tmp_path, write_ticks(tmp_path / "tracks.jsonl", ticks)


def test_clear_mot_idf1_and_pair_errors_exact(tmp_path: Path) -> None:
    truth, tracks = mot_run(tmp_path)
    r = evaluate_run(truth, tracks)
    t = r.tracks
    assert (t.objects, t.matches, t.misses, t.false_positives, t.id_switches) == (20, 19, 1, 1, 1)
    assert t.mota == pytest.approx(1 - 3 / 20)
    assert t.motp_m == pytest.approx((10 * 3.5 + 9 * 0.4) / 19)  # centre distances, not footprint distances
    # IDF1 = 2 IDTP / (truth + track detections): a<->1 (10), b<->2 (5); track 3 (4) and 9 (1) unmatched
    assert t.idf1 == pytest.approx(2 * 15 / (20 + 20))
    assert t.velocity_coverage == pytest.approx(10 / 19)  # b's tracks publish no velocity
    assert t.speed_error_mps.n == 10 and t.speed_error_mps.mean == pytest.approx(0.0)
    assert t.heading_error_deg.mean == pytest.approx(9 * 180 / 19)  # b's tracks point south
    assert t.heading_axis_error_deg.mean == pytest.approx(0.0)
    assert t.length_error_m.mean == pytest.approx(10 * 0.5 / 19)
    assert t.position_error_m.n == 19 and t.position_error_m.median == pytest.approx(3.5)
    assert r.visibility["per_vessel"][1]["switches"] == 1
    assert r.alignment["time_offset_s"] == 0.0 and r.alignment["ticks_scored"] == 10
    assert r.bins is None  # no returns.csv: nothing to judge the bins by


def test_match_distance_is_a_parameter(tmp_path: Path) -> None:
    truth, tracks = mot_run(tmp_path)
    tight = evaluate_run(truth, tracks, match_distance_m=1.0)  # track 1 (1.5 m off a's hull) no longer matches
    assert (tight.tracks.objects, tight.tracks.misses, tight.tracks.false_positives) == (20, 10 + 1, 10 + 1)
    # track 9 (2.5 m off b's hull) is now a candidate for b, but b keeps the track it already had
    loose = evaluate_run(truth, tracks, match_distance_m=3.0)
    assert (loose.tracks.matches, loose.tracks.misses, loose.tracks.false_positives) == (19, 1, 1)


def test_time_alignment_auto_and_explicit(tmp_path: Path) -> None:
    truth, tracks = mot_run(tmp_path, t_shift=T0_UNIX)  # stamped like a replay of simulated captures
    r = evaluate_run(truth, tracks)
    assert r.alignment["time_offset_s"] == -T0_UNIX and "T0_UNIX" in r.alignment["method"]
    assert r.tracks.mota == pytest.approx(0.85)
    given = evaluate_run(truth, tracks, time_offset_s=-T0_UNIX + 0.05)  # between samples: interpolated
    assert given.alignment["method"] == "given" and given.tracks.objects == 18  # the last tick is past the truth
    assert given.alignment["ticks_outside_truth"] == 1


def test_unalignable_clock_is_an_error(tmp_path: Path) -> None:
    truth, tracks = mot_run(tmp_path, t_shift=5000.0)
    with pytest.raises(EvaluationError, match="falls in the truth's span"):
        evaluate_run(truth, tracks)
    # a given offset that leaves no tick inside the truth scores nothing: an error too, not "MOTA n/a" and exit 0
    with pytest.raises(EvaluationError, match=r"with the given offset \+5\.000 s .*: nothing to score"):
        evaluate_run(truth, tracks, time_offset_s=5.0)


def test_warmup_and_frames_without_pose(tmp_path: Path) -> None:
    truth, tracks = mot_run(tmp_path)
    r = evaluate_run(truth, tracks, warmup_s=0.25)  # ticks 0, 1, 2 are not scored
    assert r.alignment["ticks_in_warmup"] == 3 and r.tracks.objects == 14
    rows = [json.loads(line) for line in tracks.read_text().splitlines()]
    rows[4]["own"] = None  # "no ego pose": the tracks are in no known frame
    write_ticks(tracks, rows)
    r = evaluate_run(truth, tracks)
    assert r.alignment["ticks_without_pose"] == 1 and r.tracks.objects == 18


def test_fairness_with_a_returns_record(tmp_path: Path) -> None:
    """Vessel b returns nothing from window 5 on: from the tick whose two reference windows both lack it, it is a
    sensor limit, not a miss, and the track still on it is neither a match nor a false positive."""
    write_truth(tmp_path, two_boats(), 2.0)
    counts = np.zeros((10, 3, 2), int)
    counts[:, 1, 0] = 50  # a, LiDAR, every window
    counts[:5, 2, 0] = 10  # b, LiDAR, windows 0-4
    write_returns(tmp_path / "returns.csv", counts, np.full((10, 72), np.inf))
    ticks = [tick_rec(0.05 + 0.1 * k, [track(1, 10.2, 0.0), track(2, 0.0, 20.3)]) for k in range(1, 10)]
    tracks = write_ticks(tmp_path / "tracks.jsonl", ticks)
    r = evaluate_run(tmp_path, tracks)
    v = r.visibility
    # tick 0.15 has one window before it: no record; 0.25 .. 0.65 see b in a reference window; 0.75 .. 0.95 do not
    assert v["vessel_ticks_without_record"] == 2
    assert v["vessel_ticks_to_track"] == 8 + 5
    assert v["vessel_ticks_sensor_limit"] == 3
    assert v["tracks_on_unreturned_vessels"] == 2 + 3
    assert (r.tracks.objects, r.tracks.misses, r.tracks.false_positives, r.tracks.mota) == (13, 0, 0, 1.0)
    assert v["per_vessel"][1] == {
        "name": "b",
        "to_track": 5,
        "sensor_limit": 3,
        "matched": 5,
        "missed": 0,
        "switches": 0,
    }
    strict = evaluate_run(tmp_path, tracks, min_returns=20)  # b's 10 returns a window are now too few
    assert strict.visibility["vessel_ticks_to_track"] == 8 and strict.visibility["vessel_ticks_sensor_limit"] == 8


def test_track_on_an_unreturned_vessel_beside_a_returned_one_is_not_false(tmp_path: Path) -> None:
    """A 1 m buoy c 1.6 m off boat a's bow returns in windows 0-4 only; its track stays on it. While c is
    unreturned that track lies within the match distance of a too, which a's own track holds: it is a track on an
    unreturned vessel (not scored), not a false positive. A second track on a with no unreturned vessel near it is
    still false."""
    scene = two_boats()
    scene.vessels.append(Vessel("c", 1.0, 1.0, 1.0, Trajectory.stationary((13.6, 0.0), 0.0)))
    write_truth(tmp_path, scene, 2.0)
    counts = np.zeros((10, 4, 2), int)
    counts[:, 1, 0] = 50  # a, every window
    counts[:, 2, 0] = 50  # b, every window
    counts[:5, 3, 0] = 10  # c, windows 0-4
    write_returns(tmp_path / "returns.csv", counts, np.full((10, 72), np.inf))
    ticks = [
        tick_rec(0.05 + 0.1 * k, [track(1, 10.0, 0.0), track(2, 0.0, 20.0), track(3, 13.6, 0.0, length=1.0)])
        for k in range(1, 10)
    ]
    ticks[-1]["tracks"].append(track(4, 0.0, 22.5))  # 1.5 m east of b's footprint, b held by track 2: false
    tracks = write_ticks(tmp_path / "tracks.jsonl", ticks)
    r = evaluate_run(tmp_path, tracks)
    v = r.visibility
    # ticks 0.25 .. 0.65 score c (5 ticks, track 3 matches it); 0.75 .. 0.95 do not (c a sensor limit)
    assert v["per_vessel"][2]["to_track"] == 5 and v["per_vessel"][2]["matched"] == 5
    # tick 0.15 has no record yet (all three tracks left out), then track 3 in the three ticks c was not returned
    assert v["tracks_on_unreturned_vessels"] == 3 + 3
    assert (r.tracks.matches, r.tracks.false_positives) == (8 + 8 + 5, 1)


def test_gnss_reference(tmp_path: Path) -> None:
    """A reference boat logged at 1 Hz going north at 2 m/s from 30 m ahead, put in the run's frame through each
    tick's world origin. Track 7 then 8 sits 0.3 m behind it; track 99 is another boat, not a false positive."""
    t0 = 1_760_000_000.0
    plane = LocalTangentPlane(59.41, 10.49, 0.0)
    ne = np.array([[30.0 + 2.0 * k, 5.0] for k in range(4)])
    lat, lon, _ = plane.to_geodetic(np.column_stack([ne, np.zeros(4)]))
    gnss = tmp_path / "reference.csv"
    gnss.write_text("time,lat,lon,fix\n" + "".join(f"{t0 + k},{lat[k]:.10f},{lon[k]:.10f},3\n" for k in range(4)))
    ticks = []
    for k in range(20):
        t = t0 + 0.5 + 0.1 * k
        n = 30.0 + 2.0 * (0.5 + 0.1 * k)
        tid = 7 if k < 10 else 8
        ticks.append(tick_rec(t, [track(tid, n - 0.3, 5.0, velocity_ne=[2.0, 0.0]), track(99, -50.0, 40.0)]))
    ticks[5]["world_origin_lat_lon"] = None  # the autopilot had not anchored the frame yet
    tracks = write_ticks(tmp_path / "tracks.jsonl", ticks)
    r = evaluate_run(gnss, tracks)
    assert r.truth_kind == "gnss" and r.alignment["time_offset_s"] == 0.0
    assert r.alignment["ticks_without_world_origin"] == 1
    t = r.tracks
    assert (t.objects, t.matches, t.false_positives, t.id_switches) == (19, 19, 0, 1)
    assert t.mota == pytest.approx(1 - 1 / 19)
    assert t.motp_m == pytest.approx(0.3, abs=1e-6)
    assert t.speed_error_mps.mean == pytest.approx(0.0, abs=1e-4)  # lat/lon written to 1e-10 deg (10 um)
    assert t.heading_error_deg.n == 0  # a GNSS track has no hull heading
    assert r.visibility["tracks_away_from_reference"] == 19
    assert r.bins is None
    far = evaluate_run(gnss, tracks, max_distance_m=30.0)  # the reference is 31..38 m out: out of range
    assert far.tracks.objects == 0 and far.visibility["vessel_ticks_out_of_range"] == 19
    assert math.isnan(far.tracks.mota)
    # saved from a spreadsheet: a byte-order mark before the header reads the same
    gnss.write_bytes(b"\xef\xbb\xbf" + gnss.read_bytes())
    assert evaluate_run(gnss, tracks).tracks.matches == 19
    # a time column in milliseconds is named as such (it gave only "give the offset", then scored nothing)
    ms = tmp_path / "ms.csv"
    ms.write_text("time,lat,lon\n" + "".join(f"{(t0 + k) * 1000:.0f},{lat[k]:.10f},{lon[k]:.10f}\n" for k in range(4)))
    with pytest.raises(EvaluationError, match=r"the time column looks like milliseconds \(1760000000000\)"):
        evaluate_run(ms, tracks)
    assert "every vessel in range is to be tracked" in evaluate_run(gnss, tracks).to_text()
    # a GNSS logger's stamps jitter by milliseconds either side of 1 s: every tick still has its reference (with a
    # 1.0 s gap limit, the ticks in the 1.002 and 1.003 s intervals were dropped as outside the truth)
    jitter = [0.0, 0.002, -0.001, 0.002]
    shaky = tmp_path / "shaky.csv"
    shaky.write_text(
        "time,lat,lon\n" + "".join(f"{t0 + k + jitter[k]:.3f},{lat[k]:.10f},{lon[k]:.10f}\n" for k in range(4))
    )
    assert evaluate_run(shaky, tracks).tracks.objects == 19
    # a row short of a column is named as such, not as an index error
    rows = gnss.read_text(encoding="utf-8-sig").splitlines()
    gnss.write_text("\n".join([*rows[:2], f"{t0 + 1},{lat[1]:.10f}", *rows[3:]]) + "\n")
    with pytest.raises(EvaluationError, match=r"reference.csv line 3: 2 column\(s\), the header names 4"):
        evaluate_run(gnss, tracks)


def test_hota_exact_cases() -> None:
    one = [np.array([0])] * 4
    # one object, one track throughout, perfect similarity
    assert hota(one, [np.array([5])] * 4, [np.ones((1, 1))] * 4).hota == pytest.approx(1.0)
    # the track changes id halfway: DetA 1, AssA 0.5 (each id covers half of the object's life)
    h = hota(one, [np.array([5])] * 2 + [np.array([6])] * 2, [np.ones((1, 1))] * 4)
    assert (h.det_a, h.ass_a, h.hota) == (pytest.approx(1.0), pytest.approx(0.5), pytest.approx(math.sqrt(0.5)))
    # similarity 0.5: a match for the thresholds 0.05 .. 0.50 (10 of 19), so DetA and AssA are 10/19
    h = hota(one, [np.array([5])] * 4, [np.full((1, 1), 0.5)] * 4)
    assert h.det_a == pytest.approx(10 / 19) and h.hota == pytest.approx(10 / 19)
    assert hota(one, [np.zeros(0, int)] * 4, [np.zeros((1, 0))] * 4).hota == 0.0


def test_hota_agrees_with_trackeval() -> None:
    trackeval = pytest.importorskip("trackeval")
    rng = np.random.default_rng(7)
    gt, tr, sim = [], [], []
    for _ in range(60):
        g = np.flatnonzero(rng.random(5) < 0.8)
        t = np.flatnonzero(rng.random(7) < 0.6)
        s = rng.random((g.size, t.size))
        s[s < 0.4] = 0.0
        gt.append(g)
        tr.append(t)
        sim.append(s)
    ours = hota(gt, tr, sim)
    data = {
        "num_tracker_dets": sum(t.size for t in tr),
        "num_gt_dets": sum(g.size for g in gt),
        "num_gt_ids": 5,
        "num_tracker_ids": 7,
        "gt_ids": gt,
        "tracker_ids": tr,
        "similarity_scores": sim,
    }
    ref = trackeval.metrics.HOTA().eval_sequence(data)
    assert ours.hota == pytest.approx(float(np.mean(ref["HOTA"])), abs=1e-12)
    assert ours.det_a == pytest.approx(float(np.mean(ref["DetA"])), abs=1e-12)
    assert ours.ass_a == pytest.approx(float(np.mean(ref["AssA"])), abs=1e-12)
    assert ours.loc_a == pytest.approx(float(np.mean(ref["LocA"])), abs=1e-12)


def test_a_round_buoy_has_no_heading_to_score_but_an_elliptic_one_and_a_boat_do(tmp_path: Path) -> None:
    """A round buoy's heading is the simulator's bookkeeping, not an axis a track could get right or wrong: its
    matched pairs score position and size, not heading. An elliptic float (length != width) and a boat keep theirs.
    Every track here points 30 deg off its vessel's heading (north)."""
    still = Trajectory.stationary
    scene = Scene(
        "buoys",
        OwnBoat(still((0.0, 0.0), 0.0)),
        [
            Vessel("buoy", 2.0, 2.0, 1.0, still((10.0, 0.0), 0.0), hull="buoy"),
            Vessel("float", 3.0, 1.5, 1.0, still((0.0, 15.0), 0.0), hull="buoy"),
            Vessel("tender", 4.0, 2.0, 1.0, still((-12.0, 0.0), 0.0), hull="round"),
        ],
        [],
    )
    write_truth(tmp_path, scene, 1.0)
    ticks = [
        tick_rec(
            round(0.1 * k, 4),
            [
                track(1, 10.0, 0.0, heading_deg=30.0),
                track(2, 0.0, 15.0, heading_deg=30.0),
                track(3, -12.0, 0.0, heading_deg=30.0),
            ],
        )
        for k in range(10)
    ]
    t = evaluate_run(tmp_path, write_ticks(tmp_path / "tracks.jsonl", ticks)).tracks
    assert t.matches == 30 and t.position_error_m.n == 30
    assert t.heading_error_deg.n == 20 and t.heading_error_deg.mean == pytest.approx(30.0)
