"""Track lifecycle: M-of-N confirmation, coasting, deletion after a time unseen, ids never reused."""

from __future__ import annotations

import pytest

from tracker.lifecycle import IdSource, Lifecycle, LifecycleConfig, TrackStatus


def make(**kw: float) -> Lifecycle:
    return Lifecycle(LifecycleConfig(**kw))


def test_confirmed_after_m_hits_within_n_cycles() -> None:
    life = make(confirm_hits=3, confirm_window=5).start(0.0)  # birth = hit 1
    assert life.status is TrackStatus.TENTATIVE and not life.confirmed
    assert life.miss(0.1) is TrackStatus.TENTATIVE
    assert life.hit(0.2) is TrackStatus.TENTATIVE  # 2 of 3 cycles
    assert life.hit(0.3) is TrackStatus.CONFIRMED  # 3 of 4 cycles
    assert life.confirmed and life.hits == 3


def test_unproven_hits_leave_a_track_tentative_until_its_evidence_stands_out() -> None:
    """``proven`` False (its returns no more than the clutter there explains): M hits do not confirm it."""
    life = make(confirm_hits=3, confirm_window=5).start(0.0)
    assert life.hit(0.1, proven=False) is TrackStatus.TENTATIVE
    assert life.hit(0.2, proven=False) is TrackStatus.TENTATIVE  # 3 of 3, but not believed
    assert life.hit(0.3, proven=False) is TrackStatus.TENTATIVE
    assert life.hit(0.4, proven=True) is TrackStatus.CONFIRMED
    assert life.hits == 5


def test_two_hits_that_stood_alone_confirm_a_track_others_need_m_of_n() -> None:
    """``confirm_hits_alone`` 2: a track born alone and hit alone once more is confirmed then; one hit near
    something else (not alone) waits for M of N like any other."""
    lc = make(confirm_hits=3, confirm_window=5, confirm_hits_alone=2)
    lone = lc.start(0.0, alone=True)
    assert lone.hit(0.1, alone=True) is TrackStatus.CONFIRMED
    crowded = lc.start(0.0, alone=True)
    assert crowded.hit(0.1, alone=False) is TrackStatus.TENTATIVE
    assert crowded.hit(0.2, alone=False) is TrackStatus.CONFIRMED  # 3 of 3
    late = lc.start(0.0, alone=False)
    assert late.miss(0.1) is TrackStatus.TENTATIVE
    assert late.hit(0.2, alone=True) is TrackStatus.TENTATIVE  # one hit alone
    assert late.hit(0.3, alone=True) is TrackStatus.CONFIRMED  # two
    assert make(confirm_hits=3, confirm_window=5).start(0.0, alone=True).hit(0.1, alone=True) is TrackStatus.TENTATIVE


def test_tentative_deleted_once_m_is_out_of_reach() -> None:
    life = make(confirm_hits=3, confirm_window=5, max_unseen_time_tentative=10.0).start(0.0)
    assert life.miss(0.1) is TrackStatus.TENTATIVE  # 1 hit, 3 cycles left: can still reach 3
    assert life.miss(0.2) is TrackStatus.TENTATIVE  # 1 hit, 2 cycles left: 3 still reachable
    assert life.miss(0.3) is TrackStatus.DELETED  # 1 hit, 1 cycle left: cannot reach 3
    assert not life.alive
    assert life.hit(0.4) is TrackStatus.DELETED  # the dead stay dead


def test_tentative_deleted_after_its_own_unseen_time() -> None:
    life = make(confirm_hits=2, confirm_window=10, max_unseen_time_tentative=0.25).start(0.0)
    assert life.miss(0.2) is TrackStatus.TENTATIVE
    assert life.miss(0.3) is TrackStatus.DELETED


def test_confirmed_track_coasts_then_is_deleted_after_max_unseen_time() -> None:
    life = make(confirm_hits=2, confirm_window=3, max_unseen_time=1.0).start(0.0)
    assert life.hit(0.1) is TrackStatus.CONFIRMED
    assert life.miss(0.2) is TrackStatus.COASTING and life.confirmed
    assert life.hit(0.3) is TrackStatus.CONFIRMED  # re-acquired
    for t in (0.5, 0.9, 1.3):
        assert life.miss(t) is TrackStatus.COASTING
    assert life.time_since_update == pytest.approx(1.0)
    assert life.miss(1.31) is TrackStatus.DELETED  # 1.01 s unseen
    assert life.age == pytest.approx(1.31)


def test_an_occluded_track_coasts_longer_and_only_while_occluded() -> None:
    life = make(confirm_hits=1, confirm_window=1, max_unseen_time=1.0, max_unseen_time_occluded=3.0).start(0.0)
    assert life.miss(2.0, occluded=True) is TrackStatus.COASTING  # 2 s unseen, hidden behind another boat
    assert life.miss(2.9, occluded=True) is TrackStatus.COASTING
    assert life.miss(3.1, occluded=True) is TrackStatus.DELETED  # past the occluded limit too
    seen_again = make(confirm_hits=1, confirm_window=1, max_unseen_time=1.0, max_unseen_time_occluded=3.0).start(0.0)
    assert seen_again.miss(2.0, occluded=True) is TrackStatus.COASTING
    assert seen_again.miss(2.1) is TrackStatus.DELETED  # out of the shadow and still not seen: the open limit


def test_m_of_one_confirms_at_birth() -> None:
    life = make(confirm_hits=1, confirm_window=1).start(5.0)
    assert life.status is TrackStatus.CONFIRMED


def test_ids_are_never_reused_even_after_deletion() -> None:
    lc = make(confirm_hits=2, confirm_window=2, max_unseen_time_tentative=0.0)
    first = lc.start(0.0)
    assert first.miss(0.1) is TrackStatus.DELETED
    ids = [first.id] + [lc.start(0.2).id for _ in range(5)]
    assert ids == [1, 2, 3, 4, 5, 6]


def test_shared_id_source_between_lifecycles() -> None:
    ids = IdSource(first=100)
    lidar, radar = Lifecycle(ids=ids), Lifecycle(ids=ids)
    assert [lidar.start(0).id, radar.start(0).id, lidar.start(0).id] == [100, 101, 102]


@pytest.mark.parametrize(("m", "n"), [(0, 3), (4, 3)])
def test_bad_m_of_n_is_rejected(m: int, n: int) -> None:
    with pytest.raises(ValueError, match="confirm_hits"):
        LifecycleConfig(confirm_hits=m, confirm_window=n)
    with pytest.raises(ValueError, match="confirm_hits_alone"):
        LifecycleConfig(confirm_hits=3, confirm_window=5, confirm_hits_alone=4)


def test_negative_unseen_time_is_rejected() -> None:
    with pytest.raises(ValueError, match="max_unseen_time"):
        LifecycleConfig(max_unseen_time=-1.0)
