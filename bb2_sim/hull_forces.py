"""Hull, appendage-at-neutral and rotary loads of the ROM (SPEC 5.1-5.6 without the planes and statics).

Inputs are the body velocities (native body axes: u < 0 ahead), CG z, and the flow angles at the CG.
Every coefficient comes from the tables (``RomTables.hull``) or from ``RomParameters.hc``; the equations
are those of the authors' force functions, including their odd dimensions (quirks Q4, Q9).
"""
from __future__ import annotations

from .parameters import RomParameters
from .tables import RomTables


def _sgn(x: float) -> float:
    return (x > 0) - (x < 0)


def _clamp(x: float, lo: float, hi: float) -> float:
    return lo if x < lo else (hi if x > hi else x)


def hull_loads(u: float, v: float, w: float, p: float, q: float, r: float, z: float,
               alpha: float, beta: float, U: float, params: RomParameters, tables: RomTables,
               *, zuvw_b_abs_beta: bool = False, kpp_once: bool = False,
               sign_u_guard: bool = False) -> tuple[float, float, float, float, float, float, float]:
    """(X, Y, Z, K, M, N, T_wq): hull/rotary loads in N, N m, and the w-q thrust change T_wq (N).

    alpha, beta in degrees (SPEC 3.1), U in m/s. K includes K_pp twice unless ``kpp_once`` (Q7).
    """
    hc, T, inp = params.hc, tables.hull, params.inputs
    rho, L = params.rho, params.L
    q2, q3, q4 = params.q2, params.q3, params.q4
    zs = _clamp(z, *inp["zs_clamp_m"])
    us5 = _clamp(u, *inp["us_clamp_Z_m_s"])
    U2 = U * U
    u2 = u * u
    sb = _sgn(beta)
    ab = abs(beta)
    if sign_u_guard:
        sign_u = _sgn(u)
    else:
        sign_u = u / abs(u)

    # X (5.1)
    X_uvw = -q2 * (T["XuvwV"].lookup(alpha, u) + T["XuvwH"].lookup(ab, u, z)) * U2 * sign_u
    X_qq = q4 * T["Xqq"].lookup(abs(q)) * q * q
    X_wq = rho * L ** 3 * hc["X_wq"] * w * q
    T_wq = q3 * hc["T_wq"] * w * q
    X = X_uvw + X_qq + X_wq

    # Y (5.2)
    Y_uvw = q2 * sb * T["Yuvw"].lookup(ab, u, z) * U2
    Y_r = -rho * L ** 2 * (hc["Y_r"] * u * r) * u2 * 2
    Y = Y_uvw + Y_r

    # Z (5.3)
    zb_beta = ab if zuvw_b_abs_beta else beta
    Z_uvw = q2 * (T["Zuvw_a"].lookup(alpha, u, z) + T["Zuvw_b"].lookup(zb_beta, u, z)) * U2
    qs = _clamp(q, *inp["qs_clamp_Zqq_rad_s"])
    sf2 = hc["speed_factor_m_s"] ** 2
    Z_qq = q4 * _sgn(qs) * T["Zqq"].lookup(abs(qs)) * q * q * sf2
    Z_uq = (hc["Z_uq"] * u * q) * 0.5 * L ** 3 * rho * hc["Z_uq_factor"]
    Z_ur = (hc["Z_ur"] * u * r) * L ** 2 * rho * sf2
    Z_prop = q3 * T["Zuq_prop"].lookup(us5 * q, u)
    Z = Z_uvw + Z_qq + Z_uq + Z_ur + Z_prop

    # K (5.4)
    K_uvw = q3 * sb * T["Kuvw"].lookup(ab, u, zs) * U2
    K_up = -rho * L ** 3 * (hc["K_up"] * u * p) * u2
    K_ur = rho * L ** 3 * (hc["K_ur"] * u * r) * u2
    K_pp = rho * L ** 3 * (hc["K_pp"] * p * abs(p))
    K = K_uvw + K_up + K_ur + K_pp + (0.0 if kpp_once else K_pp)

    # M (5.5)
    M_uvw = q3 * T["Muvw"].lookup(alpha, u, zs) * U2
    M_uq = q4 * u * q * hc["M_uq"] * hc["M_uq_factor"]
    M_prop = -rho * L ** 4 * u * q * T["Mprop"].lookup(u)
    M = M_uvw + M_uq + M_prop

    # N (5.6)
    N_uvw = q3 * sb * T["Nuvw"].lookup(ab, u, zs) * U2
    N_r = q3 * (hc["N_r"] * hc["N_r_factor"] * u * r) * u2
    N_vr = q3 * _sgn(r) * T["Nvr"].lookup(abs(v * r)) * u2
    N_rr = -q3 * _sgn(r) * T["Nrr"].lookup(r * r) * r * r * u2
    N = N_uvw + N_r + N_vr + N_rr
    return X, Y, Z, K, M, N, T_wq
