"""Lookup tables with the semantics of Simulink n-D Lookup Table blocks (SPEC section 4).

Multilinear (tensor-product linear) interpolation with **linear extrapolation** from the end segment in
every dimension; no clamping unless an input saturation is listed for an axis (then the input is clamped
first, as the Saturation block in front of the table does). Segment search: ``bp[i] <= x < bp[i+1]``;
``x <= bp[0]`` uses segment 0, ``x >= bp[-1]`` the last segment.

The ROM evaluates ~45 tables per model evaluation with scalar inputs, so lookups are plain-Python on
nested lists (faster than numpy for scalars); :meth:`LookupTable.evaluate_array` is the vectorised
equivalent used for plotting and tests.
"""
from __future__ import annotations

import json
from bisect import bisect_right
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Sequence

import numpy as np

DATA_DIR = Path(__file__).resolve().parent / "data"


def _segment(bp: Sequence[float], x: float) -> tuple[int, float]:
    """Segment index i and fraction f of x on breakpoints bp (linear extrapolation outside)."""
    n = len(bp)
    i = bisect_right(bp, x) - 1
    if i < 0:
        i = 0
    elif i > n - 2:
        i = n - 2
    x0 = bp[i]
    return i, (x - x0) / (bp[i + 1] - x0)


_AXES: dict = {}
"""The axis functions by (breakpoints, clamp): tables on the same axis share one, and with it its last answer."""


def _axis_fn(bp: Sequence[float], clamp):
    """x -> (segment, fraction) for one axis, with the axis clamp and the end segments folded in.

    Tables with the same breakpoints and clamp share the function (:data:`_AXES`), which remembers its last input
    object and answer: the ROM passes the same float (u, alpha, the depth ...) to several tables of an axis in one
    evaluation, about half of its ~95 segment searches. The memory is one tuple (input, answer), replaced whole,
    so threads sharing an axis never see one's input with another's answer."""
    key = (tuple(float(b) for b in bp), None if clamp is None else tuple(clamp))
    if key in _AXES:
        return _AXES[key]
    bp = list(bp)
    n2 = len(bp) - 2
    lo, hi = clamp if clamp is not None else (None, None)
    last = [(None, None)]

    def seg(x: float, bp=bp, n2=n2, lo=lo, hi=hi, bisect=bisect_right, last=last):
        x_last, answer = last[0]
        if x is x_last:
            return answer
        xc = x
        if lo is not None:
            xc = lo if x < lo else (hi if x > hi else x)
        i = bisect(bp, xc) - 1
        if i < 0:
            i = 0
        elif i > n2:
            i = n2
        x0 = bp[i]
        answer = i, (xc - x0) / (bp[i + 1] - x0)
        last[0] = (x, answer)
        return answer

    _AXES[key] = seg
    return seg


def _compile(t: "LookupTable"):
    """A specialised scalar lookup function for table t (1-, 2- or 3-D)."""
    v, gain = t.values, t.gain
    segs = [_axis_fn(b, c) for b, c in zip(t.breakpoints, t.clamps)]
    if len(segs) == 1:
        s0, = segs

        def f1(x0):
            i, f = s0(x0)
            return gain * (v[i] + f * (v[i + 1] - v[i]))
        return f1
    if len(segs) == 2:
        s0, s1 = segs

        def f2(x0, x1):
            i, f = s0(x0)
            j, g = s1(x1)
            a, b = v[i], v[i + 1]
            y0 = a[j] + g * (a[j + 1] - a[j])
            y1 = b[j] + g * (b[j + 1] - b[j])
            return gain * (y0 + f * (y1 - y0))
        return f2
    if len(segs) == 3:
        s0, s1, s2 = segs

        def f3(x0, x1, x2):
            i, f = s0(x0)
            j, g = s1(x1)
            k, h = s2(x2)
            a0, a1, b0, b1 = v[i][j], v[i][j + 1], v[i + 1][j], v[i + 1][j + 1]
            c00 = a0[k] + h * (a0[k + 1] - a0[k])
            c01 = a1[k] + h * (a1[k + 1] - a1[k])
            c10 = b0[k] + h * (b0[k + 1] - b0[k])
            c11 = b1[k] + h * (b1[k + 1] - b1[k])
            c0 = c00 + g * (c01 - c00)
            c1 = c10 + g * (c11 - c10)
            return gain * (c0 + f * (c1 - c0))
        return f3
    raise ValueError(f"table {t.name}: {len(segs)}-D lookups are not supported")


@dataclass
class LookupTable:
    """One n-D table (n = 1..3): ``gain * table(clamp(inputs))``."""

    name: str
    breakpoints: list[list[float]]
    values: Any  # nested lists, values[i1][i2][i3]
    clamps: list[tuple[float, float] | None]
    gain: float = 1.0
    axis_names: list[str] = field(default_factory=list)
    source: str = ""

    @classmethod
    def from_dict(cls, name: str, d: dict) -> "LookupTable":
        bps = [list(map(float, a["breakpoints"])) for a in d["axes"]]
        clamps = [tuple(a["clamp"]) if a.get("clamp") is not None else None for a in d["axes"]]
        vals = np.asarray(d["values"], dtype=float)
        if vals.shape != tuple(len(b) for b in bps):
            raise ValueError(f"table {name}: values shape {vals.shape} does not match axes")
        for b in bps:
            if any(b2 <= b1 for b1, b2 in zip(b, b[1:])):
                raise ValueError(f"table {name}: breakpoints must increase strictly")
        return cls(name, bps, vals.tolist(), clamps, float(d.get("gain", 1.0)),
                   [a["name"] for a in d["axes"]], d.get("source", ""))

    @property
    def ndim(self) -> int:
        return len(self.breakpoints)

    def __post_init__(self) -> None:
        self.lookup = _compile(self)
        """The scalar lookup itself: ``table.lookup(x1, x2, ...)`` (what ``table(...)`` calls; the ROM's force
        functions call it directly to skip one Python call per lookup)."""

    def __call__(self, *x: float) -> float:
        """Scalar lookup (inputs in axis order, raw; clamps applied here), times the gain."""
        return self.lookup(*x)

    def evaluate_array(self, *x: np.ndarray) -> np.ndarray:
        """Vectorised lookup over broadcast input arrays (same semantics as the scalar call)."""
        xs = np.broadcast_arrays(*[np.asarray(a, dtype=float) for a in x])
        out = np.empty(xs[0].shape)
        for idx in np.ndindex(out.shape):
            out[idx] = self(*[a[idx] for a in xs])
        return out


@dataclass
class RomTables:
    """All lookup tables of the ROM (hull, planes, thrust deduction)."""

    hull: dict[str, LookupTable]
    planes: dict[str, list[LookupTable]]  # component 'X'..'N' -> tables of planes 1..n
    thrust_deduction: LookupTable
    unused_hull: dict[str, LookupTable]
    provenance: str = ""


def load_tables(path: Path | str | None = None) -> RomTables:
    """Load the project's table file (default ``bb2_sim/data/rom_tables.json``)."""
    path = Path(path) if path is not None else DATA_DIR / "rom_tables.json"
    d = json.loads(path.read_text())
    hull = {k: LookupTable.from_dict(k, v) for k, v in d["hull"].items()}
    unused = {k: LookupTable.from_dict(k, v) for k, v in d.get("unused_hull", {}).items()}
    planes = {c: [LookupTable.from_dict(f"{c}.plane{i + 1}", t) for i, t in enumerate(lst)]
              for c, lst in d["planes"].items()}
    td = LookupTable.from_dict("thrust_deduction", d["thrust_deduction"])
    return RomTables(hull, planes, td, unused, d.get("_provenance", ""))
