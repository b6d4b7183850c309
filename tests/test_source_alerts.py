"""STATUSTEXT from the drivers' counters: one per kind and minute, with the sender named; news within the minute
held, not dropped."""

from __future__ import annotations

from types import SimpleNamespace

from daemon.source_alerts import SourceAlerts
from drivers.awr1843.parser import ParserStats
from drivers.vlp16.source_stats import LidarSourceStats


def test_news_is_sent_once_per_kind_and_minute() -> None:
    lidar = SimpleNamespace(stats=LidarSourceStats(sender="10.0.0.1:2368"))
    radar = SimpleNamespace(stats=SimpleNamespace(parser=ParserStats()))
    alerts = SourceAlerts(lidar, radar)
    assert alerts.poll(100.0) == []
    lidar.stats.other_senders, lidar.stats.last_foreign_ip = 1, "10.0.0.2"
    assert alerts.poll(100.1) == [(4, "usv-tracker: other LiDAR 10.0.0.2 ignored")]
    assert alerts.poll(100.2) == []  # nothing new
    lidar.stats.other_senders, lidar.stats.last_foreign_ip = 2, "10.0.0.3"
    radar.stats.parser.frames_rejected = 3
    assert alerts.poll(130.0) == [(4, "usv-tracker: radar frames of other config dropped")]  # the LiDAR's: 30 s ago
    lidar.stats.other_senders, lidar.stats.lock_moves, lidar.stats.sender = 3, 1, "10.0.0.3:2368"
    assert alerts.poll(160.1) == [
        (4, "usv-tracker: other LiDAR 10.0.0.3 ignored"),
        (4, "usv-tracker: LiDAR now from 10.0.0.3"),
    ]
    assert all(len(text) <= 50 for _, text in alerts.poll(1000.0))  # one STATUSTEXT chunk each


def test_news_within_the_minute_is_held_and_sent_when_it_is_over() -> None:
    """A takeover of the LiDAR soon after a legitimate lock move must reach the ground station, a minute late at
    worst, naming the sender that holds the lock then."""
    lidar = SimpleNamespace(stats=LidarSourceStats(sender="10.0.0.1:2368"))
    alerts = SourceAlerts(lidar, None)
    lidar.stats.lock_moves, lidar.stats.sender = 1, "10.0.0.2:2368"
    assert alerts.poll(200.0) == [(4, "usv-tracker: LiDAR now from 10.0.0.2")]
    lidar.stats.lock_moves, lidar.stats.sender = 2, "10.0.0.66:2368"
    assert alerts.poll(210.0) == []  # within the minute: held
    assert alerts.poll(259.9) == []
    assert alerts.poll(260.0) == [(4, "usv-tracker: LiDAR now from 10.0.0.66")]
    assert alerts.poll(400.0) == []  # said once


def test_sources_without_counters_give_no_news() -> None:
    assert SourceAlerts(None, None).poll(0.0) == []
