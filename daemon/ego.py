"""The boat's pose as the pipeline needs it, from the autopilot link (live) or a pose history (replay)."""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import replace
from typing import TYPE_CHECKING

import numpy as np

from daemon.pose_history import PoseHistory
from drivers.frames import EgoPose

if TYPE_CHECKING:
    from tracker.pipeline import EgoSource


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


class ShiftedEgo:
    """An EgoSource on another clock: asked for the pose at ``t``, it answers the inner source's pose at
    ``t + offset_s``, stamped back at ``t``.

    A replay played into a live autopilot with its live poses (`usv-tracker replay --to URL --pose live`) ticks on
    the recording's clock while the autopilot's poses are stamped on the host's; the replay keeps the recorded pace,
    so the two differ by a constant.
    """

    def __init__(self, inner: EgoSource, offset_s: float) -> None:
        self.inner = inner
        self.offset_s = offset_s

    @property
    def available(self) -> bool:
        return self.inner.available

    @property
    def epoch(self) -> int:
        return self.inner.epoch

    def at_many(self, times: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        return self.inner.at_many(np.asarray(times, dtype=float) + self.offset_s)

    def at(self, t: float) -> EgoPose | None:
        pose = self.inner.at(t + self.offset_s)
        return None if pose is None else replace(pose, t=t)
