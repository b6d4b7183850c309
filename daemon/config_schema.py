"""Typed TOML -> dataclass loading that names every bad key, value and why.

A crew editing /etc/usv-tracker/usv-tracker.toml on a quay needs "radar.mount.yaw: expected a number, got 'left'",
not a traceback. So loading collects every problem it finds before failing, and unknown keys are errors (a typo
such as ``max_ditance_m`` would otherwise silently keep the default).
"""

from __future__ import annotations

import dataclasses
import difflib
import math
import types
import typing
from typing import Any, TypeVar

from tracker.config_error import ConfigError as TrackerConfigError

T = TypeVar("T")


class ConfigError(TrackerConfigError):
    """One or more problems in a configuration; ``problems`` lists them as 'key: why'."""

    def __init__(self, problems: list[str], source: str = "") -> None:
        self.problems = problems
        self.source = source
        where = f"{source}: " if source else ""
        super().__init__(where + "; ".join(problems))


def _coerce(value: Any, tp: Any, key: str, problems: list[str]) -> Any:
    origin = typing.get_origin(tp)
    if origin in (typing.Union, types.UnionType):
        args = [a for a in typing.get_args(tp) if a is not type(None)]
        if value is None:
            return None
        return _coerce(value, args[0], key, problems)
    if dataclasses.is_dataclass(tp):
        if not isinstance(value, dict):
            problems.append(f"{key}: expected a table, got {value!r}")
            return None
        return _build(tp, value, key, problems)
    if origin in (list, tuple):
        (item_tp, *_) = typing.get_args(tp) or (Any,)
        if not isinstance(value, list):
            problems.append(f"{key}: expected a list, got {value!r}")
            return None
        items = [_coerce(v, item_tp, f"{key}[{i}]", problems) for i, v in enumerate(value)]
        return tuple(items) if origin is tuple else items
    if tp is bool:
        if not isinstance(value, bool):
            problems.append(f"{key}: expected true or false, got {value!r}")
            return None  # the default stands in, so the section's other values are still checked
        return value
    if origin is dict:
        if not isinstance(value, dict):
            problems.append(f"{key}: expected a table, got {value!r}")
            return None
        return value
    if tp is float:
        if isinstance(value, bool) or not isinstance(value, (int, float)):
            problems.append(f"{key}: expected a number, got {value!r}")
            return None
        try:
            number = float(value)
        except OverflowError:  # a TOML integer of hundreds of digits
            problems.append(f"{key}: too large a number (beyond 1.8e308)")
            return None
        if not math.isfinite(number):
            problems.append(f"{key}: must be a finite number, got {value!r}")
            return None
        return number
    if tp is int:
        if isinstance(value, bool) or not isinstance(value, int):
            problems.append(f"{key}: expected an integer, got {value!r}")
            return None
        return value
    if tp is str:
        if not isinstance(value, str):
            problems.append(f"{key}: expected a string, got {value!r}")
            return None
        return value
    return value


def _candidates(fields: dict[str, Any], hints: dict[str, Any]) -> list[str]:
    """The keys of a table and those of its sub-tables as "table.key": a key that moved into a group (the radar
    tracker's flat ``cluster_min_points`` became ``clustering.min_points``) is suggested where it went."""
    out = list(fields)
    for name in fields:
        if dataclasses.is_dataclass(hints.get(name)):
            out += [f"{name}.{f.name}" for f in dataclasses.fields(hints[name]) if f.init]
    return out


def _field_default(f: dataclasses.Field[Any]) -> Any:
    if f.default_factory is not dataclasses.MISSING:
        return f.default_factory()
    return None if f.default is dataclasses.MISSING else f.default


def _build(cls: type[T], table: dict[str, Any], prefix: str, problems: list[str], base: T | None = None) -> T:
    """``cls`` from ``table``; the keys the table leaves out keep ``base``'s values (the enclosing table's default
    for this one: the radar's mount sits 0.5 m forward and up, not at the origin as a bare mount does), else the
    class's own defaults."""
    hints = typing.get_type_hints(cls)
    fields = {f.name: f for f in dataclasses.fields(cls) if f.init}  # type: ignore[arg-type]
    kwargs: dict[str, Any] = {}
    reported = len(problems)
    for key, value in table.items():
        full = f"{prefix}.{key}" if prefix else key
        if key not in fields:
            candidates = _candidates(fields, hints)
            # A bare name that several groups hold (min_points: clustering's and ego's) is pointed to all of them.
            same = sorted(c for c in candidates if c.rpartition(".")[2] == key)
            close = same or difflib.get_close_matches(key, candidates, n=1)
            if len(close) > 1:
                hint = f" (did you mean one of {', '.join(repr(c) for c in close)}?)"
            else:
                hint = f" (did you mean '{close[0]}'?)" if close else f" (known keys: {', '.join(sorted(fields))})"
            problems.append(f"{full}: unknown key{hint}")
            continue
        if dataclasses.is_dataclass(hints[key]) and isinstance(value, dict):
            default = getattr(base, key) if base is not None else _field_default(fields[key])
            kwargs[key] = _build(
                hints[key], value, full, problems, default if isinstance(default, hints[key]) else None
            )
        else:
            kwargs[key] = _coerce(value, hints[key], full, problems)
    given = {k: v for k, v in kwargs.items() if v is not None}
    try:
        obj = dataclasses.replace(base, **given) if base is not None else cls(**given)  # type: ignore[type-var]
    except (TypeError, ValueError) as exc:
        problems.append(f"{prefix or 'config'}: {exc}")
        return base if base is not None else cls()  # type: ignore[call-arg]
    check = getattr(obj, "validate", None)
    if check is not None:
        try:
            found = check()
        except (TypeError, AttributeError, ValueError):
            if len(problems) == reported:
                raise  # no value was reported: a fault of validate() itself, not of the file
            found = []  # a value of the wrong type was already reported; its range cannot be checked
        problems.extend(f"{prefix}.{p}" if prefix else p for p in found)
    return obj


def build(cls: type[T], table: dict[str, Any], source: str = "") -> T:
    """Build ``cls`` from a parsed TOML table, raising ConfigError with every problem found."""
    obj, problems = build_with_problems(cls, table)
    if problems:
        raise ConfigError(problems, source)
    return obj


def build_with_problems(cls: type[T], table: dict[str, Any]) -> tuple[T, list[str]]:
    """``cls`` from a table and the problems found; a part with problems holds its defaults or the bad value."""
    problems: list[str] = []
    obj = _build(cls, table, "", problems)
    return obj, problems
