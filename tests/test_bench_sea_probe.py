"""bench/sea_probe.py's one sea: a water-only sea run through the LiDAR path is scored as the bench scores it."""

from __future__ import annotations

from bench.sea_probe import one_sea


def test_a_heeled_boat_over_a_sea_returning_most_firings_reports_no_obstacle_and_no_track() -> None:
    row = one_sea((0, ("heeled 5/3 deg", 1.5, 0.9, 1.2, 0.0)))  # the worst sea before the fit-refused fix
    assert row["crest_m"] == 0.45 and row["share"] == 0.9
    assert row["false_bin_revolutions"] == 0
    assert row["most_tracks"] == 0 and row["most_confirmed_tracks"] == 0
    assert row["first"] is None
