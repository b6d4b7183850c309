"""Bin scores of `usv-tracker evaluate`: false clear, false obstacle and accuracy on a hand-made returns record."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from evaluation import EvaluationError, evaluate_run
from tests.evaluation_fixtures import CLEAR, UNKNOWN, tick, track, two_boats, write_returns, write_ticks, write_truth


def record(tmp_path: Path) -> None:
    """Ten windows; both vessels returned in all of them. Nearest returned solid per bin, every window unless said:
    bin 0 10 m, bin 10 30 m, bin 20 20 m, bin 31 20.5 m, bin 40 10.3 m, bin 50 85 m, bin 60 10 m (even windows)."""
    write_truth(tmp_path, two_boats(), 2.0)
    counts = np.zeros((10, 3, 2), int)
    counts[:, 1:, 0] = 40
    near = np.full((10, 72), np.inf)
    for j, r in {0: 10.0, 10: 30.0, 20: 20.0, 31: 20.5, 40: 10.3, 50: 85.0}.items():
        near[:, j] = r
    near[::2, 60] = 10.0
    write_returns(tmp_path / "returns.csv", counts, near)


def sent_bins() -> list[int]:
    b = [CLEAR] * 72
    b[0] = CLEAR  # solid at 10 m throughout: false clear
    b[10] = UNKNOWN  # solid at 30 m throughout: false clear (sent unknown)
    b[20] = 1500  # nearest solid 20 m > 15 m + 0.75 m: false obstacle
    b[30] = 2000  # nothing in bin 30, 20.5 m in bin 31 <= 20 m + 1 m: not false; not within tolerance either
    b[40] = 1000  # 10.3 m returned: within max(0.5, 5 %) -> accurate
    b[5] = 5000  # nothing in bins 4..6: false obstacle
    # b[50] clear with 85 m returned (beyond 0.8 x 100 m), b[60] clear with a solid in only one window: both fine
    return b


def test_bin_counts_exact(tmp_path: Path) -> None:
    record(tmp_path)
    tracks = [track_a_b() for _ in range(9)]
    ticks = [tick(0.15 + 0.1 * k, tracks[k], sent_bins()) for k in range(9)]  # 0.15 .. 0.95
    ticks[3]["obstacle_distance_cm"] = None  # 0.45: withheld
    path = write_ticks(tmp_path / "tracks.jsonl", ticks)
    b = evaluate_run(tmp_path, path).bins
    assert b is not None
    # 0.15 has one window before it (no reference); 0.45 withheld; 7 ticks scored
    assert (b.ticks_sent, b.ticks_withheld, b.ticks_withheld_with_solid) == (8, 1, 1)
    assert (b.ticks_without_reference, b.ticks_scored, b.bins_scored) == (1, 7, 7 * 72)
    assert (b.obstacle_bins, b.clear_bins, b.unknown_bins) == (7 * 4, 7 * 67, 7 * 1)
    assert b.bins_with_solid == 7 * 5  # bins 0, 10, 20, 31, 40
    # bins 0 and 31 (the solid beside bin 30's obstacle) were sent clear, bin 10 unknown
    assert (b.false_clear, b.false_clear_sent_clear, b.false_clear_sent_unknown) == (21, 14, 7)
    assert b.false_obstacle == 7 * 2  # bins 5 and 20
    assert b.obstacle_unreturned == 0  # an older record: no present columns, nothing counted apart
    assert b.within_tolerance == 7  # bin 40
    assert b.too_far == 0  # no obstacle lies beyond its bin's solid
    assert b.false_clear_rate == pytest.approx(3 / 5)
    assert b.false_obstacle_rate == pytest.approx(0.5)
    assert b.within_tolerance_share == pytest.approx(0.25)


def test_truth_csv_named_as_a_file_takes_the_returns_beside_it(tmp_path: Path) -> None:
    """`--truth DIR/truth.csv` is the same run as `--truth DIR`: the bins are scored from the returns.csv beside it."""
    record(tmp_path)
    path = write_ticks(tmp_path / "tracks.jsonl", [tick(0.15 + 0.1 * k, track_a_b(), sent_bins()) for k in range(9)])
    by_dir, by_file = evaluate_run(tmp_path, path).bins, evaluate_run(tmp_path / "truth.csv", path).bins
    assert by_dir is not None and by_file is not None
    assert (by_file.bins_scored, by_file.false_clear, by_file.false_obstacle) == (8 * 72, 24, 16)
    assert by_file == by_dir


def track_a_b() -> list[dict[str, object]]:
    return [track(1, 10.0, 0.0), track(2, 0.0, 20.0)]


@pytest.mark.parametrize(
    ("value", "false_obstacle", "accurate", "too_far"),
    [
        (2000, 0, 1, 0),  # at the solid (20 m)
        (1951, 0, 1, 0),  # 0.49 m nearer: within max(0.5 m, 5 % of 19.51 m = 0.98 m)
        (1900, 1, 0, 0),  # 1.0 m nearer, beyond its 0.95 m tolerance: nothing returned that near, a false obstacle
        (2104, 0, 1, 0),  # 1.04 m beyond: within 5 % of 21.04 m (1.05 m)
        (2110, 0, 0, 1),  # 1.1 m beyond, past its 1.06 m: more room said than there is
        (2600, 0, 0, 1),  # 6 m beyond the solid: there is an obstacle, nearer than said: too far
    ],
)
def test_tolerance_edges(tmp_path: Path, value: int, false_obstacle: int, accurate: int, too_far: int) -> None:
    write_truth(tmp_path, two_boats(), 2.0)
    near = np.full((10, 72), np.inf)
    near[:, 20] = 20.0
    write_returns(tmp_path / "returns.csv", np.full((10, 3, 2), 40), near)
    bins = [CLEAR] * 72
    bins[20] = value
    path = write_ticks(tmp_path / "tracks.jsonl", [tick(0.55, [], bins)])
    b = evaluate_run(tmp_path, path).bins
    assert b is not None
    assert (b.false_obstacle, b.within_tolerance, b.obstacle_bins, b.too_far) == (false_obstacle, accurate, 1, too_far)


def test_bin_beyond_max_distance_is_an_error(tmp_path: Path) -> None:
    """A run with max_distance 150 m sends 15001 for clear: scored with 100 m, that must not pass as an obstacle."""
    record(tmp_path)
    bins = [15001] * 72
    path = write_ticks(tmp_path / "tracks.jsonl", [tick(0.55, [], bins)])
    with pytest.raises(EvaluationError, match="max_distance"):
        evaluate_run(tmp_path, path)
    b = evaluate_run(tmp_path, path, max_distance_m=150.0).bins
    assert b is not None and b.clear_bins == 72 and b.false_clear == 6  # now 85 m is within 0.8 x 150 m as well


def test_a_solid_on_a_bin_edge_is_no_false_clear_there(tmp_path: Path) -> None:
    """Bin 30's solid was returned only within half a degree of its edge with bin 31 (core empty); the daemon put
    it in bin 31. Bin 30 sent clear is no false clear; bin 0, whose solid lies inside it, sent clear still is."""
    write_truth(tmp_path, two_boats(), 2.0)
    counts = np.zeros((10, 3, 2), int)
    counts[:, 1:, 0] = 40
    near = np.full((10, 72), np.inf)
    near[:, [0, 30, 31]] = 20.0
    core = near.copy()
    core[:, 30] = np.inf  # the bin-30 returns all lie on the edge
    write_returns(tmp_path / "returns.csv", counts, near, core=core)
    sent = [CLEAR] * 72
    sent[31] = 2000
    ticks = [tick(0.25 + 0.1 * k, track_a_b(), sent) for k in range(5)]
    b = evaluate_run(tmp_path, write_ticks(tmp_path / "tracks.jsonl", ticks)).bins
    assert b is not None and b.ticks_scored == 5
    assert b.bins_with_solid == 5 * 2  # bins 0 and 31
    assert b.false_clear == 5  # bin 0 only
    assert b.false_obstacle == 0


def test_reference_is_the_span_the_ticks_revolution_was_swept_in(tmp_path: Path) -> None:
    """A quay at 70 m returned in the windows [0.1, 0.2) and [0.2, 0.3), not in [0.3, 0.4) nor after (met at grazing
    incidence, then not). A tick at 0.3996 s, 0.4 ms before a window's end as a replay's clock falls, used a
    revolution swept in (0.2, 0.4]: in part where nothing was returned, so its clear bin is no false clear; the tick
    at 0.2996 s had only [0.1, 0.3) to sweep and its clear bin is one. Judged by the windows that ended by the tick,
    the 0.3996 s tick would have been blamed for [0.1, 0.3), which its revolution did not see. A tick at 0.35 s (mid
    window) is judged by three windows: the quay was not there in all of them."""
    write_truth(tmp_path, two_boats(), 2.0)
    counts = np.zeros((10, 3, 2), int)
    counts[:, 1:, 0] = 40
    near = np.full((10, 72), np.inf)
    near[1:3, 12] = 70.0
    write_returns(tmp_path / "returns.csv", counts, near)
    ticks = [tick(t, track_a_b(), [CLEAR] * 72) for t in (0.2996, 0.35, 0.3996)]
    b = evaluate_run(tmp_path, write_ticks(tmp_path / "tracks.jsonl", ticks)).bins
    assert b is not None and b.ticks_scored == 3
    assert (b.bins_with_solid, b.false_clear) == (1, 1)
    # and an obstacle reported at 70 m at 0.3996 s is no false obstacle: the quay was returned at 0.2-0.3 s
    ticks = [tick(0.3996, track_a_b(), [CLEAR] * 12 + [7000] + [CLEAR] * 59)]
    b = evaluate_run(tmp_path, write_ticks(tmp_path / "tracks.jsonl", ticks)).bins
    assert b is not None and (b.obstacle_bins, b.false_obstacle, b.within_tolerance) == (1, 0, 1)


def test_an_obstacle_on_a_solid_there_but_unreturned_is_counted_apart(tmp_path: Path) -> None:
    """The present record tells a held obstacle on a hull that is there from one on open water: bin 20 sent at
    15 m with a hull there at 15.3 m that no sensor returned (counted apart), bin 5 at 50 m with a hull 53 m off
    (beyond 50 m + 2.5 m: false), bin 60 at 30 m with nothing there at all (false)."""
    write_truth(tmp_path, two_boats(), 2.0)
    counts = np.zeros((10, 3, 2), int)
    counts[:, 1:, 0] = 40
    present = np.full((10, 72), np.inf)
    present[:, 20] = 15.3
    present[:, 5] = 53.0
    write_returns(tmp_path / "returns.csv", counts, np.full((10, 72), np.inf), present=present)
    bins = [UNKNOWN] * 72
    bins[20], bins[5], bins[60] = 1500, 5000, 3000
    path = write_ticks(tmp_path / "tracks.jsonl", [tick(0.25 + 0.1 * k, track_a_b(), bins) for k in range(5)])
    b = evaluate_run(tmp_path, path).bins
    assert b is not None and b.ticks_scored == 5
    assert (b.obstacle_bins, b.obstacle_unreturned, b.false_obstacle) == (15, 5, 10)


def test_a_run_whose_records_state_another_max_distance_is_refused_by_name(tmp_path: Path) -> None:
    """A run with [output] max_distance_m = 50 sends "clear" as 5001 cm: judged with 100 m, every such bin was an
    obstacle at 50.01 m, counted silently as false obstacles. Its tick records say what it sent with."""
    record(tmp_path)
    fifty = [tick(0.15 + 0.1 * k, track_a_b(), [5001] * 72, max_distance_m=50.0) for k in range(9)]
    path = write_ticks(tmp_path / "tracks.jsonl", fifty)
    with pytest.raises(EvaluationError, match=r"max_distance_m = 50 .*--max-distance 50"):
        evaluate_run(tmp_path, path)
    b = evaluate_run(tmp_path, path, max_distance_m=50.0).bins
    assert b is not None and b.clear_bins == 8 * 72 and b.obstacle_bins == 0  # 0.15 has no reference
    # the same run stating the evaluator's 100 m, and an older record stating nothing, are taken as they are
    hundred = [tick(0.15 + 0.1 * k, track_a_b(), sent_bins(), max_distance_m=100.0) for k in range(9)]
    assert evaluate_run(tmp_path, write_ticks(tmp_path / "t100.jsonl", hundred)).bins.false_obstacle == 8 * 2


def test_a_scene_without_vessels_scores_every_confirmed_track_as_false(tmp_path: Path) -> None:
    """No vessel in the scene: the truth file holds its header only, and every tick fell "outside" the truth, so a
    run that tracked a piece of quay for the whole scene scored no false positive. The returns record spans the
    scene; within it there is nothing to track and every confirmed track is false."""
    from simulator.scene import OwnBoat, Scene, Trajectory

    write_truth(tmp_path, Scene("empty", OwnBoat(Trajectory.stationary((0.0, 0.0), 0.0)), [], []), 1.0)
    near = np.full((10, 72), np.inf)
    near[:, 0] = 30.0  # a quay's face 30 m ahead
    write_returns(tmp_path / "returns.csv", np.zeros((10, 1, 2), int), near)
    quay_piece = [track(7, 30.5, 0.0, length=6.0)]
    ticks = [tick(0.25 + 0.1 * k, quay_piece if k % 2 else [], [3000] + [CLEAR] * 71) for k in range(7)]
    r = evaluate_run(tmp_path, write_ticks(tmp_path / "tracks.jsonl", ticks))
    # 0.25 .. 0.85: the 3 ticks at 0.35, 0.55, 0.75 carry the track
    assert (r.tracks.frames, r.tracks.objects, r.tracks.matches, r.tracks.false_positives) == (7, 0, 0, 3)
    assert r.bins is not None and r.bins.false_obstacle == 0 and r.bins.within_tolerance == 7
