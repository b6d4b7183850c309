"""bench/heldout.py's pooled false track-frames: a scene with false tracks and no match is not left out."""

from __future__ import annotations

import math

from bench.heldout import false_tracks_line


def _row(seed: int, false_positives: int, matches: int) -> dict:
    figures = {
        "false_positives": false_positives,
        "matches": matches,
        "false_track_frames": false_positives / matches if matches else math.nan,
    }
    return {"seed": seed, "fused": figures}


def test_pooled_false_track_frames_count_a_scene_without_a_match() -> None:
    rows = [_row(1, 10, 1000), _row(2, 30, 1000), _row(3, 45, 0)]
    # the table's mean of the defined ratios, 2 %, leaves scene 3's 45 false positives out; pooled they count
    assert math.isnan(rows[2]["fused"]["false_track_frames"])
    line = false_tracks_line(rows)
    assert "85 false positives over 2,000 matches, 4.25%;" in line
    assert line.endswith("1 scenes with false positives and no match (left out of the mean above): 3 (45).")


def test_no_scene_is_named_when_every_scene_has_a_match() -> None:
    line = false_tracks_line([_row(7, 0, 500), _row(9, 0, 0)])
    assert line == (
        "False track-frames (fused, pooled): 0 false positives over 500 matches, 0.00%; 0 scenes with false "
        "positives and no match (left out of the mean above)."
    )


def test_the_false_clear_line_counts_ticks_withheld_beside_a_solid_when_the_run_recorded_them() -> None:
    from bench.heldout import false_clear_line

    def row(withheld: int | None) -> dict:
        fused = {"false_clear_bins": 5, "false_clear_sent_clear": 1, "too_far_bins": 7}
        if withheld is not None:
            fused["ticks_withheld_with_solid"] = withheld
        return {"seed": 1, "fused": fused}

    assert false_clear_line([row(2), row(3)]).endswith(
        'of which 2 went out "clear" and 8 "unknown"; too-far bins (an obstacle sent beyond a solid returned '
        "nearer): 14; ticks withheld with a returned solid within 80 m: 5."
    )
    # a record written before the count existed says nothing of it rather than 0
    assert false_clear_line([row(None)]).endswith("returned nearer): 7.")
