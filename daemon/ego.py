"""The boat's pose as the pipeline needs it, from the autopilot link (live) or a pose history (replay)."""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

from daemon.pose_history import PoseHistory
from drivers.frames import EgoPose


class HistoryEgo:
    """EgoSource over a PoseHistory; ``world_epoch`` says when the autopilot's world frame changed."""

    def __init__(self, history: PoseHistory, world_epoch: Callable[[], int] = lambda: 0) -> None:
        self.history = history
        self._world_epoch = world_epoch

    @property
    def available(self) -> bool:
        """False until the first pose: then the body frame at start is the world ("no ego pose" mode)."""
        return len(self.history) > 0

    @property
    def epoch(self) -> int:
        # Going from "no ego pose" to the autopilot's frame is a change of world frame too.
        return 2 * self._world_epoch() + int(self.available)

    def at_many(self, times: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        return self.history.at_many(times)

    def at(self, t: float) -> EgoPose | None:
        return self.history.at(t)
