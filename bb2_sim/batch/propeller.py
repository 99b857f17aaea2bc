"""Propeller for a batch of boats: :func:`bb2_sim.propeller.propeller_load` on arrays (N,) (the batch
thrust-deduction lookup, then the scalar code's :func:`~bb2_sim.propeller.load_with_deduction`)."""
from __future__ import annotations

import numpy as np

from ..parameters import RomParameters
from ..propeller import PropellerLoad, load_with_deduction
from .lookup import BatchTable, Segments


def propeller_load(u: np.ndarray, z: np.ndarray, rps: np.ndarray, params: RomParameters, td_table: BatchTable,
                   seg: Segments, wired_correctly: bool = False) -> PropellerLoad:
    """Thrust and torque at body velocity u (m/s, native, negative ahead), CG z (m) and n = rps, all (N,).

    Returns a :class:`bb2_sim.propeller.PropellerLoad` whose fields are arrays (N,). The thrust-deduction
    table's inputs are swapped (quirk Q8) unless ``wired_correctly``.
    """
    t = td_table(seg, ("z", z), ("u", u)) if wired_correctly else td_table(seg, ("u", u), ("z", z))
    return load_with_deduction(u, rps, t, params)
