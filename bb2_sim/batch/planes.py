"""Control planes for a batch of boats: twins of :func:`bb2_sim.planes.plane_flow` and
:func:`bb2_sim.planes.plane_loads` on arrays over boats (same expressions, same operation order).

Arrays: velocities and rates (N,) per component, native body axes; per-plane quantities (N, 5), planes 1..4 the
X-stern planes and 5 the sail planes.
"""
from __future__ import annotations

import numpy as np

from ..parameters import RomParameters
from . import libm
from .lookup import BatchRomTables, Segments

RAD2DEG = 180.0 / np.pi


def plane_flow(u, v, w, p, q, r, uw_planes: np.ndarray, params: RomParameters,
               guard: bool = False, exact: bool = False) -> tuple[np.ndarray, np.ndarray]:
    """Relative speed UeX (m/s) and geometric incidence aX (deg), both (N, 5), at the five planes.

    u..r: (N,) body velocities and rates; uw_planes: (3, 5, N) wave velocities at the planes, body axes.
    Without ``guard`` a zero relative speed gives NaN (the scalar code raises): the boat diverges.
    ``exact``: the incidence through the C library's acos, as the scalar code (:mod:`.libm`).
    """
    nh0, nh1, nh2 = params.hull_axis_list
    rx, ry, rz = params.plane_points_body.T                   # (5,) each: plane i in column i
    n0, n1, n2 = params.plane_spans_body.T
    d0, d1, d2 = params.plane_lift_dirs_body.T
    k = params.plane_incidence_gain
    u, v, w, p, q, r = (a[:, None] for a in (u, v, w, p, q, r))
    w0, w1, w2 = uw_planes[0].T, uw_planes[1].T, uw_planes[2].T
    ux = -(u + (q * rz - r * ry)) + w0
    uy = -(v + (r * rx - p * rz)) + w1
    uz = -(w + (p * ry - q * rx)) + w2
    UeX = np.sqrt(ux * ux + uy * uy + uz * uz)
    a = ux * nh0 + uy * nh1 + uz * nh2
    b = n0 * ux + n1 * uy + n2 * uz
    px, py, pz = a * nh0 + b * n0, a * nh1 + b * n1, a * nh2 + b * n2
    npn = np.sqrt(px * px + py * py + pz * pz)
    den = npn * UeX
    c = (px * ux + py * uy + pz * uz) / den
    if guard:
        c = np.where(den > 0.0, np.maximum(c, -1.0), 1.0)
    ang = np.where(c >= 1.0, 0.0, (libm.arccos(c) if exact else np.arccos(c)) * RAD2DEG * k)
    aX = np.where(d0 * ux + d1 * uy + d2 * uz < 0, -ang, ang)
    return UeX, aX


def _component(tables: BatchRomTables, comp: str, seg: Segments, *inputs: tuple[str, np.ndarray]) -> np.ndarray:
    """Lookups of load component ``comp`` for the planes that have a table: (N, n_planes); inputs (N, 5) per plane
    or (N, 1) shared by the planes, with a name for the memo."""
    cols = []
    for planes, table in tables.planes[comp]:
        sl = slice(planes[0], planes[-1] + 1)
        segs = []
        for axis, (name, x) in zip(table.axes, inputs):
            i, f = seg(axis, name, x)
            segs.append((i[:, sl], f[:, sl]) if i.shape[1] > 1 else (i, f))
        cols.append(table.interpolate(segs, stacked=True))
    return np.concatenate(cols, axis=1) if len(cols) > 1 else cols[0]


def plane_loads(dXe: np.ndarray, UeX: np.ndarray, u: np.ndarray, q: np.ndarray, z: np.ndarray,
                params: RomParameters, tables: BatchRomTables, seg: Segments,
                n_clamped_depth: bool = False) -> tuple[np.ndarray, ...]:
    """(X, Y, Z, K, M, N) of the five planes, each (N,), N and N m, native body axes.

    dXe, UeX: (N, 5) effective deflections (deg) and relative speeds; u, q, z: (N,). The stern planes' N tables
    take the raw CG z (quirk Q20) unless ``n_clamped_depth``.
    """
    rho, L = params.rho, params.L
    q2, q3 = params.q2, params.q3
    hc, inp = params.hc, params.inputs
    zs_lo, zs_hi = inp["zs_clamp_m"]
    zs = np.where(z < zs_lo, zs_lo, np.where(z > zs_hi, zs_hi, z))
    zN = zs if n_clamped_depth else z
    uq = u * q
    dXiuq = hc["dXiuq_c2"] * uq * uq + hc["dXiuq_c1"] * uq
    s2 = UeX * UeX
    d = ("dXe", dXe)
    zsc = ("zs_column", zs[:, None])
    lX = _component(tables, "X", seg, d, ("-UeX", -UeX))
    lY = _component(tables, "Y", seg, d, zsc)
    lZ = _component(tables, "Z", seg, d, zsc)
    lK = _component(tables, "K", seg, d, zsc, ("UeX", UeX))
    lM = _component(tables, "M", seg, d, zsc)
    lN = _component(tables, "N", seg, d, ("zN_column", zN[:, None]) if not n_clamped_depth else zsc)
    cY, cKN = rho * L ** 2, rho * L ** 3
    X = Y = Z = K = M = N = 0.0
    for i in range(5):
        si = s2[:, i]
        if i < 4:
            X += q2 * (lX[:, i] + dXiuq) * si
            Y += cY * lY[:, i] * si
            K += cKN * lK[:, i] * si
            N += cKN * lN[:, i] * si
        else:
            X += q2 * lX[:, i] * si
        Z += q2 * lZ[:, i] * si
        M += q3 * lM[:, i] * si
    return X, Y, Z, K, M, N
