"""Simulink Derivative blocks of a batch of boats (twin of :class:`bb2_sim.added_mass.DerivativeMemory`).

Per boat: output (u(t) - u_s) / (t - t_s) against the most recent stored major-step sample with t_s < t, zero
without one; at most two samples are kept, as in the scalar block.
"""
from __future__ import annotations

import numpy as np


class BatchDerivativeMemory:
    """Two samples (t_s, u_s) per boat, u of shape ``shape`` (the 15 x 3 section velocities)."""

    def __init__(self, n_boats: int, shape: tuple[int, ...] = (15, 3)):
        self.n = int(n_boats)
        self._t = np.full((2, self.n), np.nan)                 # [older, newer] sample times; NaN: no sample
        self._u = np.zeros((2, self.n) + tuple(shape))
        self._count = np.zeros(self.n, dtype=int)

    def reset(self) -> None:
        self._t[:] = np.nan
        self._count[:] = 0

    def derivative(self, t, u: np.ndarray, boats: np.ndarray | None = None) -> np.ndarray:
        """Derivative outputs (n, ...) at time t (scalar or (n,)) of the inputs u (n, ...) of the given boats
        (indices; None: all)."""
        sel = slice(None) if boats is None else boats
        tn, to = self._t[1, sel], self._t[0, sel]
        cnt = self._count[sel]
        t = np.broadcast_to(np.asarray(t, dtype=float), tn.shape)
        expand = (slice(None),) + (None,) * (u.ndim - 1)
        use_new = (cnt >= 1) & (tn < t)
        if use_new.all():
            return (u - self._u[1, sel]) / (t - tn)[expand]
        use_old = ~use_new & (cnt >= 2) & (to < t)
        out = np.zeros_like(u)
        for mask, slot, ts in ((use_new, 1, tn), (use_old, 0, to)):
            if mask.any():
                idx = np.flatnonzero(mask)
                rows = idx if boats is None else np.asarray(boats)[idx]
                out[idx] = (u[idx] - self._u[slot, rows]) / (t[idx] - ts[idx])[expand]
        return out

    def store(self, t, u: np.ndarray, boats: np.ndarray | None = None) -> None:
        """Store the major-step samples (t, u) of the given boats (None: all)."""
        sel = slice(None) if boats is None else boats
        self._t[0, sel] = self._t[1, sel]
        self._u[0, sel] = self._u[1, sel]
        self._t[1, sel] = t
        self._u[1, sel] = u
        self._count[sel] = np.minimum(self._count[sel] + 1, 2)
