"""Vectorised twins of :mod:`bb2_sim.tables`: the same Simulink n-D lookup semantics on arrays of inputs.

Every operation follows the scalar lookup's order (clamp, segment search ``bp[i] <= x < bp[i+1]`` with the end
segments extended, fraction ``(x - bp[i]) / (bp[i+1] - bp[i])``, the same interpolation sums), so a batch lookup
equals the scalar ``LookupTable.lookup`` of each element bit for bit.

Two savings over calling the scalar lookup per element:

* an axis (breakpoints + input clamp) is shared by every table that has it, and :class:`Segments` memoises the
  segment and fraction of a named input on an axis for one model evaluation (``u`` enters nine hull tables);
* tables with the same axes (the five planes' tables of one load) are stacked into one :class:`BatchTable`
  entered with one column of inputs per member.
"""
from __future__ import annotations

from typing import Sequence

import numpy as np

from ..tables import LookupTable, RomTables


SHORT_AXIS = 5
"""Axes with at most this many breakpoints find their segment by counting the inner breakpoints below x
(cheaper than a binary search on arrays; the same segment, the end segments included)."""


class BatchAxis:
    """One breakpoint axis with its input clamp (None: no clamp), evaluated on arrays."""

    def __init__(self, breakpoints: Sequence[float], clamp: tuple[float, float] | None):
        self.bp = np.asarray(breakpoints, dtype=float)
        self.dbp = self.bp[1:] - self.bp[:-1]          # bp[i+1] - bp[i], the scalar code's denominators
        self.n2 = len(self.bp) - 2
        self.lo, self.hi = (None, None) if clamp is None else (float(clamp[0]), float(clamp[1]))
        self._inner = [float(b) for b in self.bp[1:-1]] if len(self.bp) <= SHORT_AXIS else None

    def segment(self, x: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Segment indices i and fractions f of the inputs x (any shape), the clamp applied first."""
        if self.lo is not None:
            x = np.minimum(np.maximum(x, self.lo), self.hi)
        if self._inner is not None:      # short axis: i = number of inner breakpoints <= x (the same segment)
            i = (x >= self._inner[0]).astype(np.intp)
            for b in self._inner[1:]:
                i += x >= b
        else:
            i = self.bp.searchsorted(x, side="right")
            i -= 1
            np.maximum(i, 0, out=i)
            np.minimum(i, self.n2, out=i)
        return i, (x - self.bp.take(i)) / self.dbp.take(i)


class Segments:
    """Memo of axis segments of named inputs for one model evaluation: a name must mean one array (value and
    shape) for the whole evaluation, e.g. ``"zs"`` the clamped depth (N,) and ``"zs_column"`` the same as (N, 1)."""

    def __init__(self):
        self._memo: dict[tuple[int, str], tuple[np.ndarray, np.ndarray]] = {}

    def __call__(self, axis: BatchAxis, name: str, x: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        key = (id(axis), name)
        seg = self._memo.get(key)
        if seg is None:
            seg = self._memo[key] = axis.segment(x)
        return seg


class BatchTable:
    """One table, or several with identical axes stacked (members along the last input dimension).

    The values are pre-arranged per cell as the corners and their differences along the last axis (exactly the
    scalar code's ``a[j + 1] - a[j]``), so an evaluation gathers one row per input.
    """

    def __init__(self, tables: Sequence[LookupTable], axes: Sequence[BatchAxis]):
        t0 = tables[0]
        for t in tables[1:]:
            if t.breakpoints != t0.breakpoints or t.clamps != t0.clamps:
                raise ValueError(f"stacked tables need identical axes: {t0.name} and {t.name} differ")
        self.names = [t.name for t in tables]
        self.axes = list(axes)
        self.ndim = t0.ndim
        vals = np.array([np.asarray(t.values, dtype=float) for t in tables])          # (K, n0, ..)
        v = vals[..., :-1]                                   # v[.., j] and the scalar code's v[.., j+1] - v[.., j]
        d = vals[..., 1:] - vals[..., :-1]
        if self.ndim == 1:                                   # cell i: (v[i], d[i])
            cells = [v, d]
        elif self.ndim == 2:                                 # cell (i, j): rows i and i + 1 at column j
            cells = [v[:, :-1], d[:, :-1], v[:, 1:], d[:, 1:]]
        elif self.ndim == 3:                                 # cell (i, j, l): (i, j), (i+1, j), (i, j+1), (i+1, j+1)
            cells = [v[:, :-1, :-1], d[:, :-1, :-1], v[:, 1:, :-1], d[:, 1:, :-1],
                     v[:, :-1, 1:], d[:, :-1, 1:], v[:, 1:, 1:], d[:, 1:, 1:]]
        else:
            raise ValueError(f"table {t0.name}: {self.ndim}-D lookups are not supported")
        self._cells = np.stack(cells, axis=-1).reshape(-1, len(cells))                 # (K * cells, C)
        self._shape = vals.shape[1:]
        ncell = [n - 1 for n in self._shape]
        self._stride = [int(np.prod(ncell[a + 1:])) for a in range(self.ndim)]
        self._member_offset = np.arange(len(tables)) * int(np.prod(ncell))
        gains = np.array([t.gain for t in tables])
        self.gain = float(gains[0]) if np.all(gains == gains[0]) else gains
        self._unit_gain = np.all(gains == 1.0)              # 1.0 * y == y: the multiplication is skipped

    def interpolate(self, segs: Sequence[tuple[np.ndarray, np.ndarray]], stacked: bool = False) -> np.ndarray:
        """Value at the given per-axis segments (i, f) (broadcast together); ``stacked``: the last dimension
        of the inputs runs over the member tables."""
        idx = segs[0][0] * self._stride[0]
        for (i, _), s in zip(segs[1:], self._stride[1:]):
            idx = idx + i * s if s != 1 else idx + i
        if stacked:
            idx = idx + self._member_offset
        c = self._cells.take(idx, axis=0)
        if self.ndim == 1:
            f = segs[0][1]
            return self._times_gain(c[..., 0] + f * c[..., 1])
        if self.ndim == 2:
            f, g = segs[0][1], segs[1][1]
            y0 = c[..., 0] + g * c[..., 1]
            y1 = c[..., 2] + g * c[..., 3]
            return self._times_gain(y0 + f * (y1 - y0))
        f, g, h = segs[0][1], segs[1][1], segs[2][1]
        c00 = c[..., 0] + h * c[..., 1]
        c01 = c[..., 4] + h * c[..., 5]
        c10 = c[..., 2] + h * c[..., 3]
        c11 = c[..., 6] + h * c[..., 7]
        c0 = c00 + g * (c01 - c00)
        c1 = c10 + g * (c11 - c10)
        return self._times_gain(c0 + f * (c1 - c0))

    def _times_gain(self, y: np.ndarray) -> np.ndarray:
        if self._unit_gain:
            return y
        y *= self.gain
        return y

    def __call__(self, seg: Segments, *inputs: tuple[str, np.ndarray], stacked: bool = False) -> np.ndarray:
        """Lookup of named inputs (``(name, array)`` per axis, names memoised in ``seg``)."""
        return self.interpolate([seg(a, n, x) for a, (n, x) in zip(self.axes, inputs)], stacked)


class AxisRegistry:
    """Builds the batch tables, one :class:`BatchAxis` per distinct (breakpoints, clamp)."""

    def __init__(self):
        self._axes: dict[tuple, BatchAxis] = {}

    def axis(self, breakpoints: Sequence[float], clamp) -> BatchAxis:
        key = (tuple(breakpoints), None if clamp is None else tuple(clamp))
        if key not in self._axes:
            self._axes[key] = BatchAxis(breakpoints, clamp)
        return self._axes[key]

    def table(self, *tables: LookupTable) -> BatchTable:
        t0 = tables[0]
        return BatchTable(tables, [self.axis(b, c) for b, c in zip(t0.breakpoints, t0.clamps)])


class BatchRomTables:
    """The ROM's tables (:class:`bb2_sim.tables.RomTables`) as batch tables.

    ``planes[c]`` lists, per load component c in X..N, the groups ``(planes, table)``: the plane indices whose
    tables share their axes, stacked into one table (e.g. the four stern planes, then the sail planes).
    """

    def __init__(self, tables: RomTables):
        reg = AxisRegistry()
        self.hull = {k: reg.table(t) for k, t in tables.hull.items()}
        self.thrust_deduction = reg.table(tables.thrust_deduction)
        self.planes: dict[str, list[tuple[list[int], BatchTable]]] = {}
        for comp, lst in tables.planes.items():
            groups: list[list[int]] = []
            for i, t in enumerate(lst):
                for g in groups:
                    t0 = lst[g[0]]
                    if g[-1] == i - 1 and t.breakpoints == t0.breakpoints and t.clamps == t0.clamps:
                        g.append(i)
                        break
                else:
                    groups.append([i])
            self.planes[comp] = [(g, reg.table(*[lst[i] for i in g])) for g in groups]
