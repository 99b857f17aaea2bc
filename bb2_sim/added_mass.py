"""Lumped added mass (SPEC 8) and the Simulink Derivative block semantics it uses (SPEC 11.3).

The section relative velocities are differentiated numerically against the last major-step sample, so the
added mass acts as an explicit force with a one-step lag, exactly as the authors' model does.
"""
from __future__ import annotations

import numpy as np
from .frames import cross


def section_relative_velocity(V: np.ndarray, omega: np.ndarray, uw_sections: np.ndarray,
                              r_sections: np.ndarray) -> np.ndarray:
    """urel_i = uw_i - (V + omega x r_i), (15, 3), native body axes (m/s)."""
    return uw_sections - (V + cross(omega, r_sections))


class DerivativeMemory:
    """Simulink Derivative block: output (u(t) - u_s)/(t - t_s) against the most recent sample with t_s < t.

    Only major steps store samples (:meth:`store`); with no earlier sample the output is 0.
    """

    def __init__(self):
        self._samples: list[tuple[float, np.ndarray]] = []  # at most two, oldest first

    def reset(self) -> None:
        self._samples.clear()

    def derivative(self, t: float, u: np.ndarray) -> np.ndarray:
        for ts, us in reversed(self._samples):
            if ts < t:
                return (u - us) / (t - ts)
        return np.zeros_like(u)

    def store(self, t: float, u: np.ndarray) -> None:
        self._samples.append((float(t), np.array(u, dtype=float)))
        if len(self._samples) > 2:
            self._samples.pop(0)
