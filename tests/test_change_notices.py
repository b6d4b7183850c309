"""Up/down notices: a plain outage said at its start and end, a flapping one counted instead of said each time."""

from __future__ import annotations

import time

import numpy as np

from daemon.autopilot import AutopilotLink
from daemon.change_notices import ChangeNotices
from daemon.loop import MAV_STATE_EMERGENCY, DaemonLoop, LoopSettings, SensorInputs
from simulator.autopilot import SimAutopilot, wait_until
from tracker.pipeline import PerceptionOutput, PerceptionPipeline


def test_a_plain_outage_is_said_when_it_starts_and_when_it_ends() -> None:
    n = ChangeNotices(quiet_s=10.0, burst=2)
    n.start("LiDAR", True)
    assert n.note("LiDAR", True, 0.0) is None
    assert n.note("LiDAR", False, 1.0) == 0
    assert n.note("LiDAR", False, 1.1) is None
    assert n.note("LiDAR", True, 3.0) == 0  # said at once: the second notice in 10 s


def test_flapping_is_counted_and_said_when_the_quiet_time_allows() -> None:
    n = ChangeNotices(quiet_s=10.0, burst=2)
    n.start("LiDAR", True)
    said = {}
    for k in range(1, 15):  # 14 changes, one every 0.7 s
        t, state = 0.7 * k, k % 2 == 0
        out = n.note("LiDAR", state, t)
        if out is not None:
            said[round(t, 1)] = (state, out)
    assert said == {0.7: (False, 0), 1.4: (True, 0)}  # two said, twelve counted
    # 10 s after the first notice: up, as last said, but after 12 changes nobody heard of: said again with them
    assert n.note("LiDAR", True, 10.5) is None  # two notices in the last 10 s (0.7, 1.4)
    assert n.note("LiDAR", True, 10.8) == 12
    assert n.note("LiDAR", True, 10.9) is None  # nothing new
    assert n.note("LiDAR", False, 11.0) is None  # two notices within 10 s (1.4, 10.8): counted
    assert n.note("LiDAR", False, 11.5) == 0  # 10 s after 1.4: said, the change itself


def test_a_sensor_flapping_at_its_timeout_does_not_flood_the_telemetry_link(
    pair: tuple[AutopilotLink, SimAutopilot],
) -> None:
    """The LiDAR of a LiDAR + radar boat comes and goes every 0.3 s for 10 s (a sender hovering at the 0.5 s
    timeout): the feed follows it tick by tick, the autopilot hears of it twice, then once more when it settles."""
    ap_link, sim = pair
    assert wait_until(lambda: ap_link.connected, 5.0)
    loop = DaemonLoop(PerceptionPipeline(), SensorInputs(), ap_link, None, LoopSettings(radar_expected=True))
    bins = np.full(72, 65535, dtype=np.uint16)
    for k in range(150):
        t = 5.0 + 0.1 * k  # after the start-up grace
        lidar = k >= 100 or (k // 3) % 2 == 0  # flapping for 10 s, then steady
        loop._publish(PerceptionOutput(t, [], bins, lidar_fresh=lidar, radar_fresh=True))
    assert wait_until(lambda: len(sim.statustexts()) >= 3, 5.0)
    time.sleep(0.5)  # a fourth, unwanted notice would be on its way by now
    texts = [s.text for s in sim.statustexts()]
    assert texts[:2] == ["usv-tracker: LiDAR silent", "usv-tracker: LiDAR back"]
    assert texts[2:] == ["usv-tracker: LiDAR back, unsteady"]
    assert loop.sent == 150  # the radar kept the feed going throughout


def test_a_sensor_silent_from_start_up_and_an_outage_of_a_feed_that_started_at_once_are_said(
    pair: tuple[AutopilotLink, SimAutopilot],
) -> None:
    """The LiDAR delivers from the first tick, the radar never (its ports not there yet): the radar is said silent
    once the start-up grace is over; the LiDAR's outage later stops the feed, and both are said, then their end."""
    ap_link, sim = pair
    assert wait_until(lambda: ap_link.connected, 5.0)
    loop = DaemonLoop(PerceptionPipeline(), SensorInputs(), ap_link, None, LoopSettings(radar_expected=True))
    bins = np.full(72, 65535, dtype=np.uint16)
    for k in range(70):
        t = 0.1 * k
        loop._publish(PerceptionOutput(t, [], bins, lidar_fresh=not 40 <= k < 60, radar_fresh=False))
    assert wait_until(lambda: len(sim.statustexts()) >= 5, 5.0)
    time.sleep(0.5)
    assert [s.text for s in sim.statustexts()] == [
        "usv-tracker: radar silent",
        "usv-tracker: LiDAR silent",
        "usv-tracker: no sensor data, obstacles withheld",
        "usv-tracker: LiDAR back",
        "usv-tracker: sensor data back",
    ]
    assert (loop.sent, loop.withheld) == (50, 20)


def test_the_radar_alone_without_the_own_pose_withholds_the_array_and_says_so(
    pair: tuple[AutopilotLink, SimAutopilot],
) -> None:
    """A radar-only boat whose autopilot's pose stops for 2 s: the tracker cannot place the radar's frames, so every
    bin is unknown. Sent, that array reads as "sensor Good, nothing around" to the autopilot (spec): it is withheld,
    so the autopilot reports No Data, the heartbeat says no output, and the crew hears why, then that the array goes
    again. Later the radar stops for 8 s and comes back while the pose is lost again: that is said too, not left at
    "sensor data back". An all-unknown array while the pose is known (nothing in the radar's view) is sent as it
    is: it is what the sensors saw."""
    ap_link, sim = pair
    assert wait_until(lambda: ap_link.connected, 5.0)
    loop = DaemonLoop(PerceptionPipeline(), SensorInputs(), ap_link, None, LoopSettings(lidar_expected=False))
    unknown = np.full(72, 65535, dtype=np.uint16)
    for k in range(170):
        pose = not (40 <= k < 60 or k >= 140)
        radar = not 70 <= k < 150
        loop._publish(PerceptionOutput(0.1 * k, [], unknown, lidar_fresh=False, radar_fresh=radar, pose_known=pose))
    assert wait_until(lambda: len(sim.statustexts()) >= 7 and len(sim.obstacle_distances()) >= 50, 5.0)
    time.sleep(0.5)
    assert [s.text for s in sim.statustexts()] == [
        "usv-tracker: no pose, obstacles withheld",
        "usv-tracker: obstacles sent again",
        "usv-tracker: radar silent",
        "usv-tracker: no sensor data, obstacles withheld",
        "usv-tracker: radar back",
        "usv-tracker: sensor data back",
        "usv-tracker: no pose, obstacles withheld",
    ]
    assert (loop.sent, loop.withheld, loop.unplaced) == (50, 120, 40)
    assert len(sim.obstacle_distances()) == 50
    assert loop._status == MAV_STATE_EMERGENCY  # the radar delivers, but nothing goes out
    assert "(radar without pose 40)" in loop.health_line(17.0)
