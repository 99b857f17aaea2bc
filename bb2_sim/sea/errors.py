"""The error of bad sea and current input (a ValueError, so callers that catch ValueError still do)."""
from __future__ import annotations

import math


class SeaInputError(ValueError):
    """A sea, spectrum, spreading, component list or current parameter is out of its domain."""


def finite(name: str, value, *, positive: bool = False, nonnegative: bool = False) -> float:
    """``value`` as a float, raising :class:`SeaInputError` if it is NaN/inf or of the wrong sign."""
    try:
        v = float(value)
    except (TypeError, ValueError) as exc:
        raise SeaInputError(f"{name} must be a number, got {value!r}") from exc
    if not math.isfinite(v):
        raise SeaInputError(f"{name} must be finite, got {value!r}")
    if positive and not v > 0:
        raise SeaInputError(f"{name} must be > 0, got {v!r}")
    if nonnegative and v < 0:
        raise SeaInputError(f"{name} must be >= 0, got {v!r}")
    return v
