"""Actuators of a batch of boats: the rate limiters and saturations of :class:`bb2_sim.actuators.Actuators`
with one memory row per boat (same limits, same operation order)."""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..actuators import Actuators
from ..parameters import RomParameters
from .pressure import PlaneRotations


@dataclass
class BatchActuatorOutputs:
    """Applied values held during one step, per boat: planes (N, 5) deg (native plane signs), rps (N,),
    ballast (N,) kg. ``rotations`` caches the planes' hinge rotations for these deflections
    (:class:`bb2_sim.batch.pressure.PlaneRotations`, set by the model or the simulator)."""

    planes_deg: np.ndarray
    rps: np.ndarray
    dmass_kg: np.ndarray
    rotations: PlaneRotations | None = None


class BatchActuators:
    """Rate limiters + saturations for the 5 planes, the propeller and the ballast of N boats."""

    def __init__(self, params: RomParameters, n_boats: int, h: float | None = None):
        one = Actuators(params, h)
        self.h, self.rate, self.lo, self.hi = one.h, one.rate, one.lo, one.hi
        self.memory = np.zeros((int(n_boats), 7))

    def reset(self, initial: np.ndarray | None = None) -> None:
        """Limiter memories to 0 (the model's start) or to given values (N, 7): planes 5, rps, dmass."""
        self.memory = np.zeros_like(self.memory) if initial is None else \
            np.array(np.broadcast_to(np.asarray(initial, dtype=float), self.memory.shape))

    def step(self, planes_cmd_deg: np.ndarray, rps_cmd: np.ndarray, dmass_cmd_kg: np.ndarray,
             boats: np.ndarray | None = None) -> BatchActuatorOutputs:
        """Major-step update of the given boats (indices; None: all) with their commands (rows of those boats)."""
        u = np.concatenate([planes_cmd_deg, rps_cmd[:, None], dmass_cmd_kg[:, None]], axis=1)
        mem = self.memory if boats is None else self.memory[boats]
        dmax = self.rate * self.h
        y = mem + np.minimum(np.maximum(u - mem, -dmax), dmax)
        if boats is None:
            self.memory = y
        else:
            self.memory[boats] = y
        out = np.minimum(np.maximum(y, self.lo), self.hi)
        return BatchActuatorOutputs(out[:, :5], out[:, 5], out[:, 6])
