"""The 50-vessel crowd bench/load.py runs against (no named scenario has 50): every boat in range and apart."""

from __future__ import annotations

import itertools

import numpy as np

from bench.load import crowd_scene


def test_the_crowd_has_50_vessels_in_range_and_apart_for_its_120_s() -> None:
    scene = crowd_scene()
    assert len(scene.vessels) == 50
    for t in np.arange(0.0, 120.1, 5.0):
        states = [(v, v.trajectory.state(float(t)).position.reshape(2)) for v in scene.vessels]
        for v, p in states:
            assert np.hypot(*p) + v.length / 2 < 100.0  # within the VLP-16's 100 m
            assert abs(p[0]) - v.width / 2 > 5.0  # clear of the own boat (lanes run east-west)
        for (a, pa), (b, pb) in itertools.combinations(states, 2):
            north, east = abs(pa[0] - pb[0]), abs(pa[1] - pb[1])
            assert north >= (a.width + b.width) / 2 + 1.0 or east >= (a.length + b.length) / 2 + 1.0, (a.name, b.name)
