"""ShiftedEgo: poses kept on the host's clock, asked for on a recording's."""

from __future__ import annotations

import numpy as np
import pytest

from daemon.ego import HistoryEgo, ShiftedEgo
from daemon.pose_history import PoseHistory
from drivers.frames import EgoPose

HOST_T0 = 5000.0  # host monotonic seconds
DATA_T0 = 1_767_225_600.0  # the recording's Unix seconds (simulator's T0_UNIX)


def test_a_recording_time_is_answered_with_the_pose_at_the_matching_host_time() -> None:
    history = PoseHistory()
    for k in range(21):  # 2 m/s north, turning 0.1 rad/s, 10 Hz for 2 s
        t = HOST_T0 + 0.1 * k
        history.add(EgoPose(t, np.array([2.0 * 0.1 * k, 0.0, 0.0]), np.array([2.0, 0.0, 0.0]), 0.0, 0.0, 0.01 * k, 0.1))
    ego = ShiftedEgo(HistoryEgo(history), HOST_T0 - DATA_T0)
    assert ego.available and ego.epoch == HistoryEgo(history).epoch
    pose = ego.at(DATA_T0 + 1.05)
    assert pose is not None
    assert pose.t == DATA_T0 + 1.05  # stamped on the clock it was asked on
    # half-way between two samples: 2.1 m north, yaw 0.105 rad (exact up to float rounding of the Unix time)
    assert pose.position[0] == pytest.approx(2.1, abs=1e-6)
    assert pose.yaw == pytest.approx(0.105, abs=1e-6)
    pos, _roll, _pitch, yaw = ego.at_many(np.array([DATA_T0 + 0.5, DATA_T0 + 1.5]))
    np.testing.assert_allclose(pos[:, 0], [1.0, 3.0], atol=1e-6)
    np.testing.assert_allclose(yaw, [0.05, 0.15], atol=1e-6)
    # a recording time whose host time lies far past the newest pose is unknown, as it would be live
    assert ego.at(DATA_T0 + 60.0) is None
