"""bench/heldout.py's count of confirmed tracks on a quay (issue 12's goal: none), on a hand-written tracks file."""

from __future__ import annotations

import json
from pathlib import Path

from bench.heldout import tracks_on_quays
from simulator.scene import Quay


def _tick(t: float, tracks: list[tuple[int, bool, float, float]]) -> str:
    rows = [{"id": i, "confirmed": c, "position_ne": [n, e]} for i, c, n, e in tracks]
    return json.dumps({"t": t, "tracks": rows, "obstacle_distance_cm": None})


def test_tracks_on_the_quay_or_just_off_its_face_count_and_a_moored_boats_centre_does_not(tmp_path: Path) -> None:
    # A wall from (0, 0) to (20, 0) north/east, land to starboard: the land strip is east 0 .. 4 m, water west of 0.
    quay = Quay(points=[[0.0, 0.0], [20.0, 0.0]], land_side="starboard", depth=4.0)
    path = tmp_path / "tracks.jsonl"
    path.write_text(
        "\n".join(
            [
                _tick(0.0, [(1, True, 10.0, 2.0), (2, True, 5.0, -0.4), (3, True, 5.0, -0.8), (4, False, 8.0, 1.0)]),
                _tick(0.1, [(1, True, 10.0, 3.9), (2, True, 25.0, -0.1), (5, True, 10.0, -30.0)]),
                _tick(0.2, []),
            ]
        )
        + "\n"
    )
    # Track 1 stands on the land strip twice; track 2 is 0.4 m off the face, then 5 m past the wall's end (not on it);
    # track 3 is where a 1 m wide boat moored 0.3 m off the face has its centre; track 4 is tentative; 5 is at sea.
    assert tracks_on_quays([quay], path) == {"track_ticks": 3, "tracks": 2}
    assert tracks_on_quays([quay], path, margin_m=1.0) == {"track_ticks": 4, "tracks": 3}
    assert tracks_on_quays([], path) == {"track_ticks": 0, "tracks": 0}
