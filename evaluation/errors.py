"""The one error the evaluator raises for anything wrong with its inputs or its environment."""

from __future__ import annotations


class EvaluationError(ValueError):
    """Bad input (the message names the file and the line) or a missing optional dependency (it names the extra).

    The command line turns it into a message on stderr and exit status 2, never a traceback."""


class MissingDependencyError(EvaluationError):
    """An optional package the evaluation needs is not installed."""
