"""Range checks shared by the trackers' config groups: each raises ConfigError naming the group, the key and why."""

from __future__ import annotations

import math
from dataclasses import fields

from tracker.config_error import ConfigError


def choice(owner: object, name: str, allowed: tuple[str, ...]) -> None:
    value = getattr(owner, name)
    if value not in allowed:
        raise ConfigError(f"{type(owner).__name__}.{name}: {value!r} is not one of {', '.join(allowed)}")


def positive(owner: object, *names: str, allow_zero: bool = False, allow_inf: bool = False) -> None:
    """Each of ``names`` a finite number > 0 (>= 0 with ``allow_zero``; inf too with ``allow_inf``)."""
    for name in names:
        value = getattr(owner, name)
        ok = value >= 0 if allow_zero else value > 0
        if not (isinstance(value, (int, float)) and (allow_inf or math.isfinite(value)) and ok):
            bound = ">= 0" if allow_zero else "> 0"
            what = "a number" if allow_inf else "a finite number"
            raise ConfigError(f"{type(owner).__name__}.{name}: must be {what} {bound}, got {value!r}")


def no_nan(owner: object) -> None:
    """No float field of the dataclass ``owner`` is NaN (every comparison with NaN is False: no other check sees it)."""
    for f in fields(owner):  # type: ignore[arg-type]
        value = getattr(owner, f.name)
        if isinstance(value, float) and math.isnan(value):
            raise ConfigError(f"{type(owner).__name__}.{f.name} is NaN")


def share(owner: object, *names: str) -> None:
    """Each of ``names`` in (0, 1]: a share or a probability that must leave something."""
    for name in names:
        value = getattr(owner, name)
        if not (isinstance(value, (int, float)) and 0.0 < value <= 1.0):
            raise ConfigError(f"{type(owner).__name__}.{name}: must be in (0, 1], got {value!r}")


def at_least_one(owner: object, *names: str) -> None:
    """Each of ``names`` a count >= 1."""
    for name in names:
        value = getattr(owner, name)
        if not (isinstance(value, (int, float)) and value >= 1):
            raise ConfigError(f"{type(owner).__name__}.{name}: must be >= 1, got {value!r}")
