"""Points per frame of the simulated AWR1843: a harbour on a moderate sea fills a frame as a real best-range profile
does (100-200 points), a calm day stays where the named scenes always were (tens), the device's bound holds."""

from __future__ import annotations

import math

import numpy as np
import pytest

from simulator.radar_model import Awr1843Model
from simulator.scenarios import get_scenario
from simulator.scene import LABEL_CLUTTER, LABEL_GHOST, LABEL_SHORE, OwnBoat, Quay, Scene, Trajectory, Vessel
from simulator.sea import Sea

# 14 vessels in front of the own boat (north, east, length, width, height, speed, course deg); a quay to starboard
FLEET = [
    (12.0, -6.0, 2.5, 1.5, 0.8, 1.0, 90.0),
    (18.0, 8.0, 2.5, 1.5, 0.8, 0.0, 0.0),
    (30.0, -20.0, 2.5, 1.5, 0.8, 2.0, 45.0),
    (15.0, 3.0, 4.5, 2.0, 1.2, 1.5, 180.0),
    (22.0, -12.0, 5.5, 2.2, 1.3, 0.5, 270.0),
    (26.0, 14.0, 6.0, 2.4, 1.5, 0.0, 30.0),
    (35.0, 2.0, 6.5, 2.4, 1.6, 3.0, 120.0),
    (40.0, -25.0, 5.0, 2.0, 1.2, 1.0, 0.0),
    (33.0, -8.0, 8.0, 3.0, 2.0, 0.0, 80.0),
    (44.0, 10.0, 10.0, 3.5, 2.5, 2.0, 200.0),
    (20.0, -22.0, 12.0, 4.0, 3.5, 1.0, 10.0),
    (38.0, 18.0, 4.0, 1.8, 1.0, 0.5, 300.0),
    (28.0, -2.0, 3.5, 1.6, 1.0, 2.5, 250.0),
    (45.0, -5.0, 20.0, 6.0, 5.0, 1.5, 95.0),
]


def _harbour(sea_state: int) -> Scene:
    vessels = [
        Vessel(
            f"v{i}",
            length,
            width,
            height,
            Trajectory.constant_velocity(
                (n, e), (v * math.cos(math.radians(c)), v * math.sin(math.radians(c))), heading=math.radians(c)
            ),
            hull="pointed" if i % 2 else "box",
            freeboard=height / 2 if length >= 8 else None,
        )
        for i, (n, e, length, width, height, v, c) in enumerate(FLEET)
    ]
    quay = Quay(np.array([[-20.0, 26.0], [90.0, 26.0]]), height=1.5)  # land to starboard
    own = OwnBoat(
        Trajectory.stationary((0.0, 0.0), 0.0),
        roll_amplitude=math.radians(1.0 + sea_state),
        pitch_amplitude=math.radians(0.5 + 0.5 * sea_state),
        heave_amplitude=0.1 * sea_state,
    )
    return Scene("harbour_sea", own, vessels, [quay], sea=Sea.state(sea_state, seed=3))


def _per_frame(scene: Scene, seconds: float = 5.0) -> dict[str, float]:
    frames = list(Awr1843Model(scene, seed=1).frames(0.0, seconds))
    n = len(frames)
    label = np.concatenate([f.label for f in frames])
    return {
        "all": label.size / n,
        "vessels": np.sum(label >= 0) / n,
        "clutter": np.sum(label == LABEL_CLUTTER) / n,
        "shore": np.sum(label == LABEL_SHORE) / n,
        "ghosts": np.sum(label == LABEL_GHOST) / n,
    }


@pytest.mark.parametrize("sea_state", [2, 3])
def test_a_harbour_on_a_moderate_sea_gives_100_to_200_points_a_frame(sea_state: int) -> None:
    """14 vessels, a quay, sea state 2 (0.15 m crests) or 3 (0.3 m): what a real best-range profile delivers."""
    counts = _per_frame(_harbour(sea_state))
    assert 100.0 <= counts["all"] <= 200.0, counts
    assert counts["vessels"] >= 40.0 and counts["clutter"] >= 40.0, counts


def test_the_same_harbour_on_a_calm_day_gives_tens() -> None:
    counts = _per_frame(_harbour(0))
    assert 40.0 <= counts["all"] <= 80.0, counts
    assert counts["clutter"] < 3.0, counts


@pytest.mark.parametrize("name", ["harbour", "radar_paper:low", "dense", "crossing"])
def test_the_named_calm_scenes_keep_tens_of_points_a_frame(name: str) -> None:
    """The named scenarios have a calm sea: the tracker's world of before (12-37 points a frame) stays."""
    counts = _per_frame(get_scenario(name), seconds=10.0)
    assert 10.0 <= counts["all"] <= 45.0, counts
    assert counts["clutter"] < 3.0, counts


def test_no_more_points_than_the_device_can_send_and_the_strongest_are_kept() -> None:
    scene = _harbour(3)
    full = Awr1843Model(scene, seed=7)
    capped = Awr1843Model(scene, seed=7, max_points=60)
    for a, b in zip(full.frames(0.0, 1.0), capped.frames(0.0, 1.0), strict=True):
        assert a.n_points > 60 and b.n_points == 60
        np.testing.assert_array_equal(np.sort(b.snr_db), np.sort(a.snr_db)[-60:])
        ghosts = np.flatnonzero(b.ghost_of >= 0)
        assert np.all(b.label[b.ghost_of[ghosts]] >= 0)  # a kept copy keeps its source, re-indexed
    assert Awr1843Model(scene).max_points == 500  # the parser takes up to 512; 921600 baud carries ~450 a frame
