"""Validation helpers shared by every config: each returns the checked value or raises
:class:`~pickplace.errors.ConfigError` naming the field, the value and what is allowed."""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np

from pickplace.errors import ConfigError


def check_finite(name: str, value: float) -> float:
    """Return ``value`` as a float, or raise if it is not a finite number (strings are not numbers)."""
    if isinstance(value, (str, bytes)):
        raise ConfigError(name, value, "must be a finite number")
    try:
        v = float(value)
    except (TypeError, ValueError):
        raise ConfigError(name, value, "must be a finite number") from None
    if isinstance(value, bool) or not math.isfinite(v):
        raise ConfigError(name, value, "must be a finite number")
    return v


def check_range(
    name: str,
    value: float,
    lo: float | None = None,
    hi: float | None = None,
    *,
    lo_open: bool = False,
    hi_open: bool = False,
    unit: str = "",
) -> float:
    """Check that ``value`` is finite and inside ``[lo, hi]`` (or the open variants).

    Returns:
        The value as a float.
    """
    v = check_finite(name, value)
    lo_ok = lo is None or (v > lo if lo_open else v >= lo)
    hi_ok = hi is None or (v < hi if hi_open else v <= hi)
    if not (lo_ok and hi_ok):
        left = "" if lo is None else f"{'>' if lo_open else '>='} {lo:g}"
        right = "" if hi is None else f"{'<' if hi_open else '<='} {hi:g}"
        allowed = " and ".join(s for s in (left, right) if s)
        raise ConfigError(name, value, f"must be {allowed}{' ' + unit if unit else ''}")
    return v


def check_int(name: str, value: int, lo: int, hi: int | None = None) -> int:
    """Check that ``value`` is an integer in ``[lo, hi]``."""
    if isinstance(value, bool) or not isinstance(value, (int, np.integer)):
        raise ConfigError(name, value, "must be an integer")
    if value < lo or (hi is not None and value > hi):
        raise ConfigError(name, value, f"must be >= {lo}" + (f" and <= {hi}" if hi is not None else ""))
    return int(value)


def check_vector(
    name: str,
    value: Sequence[float],
    size: int,
    lo: float | None = None,
    hi: float | None = None,
    *,
    lo_open: bool = False,
    unit: str = "",
) -> tuple[float, ...]:
    """Check a fixed-size vector of finite numbers, each in range; return it as a tuple."""
    try:
        items = list(value)
    except TypeError:
        raise ConfigError(name, value, f"must be a sequence of {size} numbers") from None
    if len(items) != size:
        raise ConfigError(name, value, f"must have exactly {size} elements")
    return tuple(
        check_range(f"{name}[{i}]", v, lo, hi, lo_open=lo_open, unit=unit) for i, v in enumerate(items)
    )


__all__ = ["check_finite", "check_int", "check_range", "check_vector"]
