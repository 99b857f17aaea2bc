"""The authors' regular waves of a batch: one :class:`bb2_sim.waves.Wave` per boat (calm: amplitude 0).

The orbital velocities of the boats in a sea are :func:`bb2_sim.waves.orbital_velocity_earth` on arrays over boats
(every operation element by element as the scalar code's: bit for bit); their per-point pressure pass runs boat by
boat (:mod:`bb2_sim.batch.pressure`).
"""
from __future__ import annotations

from dataclasses import dataclass
import math
from typing import Sequence

import numpy as np

from ..waves import Wave, orbital_velocity_of


@dataclass(frozen=True)
class BatchWaves:
    """The boats' waves and their amplitudes (m) as an array (N,)."""

    amplitude: np.ndarray
    waves: tuple[Wave, ...]

    @classmethod
    def from_waves(cls, waves: Sequence[Wave]) -> "BatchWaves":
        ws = tuple(waves)
        for i, w in enumerate(ws):
            if not isinstance(w, Wave):
                raise ValueError(f"batch: boat {i}: a wave must be a bb2_sim.waves.Wave (the authors' regular sea), "
                                 f"got {type(w).__name__} (give an irregular sea as seas=[...])")
        return cls(np.array([float(w.amplitude) for w in ws]), ws)

    def __len__(self) -> int:
        return len(self.waves)

    @property
    def wavy(self) -> np.ndarray:
        """Boolean mask of the boats in a sea (not calm)."""
        return self.amplitude != 0.0

    def subset(self, boats: np.ndarray) -> "BatchWaves":
        """The waves of the boats with the given indices."""
        return BatchWaves(self.amplitude[boats], tuple(self.waves[i] for i in boats))

    def orbital_velocity_earth(self, x: np.ndarray, z: np.ndarray, t, in_phase_with_pressure: bool = False
                               ) -> np.ndarray:
        """:func:`bb2_sim.waves.orbital_velocity_earth` of every boat at once: (u, v, w) earth axes (N, P, 3) at
        the earth points (x, z) (N, P) of the boats (all in a sea: amplitude != 0); t scalar or (N,) s."""
        ws = self.waves
        col = lambda values: np.array(values)[:, None]  # noqa: E731  (one row per boat)
        t = t if np.ndim(t) == 0 else np.asarray(t, dtype=float)[:, None]
        return orbital_velocity_of(col([w.wavenumber for w in ws]), col([w.omega for w in ws]),
                                   col([w.phase for w in ws]), col([w.amplitude * w.omega for w in ws]),
                                   col([math.cos(math.pi * w.heading_param) for w in ws]),
                                   col([math.sin(math.pi * w.heading_param) for w in ws]), x, z, t,
                                   in_phase_with_pressure)
