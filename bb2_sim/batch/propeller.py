"""Propeller for a batch of boats: the twin of :func:`bb2_sim.propeller.propeller_load` on arrays (N,)."""
from __future__ import annotations

import numpy as np

from ..parameters import RomParameters
from ..propeller import PropellerLoad
from .lookup import BatchTable, Segments


def propeller_load(u: np.ndarray, z: np.ndarray, rps: np.ndarray, params: RomParameters, td_table: BatchTable,
                   seg: Segments, wired_correctly: bool = False) -> PropellerLoad:
    """Thrust and torque at body velocity u (m/s, native, negative ahead), CG z (m) and n = rps, all (N,).

    Returns a :class:`bb2_sim.propeller.PropellerLoad` whose fields are arrays (N,). The thrust-deduction
    table's inputs are swapped (quirk Q8) unless ``wired_correctly``.
    """
    D = params.prop_D
    J = (-u) / (rps * D)
    a, b, c = params.KT_poly
    KT = a * J * J + b * J + c
    a, b, c = params.KQ_poly
    KQ = a * J * J + b * J + c
    t = td_table(seg, ("z", z), ("u", u)) if wired_correctly else td_table(seg, ("u", u), ("z", z))
    n2 = rps * rps
    thrust = KT * (1.0 - t) * params.rho * n2 * D ** 4
    torque = KQ * params.rho * n2 * D ** 5
    return PropellerLoad(J, KT, KQ, t, thrust, torque)
