"""The vehicle state exchanged between the ROM, the controllers and the ROS contract.

All vectors are in the ROM's native frames (SPEC 1): earth z up with the bow along -x at psi = 0,
body x aft / y starboard / z up.  Conversions to REP-103 and NED live in :mod:`bb2_sim.frames`.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True)
class VehicleState:
    """Kinematic state of the CG at time ``t`` (s).

    p_native: earth position (x, y, z) of the CG, m (z up, negative below the surface).
    euler_native: (phi, theta, psi), rad, ZYX (theta > 0 bow up, psi > 0 bow to port).
    v_body_native: (u, v, w), m/s, body axes x aft / y stbd / z up (u < 0 moving ahead).
    w_body_native: (p, q, r), rad/s, body axes (q > 0 bow up, r > 0 bow to port).
    """

    t: float
    p_native: np.ndarray
    euler_native: np.ndarray
    v_body_native: np.ndarray
    w_body_native: np.ndarray

    @classmethod
    def from_vector(cls, t: float, x12: np.ndarray) -> "VehicleState":
        """From the ROM state vector [x, y, z, phi, theta, psi, u, v, w, p, q, r]."""
        x12 = np.asarray(x12, dtype=float)
        return cls(float(t), x12[0:3].copy(), x12[3:6].copy(), x12[6:9].copy(), x12[9:12].copy())

    def as_vector(self) -> np.ndarray:
        """The ROM state vector [x, y, z, phi, theta, psi, u, v, w, p, q, r]."""
        return np.concatenate([self.p_native, self.euler_native, self.v_body_native, self.w_body_native])

    @property
    def depth_m(self) -> float:
        """Depth of the CG below the calm surface, m (positive down)."""
        return float(-self.p_native[2])
