"""Propeller of the ROM (SPEC 6): open-water KT/KQ polynomials, thrust deduction, no wake fraction."""
from __future__ import annotations

from dataclasses import dataclass

from .parameters import RomParameters
from .tables import LookupTable


@dataclass(frozen=True)
class PropellerLoad:
    J: float
    KT: float
    KQ: float
    t: float          # thrust deduction
    thrust: float     # N, net thrust (1 - t) KT rho n^2 D^4, acts forward (X gets -thrust)
    torque: float     # N m, KQ rho n^2 D^5, added to the roll moment K


def propeller_load(u: float, z: float, rps: float, params: RomParameters, td_table: LookupTable,
                   wired_correctly: bool = False) -> PropellerLoad:
    """Thrust and torque at body velocity u (m/s, negative ahead), CG z (m) and n = rps (>= 0.01).

    The thrust-deduction table's inputs are swapped in the model (quirk Q8): u goes to the depth axis and z
    to the speed axis, so t is constant in practice. ``wired_correctly`` feeds z and u to their own axes.
    """
    return load_with_deduction(u, rps, td_table(z, u) if wired_correctly else td_table(u, z), params)


def load_with_deduction(u, rps, t, params: RomParameters) -> PropellerLoad:
    """The open-water polynomials and the loads at body velocity u (m/s), n = rps and thrust deduction t: floats
    for one boat, or arrays (N,) elementwise for a batch (:mod:`bb2_sim.batch.propeller`; the same operations, so
    the same bits)."""
    D = params.prop_D
    J = (-u) / (rps * D)
    a, b, c = params.KT_poly
    KT = a * J * J + b * J + c
    a, b, c = params.KQ_poly
    KQ = a * J * J + b * J + c
    n2 = rps * rps
    thrust = KT * (1.0 - t) * params.rho * n2 * D ** 4
    torque = KQ * params.rho * n2 * D ** 5
    return PropellerLoad(J, KT, KQ, t, thrust, torque)
