"""A boat closing faster than the radar's unambiguous speed: its Doppler wraps round, and the tracker unwraps it.

The AWR1843 measures the Doppler modulo 2 v_max (v_max = 8.33 m/s with the shipped profile). Head-on, a boat making
6.8 m/s towards the own boat making 4.5 m/s closes at 11.3 m/s; the radar reports it receding at 5.35 m/s. Taken as
measured, its speed over ground comes out +9.85 m/s (receding) instead of -6.8: its track runs away from its returns.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from daemon.config import Config
from daemon.tracker_adapters import radar_tracker_table, tracker_factories
from drivers.awr1843.parser import RadarFrameParser, encode_frame
from drivers.awr1843.profile import load_profile
from simulator.radar_model import SHIPPED_PROFILE, Awr1843Model
from simulator.scene import OwnBoat, Scene, Trajectory, Vessel
from tests.radar_sim_settings import EXACT
from tracker.radar.config import RadarTrackerConfig
from tracker.radar.detector import RadarDetector

V_MAX = load_profile(SHIPPED_PROFILE).max_velocity_mps
OWN_SPEED = 4.5  # m/s north
BOAT_SPEED = 6.8  # m/s south, head-on


def _wrapped(v: float) -> float:
    return (v + V_MAX) % (2 * V_MAX) - V_MAX


def test_the_shipped_profile_wraps_below_the_closing_speed_of_two_harbour_boats() -> None:
    assert pytest.approx(8.326, abs=1e-3) == V_MAX
    assert OWN_SPEED + BOAT_SPEED > V_MAX
    assert _wrapped(-(OWN_SPEED + BOAT_SPEED)) == pytest.approx(5.353, abs=1e-3)


def test_a_wrapped_doppler_is_taken_back_to_the_speed_over_ground() -> None:
    """Three returns 45 m dead ahead of a boat heading north; their Doppler as the radar reports it (wrapped)."""
    body = np.array([[45.0, -0.5, 0.0], [45.2, 0.0, 0.0], [45.0, 0.5, 0.0]])
    los = body[:, :2] / np.hypot(body[:, 0], body[:, 1])[:, None]
    relative = los @ np.array([-BOAT_SPEED - OWN_SPEED, 0.0])  # positive = receding
    measured = np.array([_wrapped(v) for v in relative])
    assert np.all(measured > 5.0)  # the radar says: receding
    truth = los @ np.array([-BOAT_SPEED, 0.0])
    cfg = RadarTrackerConfig().replaced(roi={"max_range_m": 50.0})
    args = (body, measured, None, 0.0, np.zeros(2), 0.0, np.array([OWN_SPEED, 0.0]))
    unwrapped = RadarDetector(cfg.replaced(max_radial_speed_mps=V_MAX)).detect(*args)
    np.testing.assert_allclose(unwrapped.doppler_world, truth, atol=1e-9)
    as_measured = RadarDetector(cfg).detect(*args)
    np.testing.assert_allclose(as_measured.doppler_world, truth + 2 * V_MAX, atol=1e-9)


def _head_on_scene() -> Scene:
    own = OwnBoat(Trajectory.constant_velocity((0.0, 0.0), (OWN_SPEED, 0.0), heading=0.0))
    boat = Vessel(
        "closing", 6.0, 2.2, 1.5, Trajectory.constant_velocity((55.0, 1.0), (-BOAT_SPEED, 0.0), heading=math.pi)
    )
    return Scene("head-on", own, [boat], [])


def _confirmed_velocities(max_radial_speed: float | None) -> list[np.ndarray]:
    """The radar tracker as the daemon builds it (shipped profile) over the simulated AWR1843's frames of a boat
    closing head-on from 55 m: the velocity of every confirmed track in the frame 2 s on (closing from 33 m)."""
    scene = _head_on_scene()
    config = Config()
    config.radar.profile = str(SHIPPED_PROFILE)
    config.radar.mount.x, config.radar.mount.y, config.radar.mount.z = 0.0, 0.0, 0.0
    config.radar.mount.yaw = 0.0
    if max_radial_speed is not None:
        config.tracker.radar = {"max_radial_speed_mps": max_radial_speed}
    _, make_radar, _ = tracker_factories(config)
    assert make_radar is not None
    tracker = make_radar()
    model = Awr1843Model(scene, scene.radar_mount, seed=3, **EXACT)
    assert model.v_max == V_MAX
    parser = RadarFrameParser(None, scene.radar_mount)  # the bytes the radar would send, through the real parser
    tracks = []
    for k, d in enumerate(model.frames(0.0, 2.05)):
        for frame in parser.feed(encode_frame(k + 1, d.xyz_ti, d.doppler, d.snr_db, d.noise_db), d.t):
            tracks = tracker.step_frame(frame, scene.own.pose(frame.stamp))
    return [tr.velocity for tr in tracks if tr.confirmed]


def test_a_boat_closing_head_on_faster_than_v_max_is_tracked_at_its_speed() -> None:
    """Fails without the unwrap: no confirmed track, or one receding at 9.9 m/s."""
    (velocity,) = _confirmed_velocities(None)
    np.testing.assert_allclose(velocity, [-BOAT_SPEED, 0.0], atol=0.5)


def test_without_the_unwrap_the_closing_boat_is_not_tracked_at_its_speed() -> None:
    assert not any(np.allclose(v, [-BOAT_SPEED, 0.0], atol=0.5) for v in _confirmed_velocities(0.0))


def test_the_daemon_takes_v_max_from_the_radar_profile_it_sends(tmp_path) -> None:
    """From [radar] profile; none without a readable profile, and none when the profile turns on the demo's own
    velocity disambiguation (extendedMaxVelocity), whose speeds may lie beyond the chirp's v_max."""
    config = Config()
    config.radar.profile = str(SHIPPED_PROFILE)
    assert radar_tracker_table(config)["max_radial_speed_mps"] == pytest.approx(8.3264, abs=1e-4)
    config.radar.profile = str(tmp_path / "missing.cfg")
    assert radar_tracker_table(config)["max_radial_speed_mps"] == 0.0
    extended = tmp_path / "extended.cfg"
    text = SHIPPED_PROFILE.read_text()
    assert "extendedMaxVelocity -1 0" in text
    extended.write_text(text.replace("extendedMaxVelocity -1 0", "extendedMaxVelocity -1 1"))
    config.radar.profile = str(extended)
    assert radar_tracker_table(config)["max_radial_speed_mps"] == 0.0
