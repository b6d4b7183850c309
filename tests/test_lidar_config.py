"""LiDAR tracker configuration: the paper's numbers as defaults, and bad values named by key."""

from __future__ import annotations

import math
from collections.abc import Callable

import pytest

from tracker.lidar.config import (
    AssociationConfig,
    ClusterConfig,
    ConfigError,
    EkfConfig,
    LidarTrackerConfig,
    PreprocessConfig,
    ShapeConfig,
)


def test_paper_defaults() -> None:
    cfg = LidarTrackerConfig()
    assert cfg.ekf.r_full_std == (0.1, 0.1, 0.05, 0.5, 0.5, 0.5)  # eq. 12 (+ height, see config)
    assert cfg.ekf.adaptive_r is True  # eq. 11
    assert cfg.shape.mode == "adaptive"  # Algorithm 4
    assert cfg.shape.lshape_method == "corner"  # sec. 3.1: the paper's choice
    assert cfg.preprocess.max_range == 100.0  # VLP-16


@pytest.mark.parametrize(
    ("make", "key"),
    [
        (lambda: ShapeConfig(mode="boxes"), "ShapeConfig.mode"),  # type: ignore[arg-type]
        (lambda: ShapeConfig(lshape_method="hough"), "ShapeConfig.lshape_method"),  # type: ignore[arg-type]
        (lambda: ShapeConfig(rotation_step=0.0), "ShapeConfig.rotation_step"),
        (lambda: ShapeConfig(rotation_step=math.radians(95.0)), "ShapeConfig.rotation_step"),
        (lambda: EkfConfig(r_full_std=(0.1, 0.1, 0.05, 0.5, 0.5)), "EkfConfig.r_full_std"),  # type: ignore[arg-type]
        (lambda: EkfConfig(r_full_std=(0.1, 0.1, 0.0, 0.5, 0.5, 0.5)), "EkfConfig.r_full_std"),
        (lambda: EkfConfig(inflation_form="full"), "EkfConfig.inflation_form"),  # type: ignore[arg-type]
        (lambda: EkfConfig(r_inflation=-1.0), "EkfConfig.r_inflation"),
        (lambda: EkfConfig(occluded_visibility=1.5), "EkfConfig.occluded_visibility"),
        (lambda: ClusterConfig(min_points=0), "ClusterConfig.min_points"),
        (lambda: ClusterConfig(grid_cell=0.6), "ClusterConfig.grid_cell"),
        (lambda: ClusterConfig(base_tolerance=float("nan")), "ClusterConfig.base_tolerance"),
        (lambda: PreprocessConfig(min_range=150.0), "PreprocessConfig.min_range"),
        (lambda: PreprocessConfig(own_box=(0.0, 1.0)), "PreprocessConfig.own_box"),  # type: ignore[arg-type]
        (lambda: AssociationConfig(gate=0.0), "AssociationConfig.gate"),
    ],
)
def test_bad_values_name_their_key(make: Callable[[], object], key: str) -> None:
    with pytest.raises(ConfigError, match=key.replace(".", r"\.")):
        make()
