"""Simulink Derivative blocks of a batch of boats (twin of :class:`bb2_sim.added_mass.DerivativeMemory`).

Per boat: output (u(t) - u_s) / (t - t_s) against the most recent stored major-step sample with t_s < t, zero
without one; at most two samples are kept, as in the scalar block.
"""
from __future__ import annotations

from dataclasses import dataclass

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


@dataclass
class AddedMassInputs:
    """What the default mode's added-mass Derivative blocks differentiate, for n boats: their body velocities and
    rates nu (n, 6) and, for the boats in a sea (rows ``wavy``, indices into the n), the sections' wave
    velocities (m, 15, 3), body axes. The relative velocities urel_i = uw_i - (V + omega x r_i) are linear in
    them, so are the blocks: the added-mass load is the derivative of nu's part plus that of the waves' part."""

    nu: np.ndarray
    uw_sections: np.ndarray | None
    wavy: np.ndarray


class BatchAddedMassMemory:
    """The default mode's Derivative blocks of the added mass: the motion's (6 per boat) and, for the boats in a
    sea, the sections' wave velocities (15 x 3 per boat). The motion's part of a derivative, (nu - nu_s) / dt,
    is then taken on the velocities themselves: as precise as the scalar code's section by section differences."""

    def __init__(self, n_boats: int, n_sections: int):
        self.motion = BatchDerivativeMemory(n_boats, (6,))
        self.wave = BatchDerivativeMemory(n_boats, (n_sections, 3))

    def reset(self) -> None:
        self.motion.reset()
        self.wave.reset()

    @staticmethod
    def _wave_rows(t, inputs: AddedMassInputs, boats: np.ndarray | None):
        t_w = t if np.ndim(t) == 0 else np.asarray(t)[inputs.wavy]
        return t_w, (inputs.wavy if boats is None else np.asarray(boats)[inputs.wavy])

    def derivatives(self, t, inputs: AddedMassInputs,
                    boats: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray | None]:
        """(d nu/dt (n, 6), d uw/dt of the boats in a sea (m, 15, 3) or None) at t (scalar or (n,))."""
        d_nu = self.motion.derivative(t, inputs.nu, boats)
        if inputs.uw_sections is None or len(inputs.wavy) == 0:
            return d_nu, None
        t_w, rows = self._wave_rows(t, inputs, boats)
        return d_nu, self.wave.derivative(t_w, inputs.uw_sections, rows)

    def store(self, t, inputs: AddedMassInputs, boats: np.ndarray | None = None) -> None:
        """Store the major-step samples of the given boats (None: all)."""
        self.motion.store(t, inputs.nu, boats)
        if inputs.uw_sections is not None and len(inputs.wavy):
            t_w, rows = self._wave_rows(t, inputs, boats)
            self.wave.store(t_w, inputs.uw_sections, rows)
