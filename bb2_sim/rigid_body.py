"""Rigid-body equations of the ROM (SPEC 2): d[u,v,w,p,q,r]/dt = A^-1 (F - b), added mass not in A."""
from __future__ import annotations

import numpy as np

from .parameters import RomParameters


def velocity_terms(u, v, w, p, q, r, params: RomParameters, euler_roll: bool = False) -> list:
    """The six components of the b-vector (the rigid body's velocity-dependent terms, native body axes) of
    d[u,v,w,p,q,r]/dt = A^-1 (F - b): floats for one boat, or arrays (N,) elementwise for a batch (the same
    operations in the same order, so both give the same bits).

    The authors' roll equation uses (Ixx - Iyy) q r (quirk Q1); ``euler_roll`` uses the Euler term
    (Izz - Iyy) q r. CG offsets (zero for the BB2) are kept as coded.
    """
    Mb = params.Mb
    Ixx, Iyy, Izz = params.inertia
    Xg, Yg, Zg = params.cg_offset
    return [
        Mb * (w * q - v * r - Xg * (q * q + r * r) + Yg * p * q + Zg * p * r),
        Mb * (u * r - w * p - Yg * (r * r + p * p) + Zg * q * r + Xg * p * q),
        Mb * (v * p - u * q - Zg * (p * p + q * q) + Xg * r * p + Yg * r * q),
        ((Izz - Iyy) if euler_roll else (Ixx - Iyy)) * q * r + Mb * (Yg * (v * p - u * q) - Zg * (u * r - w * p)),
        (Ixx - Izz) * r * p + Mb * (Zg * (w * q - v * r) - Xg * (v * p - u * q)),
        (Iyy - Ixx) * p * q + Mb * (Xg * (u * r - w * p) - Yg * (w * q - v * r)),
    ]


def rigid_body_acceleration(F: np.ndarray, V: np.ndarray, omega: np.ndarray, params: RomParameters,
                            euler_roll: bool = False) -> np.ndarray:
    """Body accelerations (native body axes) for the total load F = [X, Y, Z, K, M, N] (b: :func:`velocity_terms`)."""
    u, v, w = V
    p, q, r = omega
    b = np.array(velocity_terms(u, v, w, p, q, r, params, euler_roll))
    Ixx, Iyy, Izz = params.inertia
    diagA = np.array([params.Mb, params.Mb, params.Mb, Ixx, Iyy, Izz])
    return (F - b) / diagA
