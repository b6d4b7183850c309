"""Bridge between the [tracker.*] tables and the trackers' own config dataclasses (which carry the papers' values)."""

from __future__ import annotations

from typing import Any

from daemon.config_schema import ConfigError, build


def _config_classes() -> dict[str, type]:
    classes: dict[str, type] = {}
    try:
        from tracker.lidar.config import LidarTrackerConfig

        classes["lidar"] = LidarTrackerConfig
    except ImportError:
        pass
    try:
        from tracker.radar.config import RadarTrackerConfig

        classes["radar"] = RadarTrackerConfig
    except ImportError:
        pass
    return classes


def build_tracker_config(name: str, table: dict[str, Any]) -> Any:
    cls = _config_classes().get(name)
    if cls is None:
        return None
    return build(cls, table)


def tracker_config_problems(tracker: Any) -> list[str]:
    problems: list[str] = []
    for name, cls in _config_classes().items():
        try:
            build(cls, getattr(tracker, name))
        except ConfigError as exc:
            problems += [f"tracker.{name}.{p}" for p in exc.problems]
    return problems
