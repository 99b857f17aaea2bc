"""Actuator model of the ROM (SPEC 9.2): discrete rate limiters (sample time h) followed by saturation.

Every channel: ``y_k = y_{k-1} + clamp(u_k - y_{k-1}, -rate h, +rate h)`` with ``y_{-1} = 0`` at each major
step (direct feed-through of the current command), the limiter memory keeps the unsaturated y, and the
applied value ``clamp(y_k, lo, hi)`` is held during the step's solver stages.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .parameters import RomParameters


@dataclass(frozen=True)
class ActuatorOutputs:
    """Applied actuator values held during one step: planes (deg, native plane signs), rps, ballast (kg)."""

    planes_deg: np.ndarray
    rps: float
    dmass_kg: float = 0.0


class Actuators:
    """Rate limiters + saturations for the 5 planes, the propeller and the ballast."""

    def __init__(self, params: RomParameters, h: float | None = None):
        a = params.act
        self.h = float(h if h is not None else params.h)
        self.rate = np.array([a["plane_rate_deg_s"]] * 5 + [a["rps_rate_per_s"], a["dmass_rate_kg_s"]], float)
        self.lo = np.array([-a["plane_limit_deg"]] * 5 + [a["rps_limits"][0], -a["dmass_limit_kg"]], float)
        self.hi = np.array([a["plane_limit_deg"]] * 5 + [a["rps_limits"][1], a["dmass_limit_kg"]], float)
        self.memory = np.zeros(7)

    def reset(self, initial: np.ndarray | None = None) -> None:
        """Limiter memories to 0 (the model's start) or to given values (planes 5, rps, dmass)."""
        self.memory = np.zeros(7) if initial is None else np.asarray(initial, dtype=float).copy()

    def step(self, planes_cmd_deg, rps_cmd: float, dmass_cmd_kg: float = 0.0) -> ActuatorOutputs:
        """Major-step update with the current commands; returns the applied (saturated) values."""
        u = np.concatenate([np.asarray(planes_cmd_deg, dtype=float), [rps_cmd, dmass_cmd_kg]])
        dmax = self.rate * self.h
        y = self.memory + np.clip(u - self.memory, -dmax, dmax)
        self.memory = y
        out = np.clip(y, self.lo, self.hi)
        return ActuatorOutputs(out[:5].copy(), float(out[5]), float(out[6]))

    def plane_limit_deg(self) -> float:
        return float(self.hi[0])
