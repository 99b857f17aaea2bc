"""Pressure (depth) sensor: absolute pressure at its mounting point under the instantaneous sea (no ROS).

    p = p_atm + rho g max(0, -z_s + h_wave(x_s, z_s, t)) + offset + noise,   quantised to ``resolution_pa``

``z_s`` the sensor's height (native earth = ENU z), ``h_wave`` the sea's dynamic pressure head at the sensor
(``Sea.pressure_head``: the wave pressure above it, decaying with depth; 0 in calm water); ``p_atm`` the day's
atmospheric pressure (``atmospheric_pressure_pa``: a consumer converting with the standard 101325 Pa sees the
difference as a depth offset); ``offset`` the zero offset drawn per seed.  Variance: noise^2 + resolution^2/12 +
offset sigma^2.
"""
from __future__ import annotations

import numpy as np

from .config import PressureConfig
from .noise import stream
from .samples import PressureSample
from .truth import TruthBatch

__all__ = ["PressureModel"]

_D = np.array([-1.0, -1.0, 1.0])


class PressureModel:
    name = "pressure"

    def __init__(self, cfg: PressureConfig, seed: int, index: int = 1, t0: float = 0.0) -> None:
        self.cfg = cfg
        self.period = 1.0 / cfg.rate_hz
        init = stream(seed, index, 0)
        self.rng = stream(seed, index, 1)
        self.offset_pa = cfg.offset_pa * float(init.standard_normal())
        self.variance = cfg.noise_pa ** 2 + cfg.resolution_pa ** 2 / 12.0 + cfg.offset_pa ** 2

    def sample(self, truth: TruthBatch, env) -> list[PressureSample]:
        c = self.cfg
        W = self.rng.standard_normal((truth.n, 1))
        p_enu = truth.point_enu(c.mounting.position_flu)
        head = np.zeros(truth.n)
        if env.sea is not None:
            for k in range(truth.n):
                head[k] = float(env.sea.pressure_head((p_enu[k] * _D)[None, :], float(truth.t[k]))[0])
        column = np.maximum(0.0, -p_enu[:, 2] + head)
        p = c.atmospheric_pressure_pa + env.rho * env.g * column + self.offset_pa + c.noise_pa * W[:, 0]
        if c.resolution_pa > 0:
            p = np.round(p / c.resolution_pa) * c.resolution_pa
        return [PressureSample("pressure", float(t), float(t), c.frame_id, float(v), self.variance)
                for t, v in zip(truth.t, p)]
