"""The C library's sin, cos, atan and acos element by element, for the exact batch.

The single-boat code calls :mod:`math` (the C library) for the flow angles, the plane incidences and the weight's
components. numpy's float64 ``sin``, ``cos``, ``arctan`` and ``arccos`` may run vectorised kernels instead (SVML
on AVX-512 machines) that differ from the C library in the last bit for rare arguments, enough to part a batch
from its single runs after a hundred steps. The exact batch (bit for bit the single code on every machine) applies
the C library's functions through these, at about 0.1 us an element; the default batch keeps numpy's kernels.
"""
from __future__ import annotations

import math
from typing import Callable

import numpy as np


def elementwise(fn: Callable[[float], float], a) -> np.ndarray:
    """``fn`` (a :mod:`math` function) of every element of ``a``, float64 of a's shape; NaN where fn raises
    (outside its domain, as numpy gives)."""
    a = np.asarray(a, dtype=float)
    values = a.ravel().tolist()
    try:
        return np.fromiter(map(fn, values), dtype=float, count=a.size).reshape(a.shape)
    except (ValueError, OverflowError):                    # rare (a diverging boat): element by element

        def safe(v: float) -> float:
            try:
                return fn(v)
            except (ValueError, OverflowError):
                return math.nan
        return np.fromiter(map(safe, values), dtype=float, count=a.size).reshape(a.shape)


def sin(a) -> np.ndarray:
    return elementwise(math.sin, a)


def cos(a) -> np.ndarray:
    return elementwise(math.cos, a)


def arctan(a) -> np.ndarray:
    return elementwise(math.atan, a)


def arccos(a) -> np.ndarray:
    return elementwise(math.acos, a)
