"""The authors' v12.1 autopilot and the root model's speed PI for a batch of boats: the scalar classes
:class:`bb2_sim.autopilot_v12.V12Autopilot` and :class:`bb2_sim.speed_control.SpeedPI` given arrays (N,) -- one
state per boat -- so their own ``step`` (elementwise, the same gains and operation order) runs every boat.
"""
from __future__ import annotations

import numpy as np

from ..autopilot_v12 import V12Autopilot
from ..speed_control import SpeedPI


class BatchV12Autopilot(V12Autopilot):
    """Depth/pitch PID + heading PD per boat: references z_ref (m, native CG z) and psi_ref (rad), (N,) each (a
    scalar psi_ref is every boat's).  :meth:`step` takes z, theta, psi (N,) and returns (dv, dh) (N,) in deg."""

    def __init__(self, z_ref, psi_ref):
        z = np.array(z_ref, dtype=float)
        super().__init__(z, np.array(np.broadcast_to(np.asarray(psi_ref, dtype=float), z.shape)))


class BatchSpeedPI(SpeedPI):
    """n_cmd = ff tgt_speed + P e_u + I int(e_u) per boat, e_u = u - tgt_speed (native u, m/s, (N,))."""

    def __init__(self, tgt_speed, corrected_feedforward: bool = False):
        super().__init__(np.array(tgt_speed, dtype=float), corrected_feedforward)
