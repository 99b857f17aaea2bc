"""Rigid-body equations and kinematics for a batch of boats: :func:`bb2_sim.rigid_body.rigid_body_acceleration`
on arrays (N,) (its b-vector, :func:`bb2_sim.rigid_body.velocity_terms`, shared) and twins of the kinematics
of :meth:`bb2_sim.model.BB2Model.evaluate` (``R @ V`` and ``euler_rate_matrix @ omega``).
"""
from __future__ import annotations

import numpy as np

from ..parameters import RomParameters
from ..rigid_body import velocity_terms


def rigid_body_acceleration(F: np.ndarray, u, v, w, p, q, r, params: RomParameters,
                            euler_roll: bool = False) -> np.ndarray:
    """Body accelerations d[u, v, w, p, q, r]/dt (N, 6), native body axes, for the total loads F (N, 6).

    The scalar code's b-vector (:func:`bb2_sim.rigid_body.velocity_terms`) on arrays: the authors' roll term
    (Ixx - Iyy) q r (quirk Q1) unless ``euler_roll``; the data's Mb.
    """
    b = np.stack(velocity_terms(u, v, w, p, q, r, params, euler_roll), axis=1)
    Ixx, Iyy, Izz = params.inertia
    diagA = np.array([params.Mb, params.Mb, params.Mb, Ixx, Iyy, Izz])
    return (F - b) / diagA


def kinematics(R: np.ndarray, phi: np.ndarray, theta: np.ndarray, V: np.ndarray, omega: np.ndarray) -> np.ndarray:
    """d[x, y, z, phi, theta, psi]/dt (N, 6): earth velocity R V (native earth) and Euler-angle rates T omega.

    R: body->earth rotations as (3, 3, N) (the layout :func:`bb2_sim.frames.rotation_native` gives for arrays);
    V, omega: body velocities and rates (N, 3). The matrix-vector products go through numpy's stacked matvec,
    which calls the scalar code's BLAS kernel per boat (bit for bit its ``R @ V`` and ``T @ omega``).
    """
    cf, sf = np.cos(phi), np.sin(phi)
    ct, tt = np.cos(theta), np.tan(theta)
    T = np.empty((len(phi), 3, 3))                    # bb2_sim.frames.euler_rate_matrix per boat
    T[:, 0, 0], T[:, 0, 1], T[:, 0, 2] = 1.0, tt * sf, tt * cf
    T[:, 1, 0], T[:, 1, 1], T[:, 1, 2] = 0.0, cf, -sf
    T[:, 2, 0], T[:, 2, 1], T[:, 2, 2] = 0.0, sf / ct, cf / ct
    out = np.empty((len(phi), 6))
    out[:, 0:3] = np.matvec(np.ascontiguousarray(R.transpose(2, 0, 1)), np.ascontiguousarray(V))
    out[:, 3:6] = np.matvec(T, np.ascontiguousarray(omega))
    return out
