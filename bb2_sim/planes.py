"""Control planes of the ROM (SPEC 3.2, 3.3 and the plane terms of 5.1-5.6).

Planes 1..4 are the X-stern planes (1 lower starboard, 2 upper starboard, 3 upper port, 4 lower port),
plane 5 the sail planes. Local flow and incidence are evaluated at each plane's reference point in
native body axes; the tables are entered with the effective deflection dX_i + aX_i (deg).
"""
from __future__ import annotations

import math

import numpy as np

from .parameters import RomParameters
from .frames import cross
from .tables import RomTables

RAD2DEG = 180.0 / math.pi


def plane_flow(V: np.ndarray, omega: np.ndarray, uw_planes: np.ndarray, params: RomParameters,
               guard: bool = False) -> tuple[np.ndarray, np.ndarray]:
    """Relative speed UeX_i (m/s) and geometric incidence aX_i (deg) at the five planes.

    ``guard`` (zero-speed guard, quirk Q13): at zero relative speed the incidence is 0 instead of NaN.
    """
    r = params.plane_points_body
    ur = -(V + cross(omega, r)) + uw_planes               # (5, 3)
    UeX = np.sqrt(np.einsum("ij,ij->i", ur, ur))
    nh = params.hull_axis_body
    n = params.plane_spans_body
    a = ur @ nh
    b = np.einsum("ij,ij->i", n, ur)
    npj = a[:, None] * nh + b[:, None] * n
    nnp = np.sqrt(np.einsum("ij,ij->i", npj, npj))
    with np.errstate(invalid="ignore", divide="ignore"):
        c = np.einsum("ij,ij->i", npj, ur) / (nnp * UeX)
    if guard:
        c = np.where(np.isfinite(c), np.clip(c, -1.0, 1.0), 1.0)
    with np.errstate(invalid="ignore"):
        aX = np.where(c >= 1.0, 0.0, np.arccos(np.minimum(c, 1.0)) * RAD2DEG * params.plane_incidence_gain)
    side = np.einsum("ij,ij->i", params.plane_lift_dirs_body, ur)
    aX = np.where(side < 0, -aX, aX)
    return UeX, aX


def plane_loads(dXe: np.ndarray, UeX: np.ndarray, u: float, q: float, z: float, params: RomParameters,
                tables: RomTables, n_clamped_depth: bool = False) -> tuple[float, ...]:
    """(X, Y, Z, K, M, N) of the five planes, N and N m, native body axes.

    The N tables of the stern planes take the raw CG z (quirk Q20) unless ``n_clamped_depth``.
    """
    rho, L = params.rho, params.L
    q2, q3 = params.q2, params.q3
    T = tables.planes
    hc, inp = params.hc, params.inputs
    zs_lo, zs_hi = inp["zs_clamp_m"]
    zs = zs_lo if z < zs_lo else (zs_hi if z > zs_hi else z)
    zN = zs if n_clamped_depth else z
    uq = u * q
    dXiuq = hc["dXiuq_c2"] * uq * uq + hc["dXiuq_c1"] * uq
    X = Y = Z = K = M = N = 0.0
    for i in range(5):
        d = float(dXe[i])
        s = float(UeX[i])
        s2 = s * s
        if i < 4:
            X += q2 * (T["X"][i](d, -s) + dXiuq) * s2
            Y += rho * L ** 2 * T["Y"][i](d, zs) * s2
            K += rho * L ** 3 * T["K"][i](d, zs, s) * s2
            N += rho * L ** 3 * T["N"][i](d, zN) * s2
        else:
            X += q2 * T["X"][i](d, -s) * s2
        Z += q2 * T["Z"][i](d, zs) * s2
        M += q3 * T["M"][i](d, zs) * s2
    return X, Y, Z, K, M, N
