"""Hull, appendage-at-neutral and rotary loads for a batch of boats: the twin of
:func:`bb2_sim.hull_forces.hull_loads` on arrays (N,), the same expressions in the same order.

Inputs: body velocities and rates (native body axes, u < 0 ahead), CG z, flow angles at the CG (deg) and U.
"""
from __future__ import annotations

import numpy as np

from ..parameters import RomParameters
from .lookup import BatchRomTables, Segments


def _sgn(x: np.ndarray) -> np.ndarray:
    return np.sign(x)


def _clamp(x: np.ndarray, lo: float, hi: float) -> np.ndarray:
    return np.where(x < lo, lo, np.where(x > hi, hi, x))


def hull_loads(u, v, w, p, q, r, z, alpha, beta, U, params: RomParameters, tables: BatchRomTables, seg: Segments,
               *, zuvw_b_abs_beta: bool = False, kpp_once: bool = False,
               sign_u_guard: bool = False) -> tuple[np.ndarray, ...]:
    """(X, Y, Z, K, M, N, T_wq), each (N,): hull/rotary loads in N, N m, and the w-q thrust change T_wq (N).

    Without ``sign_u_guard`` u = 0 gives NaN (the scalar code raises): the boat diverges.
    """
    hc, T, inp = params.hc, tables.hull, params.inputs
    rho, L = params.rho, params.L
    q2, q3, q4 = params.q2, params.q3, params.q4
    zs = _clamp(z, *inp["zs_clamp_m"])
    us5 = _clamp(u, *inp["us_clamp_Z_m_s"])
    U2 = U * U
    u2 = u * u
    sb = _sgn(beta)
    ab = np.abs(beta)
    if sign_u_guard:
        sign_u = _sgn(u)
    else:
        sign_u = u / np.abs(u)
    A, Ab, B, Uu, Z, Zs = ("alpha", alpha), ("abs_beta", ab), ("beta", beta), ("u", u), ("z", z), ("zs", zs)

    # X (5.1)
    X_uvw = -q2 * (T["XuvwV"](seg, A, Uu) + T["XuvwH"](seg, Ab, Uu, Z)) * U2 * sign_u
    X_qq = q4 * T["Xqq"](seg, ("abs_q", np.abs(q))) * q * q
    X_wq = rho * L ** 3 * hc["X_wq"] * w * q
    T_wq = q3 * hc["T_wq"] * w * q
    X = X_uvw + X_qq + X_wq

    # Y (5.2)
    Y_uvw = q2 * sb * T["Yuvw"](seg, Ab, Uu, Z) * U2
    Y_r = -rho * L ** 2 * (hc["Y_r"] * u * r) * u2 * 2
    Y = Y_uvw + Y_r

    # Z (5.3)
    zb_beta = Ab if zuvw_b_abs_beta else B
    Z_uvw = q2 * (T["Zuvw_a"](seg, A, Uu, Z) + T["Zuvw_b"](seg, zb_beta, Uu, Z)) * U2
    qs = _clamp(q, *inp["qs_clamp_Zqq_rad_s"])
    sf2 = hc["speed_factor_m_s"] ** 2
    Z_qq = q4 * _sgn(qs) * T["Zqq"](seg, ("abs_qs", np.abs(qs))) * q * q * sf2
    Z_uq = (hc["Z_uq"] * u * q) * 0.5 * L ** 3 * rho * hc["Z_uq_factor"]
    Z_ur = (hc["Z_ur"] * u * r) * L ** 2 * rho * sf2
    Z_prop = q3 * T["Zuq_prop"](seg, ("us_q", us5 * q), Uu)
    Zf = Z_uvw + Z_qq + Z_uq + Z_ur + Z_prop

    # K (5.4)
    K_uvw = q3 * sb * T["Kuvw"](seg, Ab, Uu, Zs) * U2
    K_up = -rho * L ** 3 * (hc["K_up"] * u * p) * u2
    K_ur = rho * L ** 3 * (hc["K_ur"] * u * r) * u2
    K_pp = rho * L ** 3 * (hc["K_pp"] * p * np.abs(p))
    K = K_uvw + K_up + K_ur + K_pp + (0.0 if kpp_once else K_pp)

    # M (5.5)
    M_uvw = q3 * T["Muvw"](seg, A, Uu, Zs) * U2
    M_uq = q4 * u * q * hc["M_uq"] * hc["M_uq_factor"]
    M_prop = -rho * L ** 4 * u * q * T["Mprop"](seg, Uu)
    M = M_uvw + M_uq + M_prop

    # N (5.6)
    N_uvw = q3 * sb * T["Nuvw"](seg, Ab, Uu, Zs) * U2
    N_r = q3 * (hc["N_r"] * hc["N_r_factor"] * u * r) * u2
    N_vr = q3 * _sgn(r) * T["Nvr"](seg, ("abs_vr", np.abs(v * r))) * u2
    N_rr = -q3 * _sgn(r) * T["Nrr"](seg, ("r2", r * r)) * r * r * u2
    N = N_uvw + N_r + N_vr + N_rr
    return X, Y, Zf, K, M, N, T_wq
