"""The authors' regular waves of a batch: one :class:`bb2_sim.waves.Wave` per boat (calm: amplitude 0).

A boat in a sea runs the scalar wave code itself (orbital velocities, the per-point pressure integral: that work
is per boat anyway); only the calm boats take the vectorised paths.
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Sequence

import numpy as np

from ..waves import Wave


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
                                 f"got {type(w).__name__} (irregular seas not supported yet)")
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
