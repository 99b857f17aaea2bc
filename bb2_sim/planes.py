"""Control planes of the ROM (SPEC 3.2, 3.3 and the plane terms of 5.1-5.6).

Planes 1..4 are the X-stern planes (1 lower starboard, 2 upper starboard, 3 upper port, 4 lower port),
plane 5 the sail planes. Local flow and incidence are evaluated at each plane's reference point in
native body axes; the tables are entered with the effective deflection dX_i + aX_i (deg).
"""
from __future__ import annotations

import math

import numpy as np

from .parameters import RomParameters
from .tables import RomTables

RAD2DEG = 180.0 / math.pi


def plane_flow(V: np.ndarray, omega: np.ndarray, uw_planes: np.ndarray, params: RomParameters,
               guard: bool = False) -> tuple[np.ndarray, np.ndarray]:
    """Relative speed UeX_i (m/s) and geometric incidence aX_i (deg) at the five planes.

    Per plane (SPEC 3.2): ur = -(V + omega x r_i) + uw_i, UeX = |ur|, np = (nh.ur) nh + (n_i.ur) n_i,
    c = np.ur / (|np| |ur|), aX = acos(c) k_i (0 when c >= 1), negative when d_i.ur < 0. Plain float
    arithmetic on the five 3-vectors (numpy's per-call overhead dominates at this size).

    ``guard`` (zero-speed guard, quirk Q13): at zero relative speed the incidence is 0. Without it the
    authors' division by zero stands (NaN, or ZeroDivisionError/ValueError from the float arithmetic: the
    integrator reports either as a non-finite model evaluation).
    """
    u, v, w = float(V[0]), float(V[1]), float(V[2])
    p, q, r = float(omega[0]), float(omega[1]), float(omega[2])
    nh0, nh1, nh2 = params.hull_axis_list
    UeX = np.empty(5)
    aX = np.empty(5)
    for i, ((rx, ry, rz), (n0, n1, n2), (d0, d1, d2), k, (w0, w1, w2)) in enumerate(zip(
            params.plane_points_list, params.plane_spans_list, params.plane_lift_dirs_list,
            params.plane_incidence_gain_list, uw_planes.tolist())):
        ux = -(u + (q * rz - r * ry)) + w0
        uy = -(v + (r * rx - p * rz)) + w1
        uz = -(w + (p * ry - q * rx)) + w2
        s = math.sqrt(ux * ux + uy * uy + uz * uz)
        a = ux * nh0 + uy * nh1 + uz * nh2
        b = n0 * ux + n1 * uy + n2 * uz
        px, py, pz = a * nh0 + b * n0, a * nh1 + b * n1, a * nh2 + b * n2
        npn = math.sqrt(px * px + py * py + pz * pz)
        den = npn * s
        if guard and not den > 0.0:
            c = 1.0
        else:
            c = (px * ux + py * uy + pz * uz) / den
            if guard:
                c = -1.0 if c < -1.0 else c
        ang = 0.0 if c >= 1.0 else math.acos(c) * RAD2DEG * k
        if d0 * ux + d1 * uy + d2 * uz < 0:
            ang = -ang
        UeX[i] = s
        aX[i] = ang
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
            X += q2 * (T["X"][i].lookup(d, -s) + dXiuq) * s2
            Y += rho * L ** 2 * T["Y"][i].lookup(d, zs) * s2
            K += rho * L ** 3 * T["K"][i].lookup(d, zs, s) * s2
            N += rho * L ** 3 * T["N"][i].lookup(d, zN) * s2
        else:
            X += q2 * T["X"][i].lookup(d, -s) * s2
        Z += q2 * T["Z"][i].lookup(d, zs) * s2
        M += q3 * T["M"][i].lookup(d, zs) * s2
    return X, Y, Z, K, M, N
