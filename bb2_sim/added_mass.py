"""Lumped added mass (SPEC 8) and the Simulink Derivative block semantics it uses (SPEC 11.3).

The section relative velocities are differentiated numerically against the last major-step sample, so the
added mass acts as an explicit force with a one-step lag, exactly as the authors' model does.
"""
from __future__ import annotations

import numpy as np


def section_relative_velocity(V: np.ndarray, omega: np.ndarray, uw_sections: np.ndarray,
                              r_sections: np.ndarray) -> np.ndarray:
    """urel_i = uw_i - (V + omega x r_i), (15, 3), native body axes (m/s)."""
    p, q, r = omega
    skew_T = np.array([[0.0, r, -q], [-r, 0.0, p], [q, -p, 0.0]])   # r_i @ skew_T = omega x r_i
    return uw_sections - (V + r_sections @ skew_T)


def moment_of_forces(r_points: np.ndarray, F: np.ndarray) -> np.ndarray:
    """sum_i r_i x F_i for (n, 3) points and forces, from the 3x3 matrix A = r^T F (one product)."""
    A = r_points.T @ F
    return np.array([A[1, 2] - A[2, 1], A[2, 0] - A[0, 2], A[0, 1] - A[1, 0]])


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
