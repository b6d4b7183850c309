"""Scoring a run against ground truth: `usv-tracker evaluate` and its Python API.

    from evaluation import evaluate_run
    result = evaluate_run("capture_dir", "capture_dir/tracks.jsonl")
    print(result.to_text()); data = result.to_dict()

Tracks: CLEAR MOT (MOTA, MOTP), IDF1 and id switches through py-motmetrics (the ``eval`` extra), HOTA, and the errors
of matched pairs. Bins: false clear, false obstacle and accuracy of the 72 OBSTACLE_DISTANCE bins against the solids
the sensors returned. Definitions in evaluation/api.py, tracking.py and bins.py.
"""

from __future__ import annotations

from typing import Any

__all__ = ["EvaluationError", "EvaluationResult", "MissingDependencyError", "evaluate_run"]


def __getattr__(name: str) -> Any:
    # Loaded on first use, so that `usv-tracker run` (whose parser knows the evaluate command) never imports it.
    if name == "evaluate_run":
        from evaluation.api import evaluate_run

        return evaluate_run
    if name in ("EvaluationError", "MissingDependencyError"):
        from evaluation import errors

        return getattr(errors, name)
    if name == "EvaluationResult":
        from evaluation.result import EvaluationResult

        return EvaluationResult
    raise AttributeError(f"module 'evaluation' has no attribute {name!r}")
