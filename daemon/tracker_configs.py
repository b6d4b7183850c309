"""Check the [tracker.*] tables against the trackers' own config classes (which carry the papers' values)."""

from __future__ import annotations

from typing import Any

from daemon.config_schema import ConfigError


def tracker_config_problems(config: Any) -> list[str]:
    from daemon.config_schema import build
    from daemon.tracker_adapters import lidar_tracker_table, radar_tracker_table
    from tracker.lidar.config import LidarTrackerConfig
    from tracker.radar.config import RadarTrackerConfig

    problems: list[str] = []
    for name, cls, table in (
        ("lidar", LidarTrackerConfig, lidar_tracker_table(config)),
        ("radar", RadarTrackerConfig, radar_tracker_table(config)),
    ):
        try:
            build(cls, table)
        except ConfigError as exc:
            problems += [f"tracker.{name}.{p}" for p in exc.problems]
        except (TypeError, ValueError) as exc:
            problems.append(f"tracker.{name}: {exc}")
    return problems
