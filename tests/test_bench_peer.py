"""bench/peer.py: the detection covariance handed to Stone Soup, the skip without Stone Soup, and the adapter."""

from __future__ import annotations

import math
import sys

import numpy as np
import pytest

from bench import peer
from tracker.types import Detection, ShapeKind


def test_covariance_follows_the_hull_axis() -> None:
    # a 12 x 4 m hull heading east: 3 m along (east), 1 m across (north)
    cov = peer.position_covariance(math.pi / 2, 12.0, 4.0)
    assert np.allclose(cov, np.diag([1.0, 9.0]), atol=1e-12)
    # at 45 deg the two axes mix but the eigenvalues stay the box's
    cov = peer.position_covariance(math.pi / 4, 12.0, 4.0)
    assert np.allclose(np.sort(np.linalg.eigvalsh(cov)), [1.0, 9.0])
    assert np.allclose(cov, cov.T)


def test_covariance_floor_keeps_small_detections_honest() -> None:
    # a 0.4 x 0.2 m blob would claim 0.1 m: no fit of a few returns is that good
    cov = peer.position_covariance(0.3, 0.4, 0.2)
    assert np.allclose(np.linalg.eigvalsh(cov), [peer.SIGMA_FLOOR_M**2] * 2)


def test_skips_cleanly_without_stonesoup(monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]) -> None:
    monkeypatch.setitem(sys.modules, "stonesoup", None)  # import stonesoup now raises ImportError
    monkeypatch.setattr(sys, "argv", ["bench/peer.py"])
    peer.main()
    out = capsys.readouterr().out
    assert "skipped" in out
    assert "pip install -e '.[peer]'" in out


def _detection(t: float, north: float, east: float) -> Detection:
    return Detection(
        t=t,
        center=np.array([north, east]),
        heading=0.0,
        length=6.0,
        width=2.0,
        height=1.5,
        shape=ShapeKind.BOX,
        mse=0.01,
        n_points=40,
        range_m=30.0,
    )


def test_stonesoup_confirms_one_boat_after_min_points_and_keeps_its_id() -> None:
    pytest.importorskip("stonesoup")
    setup = peer.StoneSoupSetup(q=0.5, min_points=3)
    runner = peer.StoneSoupRunner(setup)
    seen: list[list[dict]] = []
    for k in range(20):
        t = 0.1 * k
        dets = runner.detections([_detection(t, 30.0 + 3.0 * t, 5.0)], t)  # 3 m/s north
        seen.append(runner.step(dets, t))
    counts = [len(rows) for rows in seen]
    # born on the first scan, held by the initiator until its 3rd update, then released
    assert counts[:2] == [0, 0]
    assert all(c == 1 for c in counts[3:])
    ids = {rows[0]["id"] for rows in seen[3:]}
    assert ids == {1}
    last = seen[-1][0]
    assert last["position_ne"][0] == pytest.approx(30.0 + 3.0 * 1.9, abs=1.0)  # within the 1.5 m along-hull sigma
    assert last["velocity_ne"][0] == pytest.approx(3.0, abs=1.0)
    assert last["heading_deg"] is None  # a point model has no hull: the evaluator gets null
