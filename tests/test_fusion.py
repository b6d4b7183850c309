"""Track-level fusion: a radar track joins the nearest LiDAR track that reaches it, not the first listed."""

from __future__ import annotations

import dataclasses

import numpy as np

from tracker.fusion import PublishedIds, fuse_track_groups, report_second_tracks_tentative
from tracker.types import Track


def track(tid: int, north: float, east: float, source: str, length: float = 8.0, width: float = 3.0) -> Track:
    return Track(
        tid, 0.0, np.array([north, east]), np.zeros(2), 0.0, 0.0, length, width, 1.5, confirmed=True, source=source
    )


def fuse_tracks(lidar: list[Track], radar: list[Track], *args: object) -> list[Track]:
    """The fused objects without their members."""
    return [tr for tr, _ in fuse_track_groups(lidar, radar, *args)]  # type: ignore[arg-type]


def test_a_radar_track_joins_the_nearest_lidar_track_that_reaches_it() -> None:
    # Two boats moored 6 m apart (centres east 0 and 6); a radar track at east 4.5 lies on the second. Both LiDAR
    # tracks reach it (4 + 3 m of gate), the first listed is the farther.
    lidar = [track(1, 20.0, 0.0, "lidar"), track(2, 20.0, 6.0, "lidar")]
    radar = [track(7, 20.0, 4.5, "radar")]
    out = fuse_tracks(lidar, radar, 3.0)
    assert [(t.id, t.source) for t in out] == [(1, "lidar"), (2, "fused")]


def test_each_lidar_track_takes_its_own_radar_tracks_and_the_rest_stay() -> None:
    lidar = [track(1, 20.0, 0.0, "lidar"), track(2, 20.0, 6.0, "lidar")]
    radar = [track(7, 20.0, 5.5, "radar"), track(8, 20.5, 0.5, "radar"), track(9, 60.0, 0.0, "radar")]
    out = fuse_tracks(lidar, radar, 3.0)
    assert [(t.id, t.source) for t in out] == [(1, "fused"), (2, "fused"), (9, "radar")]


def test_a_radar_track_whose_extent_comes_within_the_gate_of_a_lidar_track_joins_it() -> None:
    # Centres 8 m apart: the LiDAR track's half-size (4 m) and the gate (3 m) alone stop 1 m short; the radar
    # track's own half-size (3 m: its scatterers spread along the hull) closes it. A 1 m radar track there stays.
    lidar = [track(1, 20.0, 0.0, "lidar")]
    assert [t.source for t in fuse_tracks(lidar, [track(7, 20.0, 8.0, "radar", 6.0, 2.0)], 3.0)] == ["fused"]
    assert [t.source for t in fuse_tracks(lidar, [track(7, 20.0, 8.0, "radar", 1.0, 1.0)], 3.0)] == ["lidar", "radar"]


def test_a_radar_track_in_the_shadow_of_a_lidar_track_is_the_same_hull() -> None:
    """An 8.6 m boat end-on 40 m north: the LiDAR tracks its near end (3 x 1.6 m), the radar its middle 7 m farther.
    In the shadow (behind it, within 1.5 + 10 m beyond and 1.5 + 3 m to the side) it joins; the same radar track
    in front of the LiDAR track, beside it, or with shadow_m 0 stays apart."""
    own = np.array([0.0, 0.0])
    lidar = [track(1, 40.0, 0.0, "lidar", 3.0, 1.6)]

    def sources(north: float, east: float, shadow_m: float = 10.0) -> list[str]:
        radar = [track(7, north, east, "radar", 1.4, 2.0)]
        return [t.source for t in fuse_tracks(lidar, radar, 3.0, own, shadow_m)]

    assert sources(47.0, 0.0) == ["fused"]
    assert sources(51.0, 4.0) == ["fused"]  # 11 m beyond, 4 m aside: the edge
    assert sources(47.0, 0.0, shadow_m=0.0) == ["lidar", "radar"]
    assert sources(33.0, 0.0) == ["lidar", "radar"]  # in front: a nearer boat the LiDAR would have seen
    assert sources(53.0, 0.0) == ["lidar", "radar"]  # 13 m beyond
    assert sources(47.0, 5.5) == ["lidar", "radar"]  # 5.5 m aside


def test_a_boat_keeps_its_id_when_the_lidar_picks_up_what_the_radar_held_alone_and_loses_it_again() -> None:
    # A boat in the LiDAR's blind gap: the radar alone holds it as track 7 for 2 s; the LiDAR's track 12 picks it
    # up (fused) for 2 s, then the radar loses it and the LiDAR carries on alone. One vessel: one id throughout.
    ids = PublishedIds(forget_s=5.0)
    sent = []
    for k in range(60):
        t = 0.1 * k
        lidar = [track(12, 40.0, 0.0, "lidar")] if k >= 20 else []
        radar = [track(7, 40.5, 0.5, "radar")] if k < 40 else []
        out = ids.publish(t, fuse_track_groups(lidar, radar, 3.0))
        sent.append([(tr.id, tr.source) for tr in out])
    assert sent[0] == [(7, "radar")] and sent[25] == [(7, "fused")] and sent[59] == [(7, "lidar")]
    assert {tid for cycle in sent for tid, _ in cycle} == {7}


def test_a_track_that_leaves_an_object_does_not_take_the_id_of_a_live_one() -> None:
    # LiDAR track 1 (sent first) absorbs radar track 9 on the same hull; then they part: two boats that had moored
    # side by side. The LiDAR track keeps 1; the radar track, whose alias is 1, goes back to its own id.
    ids = PublishedIds()
    for k in range(10):
        ids.publish(0.1 * k, fuse_track_groups([track(1, 20.0, 0.0, "lidar")], [], 3.0))
    out = ids.publish(1.0, fuse_track_groups([track(1, 20.0, 0.0, "lidar")], [track(9, 20.0, 1.0, "radar")], 3.0))
    assert [(tr.id, tr.source) for tr in out] == [(1, "fused")]
    out = ids.publish(1.1, fuse_track_groups([track(1, 20.0, 0.0, "lidar")], [track(9, 60.0, 0.0, "radar")], 3.0))
    assert [(tr.id, tr.source) for tr in out] == [(1, "lidar"), (9, "radar")]


def coasting(tid: int, north: float, east: float) -> Track:
    """A LiDAR track reported tentative while it coasts (the boat between two beams for a revolution)."""
    return dataclasses.replace(track(tid, north, east, "lidar", 3.0, 1.2), confirmed=False, time_since_update=0.2)


def cycle(ids: PublishedIds, t: float, lidar: list[Track], radar: list[Track]) -> list[tuple[int, str, bool]]:
    """One cycle as the pipeline runs it: fuse, hold coasting partners, publish."""
    out = ids.publish(t, ids.hold_coasting_partners(fuse_track_groups(lidar, radar, 3.0), 3.0))
    return [(tr.id, tr.source, tr.confirmed) for tr in out]


def test_a_radar_track_keeps_the_id_while_its_lidar_partner_coasts_tentative() -> None:
    # A 3 m boat 35 m off: LiDAR track 4 and radar track 9 fused and sent as 4; the LiDAR loses the boat for two
    # revolutions (its track coasts, reported tentative), the radar does not. The radar track is sent as 4 meanwhile,
    # at its own position, and the LiDAR track's tentative row is not sent beside it: one object, one id throughout.
    ids = PublishedIds()
    lidar, radar = track(4, 35.0, 0.0, "lidar", 3.0, 1.2), track(9, 35.4, 0.3, "radar", 2.0, 1.5)
    assert cycle(ids, 0.0, [lidar], [radar]) == [(4, "fused", True)]
    assert cycle(ids, 0.1, [coasting(4, 35.0, 0.0)], [radar]) == [(4, "radar", True)]
    assert cycle(ids, 0.2, [coasting(4, 35.0, 0.0)], [radar]) == [(4, "radar", True)]
    assert cycle(ids, 0.3, [lidar], [radar]) == [(4, "fused", True)]


def test_a_coasting_lidar_track_is_not_folded_into_a_stranger_or_a_far_radar_track() -> None:
    # Radar track 9 was never sent with LiDAR track 4 (another boat); radar track 10 was, but has moved 8 m away
    # (boxes 3 m and 2 m: reach 2.5 + 3 m): both stay their own objects, and the
    # tentative LiDAR track is sent as it was.
    ids = PublishedIds()
    cycle(ids, 0.0, [track(4, 35.0, 0.0, "lidar", 3.0, 1.2)], [track(10, 35.0, 0.5, "radar", 2.0, 1.5)])
    out = cycle(
        ids,
        0.1,
        [coasting(4, 35.0, 0.0)],
        [track(9, 35.5, 0.0, "radar", 2.0, 1.5), track(10, 43.0, 0.0, "radar", 2.0, 1.5)],
    )
    assert out == [(4, "lidar", False), (9, "radar", True), (10, "radar", True)]
    # A LiDAR track tentative without coasting (seen this revolution: a quay piece) is left alone too.
    ids = PublishedIds()
    cycle(ids, 0.0, [track(4, 35.0, 0.0, "lidar", 3.0, 1.2)], [track(10, 35.0, 0.5, "radar", 2.0, 1.5)])
    still = dataclasses.replace(coasting(4, 35.0, 0.0), time_since_update=0.0)
    assert cycle(ids, 0.1, [still], [track(10, 35.0, 0.5, "radar", 2.0, 1.5)]) == [
        (4, "lidar", False),
        (10, "radar", True),
    ]


def test_an_id_unseen_for_longer_than_the_memory_is_forgotten() -> None:
    # Radar track 7 fused into LiDAR track 12 and sent as 7; the radar track ends, the LiDAR's stays 7. Once 7's
    # object has been gone for forget_s, a new object that happens to hold track 12 is sent as 12.
    ids = PublishedIds(forget_s=1.0)
    ids.publish(0.0, fuse_track_groups([], [track(7, 40.0, 0.0, "radar")], 3.0))
    out = ids.publish(0.1, fuse_track_groups([track(12, 40.0, 0.0, "lidar")], [track(7, 40.0, 0.0, "radar")], 3.0))
    assert [tr.id for tr in out] == [7]
    assert [tr.id for tr in ids.publish(0.2, fuse_track_groups([track(12, 40.0, 0.0, "lidar")], [], 3.0))] == [7]
    ids.publish(0.3, [])
    assert [tr.id for tr in ids.publish(1.5, fuse_track_groups([track(12, 40.0, 0.0, "lidar")], [], 3.0))] == [12]


def moving(tid: int, north: float, east: float, length: float, width: float, v_north: float) -> Track:
    """A confirmed LiDAR track heading north (its length along north) at ``v_north`` m/s."""
    return dataclasses.replace(track(tid, north, east, "lidar", length, width), velocity=np.array([v_north, 0.0]))


def test_a_younger_track_on_an_older_hulls_box_is_reported_tentative() -> None:
    """A 30 m hull's track covers what was seen of it (20 m); a piece beyond its end moving with it, 1.5 m past the
    box, is that hull; so is one whose velocity is not known yet. A boat as close that moves apart (at rest beside the
    moving host), a track 2.6 m off, an older track and one longer than the host stay vessels."""
    host = moving(1, 0.0, 0.0, 20.0, 5.0, 3.0)  # heading north: length along north
    piece = moving(7, 11.5, 0.0, 4.0, 2.0, 3.2)  # 1.5 m beyond the host's bow end, moving alike
    crossing = moving(8, 0.0, 4.0, 3.0, 1.5, 0.0)  # beside the host, at rest while the host makes 3 m/s
    far = moving(9, 0.0, 5.1, 4.0, 2.0, 3.0)  # 2.6 m off the host's side
    unknown = moving(10, -11.0, 0.0, 3.0, 1.5, float("nan"))  # velocity not known yet: not known to move apart
    out = report_second_tracks_tentative([host, piece, crossing, far, unknown], 2.0, 1.0)
    assert [tr.confirmed for tr in out] == [True, False, True, True, False]
    assert [tr.id for tr in out] == [1, 7, 8, 9, 10]
    older_piece = moving(0, 11.5, 0.0, 4.0, 2.0, 3.2)  # the piece's track is the older one: it stays
    longer = moving(11, 11.5, 0.0, 25.0, 2.0, 3.2)  # longer than the host: not its piece
    assert [tr.confirmed for tr in report_second_tracks_tentative([host, older_piece, longer], 2.0, 1.0)] == [
        True,
        True,
        True,
    ]
    assert report_second_tracks_tentative([host, piece], -1.0, 1.0)[1].confirmed  # negative: off


def test_two_tracks_both_settled_beside_each_other_are_both_vessels() -> None:
    """A buoy 1 m off an anchored boat's side (tuning seed 61) is a piece of that hull by the box test while young;
    once both tracks are 5 s old it is a vessel of its own, but a piece is still caught while it alone is young."""
    boat = dataclasses.replace(moving(1, 0.0, 0.0, 8.0, 2.8, 0.0), age=20.0)
    buoy = moving(5, 0.0, 3.3, 1.8, 1.8, 0.0)  # centre 1.9 m off the box's side, at rest like the boat
    young = report_second_tracks_tentative([boat, dataclasses.replace(buoy, age=4.9)], 2.0, 1.0, 5.0)
    settled = report_second_tracks_tentative([boat, dataclasses.replace(buoy, age=5.0)], 2.0, 1.0, 5.0)
    assert [tr.confirmed for tr in young] == [True, False]
    assert [tr.confirmed for tr in settled] == [True, True]
    # the default (no settling time) keeps the old rule: the settled buoy is a piece
    assert not report_second_tracks_tentative([boat, dataclasses.replace(buoy, age=60.0)], 2.0, 1.0)[1].confirmed
